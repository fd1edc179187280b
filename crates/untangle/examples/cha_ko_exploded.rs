//! Cha & Ko 2022, Sec. 9.2 over many seeds: the exploded handkerchief (`scenes::exploded`,
//! 14 x 14 cells = 392 triangles; the paper's had 388) run through the whole loop of Fig. 1b
//! (`Resolver`, gravity off) for each seed. Per seed it prints the steps until resolved (clean
//! and every uv edit revoked), the first clean step, whether the red-vertex count never increased
//! from one step to the next (the paper's theorem, part 1), the first increase if any, whether an
//! independent analysis of the final positions is clean, the wall time and the largest relative
//! edge stretch (over the run / at the end); then the summary
//! (resolved, median steps, monotone seeds) and the inputs' median intersecting triangles and
//! pairs. `EXPLODE_R0`, `EXPLODE_CENTRAL`, `EXPLODE_DISC` change the explosion
//! (`common::exploded_scene`). `CHAKO_SAVE_DIR=DIR` writes the final cloth of
//! every seed that did not resolve as `DIR/seedS.obj` (for `untangle check`).
//!
//! ```text
//! cargo run --release -p untangle --example cha_ko_exploded -- [first_seed] [last_seed] [cells] [max_steps]
//! ```

use std::time::Instant;
mod common;

