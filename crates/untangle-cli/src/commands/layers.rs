//! `untangle layers --body BODY.obj L1.obj L2.obj ... [--thickness t,...] [--weight w,...]
//! -o OUTDIR [--json PATH]`: implicit untangling of layered garments (Buffet et al. 2019).

use crate::output::{check_output, Context};
use anyhow::{bail, Context as _, Result};
use std::path::{Path, PathBuf};
use untangle::implicit::layers::{measure_separation, Stage};
use untangle::implicit::{untangle_layers, verify, FieldParams, GarmentInput, Params};
use untangle::mesh::{obj, Mesh};

/// Arguments of `layers`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Garment meshes (OBJ) in layer order, innermost first.
    #[arg(required = true)]
    pub layers: Vec<PathBuf>,
    /// The body (OBJ, closed): a layer of infinite stiffness that never moves.
    #[arg(long)]
    pub body: Option<PathBuf>,
    /// Cloth thickness per layer (comma separated; one value applies to all). Default: 0.2 % of
    /// the scene's bounding-box diagonal.
    #[arg(long, allow_negative_numbers = true, value_delimiter = ',')]
    pub thickness: Vec<f64>,
    /// Stiffness weight per layer (comma separated; one value applies to all). Default: 1.
    #[arg(long, allow_negative_numbers = true, value_delimiter = ',')]
    pub weight: Vec<f64>,
    /// Output folder: one OBJ per layer, same file names as the inputs.
    #[arg(long, short = 'o')]
    pub out: PathBuf,
    /// Write a JSON report here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Poisson-disk samples per garment (HRBF centres).
    #[arg(long, default_value_t = 600)]
    pub samples: usize,
    /// Grid cell of the field caches (default: about 400k nodes per garment).
    #[arg(long, allow_negative_numbers = true)]
    pub cell: Option<f64>,
    /// Sampling seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Undo the moves that would make a garment intersect itself where it did not before
    /// (slower; on large, heavily overlapping outfits the repair may then leave crossings
    /// between layers).
    #[arg(long)]
    pub no_new_self_intersections: bool,
}

fn per_layer(values: &[f64], n: usize, what: &str, default: f64) -> Result<Vec<f64>> {
    match values.len() {
        0 => Ok(vec![default; n]),
        1 => Ok(vec![values[0]; n]),
        k if k == n => Ok(values.to_vec()),
        k => bail!("--{what}: {k} values given for {n} layers (give one, or one per layer)"),
    }
}

/// Runs `layers`; exit code 0 when no intersection between layers or with the body remains.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    let mut inputs: Vec<&Path> = args.layers.iter().map(|p| p.as_path()).collect();
    if let Some(b) = &args.body {
        inputs.push(b);
    }
    let out_files: Vec<PathBuf> = args
        .layers
        .iter()
        .map(|p| args.out.join(p.file_name().unwrap_or(p.as_os_str())))
        .collect();
    for (k, f) in out_files.iter().enumerate() {
        if out_files[..k].contains(f) {
            bail!(
                "{}: two layers would be written to the same file",
                f.display()
            );
        }
        check_output(f, &inputs)?;
    }
    if let Some(j) = &args.json {
        check_output(j, &inputs)?;
    }
    let meshes: Vec<Mesh> = args
        .layers
        .iter()
        .map(|p| obj::read_obj(p))
        .collect::<std::result::Result<_, _>>()?;
    let body = args.body.as_deref().map(obj::read_obj).transpose()?;
    let n = meshes.len();
    let bbox = untangle::geom::Aabb::from_points(
        meshes
            .iter()
            .chain(body.as_ref())
            .flat_map(|m| &m.positions),
    );
    let thickness = per_layer(
        &args.thickness,
        n,
        "thickness",
        0.002 * bbox.extent().norm(),
    )?;
    let weight = per_layer(&args.weight, n, "weight", 1.0)?;
    let garments: Vec<GarmentInput> = meshes
        .iter()
        .zip(&thickness)
        .zip(&weight)
        .map(|((mesh, &thickness), &weight)| GarmentInput {
            mesh,
            thickness,
            weight,
        })
        .collect();
    let params = Params {
        fields: FieldParams {
            samples: args.samples,
            cell: args.cell,
            seed: args.seed,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut params = params;
    params.projection.prevent_self_intersections = args.no_new_self_intersections;
    params.repair.prevent_self_intersections = args.no_new_self_intersections;
    let fields_total = (n + body.is_some() as usize) as u64;
    let pb = ctx.progress(fields_total + n as u64, "untangling");
    let t = std::time::Instant::now();
    let result = untangle_layers(body.as_ref(), &garments, &params, &|s| match s {
        Stage::Field { done, .. } => {
            pb.set_message("fields");
            pb.set_position(done as u64)
        }
        Stage::Projection { layer, iteration } => {
            pb.set_message(format!("layer {} pass {iteration}", layer + 1));
            pb.set_position(fields_total + layer as u64);
        }
    })?;
    pb.finish_and_clear();
    let elapsed = t.elapsed().as_secs_f64();
    let refs: Vec<&Mesh> = meshes.iter().collect();
    let check = verify(body.as_ref(), &refs, &result.positions).context("verification")?;
    let seps = measure_separation(body.as_ref(), &garments, &result, 0.0);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the folder", args.out.display()))?;
    for ((m, p), f) in meshes.iter().zip(&result.positions).zip(&out_files) {
        let moved = Mesh {
            positions: p.clone(),
            ..m.clone()
        };
        obj::write_obj(
            f,
            &moved,
            None,
            "untangle layers (implicit untangling, Buffet et al. 2019)",
        )?;
    }
    if let Some(j) = &args.json {
        let layers: Vec<serde_json::Value> = result
            .reports
            .iter()
            .enumerate()
            .map(|(k, r)| {
                serde_json::json!({
                    "file": out_files[k].display().to_string(),
                    "thickness": thickness[k],
                    "weight": weight[k],
                    "report": r,
                    "separation": seps[k],
                    "remaining_intersections": check.per_layer[k],
                })
            })
            .collect();
        let doc = serde_json::json!({
            "layers": layers,
            "body": args.body.as_ref().map(|b| b.display().to_string()),
            "verification": check,
            "tolerance": result.tolerance,
            "body_field_ms": result.body_field_ms,
            "total_s": elapsed,
        });
        let text = serde_json::to_string_pretty(&doc).expect("serialisable");
        untangle::fsio::write_atomic(j, text.as_bytes())?;
    }
    for (k, r) in result.reports.iter().enumerate() {
        let sep = match &seps[k] {
            Some(s) if s.count > 0 => format!(
                ", separation from {}: mean {:.4} (rule {:.4}, {:.1}% off, {} vertices)",
                s.against,
                s.mean,
                s.expected,
                100.0 * s.relative_error,
                s.count
            ),
            _ => String::new(),
        };
        ctx.say(format!(
            "layer {} {}: {} of {} vertices moved (max {:.4}), {} in contact{sep}",
            k + 1,
            r.name,
            r.moved,
            r.vertices,
            r.max_displacement,
            r.in_contact
        ));
    }
    ctx.say(format!(
        "{} between layers, {} with the body, {} self-intersecting pairs (not handled); {:.2} s; written to {}",
        if check.between_layers == 0 { "no intersection".to_string() } else { format!("{} intersecting pairs", check.between_layers) },
        check.with_body,
        check.self_intersections,
        elapsed,
        args.out.display()
    ));
    Ok(if check.is_clean() { 0 } else { 1 })
}
