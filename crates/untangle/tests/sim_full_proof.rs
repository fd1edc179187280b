//! "Full-proof" continuous collision handling (Cha & Ko 2022, Sec. 1): hard scenes run for
//! hundreds of steps, and after every step the global intersection analysis (an independent,
//! exact oracle) finds no intersection — or the step report says administrative quit.
//! Also: bit-identical results for 1 and 2 threads.

use untangle::analysis::{analyze, AnalysisMesh, ObjectKind};
use untangle::geom::{Vec2, Vec3};
use untangle::mesh::{Garment, Mesh};
use untangle::scenes::handkerchief;
use untangle::sim::{Obstacle, SimParams, Simulator, StepReport, UniformThickness};

/// A square floor (two triangles) at height `y`.
fn floor(y: f64, half: f64) -> Mesh {
    Mesh::new(
        "floor",
        vec![
            Vec3::new(-half, y, -half),
            Vec3::new(half, y, -half),
            Vec3::new(half, y, half),
            Vec3::new(-half, y, half),
        ],
        vec![[0, 2, 1], [0, 3, 2]],
    )
    .unwrap()
}

struct Checked {
    reports: Vec<StepReport>,
    quits: usize,
}

/// Runs `steps` steps, calling `before(sim, k)` before step k, and checks the cloth (and the
/// obstacles) with the intersection analysis after every step.
fn run_checked(
    cloth: &Mesh,
    sim: &mut Simulator,
    obstacles: &[Mesh],
    steps: usize,
    thickness: f64,
    mut before: impl FnMut(&mut Simulator, usize),
) -> Checked {
    let mut parts: Vec<(&Mesh, ObjectKind)> = vec![(cloth, ObjectKind::Cloth)];
    parts.extend(obstacles.iter().map(|m| (m, ObjectKind::Obstacle)));
    let (am, mut pos) = AnalysisMesh::new(&parts).unwrap();
    assert!(
        analyze(&am, &pos).unwrap().is_clean(),
        "scene must start clean"
    );
    let policy = UniformThickness(thickness);
    let mut reports = Vec::new();
    let mut quits = 0;
    for k in 0..steps {
        before(sim, k);
        let r = sim.step(&policy);
        let n = sim.positions().len();
        pos[..n].copy_from_slice(sim.positions());
        pos[n..].copy_from_slice(&sim.obstacles().start);
        let a = analyze(&am, &pos).expect("analysis is consistent");
        if r.administrative_quit() {
            quits += 1;
        } else {
            assert!(
                a.is_clean(),
                "step {k}: {} intersecting triangle pairs without administrative quit; report {}",
                a.segments.len(),
                r.to_json()
            );
        }
        assert!(sim
            .positions()
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite())));
        reports.push(r);
    }
    Checked { reports, quits }
}

/// A sheet standing on its lower edge collapses onto a floor and folds onto itself.
fn folding_sheet(n: usize) -> (Mesh, Simulator, Vec<Mesh>) {
    let cloth = handkerchief("sheet", n, n, 0.5, 0.5, |p| {
        // Vertical, slightly wavy so it buckles into several folds.
        Vec3::new(p.x, p.y + 0.27, 0.02 * (6.0 * p.y).sin() + 0.01 * p.x)
    });
    let g = Garment::new(cloth.clone()).unwrap();
    let mut sim = Simulator::new(&g, SimParams::default()).unwrap();
    let fl = floor(0.0, 2.0);
    sim.add_obstacle(Obstacle::from_mesh(&fl, 2e-3, 0.3).unwrap())
        .unwrap();
    (cloth, sim, vec![fl])
}

#[test]
fn sheet_falling_onto_itself_in_folds_stays_intersection_free() {
    let (cloth, mut sim, obs) = folding_sheet(14);
    let c = run_checked(&cloth, &mut sim, &obs, 250, 2e-3, |_, _| {});
    let contacts: usize = c
        .reports
        .iter()
        .map(|r| r.collisions.proximity_impulses)
        .sum();
    let impulses: usize = c.reports.iter().map(|r| r.collisions.impulses).sum();
    eprintln!(
        "folding sheet: {} proximity impulses, {} CCD impulses, {} zone steps, {} quits",
        contacts,
        impulses,
        c.reports
            .iter()
            .filter(|r| r.collisions.impact_zones > 0)
            .count(),
        c.quits
    );
    // The scene really is hard: the sheet lands and touches itself.
    assert!(contacts > 1000, "too few contacts: {contacts}");
    // A static floor cannot pinch: no administrative quit.
    assert_eq!(c.quits, 0);
    // The sheet ends on the floor, above it by the thickness.
    let miny = sim.positions().iter().map(|p| p.y).fold(f64::MAX, f64::min);
    let maxy = sim.positions().iter().map(|p| p.y).fold(f64::MIN, f64::max);
    assert!(miny > 0.0 && maxy < 0.2, "y range {miny}..{maxy}");
}

