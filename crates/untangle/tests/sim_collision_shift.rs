//! `StepReport::collision_shift` (how far the collision handling moved the cloth from the
//! implicit solve's end positions) against an independent oracle: the same first step with
//! the collision handling turned off, whose end positions are the solve's own (no obstacles
//! and no resting contacts yet, so the solve is the same).

use untangle::analysis::AnalysisMesh;
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::scenes::handkerchief;
use untangle::sim::{Integrator, SimParams, Simulator, UniformThickness};

/// Two parallel 6 x 6 sheets 1 cm apart as one garment, and the lower sheet's vertex count
/// (its vertices come first).
fn two_sheets() -> (Garment, usize) {
    let below = handkerchief("a", 6, 6, 0.3, 0.3, |p| Vec3::new(p.x, 0.0, p.y));
    let above = handkerchief("b", 6, 6, 0.3, 0.3, |p| Vec3::new(p.x, 0.01, p.y));
    let merged = AnalysisMesh::merge_cloth(&[below.clone(), above]).unwrap();
    (Garment::new(merged).unwrap(), below.positions.len())
}

/// Two parallel sheets 1 cm apart, the upper one thrown at the lower one.
#[test]
fn collision_shift_is_the_distance_to_the_collision_free_step() {
    let (g, lower) = two_sheets();
    let nv = g.mesh.positions.len();
    // The upper sheet moves down 2 cm per step: it would pass through the lower one.
    let v: Vec<Vec3> = (0..nv)
        .map(|i| {
            if i < lower {
                Vec3::zeros()
            } else {
                Vec3::new(0.0, -1.0, 0.0)
            }
        })
        .collect();
    let policy = UniformThickness(1e-3);
    for integrator in [Integrator::BaraffWitkin, Integrator::Projective] {
        let p = SimParams {
            integrator,
            gravity: Vec3::zeros(),
            ..SimParams::default()
        };
        let run = |collisions: bool| {
            let mut sim = Simulator::new(
                &g,
                SimParams {
                    collisions,
                    ..p.clone()
                },
            )
            .unwrap();
            sim.set_velocities(&v).unwrap();
            let r = sim.step(&policy);
            (sim.positions().to_vec(), r.collision_shift)
        };
        let (free, none) = run(false);
        let (held, shift) = run(true);
        assert_eq!((none.max, none.mean), (0.0, 0.0));
        let d: Vec<f64> = free
            .iter()
            .zip(&held)
            .map(|(a, b)| (a - b).norm())
            .collect();
        let max = d.iter().cloned().fold(0.0, f64::max);
        let mean = d.iter().sum::<f64>() / nv as f64;
        assert!(
            max > 0.005,
            "{integrator:?}: the sheets were kept apart ({max})"
        );
        assert!(
            (shift.max - max).abs() < 1e-9,
            "{integrator:?}: {} vs {max}",
            shift.max
        );
        assert!(
            (shift.mean - mean).abs() < 1e-9,
            "{integrator:?}: {} vs {mean}",
            shift.mean
        );
        // The collision handling kept each vertex of the upper sheet above its twin below.
        assert!(
            (0..lower).all(|i| held[lower + i].y > held[i].y),
            "{integrator:?}"
        );
        assert!((0..lower).any(|i| free[lower + i].y < free[i].y));
    }
}

/// `Simulator::solved_velocities` are the solve's velocities before the collision handling:
/// stepped from the start positions they give the collision-free step's end positions (the
/// oracle of the test above), while the simulator's own velocities are the held ones; empty
/// before the first step and with collisions off.
#[test]
fn solved_velocities_give_the_collision_free_end_positions() {
    let (g, lower) = two_sheets();
    let nv = g.mesh.positions.len();
    let v: Vec<Vec3> = (0..nv)
        .map(|i| Vec3::new(0.0, if i < lower { 0.0 } else { -1.0 }, 0.0))
        .collect();
    let policy = UniformThickness(1e-3);
    let p = SimParams {
        gravity: Vec3::zeros(),
        ..SimParams::default()
    };
    let h = p.dt;
    let x0 = g.mesh.positions.clone();
    let mut free = Simulator::new(
        &g,
        SimParams {
            collisions: false,
            ..p.clone()
        },
    )
    .unwrap();
    free.set_velocities(&v).unwrap();
    free.step(&policy);
    assert!(free.solved_velocities().is_empty());
    let mut held = Simulator::new(&g, p).unwrap();
    assert!(held.solved_velocities().is_empty());
    held.set_velocities(&v).unwrap();
    held.step(&policy);
    let vs = held.solved_velocities();
    assert_eq!(vs.len(), nv);
    let mut differs = false;
    for i in 0..nv {
        let solved_end = x0[i] + vs[i] * h;
        assert!(
            (solved_end - free.positions()[i]).norm() < 1e-12,
            "vertex {i}: {solved_end} vs {}",
            free.positions()[i]
        );
        differs |= (vs[i] - held.velocities()[i]).norm() * h > 1e-3;
    }
    assert!(differs, "the collision handling changed some velocity");
}
