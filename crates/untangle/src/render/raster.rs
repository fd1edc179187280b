//! A small software rasteriser for pictures of cloth: an orthographic camera fitted to the
//! points, a z-buffer, flat Lambert shading (two-sided) of per-vertex colours, and 3D polylines
//! (intersection curves) drawn on top with a depth test.
//!
//! Pixel (`x`, `y`) has its centre at (`x + 0.5`, `y + 0.5`) in screen coordinates (`y` down). A
//! triangle covers the pixels whose centres lie strictly inside it; a centre exactly on an edge
//! belongs to the triangle for which that edge is a top or left edge (the usual rule, so that two
//! triangles sharing an edge never both or neither cover a pixel on it).

use super::canvas::{Canvas, Rgb};
use crate::geom::Vec3;

/// An orthographic camera: world point -> (screen x, screen y, depth), larger depth = nearer.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Unit vector from the scene towards the viewer.
    pub toward_viewer: Vec3,
    /// Unit screen-right direction in the world.
    pub right: Vec3,
    /// Unit screen-up direction in the world.
    pub up: Vec3,
    /// World point at the image centre.
    pub center: Vec3,
    /// Pixels per world unit.
    pub scale: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// A camera looking along `-toward_viewer` (with `up_hint` projected to screen-up) whose
    /// image of `points` fits `width x height` with `margin` pixels to spare on every side.
    /// Degenerate inputs (no points, zero extent, `up_hint` parallel to the view) still give a
    /// usable camera.
    pub fn fit(
        points: &[Vec3],
        toward_viewer: Vec3,
        up_hint: Vec3,
        width: u32,
        height: u32,
        margin: u32,
    ) -> Camera {
        let d = toward_viewer
            .try_normalize(1e-300)
            .unwrap_or(Vec3::new(0.0, 0.0, 1.0));
        let right = match up_hint
            .cross(&d)
            .try_normalize(1e-9 * up_hint.norm().max(1e-300))
        {
            Some(r) => r,
            None => {
                // `up_hint` is parallel to the view: any direction across it will do.
                let alt = if d.x.abs() < 0.9 {
                    Vec3::x()
                } else {
                    Vec3::y()
                };
                d.cross(&alt).normalize()
            }
        };
        let up = d.cross(&right);
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            let s = [p.dot(&right), p.dot(&up)];
            for k in 0..2 {
                lo[k] = lo[k].min(s[k]);
                hi[k] = hi[k].max(s[k]);
            }
        }
        if points.is_empty() {
            lo = [-1.0; 2];
            hi = [1.0; 2];
        }
        let mid = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let depth_mid = if points.is_empty() {
            0.0
        } else {
            points.iter().map(|p| p.dot(&d)).sum::<f64>() / points.len() as f64
        };
        let center = right * mid[0] + up * mid[1] + d * depth_mid;
        let avail_w = (width as f64 - 2.0 * margin as f64).max(1.0);
        let avail_h = (height as f64 - 2.0 * margin as f64).max(1.0);
        let ext = [(hi[0] - lo[0]).max(1e-12), (hi[1] - lo[1]).max(1e-12)];
        let scale = (avail_w / ext[0]).min(avail_h / ext[1]);
        Camera {
            toward_viewer: d,
            right,
            up,
            center,
            scale,
            width,
            height,
        }
    }

    /// Screen position (`x` right, `y` down, in pixels) and depth (larger = nearer) of `p`.
    pub fn project(&self, p: &Vec3) -> [f64; 3] {
        let q = p - self.center;
        [
            self.width as f64 / 2.0 + self.scale * q.dot(&self.right),
            self.height as f64 / 2.0 - self.scale * q.dot(&self.up),
            q.dot(&self.toward_viewer),
        ]
    }
}

/// Shading settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Shading {
    /// Unit direction towards the light (world).
    pub light: Vec3,
    /// Share of the colour lit regardless of orientation, in `[0, 1]`.
    pub ambient: f64,
}

