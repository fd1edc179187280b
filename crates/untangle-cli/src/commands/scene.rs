//! `untangle scene NAME [--seed S] [--size N] -o FILE.obj`

use crate::output::Context;
use anyhow::{anyhow, Result};
use std::path::PathBuf;
use untangle::analysis::AnalysisMesh;
use untangle::mesh::obj;

/// Arguments of `scene`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene name (see --help for the list).
    #[arg(value_parser = clap::builder::PossibleValuesParser::new(untangle::scenes::NAMES))]
    pub name: String,
    /// Random seed (for random scenes).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Resolution (cells per handkerchief side, or target size for large scenes).
    #[arg(long)]
    pub size: Option<usize>,
    /// Output OBJ (all pieces in one file, one group each).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Writes the scene.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    let scene = untangle::scenes::by_name(&args.name, args.size, args.seed)
        .ok_or_else(|| anyhow!("unknown scene '{}'", args.name))?;
    let parts: Vec<_> = scene
        .meshes
        .iter()
        .map(|m| (m, untangle::analysis::ObjectKind::Cloth))
        .collect();
    let (am, pos) = AnalysisMesh::new(&parts)?;
    let merged = am.merged(&pos, &scene.meshes.iter().collect::<Vec<_>>());
    obj::write_obj(
        &args.output,
        &merged,
        None,
        &format!("untangle scene {} --seed {}", args.name, args.seed),
    )?;
    ctx.say(format!(
        "wrote {} ({} triangles, {} vertices)",
        args.output.display(),
        merged.triangles.len(),
        merged.positions.len()
    ));
    Ok(0)
}
