//! Global intersection analysis: brute-force oracle, structural consistency, kinds of the
//! procedural scenes, inside regions against geometry, colouring rules, determinism.

mod common;

use common::*;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use untangle::analysis::{analyze, report::Report, AnalysisMesh, ObjectKind, PathKind, Region};
use untangle::geom::{Vec2, Vec3};
use untangle::mesh::Mesh;
use untangle::scenes::{self, handkerchief, rudimentary};

/// A handkerchief with random large displacements (many self-intersections, all path kinds).
fn crumpled(seed: u64, n: usize, amp: f64) -> Mesh {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut m = handkerchief("crumpled", n, n, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
    for p in &mut m.positions {
        *p += Vec3::new(
            rng.random_range(-amp..amp),
            rng.random_range(-amp..amp),
            rng.random_range(-3.0 * amp..3.0 * amp),
        );
    }
    m
}

/// Disjoint random triangles in a unit box (a valid mesh whose edges are all boundary edges).
fn soup(seed: u64, n: usize) -> Mesh {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for t in 0..n as u32 {
        let c = Vec3::new(rng.random(), rng.random(), rng.random());
        for _ in 0..3 {
            positions.push(
                c + Vec3::new(
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                ),
            );
        }
        triangles.push([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    Mesh::new("soup", positions, triangles).expect("random triangles are not degenerate")
}

fn sorted_pairs(a: &untangle::analysis::Analysis) -> Vec<[u32; 2]> {
    let mut v: Vec<[u32; 2]> = a.segments.iter().map(|s| s.triangles).collect();
    v.sort();
    v
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn pairs_match_brute_force_on_crumpled_sheets(seed in 0u64..1_000_000, n in 3usize..9, amp in 0.02f64..0.3) {
        let m = crumpled(seed, n, amp);
        let (am, pos, a) = analyse_checked(&[m]);
        prop_assert_eq!(sorted_pairs(&a), brute_pairs(&am, &pos));
    }

    #[test]
    fn pairs_match_brute_force_on_triangle_soups(seed in 0u64..1_000_000, n in 2usize..40) {
        let m = soup(seed, n);
        let (am, pos, a) = analyse_checked(&[m]);
        prop_assert_eq!(sorted_pairs(&a), brute_pairs(&am, &pos));
        // Every path of a soup lies in one triangle's pieces and ends at B or I ends, or is closed.
        for p in &a.paths {
            prop_assert!(p.closed || p.ends.is_some());
        }
    }

    /// Ties everywhere: vertices on a coarse integer lattice (coplanar and collinear configurations
    /// abound); the perturbation rule must still give a consistent structure and the brute force
    /// must agree.
    #[test]
    fn lattice_meshes_with_ties_are_consistent(seed in 0u64..1_000_000) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut m = handkerchief("lattice", 4, 4, 4.0, 4.0, |p| Vec3::new(p.x.round(), p.y.round(), 0.0));
        for p in &mut m.positions {
            *p = Vec3::new(p.x + rng.random_range(-1i32..=1) as f64, p.y + rng.random_range(-1i32..=1) as f64, rng.random_range(-1i32..=1) as f64);
        }
        if m.validate().is_err() {
            return Ok(()); // a lattice draw with a collinear triangle is invalid input, not a case
        }
        let (am, pos, a) = analyse_checked(&[m]);
        prop_assert_eq!(sorted_pairs(&a), brute_pairs(&am, &pos));
    }
}

#[test]
fn exploded_handkerchiefs_match_brute_force_and_have_no_open_paths() {
    for seed in 0..6 {
        let s = scenes::exploded::exploded(seed, 14);
        let (am, pos, a) = analyse_checked(&s.meshes);
        assert_eq!(sorted_pairs(&a), brute_pairs(&am, &pos), "seed {seed}");
        assert!(
            a.paths.iter().all(|p| p.closed),
            "no BLI or boundary paths (seed {seed})"
        );
        // The paper's scene: 163 red triangles of 388, ~3,900 intersecting pairs.
        let red_t = a.coloring.num_red_triangles();
        assert!(
            (120..=260).contains(&red_t),
            "seed {seed}: {red_t} red triangles"
        );
        assert!(
            a.segments.len() > 1000,
            "seed {seed}: {} pairs",
            a.segments.len()
        );
    }
}

#[test]
fn rudimentary_scenes_yield_exactly_their_kind() {
    let cases = [
        (
            scenes::closed(16),
            "CLOSED",
            [PathKind::Closed, PathKind::Closed],
        ),
        (
            rudimentary::bb_ii(16),
            "BBII",
            [PathKind::BoundaryBoundary, PathKind::InsideInside],
        ),
        (
            rudimentary::bi_bi(16),
            "BIBI",
            [PathKind::BoundaryInside, PathKind::BoundaryInside],
        ),
        (
            rudimentary::cross(2),
            "CROSS",
            [PathKind::BoundaryBoundary, PathKind::InsideInside],
        ),
        (
            rudimentary::eight(2),
            "EIGHT",
            [PathKind::Closed, PathKind::Closed],
        ),
    ];
    for (scene, kind, paths) in cases {
        let (_, _, a) = analyse_checked(&scene.meshes);
        assert_eq!(kinds(&a), vec![(kind.to_string(), 1)], "{}", scene.name);
        let mut got: Vec<PathKind> = a.paths.iter().map(|p| p.kind).collect();
        got.sort();
        let mut want = paths.to_vec();
        want.sort();
        assert_eq!(got, want, "{}", scene.name);
        assert_eq!(
            a.paths[0].corresponds_to, 1,
            "{}: the two paths correspond",
            scene.name
        );
    }
    for (scene, kind, pk) in [
        (rudimentary::loop_loop(2), "LL", PathKind::LoopLoop),
        (rudimentary::bli(2), "BLI", PathKind::BoundaryLoopInside),
    ] {
        let (_, _, a) = analyse_checked(&scene.meshes);
        assert_eq!(kinds(&a), vec![(kind.to_string(), 1)], "{}", scene.name);
        assert_eq!(a.paths.len(), 1);
        assert_eq!(a.paths[0].kind, pk);
        assert_eq!(a.paths[0].corresponds_to, 0, "{kind} corresponds to itself");
        let lv = if kind == "LL" { 2 } else { 1 };
        assert_eq!(a.paths[0].loop_vertices().len(), lv);
    }
    // EIGHT and CROSS keep their origin on the split paths.
    let (_, _, a) = analyse_checked(&rudimentary::eight(1).meshes);
    assert!(a
        .paths
        .iter()
        .all(|p| p.split_from == Some(PathKind::Eight)));
    let (_, _, a) = analyse_checked(&rudimentary::cross(1).meshes);
    assert!(a
        .paths
        .iter()
        .all(|p| p.split_from == Some(PathKind::Cross)));
}

#[test]
fn every_scene_has_a_valid_rest_shape() {
    let mut all = vec![
        scenes::closed(8),
        rudimentary::bb_ii(8),
        rudimentary::bi_bi(8),
        scenes::exploded::exploded(0, 14),
        scenes::folded::folded(20, 2),
        scenes::garment::skirt(16, 2),
    ];
    for lv in 0..3 {
        all.extend([
            rudimentary::cross(lv),
            rudimentary::eight(lv),
            rudimentary::loop_loop(lv),
            rudimentary::bli(lv),
        ]);
    }
    for s in all {
        for m in &s.meshes {
            m.validate().unwrap();
            let uv = m.uv.as_ref().expect("scenes carry their rest shape as uv");
            for t in &uv.triangles {
                let [a, b, c] = t.map(|i| uv.coords[i as usize]);
                assert!(
                    untangle::geom::cross2(&a, &b, &c) > 0.0,
                    "{}: uv triangle inverted",
                    s.name
                );
            }
        }
    }
}

#[test]
fn skirt_has_two_sewn_panels_and_one_closed_tanglement_per_dent() {
    for (n, dents) in [(16, 1), (32, 3)] {
        let s = scenes::garment::skirt(n, dents);
        let g = untangle::mesh::Garment::new(s.meshes[0].clone()).unwrap();
        assert_eq!(g.num_panels, 2);
        assert_eq!(g.num_seam_vertices(), 2 * (n / 2 + 1), "two side seams");
        let (_, _, a) = analyse_checked(&s.meshes);
        assert_eq!(kinds(&a), vec![("CLOSED".to_string(), dents)]);
    }
}

#[test]
fn folded_sheet_has_one_closed_tanglement_per_dent() {
    for dents in [1, 4, 9] {
        let s = scenes::folded::folded(60, dents);
        let (_, _, a) = analyse_checked(&s.meshes);
        assert_eq!(kinds(&a), vec![("CLOSED".to_string(), dents)]);
        // Every path separates the sheet; the dent side (top layer) and the pierced disc
        // (bottom layer) are the inside regions.
        assert!(a.regions.iter().all(|r| matches!(r, Region::Inside(_))));
    }
}

/// Piecewise-linear height of a sheet that is a graph over xy, at (x, y); None outside.
fn height_at(m: &Mesh, x: f64, y: f64) -> Option<f64> {
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        let (pa, pb, pc) = (
            Vec2::new(a.x, a.y),
            Vec2::new(b.x, b.y),
            Vec2::new(c.x, c.y),
        );
        let q = Vec2::new(x, y);
        let area = untangle::geom::cross2(&pa, &pb, &pc);
        let l0 = untangle::geom::cross2(&q, &pb, &pc) / area;
        let l1 = untangle::geom::cross2(&pa, &q, &pc) / area;
        let l2 = 1.0 - l0 - l1;
        if l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0 {
            return Some(l0 * a.z + l1 * b.z + l2 * c.z);
        }
    }
    None
}

#[test]
fn inside_regions_match_the_geometry_of_the_closed_scene() {
    // B's dent pokes down through A. Inside on B: B's vertices below A. Inside on A: A's
    // vertices above B. Both sheets are graphs over xy, so the oracle is a height comparison.
    let s = scenes::closed(20);
    let (a_mesh, b_mesh) = (&s.meshes[0], &s.meshes[1]);
    let (am, _, a) = analyse_checked(&s.meshes);
    let nb0 = am.objects[1].vertices.start;
    let mut want: Vec<u32> = Vec::new();
    for (i, p) in a_mesh.positions.iter().enumerate() {
        if let Some(hb) = height_at(b_mesh, p.x, p.y) {
            if hb < p.z {
                want.push(i as u32);
            }
        }
    }
    for (i, p) in b_mesh.positions.iter().enumerate() {
        if let Some(ha) = height_at(a_mesh, p.x, p.y) {
            if p.z < ha {
                want.push(nb0 + i as u32);
            }
        }
    }
    want.sort();
    let got: Vec<u32> = (0..am.num_vertices() as u32)
        .filter(|&v| a.coloring.red_vertex[v as usize])
        .collect();
    assert!(!want.is_empty());
    assert_eq!(got, want);
    // Out-most red vertices: red with a green neighbour (checked against the definition
    // evaluated from the oracle set).
    let topo = &am.topology;
    let outmost: Vec<u32> = want
        .iter()
        .copied()
        .filter(|&v| {
            topo.vertex_neighbors
                .row(v as usize)
                .iter()
                .any(|w| !want.contains(w))
        })
        .collect();
    assert_eq!(a.coloring.outmost_red, outmost);
    assert!(
        outmost.len() < want.len(),
        "the dent's tip is red but not out-most"
    );
}

/// Fig. 2a / 2c: a vertex poking through a triangle. Only that vertex is red; its fan is red;
/// the pierced triangle is red although its vertices are green; its edges stay green.
#[test]
fn colouring_of_a_vertex_triangle_tanglement() {
    // Sheet A: one big triangle x0 x1 x2 in z = 0.
    let a = Mesh::new(
        "A",
        vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.5, -1.0, 0.0),
            Vec3::new(0.0, 1.5, 0.0),
        ],
        vec![[0, 1, 2]],
    )
    .unwrap();
    // Sheet B: a hexagonal fan around x3, which is pushed below A; the ring stays above.
    let mut pos = vec![Vec3::new(0.05, 0.03, -0.3)];
    for k in 0..6 {
        let t = k as f64 * std::f64::consts::PI / 3.0 + 0.1;
        pos.push(Vec3::new(0.5 * t.cos(), 0.5 * t.sin(), 0.2));
    }
    let tris: Vec<[u32; 3]> = (0..6).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
    let b = Mesh::new("B", pos, tris).unwrap();
    let (am, _, a) = analyse_checked(&[a, b]);
    assert_eq!(kinds(&a), vec![("CLOSED".to_string(), 1)]);
    let x3 = 3u32; // first vertex of B
    let red: Vec<u32> = (0..am.num_vertices() as u32)
        .filter(|&v| a.coloring.red_vertex[v as usize])
        .collect();
    assert_eq!(red, vec![x3]);
    assert_eq!(a.coloring.outmost_red, vec![x3]);
    let red_t: Vec<u32> = (0..am.triangles.len() as u32)
        .filter(|&t| a.coloring.red_triangle[t as usize])
        .collect();
    assert_eq!(
        red_t,
        (0..7).collect::<Vec<_>>(),
        "the pierced triangle and the whole fan"
    );
    for (e, ed) in am.topology.edges.iter().enumerate() {
        let expect = ed.contains(&x3);
        assert_eq!(a.coloring.red_edge[e], expect, "edge {ed:?}");
    }
    assert!(a.coloring.red_star.is_empty());
}

