//! Cha & Ko 2022 uv-space update on small hand-made fans: vertex pull, triangle shrinkage,
//! revoke, the triangle inversion test (Fig. 6), scheduling cases 1-3 (Fig. 9), seams (Fig. 12),
//! the no-TIT-passable fallback (Sec. 6.1), and property tests on random meshes and colourings.

use proptest::prelude::*;
use untangle::analysis::Coloring;
use untangle::geom::{cross2, Vec2, Vec3};
use untangle::mesh::{Garment, Mesh, UvLayer};
use untangle::methods::cha_ko::operations::UvMesh;
use untangle::methods::cha_ko::{
    ChaKo, EndReason, Fallback, OpKind, Params, SeamKind, StallReason,
};

// ---------------------------------------------------------------------------------------------
// Fixtures

/// A one-panel garment whose world positions are its uv (z = 0).
fn flat(uv: &[[f64; 2]], tris: &[[u32; 3]]) -> Garment {
    let coords: Vec<Vec2> = uv.iter().map(|p| Vec2::new(p[0], p[1])).collect();
    let positions = coords.iter().map(|p| Vec3::new(p.x, p.y, 0.0)).collect();
    with_uv(positions, tris, coords, tris.to_vec())
}

fn with_uv(
    positions: Vec<Vec3>,
    tris: &[[u32; 3]],
    coords: Vec<Vec2>,
    uv_tris: Vec<[u32; 3]>,
) -> Garment {
    Garment::new(Mesh {
        name: "t".into(),
        positions,
        triangles: tris.to_vec(),
        uv: Some(UvLayer {
            coords,
            triangles: uv_tris,
        }),
        groups: vec![],
        source: None,
    })
    .unwrap()
}

/// A closed fan: centre 0 at the origin, ring 1..=n.
fn fan(ring: &[[f64; 2]]) -> Garment {
    let mut uv = vec![[0.0, 0.0]];
    uv.extend_from_slice(ring);
    let n = ring.len() as u32;
    let tris: Vec<[u32; 3]> = (0..n).map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect();
    flat(&uv, &tris)
}

/// Sec. 3 colouring from red vertices, edges that penetrate a triangle (their triangles are then
/// intersecting, hence red) and further intersecting triangles.
fn coloring(g: &Garment, red: &[u32], red_edges: &[(u32, u32)], red_tris: &[u32]) -> Coloring {
    let topo = &g.topology;
    let n = g.mesh.positions.len();
    let mut red_vertex = vec![false; n];
    for &v in red {
        red_vertex[v as usize] = true;
    }
    let mut red_edge: Vec<bool> = topo
        .edges
        .iter()
        .map(|e| red_vertex[e[0] as usize] || red_vertex[e[1] as usize])
        .collect();
    let mut red_triangle: Vec<bool> = g
        .mesh
        .triangles
        .iter()
        .map(|t| t.iter().any(|&v| red_vertex[v as usize]))
        .collect();
    for &(a, b) in red_edges {
        let e = topo.edge_between(a, b).expect("edge");
        red_edge[e as usize] = true;
        for t in topo.edge_triangles[e as usize] {
            if t != u32::MAX {
                red_triangle[t as usize] = true;
            }
        }
    }
    for &t in red_tris {
        red_triangle[t as usize] = true;
    }
    let outmost_red = (0..n as u32)
        .filter(|&v| {
            red_vertex[v as usize]
                && topo
                    .vertex_neighbors
                    .row(v as usize)
                    .iter()
                    .any(|&w| !red_vertex[w as usize])
        })
        .collect();
    let red_star = (0..g.mesh.triangles.len() as u32)
        .filter(|&t| {
            g.mesh.triangles[t as usize]
                .iter()
                .all(|&v| !red_vertex[v as usize])
                && topo.triangle_edges[t as usize]
                    .iter()
                    .filter(|&&e| red_edge[e as usize])
                    .count()
                    == 1
        })
        .collect();
    Coloring {
        red_vertex,
        red_edge,
        red_triangle,
        outmost_red,
        red_star,
    }
}

fn green(g: &Garment) -> Coloring {
    coloring(g, &[], &[], &[])
}

fn params(gamma: f64) -> Params {
    Params {
        gamma,
        ..Params::default()
    }
}

fn step(ck: &mut ChaKo, col: &Coloring) -> untangle::methods::cha_ko::UvUpdateReport {
    let pos = ck.garment().mesh.positions.clone();
    let r = ck.update_uv_with_coloring(col, Some(&pos)).unwrap();
    assert!(
        ck.inverted_uv_triangles().is_empty(),
        "inverted uv triangles after step {}: {:?}",
        r.step,
        ck.inverted_uv_triangles()
    );
    r
}

/// The square fan: unit spokes, so every candidate has length exactly 1.
const SQUARE: [[f64; 2]; 4] = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]];

/// Fig. 6-like concave fan: the shortest candidate (vertex 1) inverts T(0, 2, 3) at the
/// extremity; vertex 2 is the next shortest and passes.
const CONCAVE: [[f64; 2]; 5] = [
    [1.0, 0.0],
    [-0.4, 0.96],
    [-2.2, 2.4],
    [-1.0, -1.0],
    [1.0, -1.0],
];

fn star(points: usize, outer: f64, inner: f64) -> Vec<[f64; 2]> {
    (0..2 * points)
        .map(|i| {
            let a = std::f64::consts::PI * i as f64 / points as f64;
            let r = if i % 2 == 0 { outer } else { inner };
            [r * a.cos(), r * a.sin()]
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Operations

#[test]
fn pull_after_n_steps_is_target_plus_gamma_power() {
    // gamma = 1/2 and dyadic coordinates: the expected values are exact.
    let g = fan(&SQUARE);
    let mut ck = ChaKo::new(&g, params(0.5)).unwrap();
    let col = coloring(&g, &[0], &[], &[]);
    let orig = ck.original_uv().to_vec();
    for n in 1..=8 {
        let r = step(&mut ck, &col);
        assert_eq!(
            (r.pulls_started, r.pulls_continued),
            if n == 1 { (1, 0) } else { (0, 1) }
        );
        // Ties in length are broken by the lowest index: target 1 = (1, 0).
        let s = 0.5f64.powi(n);
        assert_eq!(ck.current_uv()[0], Vec2::new(1.0 - s, 0.0), "n = {n}");
        // Subject fan re-meshing: only the subject moves.
        assert_eq!(&ck.current_uv()[1..], &orig[1..]);
    }
    let op = ck.operations().next().unwrap();
    assert_eq!((op.kind, op.target, op.level), (OpKind::Pull, 1, 8));
}

#[test]
fn pull_with_gamma_08_matches_the_closed_form() {
    let g = fan(&CONCAVE);
    let mut ck = ChaKo::new(
        &g,
        Params {
            max_level: 30,
            ..Params::default()
        },
    )
    .unwrap();
    let col = coloring(&g, &[0], &[], &[]);
    let o = ck.original_uv()[0];
    for n in 1..=20 {
        step(&mut ck, &col);
        let t = ck.original_uv()[2];
        let want = t + (o - t) * 0.8f64.powi(n);
        assert!((ck.current_uv()[0] - want).norm() < 1e-15, "n = {n}");
        // Edge length scaled by gamma^n.
        let len = (ck.current_uv()[0] - t).norm();
        assert!((len - 0.8f64.powi(n) * (o - t).norm()).abs() < 1e-14);
    }
}

/// A fan around the boundary edge (0, 1): T(0, 1, 2) is red* with the red edge (0, 1).
fn shrink_fixture() -> Garment {
    flat(
        &[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [1.5, 1.0], [-0.5, 1.0]],
        &[[0, 1, 2], [1, 3, 2], [0, 2, 4]],
    )
}

#[test]
fn shrink_moves_both_red_edge_ends_toward_the_third_vertex() {
    let g = shrink_fixture();
    let col = coloring(&g, &[], &[(0, 1)], &[]);
    assert_eq!(col.red_star, vec![0]);
    let mut ck = ChaKo::new(&g, params(0.5)).unwrap();
    let orig = ck.original_uv().to_vec();
    for n in 1..=6 {
        let r = step(&mut ck, &col);
        assert_eq!(r.shrinks_started + r.shrinks_continued, 1);
        let s = 0.5f64.powi(n);
        let t = orig[2];
        assert_eq!(ck.current_uv()[0], t + (orig[0] - t) * s);
        assert_eq!(ck.current_uv()[1], t + (orig[1] - t) * s);
        assert_eq!(&ck.current_uv()[2..], &orig[2..]);
        // Both subject edges scaled by gamma^n, the red edge too.
        let e = (ck.current_uv()[0] - ck.current_uv()[1]).norm();
        assert_eq!(e, s);
    }
    let op = ck.operations().next().unwrap();
    assert_eq!(
        (op.kind, op.target, &op.subjects[..]),
        (OpKind::Shrink, 2, &[0, 1][..])
    );
}

#[test]
fn revoke_returns_exactly_to_the_original_uv() {
    let g = fan(&CONCAVE);
    // The paper's rate (Sec. 5.1.1) also once clean (by default a clean garment is restored at
    // once: `clean_colouring_revokes_at_the_clean_rate`).
    let p = Params {
        revoke_levels_when_clean: 0,
        ..Params::default()
    };
    let mut ck = ChaKo::new(&g, p).unwrap();
    let red = coloring(&g, &[0], &[], &[]);
    for _ in 0..7 {
        step(&mut ck, &red);
    }
    let all_green = green(&g);
    let (o, t) = (ck.original_uv()[0], ck.original_uv()[2]);
    for k in (0..7).rev() {
        let r = step(&mut ck, &all_green);
        assert_eq!(r.revoked_levels, 1);
        let want = t + (o - t) * 0.8f64.powi(k);
        assert!((ck.current_uv()[0] - want).norm() < 1e-15);
    }
    assert!(ck.is_restored());
    assert_eq!(ck.current_uv(), ck.original_uv(), "bit for bit");
    let rec = &ck.finesse_log()[0];
    assert_eq!(rec.end, Some(EndReason::Finished));
    assert_eq!(
        (rec.start_step, rec.end_step, rec.restored_step),
        (0, Some(7), Some(13))
    );
    assert_eq!(rec.steps(), Some(7));
    assert_eq!(rec.max_level, 7);
    assert_eq!(rec.seam, SeamKind::OffSeam);
}

// ---------------------------------------------------------------------------------------------
// Triangle inversion test

/// Dense oracle: does moving the copies along their paths invert a fan triangle at any of
/// `samples` scales in (0, 1]? Exact orientation on the computed positions.
fn inverts(g: &Garment, copies: &[(u32, Vec2)], samples: usize) -> bool {
    let uv = g.uv();
    (1..=samples).any(|k| {
        let s = k as f64 / samples as f64;
        let mut cur = uv.coords.clone();
        for &(c, a) in copies {
            cur[c as usize] = a + (uv.coords[c as usize] - a) * s;
        }
        uv.triangles.iter().any(|t| {
            let [a, b, c] = t.map(|i| cur[i as usize]);
            cross2(&a, &b, &c) < 0.0
        })
    })
}

#[test]
fn tit_rejects_the_target_that_inverts_a_triangle_fig6() {
    let g = fan(&CONCAVE);
    let mesh = UvMesh::new(g.clone(), Params::default().min_scale());
    let orig = g.uv().coords.clone();
    for t in 1..=5u32 {
        let p = mesh.pull(&orig, 0, t);
        let pass = mesh.test(&orig, &p).pass;
        let oracle = inverts(&g, &[(0, orig[t as usize])], 4000);
        assert_eq!(pass, !oracle, "target {t}");
    }
    assert!(!mesh.test(&orig, &mesh.pull(&orig, 0, 1)).pass);
    assert!(mesh.test(&orig, &mesh.pull(&orig, 0, 2)).pass);
    // The shortest candidate (1) fails; the scheduler takes the next one (2).
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &coloring(&g, &[0], &[], &[]));
    assert_eq!((r.pulls_started, r.tit_rejected), (1, 1));
    assert_eq!(ck.operations().next().unwrap().target, 2);
    assert!(r.fallbacks.is_empty() && !r.no_tit_passable_fan);
}

#[test]
fn convex_fan_passes_for_every_target() {
    let ring: Vec<[f64; 2]> = (0..7)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * i as f64 / 7.0 + 0.1;
            [a.cos() * (1.0 + 0.1 * i as f64), a.sin()]
        })
        .collect();
    let g = fan(&ring);
    let mesh = UvMesh::new(g.clone(), Params::default().min_scale());
    let orig = g.uv().coords.clone();
    for t in 1..=7 {
        assert!(mesh.test(&orig, &mesh.pull(&orig, 0, t)).pass);
    }
}

