//! Wicke et al. 2006, Sec. 5 (RBF correspondences and penalty forces, `methods::wicke`) beside
//! Cha & Ko 2022 (`methods::cha_ko`) on the same scenes and simulator: the six rudimentary
//! cases of Cha & Ko Fig. 13 and exploded handkerchiefs (Sec. 9.2), gravity off. Per scene and
//! method: outcome, steps, whether an independent analysis of the final positions is clean,
//! and the wall time. `WICKE_K` / `WICKE_AMAX` override the force settings; `WICKE_ONLY=1`
//! skips Cha & Ko. `COMBINED=P` runs the combined method (`methods::combined`, pre-pass
//! patience `P`) on the exploded seeds instead, with steps per stage; `GARMENTS=S` compares the
//! three methods on the ARCSim garments sagged `S` steps with self-collision off.
//!
//! ```text
//! cargo run --release -p untangle --example wicke_bench -- [first_seed] [last_seed] [max_steps] [rudimentary|exploded|all]
//! ```

mod common;

use std::time::Instant;
use untangle::analysis::{analyze, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{ResolveParams, Resolver};
use untangle::methods::combined::{CombinedParams, CombinedResolver};
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
    if std::env::var("WICKE_MS").is_ok() {
        let h: Vec<_> = r
            .history()
            .iter()
            .filter(|s| s.intersecting_pairs > 0)
            .collect();
        let n = h.len().max(1) as f64;
        let m = |k: usize| h.iter().map(|s| s.ms[k]).sum::<f64>() / n;
        eprintln!(
            "wicke ms/step: analysis {:.2} forces {:.2} simulation {:.2} (first step: {:.2} / {:.2} / {:.2})",
            m(0),
            m(1),
            m(2),
            h.first().map_or(0.0, |s| s.ms[0]),
            h.first().map_or(0.0, |s| s.ms[1]),
            h.first().map_or(0.0, |s| s.ms[2])
        );
    }
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

/// `COMBINED_KEEP` (`prepass_keep_below`; 1 hands the pre-pass's best state over always, as
/// before that rule) and `COMBINED_ROUNDS` (`rounds`; 1 = one round, as before rounds).
fn combined_knobs(p: &mut CombinedParams) {
    let env = |k: &str| std::env::var(k).ok().map(|s| s.parse::<f64>().expect(k));
    if let Some(v) = env("COMBINED_KEEP") {
        p.prepass_keep_below = v;
    }
    if let Some(v) = env("COMBINED_ROUNDS") {
        p.rounds = v as usize;
    }
}

/// The combined loop (`methods::combined`: Wicke pre-pass, Cha & Ko, Wicke finish) with
/// pre-pass patience `patience`: (steps per stage, outcome, clean by an independent analysis,
/// wall).
fn run_combined(g: &Garment, max_steps: usize, patience: usize) -> ([usize; 3], String, bool, f64) {
    let (am, _) = AnalysisMesh::single(&g.mesh).expect("analysable");
    let mut p = CombinedParams {
        prepass_patience: patience,
        max_steps,
        ..Default::default()
    };
    p.wicke.sim.gravity = Vec3::zeros();
    p.cha_ko.sim.gravity = Vec3::zeros();
    combined_knobs(&mut p);
    let t = Instant::now();
    let mut r = CombinedResolver::new(g, p).expect("loop");
    let o = r.run(|_| {}).expect("runs");
    let clean = analyze(&am, r.positions())
        .map(|a| a.is_clean())
        .unwrap_or(false);
    (
        r.stage_steps(),
        format!("{o:?}"),
        clean,
        t.elapsed().as_secs_f64(),
    )
}

/// The ARCSim garments (tshirt, dress3, pants3, refined to >= 2,000 vertices), sagged with
/// self-collision off for `sag` steps (as `cha_ko_garments`), then untangled by each method
/// with the same pins and gravity: one row per garment and method.
fn garments(sag: usize, max_steps: usize) {
    use untangle::mesh::subdivide;
    use untangle::scenes::sagged;
    println!("| garment | vertices | pairs after sagging | method | outcome | steps (pre-pass / Cha & Ko / finish) | clean | wall s |");
    println!("|---|---|---|---|---|---|---|---|");
    for name in ["tshirt", "dress3", "pants3"] {
        let Some(mut mesh) = common::arcsim_mesh(name) else {
            println!("garments: skipped (no ../shared data)");
            return;
        };
        while mesh.positions.len() < 2000 {
            mesh = subdivide::subdivide(&mesh);
        }
        let g = Garment::new(mesh.clone()).expect("garment");
        let gravity = sagged::GRAVITY_Z;
        let pins = sagged::top_vertices(&mesh, &Vec3::z(), 0.03);
        let tangled = sagged::sagged(&g, gravity, &pins, sag).expect("sagging");
        let (am, _) = AnalysisMesh::single(&tangled).expect("analysis mesh");
        let pairs = analyze(&am, &tangled.positions)
            .expect("analysis")
            .segments
            .len();
        let tg = Garment::new(tangled).expect("garment");
        let clean = |x: &[Vec3]| analyze(&am, x).map(|a| a.is_clean()).unwrap_or(false);
        let row = |method: &str, o: String, steps: String, ok: bool, wall: f64| {
            println!(
                "| {name} | {} | {pairs} | {method} | {o} | {steps} | {ok} | {wall:.1} |",
                mesh.positions.len()
            );
        };
        // Cha & Ko.
        let t = Instant::now();
        let mut p = ResolveParams::default();
        p.sim.gravity = gravity;
        p.max_steps = max_steps;
        let mut r = Resolver::new(&tg, p).expect("loop");
        for &v in &pins {
            r.simulator_mut().set_pinned(v, true).expect("pin");
        }
        let s = r.run(|_| {}).expect("runs");
        let ok = clean(r.simulator().positions());
        row(
            "cha-ko",
            format!("{:?}", s.outcome),
            s.steps.to_string(),
            ok,
            t.elapsed().as_secs_f64(),
        );
        // Wicke.
        let t = Instant::now();
        let mut p = WickeParams::default();
        p.sim.gravity = gravity;
        p.max_steps = max_steps;
        let mut w = WickeResolver::new(&tg, &am, p).expect("loop");
        for &v in &pins {
            w.simulator_mut().set_pinned(v, true).expect("pin");
        }
        let o = w.run(|_| {}).expect("runs");
        let ok = clean(w.simulator().positions());
        let n = w
            .history()
            .iter()
            .filter(|s| s.intersecting_pairs > 0)
            .count();
        row(
            "wicke",
            format!("{o:?}"),
            n.to_string(),
            ok,
            t.elapsed().as_secs_f64(),
        );
        // Combined.
        let t = Instant::now();
        let mut p = CombinedParams {
            max_steps,
            ..Default::default()
        };
        p.wicke.sim.gravity = gravity;
        p.cha_ko.sim.gravity = gravity;
        combined_knobs(&mut p);
        let mut c = CombinedResolver::new(&tg, p).expect("loop");
        for &v in &pins {
            c.pin(v).expect("pin");
        }
        let o = c.run(|_| {}).expect("runs");
        let ok = clean(c.positions());
        let n = c.stage_steps();
        row(
            "combined",
            format!("{o:?}"),
            format!(
                "{} ({} / {} / {})",
                n.iter().sum::<usize>(),
                n[0],
                n[1],
                n[2]
            ),
            ok,
            t.elapsed().as_secs_f64(),
        );
    }
}

fn main() {
    use common::arg;
    if let Ok(sag) = std::env::var("GARMENTS") {
        garments(sag.parse().expect("GARMENTS"), 600);
        return;
    }
    if let Ok(pat) = std::env::var("COMBINED") {
        let patience: usize = pat.parse().expect("COMBINED");
        let (first, last, max_steps) = (arg(1, 1) as u64, arg(2, 10) as u64, arg(3, 2000));
        println!("| seed | pre-pass steps | Cha & Ko steps | finish steps | total | outcome | clean | wall s | Cha & Ko alone: steps | clean |");
        println!("|---|---|---|---|---|---|---|---|---|---|");
        let (mut totals, mut alone) = (Vec::new(), Vec::new());
        let mut cmp = [0usize; 3]; // combined faster, slower, equal (both clean)
        for seed in first..=last {
            let s = untangle::scenes::exploded::exploded(seed, 14);
            let g = Garment::new(s.meshes[0].clone()).expect("garment");
            let (n, o, clean, wall) = run_combined(&g, max_steps, patience);
            // Cha & Ko alone, as `cha_ko_exploded` runs it (400-step limit).
            let (_, ck_steps, ck_clean, _, _) = run_chako(&g, 400);
            let total = n.iter().sum::<usize>();
            println!(
                "| {seed} | {} | {} | {} | {total} | {o} | {clean} | {wall:.2} | {ck_steps} | {ck_clean} |",
                n[0], n[1], n[2]
            );
            if clean {
                totals.push(total);
            }
            if ck_clean {
                alone.push(ck_steps);
            }
            if clean && ck_clean {
                cmp[match total.cmp(&ck_steps) {
                    std::cmp::Ordering::Less => 0,
                    std::cmp::Ordering::Greater => 1,
                    std::cmp::Ordering::Equal => 2,
                }] += 1;
            }
        }
        let median = |v: &mut Vec<usize>| {
            v.sort_unstable();
            let m = v.len();
            (m > 0).then(|| (v[(m - 1) / 2] + v[m / 2]) as f64 / 2.0)
        };
        let seeds = last - first + 1;
        println!(
            "combined: clean {} / {seeds}, median total steps (clean seeds) {:?}; Cha & Ko alone: clean {} / {seeds}, median {:?}; seeds clean in both: combined faster on {}, slower on {}, equal on {}",
            totals.len(),
            median(&mut totals),
            alone.len(),
            median(&mut alone),
            cmp[0],
            cmp[1],
            cmp[2]
        );
        return;
    }
    let (first, last, max_steps) = (arg(1, 1) as u64, arg(2, 10) as u64, arg(3, 400));
    let which = std::env::args().nth(4).unwrap_or_else(|| "all".into());
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
