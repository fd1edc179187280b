//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use untangle::analysis::{analyze, Analysis, AnalysisMesh, End, ObjectKind};
use untangle::mesh::Mesh;

/// `f` run in a rayon pool of `threads` workers (the 1-vs-2-thread determinism tests).
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool")
        .install(f)
}

/// The shared data folder (`UNTANGLE_SHARED` or `../shared` beside the checkout), if present.
pub fn shared() -> Option<PathBuf> {
    let p = std::env::var_os("UNTANGLE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")));
    if p.join("data").is_dir() {
        Some(p)
    } else {
        eprintln!(
            "skipping: shared data folder not found at {} (set UNTANGLE_SHARED)",
            p.display()
        );
        None
    }
}

/// Analysis of cloth meshes.
pub fn run(meshes: &[Mesh]) -> (AnalysisMesh, Vec<untangle::geom::Vec3>, Analysis) {
    let parts: Vec<_> = meshes.iter().map(|m| (m, ObjectKind::Cloth)).collect();
    let (am, pos) = AnalysisMesh::new(&parts).expect("valid meshes");
    let a = analyze(&am, &pos).expect("consistent analysis");
    (am, pos, a)
}

/// Tanglement kinds with counts, sorted.
pub fn kinds(a: &Analysis) -> Vec<(String, usize)> {
    let mut m = std::collections::BTreeMap::new();
    for t in &a.tanglements {
        *m.entry(t.kind.to_string()).or_insert(0) += 1;
    }
    m.into_iter().collect()
}

/// Brute-force O(n^2) intersecting pairs with the independent pair test.
pub fn brute_pairs(am: &AnalysisMesh, pos: &[untangle::geom::Vec3]) -> Vec<[u32; 2]> {
    let mut v = Vec::new();
    for i in 0..am.triangles.len() {
        for j in i + 1..am.triangles.len() {
            if am.kind_of_triangle(i as u32) == ObjectKind::Obstacle
                && am.kind_of_triangle(j as u32) == ObjectKind::Obstacle
            {
                continue;
            }
            if untangle::geom::tri_tri::triangles_intersect(am.triangles[i], am.triangles[j], pos) {
                v.push([i as u32, j as u32]);
            }
        }
    }
    v
}

/// Structural invariants of an analysis; panics with a message when one fails.
pub fn check_consistency(am: &AnalysisMesh, a: &Analysis) {
    let topo = &am.topology;
    const NONE: u32 = u32::MAX;
    // Crossings: sorted, unique, edge not incident to triangle.
    assert!(
        a.crossings.windows(2).all(|w| w[0] < w[1]),
        "crossings sorted and unique"
    );
    for c in &a.crossings {
        let e = topo.edges[c.edge as usize];
        let t = am.triangles[c.triangle as usize];
        assert!(
            !t.contains(&e[0]) && !t.contains(&e[1]),
            "crossing edge incident to its triangle"
        );
    }
    // Segments and their ends.
    let mut uses = vec![Vec::new(); a.crossings.len()];
    for (s, seg) in a.segments.iter().enumerate() {
        assert!(seg.triangles[0] < seg.triangles[1]);
        let [ta, tb] = seg.triangles.map(|t| am.triangles[t as usize]);
        for end in seg.ends {
            match end {
                End::Crossing(c) => {
                    let cr = a.crossings[c as usize];
                    let et = topo.edge_triangles[cr.edge as usize];
                    let other = if cr.triangle == seg.triangles[0] {
                        seg.triangles[1]
                    } else {
                        seg.triangles[0]
                    };
                    assert!(
                        seg.triangles.contains(&cr.triangle),
                        "crossing triangle in its segment"
                    );
                    assert!(
                        et.contains(&other),
                        "crossing edge beside the other triangle"
                    );
                    uses[c as usize].push(s as u32);
                }
                End::LoopVertex(v) => {
                    assert!(ta.contains(&v) && tb.contains(&v), "loop vertex shared");
                }
            }
        }
        assert!(
            matches!(seg.ends[0], End::Crossing(_)),
            "every segment has a crossing"
        );
    }
    for (c, u) in uses.iter().enumerate() {
        let cr = a.crossings[c];
        let beside = topo.edge_triangles[cr.edge as usize]
            .iter()
            .filter(|&&t| t != NONE)
            .count();
        assert_eq!(
            u.len(),
            beside,
            "crossing {c} used by one segment per triangle beside its edge"
        );
        let oc = a.segments_of_crossing[c];
        let mut listed: Vec<u32> = oc.iter().copied().filter(|&s| s != NONE).collect();
        listed.sort();
        let mut u = u.clone();
        u.sort();
        assert_eq!(listed, u);
    }
    // Paths: every piece exactly once, consecutive pieces adjacent, ends and correspondence.
    let mut seen = vec![0u32; a.segments.len() * 2];
    for (i, p) in a.paths.iter().enumerate() {
        for &pc in p.pieces() {
            seen[pc as usize] += 1;
        }
        let tri = |pc: u32| a.segments[(pc / 2) as usize].triangles[(pc % 2) as usize];
        for w in p.pieces().windows(2) {
            let (t0, t1) = (tri(w[0]), tri(w[1]));
            let shares_edge = t0 == t1 || {
                let (x, y) = (am.triangles[t0 as usize], am.triangles[t1 as usize]);
                x.iter().filter(|v| y.contains(v)).count() >= 1
            };
            assert!(
                shares_edge,
                "consecutive pieces of path {i} in neighbouring triangles"
            );
        }
        assert_eq!(p.closed, p.ends.is_none());
        assert!((p.corresponds_to as usize) < a.paths.len());
        assert_eq!(
            a.paths[p.corresponds_to as usize].corresponds_to, i as u32,
            "correspondence is mutual"
        );
        let t = &a.tanglements[p.tanglement as usize];
        assert!(t.paths.contains(&(i as u32)));
    }
    assert!(
        seen.iter().all(|&n| n == 1),
        "every piece on exactly one path"
    );
}

/// A shortcut: validates and checks everything for some meshes.
pub fn analyse_checked(meshes: &[Mesh]) -> (AnalysisMesh, Vec<untangle::geom::Vec3>, Analysis) {
    let (am, pos, a) = run(meshes);
    check_consistency(&am, &a);
    (am, pos, a)
}
