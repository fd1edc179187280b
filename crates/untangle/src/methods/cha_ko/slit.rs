//! Slits: partitioning paths that run out and back through the same triangles **(ours, beyond
//! the paper)**.
//!
//! A partitioning path (CLOSED, LL, BB) bounds an inside region (Cha & Ko 2022, Sec. 3). When a
//! fold of the *other* surface pokes through the path's surface, the path on that surface can
//! run out to the fold's tip and back along the same triangles: every edge on its way is crossed
//! twice, once by each flank of the fold, so its cut is empty and there is no region and no red
//! vertex (the CROSS case after ~60 loop steps, see `docs/cha-ko.md`). The crossing edges and
//! the fold's triangles are red, but the fold's ridge is green: the doubly crossed edges straddle
//! it, and red-green pairs are held `eps_RG` apart (Sec. 5.3), so nothing can slip off the ridge.
//!
//! The *ridge vertices* of a slit are the vertices shared by two triangles that pierce the same
//! edge of the path's surface, loop vertices excepted: the fold the edge straddles. Colouring
//! them red makes the ridge red (so the straddling edges may cross it) and makes the ridge
//! vertices out-most red vertices, which Alg. 2 pulls toward their green neighbours across the
//! slit (VT-type finesse, Sec. 7): the fold withdraws through the surface.

use super::regionless::is_regionless;
use crate::analysis::{coloring, Analysis, AnalysisMesh, End};

/// The edges path `i` passes across at least twice, each with the triangles that pierce it
/// there (distinct crossings, ascending by edge). An edge `e` of a piece's own triangle is passed
/// across where the crossing `(e, other triangle of the segment)` ends the piece.
pub fn doubled_edges(mesh: &AnalysisMesh, analysis: &Analysis, i: usize) -> Vec<(u32, Vec<u32>)> {
    let mut seen: Vec<u32> = Vec::new();
    for &piece in analysis.paths[i].pieces() {
        let seg = &analysis.segments[(piece / 2) as usize];
        let own = mesh.triangles[analysis.piece_triangle(piece) as usize];
        for end in seg.ends {
            if let End::Crossing(c) = end {
                let [a, b] = mesh.topology.edges[analysis.crossings[c as usize].edge as usize];
                if own.contains(&a) && own.contains(&b) {
                    seen.push(c);
                }
            }
        }
    }
    seen.sort_unstable();
    seen.dedup();
    let mut by_edge: Vec<(u32, u32)> = seen
        .iter()
        .map(|&c| {
            let x = analysis.crossings[c as usize];
            (x.edge, x.triangle)
        })
        .collect();
    by_edge.sort_unstable();
    let mut out: Vec<(u32, Vec<u32>)> = Vec::new();
    for (e, t) in by_edge {
        match out.last_mut() {
            Some((le, ts)) if *le == e => ts.push(t),
            _ => out.push((e, vec![t])),
        }
    }
    out.retain(|(_, ts)| ts.len() >= 2);
    out
}