/// Fig. 2b and the BI/BI case: all vertices green, penetrating edges red, and the red*
/// triangles are exactly those with one red edge.
#[test]
fn colouring_of_edge_edge_tanglements_gives_red_star_triangles() {
    let (am, _, a) = analyse_checked(&rudimentary::bi_bi(12).meshes);
    assert_eq!(a.coloring.num_red_vertices(), 0);
    let mut penetrating: Vec<u32> = a.crossings.iter().map(|c| c.edge).collect();
    penetrating.sort();
    penetrating.dedup();
    let red_e: Vec<u32> = (0..am.topology.num_edges() as u32)
        .filter(|&e| a.coloring.red_edge[e as usize])
        .collect();
    assert_eq!(red_e, penetrating);
    let star: Vec<u32> = (0..am.triangles.len() as u32)
        .filter(|&t| {
            am.topology.triangle_edges[t as usize]
                .iter()
                .filter(|&&e| penetrating.contains(&e))
                .count()
                == 1
        })
        .collect();
    assert_eq!(a.coloring.red_star, star);
    assert!(!star.is_empty());
}

#[test]
fn obstacles_are_analysed_against_cloth_only() {
    // The closed scene with A as an obstacle: same pairs; A's own intersections (none) ignored,
    // and obstacle paths do not colour the cloth.
    let s = scenes::closed(12);
    let parts = [
        (&s.meshes[0], ObjectKind::Obstacle),
        (&s.meshes[1], ObjectKind::Cloth),
    ];
    let (am, pos) = AnalysisMesh::new(&parts).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let (_, _, b) = run(&s.meshes);
    assert_eq!(sorted_pairs(&a), sorted_pairs(&b));
    let body = &am.objects[0].vertices;
    assert!(body.clone().all(|v| !a.coloring.red_vertex[v as usize]));
    let report = Report::new(&am, &pos, &a);
    assert_eq!(report.pairs_by_objects[0].relation, "cloth-obstacle");
}

