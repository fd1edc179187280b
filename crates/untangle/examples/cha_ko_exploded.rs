//! Cha & Ko 2022, Sec. 9.2 over many seeds: the exploded handkerchief (`scenes::exploded`,
//! 14 x 14 cells = 392 triangles; the paper's had 388) run through the whole loop of Fig. 1b
//! (`Resolver`, gravity off) for each seed. Per seed it prints the steps until resolved (clean
//! and every uv edit revoked), the first clean step, whether the red-vertex count never increased
//! from one step to the next (the paper's theorem, part 1), the first increase if any, whether an
//! independent analysis of the final positions is clean, and the wall time; then the summary
//! (resolved, median steps, monotone seeds).
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
    println!("| seed | pairs | outcome | steps | clean at | red monotone | first increase (step: from -> to) | increases | final clean (independent) | wall s |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut steps_resolved = Vec::new();
    let mut resolved = 0;
    let mut monotone = 0;
    let mut independent_clean = 0;
    let mut total = 0;
    let t_all = Instant::now();
    for seed in first..=last {
        total += 1;
        let scene = untangle::scenes::exploded::exploded(seed, cells as usize);
        let g = Garment::new(scene.meshes[0].clone()).expect("garment");
        let mut p = ResolveParams::default();
        p.sim.gravity = Vec3::zeros();
        p.max_steps = max_steps as usize;
        // UNTANGLE_INTEGRATOR=projective: projective dynamics (see `common`).
        p.sim = common::integrator_params(p.sim);
        // Parameter experiments: CHAKO_MAX_LEVEL, CHAKO_HOLD, CHAKO_REVOKE, CHAKO_GAMMA,
        // CHAKO_PERSIST, CHAKO_MIXED (0 1 2), CHAKO_AVOID_LOOP_PULL, CHAKO_LAST_RESORT,
        // CHAKO_ZONE_SPIN (0: impact zones translate), CHAKO_ZONE_SOFT (soft zone levels),
        // CHAKO_AVOID_LOOP_PULL_START.
        let env = |k: &str| std::env::var(k).ok().map(|s| s.parse::<f64>().expect(k));
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
        let t = Instant::now();
        let mut r = Resolver::new(&g, p).expect("resolver");
        let mut reds: Vec<usize> = Vec::new();
        let s = r.run(|st| reds.push(st.red_vertices)).expect("run");
        let wall = t.elapsed().as_secs_f64();
        let increases: Vec<(usize, usize, usize)> = reds
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[1] > w[0])
            .map(|(i, w)| (i + 1, w[0], w[1]))
            .collect();
        let (am, _) = AnalysisMesh::single(&g.mesh).expect("analysis mesh");
        let clean = analyze(&am, r.simulator().positions()).is_ok_and(|a| a.is_clean());
        let ok = s.outcome == Outcome::Resolved;
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
            "| {seed} | {} | {:?} | {} | {} | {} | {} | {} | {} | {:.1} |",
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
            wall
        );
    }
    steps_resolved.sort_unstable();
    let median = if steps_resolved.is_empty() {
        f64::NAN
    } else {
        let n = steps_resolved.len();
        if n % 2 == 1 {
            steps_resolved[n / 2] as f64
        } else {
            (steps_resolved[n / 2 - 1] + steps_resolved[n / 2]) as f64 / 2.0
        }
    };
    println!();
    println!(
        "seeds {first}-{last}, {cells}x{cells} cells: resolved {resolved}/{total}, final state clean by an independent analysis {independent_clean}/{total}, median steps (resolved) {median}, red-vertex count monotone {monotone}/{total}, total wall {:.0} s",
        t_all.elapsed().as_secs_f64()
    );
}
