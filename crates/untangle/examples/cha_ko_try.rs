//! One run of the Cha & Ko loop (Fig. 1b) on a named scene, printing every step (pairs,
//! tanglements, red vertices/triangles, operations, stalls, impact zones, milliseconds) and the
//! summary as JSON. Used for the rudimentary-case and ablation tables of BENCHMARKS.md.
//!
//! `cargo run --release -p untangle --example cha_ko_try -- NAME [SIZE] [SEED] [MAX_LEVEL] [HOLD]`
//! with NAME a scene of `untangle scene` (`closed`, `ll`, `eight`, `cross`, `bbii`, `bibi`, `bli`)
//! or `exploded` (SIZE = cells per side); env `MAX_STEPS`, `STUCK`, `NO_UV=1` (m-CCH alone),
//! `CHAKO_ZONE_SOFT`, `CHAKO_ZONE_SPIN` (the simulator's `ZoneMotion`), `CHAKO_AVOID_LOOP_PULL`,
//! `CHAKO_REVOKE`, the trial step's `CHAKO_TRIAL*` (see `common::trial_params`),
//! `UNTANGLE_INTEGRATOR` and `UNTANGLE_PD_CG_CAP` (see `common::loop_params`); `AFTER=N` runs N
//! plain simulator steps after the loop (stretch and energies every 10 steps).
mod common;

use untangle::analysis::AnalysisMesh;
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{ResolveParams, Resolver};

fn main() {
    let which = std::env::args().nth(1).unwrap_or("closed".into());
    let n: usize = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(12);
    let seed: u64 = std::env::args()
        .nth(3)
        .map(|s| s.parse().unwrap())
        .unwrap_or(1);
    let g = if which != "exploded" {
        let scene = untangle::scenes::by_name(&which, (n > 0).then_some(n), seed).unwrap();
        Garment::new(AnalysisMesh::merge_cloth(&scene.meshes).unwrap()).unwrap()
    } else {
        Garment::new(untangle::scenes::exploded::exploded(seed, n).meshes[0].clone()).unwrap()
    };
    let mut p = ResolveParams::default();
    p.sim.gravity = Vec3::zeros();
    p.max_steps = std::env::var("MAX_STEPS").map_or(400, |s| s.parse().unwrap());
    if let Ok(s) = std::env::var("STUCK") {
        p.stuck_steps = s.parse().unwrap();
    }
    // Impact-zone motion of the simulator (`sim::ZoneMotion`).
    if let Ok(v) = std::env::var("CHAKO_ZONE_SOFT") {
        p.sim.zone_motion.soft_levels = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("CHAKO_ZONE_SPIN") {
        p.sim.zone_motion.spin = v != "0";
    }
    if let Ok(v) = std::env::var("CHAKO_AVOID_LOOP_PULL") {
        p.cha_ko.avoid_loop_pull_targets = v != "0";
    }
    if let Ok(v) = std::env::var("CHAKO_REVOKE") {
        p.cha_ko.revoke_levels_per_step = v.parse().unwrap();
    }
    common::trial_params(&mut p.cha_ko);
    // UNTANGLE_INTEGRATOR=pd, UNTANGLE_PD_CG_CAP (see `common::loop_params`).
    common::loop_params(&mut p);
    // Ablation: m-CCH alone, no uv-space update.
    p.uv_update = std::env::var("NO_UV").is_err();
    if !p.uv_update {
        p.stuck_steps = usize::MAX;
    }
    if let Some(l) = std::env::args().nth(4) {
        p.cha_ko.max_level = l.parse().unwrap();
    }
    if let Some(h) = std::env::args().nth(5) {
        p.cha_ko.hold_steps = h.parse().unwrap();
    }
    let mut r = Resolver::new(&g, p).unwrap();
    let (s, tracked) = common::run_tracking(&mut r, |st, sr| {
        println!(
                "{} pairs {} tang {} red {} rtri {} | pull +{} ~{} shrink +{} ~{} rev {} blk {}/{} act {} sat {} fb {} st {} | trial {} new {} inc {} blk {} | aq {} z {} | {:.1} {:.1} {:.1} ms | stretch {:.3} shift {:.4} / {:.5}",
                st.step, st.intersecting_pairs, st.tanglements, st.red_vertices, st.red_triangles,
                st.uv.pulls_started, st.uv.pulls_continued, st.uv.shrinks_started, st.uv.shrinks_continued,
                st.uv.revoked_levels, st.uv.blocked_fan, st.uv.blocked_subject, st.uv.active_ops, st.uv.saturated_ops,
                st.uv.fallbacks.len(), st.uv.stalls.len(),
                st.trial.retries, st.trial.newly_red_first, st.trial.red_increase_accepted, st.trial.blocked_pairs,
                st.administrative_quit, st.impact_zones, st.ms_analysis, st.ms_uv, st.ms_sim, sr.max_stretch,
                sr.collision_shift.max, sr.collision_shift.mean
            )
    });
    println!(
        "max stretch (run / final) {:.3} / {:.3}, final elastic / kinetic energy {:.3e} / {:.3e} J, mean collision shift {:.5} m, BW steps / switches {}",
        tracked.max_stretch, tracked.final_stretch, tracked.final_elastic, tracked.final_kinetic, tracked.mean_shift,
        common::integrator_use(&r)
    );
    // AFTER=N: N more plain simulator steps (collision thickness `eps`, the loop's simulator and
    // settings) after the loop, printing the stretch and energies every 10 steps.
    let after: usize = std::env::var("AFTER").map_or(0, |s| s.parse().unwrap());
    let eps = r.chako().params().eps;
    for k in 1..=after {
        let sr = r
            .simulator_mut()
            .step(&untangle::sim::UniformThickness(eps));
        if k % 10 == 0 || k == after {
            println!(
                "after {k}: max stretch {:.3}, elastic / kinetic energy {:.3e} / {:.3e} J",
                sr.max_stretch,
                sr.energy.stretch + sr.energy.bend,
                sr.energy.kinetic
            );
        }
    }
    let mut s2 = s.clone();
    s2.stalls.truncate(5);
    println!("{}", serde_json::to_string(&s2).unwrap());
}