#[test]
fn report_is_identical_for_one_and_two_threads() {
    // The paper-size ball, one that takes the paths of two ranges of chains only (from 16,384
    // steps: n = 20 has 28k), and one dense enough that two threads take the parallel paths of
    // every phase (the kernel over the listed pairs; the linking in two halves, from 65,536
    // crossings: n = 40 has 225k intersecting pairs).
    for (seed, n) in [(3, 14), (0, 20), (0, 40)] {
        let s = scenes::exploded::exploded(seed, n);
        let (am, pos) = AnalysisMesh::single(&s.meshes[0]).unwrap();
        let run = |threads: usize| {
            common::with_threads(threads, || {
                let a = analyze(&am, &pos).unwrap();
                let mut r = Report::new(&am, &pos, &a);
                r.timing_ms = Default::default();
                let rest = format!(
                    "{:?}",
                    (
                        &a.segments,
                        &a.segments_of_crossing,
                        &a.paths,
                        &a.tanglements,
                        &a.regions
                    )
                );
                (r, a.coloring, a.crossings, rest)
            })
        };
        let (r1, c1, x1, rest1) = run(1);
        let (r2, c2, x2, rest2) = run(2);
        assert_eq!(r1, r2);
        assert_eq!(c1, c2);
        assert_eq!(x1, x2);
        assert!(
            rest1 == rest2,
            "segments, paths, tanglements, regions differ"
        );
        assert!(r1.intersecting_triangle_pairs > 2000);
    }
}

