//! `untangle fix --method wicke` and `--method combined`: Wicke et al. 2006, Sec. 5 (RBF
//! correspondences from the intersection paths to their inside regions, penalty forces toward
//! the targets, BI/BI pairs pushed to the boundary) inside the same simulator as `--method
//! cha-ko`, alone or as the stages around Cha & Ko's loop (`methods::combined`), with the same
//! inputs, outputs and exit codes (0: the output is free of intersections by the analysis, 1:
//! the run stopped with tanglements left, 2: error).

use super::fix::{
    begin, choose_output, output_state_json, output_state_line, write_frame, Args, Method, Scene,
    Setup,
};
use crate::output::Context;
use anyhow::{Context as _, Result};
use untangle::analysis::report::Report;
use untangle::analysis::{Analysis, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::{obj, Garment};
use untangle::methods::combined::{
    CombinedOutcome, CombinedParams, CombinedResolver, CombinedStep,
};
use untangle::methods::fewest::Fewest;
use untangle::methods::wicke::{WickeOutcome, WickeParams, WickeResolver, WickeStep};
use untangle::sim::Simulator;

/// The loop being run: Wicke's alone, or the combined stages.
enum Runner {
    Wicke(Box<WickeResolver>),
    Combined(Box<CombinedResolver>),
}

impl Runner {
    fn simulator(&self) -> Option<&Simulator> {
        match self {
            Runner::Wicke(w) => Some(w.simulator()),
            Runner::Combined(c) => c.simulator(),
        }
    }

    fn positions(&self) -> &[Vec3] {
        match self {
            Runner::Wicke(w) => w.simulator().positions(),
            Runner::Combined(c) => c.positions(),
        }
    }

    /// Whether the loop has stopped with the cloth clean.
    fn resolved(&self) -> bool {
        match self {
            Runner::Wicke(w) => w.stop_reason() == Some(WickeOutcome::Resolved),
            Runner::Combined(c) => c.stop_reason() == Some(CombinedOutcome::Resolved),
        }
    }

    /// Whether the loop has stopped, and how (a word for the summary, the JSON outcome).
    fn stopped(&self) -> Option<(&'static str, String)> {
        match self {
            Runner::Wicke(w) => w.stop_reason().map(|o| {
                let word = match o {
                    WickeOutcome::Resolved => "resolved",
                    WickeOutcome::StepLimit => "step limit reached",
                    WickeOutcome::Stuck => "stuck",
                };
                (word, format!("{o:?}"))
            }),
            Runner::Combined(c) => c.stop_reason().map(|o| {
                let word = match o {
                    CombinedOutcome::Resolved => "resolved",
                    CombinedOutcome::StepLimit => "step limit reached",
                    CombinedOutcome::Unresolved => "stuck",
                };
                (word, format!("{o:?}"))
            }),
        }
    }

    /// One step: `None` once stopped, else the pairs at its start and its report entry. A
    /// Wicke pass that only analysed (and found the cloth clean) is not a step.
    fn step(&mut self, k: usize) -> Result<Option<(usize, serde_json::Value)>> {
        match self {
            Runner::Wicke(w) => {
                if w.stop_reason().is_some() {
                    return Ok(None);
                }
                let (s, stepped) = w.step().context("wicke step")?;
                Ok(stepped.map(|_| {
                    (
                        s.intersecting_pairs,
                        labelled(step_json(&s), k, "wicke".into()),
                    )
                }))
            }
            Runner::Combined(c) => Ok(c.step().context("combined step")?.map(|s| {
                let json = match &s {
                    CombinedStep::Wicke(_, w) => step_json(w),
                    CombinedStep::ChaKo(l) => super::fix::step_json(l),
                };
                // Stage labels as `Stage` serialises: prepass, cha_ko, finish.
                let json = labelled(json, k, serde_json::json!(s.stage()));
                (s.intersecting_pairs(), json)
            })),
        }
    }

    fn ms(&self) -> f64 {
        match self {
            // Folds from +0.0: an empty `sum` of floats is -0.0, printed "-0.00".
            Runner::Wicke(w) => w
                .history()
                .iter()
                .fold(0.0, |t, s| t + s.ms.iter().sum::<f64>()),
            Runner::Combined(c) => c.history().iter().fold(0.0, |t, s| t + s.ms()),
        }
    }
}

/// The loop's settings from the command line.
pub fn params(args: &Args) -> WickeParams {
    let mut p = WickeParams::default();
    p.forces.stiffness = args.wicke_stiffness;
    p.forces.max_acceleration = args.wicke_max_acceleration;
    p.thickness = args.eps;
    p.sim.dt = args.dt;
    p.sim.gravity = Vec3::new(0.0, -args.gravity, 0.0);
    p.max_steps = args.max_steps;
    p.stuck_steps = args.stuck_steps;
    p
}

/// A step's report entry with its index in the whole run and its stage.
fn labelled(mut j: serde_json::Value, k: usize, stage: serde_json::Value) -> serde_json::Value {
    j["step"] = serde_json::json!(k);
    j["stage"] = stage;
    j
}

/// The per-step entry of the report for a step of Wicke's loop (without step and stage).
fn step_json(s: &WickeStep) -> serde_json::Value {
    serde_json::json!({
        "intersecting_pairs": s.intersecting_pairs,
        "tanglements": s.tanglements,
        "inside_points": s.forces.inside_points,
        "mapped_paths": s.forces.mapped_paths,
        "bi_paths": s.forces.bi_paths,
        "paths_without_force": s.forces.unhandled_paths,
        "free_vertices": s.forces.free_vertices,
        "ms": s.ms.iter().sum::<f64>(),
        "ms_analysis": s.ms[0],
        "ms_forces": s.ms[1],
        "ms_sim": s.ms[2],
    })
}

/// The combined loop's settings from the command line (Cha & Ko's options for its stage,
/// Wicke's for the others).
pub fn combined_params(args: &Args) -> CombinedParams {
    CombinedParams {
        wicke: params(args),
        cha_ko: args.params(),
        max_steps: args.max_steps,
        ..Default::default()
    }
}

/// Runs the loop (`wicke` or `combined`), writes the mesh, the report and the frames, prints
/// the summary; the exit code.
pub fn run(args: &Args, garment: &Garment, setup: &Setup, ctx: &Context) -> Result<u8> {
    setup.validate()?;
    let combined = args.method == Method::Combined;
    let method = if combined { "combined" } else { "wicke" };
    let p = params(args);
    let cp = combined_params(args);
    let max_steps = p.max_steps;
    let (am, _) = AnalysisMesh::single(&garment.mesh)?;
    let obstacle = setup.obstacle()?;
    let mut runner = if combined {
        let mut c = CombinedResolver::new(garment, cp.clone()).context("combined")?;
        if let Some(o) = &obstacle {
            c.add_obstacle(o.clone())?;
        }
        for &v in setup.pinned {
            c.pin(v)?;
        }
        Runner::Combined(Box::new(c))
    } else {
        let mut w = WickeResolver::new(garment, &am, p.clone()).context("wicke")?;
        if let Some(o) = &obstacle {
            w.simulator_mut().add_obstacle(o.clone())?;
        }
        for &v in setup.pinned {
            w.simulator_mut().set_pinned(v, true)?;
        }
        Runner::Wicke(Box::new(w))
    };
    let mut scene = Scene::new(&garment.mesh, setup.body)?;
    let analyse = |scene: &mut Scene, runner: &Runner| -> Result<Analysis> {
        match runner.simulator() {
            Some(sim) => scene.analyse(sim),
            None => {
                let n = garment.mesh.positions.len();
                scene.pos[..n].copy_from_slice(runner.positions());
                if let Runner::Combined(c) = runner {
                    // The loop has stopped: the body is where its last step left it.
                    if let Some(body) = c.obstacles().first() {
                        scene.pos[n..].copy_from_slice(&body.positions);
                    }
                }
                untangle::analysis::analyze(&scene.am, &scene.pos).context("intersection analysis")
            }
        }
    };
    let initial = analyse(&mut scene, &runner)?;
    let initial_pairs = initial.segments.len() as u64;
    let (input_body_pairs, pb) = begin(
        ctx,
        setup,
        &scene,
        &initial,
        &format!("untangle fix --method {method}: input"),
        (initial_pairs, "pairs resolved"),
    )?;
    let mut steps_json = Vec::new();
    let mut fewest = Fewest::new(setup.keeps_fewest());
    loop {
        let k = steps_json.len();
        if let Some(next) = setup.animated_body_at(k + 1) {
            match &mut runner {
                Runner::Wicke(w) if w.stop_reason().is_none() => {
                    w.simulator_mut().set_obstacle_next_positions(0, &next)?
                }
                Runner::Combined(c) if c.stop_reason().is_none() => {
                    c.set_obstacle_next_positions(0, &next)?
                }
                _ => {}
            }
        }
        let before = fewest.before_step(runner.positions());
        let Some((pairs, json)) = runner.step(k)? else {
            break;
        };
        fewest.offer(k, pairs, before);
        steps_json.push(json);
        pb.set_position(initial_pairs.saturating_sub(pairs as u64));
        pb.set_message(format!("step {}/{max_steps}: {pairs} pairs", k + 1));
        if let Some((dir, every)) = setup.frames {
            if (k + 1) % every.max(1) == 0 {
                let a = analyse(&mut scene, &runner)?;
                let text = scene.colored_obj(
                    &a,
                    &format!("untangle fix --method {method}: after step {}", k + 1),
                );
                write_frame(dir, k + 1, &text)?;
            }
        }
    }
    pb.finish_and_clear();
    let (word, outcome) = runner
        .stopped()
        .unwrap_or(("stopped", "Stopped".to_string()));
    let tail = if runner.resolved() {
        super::fix::play_rest_of_body(
            garment,
            runner.positions(),
            &p.sim,
            p.thickness,
            setup,
            &mut scene,
            steps_json.len(),
        )?
    } else {
        None
    };
    let body_tail_steps = tail.as_ref().map_or(0, |t| t.1);
    let mut final_analysis = match &tail {
        Some((sim, _)) => scene.analyse(sim)?,
        None => analyse(&mut scene, &runner)?,
    };
    let steps = steps_json.len();
    if let (Some((dir, every)), None) = (setup.frames, &tail) {
        if steps % every.max(1) != 0 || steps == 0 {
            let text = scene.colored_obj(
                &final_analysis,
                &format!("untangle fix --method {method}: after step {steps}"),
            );
            write_frame(dir, steps, &text)?;
        }
    }
    let output_state = choose_output(&mut scene, &fewest, runner.resolved(), &mut final_analysis)?;
    let final_pos = scene.pos.clone();
    let clean = final_analysis.is_clean();
    let mut out_mesh = garment.mesh.clone();
    out_mesh.positions = final_pos[..garment.mesh.positions.len()].to_vec();
    obj::write_obj(
        &args.out,
        &out_mesh,
        None,
        &format!("untangle fix --method {method}: {outcome} after {steps} steps"),
    )?;
    let total_ms = runner.ms();
    let stage_steps = match &runner {
        Runner::Combined(c) => Some(c.stage_steps()),
        Runner::Wicke(_) => None,
    };
    if let Some(j) = &args.json {
        let final_report = Report::new(&scene.am, &final_pos, &final_analysis);
        let final_json: serde_json::Value = serde_json::from_str(&final_report.to_json())?;
        let mut params_json = serde_json::json!({
            "stiffness": p.forces.stiffness,
            "max_acceleration": p.forces.max_acceleration,
            "max_centers": p.forces.max_centers,
            "symmetric": p.forces.symmetric,
            "thickness": p.thickness,
            "dt": p.sim.dt,
            "max_steps": p.max_steps,
            "stuck_steps": p.stuck_steps,
        });
        if combined {
            params_json = serde_json::json!({
                "wicke": params_json,
                "cha_ko": cp.cha_ko.cha_ko,
                "prepass_patience": cp.prepass_patience,
                "prepass_keep_below": cp.prepass_keep_below,
                "finish_steps": cp.finish_steps,
                "finish_stuck_steps": cp.finish_stuck_steps,
                "rounds": cp.rounds,
                "max_steps": cp.max_steps,
            });
        }
        let report = serde_json::json!({
            "method": method,
            "input": args.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "vertices": garment.mesh.positions.len(),
            "triangles": garment.mesh.triangles.len(),
            "pinned": setup.pinned.len(),
            "body": super::fix::body_json(setup),
            "params": params_json,
            "outcome": outcome,
            "steps_run": steps,
            "body_tail_steps": body_tail_steps,
            "stage_steps": stage_steps.map(|n| serde_json::json!({
                "prepass": n[0], "cha_ko": n[1], "finish": n[2],
            })),
            "output_intersection_free": clean,
            "output_intersecting_pairs": final_analysis.segments.len(),
            "output_state": output_state_json(output_state.as_ref(), steps),
            "input_intersecting_pairs": initial.segments.len(),
            "input_body_intersecting_pairs": input_body_pairs,
            "timing_ms": { "total": total_ms },
            "steps": steps_json,
            "final_analysis": final_json,
        });
        untangle::fsio::write_atomic(j, serde_json::to_string_pretty(&report)?.as_bytes())?;
    }
    if !ctx.quiet {
        let what = if runner.resolved() && !clean {
            "cloth tanglements resolved"
        } else {
            word
        };
        println!(
            "{method}: {what} after {steps} step{}: {} -> {} intersecting triangle pairs",
            if steps == 1 { "" } else { "s" },
            initial.segments.len(),
            final_analysis.segments.len()
        );
        if let Some(n) = stage_steps {
            println!(
                "stages: Wicke pre-pass {} steps, Cha & Ko {} steps, Wicke finish {} steps",
                n[0], n[1], n[2]
            );
        }
        if let Runner::Combined(c) = &runner {
            let cha_ko = c.history().iter().enumerate().filter_map(|(k, s)| match s {
                CombinedStep::ChaKo(l) => Some((k, &**l)),
                CombinedStep::Wicke(..) => None,
            });
            if let Some(line) = super::fix::divergence_line(cha_ko) {
                println!("{line}");
            }
        }
        if body_tail_steps > 0 {
            println!("then {body_tail_steps} steps with full collision handling to play the rest of the body animation");
        }
        if clean {
            println!("output: free of intersections");
        } else {
            let r = Report::new(&scene.am, &final_pos, &final_analysis);
            let kinds: Vec<String> = r
                .tanglements_by_kind
                .iter()
                .map(|(k, n)| format!("{n} {k}"))
                .collect();
            println!(
                "output: {} intersecting triangle pairs in {} tanglements left: {} (locations in the JSON report)",
                final_analysis.segments.len(),
                final_analysis.tanglements.len(),
                kinds.join(", ")
            );
            if let Some(o) = &output_state {
                println!("{}", output_state_line(o, final_analysis.segments.len()));
            }
        }
        println!(
            "time: {:.2} s ({:.2} ms/step)",
            total_ms / 1e3,
            total_ms / steps.max(1) as f64
        );
        println!("wrote {}", args.out.display());
        if let Some(j) = &args.json {
            println!("wrote {}", j.display());
        }
        if let Some(d) = &args.frames {
            println!("wrote frames into {}", d.display());
        }
    }
    Ok(if clean { 0 } else { 1 })
}
