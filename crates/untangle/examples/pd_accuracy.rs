//! Accuracy of projective dynamics' local/global iterations per step: the level-2 ARCSim t-shirt
//! of `sim_bench 2` (4,950 vertices, pinned at the shoulders, pushed sideways) is run for
//! `STEPS` steps with the default parameters; from the states at a few of those steps one step
//! is solved again (collision handling off, so the result is the solve's) with several
//! (iterations, Chebyshev rho) settings and compared with a 300-iteration reference: the
//! largest and the RMS vertex error relative to the largest and RMS motion of that step, and
//! the elastic energy (J) and max edge stretch after it.
//!
//! `UNTANGLE_SHARED=/work/shared cargo run --release -p untangle --example pd_accuracy [-- STEPS]`

mod common;

use untangle::geom::Vec3;
use untangle::mesh::{subdivide::subdivide, Garment};
use untangle::sim::{Integrator, SimParams, Simulator, UniformThickness};

fn params(iterations: usize, rho: f64, anderson: usize, collisions: bool) -> SimParams {
    SimParams {
        projective_anderson: anderson,
        gravity: Vec3::new(0.0, 0.0, -9.81),
        integrator: Integrator::Projective,
        projective_iterations: iterations,
        projective_chebyshev: rho,
        collisions,
        ..SimParams::default()
    }
}

fn main() {
    let steps = common::arg(1, 36);
    let Some(mut m) = common::arcsim_mesh("tshirt") else {
        return;
    };
    for _ in 0..2 {
        m = subdivide(&m);
    }
    m.uv = Some(untangle::sim::rest::isometric_uv(
        &m.positions,
        &m.triangles,
    ));
    let g = Garment::new(m.clone()).expect("valid garment");
    let make = |p: SimParams| {
        let mut sim = Simulator::new(&g, p).expect("simulator");
        common::pin_top(&mut sim, &m);
        sim
    };
    let policy = UniformThickness(2e-3);
    let d = SimParams::default();
    let mut sim = make(params(
        d.projective_iterations,
        d.projective_chebyshev,
        d.projective_anderson,
        true,
    ));
    let top = m.positions.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    sim.set_velocities(&common::sideways_push(&m, top)).unwrap();
    let samples: Vec<usize> = (0..steps).step_by(6).collect();
    let mut states = Vec::new();
    for k in 0..steps {
        if samples.contains(&k) {
            states.push((k, sim.positions().to_vec(), sim.velocities().to_vec()));
        }
        sim.step(&policy);
    }
    // (iterations, Chebyshev rho, Anderson window).
    let settings: [(usize, f64, usize); 11] = [
        (10, 0.9, 0),
        (10, 0.0, 0),
        (8, 0.9, 0),
        (7, 0.9, 0),
        (6, 0.9, 0),
        (10, 0.0, 5),
        (8, 0.0, 5),
        (7, 0.0, 5),
        (6, 0.0, 5),
        (5, 0.0, 5),
        (7, 0.0, 3),
    ];
    let solve = |x: &[Vec3], v: &[Vec3], it: usize, rho: f64, aa: usize| {
        let mut s = make(params(it, rho, aa, false));
        s.set_positions(x).unwrap();
        s.set_velocities(v).unwrap();
        let r = s.step(&policy);
        (
            s.positions().to_vec(),
            r.energy.stretch + r.energy.bend,
            s.max_stretch(),
        )
    };
    println!(
        "{:>4} {:>5} {:>5} {:>3} {:>10} {:>10} {:>11} {:>8}",
        "step", "iters", "rho", "aa", "max err", "rms err", "elastic J", "stretch"
    );
    for (k, x, v) in &states {
        let (reference, e_ref, s_ref) = solve(x, v, 300, 0.0, 0);
        let motion: Vec<f64> = reference
            .iter()
            .zip(x)
            .map(|(a, b)| (a - b).norm())
            .collect();
        let max_motion = motion.iter().cloned().fold(0.0, f64::max);
        let rms = |e: &[f64]| (e.iter().map(|a| a * a).sum::<f64>() / e.len() as f64).sqrt();
        let rms_motion = rms(&motion);
        println!(
            "{k:>4} {:>5} {:>5} {:>3} {:>10} {:>10} {e_ref:>11.4e} {s_ref:>8.4}",
            300, 0.0, 0, "-", "-"
        );
        for &(it, rho, aa) in &settings {
            let (y, e, s) = solve(x, v, it, rho, aa);
            let err: Vec<f64> = y
                .iter()
                .zip(&reference)
                .map(|(a, b)| (a - b).norm())
                .collect();
            let max_err = err.iter().cloned().fold(0.0, f64::max);
            println!(
                "{k:>4} {it:>5} {rho:>5} {aa:>3} {:>10.4} {:>10.4} {e:>11.4e} {s:>8.4}",
                max_err / max_motion,
                rms(&err) / rms_motion
            );
        }
    }
}