/// The components of the mesh's vertex graph without the `removed` vertices and the `cut` edges
/// (breadth-first search; the oracle of the flood fills).
fn components(am: &AnalysisMesh, removed: &[u32], cut: &[u32]) -> Vec<Vec<u32>> {
    let topo = &am.topology;
    let n = am.num_vertices();
    let mut comp = vec![usize::MAX; n];
    let mut out: Vec<Vec<u32>> = Vec::new();
    for s in 0..n as u32 {
        if comp[s as usize] != usize::MAX || removed.contains(&s) {
            continue;
        }
        let id = out.len();
        let mut queue = vec![s];
        comp[s as usize] = id;
        let mut i = 0;
        while i < queue.len() {
            let v = queue[i];
            i += 1;
            for (&w, &e) in topo
                .vertex_neighbors
                .row(v as usize)
                .iter()
                .zip(topo.vertex_edges.row(v as usize))
            {
                if comp[w as usize] == usize::MAX && !removed.contains(&w) && !cut.contains(&e) {
                    comp[w as usize] = id;
                    queue.push(w);
                }
            }
        }
        queue.sort_unstable();
        out.push(queue);
    }
    out
}

/// A BLI path whose loop vertex is on the boundary (the fan of `rudimentary::bli`) separates its
/// mesh along the half that ends on the boundary: its inside region is the smaller side, as for
/// a BB path — checked against the components of the cut graph — and it holds the dipping
/// wedge's tip (core vertex 5), the part that went through.
#[test]
fn bli_paths_with_a_boundary_loop_vertex_get_the_smaller_side() {
    for lv in 1..4 {
        let s = rudimentary::bli(lv);
        let (am, pos) = AnalysisMesh::single(&s.meshes[0]).unwrap();
        let a = analyze(&am, &pos).unwrap();
        assert_eq!(a.paths.len(), 1);
        let p = &a.paths[0];
        assert_eq!(p.kind, PathKind::BoundaryLoopInside);
        assert!(p
            .loop_vertices()
            .iter()
            .all(|&v| am.topology.boundary_vertex[v as usize]));
        let Region::Inside(inside) = &a.regions[0] else {
            panic!("level {lv}: region expected, got {:?}", a.regions[0]);
        };
        let mut comps = components(&am, p.loop_vertices(), p.cut_edges());
        assert_eq!(comps.len(), 2, "level {lv}: the boundary half separates");
        comps.sort_by_key(|c| c.len());
        assert_eq!(inside, &comps[0], "level {lv}");
        assert!(inside.contains(&5), "level {lv}: the dipping tip is inside");
    }
}