use untangle::analysis::{analyze, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{Outcome, ResolveParams, Resolver};

fn main() {
    let arg = |i: usize, d: u64| {
        std::env::args()
            .nth(i)
            .map(|s| s.parse().expect("a number"))
            .unwrap_or(d)
    };
    let (first, last, cells, max_steps) = (arg(1, 1), arg(2, 50), arg(3, 14), arg(4, 400));
    println!("| seed | pairs | outcome | steps | clean at | red monotone | first increase (step: from -> to) | increases | final clean (independent) | wall s | trial: steps retried / retries / accepted with increase | max stretch (run / final) | BW steps / switches |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut trial_total = [0usize; 3];
    let mut steps_resolved = Vec::new();
    // Per seed, the input's intersecting triangles and pairs (the paper's scene: 163 and ~3,830).
    let mut input_stats: Vec<(u64, u64)> = Vec::new();
    let mut resolved = 0;
    let mut monotone = 0;
    let mut independent_clean = 0;
    let mut total = 0;
    // Steps in which the divergence guard saw a diverged simulator step, over all seeds.
    let mut diverged_steps = 0;
    // The largest step energy growth the guard saw (`DivergenceReport::growth`), and its seed.
    let mut largest_growth = (0.0f64, 0u64);
    let t_all = Instant::now();
    for seed in first..=last {
        total += 1;
        let scene = common::exploded_scene(seed, cells as usize);
        let g = Garment::new(scene.meshes[0].clone()).expect("garment");
        let (am, pos) = AnalysisMesh::single(&g.mesh).expect("analysis mesh");
        let a = analyze(&am, &pos).expect("analysis");
        input_stats.push((
            a.intersecting_triangles().len() as u64,
            a.segments.len() as u64,
        ));
        let mut p = ResolveParams::default();
        p.sim.gravity = Vec3::zeros();
        p.max_steps = max_steps as usize;
        // UNTANGLE_INTEGRATOR=projective: projective dynamics; the loop simulator's material,
        // damping, CG, CCD and friction knobs CHAKO_SIM_* and CHAKO_EPS (see `common`).
        common::loop_params(&mut p);
        // Parameter experiments: CHAKO_SLIT=0|1 (slit ridges, on by default), CHAKO_SLIT_STALL, CHAKO_REGIONLESS_AFTER (0 = off), CHAKO_MAX_LEVEL, CHAKO_HOLD, CHAKO_REVOKE, CHAKO_GAMMA,
        // CHAKO_PERSIST, CHAKO_MIXED (0 1 2), CHAKO_AVOID_LOOP_PULL, CHAKO_LAST_RESORT,
        // CHAKO_ZONE_SPIN (0: impact zones translate), CHAKO_ZONE_SOFT (soft zone levels),
        // CHAKO_AVOID_LOOP_PULL_START, CHAKO_TRIAL (retries of the trial step, 0 = off),
        // CHAKO_TRIAL_BLOCK (0: blocked pairs green-green, 1: red-green), CHAKO_TRIAL_TRIGGER
        // (0: any newly red vertex, 1: the count went up), CHAKO_TRIAL_SCOPE (0: crossings at
        // the newly red vertices' edges and triangles, 1: edges only), CHAKO_TRIAL_RELEASE (a
        // pair blocked this many steps in a row may cross; 0 = never).
        let env = |k: &str| std::env::var(k).ok().map(|s| s.parse::<f64>().expect(k));
        if let Some(v) = env("CHAKO_SLIT") {
            p.slit_ridges = v != 0.0;
        }
        if let Some(v) = env("CHAKO_SLIT_STALL") {
            p.slit_stall = v as usize;
        }
        if let Some(v) = env("CHAKO_REGIONLESS_AFTER") {
            p.regionless_after = v as usize;
        }
        if let Some(v) = env("CHAKO_MAX_LEVEL") {
            p.cha_ko.max_level = v as u32;
        }
        if let Some(v) = env("CHAKO_HOLD") {
            p.cha_ko.hold_steps = v as u32;
        }
        if let Some(v) = env("CHAKO_REVOKE") {
            p.cha_ko.revoke_levels_per_step = v as u32;
        }
        if let Some(v) = env("CHAKO_PERSIST") {
            p.cha_ko.persistent_green = v != 0.0;
        }
        if let Some(v) = env("CHAKO_MIXED") {
            use untangle::methods::cha_ko::MixedEdges;
            p.cha_ko.mixed_edges =
                [MixedEdges::Red, MixedEdges::Green, MixedEdges::NotWithMixed][v as usize];
        }
        if let Some(v) = env("CHAKO_AVOID_LOOP_PULL") {
            p.cha_ko.avoid_loop_pull_targets = v != 0.0;
        }
        if let Some(v) = env("CHAKO_AVOID_LOOP_PULL_START") {
            p.cha_ko.avoid_loop_pull_targets_at_start = v != 0.0;
        }
        if let Some(v) = env("CHAKO_LAST_RESORT") {
            p.cha_ko.loop_target_last_resort = v != 0.0;
        }
        if let Some(v) = env("CHAKO_ZONE_SPIN") {
            p.sim.zone_motion.spin = v != 0.0;
        }
        if let Some(v) = env("CHAKO_ZONE_SOFT") {
            p.sim.zone_motion.soft_levels = v as u32;
        }
        if let Some(v) = env("CHAKO_GAMMA") {
            p.cha_ko.gamma = v;
        }
        common::trial_params(&mut p.cha_ko);
        common::schedule_params(&mut p.cha_ko);
        // CHAKO_TRACE=1: one line per step on stderr.
        let trace = env("CHAKO_TRACE").is_some_and(|v| v != 0.0);
        let t = Instant::now();
        let mut r = Resolver::new(&g, p).expect("resolver");
        let mut reds: Vec<usize> = Vec::new();
        // Trial step: steps with a retry, retries, steps accepted with a newly red vertex.
        let mut trial = [0usize; 3];
        let (s, tracked) = common::run_tracking(&mut r, |st, _| {
            if trace {
                eprintln!(
                        "seed {seed} step {} pairs {} red {} ops {} pulls {}+{} shrinks {}+{} | trial retries {} newly red {} -> {} blocked {} all_new {} stop {} released {} | zones {} ms sim {:.0}",
                        st.step,
                        st.intersecting_pairs,
                        st.red_vertices,
                        st.uv.active_ops,
                        st.uv.pulls_started,
                        st.uv.pulls_continued,
                        st.uv.shrinks_started,
                        st.uv.shrinks_continued,
                        st.trial.retries,
                        st.trial.newly_red_first,
                        st.trial.newly_red_accepted,
                        st.trial.blocked_pairs,
                        st.trial.blocked_all_new,
                        st.trial.nothing_new_to_block,
                        st.trial.released,
                        st.impact_zones,
                        st.ms_sim
                    );
            }
            reds.push(st.red_vertices);
            trial[0] += (st.trial.retries > 0) as usize;
            trial[1] += st.trial.retries as usize;
            trial[2] += (st.trial.red_increase_accepted > 0) as usize;
        });
        trial_total.iter_mut().zip(trial).for_each(|(t, x)| *t += x);
        // CHAKO_DIAG=1: where the steps went (phases, waiting steps, finesse lives) on stderr.
        if env("CHAKO_DIAG").is_some_and(|v| v != 0.0) {
            diagnose(seed, &r, env("CHAKO_DIAG") == Some(2.0));
        }
        let wall = t.elapsed().as_secs_f64();
        diverged_steps += r
            .history()
            .iter()
            .filter(|s| s.divergence.diverged > 0)
            .count();
        for h in r.history() {
            if h.divergence.growth > largest_growth.0 {
                largest_growth = (h.divergence.growth, seed);
            }
        }
        let increases: Vec<(usize, usize, usize)> = reds
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[1] > w[0])
            .map(|(i, w)| (i + 1, w[0], w[1]))
            .collect();
        let clean = analyze(&am, r.simulator().positions()).is_ok_and(|a| a.is_clean());
        let ok = s.outcome == Outcome::Resolved;
        if let (false, Ok(dir)) = (ok, std::env::var("CHAKO_SAVE_DIR")) {
            let mut m = g.mesh.clone();
            m.positions = r.simulator().positions().to_vec();
            let path = std::path::Path::new(&dir).join(format!("seed{seed}.obj"));
            untangle::mesh::obj::write_obj(&path, &m, None, "").expect("write");
        }
        if ok {
            resolved += 1;
            steps_resolved.push(s.steps);
        }
        if increases.is_empty() {
            monotone += 1;
        }
        if clean {
            independent_clean += 1;
        }
        println!(
            "| {seed} | {} | {:?} | {} | {} | {} | {} | {} | {} | {:.1} | {} / {} / {} | {:.3} / {:.3} | {} |",
            s.initial_pairs,
            s.outcome,
            s.steps,
            s.clean_at.map_or("-".into(), |c| c.to_string()),
            if increases.is_empty() { "yes" } else { "no" },
            increases
                .first()
                .map_or("-".into(), |(i, a, b)| format!("{i}: {a} -> {b}")),
            increases.len(),
            if clean { "yes" } else { "no" },
            wall,
            trial[0],
            trial[1],
            trial[2],
            tracked.max_stretch,
            tracked.final_stretch,
            common::integrator_use(&r)
        );
    }
    let median_steps = median(steps_resolved);
    println!();
    println!(
        "input: median intersecting triangles {}, median intersecting pairs {}",
        median(input_stats.iter().map(|s| s.0).collect()),
        median(input_stats.iter().map(|s| s.1).collect())
    );
    println!(
        "seeds {first}-{last}, {cells}x{cells} cells: resolved {resolved}/{total}, final state clean by an independent analysis {independent_clean}/{total}, median steps (resolved) {median_steps}, red-vertex count monotone {monotone}/{total}, trial: steps retried {} retries {} accepted with increase {}, steps with a diverged simulator step {diverged_steps} (largest step energy growth {:.2}x, seed {}), total wall {:.0} s",
        trial_total[0],
        trial_total[1],
        trial_total[2],
        largest_growth.0,
        largest_growth.1,
        t_all.elapsed().as_secs_f64()
    );
}

/// The median of `v` (the mean of the two middle values for an even count; NaN when empty).
fn median(mut v: Vec<u64>) -> f64 {
    v.sort_unstable();
    let n = v.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => v[n / 2] as f64,
        _ => (v[n / 2 - 1] + v[n / 2]) as f64 / 2.0,
    }
}

