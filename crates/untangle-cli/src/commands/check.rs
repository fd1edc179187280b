//! `untangle check FILE... [--body FILE] [--json PATH] [--colored-obj PATH] [--png PATH]
//! [--winding-regions]`

use crate::output::{check_output, Context};
use anyhow::{Context as _, Result};
use std::path::{Path, PathBuf};
use untangle::analysis::{self, report::Report, AnalysisMesh, ObjectKind};
use untangle::mesh::obj;

/// Arguments of `check`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cloth meshes (OBJ), analysed together.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// An obstacle (body) mesh: only its intersections with the cloth are analysed.
    #[arg(long)]
    pub body: Option<PathBuf>,
    /// Write the JSON report here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write all meshes as one OBJ with per-vertex colours (red, green; grey for the body).
    #[arg(long)]
    pub colored_obj: Option<PathBuf>,
    /// Write a picture of the meshes coloured like `--colored-obj`, with the intersection
    /// curves in dark blue (PNG).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Give the paths Wicke's rules leave without an inside region the cloth that has passed
    /// into another tube of the same garment (generalized winding number), as `fix --method
    /// cha-ko` does: a leg's wall inside the other leg, a hem through a sleeve. Reported as the
    /// path's inside region; coloured red unless the path is a BLI.
    #[arg(long)]
    pub winding_regions: bool,
}

/// Runs `check`; exit code 0 when nothing intersects, 1 otherwise.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    let mut inputs: Vec<&Path> = args.files.iter().map(|p| p.as_path()).collect();
    if let Some(b) = &args.body {
        inputs.push(b);
    }
    for out in [&args.json, &args.colored_obj, &args.png]
        .into_iter()
        .flatten()
    {
        check_output(out, &inputs)?;
    }
    let mut meshes = Vec::new();
    for f in &args.files {
        for m in obj::read_obj(f)?.split_objects() {
            meshes.push((m, ObjectKind::Cloth));
        }
    }
    if let Some(b) = &args.body {
        meshes.push((obj::read_obj(b)?, ObjectKind::Obstacle));
    }
    let parts: Vec<_> = meshes.iter().map(|(m, k)| (m, *k)).collect();
    let (am, pos) = AnalysisMesh::new(&parts)?;
    let options = analysis::Options {
        winding_regions: args.winding_regions,
        ..Default::default()
    };
    let a = analysis::analyze_with(&am, &pos, &options).context("intersection analysis")?;
    let refs: Vec<_> = meshes.iter().map(|m| &m.0).collect();
    let report = Report::new(&am, &pos, &a).with_garment_info(&refs);
    if let Some(p) = &args.json {
        untangle::fsio::write_atomic(p, report.to_json().as_bytes())?;
    }
    if let Some(p) = &args.colored_obj {
        let merged = am.merged(&pos, &meshes.iter().map(|m| &m.0).collect::<Vec<_>>());
        let colors = analysis::coloring::vertex_colors(&am, &a.coloring, &a.segments);
        let mut text = obj::format_obj(
            &merged,
            Some(&colors),
            "untangle check: red = inside a tanglement, orange = on an intersecting triangle, \
             green = clean, grey = obstacle; objects 'curve_N' are the intersection curves",
        );
        let curves = analysis::curves::tanglement_curves(&am, &pos, &a);
        obj::append_polylines(&mut text, merged.positions.len(), "curve_", &curves);
        untangle::fsio::write_atomic(p, text.as_bytes())?;
    }
    if let Some(p) = &args.png {
        let cam = crate::pictures::camera(&pos, 720, 600);
        let caption = format!(
            "{} red vertices, {} intersecting pairs",
            a.coloring.num_red_vertices(),
            a.segments.len()
        );
        let pic = crate::pictures::analysis_picture(&am, &pos, &a, &cam, &caption);
        crate::pictures::write_png(p, &pic)?;
    }
    if !ctx.quiet {
        print!("{}", summary(&report));
    }
    Ok(if a.is_clean() { 0 } else { 1 })
}

/// A short human summary of a report.
pub fn summary(r: &Report) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let names: Vec<&str> = r.objects.iter().map(|o| o.name.as_str()).collect();
    let _ = writeln!(
        s,
        "analysed {} ({} triangles, {} vertices)",
        names.join(", "),
        r.triangles,
        r.vertices
    );
    for o in &r.objects {
        if let (Some(p), Some(sv)) = (o.panels, o.seam_vertices) {
            if p > 1 || sv > 0 {
                let panels = if p == 1 { "panel" } else { "panels" };
                let seams = if sv == 1 {
                    "seam vertex"
                } else {
                    "seam vertices"
                };
                let _ = writeln!(s, "  {}: {p} {panels}, {sv} {seams}", o.name);
            }
        }
    }
    if r.intersecting_triangle_pairs == 0 {
        let _ = writeln!(s, "no intersections");
    } else {
        let _ = writeln!(
            s,
            "{} intersecting triangle pairs ({} triangles), {} crossings",
            r.intersecting_triangle_pairs,
            r.intersecting_triangles.len(),
            r.crossings
        );
        for g in &r.pairs_by_objects {
            let [a, b] = g.objects.map(|o| r.objects[o as usize].name.as_str());
            let what = if g.relation == "self" {
                format!("{a} (self)")
            } else {
                format!("{a} x {b}")
            };
            let _ = writeln!(s, "  {what}: {} pairs", g.pairs);
        }
        let kinds: Vec<String> = r
            .tanglements_by_kind
            .iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        let _ = writeln!(s, "tanglements: {}", kinds.join(", "));
        let kinds: Vec<String> = r
            .paths_by_kind
            .iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        let _ = writeln!(s, "paths: {}", kinds.join(", "));
        let _ = writeln!(
            s,
            "red: {} vertices ({} out-most), {} triangles ({} red*)",
            r.red_vertices, r.outmost_red_vertices, r.red_triangles, r.red_star_triangles
        );
        let blis: Vec<&analysis::report::PathReport> =
            r.paths.iter().filter(|p| p.kind == "BLI").collect();
        for p in blis.iter().take(5) {
            let [x, y, z] = p.location;
            let v = p.loop_vertices.first().map(|v| v + 1).unwrap_or(0);
            let region = p
                .inside_vertices
                .map(|n| format!(" (inside region: {n} vertices)"))
                .unwrap_or_default();
            let _ = writeln!(
                s,
                "  BLI on {} at vertex {v} ({x:.4}, {y:.4}, {z:.4}): outside Cha & Ko's method{region}",
                r.objects[p.object as usize].name
            );
        }
        if blis.len() > 5 {
            let _ = writeln!(
                s,
                "  ... and {} more BLI paths (see --json)",
                blis.len() - 5
            );
        }
    }
    let _ = writeln!(s, "time: {:.2} ms", r.timing_ms.total);
    s
}
