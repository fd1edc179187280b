//! `untangle fix FILE... --out OUT.obj [--method cha-ko] [--json REPORT.json] [options]`
//!
//! Removes self-intersections of a garment by simulation: Cha & Ko 2022 (intersection analysis
//! and colouring, uv-space pulls / shrinks / revokes, m-CCH) inside the implicit cloth simulator.
//! Several input files are sewn into nothing: they are analysed and simulated together as the
//! panels of one garment.

use crate::output::{check_output, Context};
use anyhow::{bail, Context as _, Result};
use std::path::{Path, PathBuf};
use untangle::analysis::{AnalysisMesh, ObjectKind};
use untangle::geom::Vec3;
use untangle::mesh::{obj, Garment};
use untangle::methods::cha_ko::{Outcome, ResolveParams, Resolver};

/// Resolution methods.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Cha & Ko 2022: uv-space vertex pull and triangle shrinkage with m-CCH.
    ChaKo,
}

/// Arguments of `fix`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Garment mesh(es) (OBJ with `vt` sewing-pattern coordinates; without `vt` the mesh is its
    /// own flat pattern).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Write the untangled garment here (OBJ; original uv).
    #[arg(long)]
    pub out: PathBuf,
    /// Method.
    #[arg(long, value_enum, default_value = "cha-ko")]
    pub method: Method,
    /// Write the JSON report (summary, every step, every operation) here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// A static obstacle (body) the cloth collides with.
    #[arg(long)]
    pub body: Option<PathBuf>,
    /// Obstacle thickness (metres).
    #[arg(long, default_value_t = 2e-3)]
    pub body_thickness: f64,
    /// Pull / shrink scale per step (Cha & Ko's gamma).
    #[arg(long, default_value_t = 0.8)]
    pub gamma: f64,
    /// Time step (seconds).
    #[arg(long, default_value_t = 0.02)]
    pub dt: f64,
    /// Green-green collision thickness (epsilon_CCD).
    #[arg(long, default_value_t = 1e-6)]
    pub eps: f64,
    /// Red-green thickness as a multiple of the average edge length (epsilon_RG).
    #[arg(long, default_value_t = 0.1)]
    pub eps_rg_factor: f64,
    /// Deepest pull / shrink level (rest length kept >= gamma^max_level).
    #[arg(long, default_value_t = 15)]
    pub max_level: u32,
    /// Step limit.
    #[arg(long, default_value_t = 2000)]
    pub max_steps: usize,
    /// Stop after this many steps without progress.
    #[arg(long, default_value_t = 100)]
    pub stuck_steps: usize,
    /// Gravity along -y (m/s^2); 0 keeps the garment in place while it untangles.
    #[arg(long, default_value_t = 0.0)]
    pub gravity: f64,
    /// Disable the fallbacks used when no fan passes the triangle inversion test.
    #[arg(long)]
    pub no_fallback: bool,
    /// Leave BLI paths uncoloured (the paper's method; by default their cone regions, Wicke's
    /// heuristic, are coloured red and pulled out like any other region).
    #[arg(long)]
    pub no_bli_regions: bool,
}