/// BLI paths whose loop vertex is interior separate nothing; they get an inside region by
/// Wicke's cone heuristic: a geodesic disc around the loop vertex reaching the nearer end of
/// the path, split by the path.
#[test]
fn bli_paths_get_a_cone_region_near_their_loop_vertex() {
    use untangle::analysis::{analyze_with, Options};
    for lv in 1..4 {
        let s = rudimentary::bli_interior(lv);
        let (am, pos) = AnalysisMesh::single(&s.meshes[0]).unwrap();
        let plain = analyze(&am, &pos).unwrap();
        assert_eq!(plain.paths.len(), 1, "level {lv}");
        assert_eq!(plain.paths[0].kind, PathKind::BoundaryLoopInside);
        assert_eq!(plain.paths[0].loop_vertices(), vec![0], "level {lv}");
        assert!(!am.topology.boundary_vertex[0]);
        assert_eq!(
            components(&am, &[0], plain.paths[0].cut_edges()).len(),
            1,
            "level {lv}: an interior BLI separates nothing"
        );
        assert_eq!(
            plain.coloring.num_red_vertices(),
            0,
            "BLI does not colour by default"
        );
        let Region::Inside(inside) = &plain.regions[0] else {
            panic!(
                "level {lv}: BLI cone region expected, got {:?}",
                plain.regions[0]
            );
        };
        let apex = plain.paths[0].loop_vertices()[0];
        assert!(!inside.is_empty() && !inside.contains(&apex));
        // The region is one side of the path: no inside vertex is joined to a disc vertex of
        // the other side except across a cut edge — checked through the definition: every
        // uncut edge from an inside vertex leads to an inside vertex, the apex, or out of the disc.
        let far = inside
            .iter()
            .map(|&v| (pos[v as usize] - pos[apex as usize]).norm())
            .fold(0.0, f64::max);
        let cut = plain.paths[0].cut_edges();
        let topo = &am.topology;
        for &v in inside {
            for (&w, &e) in topo
                .vertex_neighbors
                .row(v as usize)
                .iter()
                .zip(topo.vertex_edges.row(v as usize))
            {
                let near = (pos[w as usize] - pos[apex as usize]).norm() < 0.5 * far;
                if near && !cut.contains(&e) && w != apex {
                    assert!(
                        inside.contains(&w),
                        "level {lv}: region leaks from {v} to {w}"
                    );
                }
            }
        }
        let red = analyze_with(
            &am,
            &pos,
            &Options {
                bli_regions_red: true,
                winding_regions: false,
            },
        )
        .unwrap();
        let reds: Vec<u32> = (0..am.num_vertices() as u32)
            .filter(|&v| red.coloring.red_vertex[v as usize])
            .collect();
        assert_eq!(&reds, inside, "with the option the cone region is red");
        let report = Report::new(&am, &pos, &plain);
        let p = pos[apex as usize];
        assert_eq!(
            report.paths[0].location,
            [p.x, p.y, p.z],
            "reported at its loop vertex"
        );
    }
}

