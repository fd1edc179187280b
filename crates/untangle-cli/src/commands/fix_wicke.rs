//! `untangle fix --method wicke`: Wicke et al. 2006, Sec. 5 (RBF correspondences from the
//! intersection paths to their inside regions, penalty forces toward the targets, BI/BI pairs
//! pushed to the boundary) inside the same simulator as `--method cha-ko`, with the same
//! inputs, outputs and exit codes (0: the output is free of intersections by the analysis, 1:
//! the run stopped with tanglements left, 2: error).

use super::fix::{body_note, write_frame, Args, Scene, Setup};
use crate::output::Context;
use anyhow::{bail, Context as _, Result};
use untangle::analysis::report::Report;
use untangle::analysis::{Analysis, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::{obj, Garment};
use untangle::methods::wicke::{WickeOutcome, WickeParams, WickeResolver, WickeStep};

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

/// The per-step entry of the report.
fn step_json(k: usize, s: &WickeStep) -> serde_json::Value {
    serde_json::json!({
        "step": k,
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

/// Runs the loop, writes the mesh, the report and the frames, prints the summary; the exit
/// code.
pub fn run(args: &Args, garment: &Garment, setup: &Setup, ctx: &Context) -> Result<u8> {
    if setup.body_frame_steps == 0 {
        bail!("--body-frame-steps must be at least 1");
    }
    let p = params(args);
    let max_steps = p.max_steps;
    let (am, _) = AnalysisMesh::single(&garment.mesh)?;
    let mut resolver = WickeResolver::new(garment, &am, p.clone()).context("wicke")?;
    if let Some(b) = setup.body {
        resolver
            .simulator_mut()
            .add_obstacle(untangle::sim::Obstacle::from_mesh(
                &b.mesh,
                setup.body_thickness,
                0.3,
            )?)?;
    }
    for &v in setup.pinned {
        resolver.simulator_mut().set_pinned(v, true)?;
    }
    let mut scene = Scene::new(&garment.mesh, setup.body)?;
    let initial = scene.analyse(resolver.simulator())?;
    let initial_pos = scene.pos.clone();
    if let Some((dir, _)) = setup.frames {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        write_frame(
            dir,
            0,
            &scene.colored_obj(&initial, "untangle fix --method wicke: input"),
        )?;
    }
    let body_pairs = |am: &AnalysisMesh, pos: &[Vec3], a: &Analysis| -> usize {
        Report::new(am, pos, a)
            .pairs_by_objects
            .iter()
            .filter(|g| g.relation == "cloth-obstacle")
            .map(|g| g.pairs)
            .sum()
    };
    let input_body_pairs = body_pairs(&scene.am, &initial_pos, &initial);
    if input_body_pairs > 0 {
        ctx.say(format!("note: {}", body_note(input_body_pairs)));
    }
    let initial_pairs = initial.segments.len() as u64;
    let pb = ctx.progress(initial_pairs.max(1), "untangling");
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg:34} [{bar:20}] {pos}/{len} pairs resolved {elapsed}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    let body_span = setup.body.map_or(0, |b| {
        (b.frames.len().saturating_sub(1)) * setup.body_frame_steps
    });
    let outcome = loop {
        if let Some(o) = resolver.stop_reason() {
            break o;
        }
        let k = resolver.history().len();
        if let Some(b) = setup.body {
            if b.frames.len() > 1 {
                let next = super::simulate::body_at(b, (k + 1).min(body_span), body_span);
                resolver
                    .simulator_mut()
                    .set_obstacle_next_positions(0, &next)?;
            }
        }
        let (rec, stepped) = resolver.step().context("wicke step")?;
        pb.set_position(initial_pairs.saturating_sub(rec.intersecting_pairs as u64));
        pb.set_message(format!(
            "step {}/{max_steps}: {} pairs",
            k + 1,
            rec.intersecting_pairs
        ));
        if let (Some((dir, every)), Some(_)) = (setup.frames, stepped) {
            let done = resolver.stop_reason().is_some();
            if (k + 1) % every.max(1) == 0 || done {
                let a = scene.analyse(resolver.simulator())?;
                let text = scene.colored_obj(
                    &a,
                    &format!("untangle fix --method wicke: after step {}", k + 1),
                );
                write_frame(dir, k + 1, &text)?;
            }
        }
    };
    pb.finish_and_clear();
    let final_analysis = scene.analyse(resolver.simulator())?;
    let final_pos = scene.pos.clone();
    let clean = final_analysis.is_clean();
    // Steps that moved the cloth (the last pass only analysed when it found the cloth clean).
    let steps = resolver
        .history()
        .iter()
        .filter(|s| s.intersecting_pairs > 0)
        .count();
    let mut out_mesh = garment.mesh.clone();
    out_mesh.positions = resolver.simulator().positions().to_vec();
    obj::write_obj(
        &args.out,
        &out_mesh,
        None,
        &format!("untangle fix --method wicke: {outcome:?} after {steps} steps"),
    )?;
    let history = resolver.history();
    let total_ms: f64 = history.iter().map(|s| s.ms.iter().sum::<f64>()).sum();
    if let Some(j) = &args.json {
        let final_report = Report::new(&scene.am, &final_pos, &final_analysis);
        let final_json: serde_json::Value = serde_json::from_str(&final_report.to_json())?;
        let report = serde_json::json!({
            "method": "wicke",
            "input": args.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "vertices": garment.mesh.positions.len(),
            "triangles": garment.mesh.triangles.len(),
            "pinned": setup.pinned.len(),
            "params": {
                "stiffness": p.forces.stiffness,
                "max_acceleration": p.forces.max_acceleration,
                "max_centers": p.forces.max_centers,
                "symmetric": p.forces.symmetric,
                "thickness": p.thickness,
                "dt": p.sim.dt,
                "max_steps": p.max_steps,
                "stuck_steps": p.stuck_steps,
            },
            "outcome": format!("{outcome:?}"),
            "steps_run": steps,
            "output_intersection_free": clean,
            "output_intersecting_pairs": final_analysis.segments.len(),
            "input_intersecting_pairs": initial.segments.len(),
            "input_body_intersecting_pairs": input_body_pairs,
            "timing_ms": { "total": total_ms },
            "steps": history.iter().enumerate().map(|(k, s)| step_json(k, s)).collect::<Vec<_>>(),
            "final_analysis": final_json,
        });
        untangle::fsio::write_atomic(j, serde_json::to_string_pretty(&report)?.as_bytes())?;
    }
    if !ctx.quiet {
        let what = match outcome {
            WickeOutcome::Resolved if clean => "resolved",
            WickeOutcome::Resolved => "cloth tanglements resolved",
            WickeOutcome::StepLimit => "step limit reached",
            WickeOutcome::Stuck => "stuck",
        };
        println!(
            "wicke: {what} after {steps} step{}: {} -> {} intersecting triangle pairs",
            if steps == 1 { "" } else { "s" },
            initial.segments.len(),
            final_analysis.segments.len()
        );
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