/// A fan around the red edge (0, 1) of red* triangle T(0, 1, 2) whose far side around vertex 0
/// is concave: the long edge (4, 5) grazes the way from 0 to the target 2, so a shrink toward 2
/// inverts T(0, 4, 5) when vertex 5 is high enough (`y5 > -0.814`). With `closed`, T(0, 6, 1)
/// closes the fan and is red* too (target 6).
fn shrink_fan(y5: f64, closed: bool) -> Garment {
    let mut tris = vec![[0, 1, 2], [1, 3, 2], [0, 2, 4], [0, 4, 5], [0, 5, 6]];
    if closed {
        tris.push([0, 6, 1]);
    }
    flat(
        &[
            [0.0, 0.0],
            [1.0, 0.0],
            [0.5, 1.0],
            [1.5, 0.8],
            [-0.664, 0.107],
            [-1.864, y5],
            [0.5, -1.0],
        ],
        &tris,
    )
}

#[test]
fn shrink_tit_agrees_with_dense_sampling() {
    let (mut passes, mut fails) = (0, 0);
    for k in 0..=40 {
        let y = -1.2 + 0.035 * k as f64;
        let g = shrink_fan(y, false);
        let mesh = UvMesh::new(g.clone(), Params::default().min_scale());
        let orig = g.uv().coords.clone();
        let p = mesh.shrink(&orig, 0, 2, 0, 1);
        let pass = mesh.test(&orig, &p).pass;
        let oracle = inverts(&g, &[(0, orig[2]), (1, orig[2])], 4000);
        assert_eq!(pass, !oracle, "vertex 5 at y = {y}");
        assert_eq!(pass, y < -0.814, "analytic threshold, y = {y}");
        if pass {
            passes += 1;
        } else {
            fails += 1;
        }
    }
    assert!(passes > 5 && fails > 5);
}

#[test]
fn failed_shrink_yields_to_the_next_red_star_triangle() {
    let g = shrink_fan(-0.133, true);
    let col = coloring(&g, &[], &[(0, 1)], &[]);
    assert_eq!(col.red_star, vec![0, 5]);
    let mesh = UvMesh::new(g.clone(), Params::default().min_scale());
    let orig = g.uv().coords.clone();
    assert!(!mesh.test(&orig, &mesh.shrink(&orig, 0, 2, 0, 1)).pass);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &col);
    assert_eq!((r.shrinks_started, r.tit_rejected), (1, 1));
    assert!(r.fallbacks.is_empty());
    let op = ck.operations().next().unwrap();
    assert_eq!((op.triangle, op.target), (5, 6));
}

#[test]
fn shrink_that_fails_the_test_is_shortened() {
    let g = shrink_fan(-0.133, false);
    let col = coloring(&g, &[], &[(0, 1)], &[]);
    assert_eq!(col.red_star, vec![0]);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &col);
    assert!(r.no_tit_passable_fan);
    assert_eq!(r.shrinks_started, 1);
    // The grazing edge crosses the way to the target at about 27% of it: half and a quarter
    // are tried, a quarter passes.
    assert_eq!(
        r.fallbacks[0].fallback,
        Fallback::Shortened { lambda: 0.25 }
    );
    for _ in 0..40 {
        step(&mut ck, &col);
    }
    let op = ck.operations().next().unwrap();
    let want = ck.original_uv()[2] * 0.25;
    assert!((op.copies[0].anchor - want).norm() < 1e-15);
}

// ---------------------------------------------------------------------------------------------
// No TIT-passable fan (Sec. 6.1)

#[test]
fn star_fan_has_no_passable_target_and_falls_back_to_the_kernel() {
    let g = fan(&star(5, 2.0, 0.5));
    let col = coloring(&g, &[0], &[], &[]);
    let mesh = UvMesh::new(g.clone(), Params::default().min_scale());
    let orig = g.uv().coords.clone();
    for t in 1..=10 {
        assert!(
            !mesh.test(&orig, &mesh.pull(&orig, 0, t)).pass,
            "target {t}"
        );
    }
    // Fallback off: the paper's method halts here; we report the vertex and its location.
    let mut off = ChaKo::new(
        &g,
        Params {
            fallback: false,
            ..Params::default()
        },
    )
    .unwrap();
    let r = step(&mut off, &col);
    assert!(r.no_tit_passable_fan);
    assert_eq!(r.tit_rejected, 10);
    assert_eq!(r.stalls.len(), 1);
    assert_eq!(r.stalls[0].reason, StallReason::NoTitPassableFan);
    assert_eq!(r.stalls[0].vertex, Some(0));
    assert_eq!(r.stalls[0].position, Some([0.0, 0.0, 0.0]));
    assert!(!r.uv_changed && off.is_restored());
    // Fallback on: pulled toward the kernel point nearest to a target, never inverting.
    let mut on = ChaKo::new(
        &g,
        Params {
            hold_steps: 0,
            ..Params::default()
        },
    )
    .unwrap();
    let r = step(&mut on, &col);
    assert!(r.no_tit_passable_fan, "the regular test still failed");
    assert_eq!(r.fallbacks.len(), 1);
    assert_eq!(r.fallbacks[0].fallback, Fallback::KernelTarget);
    let op = on.operations().next().unwrap().clone();
    for _ in 0..40 {
        step(&mut on, &col);
    }
    let t = orig[op.target as usize];
    let d0 = (orig[0] - t).norm();
    let d = (on.current_uv()[0] - t).norm();
    assert!(d < d0 * 0.95, "moved toward the target: {d} vs {d0}");
    // Independent check of the kernel point: every fan triangle is positive with the subject at
    // the anchor.
    let a = op.copies[0].anchor;
    for tri in &g.uv().triangles {
        let [p, q, r] = tri.map(|i| if i == 0 { a } else { orig[i as usize] });
        assert!(cross2(&p, &q, &r) > 0.0);
    }
    // It saturates (the kernel does not reach the target) and says so once.
    let log = &on.finesse_log()[0];
    assert!(log.saturated_step.is_some());
    assert_eq!(log.fallback, Some(Fallback::KernelTarget));
}

