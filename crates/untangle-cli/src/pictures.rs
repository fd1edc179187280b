//! PNG files for people: mesh pictures coloured by the analysis and per-step charts, drawn by
//! `untangle::render` and encoded with the `image` crate; written atomically.

use anyhow::{anyhow, Result};
use std::path::Path;
use untangle::analysis::{self, Analysis, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::render::{self, Camera, Canvas};

/// Encodes a canvas as PNG bytes.
pub fn encode_png(c: &Canvas) -> Result<Vec<u8>> {
    let img = image::RgbImage::from_raw(c.width, c.height, c.rgb.clone())
        .ok_or_else(|| anyhow!("internal: canvas size does not match its pixels"))?;
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png)?;
    Ok(buf.into_inner())
}

/// Writes a canvas as a PNG file, atomically.
pub fn write_png(path: &Path, c: &Canvas) -> Result<()> {
    untangle::fsio::write_atomic(path, &encode_png(c)?)?;
    Ok(())
}

/// The view of mesh pictures: from the front, somewhat from the right and above.
pub const VIEW: [f64; 3] = [0.55, 0.7, 1.0];

/// A camera for pictures of `points` (fit every picture to be compared to the same points).
pub fn camera(points: &[Vec3], width: u32, height: u32) -> Camera {
    Camera::fit(
        points,
        Vec3::new(VIEW[0], VIEW[1], VIEW[2]),
        Vec3::y(),
        width,
        height,
        24,
    )
}

/// A picture of analysed meshes: red / orange / green / grey vertex colours
/// (`analysis::coloring::vertex_colors`), the triangle edges when they are on average more than
/// 8 pixels long, and the intersection curves in dark blue.
pub fn analysis_picture(
    am: &AnalysisMesh,
    pos: &[Vec3],
    a: &Analysis,
    cam: &Camera,
    caption: &str,
) -> Canvas {
    let colors = analysis::coloring::vertex_colors(am, &a.coloring, &a.segments);
    let curves = analysis::curves::tanglement_curves(am, pos, a);
    // Triangle edges only where they are far enough apart on screen to help, not to darken.
    let edge_sum: f64 = am
        .triangles
        .iter()
        .map(|t| (pos[t[0] as usize] - pos[t[1] as usize]).norm())
        .sum();
    let mean_edge_px = cam.scale * edge_sum / am.triangles.len().max(1) as f64;
    render::mesh_picture(&render::MeshPicture {
        positions: pos,
        triangles: &am.triangles,
        colors: Some(&colors),
        curves: &curves,
        camera: cam,
        caption,
        wireframe: mean_edge_px > 8.0,
    })
}

/// The Fig. 15-like chart of a run: red vertices per step (red curve) over the time per step
/// (grey bars, log scale).
pub fn red_vertex_chart(red: &[f64], ms: &[f64], title: &str) -> Canvas {
    render::step_chart(&render::StepChart {
        title,
        x_label: "step",
        y_label: "red vertices",
        curve: red,
        bars: Some(("ms per step", ms)),
        width: 800,
        height: 480,
    })
}