/// An annular strip winding 1.15 turns whose end dips through its beginning: every normal is
/// close to +z, so only the boundary test of the patch certificate can refuse to cull it. The
/// analysis must find exactly the brute-force pairs, for several resolutions.
#[test]
fn overlapping_spiral_strip_is_not_culled() {
    for (nt, nr) in [(60usize, 3usize), (120, 4), (240, 6)] {
        let turns = 1.15;
        let mut positions = Vec::new();
        for i in 0..=nt {
            let th = turns * std::f64::consts::TAU * i as f64 / nt as f64;
            // A gentle helix rising 0.02 over the first turn, then dipping below the start
            // (0.05) and rising back above it: the end crosses the start twice.
            let tau = std::f64::consts::TAU;
            let z = if th <= tau {
                0.05 + 0.02 * th / tau
            } else {
                let u = (th - tau) / (0.15 * tau);
                0.07 - 0.06 * (u * std::f64::consts::PI).sin()
            };
            for j in 0..=nr {
                let r = 1.0 + j as f64 / nr as f64;
                positions.push(Vec3::new(r * th.cos(), r * th.sin(), z + 0.001 * r));
            }
        }
        let id = |i: usize, j: usize| (i * (nr + 1) + j) as u32;
        let mut triangles = Vec::new();
        for i in 0..nt {
            for j in 0..nr {
                triangles.push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
                triangles.push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
            }
        }
        let m = Mesh::new("spiral", positions, triangles).unwrap();
        let (am, pos, a) = analyse_checked(&[m]);
        let brute = brute_pairs(&am, &pos);
        assert!(!brute.is_empty(), "the strip's end pierces its start");
        assert_eq!(sorted_pairs(&a), brute, "resolution {nt}x{nr}");
    }
}

