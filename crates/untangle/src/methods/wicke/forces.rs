//! Correction forces (Wicke et al. 2006, Sec. 5.2-5.3) and the set of cloth parts allowed to
//! pass through each other while they act.
//!
//! - Paths with an inside region (Sec. 5.2, Eq. 4): each inside vertex `r` is pulled toward
//!   its target `r' = s(d_P(r))` with `F = m a`, `a = (r' - r)/|r' - r| min(k |r' - r|, a_max)`
//!   (the paper prints `max`; "up to a maximum value" is a `min`), and, applied symmetrically,
//!   `-F` goes to the corners of the triangle holding `r'` by its barycentric weights. A region
//!   without vertices (a small loop inside a few triangles) uses one inside point instead of a
//!   random one per triangle: the centroid of the path's samples, whose force goes to the
//!   corners of its triangle (deterministic, ours).
//! - BI/BI pairs (Sec. 5.3, Eq. 5-7): a distance field `h` to the cloth boundary (Dijkstra
//!   distances along rest edge lengths, per vertex, linear on triangles); on the surface around
//!   `P'` the force field `F_out = -grad h / |grad h| min(k h, a_max)` is averaged over `P'`
//!   by segment length and applied to every vertex of the triangles holding `P`'s pieces, so
//!   `P` is pushed over the other sheet toward that sheet's nearest boundary. The gradient is
//!   that of the linear interpolant on the world triangle (the paper's `T(u) grad_u h` up to
//!   the distortion of the parameterisation; only its direction is used).
//! - Free parts (Sec. 5.2, last paragraph): collision handling is off between inside
//!   vertices and the corners of intersecting triangles ("a small region around the
//!   intersection lines"), whatever tanglement they belong to; every other pair keeps the
//!   ordinary thickness. (Read per tanglement instead, free parts of different tanglements
//!   kept apart, the exploded handkerchief made no progress at all: in a crumpled ball the
//!   tanglements interleave and must pass through each other. BENCHMARKS.md, "Wicke".)
//!
//! Forces are expressed as accelerations (`k` in 1/s², `a_max` in m/s²), so the settings do
//! not depend on the cloth's density.

use super::correspondence::{panel_maps, path_samples, uv_point, PanelMap, Sample, UvLocator};
use crate::analysis::{Analysis, AnalysisMesh, PathKind, Region};
use crate::geom::{Vec2, Vec3};
use crate::mesh::Garment;

/// An inside point: the vertices carrying it with their weights, its uv and its panel.
type Source = (Vec<(u32, f64)>, Vec2, u32);

/// Force settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceParams {
    /// `k` of Eq. 4 and 6, as an acceleration per metre of penetration (1/s²).
    pub stiffness: f64,
    /// `f_max` of Eq. 4 and 6, as an acceleration (m/s²).
    pub max_acceleration: f64,
    /// At most this many RBF centres per path and panel (the paper: 5-30).
    pub max_centers: usize,
    /// Apply the reaction `-F` at the target points (Sec. 5.2: "should be applied
    /// symmetrically").
    pub symmetric: bool,
}

impl Default for ForceParams {
    fn default() -> Self {
        ForceParams {
            stiffness: 200.0,
            max_acceleration: 20.0,
            max_centers: 30,
            symmetric: true,
        }
    }
}

/// What the forces of one analysis acted on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForceReport {
    /// Inside points given a target (vertices, or one centroid for a region without vertices).
    pub inside_points: usize,
    /// Paths whose inside points were given targets.
    pub mapped_paths: usize,
    /// BI paths pushed toward the boundary (Sec. 5.3).
    pub bi_paths: usize,
    /// Paths with neither (II paths of BB/II pairs, paths without a usable region or fit).
    pub unhandled_paths: usize,
    /// Vertices free to pass through each other this step.
    pub free_vertices: usize,
}

/// Per vertex, the distance to the cloth's boundary along edges of rest (uv) length
/// ([`crate::mesh::Topology::distances_to_boundary`]). Infinite everywhere for a closed
/// surface.
pub fn boundary_distance(g: &Garment) -> Vec<f64> {
    let topo = &g.topology;
    let uv = g.mesh.uv.as_ref().expect("a garment always has uv");
    // Rest length of each world edge: its uv length in the triangles holding it (the shorter).
    let mut len = vec![f64::INFINITY; topo.num_edges()];
    for (t, tri) in g.mesh.triangles.iter().enumerate() {
        let ut = uv.triangles[t];
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if let Some(e) = topo.edge_between(a, b) {
                let l = (uv.coords[ut[k] as usize] - uv.coords[ut[(k + 1) % 3] as usize]).norm();
                len[e as usize] = len[e as usize].min(l);
            }
        }
    }
    topo.distances_to_boundary(|_, _, e| len[e as usize])
}

