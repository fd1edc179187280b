//! Diagnostic: how well the world mesh of the Cha & Ko loop follows its uv edits (Sec. 5.2-5.3,
//! Fig. 1b). A pull or shrink only edits the uv rest shape; one implicit step must then shorten
//! the subject-target edges, and the m-CCH (proximity impulses, CCD impulses, impact zones) may
//! undo part of that motion. For every running operation and every step, with `l` the edge's uv
//! rest length after the step's uv update, `w0` its world length before the simulator step, `ws`
//! at the solve's end positions (before the collision handling) and `w1` after the step:
//!
//! - `ratio` = `w1 / l` (1: the edge reached its target in one step),
//! - `solve` = `(w0 - ws) / (w0 - l)`, the share of the remaining shortening the solve achieved,
//! - `step` = `(w0 - w1) / (w0 - l)`, the share the whole step kept (the collision handling
//!   removed `solve - step`); both only over edges longer than `1.05 l` before the step;
//!   `far` restricts them to targets `l > 2 eps_RG` (below `eps_RG` the red-green thickness
//!   around the target necessarily holds the subject back: the finesse of Sec. 7).
//!
//! Per seed it prints the outcome and the quantiles of these over all (operation, step) samples,
//! and the means per step of the collision handling's effort and of the kinetic energy. Seeds
//! and the loop's knobs as in `cha_ko_exploded` (`common::loop_params`, `CHAKO_SIM_*`,
//! `CHAKO_ZONE_SOFT`, `CHAKO_REVOKE`); `FOLLOW_TRACE=1` prints one line per step.
//!
//! `FOLLOW_SPLIT=1` also replays every step from a snapshot with the proximity pass off (CCD
//! impulses and impact zones only; the colouring of a fresh analysis of the step's start, so
//! without slit ridges) and reports that step's share as `no-prox`: `solve - no-prox` is what
//! CCD and the zones removed, `no-prox - step` roughly what proximity removed. The replay is
//! undone, so the loop runs as without it.
//!
//! ```text
//! cargo run --release -p untangle --example cha_ko_follow -- [first_seed] [last_seed] [cells] [max_steps]
//! ```

mod common;