/// The intersection curve of the closed scene lies on sheet A (the plane z = 0.0123 x), is closed
/// and continuous (consecutive points no farther apart than a triangle's diameter).
#[test]
fn intersection_curves_lie_on_both_sheets_and_are_continuous() {
    let s = scenes::closed(20);
    let (am, pos, a) = analyse_checked(&s.meshes);
    let curves = untangle::analysis::curves::tanglement_curves(&am, &pos, &a);
    assert_eq!(curves.len(), 1);
    let c = &curves[0];
    assert_eq!(
        c.len(),
        a.paths[0].pieces().len() + 2,
        "one point per piece, start repeated"
    );
    assert_eq!(c.first(), c.last());
    let cell = 1.0 / 20.0 * 2f64.sqrt() * 1.05;
    for w in c.windows(2) {
        assert!(
            (w[1] - w[0]).norm() <= cell,
            "continuous: {:?} -> {:?}",
            w[0],
            w[1]
        );
    }
    for p in c {
        assert!((p.z - 0.0123 * p.x).abs() < 1e-9, "on sheet A: {p:?}");
    }
}

/// A small mesh analysed from a thread outside rayon's pool runs on the calling thread (with a
/// helper worker in the crossing pass); the result equals the analysis run inside a pool of one
/// and of two threads (the oracle: the whole analysis handed to the pool).
#[test]
fn small_meshes_analysed_outside_the_pool_match_the_pool() {
    use untangle::analysis::Analysis;
    let same = |a: &Analysis, b: &Analysis| {
        assert_eq!(a.crossings, b.crossings);
        assert_eq!(a.segments, b.segments);
        assert_eq!(a.segments_of_crossing, b.segments_of_crossing);
        assert_eq!(a.paths, b.paths);
        assert_eq!(a.tanglements, b.tanglements);
        assert_eq!(a.regions, b.regions);
        assert_eq!(a.coloring, b.coloring);
    };
    assert!(rayon::current_thread_index().is_none(), "the test thread");
    for (seed, n) in [(0, 14), (1, 14), (2, 14), (3, 9), (0, 20)] {
        let s = untangle::scenes::exploded::exploded(seed, n);
        let (mesh, pos) = AnalysisMesh::single(&s.meshes[0]).expect("valid");
        let here = analyze(&mesh, &pos).expect("consistent");
        assert!(!here.segments.is_empty());
        for threads in [1, 2] {
            let inside =
                common::with_threads(threads, || analyze(&mesh, &pos).expect("consistent"));
            same(&here, &inside);
        }
    }
}