/// Runs `fix`; exit code 0 when the output is free of intersections, 1 otherwise.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    let mut inputs: Vec<&Path> = args.files.iter().map(|p| p.as_path()).collect();
    if let Some(b) = &args.body {
        inputs.push(b);
    }
    for out in std::iter::once(&args.out).chain(args.json.iter()) {
        check_output(out, &inputs)?;
    }
    let meshes: Vec<_> = args
        .files
        .iter()
        .map(|f| obj::read_obj(f))
        .collect::<untangle::Result<_>>()?;
    let garment = if meshes.len() == 1 {
        Garment::new(meshes[0].clone())?
    } else {
        let parts: Vec<_> = meshes.iter().map(|m| (m, ObjectKind::Cloth)).collect();
        let (am, pos) = AnalysisMesh::new(&parts)?;
        if meshes.iter().any(|m| m.uv.is_none()) {
            bail!("several inputs must all have uv (vt) coordinates");
        }
        Garment::new(am.merged(&pos, &meshes.iter().collect::<Vec<_>>()))?
    };
    let Method::ChaKo = args.method;
    let mut p = ResolveParams::default();
    p.cha_ko.gamma = args.gamma;
    p.cha_ko.dt = args.dt;
    p.cha_ko.eps = args.eps;
    p.cha_ko.eps_rg_factor = args.eps_rg_factor;
    p.cha_ko.max_level = args.max_level;
    p.cha_ko.fallback = !args.no_fallback;
    p.sim.gravity = Vec3::new(0.0, -args.gravity, 0.0);
    p.max_steps = args.max_steps;
    p.stuck_steps = args.stuck_steps;
    p.analysis.bli_regions_red = !args.no_bli_regions;
    let mut resolver = Resolver::new(&garment, p)?;
    if let Some(b) = &args.body {
        let body = obj::read_obj(b)?;
        resolver
            .simulator_mut()
            .add_obstacle(untangle::sim::Obstacle::from_mesh(
                &body,
                args.body_thickness,
                0.3,
            )?)?;
    }
    let pb = ctx.progress(args.max_steps as u64, "untangling");
    let summary = resolver
        .run(|s| {
            pb.set_position(s.step + 1);
            pb.set_message(format!(
                "untangling: {} pairs, {} red",
                s.intersecting_pairs, s.red_vertices
            ));
        })
        .context("cha-ko resolution")?;
    pb.finish_and_clear();
    let mut out_mesh = garment.mesh.clone();
    out_mesh.positions = resolver.simulator().positions().to_vec();
    obj::write_obj(
        &args.out,
        &out_mesh,
        None,
        &format!(
            "untangle fix --method cha-ko: {:?} after {} steps",
            summary.outcome, summary.steps
        ),
    )?;
    if let Some(j) = &args.json {
        let report = serde_json::json!({
            "method": "cha-ko",
            "params": resolver.chako().params(),
            "eps_rg": resolver.chako().eps_rg(),
            "summary": summary,
            "steps": resolver.history(),
            "operations": resolver.chako().finesse_log(),
        });
        untangle::fsio::write_atomic(j, serde_json::to_string_pretty(&report)?.as_bytes())?;
    }
    if !ctx.quiet {
        print!("{}", text_summary(&summary));
    }
    // The last analysed state; a resolved run ends clean.
    Ok(if summary.outcome == Outcome::Resolved {
        0
    } else {
        1
    })
}

fn text_summary(s: &untangle::methods::cha_ko::ResolveSummary) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "{:?} after {} steps: {} -> {} intersecting triangle pairs, {} -> {} red vertices",
        s.outcome,
        s.steps,
        s.initial_pairs,
        s.final_pairs,
        s.initial_red_vertices,
        s.final_red_vertices
    );
    for r in &s.finesse.rows {
        if r.count + r.unfinished > 0 {
            let _ = writeln!(
                t,
                "  {:?}: {} finesses, {:.2} steps each ({} unfinished)",
                r.seam, r.count, r.mean_steps, r.unfinished
            );
        }
    }
    for st in s.stalls.iter().take(5) {
        let _ = writeln!(
            t,
            "  stall: {:?} at vertex {:?} triangle {:?} position {:?}",
            st.reason, st.vertex, st.triangle, st.position
        );
    }
    if s.stalls.len() > 5 {
        let _ = writeln!(
            t,
            "  ... {} stalls in all (see the JSON report)",
            s.stalls.len()
        );
    }
    if s.administrative_quits + s.analysis_errors > 0 {
        let _ = writeln!(
            t,
            "  {} administrative quits of the collision handling, {} failed analyses",
            s.administrative_quits, s.analysis_errors
        );
    }
    let _ = writeln!(
        t,
        "time per step: analysis {:.2} ms, uv update {:.2} ms, simulation {:.2} ms",
        s.mean_ms[0], s.mean_ms[1], s.mean_ms[2]
    );
    t
}