use untangle::analysis::{analyze_with, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{ResolveParams, Resolver};

fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let (first, last) = (common::arg(1, 1), common::arg(2, 4));
    let (cells, max_steps) = (common::arg(3, 14), common::arg(4, 400));
    let trace = std::env::var("FOLLOW_TRACE").is_ok_and(|v| v != "0");
    let split = std::env::var("FOLLOW_SPLIT").is_ok_and(|v| v != "0");
    println!("| seed | outcome | steps | samples | ratio w1/l p50 / p90 | solve share p50 / p10 | step share p50 / p10 | far: samples, solve / step share p50 | no-prox share p50 (all / far) | steps with zones | zone vertices / step | impulses / step | proximity / step | KE / step (J) | shift mean (mm) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for seed in first..=last {
        let scene = untangle::scenes::exploded::exploded(seed as u64, cells);
        let g = Garment::new(scene.meshes[0].clone()).expect("garment");
        let mut p = ResolveParams::default();
        p.sim.gravity = Vec3::zeros();
        p.max_steps = max_steps;
        common::loop_params(&mut p);
        let env = |k: &str| std::env::var(k).ok().map(|s| s.parse::<f64>().expect(k));
        if let Some(v) = env("CHAKO_ZONE_SOFT") {
            p.sim.zone_motion.soft_levels = v as u32;
        }
        if let Some(v) = env("CHAKO_REVOKE") {
            p.cha_ko.revoke_levels_per_step = v as u32;
        }
        let h = p.cha_ko.dt;
        let mut r = Resolver::new(&g, p).expect("resolver");
        let eps_rg = r.chako().eps_rg();
        let (mut ratio, mut solve, mut step) = (Vec::new(), Vec::new(), Vec::new());
        let (mut far_solve, mut far_step) = (Vec::new(), Vec::new());
        let (mut noprox, mut far_noprox) = (Vec::new(), Vec::new());
        let analysis_opts = ResolveParams::default().analysis;
        let (am, _) = AnalysisMesh::single(&g.mesh).expect("analysis mesh");
        let (mut zone_steps, mut zv, mut imp, mut prox, mut ke, mut shift) =
            (0usize, 0usize, 0usize, 0usize, 0.0, 0.0);
        let outcome = loop {
            if let Some(o) = r.stop_reason() {
                break o;
            }
            let x0: Vec<Vec3> = r.simulator().positions().to_vec();
            let before = split.then(|| r.simulator().snapshot());
            let (st, sr) = r.step().expect("loop step");
            // The replay without proximity: end positions of the same step.
            let x_np: Option<Vec<Vec3>> = before.and_then(|before| {
                let a = analyze_with(&am, &x0, &analysis_opts).ok()?;
                let after = r.simulator().snapshot();
                let sp = r.simulator().params().clone();
                let policy = r.chako().contact_policy(&am, &a);
                let sim = r.simulator_mut();
                sim.restore(&before).expect("restore");
                sim.set_params(untangle::sim::SimParams {
                    proximity: false,
                    ..sp.clone()
                })
                .expect("params");
                sim.step(&policy);
                let x = sim.positions().to_vec();
                sim.restore(&after).expect("restore");
                sim.set_params(sp).expect("params");
                Some(x)
            });
            let x1 = r.simulator().positions();
            let vs = r.simulator().solved_velocities();
            let cu = r.chako().current_uv();
            let (mut sr_ratio, mut sr_solve, mut sr_step) = (Vec::new(), Vec::new(), Vec::new());
            for op in r.chako().operations() {
                let t = op.target as usize;
                for &s in &op.subjects {
                    let s = s as usize;
                    let l = (cu[s] - cu[t]).norm();
                    let w0 = (x0[s] - x0[t]).norm();
                    let w1 = (x1[s] - x1[t]).norm();
                    sr_ratio.push(w1 / l);
                    if w0 > 1.05 * l && !vs.is_empty() {
                        let ws = ((x0[s] + vs[s] * h) - (x0[t] + vs[t] * h)).norm();
                        sr_solve.push((w0 - ws) / (w0 - l));
                        sr_step.push((w0 - w1) / (w0 - l));
                        if l > 2.0 * eps_rg {
                            far_solve.push((w0 - ws) / (w0 - l));
                            far_step.push((w0 - w1) / (w0 - l));
                        }
                        if let Some(xn) = &x_np {
                            let wn = (xn[s] - xn[t]).norm();
                            noprox.push((w0 - wn) / (w0 - l));
                            if l > 2.0 * eps_rg {
                                far_noprox.push((w0 - wn) / (w0 - l));
                            }
                        }
                    }
                }
            }
            let c = &sr.collisions;
            zone_steps += (c.impact_zones > 0) as usize;
            zv += c.zone_vertices;
            imp += c.impulses;
            prox += c.proximity_impulses;
            ke += sr.energy.kinetic;
            shift += sr.collision_shift.mean;
            if trace {
                let n = sr_ratio.len();
                eprintln!(
                    "seed {seed} step {} pairs {} red {} ops {} | ratio p50 {:.3} max {:.3} | solve p50 {:.3} step p50 {:.3} | prox {} imp {} zones {} zv {} | KE {:.3e} shift {:.2e}",
                    st.step,
                    st.intersecting_pairs,
                    st.red_vertices,
                    n,
                    quantile(&mut sr_ratio, 0.5),
                    quantile(&mut sr_ratio, 1.0),
                    quantile(&mut sr_solve, 0.5),
                    quantile(&mut sr_step, 0.5),
                    c.proximity_impulses,
                    c.impulses,
                    c.impact_zones,
                    c.zone_vertices,
                    sr.energy.kinetic,
                    sr.collision_shift.mean
                );
            }
            ratio.extend(sr_ratio);
            solve.extend(sr_solve);
            step.extend(sr_step);
        };
        let n = r.history().len().max(1) as f64;
        let samples = ratio.len();
        println!(
            "| {seed} | {outcome:?} | {} | {samples} | {:.3} / {:.3} | {:.3} / {:.3} | {:.3} / {:.3} | {}, {:.3} / {:.3} | {:.3} / {:.3} | {zone_steps} | {:.1} | {:.1} | {:.1} | {:.2e} | {:.3} |",
            r.history().len(),
            quantile(&mut ratio, 0.5),
            quantile(&mut ratio, 0.9),
            quantile(&mut solve, 0.5),
            quantile(&mut solve, 0.1),
            quantile(&mut step, 0.5),
            quantile(&mut step, 0.1),
            far_solve.len(),
            quantile(&mut far_solve, 0.5),
            quantile(&mut far_step, 0.5),
            quantile(&mut noprox, 0.5),
            quantile(&mut far_noprox, 0.5),
            zv as f64 / n,
            imp as f64 / n,
            prox as f64 / n,
            ke / n,
            shift / n * 1e3
        );
    }
}