/// A canvas with a depth buffer.
#[derive(Clone, Debug)]
pub struct Raster {
    /// The picture.
    pub canvas: Canvas,
    /// Depth per pixel (larger = nearer; `-inf` where nothing was drawn).
    pub depth: Vec<f64>,
}

/// Twice the signed area of (a, b, p) in screen coordinates (positive when p is to the left of
/// a -> b in a y-up frame, i.e. counter-clockwise on screen with y down negated).
fn edge_fn(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Whether edge a -> b of a triangle whose edge functions are positive inside is a top or left
/// edge (screen y down).
fn top_left(a: [f64; 2], b: [f64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    // The interior lies below a top edge (larger y: a horizontal edge running towards +x) and
    // to the right of a left edge (an edge running towards -y).
    (dy == 0.0 && dx > 0.0) || dy < 0.0
}

impl Raster {
    /// An empty `width x height` raster filled with `background`.
    pub fn new(width: u32, height: u32, background: Rgb) -> Raster {
        Raster {
            canvas: Canvas::new(width, height, background),
            depth: vec![f64::NEG_INFINITY; width as usize * height as usize],
        }
    }

    /// The pixels whose centres the screen triangle `s` covers (see the module text), with the
    /// barycentric weights of each centre. Degenerate triangles cover nothing.
    pub fn covered(&self, s: [[f64; 2]; 3], mut f: impl FnMut(i64, i64, [f64; 3])) {
        let area = edge_fn(s[0], s[1], s[2]);
        if area == 0.0 || !area.is_finite() {
            return;
        }
        // Orient so that the edge functions are positive inside.
        let s = if area > 0.0 { s } else { [s[0], s[2], s[1]] };
        let area = area.abs();
        let lo_x = s.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
        let hi_x = s.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max);
        let lo_y = s.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
        let hi_y = s.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
        let x0 = ((lo_x - 0.5).floor() as i64).max(0);
        let x1 = ((hi_x - 0.5).ceil() as i64).min(self.canvas.width as i64 - 1);
        let y0 = ((lo_y - 0.5).floor() as i64).max(0);
        let y1 = ((hi_y - 0.5).ceil() as i64).min(self.canvas.height as i64 - 1);
        let edges = [(1, 2), (2, 0), (0, 1)];
        let tl = edges.map(|(i, j)| top_left(s[i], s[j]));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                let w = edges.map(|(i, j)| edge_fn(s[i], s[j], p));
                if (0..3).all(|k| w[k] > 0.0 || (w[k] == 0.0 && tl[k])) {
                    f(x, y, w.map(|v| v / area));
                }
            }
        }
    }

    /// Draws a world triangle with per-corner colours (linear in `[0, 1]`) shaded flat by its
    /// normal (two-sided Lambert), keeping the nearest surface per pixel.
    pub fn triangle(&mut self, cam: &Camera, p: [Vec3; 3], colors: [[f32; 3]; 3], sh: &Shading) {
        let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
        let lambert = n
            .try_normalize(1e-300)
            .map_or(0.0, |n| n.dot(&sh.light).abs());
        let shade = sh.ambient + (1.0 - sh.ambient) * lambert;
        let q = p.map(|x| cam.project(&x));
        let s = q.map(|x| [x[0], x[1]]);
        // The corners in the order `covered` reports weights for.
        let area = edge_fn(s[0], s[1], s[2]);
        let order = if area > 0.0 { [0, 1, 2] } else { [0, 2, 1] };
        let mut hits = Vec::new();
        self.covered(s, |x, y, w| hits.push((x, y, w)));
        let w_cnt = self.canvas.width as usize;
        for (x, y, w) in hits {
            let z: f64 = (0..3).map(|k| w[k] * q[order[k]][2]).sum();
            let i = y as usize * w_cnt + x as usize;
            if z > self.depth[i] {
                self.depth[i] = z;
                let mut c = [0u8; 3];
                for ch in 0..3 {
                    let v: f64 = (0..3)
                        .map(|k| w[k] * colors[order[k]][ch] as f64)
                        .sum::<f64>()
                        * shade;
                    c[ch] = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                }
                self.canvas.set(x, y, c);
            }
        }
    }

    /// Draws a mesh: every triangle with its corners' colours (`colors[v]`, or light grey).
    pub fn mesh(
        &mut self,
        cam: &Camera,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        colors: Option<&[[f32; 3]]>,
        sh: &Shading,
    ) {
        for t in triangles {
            let p = t.map(|v| positions[v as usize]);
            let c = t.map(|v| colors.map_or([0.8, 0.8, 0.8], |c| c[v as usize]));
            self.triangle(cam, p, c, sh);
        }
    }

    /// Draws a 3D polyline `width` pixels thick where it is not behind a surface by more than
    /// `bias` (world units along the view; curves lying on a surface stay visible).
    pub fn polyline(&mut self, cam: &Camera, pts: &[Vec3], width: u32, bias: f64, c: Rgb) {
        let w = width.max(1) as i64;
        let lo = -(w - 1) / 2;
        for seg in pts.windows(2) {
            let a = cam.project(&seg[0]);
            let b = cam.project(&seg[1]);
            let n = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil().max(1.0) as usize;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let x = a[0] + (b[0] - a[0]) * t;
                let y = a[1] + (b[1] - a[1]) * t;
                let z = a[2] + (b[2] - a[2]) * t;
                let (px, py) = (x.floor() as i64, y.floor() as i64);
                for dy in lo..lo + w {
                    for dx in lo..lo + w {
                        let (xx, yy) = (px + dx, py + dy);
                        if xx < 0
                            || yy < 0
                            || xx >= self.canvas.width as i64
                            || yy >= self.canvas.height as i64
                        {
                            continue;
                        }
                        let i = yy as usize * self.canvas.width as usize + xx as usize;
                        if z + bias >= self.depth[i] {
                            self.canvas.set(xx, yy, c);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
        robust::orient2d(
            robust::Coord { x: a[0], y: a[1] },
            robust::Coord { x: b[0], y: b[1] },
            robust::Coord { x: c[0], y: c[1] },
        )
    }

    /// Independent oracle: the centre is strictly inside by exact orientation tests; `None` when
    /// it lies exactly on an edge line (the tie rule decides; not compared).
    fn inside(s: [[f64; 2]; 3], p: [f64; 2]) -> Option<bool> {
        let o = [
            orient(s[0], s[1], p),
            orient(s[1], s[2], p),
            orient(s[2], s[0], p),
        ];
        if o.contains(&0.0) {
            return None;
        }
        Some(o.iter().all(|&v| v > 0.0) || o.iter().all(|&v| v < 0.0))
    }

    fn check_coverage(s: [[f64; 2]; 3]) {
        let r = Raster::new(32, 24, [0; 3]);
        let mut got = std::collections::BTreeSet::new();
        r.covered(s, |x, y, w| {
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
            assert!(got.insert((x, y)));
        });
        if orient(s[0], s[1], s[2]) == 0.0 {
            assert!(got.is_empty());
            return;
        }
        for y in 0..24 {
            for x in 0..32 {
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                if let Some(ins) = inside(s, p) {
                    assert_eq!(got.contains(&(x, y)), ins, "pixel {x},{y} of {s:?}");
                }
            }
        }
    }

    #[test]
    fn a_fixed_triangle_covers_exactly_its_pixels() {
        // Centres strictly inside (0.3,0.2)-(10.7,0.2)-(0.3,8.9): x+0.5 in (0.3, ...) etc.
        let s = [[0.3, 0.2], [10.7, 0.2], [0.3, 8.9]];
        let r = Raster::new(32, 24, [0; 3]);
        let mut n = 0;
        r.covered(s, |_, _, _| n += 1);
        // Count by hand: row y has centre y+0.5; inside if x+0.5 > 0.3 and
        // (x+0.5-0.3)/10.4 + (y+0.5-0.2)/8.7 < 1.
        let mut expect = 0;
        for y in 0..24 {
            for x in 0..32 {
                let (u, v) = ((x as f64 + 0.5 - 0.3) / 10.4, (y as f64 + 0.5 - 0.2) / 8.7);
                if u > 0.0 && v > 0.0 && u + v < 1.0 {
                    expect += 1;
                }
            }
        }
        assert_eq!(n, expect);
        assert!(n > 30);
        check_coverage(s);
        check_coverage([s[0], s[2], s[1]]);
    }

    #[test]
    fn shared_edges_cover_every_centre_once() {
        // Two triangles of a quad whose diagonal passes through pixel centres.
        let a = [[2.5, 2.5], [12.5, 2.5], [12.5, 12.5]];
        let b = [[2.5, 2.5], [12.5, 12.5], [2.5, 12.5]];
        let r = Raster::new(32, 24, [0; 3]);
        let mut hits = std::collections::BTreeMap::new();
        for s in [a, b] {
            r.covered(s, |x, y, _| *hits.entry((x, y)).or_insert(0) += 1);
        }
        assert!(hits.values().all(|&n| n == 1));
        // Every centre strictly inside the quad, and on its top/left sides, is covered once.
        for y in 2..12 {
            for x in 2..12 {
                assert_eq!(hits.get(&(x, y)), Some(&1), "{x},{y}");
            }
        }
        assert_eq!(hits.len(), 100);
    }

    proptest! {
        #[test]
        fn coverage_matches_exact_inside_test(
            c in proptest::array::uniform6(-4.0f64..36.0)
        ) {
            check_coverage([[c[0], c[1]], [c[2], c[3]], [c[4], c[5]]]);
        }
    }

    proptest! {
        /// The z-buffer keeps, per pixel, the nearest of the triangles drawn there: the oracle
        /// renders each triangle alone and takes the pointwise maximum depth (and that
        /// triangle's colour); the draw order does not matter.
        #[test]
        fn z_buffer_is_the_pointwise_nearest_of_single_renders(
            c in proptest::collection::vec(-1.0f64..1.0, 45)
        ) {
            let tris: Vec<[Vec3; 3]> = c
                .chunks(9)
                .map(|v| [
                    Vec3::new(v[0], v[1], v[2]),
                    Vec3::new(v[3], v[4], v[5]),
                    Vec3::new(v[6], v[7], v[8]),
                ])
                .collect();
            let pts: Vec<Vec3> = tris.iter().flatten().copied().collect();
            let cam = Camera::fit(&pts, Vec3::new(0.3, 0.4, 1.0), Vec3::y(), 48, 40, 2);
            let sh = Shading { light: Vec3::z(), ambient: 0.3 };
            let color = |k: usize| [[k as f32 / 5.0, 0.5, 1.0 - k as f32 / 5.0]; 3];
            let singles: Vec<Raster> = tris
                .iter()
                .enumerate()
                .map(|(k, t)| {
                    let mut r = Raster::new(48, 40, [0; 3]);
                    r.triangle(&cam, *t, color(k), &sh);
                    r
                })
                .collect();
            for order in [vec![0, 1, 2, 3, 4], vec![4, 3, 2, 1, 0], vec![2, 0, 4, 1, 3]] {
                let mut r = Raster::new(48, 40, [0; 3]);
                for &k in &order {
                    r.triangle(&cam, tris[k], color(k), &sh);
                }
                for i in 0..48 * 40 {
                    let best = (0..5)
                        .filter(|&k| singles[k].depth[i] > f64::NEG_INFINITY)
                        .max_by(|&a, &b| singles[a].depth[i].total_cmp(&singles[b].depth[i]));
                    match best {
                        None => prop_assert_eq!(r.depth[i], f64::NEG_INFINITY),
                        Some(k) => {
                            prop_assert_eq!(r.depth[i], singles[k].depth[i]);
                            let ties = (0..5).filter(|&j| singles[j].depth[i] == singles[k].depth[i]).count();
                            if ties == 1 {
                                prop_assert_eq!(&r.canvas.rgb[3 * i..3 * i + 3], &singles[k].canvas.rgb[3 * i..3 * i + 3]);
                            }
                        }
                    }
                }
            }
        }
    }

    fn quad(z: f64, x0: f64, x1: f64) -> [[Vec3; 3]; 2] {
        let p = |x: f64, y: f64| Vec3::new(x, y, z);
        [
            [p(x0, -1.0), p(x1, -1.0), p(x1, 1.0)],
            [p(x0, -1.0), p(x1, 1.0), p(x0, 1.0)],
        ]
    }

    #[test]
    fn z_buffer_keeps_the_nearer_quad_in_any_order() {
        let pts = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)];
        let cam = Camera::fit(&pts, Vec3::z(), Vec3::y(), 40, 40, 4);
        let sh = Shading {
            light: Vec3::z(),
            ambient: 0.2,
        };
        let red = [[1.0, 0.0, 0.0]; 3];
        let blue = [[0.0, 0.0, 1.0]; 3];
        // Near quad (z = 0.5) covers the left part, far quad (z = -0.5) everything.
        let near = quad(0.5, -1.0, 0.2);
        let far = quad(-0.5, -1.0, 1.0);
        let mut pics = Vec::new();
        for near_first in [true, false] {
            let mut r = Raster::new(40, 40, [255; 3]);
            let mut order = vec![(near, red), (far, blue)];
            if !near_first {
                order.reverse();
            }
            for (q, c) in order {
                for t in q {
                    r.triangle(&cam, t, c, &sh);
                }
            }
            pics.push(r.canvas);
        }
        assert_eq!(pics[0], pics[1]);
        let c = &pics[0];
        // Left of x = 0.2 red, right of it blue, outside white; lit head-on: full colour.
        let x_split = cam.project(&Vec3::new(0.2, 0.0, 0.0))[0];
        for y in 6..34 {
            for x in 6..34 {
                let got = c.get(x, y).unwrap();
                let cx = x as f64 + 0.5;
                if cx < x_split - 0.01 {
                    assert_eq!(got, [255, 0, 0], "{x},{y}");
                } else if cx > x_split + 0.01 {
                    assert_eq!(got, [0, 0, 255], "{x},{y}");
                }
            }
        }
        assert_eq!(c.get(1, 1), Some([255; 3]));
        // Lambert: a quad tilted by 60 degrees from the light gets ambient + (1-ambient)/2.
        let mut r = Raster::new(40, 40, [255; 3]);
        let t = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        let rot =
            nalgebra::Rotation3::from_axis_angle(&Vec3::y_axis(), std::f64::consts::FRAC_PI_3);
        r.triangle(&cam, t.map(|p| rot * p), [[1.0, 1.0, 1.0]; 3], &sh);
        let v = ((0.2 + 0.8 * 0.5) * 255.0f64).round() as u8;
        assert!(r.canvas.count([v, v, v]) > 50);
    }

    #[test]
    fn camera_fit_keeps_points_inside_the_margin() {
        let pts: Vec<Vec3> = (0..50)
            .map(|i| {
                let t = i as f64 * 0.7;
                Vec3::new(t.sin() * 3.0, t.cos() + 2.0, (t * 1.3).sin() - 5.0)
            })
            .collect();
        for dir in [Vec3::z(), Vec3::new(1.0, 0.8, 1.2), Vec3::y(), Vec3::x()] {
            let cam = Camera::fit(&pts, dir, Vec3::y(), 200, 100, 10);
            let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
            for p in &pts {
                let s = cam.project(p);
                for k in 0..2 {
                    lo[k] = lo[k].min(s[k]);
                    hi[k] = hi[k].max(s[k]);
                }
            }
            assert!(
                lo[0] >= 10.0 - 1e-9 && hi[0] <= 190.0 + 1e-9,
                "{dir:?} {lo:?} {hi:?}"
            );
            assert!(
                lo[1] >= 10.0 - 1e-9 && hi[1] <= 90.0 + 1e-9,
                "{dir:?} {lo:?} {hi:?}"
            );
            // Tight along one axis.
            assert!(
                (lo[0] - 10.0).abs() < 1e-6 || (lo[1] - 10.0).abs() < 1e-6,
                "{dir:?} {lo:?}"
            );
            // Orthonormal frame, right-handed: right x up = toward viewer.
            assert!((cam.right.cross(&cam.up) - cam.toward_viewer).norm() < 1e-12);
        }
    }
}
