//! Point-to-point correspondences between intersecting parts of the cloth (Wicke et al. 2006,
//! Sec. 5.1): along an intersection path `P` every point has a known partner on the
//! corresponding path `P'` (the same world point, seen from the other triangle); a thin-plate
//! fit ([`super::rbf`]) in parameter space extrapolates that map to the inside region of `P`,
//! giving each inside vertex its target point.
//!
//! Parameter space is the garment's uv layer. A path may cross seams (several panels) and its
//! partner may lie on another panel, so one fit is made per panel of `P`, from the samples on
//! that panel whose partners lie on the panel most of them use; a vertex is mapped through the
//! fit of one of its uv copies' panels, and its target is looked up on that partner panel
//! ([`UvLocator`]).

use super::rbf::ThinPlate;
use crate::analysis::{Analysis, AnalysisMesh, End, Path};
use crate::geom::tri_tri::edge_triangle_point;
use crate::geom::{Vec2, Vec3};
use crate::mesh::Garment;

/// Barycentric coordinates of a segment end in triangle `t` (one of the two triangles of a
/// segment ending there): from the crossing's point on the crossed triangle, its parameter
/// along the crossing edge in a triangle holding that edge, or the corner of a loop vertex.
/// Floating point (positions only; the analysis's decisions are exact).
pub fn end_barycentric(
    mesh: &AnalysisMesh,
    pos: &[Vec3],
    a: &Analysis,
    end: End,
    t: u32,
) -> [f64; 3] {
    let tri = mesh.triangles[t as usize];
    let corner = |v: u32| tri.iter().position(|&c| c == v);
    let mut b = [0.0; 3];
    match end {
        End::LoopVertex(v) => {
            if let Some(k) = corner(v) {
                b[k] = 1.0;
            }
        }
        End::Crossing(c) => {
            let cr = a.crossings[c as usize];
            let [i, j] = mesh.topology.edges[cr.edge as usize];
            let p = |v: u32| &pos[v as usize];
            let ct = mesh.triangles[cr.triangle as usize];
            let (s, bary) = edge_triangle_point(p(i), p(j), p(ct[0]), p(ct[1]), p(ct[2]));
            if cr.triangle == t {
                b = bary;
            } else if let (Some(ki), Some(kj)) = (corner(i), corner(j)) {
                b[ki] = 1.0 - s;
                b[kj] = s;
            }
        }
    }
    b
}

/// One correspondence sample: a point of a path in the triangle of one of its pieces, and the
/// same world point in the partner piece's triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Triangle of the piece on `P`.
    pub here_triangle: u32,
    /// Barycentric coordinates there.
    pub here: [f64; 3],
    /// Triangle of the partner piece (on `P'`).
    pub there_triangle: u32,
    /// Barycentric coordinates there.
    pub there: [f64; 3],
    /// World length of the piece's segment (weight of the sample in averages, Eq. 7).
    pub length: f64,
}

/// One sample per piece of `path`, at the midpoint of its segment, in path order.
pub fn path_samples(mesh: &AnalysisMesh, pos: &[Vec3], a: &Analysis, path: &Path) -> Vec<Sample> {
    path.pieces()
        .iter()
        .map(|&piece| {
            let seg = &a.segments[(piece / 2) as usize];
            let side = (piece & 1) as usize;
            let (t, u) = (seg.triangles[side], seg.triangles[1 - side]);
            // Both ends in triangle `x`, read once each.
            let ends = |x: u32| seg.ends.map(|e| end_barycentric(mesh, pos, a, e, x));
            let mid = |[b0, b1]: [[f64; 3]; 2]| [0, 1, 2].map(|k| 0.5 * (b0[k] + b1[k]));
            let world = |b: [f64; 3]| {
                let tri = mesh.triangles[t as usize];
                (0..3).fold(Vec3::zeros(), |s, k| s + pos[tri[k] as usize] * b[k])
            };
            let here = ends(t);
            Sample {
                here_triangle: t,
                here: mid(here),
                there_triangle: u,
                there: mid(ends(u)),
                length: (world(here[1]) - world(here[0])).norm(),
            }
        })
        .collect()
}

/// The uv point of barycentric coordinates `b` in triangle `t` of the garment's uv layer.
pub fn uv_point(g: &Garment, t: u32, b: &[f64; 3]) -> Vec2 {
    let uv = g.mesh.uv.as_ref().expect("a garment always has uv");
    let tri = uv.triangles[t as usize];
    (0..3).fold(Vec2::zeros(), |s, k| s + uv.coords[tri[k] as usize] * b[k])
}

/// Per panel of a path, its correspondence map `d_P` (Sec. 5.1) into one partner panel.
#[derive(Clone, Debug)]
pub struct PanelMap {
    /// Panel the map is defined on.
    pub from: u32,
    /// Panel its values lie on.
    pub to: u32,
    /// The fit.
    pub map: ThinPlate,
}