/// The ridge vertices of every slit of `analysis` (see the module documentation), ascending:
/// for each regionless partitioning path, each edge it passes across twice or more, and each
/// pair of triangles piercing that edge, their shared corners that are neither loop vertices
/// (of any path) nor ends of the edge.
pub fn ridge_vertices(mesh: &AnalysisMesh, analysis: &Analysis) -> Vec<u32> {
    let loops = analysis.loop_vertices();
    let mut out = Vec::new();
    for i in 0..analysis.paths.len() {
        // A slit candidate: a partitioning path without a non-empty inside region.
        if !is_regionless(analysis, i) {
            continue;
        }
        for (e, ts) in doubled_edges(mesh, analysis, i) {
            let ends = mesh.topology.edges[e as usize];
            for (k, &t0) in ts.iter().enumerate() {
                for &t1 in &ts[k + 1..] {
                    let c1 = mesh.triangles[t1 as usize];
                    for v in mesh.triangles[t0 as usize] {
                        if c1.contains(&v) && !ends.contains(&v) && loops.binary_search(&v).is_err()
                        {
                            out.push(v);
                        }
                    }
                }
            }
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// Colours the ridge vertices of every slit red and recolours `analysis` by Sec. 3 (edges,
/// triangles, out-most red vertices, red* triangles). Returns how many vertices turned red.
pub fn color_slits(mesh: &AnalysisMesh, analysis: &mut Analysis) -> usize {
    let ridge = ridge_vertices(mesh, analysis);
    let mut red = analysis.coloring.red_vertex.clone();
    let mut added = 0;
    for v in ridge {
        if !red[v as usize] {
            red[v as usize] = true;
            added += 1;
        }
    }
    if added > 0 {
        analysis.coloring = coloring::color(mesh, red, &analysis.crossings, &analysis.segments);
    }
    added
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{analyze, AnalysisMesh, ObjectKind, PathKind};
    use crate::geom::Vec3;
    use crate::mesh::Mesh;

    /// A square sheet in `z = 0` (two triangles) and a roof (two triangles on the ridge `a b`,
    /// vertices 4 and 5) shifted by `(dx, dy)`. At `(0, 0)` the ridge pierces the sheet just inside
    /// its boundary edge `y = 0`, which pierces both roof faces: the sheet's path runs in from
    /// that edge to the ridge and back out through the same triangle (a slit). At `(0.6, 1)` the
    /// roof's tip pokes through the middle of one sheet triangle: an ordinary BBII (the roof's path has
    /// the region `{a}`).
    fn sheet_and_roof(dx: f64, dy: f64) -> (AnalysisMesh, Vec<Vec3>) {
        let sheet = Mesh::new(
            "sheet",
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(2.0, 2.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
        let roof = Mesh::new(
            "roof",
            vec![
                Vec3::new(1.0 + dx, -1.0 + dy, 0.6),
                Vec3::new(1.0 + dx, 1.0 + dy, -0.4),
                Vec3::new(0.2 + dx, 0.1 + dy, -1.0),
                Vec3::new(1.8 + dx, -0.1 + dy, -1.0),
            ],
            vec![[0, 1, 2], [1, 0, 3]],
        )
        .unwrap();
        AnalysisMesh::new(&[(&sheet, ObjectKind::Cloth), (&roof, ObjectKind::Cloth)]).unwrap()
    }

    fn orient(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> f64 {
        (b - a).cross(&(c - a)).dot(&(d - a))
    }

    /// Brute-force oracle: whether segment `pq` crosses triangle `abc` (general position).
    fn crosses(p: Vec3, q: Vec3, [a, b, c]: [Vec3; 3]) -> bool {
        let (sp, sq) = (orient(a, b, c, p), orient(a, b, c, q));
        if sp * sq >= 0.0 {
            return false;
        }
        let s = [orient(p, q, a, b), orient(p, q, b, c), orient(p, q, c, a)];
        s.iter().all(|&x| x > 0.0) || s.iter().all(|&x| x < 0.0)
    }

    /// The oracle's ridge vertices: for every edge that triangles of the other object cross at
    /// least twice (by brute force), the corners shared by two of those triangles, minus the
    /// edge's ends; also checks that every sheet edge (object 0) is crossed an even number of
    /// times when `expect_even` (the sheet's cut is empty, whatever its path).
    fn oracle(am: &AnalysisMesh, pos: &[Vec3], expect_even: bool) -> Vec<u32> {
        let mut out = Vec::new();
        for &[u, w] in &am.topology.edges {
            let obj =
                am.object_of_triangle[am.triangles.iter().position(|t| t.contains(&u)).unwrap()];
            let hits: Vec<usize> = (0..am.triangles.len())
                .filter(|&t| am.object_of_triangle[t] != obj)
                .filter(|&t| {
                    let c = am.triangles[t].map(|v| pos[v as usize]);
                    crosses(pos[u as usize], pos[w as usize], c)
                })
                .collect();
            if expect_even && obj == 0 {
                assert_eq!(
                    hits.len() % 2,
                    0,
                    "edge {u}-{w} crossed an odd number of times"
                );
            }
            for (k, &t0) in hits.iter().enumerate() {
                for &t1 in &hits[k + 1..] {
                    for v in am.triangles[t0] {
                        if am.triangles[t1].contains(&v) && v != u && v != w {
                            out.push(v);
                        }
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    #[test]
    fn the_ridge_of_a_fold_through_a_slit_is_found_and_coloured() {
        let (am, pos) = sheet_and_roof(0.0, 0.0);
        let mut a = analyze(&am, &pos).unwrap();
        // The sheet's path is a boundary-boundary path without a region, with no red vertex.
        let bb = (0..a.paths.len())
            .find(|&i| a.paths[i].kind == PathKind::BoundaryBoundary)
            .expect("a BB path");
        assert!(is_regionless(&a, bb));
        assert!(a.paths[bb].cut_edges().is_empty());
        assert_eq!(a.coloring.num_red_vertices(), 0);
        // The sheet's boundary edge 0-1 is passed twice, pierced by both roof faces.
        let doubled = doubled_edges(&am, &a, bb);
        assert_eq!(doubled.len(), 1);
        assert_eq!(am.topology.edges[doubled[0].0 as usize], [0, 1]);
        assert_eq!(doubled[0].1, vec![2, 3]);
        let want = oracle(&am, &pos, true);
        assert_eq!(want, vec![4, 5], "the oracle sees the ridge a b");
        assert_eq!(ridge_vertices(&am, &a), want);
        assert_eq!(color_slits(&am, &mut a), 2);
        assert!(a.coloring.red_vertex[4] && a.coloring.red_vertex[5]);
        assert_eq!(a.coloring.outmost_red, vec![4, 5]);
        // A second pass adds nothing.
        assert_eq!(color_slits(&am, &mut a), 0);
    }

    #[test]
    fn an_ordinary_fold_tip_has_no_slit() {
        let (am, pos) = sheet_and_roof(0.6, 1.0);
        let mut a = analyze(&am, &pos).unwrap();
        assert!(a.paths.iter().any(|p| p.kind == PathKind::BoundaryBoundary));
        assert!(oracle(&am, &pos, false).is_empty());
        assert!(ridge_vertices(&am, &a).is_empty());
        let before = a.coloring.clone();
        assert_eq!(color_slits(&am, &mut a), 0);
        assert_eq!(a.coloring, before);
    }
}