#[test]
fn saturation_is_reported_once_with_its_location() {
    let g = fan(&SQUARE);
    let mut ck = ChaKo::new(
        &g,
        Params {
            max_level: 5,
            ..Params::default()
        },
    )
    .unwrap();
    let col = coloring(&g, &[0], &[], &[]);
    let mut saturated_reports = 0;
    for n in 0..12 {
        let r = step(&mut ck, &col);
        saturated_reports += r
            .stalls
            .iter()
            .filter(|s| s.reason == StallReason::Saturated)
            .count();
        assert_eq!(r.saturated_ops, usize::from(n >= 4));
    }
    assert_eq!(saturated_reports, 1);
    assert_eq!(ck.operations().next().unwrap().level, 5);
}

#[test]
fn saturated_operation_is_abandoned_and_another_target_tried() {
    let g = fan(&SQUARE);
    let params = Params {
        max_level: 3,
        hold_steps: 2,
        ..Params::default()
    };
    let mut ck = ChaKo::new(&g, params).unwrap();
    let col = coloring(&g, &[0], &[], &[]);
    let reports: Vec<_> = (0..8).map(|_| step(&mut ck, &col)).collect();
    assert_eq!(ck.finesse_log()[0].saturated_step, Some(2));
    assert_eq!(reports[4].abandoned, 1);
    assert_eq!(reports[4].stalls[0].reason, StallReason::Abandoned);
    assert_eq!(ck.finesse_log()[0].end, Some(EndReason::Abandoned));
    assert_eq!(ck.finesse_log()[0].restored_step, Some(6));
    assert_eq!(reports[7].pulls_started, 1);
    assert_eq!(reports[7].blocked_tabu, 1);
    let op = ck.operations().next().unwrap();
    assert_eq!(op.target, 2, "target 1 is barred");
}

#[test]
fn held_operation_that_stopped_closing_in_is_abandoned_early() {
    let g = fan(&SQUARE);
    let params = Params {
        max_level: 3,
        hold_steps: 10,
        hold_progress_steps: 2,
        ..Params::default()
    };
    let col = coloring(&g, &[0], &[], &[]);
    // `approach`: the world distance from the subject (vertex 0) to every ring vertex shrinks by
    // 10 % per step, or stays (0.0).
    let abandoned_at = |approach: f64| {
        let mut ck = ChaKo::new(&g, params.clone()).unwrap();
        let mut pos = g.mesh.positions.clone();
        for s in 0..20 {
            let r = ck.update_uv_with_coloring(&col, Some(&pos)).unwrap();
            if r.abandoned > 0 {
                assert_eq!(ck.finesse_log()[0].end, Some(EndReason::Abandoned));
                return s;
            }
            for p in pos.iter_mut().skip(1) {
                *p *= 1.0 - approach;
            }
        }
        panic!("never abandoned");
    };
    // Saturated at step 2; its distance is first seen at step 3, and two steps without a new
    // minimum end it at step 5 instead of 2 + hold_steps = 12.
    assert_eq!(abandoned_at(0.0), 5);
    assert_eq!(abandoned_at(0.1), 12);
    // Off (0): the full hold, whatever the positions.
    let off = Params {
        hold_progress_steps: 0,
        ..params.clone()
    };
    let mut ck = ChaKo::new(&g, off).unwrap();
    let steps: Vec<usize> = (0..14).map(|_| step(&mut ck, &col).abandoned).collect();
    assert_eq!(steps.iter().position(|&a| a > 0), Some(12));
}

#[test]
fn nothing_to_operate_on_is_reported() {
    // An intersecting triangle but no red vertex and no red* triangle (e.g. a BLI path).
    let g = fan(&SQUARE);
    let col = coloring(&g, &[], &[], &[2]);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &col);
    assert_eq!(r.stalls.len(), 1);
    assert_eq!(r.stalls[0].reason, StallReason::NothingToOperateOn);
    assert_eq!(r.stalls[0].triangle, Some(2));
    assert!(r.stalls[0].position.is_some());
}

// ---------------------------------------------------------------------------------------------
// Scheduling (Alg. 2, Fig. 9)

fn grid(n: usize) -> Garment {
    let m =
        untangle::scenes::handkerchief("g", n, n, n as f64, n as f64, |p| Vec3::new(p.x, p.y, 0.0));
    Garment::new(m).unwrap()
}

fn gid(n: usize, i: usize, j: usize) -> u32 {
    (j * (n + 1) + i) as u32
}

#[test]
fn case1_adjacent_outmost_red_vertices_are_sequential() {
    let n = 4;
    let g = grid(n);
    let (a, b) = (gid(n, 2, 2), gid(n, 3, 2));
    assert!(g.topology.edge_between(a, b).is_some());
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let both = coloring(&g, &[a, b], &[], &[]);
    for s in 0..3 {
        let r = step(&mut ck, &both);
        assert_eq!(r.pulls_started + r.pulls_continued, 1, "step {s}");
        assert_eq!(r.blocked_fan, 1);
        assert_eq!(ck.operations().count(), 1);
        assert_eq!(ck.operations().next().unwrap().subjects, vec![a]);
    }
    // a escapes (turns green): it is revoked over 3 steps; b waits until a is back.
    let only_b = coloring(&g, &[b], &[], &[]);
    for s in 3..6 {
        let r = step(&mut ck, &only_b);
        assert_eq!(r.pulls_started, 0, "step {s}");
        assert_eq!(r.revoked_levels, 1);
    }
    let r = step(&mut ck, &only_b);
    assert_eq!(r.pulls_started, 1);
    assert_eq!(ck.operations().next().unwrap().subjects, vec![b]);
    let rec = &ck.finesse_log()[0];
    assert_eq!(
        (rec.end, rec.end_step, rec.restored_step),
        (Some(EndReason::Finished), Some(3), Some(5))
    );
}

#[test]
fn far_apart_pulls_run_simultaneously() {
    let n = 6;
    let g = grid(n);
    let col = coloring(&g, &[gid(n, 1, 1), gid(n, 5, 5)], &[], &[]);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &col);
    assert_eq!(r.pulls_started, 2);
}

#[test]
fn case2_adjacent_red_star_triangles_are_sequential() {
    let n = 4;
    let g = grid(n);
    let c = gid(n, 2, 2);
    // Two red edges at c whose far ends are not adjacent: four red* triangles sharing c.
    let (p, q) = (gid(n, 1, 2), gid(n, 3, 2));
    assert!(g.topology.edge_between(p, q).is_none());
    let col = coloring(&g, &[], &[(c, p), (c, q)], &[]);
    assert_eq!(col.red_star.len(), 4);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    for s in 0..4 {
        let r = step(&mut ck, &col);
        assert_eq!(r.shrinks_started + r.shrinks_continued, 1, "step {s}");
        assert_eq!(r.blocked_fan + r.blocked_subject, 3);
    }
    let first = ck.operations().next().unwrap().clone();
    assert_eq!(first.triangle, col.red_star[0]);
    // Its red edge turns green: revoked over 4 steps, then the next red* triangle starts.
    let e = first.subjects.clone();
    let rest: Vec<(u32, u32)> = [(c, p), (c, q)]
        .into_iter()
        .filter(|&(x, y)| !(e.contains(&x) && e.contains(&y)))
        .collect();
    let col2 = coloring(&g, &[], &rest, &[]);
    for _ in 0..4 {
        let r = step(&mut ck, &col2);
        assert_eq!(r.shrinks_started, 0);
    }
    let r = step(&mut ck, &col2);
    assert_eq!(r.shrinks_started, 1);
    assert_eq!(ck.finesse_log()[0].end, Some(EndReason::Finished));
}

#[test]
fn case3_red_star_goes_before_a_neighbouring_pull() {
    let n = 4;
    let g = grid(n);
    let x = gid(n, 2, 2);
    // A red edge (p, q) with both ends adjacent to x: T(x, p, q) is red (x is red), the
    // triangle across (p, q) is red*, and fan(x) contains p and q.
    let topo = &g.topology;
    let nb = topo.vertex_neighbors.row(x as usize);
    let (p, q) = nb
        .iter()
        .flat_map(|&p| nb.iter().map(move |&q| (p, q)))
        .find(|&(p, q)| p < q && topo.edge_between(p, q).is_some())
        .unwrap();
    let col = coloring(&g, &[x], &[(p, q)], &[]);
    assert_eq!(col.red_star.len(), 1);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &col);
    assert_eq!(
        (r.shrinks_started, r.pulls_started, r.blocked_fan),
        (1, 0, 1)
    );
    let r = step(&mut ck, &col);
    assert_eq!((r.shrinks_continued, r.pulls_started), (1, 0));
}

