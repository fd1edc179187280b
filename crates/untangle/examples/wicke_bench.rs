//! Wicke et al. 2006, Sec. 5 (RBF correspondences and penalty forces, `methods::wicke`) beside
//! Cha & Ko 2022 (`methods::cha_ko`) on the same scenes and simulator: the six rudimentary
//! cases of Cha & Ko Fig. 13 and exploded handkerchiefs (Sec. 9.2), gravity off. Per scene and
//! method: outcome, steps, whether an independent analysis of the final positions is clean,
//! and the wall time. `WICKE_K` / `WICKE_AMAX` override the force settings.
//!
//! ```text
//! cargo run --release -p untangle --example wicke_bench -- [first_seed] [last_seed] [max_steps] [rudimentary|exploded|all]
//! ```

use std::time::Instant;
use untangle::analysis::{analyze, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{ResolveParams, Resolver};
use untangle::methods::wicke::{WickeParams, WickeResolver};

fn run_wicke(g: &Garment, max_steps: usize) -> (String, usize, bool, f64, f64) {
    let (am, _) = AnalysisMesh::single(&g.mesh).expect("analysable");
    let mut p = WickeParams::default();
    p.sim.gravity = Vec3::zeros();
    p.max_steps = max_steps;
    let env = |k: &str| std::env::var(k).ok().map(|s| s.parse::<f64>().expect(k));
    if let Some(k) = env("WICKE_K") {
        p.forces.stiffness = k;
    }
    if let Some(a) = env("WICKE_AMAX") {
        p.forces.max_acceleration = a;
    }
    let t = Instant::now();
    let mut r = WickeResolver::new(g, &am, p).expect("loop");
    let o = r.run(|_| {}).expect("runs");
    let wall = t.elapsed().as_secs_f64();
    let clean = analyze(&am, r.simulator().positions())
        .map(|a| a.is_clean())
        .unwrap_or(false);
    let steps = r.history().len().saturating_sub(1);
    if std::env::var("WICKE_TRACE").is_ok() {
        for (i, s) in r.history().iter().enumerate() {
            eprintln!(
                "{i}: pairs {} tangl {} {:?}",
                s.intersecting_pairs, s.tanglements, s.forces
            );
        }
    }
    (
        format!("{o:?}"),
        steps,
        clean,
        wall,
        r.simulator().max_stretch(),
    )
}

fn run_chako(g: &Garment, max_steps: usize) -> (String, usize, bool, f64, f64) {
    let (am, _) = AnalysisMesh::single(&g.mesh).expect("analysable");
    let mut p = ResolveParams::default();
    p.sim.gravity = Vec3::zeros();
    p.max_steps = max_steps;
    let t = Instant::now();
    let mut r = Resolver::new(g, p).expect("loop");
    let s = r.run(|_| {}).expect("runs");
    let wall = t.elapsed().as_secs_f64();
    let clean = analyze(&am, r.simulator().positions())
        .map(|a| a.is_clean())
        .unwrap_or(false);
    (
        format!("{:?}", s.outcome),
        s.steps as usize,
        clean,
        wall,
        r.simulator().max_stretch(),
    )
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let num = |i: usize, d: u64| {
        args.get(i)
            .map(|s| s.parse().expect("a number"))
            .unwrap_or(d)
    };
    let (first, last, max_steps) = (num(1, 1), num(2, 10), num(3, 400) as usize);
    let which = args.get(4).map(String::as_str).unwrap_or("all");
    let mut scenes: Vec<(String, Garment)> = Vec::new();
    if which != "exploded" {
        for name in ["closed", "eight", "ll", "cross", "bibi", "bbii"] {
            let s = untangle::scenes::by_name(name, None, 1).expect("scene");
            let m = AnalysisMesh::merge_cloth(&s.meshes).expect("merge");
            scenes.push((name.into(), Garment::new(m).expect("garment")));
        }
    }
    if which != "rudimentary" {
        for seed in first..=last {
            let s = untangle::scenes::exploded::exploded(seed, 14);
            scenes.push((
                format!("exploded {seed}"),
                Garment::new(s.meshes[0].clone()).expect("garment"),
            ));
        }
    }
    println!("| scene | Wicke: outcome | steps | clean | wall s | max stretch | Cha & Ko: outcome | steps | clean | wall s | max stretch |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let (mut w_ok, mut c_ok) = (0, 0);
    for (name, g) in &scenes {
        let w = run_wicke(g, max_steps);
        let c = if std::env::var("WICKE_ONLY").is_ok() {
            ("-".into(), 0, false, 0.0, 0.0)
        } else {
            run_chako(g, max_steps)
        };
        w_ok += w.2 as usize;
        c_ok += c.2 as usize;
        println!(
            "| {name} | {} | {} | {} | {:.2} | {:.3} | {} | {} | {} | {:.2} | {:.3} |",
            w.0, w.1, w.2, w.3, w.4, c.0, c.1, c.2, c.3, c.4
        );
    }
    println!(
        "clean at the end: Wicke {w_ok} / {n}, Cha & Ko {c_ok} / {n}",
        n = scenes.len()
    );
}