/// Gradient of the linear interpolant of `h` on the world triangle `x` (zero when degenerate).
pub fn triangle_gradient(x: [Vec3; 3], h: [f64; 3]) -> Vec3 {
    let n = (x[1] - x[0]).cross(&(x[2] - x[0]));
    let a2 = n.norm_squared();
    if a2 == 0.0 || !a2.is_finite() {
        return Vec3::zeros();
    }
    // grad(lambda_i) = n x (x_{i+2} - x_{i+1}) / |n|^2.
    (0..3).fold(Vec3::zeros(), |g, i| {
        g + n.cross(&(x[(i + 2) % 3] - x[(i + 1) % 3])) * (h[i] / a2)
    })
}

/// The context the forces need that does not change between steps (owns copies of the garment
/// and its analysis mesh, so that a loop can keep it beside them).
pub struct ForceContext {
    /// The garment (uv layer, panels, topology).
    pub garment: Garment,
    /// Its analysis mesh (one object).
    pub mesh: AnalysisMesh,
    /// uv point location.
    pub locator: UvLocator,
    /// Distance to the boundary per vertex ([`boundary_distance`]).
    pub boundary: Vec<f64>,
}

impl ForceContext {
    /// The context of `garment` analysed as `mesh`.
    pub fn new(garment: &Garment, mesh: &AnalysisMesh) -> Self {
        ForceContext {
            garment: garment.clone(),
            mesh: mesh.clone(),
            locator: UvLocator::new(garment),
            boundary: boundary_distance(garment),
        }
    }

    /// The acceleration of Eq. 4 / Eq. 6 for a penetration `d` along unit direction `dir`.
    fn accel(p: &ForceParams, dir: Vec3, d: f64) -> Vec3 {
        dir * (p.stiffness * d).min(p.max_acceleration)
    }

    /// Per vertex, the acceleration (m/s²) of the correction forces of analysis `a` at
    /// positions `pos` with masses `mass`, the free vertices, and what acted.
    pub fn accelerations(
        &self,
        a: &Analysis,
        pos: &[Vec3],
        mass: &[f64],
        p: &ForceParams,
    ) -> (Vec<Vec3>, Vec<bool>, ForceReport) {
        let n = pos.len();
        let mut acc = vec![Vec3::zeros(); n];
        let mut free = vec![false; n];
        let mut rep = ForceReport::default();
        // The small region around the intersection lines: the corners of the intersecting
        // triangles.
        for c in a.intersecting_triangles() {
            for v in self.mesh.triangles[c as usize] {
                free[v as usize] = true;
            }
        }
        for (i, path) in a.paths.iter().enumerate() {
            let Some(partner) = a.paths.get(path.corresponds_to as usize) else {
                rep.unhandled_paths += 1;
                continue;
            };
            let samples = path_samples(&self.mesh, pos, a, path);
            if samples.is_empty() {
                rep.unhandled_paths += 1;
                continue;
            }
            if path.kind == PathKind::BoundaryInside && partner.kind == PathKind::BoundaryInside {
                // Sec. 5.3 on every vertex of the triangles holding P's pieces.
                let f_p = self.boundary_acceleration(&samples, pos, p);
                let mut verts: Vec<u32> = samples
                    .iter()
                    .flat_map(|s| self.mesh.triangles[s.here_triangle as usize])
                    .collect();
                verts.sort_unstable();
                verts.dedup();
                for v in verts {
                    acc[v as usize] += f_p;
                }
                rep.bi_paths += 1;
                continue;
            }
            // Sec. 5.2: inside points and their targets.
            let inside: &[u32] = match &a.regions[i] {
                Region::Inside(vs) => vs,
                _ => &[],
            };
            if inside.is_empty() && !path.closed {
                rep.unhandled_paths += 1;
                continue;
            }
            // The inside region is free (Sec. 5.2) whether or not a correspondence can be fitted.
            for &v in inside {
                free[v as usize] = true;
            }
            let maps = panel_maps(&self.garment, &samples, p.max_centers);
            if maps.is_empty() {
                rep.unhandled_paths += 1;
                continue;
            }
            let sources = if inside.is_empty() {
                self.centroid_source(&samples, &maps[0])
                    .into_iter()
                    .collect()
            } else {
                self.vertex_sources(inside, &maps)
            };
            let pulled = self.pull_to_targets(&sources, &maps, pos, mass, p, &mut acc);
            rep.inside_points += pulled;
            if pulled > 0 {
                rep.mapped_paths += 1;
            } else {
                rep.unhandled_paths += 1;
            }
        }
        rep.free_vertices = free.iter().filter(|&&f| f).count();
        (acc, free, rep)
    }