/// The maps of a path's samples: one per panel of its pieces (panel order), from at most
/// `max_centers` samples spread evenly by arc length along the path (the paper uses 5-30
/// centres chosen by path length).
pub fn panel_maps(g: &Garment, samples: &[Sample], max_centers: usize) -> Vec<PanelMap> {
    let mut panels: Vec<u32> = samples
        .iter()
        .map(|s| g.panel_of_triangle[s.here_triangle as usize])
        .collect();
    panels.sort_unstable();
    panels.dedup();
    let mut maps = Vec::new();
    for from in panels {
        // The partner panel most samples of this panel map into (ties: lowest index).
        let mut to_counts: Vec<(u32, usize)> = Vec::new();
        for s in samples {
            if g.panel_of_triangle[s.here_triangle as usize] != from {
                continue;
            }
            let to = g.panel_of_triangle[s.there_triangle as usize];
            match to_counts.iter_mut().find(|(p, _)| *p == to) {
                Some(c) => c.1 += 1,
                None => to_counts.push((to, 1)),
            }
        }
        to_counts.sort_by_key(|&(p, c)| (std::cmp::Reverse(c), p));
        let Some(&(to, _)) = to_counts.first() else {
            continue;
        };
        let pts: Vec<(Vec2, Vec2)> = samples
            .iter()
            .filter(|s| {
                g.panel_of_triangle[s.here_triangle as usize] == from
                    && g.panel_of_triangle[s.there_triangle as usize] == to
            })
            .map(|s| {
                (
                    uv_point(g, s.here_triangle, &s.here),
                    uv_point(g, s.there_triangle, &s.there),
                )
            })
            .collect();
        let chosen = spread_by_arc_length(&pts, max_centers.max(1));
        let (cs, vs): (Vec<Vec2>, Vec<Vec2>) = chosen.into_iter().unzip();
        if let Some(map) = ThinPlate::fit(&cs, &vs) {
            maps.push(PanelMap { from, to, map });
        }
    }
    maps
}

/// At most `k` of `pts` (in order), evenly spaced by the arc length of their first
/// coordinates; all of them when there are at most `k`.
fn spread_by_arc_length(pts: &[(Vec2, Vec2)], k: usize) -> Vec<(Vec2, Vec2)> {
    if pts.len() <= k {
        return pts.to_vec();
    }
    let mut arc = Vec::with_capacity(pts.len());
    let mut s = 0.0;
    for (i, p) in pts.iter().enumerate() {
        if i > 0 {
            s += (p.0 - pts[i - 1].0).norm();
        }
        arc.push(s);
    }
    let total = s;
    let mut out = Vec::with_capacity(k);
    let mut next = 0;
    for j in 0..k {
        let want = total * j as f64 / k as f64;
        while next + 1 < pts.len() && arc[next] < want {
            next += 1;
        }
        out.push(pts[next]);
        next += 1;
        if next >= pts.len() {
            break;
        }
    }
    out
}

/// Point location in the uv layer, per panel: a uniform grid of triangle boxes; a point outside
/// every triangle of the panel gets the closest point of the nearest one (the fit extrapolates,
/// and targets must stay on the cloth).
pub struct UvLocator {
    min: Vec2,
    cell: f64,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<u32>>,
    tri_uv: Vec<[Vec2; 3]>,
    panel: Vec<u32>,
    by_panel: Vec<Vec<u32>>,
}

impl UvLocator {
    /// The locator of `g`'s uv layer.
    pub fn new(g: &Garment) -> UvLocator {
        let uv = g.mesh.uv.as_ref().expect("a garment always has uv");
        let tri_uv: Vec<[Vec2; 3]> = uv
            .triangles
            .iter()
            .map(|t| [0, 1, 2].map(|k| uv.coords[t[k] as usize]))
            .collect();
        let mut min = Vec2::new(f64::INFINITY, f64::INFINITY);
        let mut max = -min;
        for c in &uv.coords {
            min = min.inf(c);
            max = max.sup(c);
        }
        let n = tri_uv.len().max(1);
        let ext = (max - min).sup(&Vec2::new(1e-12, 1e-12));
        let cell = (ext.x * ext.y / n as f64).sqrt().max(1e-12);
        let nx = ((ext.x / cell).ceil() as usize).clamp(1, 4096);
        let ny = ((ext.y / cell).ceil() as usize).clamp(1, 4096);
        let mut loc = UvLocator {
            min,
            cell,
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
            tri_uv,
            panel: g.panel_of_triangle.clone(),
            by_panel: vec![Vec::new(); g.num_panels],
        };
        for t in 0..loc.tri_uv.len() {
            let tri = loc.tri_uv[t];
            let lo = tri[0].inf(&tri[1]).inf(&tri[2]);
            let hi = tri[0].sup(&tri[1]).sup(&tri[2]);
            let (x0, y0) = loc.cell_of(&lo);
            let (x1, y1) = loc.cell_of(&hi);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    loc.cells[y * nx + x].push(t as u32);
                }
            }
            loc.by_panel[loc.panel[t] as usize].push(t as u32);
        }
        loc
    }

    fn cell_of(&self, p: &Vec2) -> (usize, usize) {
        let f = |v: f64, n: usize| ((v / self.cell).floor().max(0.0) as usize).min(n - 1);
        (f(p.x - self.min.x, self.nx), f(p.y - self.min.y, self.ny))
    }

    /// The triangle of `panel` containing `p` and the barycentric coordinates of `p` in it,
    /// or, when none contains it, the nearest triangle and the coordinates of its closest point.
    /// `None` for an empty panel or a non-finite point.
    pub fn locate(&self, p: &Vec2, panel: u32) -> Option<(u32, [f64; 3])> {
        if !p.x.is_finite() || !p.y.is_finite() {
            return None;
        }
        let inside = p.x >= self.min.x
            && p.y >= self.min.y
            && p.x <= self.min.x + self.cell * self.nx as f64
            && p.y <= self.min.y + self.cell * self.ny as f64;
        if inside {
            let (x, y) = self.cell_of(p);
            for &t in &self.cells[y * self.nx + x] {
                if self.panel[t as usize] != panel {
                    continue;
                }
                let (b, d2) = closest_barycentric(&self.tri_uv[t as usize], p);
                if d2 == 0.0 {
                    return Some((t, b));
                }
            }
        }
        let mut best: Option<(f64, u32, [f64; 3])> = None;
        for &t in self.by_panel.get(panel as usize)? {
            let (b, d2) = closest_barycentric(&self.tri_uv[t as usize], p);
            if best.is_none_or(|(bd, _, _)| d2 < bd) {
                best = Some((d2, t, b));
            }
        }
        best.map(|(_, t, b)| (t, b))
    }
}