#[test]
fn pull_whose_target_turns_red_is_revoked_then_retargeted() {
    let g = fan(&SQUARE);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    for _ in 0..3 {
        step(&mut ck, &coloring(&g, &[0], &[], &[]));
    }
    assert_eq!(ck.operations().next().unwrap().target, 1);
    let col = coloring(&g, &[0, 1], &[], &[]);
    for _ in 0..3 {
        let r = step(&mut ck, &col);
        assert_eq!(r.pulls_started, 0);
    }
    assert!(ck.is_restored());
    let r = step(&mut ck, &col);
    assert_eq!(r.pulls_started, 1);
    let op = ck.operations().next().unwrap();
    assert_ne!(op.target, 1);
    assert_eq!(ck.finesse_log()[0].end, Some(EndReason::Superseded));
}

/// Pulls `a` (grid 6 x 6) for `levels` steps while `far` is red too (its pull runs alongside),
/// then returns the updater.
fn pulled(params: Params, a: u32, far: u32, levels: usize) -> (Garment, ChaKo) {
    let g = grid(6);
    let mut ck = ChaKo::new(&g, params).unwrap();
    let col = coloring(&g, &[a, far], &[], &[]);
    for _ in 0..levels {
        step(&mut ck, &col);
    }
    (g, ck)
}

/// Levels revoked per step for the operation whose subject is `v`, until it is restored.
fn revoke_trace(ck: &mut ChaKo, col: &Coloring, v: u32) -> Vec<u32> {
    let mut levels = Vec::new();
    loop {
        let level = ck
            .operations()
            .find(|o| o.subjects == vec![v])
            .map(|o| o.level);
        let Some(level) = level else { break };
        levels.push(level);
        step(ck, col);
        assert!(levels.len() < 50);
    }
    levels
}

#[test]
fn clean_colouring_revokes_at_the_clean_rate() {
    let n = 6;
    let (a, far) = (gid(n, 1, 1), gid(n, 5, 5));
    // The paper's rate throughout (clean rate 0: as `revoke_levels_per_step`): one level per
    // step.
    let one = Params {
        revoke_levels_when_clean: 0,
        ..Params::default()
    };
    let (g, mut ck) = pulled(one, a, far, 4);
    assert_eq!(revoke_trace(&mut ck, &green(&g), a), vec![4, 3, 2, 1]);
    assert_eq!(
        Params::default().revoke_levels_when_clean,
        0,
        "the paper's rate by default"
    );
    // Everything at once (200, above any level cap): an all-green garment (no red triangle:
    // nothing intersects) is restored in one step, exactly.
    let at_once = Params {
        revoke_levels_when_clean: 200,
        ..Params::default()
    };
    let (g, mut ck) = pulled(at_once.clone(), a, far, 4);
    assert_eq!(revoke_trace(&mut ck, &green(&g), a), vec![4]);
    assert!(ck.is_restored());
    assert_eq!(ck.current_uv(), ck.original_uv());
    // Not clean (`far` stays red): `a`'s finished pull is revoked one level per step.
    let (g, mut ck) = pulled(at_once, a, far, 4);
    let col = coloring(&g, &[far], &[], &[]);
    assert_eq!(revoke_trace(&mut ck, &col, a), vec![4, 3, 2, 1]);
    // A clean rate of 2.
    let two = Params {
        revoke_levels_when_clean: 2,
        ..Params::default()
    };
    let (g, mut ck) = pulled(two, a, far, 5);
    assert_eq!(revoke_trace(&mut ck, &green(&g), a), vec![5, 3, 1]);
}

#[test]
fn finished_operations_revoke_at_their_own_rate() {
    let n = 6;
    let (a, far) = (gid(n, 1, 1), gid(n, 5, 5));
    let p = Params {
        revoke_levels_finished: 2,
        ..Params::default()
    };
    // `a` turns green (finished) while `far` stays red: two levels per step.
    let (g, mut ck) = pulled(p.clone(), a, far, 5);
    let col = coloring(&g, &[far], &[], &[]);
    assert_eq!(revoke_trace(&mut ck, &col, a), vec![5, 3, 1]);
    assert_eq!(ck.finesse_log()[0].end, Some(EndReason::Finished));
    // Its target turns red instead (superseded): one level per step.
    let (g, mut ck) = pulled(p, a, far, 5);
    let t = ck
        .operations()
        .find(|o| o.subjects == vec![a])
        .unwrap()
        .target;
    let col = coloring(&g, &[a, t, far], &[], &[]);
    assert_eq!(revoke_trace(&mut ck, &col, a), vec![5, 4, 3, 2, 1]);
    assert_eq!(ck.finesse_log()[0].end, Some(EndReason::Superseded));
}

#[test]
fn fewest_neighbours_order_starts_more_pulls() {
    use untangle::methods::cha_ko::PullOrder;
    let n = 4;
    let g = grid(n);
    let topo = &g.topology;
    // b and two of its neighbours a, c that are not adjacent to each other, both numbered
    // after b: in index order b goes first and blocks both (Case 1).
    let (b, a, c) = (0..g.mesh.positions.len() as u32)
        .flat_map(|b| {
            let nb = topo.vertex_neighbors.row(b as usize).to_vec();
            let pairs: Vec<(u32, u32, u32)> = nb
                .iter()
                .flat_map(|&a| nb.iter().map(move |&c| (b, a, c)))
                .filter(|&(b, a, c)| b < a && a < c && topo.edge_between(a, c).is_none())
                .collect();
            pairs
        })
        .find(|&(b, _, _)| b > 0)
        .unwrap();
    let col = coloring(&g, &[a, b, c], &[], &[]);
    assert_eq!(col.outmost_red, {
        let mut v = vec![a, b, c];
        v.sort();
        v
    });
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &col);
    assert_eq!((r.pulls_started, r.blocked_fan), (1, 2));
    assert_eq!(ck.operations().next().unwrap().subjects, vec![b]);
    let p = Params {
        pull_order: PullOrder::FewestOutmostNeighbours,
        ..Params::default()
    };
    let mut ck = ChaKo::new(&g, p).unwrap();
    let r = step(&mut ck, &col);
    assert_eq!((r.pulls_started, r.blocked_fan), (2, 1));
    let mut subjects: Vec<u32> = ck.operations().map(|o| o.subjects[0]).collect();
    subjects.sort();
    assert_eq!(subjects, vec![a, c]);
}

// ---------------------------------------------------------------------------------------------
// Seams (Sec. 8)

