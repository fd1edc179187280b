//! Pictures for people: a small software rasteriser for meshes coloured by the analysis (Cha &
//! Ko 2022, Sec. 3: red / green vertices) with their intersection curves, and per-step charts
//! like the paper's Fig. 15. Everything draws into an RGB [`Canvas`]; encoding to PNG is the
//! caller's (the CLI uses the `image` crate), so the library has no image or terminal
//! dependency.
//!
//! Modules: [`canvas`] (pixels, lines, text), [`font`] (5 x 7 bitmap glyphs), [`raster`]
//! (camera, z-buffer, shading), [`plot`] (charts).

pub mod canvas;
pub mod font;
pub mod plot;
pub mod raster;

pub use canvas::{Canvas, Rgb};
pub use plot::{step_chart, StepChart};
pub use raster::{Camera, Raster, Shading};

use crate::geom::Vec3;

/// A picture of a mesh: what to draw and from where.
#[derive(Clone, Debug)]
pub struct MeshPicture<'a> {
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Triangles (vertex indices).
    pub triangles: &'a [[u32; 3]],
    /// Per-vertex colours in `[0, 1]` (e.g. `analysis::coloring::vertex_colors`); `None` draws
    /// light grey.
    pub colors: Option<&'a [[f32; 3]]>,
    /// Polylines drawn on top (e.g. `analysis::curves::tanglement_curves`).
    pub curves: &'a [Vec<Vec3>],
    /// The camera (e.g. [`Camera::fit`] to the points of every picture to be compared).
    pub camera: &'a Camera,
    /// A caption written in the top-left corner.
    pub caption: &'a str,
    /// Draw the triangle edges (one pixel, [`WIRE_COLOR`]) where they are visible.
    pub wireframe: bool,
}

/// Background of mesh pictures.
pub const BACKGROUND: Rgb = [250, 250, 250];
/// Colour of triangle edges drawn over a mesh.
pub const WIRE_COLOR: Rgb = [45, 45, 45];
/// Colour of curves drawn over a mesh.
pub const CURVE_COLOR: Rgb = [20, 20, 160];

/// The light of mesh pictures: from the viewer, a little from above and the left.
pub fn default_shading(cam: &Camera) -> Shading {
    Shading {
        light: (cam.toward_viewer * 1.0 + cam.up * 0.45 - cam.right * 0.25).normalize(),
        ambient: 0.35,
    }
}

/// Draws a [`MeshPicture`]: z-buffered, flat-shaded triangles, the visible triangle edges if
/// asked, then the curves (two pixels
/// wide, visible where they are not behind a surface by more than 1% of the picture's depth
/// range), then the caption.
pub fn mesh_picture(p: &MeshPicture) -> Canvas {
    let cam = p.camera;
    let mut r = Raster::new(cam.width, cam.height, BACKGROUND);
    let sh = default_shading(cam);
    r.mesh(cam, p.positions, p.triangles, p.colors, &sh);
    let depths: Vec<f64> = p.positions.iter().map(|x| cam.project(x)[2]).collect();
    let lo = depths.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = depths.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let bias = if hi > lo { 0.01 * (hi - lo) } else { 0.0 };
    if p.wireframe {
        let mut edges: Vec<[u32; 2]> = p
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| [t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3])]))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        for [a, b] in edges {
            let seg = [p.positions[a as usize], p.positions[b as usize]];
            r.polyline(cam, &seg, 1, 0.3 * bias, WIRE_COLOR);
        }
    }
    for c in p.curves {
        r.polyline(cam, c, 2, bias, CURVE_COLOR);
    }
    r.canvas.text(10, 10, p.caption, 2, plot::INK);
    r.canvas
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coloured_sheet_shows_its_colours_and_a_curve_on_it() {
        let m = crate::scenes::handkerchief("s", 8, 8, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
        let colors: Vec<[f32; 3]> = m
            .positions
            .iter()
            .map(|p| {
                if p.x < 0.0 {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                }
            })
            .collect();
        let cam = Camera::fit(&m.positions, Vec3::z(), Vec3::y(), 200, 200, 10);
        let curve = vec![vec![Vec3::new(0.3, -0.4, 0.0), Vec3::new(0.3, 0.4, 0.0)]];
        let pic = mesh_picture(&MeshPicture {
            positions: &m.positions,
            triangles: &m.triangles,
            colors: Some(&colors),
            curves: &curve,
            camera: &cam,
            caption: "TEST",
            wireframe: false,
        });
        assert_eq!((pic.width, pic.height), (200, 200));
        // Lit almost head-on: pure-ish red on the left, green on the right.
        let px = |x: f64, y: f64| {
            let s = cam.project(&Vec3::new(x, y, 0.0));
            pic.get(s[0] as i64, s[1] as i64).unwrap()
        };
        let l = px(-0.3, 0.1);
        let r = px(0.15, 0.1);
        assert!(l[0] > 150 && l[1] < 10 && l[2] < 10, "{l:?}");
        assert!(r[1] > 150 && r[0] < 10 && r[2] < 10, "{r:?}");
        // The curve is drawn over the sheet.
        assert_eq!(px(0.3, 0.0), CURVE_COLOR);
        // Background around the sheet (the margin).
        assert_eq!(pic.get(3, 100), Some(BACKGROUND));
        assert_eq!(pic.count(WIRE_COLOR), 0);
        // With the wireframe: grid lines (x = -0.25 is one) are drawn, cell interiors are not.
        let wired = mesh_picture(&MeshPicture {
            positions: &m.positions,
            triangles: &m.triangles,
            colors: Some(&colors),
            curves: &curve,
            camera: &cam,
            caption: "TEST",
            wireframe: true,
        });
        let at = |x: f64, y: f64| {
            let s = cam.project(&Vec3::new(x, y, 0.0));
            wired.get(s[0].floor() as i64, s[1].floor() as i64).unwrap()
        };
        assert_eq!(at(-0.25, 0.1), WIRE_COLOR);
        assert_eq!(at(-0.3, 0.1), l);
        assert_eq!(at(0.3, 0.0), CURVE_COLOR);
    }
}