/// Barycentric coordinates of the point of triangle `tri` closest to `p`, and the squared
/// distance (0 when `p` is inside or on the triangle).
///
/// A planar specialisation of `geom::distance::point_triangle`: in the plane, a point inside
/// gets a distance of exactly 0 (its own barycentric coordinates, no projection), which
/// [`UvLocator::locate`]'s grid fast path relies on; the 3-D version's projection leaves a
/// rounding residue there and always lets the edges compete.
pub fn closest_barycentric(tri: &[Vec2; 3], p: &Vec2) -> ([f64; 3], f64) {
    let [a, b, c] = *tri;
    let cross = |u: Vec2, v: Vec2| u.x * v.y - u.y * v.x;
    let area = cross(b - a, c - a);
    if area != 0.0 {
        let l0 = cross(b - p, c - p) / area;
        let l1 = cross(c - p, a - p) / area;
        let l2 = 1.0 - l0 - l1;
        if l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0 {
            return ([l0, l1, l2], 0.0);
        }
    }
    // Outside (or degenerate): the closest point on the three edges.
    let mut best = ([1.0, 0.0, 0.0], (a - p).norm_squared());
    for (i, j) in [(0usize, 1usize), (1, 2), (2, 0)] {
        let (u, v) = (tri[i], tri[j]);
        let d = v - u;
        let len2 = d.norm_squared();
        let s = if len2 > 0.0 {
            ((p - u).dot(&d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = u + d * s;
        let d2 = (q - p).norm_squared();
        if d2 < best.1 {
            let mut bb = [0.0; 3];
            bb[i] = 1.0 - s;
            bb[j] = s;
            best = (bb, d2);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The closest point against dense sampling of the triangle.
        #[test]
        fn closest_barycentric_matches_sampling(
            t in prop::array::uniform6(-1.0f64..1.0),
            p in prop::array::uniform2(-2.0f64..2.0),
        ) {
            let tri = [Vec2::new(t[0], t[1]), Vec2::new(t[2], t[3]), Vec2::new(t[4], t[5])];
            let p = Vec2::new(p[0], p[1]);
            let (b, d2) = closest_barycentric(&tri, &p);
            prop_assert!(b.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)));
            prop_assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-9);
            let q = tri[0] * b[0] + tri[1] * b[1] + tri[2] * b[2];
            prop_assert!(((q - p).norm_squared() - d2).abs() < 1e-9 || d2 == 0.0);
            let n = 60;
            let mut best = f64::INFINITY;
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let s = tri[0] * (1.0 - u - v) + tri[1] * u + tri[2] * v;
                    best = best.min((s - p).norm());
                }
            }
            prop_assert!((q - p).norm() <= best + 1e-9);
            let diam = (tri[0] - tri[1]).norm().max((tri[1] - tri[2]).norm()).max((tri[2] - tri[0]).norm());
            prop_assert!((q - p).norm() >= best - diam / n as f64 * 1.5 - 1e-9);
        }
    }

    #[test]
    fn spread_keeps_order_and_count() {
        let pts: Vec<(Vec2, Vec2)> = (0..100)
            .map(|i| (Vec2::new(i as f64, 0.0), Vec2::new(0.0, i as f64)))
            .collect();
        let s = spread_by_arc_length(&pts, 10);
        assert_eq!(s.len(), 10);
        assert!(s.windows(2).all(|w| w[0].0.x < w[1].0.x));
        assert_eq!(s[0].0.x, 0.0);
        assert!(s[9].0.x >= 85.0);
        assert_eq!(spread_by_arc_length(&pts[..5], 10).len(), 5);
    }
}
