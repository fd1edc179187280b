//! `untangle demo`: the main job on a built-in tangled scene, no input files needed. It builds
//! the exploded handkerchief of Cha & Ko 2022, Sec. 9.2 (a seeded draw that the method resolves
//! in well under a second), analyses it, untangles it with the Cha & Ko loop and writes what a
//! person wants to look at into `./untangle-demo/`:
//!
//! - `input.obj` (the tangled scene), `colored.obj` (the same, coloured by the analysis, with the
//!   intersection curves as polylines), `untangled.obj` (the result);
//! - `report.json` (the `untangle fix` report: every step, every operation, what is left);
//! - `red_vertices.png` (red vertices per step over the time per step, like the paper's Fig. 15);
//! - `before.png`, `after.png` (pictures of the cloth coloured by the analysis).

use super::fix::{self, Setup};
use crate::output::Context;
use crate::pictures;
use anyhow::{Context as _, Result};
use std::path::PathBuf;
use untangle::geom::Vec3;
use untangle::mesh::{obj, Garment};
use untangle::methods::cha_ko::ResolveParams;

/// The default draw of the exploded handkerchief.
pub const DEMO_SEED: u64 = 4;

/// Arguments of `demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder.
    #[arg(long, default_value = "untangle-demo")]
    pub out: PathBuf,
    /// Seed of the exploded handkerchief.
    #[arg(long, default_value_t = DEMO_SEED)]
    pub seed: u64,
    /// Cells per side of the handkerchief (14 = the paper's 388-triangle size).
    #[arg(long, default_value_t = 14)]
    pub size: usize,
}

/// Builds the scene, untangles it, writes meshes, the report and the pictures. Exit code 0 when
/// the result is free of intersections, 1 otherwise.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create folder", args.out.display()))?;
    let scene = untangle::scenes::exploded::exploded(args.seed, args.size);
    let mesh = scene.meshes[0].clone();
    let garment = Garment::new(mesh.clone())?;
    ctx.say(format!(
        "untangle demo: exploded handkerchief (Cha & Ko Sec. 9.2), seed {}, {} triangles, {} vertices",
        args.seed,
        mesh.triangles.len(),
        mesh.positions.len()
    ));
    let setup = Setup {
        body: None,
        body_frame_steps: 1,
        body_thickness: 0.0,
        pinned: &[],
        frames: None,
        output_last: false,
    };
    // As `untangle fix` by default: no gravity, the cloth untangles where it is.
    let mut params = ResolveParams::default();
    params.sim.gravity = Vec3::zeros();
    let run = fix::untangle(&garment, params, &setup, ctx)?;
    let path = |name: &str| args.out.join(name);
    obj::write_obj(
        &path("input.obj"),
        &mesh,
        None,
        "untangle demo: built-in tangled scene (exploded handkerchief)",
    )?;
    let am = &run.final_am;
    {
        let a = &run.initial_analysis;
        let colors = untangle::analysis::coloring::vertex_colors(am, &a.coloring, &a.segments);
        let mut text = obj::format_obj(
            &mesh,
            Some(&colors),
            "untangle demo: red = inside a tanglement, orange = on an intersecting triangle, \
             green = clean; objects 'curve_N' are the intersection curves",
        );
        let curves = untangle::analysis::curves::tanglement_curves(am, &run.initial_pos, a);
        obj::append_polylines(&mut text, mesh.positions.len(), "curve_", &curves);
        untangle::fsio::write_atomic(&path("colored.obj"), text.as_bytes())?;
    }
    obj::write_obj(
        &path("untangled.obj"),
        &run.out_mesh,
        None,
        &format!(
            "untangle demo: untangled by cha-ko in {} steps",
            run.summary.steps
        ),
    )?;
    let mut report = run.report.clone();
    report["scene"] = serde_json::json!({
        "name": "exploded",
        "seed": args.seed,
        "size": args.size,
    });
    untangle::fsio::write_atomic(
        &path("report.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    // The chart: red vertices at the start of every step, and after the last one.
    let mut red: Vec<f64> = run.history.iter().map(|s| s.red_vertices as f64).collect();
    red.push(run.final_analysis.coloring.num_red_vertices() as f64);
    let mut ms: Vec<f64> = run.history.iter().map(fix::step_ms).collect();
    ms.push(0.0);
    let chart = pictures::red_vertex_chart(
        &red,
        &ms,
        &format!("Cha & Ko: exploded handkerchief, seed {}", args.seed),
    );
    pictures::write_png(&path("red_vertices.png"), &chart)?;
    let mut all = run.initial_pos.clone();
    all.extend_from_slice(&run.final_pos);
    let cam = pictures::camera(&all, 720, 600);
    let a0 = &run.initial_analysis;
    let before = pictures::analysis_picture(
        am,
        &run.initial_pos,
        a0,
        &cam,
        &format!(
            "before: {} red vertices, {} intersecting pairs",
            a0.coloring.num_red_vertices(),
            a0.segments.len()
        ),
    );
    pictures::write_png(&path("before.png"), &before)?;
    let a1 = &run.final_analysis;
    let after = pictures::analysis_picture(
        am,
        &run.final_pos,
        a1,
        &cam,
        &format!(
            "after {} steps: {} red vertices, {} intersecting pairs",
            run.summary.steps,
            a1.coloring.num_red_vertices(),
            a1.segments.len()
        ),
    );
    pictures::write_png(&path("after.png"), &after)?;
    if !ctx.quiet {
        print!("{}", fix::text_summary(&run));
        let names = [
            "input.obj",
            "colored.obj",
            "untangled.obj",
            "report.json",
            "red_vertices.png",
            "before.png",
            "after.png",
        ];
        println!("wrote into {}: {}", args.out.display(), names.join(", "));
    }
    Ok(if run.is_clean() { 0 } else { 1 })
}