    /// Eq. 7: the boundary field `F_out` (Eq. 6) on the surface around `P'` (the samples'
    /// partner triangles), averaged over the samples by segment length.
    fn boundary_acceleration(&self, samples: &[Sample], pos: &[Vec3], p: &ForceParams) -> Vec3 {
        let total: f64 = samples.iter().map(|s| s.length).sum();
        let mut f_p = Vec3::zeros();
        for s in samples {
            let t = self.mesh.triangles[s.there_triangle as usize];
            let hs = [0, 1, 2].map(|k| self.boundary[t[k] as usize]);
            if hs.iter().any(|h| !h.is_finite()) {
                continue;
            }
            let xs = [0, 1, 2].map(|k| pos[t[k] as usize]);
            let grad = triangle_gradient(xs, hs);
            let gn = grad.norm();
            if gn == 0.0 || total <= 0.0 {
                continue;
            }
            let h = (0..3).map(|k| hs[k] * s.there[k]).sum::<f64>();
            f_p += Self::accel(p, -grad / gn, h) * (s.length / total);
        }
        f_p
    }

    /// A region without vertices: one inside point, the centroid of the samples on the
    /// panel of `map`, carried by the corners of its triangle.
    fn centroid_source(&self, samples: &[Sample], map: &PanelMap) -> Option<Source> {
        let g = &self.garment;
        let on: Vec<_> = samples
            .iter()
            .filter(|s| g.panel_of_triangle[s.here_triangle as usize] == map.from)
            .collect();
        let c = on.iter().fold(Vec2::zeros(), |s, x| {
            s + uv_point(g, x.here_triangle, &x.here)
        }) / on.len().max(1) as f64;
        let (t, b) = self.locator.locate(&c, map.from)?;
        let corners = self.mesh.triangles[t as usize];
        Some(((0..3).map(|k| (corners[k], b[k])).collect(), c, map.from))
    }

    /// The inside vertices, each at the uv copy on the first of its panels that has a map.
    fn vertex_sources(&self, inside: &[u32], maps: &[PanelMap]) -> Vec<Source> {
        let g = &self.garment;
        let uv = g.mesh.uv.as_ref().expect("a garment always has uv");
        inside
            .iter()
            .filter_map(|&v| {
                g.uv_copies.row(v as usize).iter().find_map(|&c| {
                    let panel = g.panel_of_uv[c as usize];
                    maps.iter()
                        .any(|m| m.from == panel)
                        .then(|| (vec![(v, 1.0)], uv.coords[c as usize], panel))
                })
            })
            .collect()
    }

    /// Eq. 4 for each source: pulled toward `s(d_P(u))`, the reaction on the target's corners
    /// when symmetric. Adds to `acc`; returns how many sources got a target.
    fn pull_to_targets(
        &self,
        sources: &[Source],
        maps: &[PanelMap],
        pos: &[Vec3],
        mass: &[f64],
        p: &ForceParams,
        acc: &mut [Vec3],
    ) -> usize {
        // A force `f` (mass times acceleration) on vertex `v`.
        let mut push = |v: u32, f: Vec3| {
            let m = mass[v as usize];
            if m > 0.0 {
                acc[v as usize] += f / m;
            }
        };
        let mut pulled = 0;
        for (corners, u, panel) in sources {
            let Some(m) = maps.iter().find(|m| m.from == *panel) else {
                continue;
            };
            let Some((t, b)) = self.locator.locate(&m.map.eval(u), m.to) else {
                continue;
            };
            let tri = self.mesh.triangles[t as usize];
            let here = corners
                .iter()
                .fold(Vec3::zeros(), |s, &(v, w)| s + pos[v as usize] * w);
            let there = (0..3).fold(Vec3::zeros(), |s, k| s + pos[tri[k] as usize] * b[k]);
            let d = there - here;
            let dn = d.norm();
            if dn == 0.0 || !dn.is_finite() {
                continue;
            }
            let m_src: f64 = corners.iter().map(|&(v, w)| mass[v as usize] * w).sum();
            let f = Self::accel(p, d / dn, dn) * m_src;
            for &(v, w) in corners {
                push(v, f * w);
            }
            if p.symmetric {
                for k in 0..3 {
                    push(tri[k], -f * b[k]);
                }
            }
            pulled += 1;
        }
        pulled
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The gradient of a linear function restricted to a triangle is the function's gradient
        /// projected onto the triangle's plane.
        #[test]
        fn triangle_gradient_of_a_linear_function(
            x in prop::array::uniform9(-1.0f64..1.0),
            g in prop::array::uniform3(-3.0f64..3.0),
            c in -1.0f64..1.0,
        ) {
            let xs = [Vec3::new(x[0], x[1], x[2]), Vec3::new(x[3], x[4], x[5]), Vec3::new(x[6], x[7], x[8])];
            let n = (xs[1] - xs[0]).cross(&(xs[2] - xs[0]));
            prop_assume!(n.norm() > 1e-3);
            let gv = Vec3::new(g[0], g[1], g[2]);
            let h = xs.map(|p| gv.dot(&p) + c);
            let nn = n / n.norm();
            let want = gv - nn * nn.dot(&gv);
            let got = triangle_gradient(xs, h);
            prop_assert!((got - want).norm() < 1e-8 * (1.0 + want.norm()) / (n.norm() * n.norm()).min(1.0), "{got:?} vs {want:?}");
        }
    }
}
