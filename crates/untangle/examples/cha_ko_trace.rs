//! Diagnostic: per-step trace of the Cha & Ko loop on one exploded-handkerchief seed, with the
//! simulator's side of every step (energies, CG effort, contact springs, impulses, impact zones)
//! and the world length of the cloth's edges and of the operations' subject-target edges; then,
//! optionally, a *replay* from a snapshot: the state at step `K` continued by the simulator
//! alone (rest shape and colouring frozen at step `K`) under variants of the simulator's
//! settings, to see which part keeps stretched pulled edges from contracting.
//!
//! ```text
//! cargo run --release -p untangle --example cha_ko_trace -- SEED [CELLS] [MAX_STEPS] [REPLAY_AT] [REPLAY_STEPS]
//! ```
//!
//! Env `TRACE_EVERY` (print every n-th step, default 1), `CHAKO_AVOID_LOOP_PULL`, `CHAKO_REVOKE`,
//! and the integrator settings of `common::loop_params` (`UNTANGLE_INTEGRATOR=pd|adaptive`, ...).

mod common;

use untangle::analysis::{analyze_with, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{ResolveParams, Resolver};
use untangle::sim::{SimParams, Simulator, UniformThickness, ZoneMotion};

fn arg(i: usize, d: u64) -> u64 {
    std::env::args()
        .nth(i)
        .map(|s| s.parse().expect("a number"))
        .unwrap_or(d)
}

/// Longest and mean world edge length.
fn edge_stats(g: &Garment, x: &[Vec3]) -> (f64, f64) {
    let e = &g.topology.edges;
    let l: Vec<f64> = e
        .iter()
        .map(|e| (x[e[0] as usize] - x[e[1] as usize]).norm())
        .collect();
    (
        l.iter().cloned().fold(0.0, f64::max),
        l.iter().sum::<f64>() / l.len() as f64,
    )
}

/// Angular momentum about the centre of mass, and the kinetic energy.
fn momentum(sim: &Simulator) -> (f64, f64) {
    let (x, v, m) = (sim.positions(), sim.velocities(), sim.masses());
    let total: f64 = m.iter().sum();
    let c = (0..x.len()).fold(Vec3::zeros(), |a, i| a + x[i] * m[i]) / total;
    let l = (0..x.len()).fold(Vec3::zeros(), |a, i| a + (x[i] - c).cross(&v[i]) * m[i]);
    let ke = (0..x.len()).map(|i| 0.5 * m[i] * v[i].norm_squared()).sum();
    (l.norm(), ke)
}

/// Over the running operations: (count, longest subject-target world length, its rest length).
fn op_stats(r: &Resolver) -> (usize, f64, f64) {
    let x = r.simulator().positions();
    let cu = r.chako().current_uv();
    let mut best = (0usize, 0.0f64, 0.0f64);
    for op in r.chako().operations() {
        best.0 += 1;
        for &s in &op.subjects {
            let w = (x[s as usize] - x[op.target as usize]).norm();
            if w > best.1 {
                best.1 = w;
                best.2 = (cu[s as usize] - cu[op.target as usize]).norm();
            }
        }
    }
    best
}

fn main() {
    let seed = arg(1, 38);
    let cells = arg(2, 14) as usize;
    let max_steps = arg(3, 400) as usize;
    let replay_at = arg(4, 0) as usize;
    let replay_steps = arg(5, 50) as usize;
    let every = std::env::var("TRACE_EVERY").map_or(1, |s| s.parse().expect("a number"));
    let scene = untangle::scenes::exploded::exploded(seed, cells);
    let g = Garment::new(scene.meshes[0].clone()).expect("garment");
    let mut p = ResolveParams::default();
    p.sim.gravity = Vec3::zeros();
    p.max_steps = max_steps;
    if let Ok(v) = std::env::var("CHAKO_AVOID_LOOP_PULL") {
        p.cha_ko.avoid_loop_pull_targets = v != "0";
    }
    if let Ok(v) = std::env::var("CHAKO_REVOKE") {
        p.cha_ko.revoke_levels_per_step = v.parse().expect("a number");
    }
    if std::env::var("CHAKO_ZONE_TRANSLATE").is_ok_and(|v| v != "0") {
        p.sim.zone_motion.spin = false;
    }
    if let Ok(v) = std::env::var("CHAKO_ZONE_SOFT") {
        p.sim.zone_motion.soft_levels = v.parse().expect("a number");
    }
    common::loop_params(&mut p);
    let mut r = Resolver::new(&g, p.clone()).expect("resolver");
    println!("step pairs red | KE Es | cg it conv | springs prox imp zones zv stall | edge max mean | ops n wmax rest | L_end KE_end");
    let mut snapshot = None;
    loop {
        if let Some(o) = r.stop_reason() {
            println!("outcome {o:?} after {} steps", r.history().len());
            break;
        }
        let i = r.history().len();
        if replay_at > 0 && i == replay_at {
            snapshot = Some((
                r.simulator().positions().to_vec(),
                r.simulator().velocities().to_vec(),
                r.chako().current_uv().to_vec(),
            ));
            break;
        }
        let (st, sr) = r.step().expect("step");
        if i % every == 0 {
            let (emax, emean) = edge_stats(&g, r.simulator().positions());
            let (nops, wmax, rest) = op_stats(&r);
            let (l_end, ke_end) = momentum(r.simulator());
            println!(
                "{i} {} {} | {:.3e} {:.3e} | {} {} | {} {} {} {} {} {} | {:.3} {:.4} | {} {:.3} {:.4} | {:.3e} {:.3e}",
                st.intersecting_pairs,
                st.red_vertices,
                sr.energy.kinetic,
                sr.energy.stretch,
                sr.cg.iterations,
                sr.cg.converged as u8,
                sr.contact_springs,
                sr.collisions.proximity_impulses,
                sr.collisions.impulses,
                sr.collisions.impact_zones,
                sr.collisions.zone_vertices,
                sr.collisions.stalled as u8,
                emax,
                emean,
                nops,
                wmax,
                rest,
                l_end,
                ke_end
            );
        }
    }
    let Some((x, v, uv)) = snapshot else { return };
    // Replay: the simulator alone from the snapshot, rest shape frozen, under variants.
    let (am, _) = AnalysisMesh::single(&g.mesh).expect("analysis mesh");
    let a = analyze_with(&am, &x, &p.analysis).expect("analysis");
    let policy = r.chako().contact_policy(&am, &a);
    let base = {
        let mut s = p.sim.clone();
        s.dt = p.cha_ko.dt;
        s
    };
    let variants: Vec<(&str, SimParams, bool)> = vec![
        ("loop settings (m-CCH)", base.clone(), true),
        (
            "collisions off",
            SimParams {
                collisions: false,
                ..base.clone()
            },
            true,
        ),
        (
            "contacts_within_reach off",
            SimParams {
                contacts_within_reach: false,
                ..base.clone()
            },
            true,
        ),
        (
            "CG cap 2000, tol 1e-6",
            SimParams {
                cg_max_iterations: 2000,
                cg_tolerance: 1e-6,
                ..base.clone()
            },
            true,
        ),
        (
            "impulse passes 100",
            SimParams {
                max_impulse_iterations: 100,
                ..base.clone()
            },
            true,
        ),
        (
            "zones translate",
            SimParams {
                zone_motion: ZoneMotion {
                    spin: false,
                    soft_levels: 0,
                },
                ..base.clone()
            },
            true,
        ),
        ("plain CCH eps (no red-red skip)", base.clone(), false),
    ];
    for (name, sp, mcch) in variants {
        let mut sim = Simulator::new(&g, sp).expect("simulator");
        sim.set_positions(&x).expect("positions");
        sim.set_velocities(&v).expect("velocities");
        sim.set_rest_uv(&uv).expect("rest uv");
        println!("--- replay from step {replay_at}: {name}");
        for k in 0..replay_steps {
            let sr = if mcch {
                sim.step(&policy)
            } else {
                sim.step(&UniformThickness(1e-6))
            };
            if k % 5 == 0 || k + 1 == replay_steps {
                let (emax, emean) = edge_stats(&g, sim.positions());
                let (l_end, _) = momentum(&sim);
                println!(
                    "  {k}: KE {:.3e} Es {:.3e} cg {} {} springs {} imp {} zones {} zv {} | edge max {:.3} mean {:.4} | L {:.3e}",
                    sr.energy.kinetic,
                    sr.energy.stretch,
                    sr.cg.iterations,
                    sr.cg.converged as u8,
                    sr.contact_springs,
                    sr.collisions.impulses,
                    sr.collisions.impact_zones,
                    sr.collisions.zone_vertices,
                    emax,
                    emean,
                    l_end
                );
            }
        }
    }
}
