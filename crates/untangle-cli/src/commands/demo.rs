//! `untangle demo`: the main job on a built-in tangled scene, no input files needed.

use crate::output::Context;
use anyhow::{Context as _, Result};
use std::path::PathBuf;
use untangle::analysis::{self, report::Report, AnalysisMesh, ObjectKind};
use untangle::mesh::obj;

/// Arguments of `demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder.
    #[arg(long, default_value = "untangle-demo")]
    pub out: PathBuf,
}

/// Builds the scene, analyses it, writes the report and a coloured mesh.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create folder", args.out.display()))?;
    let scene = untangle::scenes::closed(24);
    let parts: Vec<_> = scene
        .meshes
        .iter()
        .map(|m| (m, ObjectKind::Cloth))
        .collect();
    let (am, pos) = AnalysisMesh::new(&parts)?;
    let a = analysis::analyze(&am, &pos).context("intersection analysis")?;
    let report = Report::new(&am, &pos, &a);
    let refs: Vec<_> = scene.meshes.iter().collect();
    let merged = am.merged(&pos, &refs);
    let colors = analysis::coloring::vertex_colors(&am, &a.coloring, &a.segments);
    let json = args.out.join("report.json");
    let input = args.out.join("input.obj");
    let colored = args.out.join("colored.obj");
    untangle::fsio::write_atomic(&json, report.to_json().as_bytes())?;
    obj::write_obj(
        &input,
        &merged,
        None,
        "untangle demo: built-in tangled scene",
    )?;
    obj::write_obj(&colored, &merged, Some(&colors), "untangle demo: red = inside a tanglement, orange = on an intersecting triangle, green = clean")?;
    if !ctx.quiet {
        println!("untangle demo: built-in scene '{}'", scene.name);
        print!("{}", super::check::summary(&report));
        println!(
            "wrote {}, {}, {}",
            input.display(),
            colored.display(),
            json.display()
        );
    }
    Ok(0)
}