/// A 4 x 2 cell sheet in the plane z = 0, sewn from two panels along x = 2: the left panel
/// keeps world x, y as uv; the right panel's uv is rotated by `angle`, scaled by `scale` and
/// moved away.
fn two_panels(angle: f64, scale: f64) -> (Garment, impl Fn(Vec2) -> Vec2) {
    let id = |i: usize, j: usize| (j * 5 + i) as u32;
    let positions: Vec<Vec3> = (0..3)
        .flat_map(|j| (0..5).map(move |i| Vec3::new(i as f64, j as f64, 0.0)))
        .collect();
    let (c, s) = (angle.cos(), angle.sin());
    let right = move |p: Vec2| {
        let q = p - Vec2::new(2.0, 0.0);
        Vec2::new(10.0, 3.0) + Vec2::new(c * q.x - s * q.y, s * q.x + c * q.y) * scale
    };
    let mut coords = Vec::new();
    let mut left_uv = vec![u32::MAX; 15];
    let mut right_uv = vec![u32::MAX; 15];
    for j in 0..3 {
        for i in 0..5 {
            let p = Vec2::new(i as f64, j as f64);
            if i <= 2 {
                left_uv[id(i, j) as usize] = coords.len() as u32;
                coords.push(p);
            }
            if i >= 2 {
                right_uv[id(i, j) as usize] = coords.len() as u32;
                coords.push(right(p));
            }
        }
    }
    let mut tris = Vec::new();
    let mut uv_tris = Vec::new();
    for j in 0..2 {
        for i in 0..4 {
            let map = if i < 2 { &left_uv } else { &right_uv };
            for t in [
                [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
            ] {
                tris.push(t);
                uv_tris.push(t.map(|v| map[v as usize]));
            }
        }
    }
    (with_uv(positions, &tris, coords, uv_tris), right)
}

#[test]
fn seam_pull_moves_every_copy_like_the_unfolded_planar_pull() {
    for (angle, scale) in [
        (0.0, 1.0),
        (std::f64::consts::FRAC_PI_2, 1.0),
        (2.3, 1.0),
        (0.7, 2.0),
    ] {
        let (g, right) = two_panels(angle, scale);
        assert_eq!(g.num_panels, 2);
        let x = 7u32; // world (2, 1), on the seam
        let t = 6u32; // world (1, 1), left panel only
        assert!(g.is_seam_vertex(x) && !g.is_seam_vertex(t));
        let mesh = UvMesh::new(g.clone(), Params::default().min_scale());
        let orig = g.uv().coords.clone();
        let p = mesh.pull(&orig, x, t);
        assert_eq!((p.copies.len(), p.virtual_copies, p.unsupported), (2, 1, 0));
        // Left copy: real anchor = the target's uv. Right copy: the world pull direction (-1, 0)
        // carried into the right panel's frame, i.e. the right panel's uv of world (1, 1).
        let want_right = right(Vec2::new(1.0, 1.0));
        for c in &p.copies {
            let panel = g.panel_of_uv[c.uv as usize];
            let want = if panel == 0 {
                Vec2::new(1.0, 1.0)
            } else {
                want_right
            };
            assert!(
                (c.anchor - want).norm() < 1e-12,
                "{angle} {scale}: {:?} vs {want:?}",
                c.anchor
            );
        }
        assert!(mesh.test(&orig, &p).pass);
    }
}

#[test]
fn seam_pull_through_the_scheduler_moves_both_copies() {
    let (g, _) = two_panels(1.1, 1.0);
    // The seam column and the right panel are red: the seam vertices are the out-most red ones
    // and are pulled into the left panel; their right copies follow virtual targets.
    let red = [2u32, 7, 12, 3, 8, 13, 4, 9, 14];
    let col = coloring(&g, &red, &[], &[]);
    assert_eq!(col.outmost_red, vec![2, 7, 12]);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let before = ck.current_uv().to_vec();
    let r = step(&mut ck, &col);
    // 2 and 12 are not adjacent and go together; 7 waits (Case 1).
    assert_eq!((r.pulls_started, r.blocked_fan), (2, 1));
    for op in ck.operations() {
        assert_eq!(op.copies.len(), 2);
        for c in &op.copies {
            assert_ne!(ck.current_uv()[c.uv as usize], before[c.uv as usize]);
        }
        let rec = &ck.finesse_log()[op.id as usize];
        assert_eq!((rec.seam, rec.virtual_copies), (SeamKind::OnSeamA, 1));
    }
    for _ in 0..25 {
        step(&mut ck, &col);
    }
}

#[test]
fn shrink_of_a_seam_edge_moves_all_copies() {
    let (g, _) = two_panels(0.4, 1.0);
    // Red edge along the seam (2,0)-(2,1) = world 2-7: the red* triangles on both sides.
    let col = coloring(&g, &[], &[(2, 7)], &[]);
    assert_eq!(col.red_star.len(), 2);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = step(&mut ck, &col);
    assert_eq!(r.shrinks_started, 1);
    let op = ck.operations().next().unwrap().clone();
    assert_eq!(op.copies.len(), 4, "two subjects x two panels");
    assert_eq!(ck.finesse_log()[0].seam, SeamKind::OnSeamA);
    for _ in 0..20 {
        step(&mut ck, &col);
    }
}

// ---------------------------------------------------------------------------------------------
// Contact policy

#[test]
fn contact_policy_follows_the_colouring() {
    use untangle::analysis::{analyze, AnalysisMesh};
    use untangle::methods::cha_ko::PairColour;
    use untangle::sim::{Contact as ContactRule, ContactPolicy};
    let scene = untangle::scenes::closed(10);
    let (am2, pos) = AnalysisMesh::new(&[
        (&scene.meshes[0], untangle::analysis::ObjectKind::Cloth),
        (&scene.meshes[1], untangle::analysis::ObjectKind::Cloth),
    ])
    .unwrap();
    let merged = am2.merged(&pos, &[&scene.meshes[0], &scene.meshes[1]]);
    let g = Garment::new(merged).unwrap();
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let ck = ChaKo::new(&g, Params::default()).unwrap();
    let pol = ck.contact_policy(&am, &a);
    let col = &a.coloring;
    let (mut rr, mut rg, mut gg) = (0, 0, 0);
    for v in 0..g.mesh.positions.len() as u32 {
        for t in (0..g.mesh.triangles.len() as u32).step_by(7) {
            let want = match (col.red_vertex[v as usize], col.red_triangle[t as usize]) {
                (true, true) => {
                    rr += 1;
                    ContactRule::Skip
                }
                (false, false) => {
                    gg += 1;
                    ContactRule::Thickness(1e-6)
                }
                _ => {
                    rg += 1;
                    ContactRule::Thickness(ck.eps_rg())
                }
            };
            assert_eq!(pol.vertex_triangle(v, t), want);
        }
    }
    assert!(rr > 0 && rg > 0 && gg > 0);
    for (e, ev) in g.topology.edges.iter().enumerate().step_by(5) {
        for (f, fv) in g.topology.edges.iter().enumerate().step_by(11) {
            let colour = pol.edge_edge_colour(e as u32, f as u32);
            let want = match (col.red_edge[e], col.red_edge[f]) {
                (true, true) => PairColour::RedRed,
                (false, false) => PairColour::GreenGreen,
                _ => PairColour::RedGreen,
            };
            assert_eq!(colour, want);
            assert_eq!(
                pol.edge_edge_by_vertices(*ev, *fv),
                pol.edge_edge(e as u32, f as u32)
            );
        }
    }
    // epsilon_RG = 0.1 x average uv edge length (10 x 10 grid of 0.1 cells: 0.1, 0.1, 0.1414).
    assert!((ck.average_edge_length() - ck.eps_rg() / 0.1).abs() < 1e-15);
    assert!(ck.eps_rg() > 0.01 && ck.eps_rg() < 0.0142);
}

#[test]
fn update_from_the_analysis_of_a_closed_tanglement() {
    use untangle::analysis::{analyze, AnalysisMesh, ObjectKind};
    let scene = untangle::scenes::closed(12);
    let (am2, pos) = AnalysisMesh::new(&[
        (&scene.meshes[0], ObjectKind::Cloth),
        (&scene.meshes[1], ObjectKind::Cloth),
    ])
    .unwrap();
    let g = Garment::new(am2.merged(&pos, &[&scene.meshes[0], &scene.meshes[1]])).unwrap();
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    assert!(a.coloring.num_red_vertices() > 0);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = ck.update_uv(&am, &a, &pos).unwrap();
    assert_eq!(r.outmost_red_vertices, a.coloring.outmost_red.len());
    assert!(r.pulls_started > 0);
    assert!(ck.inverted_uv_triangles().is_empty());
    // Every started pull's subject is out-most red and its target green.
    for op in ck.operations().filter(|o| o.kind == OpKind::Pull) {
        assert!(a
            .coloring
            .outmost_red
            .binary_search(&op.subjects[0])
            .is_ok());
        assert!(!a.coloring.red_vertex[op.target as usize]);
    }
    // A mesh that does not start with the garment is refused.
    let other = untangle::scenes::handkerchief("h", 2, 2, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 5.0));
    let (bad, bpos) = AnalysisMesh::single(&other).unwrap();
    let ba = analyze(&bad, &bpos).unwrap();
    assert!(ck.update_uv(&bad, &ba, &bpos).is_err());
}

// ---------------------------------------------------------------------------------------------
// Property tests

/// A jittered grid, optionally cut into two panels along column `cut` (right panel rotated,
/// independently jittered, so the seam is intrinsically non-planar).
fn random_garment(n: usize, seed: u64, cut: Option<usize>, angle: f64) -> Garment {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(Vec3::new(i as f64, j as f64, 0.0));
        }
    }
    let jit = |p: Vec2, interior: bool, rng: &mut rand_chacha::ChaCha8Rng| {
        if interior {
            p + Vec2::new(rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2))
        } else {
            p
        }
    };
    let cut = cut.unwrap_or(n + 1);
    let (c, s) = (angle.cos(), angle.sin());
    let mut coords = Vec::new();
    let mut lmap = vec![u32::MAX; positions.len()];
    let mut rmap = vec![u32::MAX; positions.len()];
    for j in 0..=n {
        for i in 0..=n {
            let p = Vec2::new(i as f64, j as f64);
            let interior = i > 0 && j > 0 && i < n && j < n;
            if i <= cut {
                lmap[id(i, j) as usize] = coords.len() as u32;
                coords.push(jit(p, interior && i != cut, &mut rng));
            }
            if i >= cut {
                rmap[id(i, j) as usize] = coords.len() as u32;
                let q = jit(p, interior && i != cut, &mut rng);
                coords.push(Vec2::new(30.0 + c * q.x - s * q.y, s * q.x + c * q.y));
            }
        }
    }
    let mut tris = Vec::new();
    let mut uv_tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let map = if i < cut { &lmap } else { &rmap };
            let (a, b, cc, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            let pair = if rng.random_bool(0.5) {
                [[a, b, cc], [a, cc, d]]
            } else {
                [[a, b, d], [b, cc, d]]
            };
            for t in pair {
                tris.push(t);
                uv_tris.push(t.map(|v| map[v as usize]));
            }
        }
    }
    with_uv(positions, &tris, coords, uv_tris)
}