/// A strip pinned at both ends; one end turns two full turns while the ends approach, so the
/// strip coils onto itself.
#[test]
fn twisted_strip_stays_intersection_free() {
    let (nx, ny) = (40, 3);
    let (len, w) = (0.8, 0.06);
    let cloth = handkerchief("strip", nx, ny, len, w, |p| Vec3::new(p.x, 0.5, p.y));
    let g = Garment::new(cloth.clone()).unwrap();
    let mut sim = Simulator::new(&g, SimParams::default()).unwrap();
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let left: Vec<u32> = (0..=ny).map(|j| id(0, j)).collect();
    let right: Vec<u32> = (0..=ny).map(|j| id(nx, j)).collect();
    for &v in left.iter().chain(&right) {
        sim.set_pinned(v, true).unwrap();
    }
    let rest: Vec<Vec3> = right.iter().map(|&v| sim.positions()[v as usize]).collect();
    let steps = 300;
    let turn_steps = 250;
    let c = run_checked(&cloth, &mut sim, &[], steps, 2e-3, |sim, k| {
        let s = ((k + 1).min(turn_steps)) as f64 / turn_steps as f64;
        let angle = s * 4.0 * std::f64::consts::PI;
        let shift = -0.35 * s;
        for (&v, p) in right.iter().zip(&rest) {
            let (y, z) = (p.y - 0.5, p.z);
            let t = Vec3::new(
                p.x + shift,
                0.5 + y * angle.cos() - z * angle.sin(),
                y * angle.sin() + z * angle.cos(),
            );
            sim.set_pin_target(v, t).unwrap();
        }
    });
    let contacts: usize = c
        .reports
        .iter()
        .map(|r| r.collisions.proximity_impulses)
        .sum();
    eprintln!(
        "twisted strip: {} proximity impulses, {} CCD impulses, {} zone steps, {} stalls, {} quits",
        contacts,
        c.reports
            .iter()
            .map(|r| r.collisions.impulses)
            .sum::<usize>(),
        c.reports
            .iter()
            .filter(|r| r.collisions.impact_zones > 0)
            .count(),
        c.reports.iter().filter(|r| r.collisions.stalled).count(),
        c.quits
    );
    assert!(contacts > 100, "the strip must touch itself: {contacts}");
    assert_eq!(c.quits, 0);
}

fn final_positions(threads: usize) -> Vec<Vec3> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| {
            // Large enough that the parallel code paths (chunks of 512 vertices, BVH
            // subtrees of 2048 primitives) really split.
            let (_, mut sim, _) = folding_sheet(40);
            let policy = UniformThickness(2e-3);
            for _ in 0..6 {
                sim.step(&policy);
            }
            sim.positions().to_vec()
        })
}

#[test]
fn one_and_two_threads_give_bit_identical_positions() {
    let a = final_positions(1);
    let b = final_positions(2);
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(&b) {
        assert_eq!(p.map(f64::to_bits), q.map(f64::to_bits));
    }
}

/// The uv rest shape can change every step (Cha & Ko): shrinking the uv of a free sheet makes it
/// contract in the world, and restoring it brings it back.
#[test]
fn rest_uv_edits_drive_the_shape() {
    let cloth = handkerchief("s", 8, 8, 0.4, 0.4, |p| Vec3::new(p.x, p.y, 0.0));
    let g = Garment::new(cloth).unwrap();
    let params = SimParams {
        gravity: Vec3::zeros(),
        ..SimParams::default()
    };
    let mut sim = Simulator::new(&g, params).unwrap();
    let uv0: Vec<Vec2> = g.uv().coords.clone();
    let width = |s: &Simulator| {
        let xs = s.positions().iter().map(|p| p.x);
        xs.clone().fold(f64::MIN, f64::max) - xs.fold(f64::MAX, f64::min)
    };
    let policy = UniformThickness(1e-3);
    let small: Vec<Vec2> = uv0.iter().map(|u| u * 0.8).collect();
    sim.set_rest_uv(&small).unwrap();
    for _ in 0..100 {
        sim.step(&policy);
    }
    let w = width(&sim);
    assert!((w - 0.32).abs() < 0.01, "shrunk width {w}");
    sim.set_rest_uv(&uv0).unwrap();
    for _ in 0..100 {
        sim.step(&policy);
    }
    let w = width(&sim);
    assert!((w - 0.4).abs() < 0.01, "restored width {w}");
    // Bad input changes nothing.
    assert!(sim.set_rest_uv(&uv0[..5]).is_err());
    let mut bad = uv0.clone();
    bad[1] = bad[0];
    bad[9] = bad[0];
    assert!(sim.set_rest_uv(&bad).is_err());
    assert_eq!(sim.rest_uv(), &uv0[..]);
}

/// The fail-safes alone: without proximity repulsion and without CCD impulses every collision
/// goes to rigid impact zones; with a zone cap of one pass the stall fail-safe takes over. Both
/// must keep the folding sheet intersection-free (a static floor cannot pinch: no quit).
#[test]
fn impact_zones_and_stall_alone_keep_the_folding_sheet_clean() {
    for (zones_cap, name) in [(1000, "zones"), (1, "stall")] {
        let (cloth, mut sim, obs) = folding_sheet(10);
        sim.set_params(SimParams {
            proximity: false,
            max_impulse_iterations: 0,
            max_zone_iterations: zones_cap,
            ..SimParams::default()
        })
        .unwrap();
        let c = run_checked(&cloth, &mut sim, &obs, 120, 2e-3, |_, _| {});
        let zone_steps = c
            .reports
            .iter()
            .filter(|r| r.collisions.impact_zones > 0)
            .count();
        let stalls = c.reports.iter().filter(|r| r.collisions.stalled).count();
        eprintln!(
            "{name}: {zone_steps} zone steps, {stalls} stalls, {} quits",
            c.quits
        );
        assert!(
            zone_steps > 5,
            "{name}: the fail-safe must have been exercised"
        );
        if zones_cap == 1 {
            assert!(stalls > 0);
        }
        assert_eq!(c.quits, 0);
    }
}