/// Where the steps of one run went (`CHAKO_DIAG=1`), one block on stderr: the phases (red
/// vertices left / no red vertex but intersecting / clean and only revoking), steps that only
/// waited (nothing started or advanced), what blocked candidates, and the finesse lives by kind
/// and end (the paper's Table 1 measures start -> completion, t*).
/// With `log` (`CHAKO_DIAG=2`) also every operation of the finesse log, one line each.
fn diagnose(seed: u64, r: &Resolver, log_lines: bool) {
    use untangle::methods::cha_ko::{EndReason, OpKind};
    let h = r.history();
    let (mut red, mut nored, mut clean, mut wait, mut wait_red) = (0, 0, 0, 0, 0);
    let (mut bf, mut bs, mut tit, mut paused, mut sat, mut act, mut started) =
        (0, 0, 0, 0, 0, 0, 0);
    for st in h {
        let u = &st.uv;
        if st.intersecting_pairs == 0 {
            clean += 1;
        } else if st.red_vertices > 0 {
            red += 1;
        } else {
            nored += 1;
        }
        let moves = u.pulls_started + u.shrinks_started + u.pulls_continued + u.shrinks_continued;
        if moves == 0 && st.intersecting_pairs > 0 {
            wait += 1;
            wait_red += (st.red_vertices > 0) as usize;
        }
        bf += u.blocked_fan;
        bs += u.blocked_subject;
        tit += u.tit_rejected;
        paused += u.paused;
        sat += u.saturated_ops;
        act += u.active_ops;
        started += u.pulls_started + u.shrinks_started;
    }
    let n = h.len().max(1);
    eprintln!(
        "seed {seed}: {} steps: red>0 {red}, red=0 intersecting {nored}, clean {clean}; wait-only {wait} ({wait_red} with red); per step: active ops {:.1}, started {:.2}, blocked fan {:.1} subject {:.1}, tit rejected {:.1}, paused {:.1}, saturated {:.1}",
        h.len(),
        act as f64 / n as f64,
        started as f64 / n as f64,
        bf as f64 / n as f64,
        bs as f64 / n as f64,
        tit as f64 / n as f64,
        paused as f64 / n as f64,
        sat as f64 / n as f64,
    );
    let log = r.chako().finesse_log();
    for kind in [OpKind::Pull, OpKind::Shrink] {
        for end in [
            Some(EndReason::Finished),
            Some(EndReason::Superseded),
            Some(EndReason::Abandoned),
            None,
        ] {
            let v: Vec<_> = log
                .iter()
                .filter(|f| f.kind == kind && f.end == end)
                .collect();
            if v.is_empty() {
                continue;
            }
            let mean = |f: &dyn Fn(&&untangle::methods::cha_ko::FinesseRecord) -> Option<f64>| {
                let xs: Vec<f64> = v.iter().filter_map(f).collect();
                if xs.is_empty() {
                    f64::NAN
                } else {
                    xs.iter().sum::<f64>() / xs.len() as f64
                }
            };
            eprintln!(
                "  {kind:?} {end:?}: {} ops, start->end {:.1}, end->restored {:.1}, max level {:.1}, saturated {}",
                v.len(),
                mean(&|f| f.end_step.map(|e| (e - f.start_step) as f64)),
                mean(&|f| f.end_step.zip(f.restored_step).map(|(e, s)| (s - e) as f64)),
                mean(&|f| Some(f.max_level as f64)),
                v.iter().filter(|f| f.saturated_step.is_some()).count()
            );
        }
    }
    // Per 10-step window: mean red vertices, pairs, active ops, started, finished.
    let mut line = String::new();
    for (w, chunk) in h.chunks(10).enumerate() {
        let fin = log
            .iter()
            .filter(|f| f.end == Some(EndReason::Finished))
            .filter(|f| f.end_step.is_some_and(|e| (e as usize) / 10 == w))
            .count();
        let m = |g: &dyn Fn(&untangle::methods::cha_ko::LoopStep) -> usize| {
            chunk.iter().map(g).sum::<usize>() as f64 / chunk.len() as f64
        };
        line += &format!(
            " [{}: p{:.0} r{:.0} a{:.1} s{:.1} f{fin}]",
            w * 10,
            m(&|s| s.intersecting_pairs),
            m(&|s| s.red_vertices),
            m(&|s| s.uv.active_ops),
            m(&|s| s.uv.pulls_started + s.uv.shrinks_started),
        );
    }
    eprintln!("  windows (pairs, red, active, started, finished):{line}");
    if log_lines {
        for f in log {
            eprintln!(
                "  op {} {:?} {:?} -> {} tri {:?}: start {} end {:?} {:?} restored {:?} max level {} saturated {:?} fallback {:?}",
                f.id, f.kind, f.subjects, f.target, f.triangle, f.start_step, f.end_step, f.end,
                f.restored_step, f.max_level, f.saturated_step, f.fallback
            );
        }
    }
}