/// A random colouring: a few red blobs (breadth-first from random seeds) and random
/// penetrating edges among green ones.
fn random_coloring(g: &Garment, rng: &mut rand_chacha::ChaCha8Rng) -> Coloring {
    use rand::Rng;
    let n = g.mesh.positions.len();
    let mut red = vec![false; n];
    for _ in 0..rng.random_range(0..3) {
        let size = rng.random_range(1..6);
        let mut queue = vec![rng.random_range(0..n as u32)];
        let mut k = 0;
        while k < queue.len() && k < size {
            let v = queue[k];
            red[v as usize] = true;
            for &w in g.topology.vertex_neighbors.row(v as usize) {
                if !red[w as usize] && rng.random_bool(0.5) {
                    queue.push(w);
                }
            }
            k += 1;
        }
    }
    let red_list: Vec<u32> = (0..n as u32).filter(|&v| red[v as usize]).collect();
    let edges: Vec<(u32, u32)> = (0..rng.random_range(0..4))
        .map(|_| {
            let e = g.topology.edges[rng.random_range(0..g.topology.num_edges())];
            (e[0], e[1])
        })
        .collect();
    coloring(g, &red_list, &edges, &[])
}

/// Checks the state invariants: every displaced copy sits on its operation's path, and no uv
/// triangle has moving corners from two operations.
fn check_invariants(ck: &ChaKo) {
    let gamma = ck.params().gamma;
    let orig = ck.original_uv();
    let cur = ck.current_uv();
    let mut owner = vec![u32::MAX; cur.len()];
    for op in ck.operations() {
        let s = gamma.powi(op.level as i32);
        for c in &op.copies {
            let want = c.anchor + (orig[c.uv as usize] - c.anchor) * s;
            assert_eq!(cur[c.uv as usize], want);
            assert_eq!(owner[c.uv as usize], u32::MAX);
            owner[c.uv as usize] = op.id;
        }
    }
    for (i, (&o, &c)) in orig.iter().zip(cur).enumerate() {
        if owner[i] == u32::MAX {
            assert_eq!(o, c, "uv {i} moved without an operation");
        }
    }
    for t in &ck.garment().uv().triangles {
        let mut ops: Vec<u32> = t
            .iter()
            .map(|&i| owner[i as usize])
            .filter(|&o| o != u32::MAX)
            .collect();
        ops.dedup();
        ops.sort_unstable();
        ops.dedup();
        assert!(ops.len() <= 1, "triangle {t:?} moved by operations {ops:?}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Random meshes (with and without a non-planar seam) and random colouring sequences: no uv
    /// triangle ever inverts, the invariants hold, and once everything is green the uv returns
    /// to the original bit for bit.
    #[test]
    fn no_operation_inverts_and_revoke_restores(
        n in 3usize..7,
        seed in 0u64..1_000_000,
        seam in proptest::bool::ANY,
        angle in 0.0f64..std::f64::consts::TAU,
        gamma in 0.3f64..0.9,
        max_level in 2u32..12,
    ) {
        use rand::{Rng, SeedableRng};
        let cut = seam.then_some(n / 2);
        let g = random_garment(n, seed, cut, angle);
        let mut ck = ChaKo::new(&g, Params { gamma, max_level, ..Params::default() }).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
        for _ in 0..6 {
            let col = random_coloring(&g, &mut rng);
            for _ in 0..rng.random_range(1..8) {
                step(&mut ck, &col);
                check_invariants(&ck);
            }
        }
        let green = green(&g);
        let mut k = 0;
        while !ck.is_restored() {
            step(&mut ck, &green);
            check_invariants(&ck);
            k += 1;
            prop_assert!(k <= max_level, "revoke takes at most max_level steps");
        }
        prop_assert_eq!(ck.current_uv(), ck.original_uv());
    }

    /// Same input, same steps: same output (determinism).
    #[test]
    fn deterministic(seed in 0u64..1_000_000) {
        use rand::SeedableRng;
        let g = random_garment(5, seed, Some(2), 1.0);
        let run = || {
            let mut ck = ChaKo::new(&g, Params::default()).unwrap();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut out = Vec::new();
            for _ in 0..5 {
                let col = random_coloring(&g, &mut rng);
                for _ in 0..3 {
                    out.push(format!("{:?}", step(&mut ck, &col)));
                }
            }
            (out, ck.current_uv().to_vec())
        };
        prop_assert_eq!(run(), run());
    }
}

/// The random scenarios of the property tests do exercise pulls, shrinks, seams, fallbacks and
/// stalls (so the properties are not vacuous).
#[test]
fn random_scenarios_exercise_every_operation() {
    use rand::{Rng, SeedableRng};
    let (mut ops, mut fb, mut seam, mut shr, mut stalls) = (0, 0, 0, 0, 0);
    for seed in 0..40u64 {
        let g = random_garment(5, seed, Some(2), 0.3 * seed as f64);
        let mut ck = ChaKo::new(
            &g,
            Params {
                max_level: 6,
                ..Params::default()
            },
        )
        .unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..6 {
            let col = random_coloring(&g, &mut rng);
            for _ in 0..rng.random_range(1..8) {
                let r = step(&mut ck, &col);
                fb += r.fallbacks.len();
                stalls += r.stalls.len();
            }
        }
        ops += ck.finesse_log().len();
        seam += ck
            .finesse_log()
            .iter()
            .filter(|r| r.seam != SeamKind::OffSeam)
            .count();
        shr += ck
            .finesse_log()
            .iter()
            .filter(|r| r.kind == OpKind::Shrink)
            .count();
    }
    eprintln!("ops {ops} fallbacks {fb} seam {seam} shrinks {shr} stalls {stalls}");
    assert!(ops > 100 && fb > 0 && seam > 10 && shr > 10 && stalls > 0);
}

#[test]
fn red_star_triangles_are_not_shrunk_toward_a_loop_vertex() {
    // CROSS: the two wedges intersect along a segment that starts at the loop vertex, so a red*
    // triangle at it whose target is the loop vertex can never finish its shrink.
    use untangle::analysis::{analyze, AnalysisMesh};
    let scene = untangle::scenes::by_name("cross", None, 1).unwrap();
    let g = Garment::new(scene.meshes[0].clone()).unwrap();
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let loops: Vec<u32> = a
        .paths
        .iter()
        .flat_map(|p| p.loop_vertices().to_vec())
        .collect();
    assert!(!loops.is_empty());
    let topo = &g.topology;
    // Oracle: the target of each red* triangle is its corner off the red edge.
    let target_of = |t: u32| {
        let tri = g.mesh.triangles[t as usize];
        let k = (0..3)
            .find(|&k| a.coloring.red_edge[topo.triangle_edges[t as usize][k] as usize])
            .unwrap();
        tri[(k + 2) % 3]
    };
    let at_loop = a
        .coloring
        .red_star
        .iter()
        .filter(|&&t| loops.contains(&target_of(t)))
        .count();
    assert!(
        at_loop > 0,
        "the scene has a red* triangle at the loop vertex"
    );
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = ck.update_uv(&am, &a, &pos).unwrap();
    assert_eq!(r.blocked_loop_target, at_loop);
    for op in ck.operations().filter(|o| o.kind == OpKind::Shrink) {
        assert!(!loops.contains(&op.target), "{op:?}");
    }
    // A bare colouring knows no paths: the same triangles are shrunk toward the loop vertex.
    let mut bare = ChaKo::new(&g, Params::default()).unwrap();
    let rb = bare.update_uv_with_coloring(&a.coloring, None).unwrap();
    assert_eq!(rb.blocked_loop_target, 0);
    assert!(bare
        .operations()
        .any(|o| o.kind == OpKind::Shrink && loops.contains(&o.target)));
}

/// Neighbours of `x` in the order the pull's target choice ranks them (original uv length, then
/// index): the oracle of the loop-vertex tests below.
fn ranked_neighbours(g: &Garment, x: u32) -> Vec<u32> {
    let uv = &g.uv().coords;
    let copy = |v: u32| g.uv_copies.row(v as usize)[0] as usize;
    let mut ws: Vec<(f64, u32)> = g
        .topology
        .vertex_neighbors
        .row(x as usize)
        .iter()
        .map(|&w| ((uv[copy(w)] - uv[copy(x)]).norm(), w))
        .collect();
    ws.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    ws.into_iter().map(|(_, w)| w).collect()
}

#[test]
fn pulls_avoid_loop_vertex_targets_while_another_green_neighbour_exists() {
    // Seed 13 of the exploded handkerchief: a red vertex pulled toward a loop vertex of an LL
    // path saturated three times (the triangle it had to cross contains the target).
    let n = 4;
    let g = grid(n);
    let x = gid(n, 2, 2);
    let ranked = ranked_neighbours(&g, x);
    let col = coloring(&g, &[x], &[], &[]);
    let on = Params {
        avoid_loop_pull_targets: true,
        ..Params::default()
    };
    let first = |loops: &[u32]| {
        let mut ck = ChaKo::new(&g, on.clone()).unwrap();
        let r = ck.update_uv_with_loops(&col, loops, None).unwrap();
        assert_eq!(r.pulls_started, 1);
        let t = ck.operations().next().unwrap().target;
        (t, r)
    };
    assert_eq!(first(&[]).0, ranked[0]);
    let (t, r) = first(&[ranked[0]]);
    assert_eq!((t, r.pull_loop_targets_skipped), (ranked[1], 1));
    let (t, _) = first(&ranked[..3]);
    assert_eq!(t, ranked[3]);
    // Every green neighbour a loop vertex: the paper's choice stands.
    let (t, r) = first(&ranked);
    assert_eq!((t, r.pull_loop_targets_skipped), (ranked[0], 0));
    // Rule off (the default): the paper's choice.
    let mut off = ChaKo::new(&g, Params::default()).unwrap();
    off.update_uv_with_loops(&col, &[ranked[0]], None).unwrap();
    assert_eq!(off.operations().next().unwrap().target, ranked[0]);

    // A running pull whose target becomes a loop vertex ends and is revoked; once x is back,
    // it is pulled toward the next neighbour.
    let mut ck = ChaKo::new(&g, on.clone()).unwrap();
    for _ in 0..3 {
        ck.update_uv_with_loops(&col, &[], None).unwrap();
    }
    assert_eq!(ck.operations().next().unwrap().level, 3);
    let mut levels = Vec::new();
    for _ in 0..4 {
        let r = ck.update_uv_with_loops(&col, &[ranked[0]], None).unwrap();
        levels.push((r.revoked_levels, r.pulls_started));
    }
    assert_eq!(levels, vec![(1, 0), (1, 0), (1, 0), (0, 1)]);
    let op = ck.operations().next().unwrap();
    assert_eq!((op.target, op.level), (ranked[1], 1));
    assert!(ck.inverted_uv_triangles().is_empty());
}

#[test]
fn the_start_only_pull_rule_steers_the_target_choice_and_lets_running_pulls_go_on() {
    // `avoid_loop_pull_targets_at_start` (experiment): the same target choice as the full rule,
    // but a running pull whose target becomes a loop vertex continues.
    let n = 4;
    let g = grid(n);
    let x = gid(n, 2, 2);
    let ranked = ranked_neighbours(&g, x);
    let col = coloring(&g, &[x], &[], &[]);
    let start_only = Params {
        avoid_loop_pull_targets_at_start: true,
        ..Params::default()
    };
    let mut ck = ChaKo::new(&g, start_only.clone()).unwrap();
    let r = ck.update_uv_with_loops(&col, &[ranked[0]], None).unwrap();
    assert_eq!((r.pulls_started, r.pull_loop_targets_skipped), (1, 1));
    assert_eq!(ck.operations().next().unwrap().target, ranked[1]);
    // Running toward ranked[0] (chosen while it was no loop vertex), which then becomes one:
    // the pull goes on, level by level, with no revoke.
    let mut ck = ChaKo::new(&g, start_only).unwrap();
    ck.update_uv_with_loops(&col, &[], None).unwrap();
    assert_eq!(ck.operations().next().unwrap().target, ranked[0]);
    for level in 2..=4 {
        let r = ck.update_uv_with_loops(&col, &[ranked[0]], None).unwrap();
        assert_eq!((r.pulls_continued, r.revoked_levels), (1, 0));
        let op = ck.operations().next().unwrap();
        assert_eq!((op.target, op.level), (ranked[0], level));
    }
    assert!(ck.inverted_uv_triangles().is_empty());
}

#[test]
fn a_red_star_shrink_toward_a_loop_vertex_is_a_last_resort() {
    let n = 6;
    let g = grid(n);
    let topo = &g.topology;
    // One penetrating edge inside the sheet; its triangles are the red* ones.
    let (a, b) = (gid(n, 2, 2), gid(n, 3, 2));
    let e = topo.edge_between(a, b).unwrap();
    let only_star = coloring(&g, &[], &[(a, b)], &[]);
    assert_eq!(only_star.red_star.len(), 2);
    let target = |t: u32| {
        let tri = g.mesh.triangles[t as usize];
        *tri.iter().find(|&&v| v != a && v != b).unwrap()
    };
    let loops: Vec<u32> = only_star.red_star.iter().map(|&t| target(t)).collect();
    assert!(topo.edge_triangles[e as usize]
        .iter()
        .all(|t| only_star.red_star.contains(t)));

    // Something else to do (an out-most red vertex far away): the loop targets are skipped.
    let far = gid(n, 5, 5);
    let busy = coloring(&g, &[far], &[(a, b)], &[]);
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = ck.update_uv_with_loops(&busy, &loops, None).unwrap();
    assert_eq!((r.blocked_loop_target, r.shrinks_started), (2, 0));
    assert_eq!(r.pulls_started, 1);

    // Nothing else: the first red* triangle (sorted order) is shrunk toward its loop target and
    // continues while it stays red*; the second is adjacent (Case 2) and waits.
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let r = ck.update_uv_with_loops(&only_star, &loops, None).unwrap();
    assert_eq!((r.shrinks_started, r.loop_target_last_resort), (1, 1));
    let op = ck.operations().next().unwrap().clone();
    assert_eq!(op.triangle, only_star.red_star[0]);
    assert_eq!(op.target, target(op.triangle));
    for s in 2..=4 {
        let r = ck.update_uv_with_loops(&only_star, &loops, None).unwrap();
        assert_eq!((r.shrinks_continued, r.shrinks_started), (1, 0), "step {s}");
        assert_eq!(ck.operations().next().unwrap().level, s);
    }
    assert!(ck.inverted_uv_triangles().is_empty());

    // Off: the rule of the loop-vertex fix alone.
    let mut ck = ChaKo::new(
        &g,
        Params {
            loop_target_last_resort: false,
            ..Params::default()
        },
    )
    .unwrap();
    let r = ck.update_uv_with_loops(&only_star, &loops, None).unwrap();
    assert_eq!((r.blocked_loop_target, r.shrinks_started), (2, 0));
}

#[test]
fn mixed_edge_rules_decide_edge_pairs_from_the_end_colours() {
    // Oracle: an edge is mixed when exactly one end is red (Sec. 3 makes it red); the rules
    // change only pairs with a mixed edge, and never let a mixed edge cross under `Green`.
    use untangle::analysis::{analyze, AnalysisMesh};
    use untangle::methods::cha_ko::{MixedEdges, PairColour};
    use untangle::sim::{Contact as ContactRule, ContactPolicy};
    let g = Garment::new({
        let scene = untangle::scenes::closed(10);
        let (am2, pos) = AnalysisMesh::new(&[
            (&scene.meshes[0], untangle::analysis::ObjectKind::Cloth),
            (&scene.meshes[1], untangle::analysis::ObjectKind::Cloth),
        ])
        .unwrap();
        am2.merged(&pos, &[&scene.meshes[0], &scene.meshes[1]])
    })
    .unwrap();
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let col = &a.coloring;
    let edges = &g.topology.edges;
    let mixed =
        |e: usize| col.red_vertex[edges[e][0] as usize] != col.red_vertex[edges[e][1] as usize];
    let n_mixed = (0..edges.len()).filter(|&e| mixed(e)).count();
    assert!(n_mixed > 0);
    let mut counts = [0usize; 3];
    for rule in [MixedEdges::Red, MixedEdges::Green, MixedEdges::NotWithMixed] {
        let ck = ChaKo::new(
            &g,
            Params {
                mixed_edges: rule,
                ..Params::default()
            },
        )
        .unwrap();
        let pol = ck.contact_policy(&am, &a);
        for e in 0..edges.len() {
            for f in (0..edges.len()).step_by(3) {
                let (re, rf) = (col.red_edge[e], col.red_edge[f]);
                let want = match rule {
                    MixedEdges::Red => (re, rf),
                    MixedEdges::Green => (re && !mixed(e), rf && !mixed(f)),
                    MixedEdges::NotWithMixed if mixed(e) && mixed(f) => (false, true),
                    MixedEdges::NotWithMixed => (re, rf),
                };
                let want = match want {
                    (true, true) => PairColour::RedRed,
                    (false, false) => PairColour::GreenGreen,
                    _ => PairColour::RedGreen,
                };
                assert_eq!(pol.edge_edge_colour(e as u32, f as u32), want);
                let c = pol.edge_edge(e as u32, f as u32);
                if rule == MixedEdges::Green && (mixed(e) || mixed(f)) {
                    assert_ne!(c, ContactRule::Skip, "a mixed edge may not cross");
                }
                if c == ContactRule::Skip {
                    counts[rule as usize] += 1;
                }
            }
        }
    }
    // The paper's rule lets the most pairs cross, `Green` the fewest.
    assert!(counts[0] > counts[2] && counts[2] > counts[1], "{counts:?}");
}

#[test]
fn persistent_green_never_turns_a_green_vertex_red() {
    // Oracle: the Sec. 3 colouring (`coloring::color`) of the analysis's red vertices restricted
    // to those red at the previous call.
    use untangle::analysis::{analyze, coloring::color, AnalysisMesh};
    let scene = untangle::scenes::closed(10);
    let (am2, pos) = AnalysisMesh::new(&[
        (&scene.meshes[0], untangle::analysis::ObjectKind::Cloth),
        (&scene.meshes[1], untangle::analysis::ObjectKind::Cloth),
    ])
    .unwrap();
    let g = Garment::new(am2.merged(&pos, &[&scene.meshes[0], &scene.meshes[1]])).unwrap();
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a0 = analyze(&am, &pos).unwrap();
    let red0 = a0.coloring.red_vertex.clone();
    let (on, off) = (
        Params {
            persistent_green: true,
            ..Params::default()
        },
        Params::default(),
    );
    let mut ck = ChaKo::new(&g, on).unwrap();
    let mut first = a0.clone();
    ck.persist_coloring(&am, &mut first);
    assert_eq!(
        first.coloring, a0.coloring,
        "the first call keeps the analysis"
    );
    // Next step: pretend half of the red vertices turned green and some green ones red.
    let mut a1 = a0.clone();
    let mut red1 = red0.clone();
    let mut flipped = 0;
    for (v, r) in red1.iter_mut().enumerate() {
        if v % 2 == 0 {
            *r = !*r;
            flipped += 1;
        }
    }
    assert!(flipped > 0);
    a1.coloring = color(&am, red1.clone(), &a1.crossings, &a1.segments);
    let mut got = a1.clone();
    ck.persist_coloring(&am, &mut got);
    let want: Vec<bool> = red1.iter().zip(&red0).map(|(&a, &b)| a && b).collect();
    assert_eq!(
        got.coloring,
        color(&am, want.clone(), &a1.crossings, &a1.segments)
    );
    assert!(got.coloring.num_red_vertices() <= a0.coloring.num_red_vertices());
    // Off: untouched.
    let mut ck = ChaKo::new(&g, off).unwrap();
    let mut x = a0.clone();
    ck.persist_coloring(&am, &mut x);
    let mut y = a1.clone();
    ck.persist_coloring(&am, &mut y);
    assert_eq!(y.coloring, a1.coloring);
}

#[test]
fn pulls_start_only_across_cut_edges() {
    // A red vertex whose edges to its green neighbours penetrate nothing (the rim of a BLI cone
    // region) has nothing to cross: it is not pulled; across a cut edge, or toward a loop
    // vertex, it is.
    let n = 4;
    let g = grid(n);
    let x = gid(n, 2, 2);
    let ranked = ranked_neighbours(&g, x);
    let col = coloring(&g, &[x], &[], &[]);
    let edge = |w: u32| g.topology.edge_between(x, w).unwrap();
    let first = |params: Params, loops: &[u32], cut: Option<&[u32]>| {
        let mut ck = ChaKo::new(&g, params).unwrap();
        let r = ck.update_uv_with_paths(&col, loops, cut, None).unwrap();
        let t = ck.operations().next().map(|o| o.target);
        (r.pulls_started, t)
    };
    let p = Params::default();
    assert!(p.pull_across_cut_edges);
    assert_eq!(
        first(p.clone(), &[], Some(&[edge(ranked[2])])),
        (1, Some(ranked[2]))
    );
    assert_eq!(first(p.clone(), &[], Some(&[])), (0, None));
    assert_eq!(
        first(p.clone(), &[ranked[1]], Some(&[])),
        (1, Some(ranked[1]))
    );
    // Cut edges unknown (a bare colouring), or the rule off: the paper's choice.
    assert_eq!(first(p.clone(), &[], None), (1, Some(ranked[0])));
    let off = Params {
        pull_across_cut_edges: false,
        ..Params::default()
    };
    assert_eq!(first(off, &[], Some(&[])), (1, Some(ranked[0])));
}

#[test]
fn the_cut_edge_rule_changes_nothing_on_the_papers_coloring() {
    // In the Sec. 3 colouring every red-green edge is a cut edge or ends at a loop vertex (the
    // inside regions are flood fills stopped only there), so the pulls of the first update are
    // the same with and without the rule. Checked on the analysis of the rudimentary scenes and
    // of exploded handkerchiefs (BLI cone regions not coloured).
    use untangle::analysis::{analyze, AnalysisMesh};
    let mut scenes: Vec<Garment> = ["closed", "eight", "bbii", "bibi", "ll", "cross"]
        .iter()
        .map(|name| {
            let s = untangle::scenes::by_name(name, None, 1).unwrap();
            Garment::new(AnalysisMesh::merge_cloth(&s.meshes).unwrap()).unwrap()
        })
        .collect();
    for seed in 1..=4 {
        scenes.push(
            Garment::new(untangle::scenes::exploded::exploded(seed, 10).meshes[0].clone()).unwrap(),
        );
    }
    let mut checked = 0;
    for g in &scenes {
        let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
        let a = analyze(&am, &pos).unwrap();
        let cut: Vec<u32> = a.crossings.iter().map(|c| c.edge).collect();
        let loops: Vec<u32> = a
            .paths
            .iter()
            .flat_map(|p| p.loop_vertices().iter().copied())
            .collect();
        let col = &a.coloring;
        for &x in &col.outmost_red {
            for &w in g.topology.vertex_neighbors.row(x as usize) {
                if col.red_vertex[w as usize] {
                    continue;
                }
                let e = g.topology.edge_between(x, w).unwrap();
                assert!(
                    cut.contains(&e) || loops.contains(&w),
                    "{}: red {x} - green {w} is neither cut nor at a loop vertex",
                    g.mesh.name
                );
                checked += 1;
            }
        }
        let ops = |params: Params| {
            let mut ck = ChaKo::new(g, params).unwrap();
            let r = ck.update_uv(&am, &a, &pos).unwrap();
            let ops: Vec<(u32, u32)> = ck.operations().map(|o| (o.subjects[0], o.target)).collect();
            (r.pulls_started, r.shrinks_started, ops)
        };
        let off = Params {
            pull_across_cut_edges: false,
            ..Params::default()
        };
        assert_eq!(ops(Params::default()), ops(off), "{}", g.mesh.name);
    }
    assert!(checked > 100, "{checked}");
}

#[test]
fn a_bli_sector_starts_first_goes_on_while_its_path_lasts_and_is_revoked_after() {
    // `bli_interior(0)`: one BLI path with interior loop vertex 0; the boundary edge 4-5 of
    // triangle (0,4,5) pierces the wedge (0,1,2), (0,2,3). Its sector is (0,4,5) with its edge
    // neighbours (0,3,4), (0,5,6): subjects 3, 4, 5, 6 toward 0, whose uv is the origin.
    use untangle::analysis::{analyze, AnalysisMesh};
    let scene = untangle::scenes::rudimentary::bli_interior(0);
    let g = Garment::new(scene.meshes[0].clone()).unwrap();
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let orig = g.uv().coords.clone();
    let mut ck = ChaKo::new(&g, Params::default()).unwrap();
    let gamma = Params::default().gamma;
    for level in 1..=3u32 {
        let r = ck.update_uv(&am, &a, &pos).unwrap();
        assert_eq!(
            (r.sectors_started, r.sectors_continued),
            if level == 1 { (1, 0) } else { (0, 1) }
        );
        let op = ck
            .operations()
            .find(|o| o.kind == OpKind::Sector)
            .expect("a sector operation");
        assert_eq!((op.target, op.level), (0, level));
        assert_eq!(op.subjects, vec![3, 4, 5, 6]);
        // Every subject's copy at gamma^level of its original uv (anchor: the origin); the
        // loop vertex and the pierced wedge's far corners 1, 2 stay.
        let s = gamma.powi(level as i32);
        for v in 0..7usize {
            let want = if (3..=6).contains(&v) {
                orig[v] * s
            } else {
                orig[v]
            };
            assert!(
                (ck.current_uv()[v] - want).norm() < 1e-12,
                "v {v} level {level}"
            );
        }
        // The sector's subjects are held: no pull or shrink of the colouring took them.
        for o in ck.operations().filter(|o| o.kind != OpKind::Sector) {
            assert!(o.subjects.iter().all(|w| !(3..=6).contains(w)), "{o:?}");
        }
    }
    // The path gone (the flat layout as world shape: nothing intersects), the sector is no
    // longer warranted: it finishes and is revoked one level per step, back to the original uv.
    let flat: Vec<Vec3> = orig.iter().map(|p| Vec3::new(p.x, p.y, 0.0)).collect();
    let (am2, _) = AnalysisMesh::single(&Mesh {
        positions: flat.clone(),
        ..g.mesh.clone()
    })
    .unwrap();
    let clean = analyze(&am2, &flat).unwrap();
    assert!(clean.is_clean());
    for step in 0..3 {
        let r = ck.update_uv(&am2, &clean, &flat).unwrap();
        assert_eq!(r.revoked_levels, 1, "step {step}");
    }
    assert!(ck.operations().next().is_none());
    assert_eq!(ck.current_uv(), &orig[..]);
    let log = ck.finesse_log();
    let rec = log.iter().find(|f| f.kind == OpKind::Sector).unwrap();
    assert_eq!(rec.end, Some(EndReason::Finished));
    // Off, no sector starts.
    let mut off = ChaKo::new(
        &g,
        Params {
            bli_sectors: false,
            ..Params::default()
        },
    )
    .unwrap();
    let r = off.update_uv(&am, &a, &pos).unwrap();
    assert_eq!(r.sectors_started, 0);
    assert!(off.operations().all(|o| o.kind != OpKind::Sector));
}
