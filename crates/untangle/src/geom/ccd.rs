//! Conservative continuous collision detection (CCD) for vertex–triangle and edge–edge pairs.
//!
//! # Problem
//!
//! Every vertex moves on a straight line from its position at `t = 0` to its position at `t = 1`
//! (the linear-trajectory model of Provot 1997, "Collision and self-collision handling in cloth
//! model dedicated to design garments", and Bridson, Fedkiw, Anderson 2002, "Robust treatment of
//! collisions, contact and friction for cloth animation", Sec. 7). A query asks for the first time
//! at which the two primitives come within the distance `thickness` of each other. Following the
//! inclusion-based formulation of Wang, Ferguson, Schneider, Jiang, Attene, Panozzo 2021 ("A Large
//! Scale Benchmark and an Inclusion-Based Algorithm for Continuous Collision Detection", ACM TOG
//! 40(5), Sec. 4), the pair touches iff the multilinear function
//!
//! ```text
//! vertex–triangle  F(t, s, r) = p(t) - a(t) - s (b(t) - a(t)) - s r (c(t) - b(t))
//! edge–edge        F(t, u, v) = ea0(t) + u (ea1(t) - ea0(t)) - eb0(t) - v (eb1(t) - eb0(t))
//! ```
//!
//! has a point of `|F| <= thickness` in the unit cube. For the triangle we use the *collapsed*
//! square `(s, r) -> (u, v) = (s (1 - r), s r)`, which maps `[0,1]^2` onto the triangle (weights of
//! `b` and `c`), so no half of the parameter box is wasted on `u + v > 1` as in the paper, and `F`
//! stays affine in each of `t`, `s`, `r` separately.
//!
//! # Algorithm
//!
//! Because `F` is affine in each parameter separately, its image over any axis-aligned
//! sub-box of parameters lies in the bounding box of its values at the 8 corners (the *inclusion*
//! of Wang et al. 2021, Sec. 4.1). A box whose inclusion misses the `thickness` neighbourhood of
//! the origin contains no contact and is discarded; otherwise it is split in half along the
//! parameter whose corner values spread most. The search is depth-first, earlier time first, with
//! branch and bound on the answer: a box is *accepted* once its inclusion is narrower than the
//! tolerance (or the box budget or the depth limit is reached), the answer becomes the smallest
//! start time of an accepted box, and boxes that start no earlier than the current answer are
//! skipped.
//!
//! The corner values of a child box are the parent's corner values and the midpoints of parent
//! edges. Since `F` is affine along every box edge, a midpoint value is exactly the average of the
//! two end values, so the whole search runs on the 8 root corner values, which are differences of
//! input points (`p - a`, `ea_i - eb_j`, ...), plus one addition and one exact halving per new
//! value. No time, barycentric coordinate or position is ever rounded.
//!
//! # Why there are no false negatives (in floating point)
//!
//! Let `u = 2^-53` and `V_k` the largest magnitude of the computed root corner values on axis
//! `k`. A root value is one rounded subtraction: its error is at most `u V_k (1 + 2u)`. A midpoint
//! is `fl(fl(x + y) * 0.5)`: the sum has relative error `<= u`, the halving is exact except in the
//! subnormal range (absolute error `<= 2^-1075`); the inherited error is the average of the two
//! parents' errors. By induction, every computed corner value of a box at depth `d` (number of
//! splits from the root, at most 170 here) is within `E_d = (d + 1) u V_k (1 + 10^-6) + d 2^-1075`
//! of the exact value of `F` at that corner, and its magnitude stays below `V_k (1 + 10^-6)`.
//! The code uses `E'_d = (d + 1) c_k` with `c_k = 4 u V_k + 2^-1020`, which exceeds `E_d` with a
//! margin that absorbs the rounding of the few operations that compute the thresholds
//! `thickness (1 + 2^-50) + E'_d` themselves. A box is discarded only if on some axis `k`
//! `min corner > threshold` or `max corner < -threshold` (so `|F_k| > thickness` on the whole
//! box, by the inclusion property and `|F_k| <= |F|`), or, for `thickness >= 2^-400`, if the
//! inclusion box widened by `E'_d` misses the Euclidean ball of radius `thickness` with a relative
//! margin of `2^-48` on the squared distances. Hence a discarded box never contains a contact, and
//! every contact lies in an accepted box or in a box skipped because it starts no earlier than
//! the current answer. The returned time is therefore never later than the first contact, and a
//! contact anywhere in `[0, 1]` always yields `Some`. Time boxes are dyadic intervals of width at
//! least `2^-52`, so their start times are exact. Non-finite input, coordinates beyond `2^1000`
//! (where the differences could overflow) and a non-finite thickness return `Some(0.0)`, the
//! always-conservative answer.
//!
//! # Accuracy of the answer (false positives)
//!
//! When a box is accepted by the tolerance test, its inclusion meets the thickness neighbourhood
//! and is at most `tol = tolerance * max_k V_k` wide on every axis, so at the returned time the
//! primitives are within `sqrt(3) (thickness + tol)` (up to rounding) of each other: a false
//! positive is a near miss closer than that. [`Impact::resolved`] is false when the answer came
//! from the box budget or the depth limit instead (still conservative, possibly early).

use super::{Real, Vec3};

/// Options of the inclusion-based CCD search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdOptions {
    /// Co-domain tolerance relative to the size of the query (the largest magnitude of the
    /// relative corner positions): a box whose inclusion is narrower than this on every axis is
    /// accepted as a contact. Smaller values mean fewer false positives and more work.
    pub tolerance: Real,
    /// Maximum number of boxes that survive the exclusion test before the search stops and
    /// conservatively reports the earliest box still open.
    pub max_boxes: u32,
}

impl Default for CcdOptions {
    fn default() -> Self {
        CcdOptions {
            tolerance: 1e-6,
            max_boxes: 100_000,
        }
    }
}

/// Detailed answer of a CCD query that found a possible contact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Impact {
    /// Conservative time of impact: never later than the first time the primitives come within
    /// the thickness of each other.
    pub toi: Real,
    /// End of the accepted time interval `[toi, toi_upper]`.
    pub toi_upper: Real,
    /// True when the answer was accepted by the tolerance test (the primitives are then within
    /// `sqrt(3) (thickness + tolerance * scale)` of each other at `toi`); false when it came from
    /// the box budget, the depth limit or invalid input (conservative but possibly early).
    pub resolved: bool,
    /// Number of boxes that survived the exclusion test (work measure).
    pub boxes: u32,
}

/// Conservative vertex–triangle CCD. `x0`/`x1` = `[p, a, b, c]` at `t = 0` / `t = 1`, linear
/// motion in between (Provot 1997; Bridson et al. 2002, Sec. 7).
///
/// Returns a time of impact `t` in `[0, 1]` at which the vertex comes within `thickness` (`>= 0`)
/// of the triangle: never later than the true first contact, and never `None` when a contact
/// (distance `<= thickness`) happens at some `t` in `[0, 1]`. False positives (near misses within
/// the tolerance, see the module docs) are possible. Inclusion-based search after Wang et al.
/// 2021, Sec. 4; see the module docs for the floating-point argument.
pub fn vertex_triangle_ccd(x0: &[Vec3; 4], x1: &[Vec3; 4], thickness: f64) -> Option<f64> {
    vertex_triangle_impact(x0, x1, thickness, &CcdOptions::default()).map(|i| i.toi)
}

/// Conservative edge–edge CCD. `x0`/`x1` = `[ea0, ea1, eb0, eb1]` at `t = 0` / `t = 1`, linear
/// motion in between. Same guarantees as [`vertex_triangle_ccd`].
pub fn edge_edge_ccd(x0: &[Vec3; 4], x1: &[Vec3; 4], thickness: f64) -> Option<f64> {
    edge_edge_impact(x0, x1, thickness, &CcdOptions::default()).map(|i| i.toi)
}

/// [`vertex_triangle_ccd`] with explicit options and a detailed answer.
pub fn vertex_triangle_impact(
    x0: &[Vec3; 4],
    x1: &[Vec3; 4],
    thickness: f64,
    options: &CcdOptions,
) -> Option<Impact> {
    // F(t, s, r) = p - a - s (b - a) - s r (c - b); corner index = 4 t + 2 s + r.
    let corner = |x: &[Vec3; 4], s: usize, r: usize| -> [f64; 3] {
        let q = match (s, r) {
            (0, _) => &x[1],
            (1, 0) => &x[2],
            _ => &x[3],
        };
        [x[0].x - q.x, x[0].y - q.y, x[0].z - q.z]
    };
    solve(x0, x1, thickness, options, corner)
}

/// [`edge_edge_ccd`] with explicit options and a detailed answer.
pub fn edge_edge_impact(
    x0: &[Vec3; 4],
    x1: &[Vec3; 4],
    thickness: f64,
    options: &CcdOptions,
) -> Option<Impact> {
    // F(t, u, v) = ea(u) - eb(v); corner index = 4 t + 2 u + v.
    let corner = |x: &[Vec3; 4], u: usize, v: usize| -> [f64; 3] {
        let (a, b) = (&x[u], &x[2 + v]);
        [a.x - b.x, a.y - b.y, a.z - b.z]
    };
    solve(x0, x1, thickness, options, corner)
}

/// Conservative vertex–triangle CCD over a batch of queries (in parallel, results in input
/// order): `queries[i] = (x0, x1)` as for [`vertex_triangle_ccd`].
pub fn vertex_triangle_ccd_batch(
    queries: &[([Vec3; 4], [Vec3; 4])],
    thickness: f64,
) -> Vec<Option<f64>> {
    use rayon::prelude::*;
    queries
        .par_iter()
        .with_min_len(256)
        .map(|(a, b)| vertex_triangle_ccd(a, b, thickness))
        .collect()
}

/// Conservative edge–edge CCD over a batch of queries (in parallel, results in input order):
/// `queries[i] = (x0, x1)` as for [`edge_edge_ccd`].
pub fn edge_edge_ccd_batch(queries: &[([Vec3; 4], [Vec3; 4])], thickness: f64) -> Vec<Option<f64>> {
    use rayon::prelude::*;
    queries
        .par_iter()
        .with_min_len(256)
        .map(|(a, b)| edge_edge_ccd(a, b, thickness))
        .collect()
}

/// Largest coordinate magnitude accepted; beyond it differences and sums could overflow.
const MAX_COORD: f64 = 1e300; // < 2^1000
/// Maximum number of halvings of the time interval (keeps box start times exact).
const MAX_DEPTH_T: u8 = 52;
/// Maximum number of halvings of each barycentric parameter.
const MAX_DEPTH_UV: u8 = 60;
/// 2^-53, the unit roundoff.
const UNIT_ROUNDOFF: f64 = f64::EPSILON * 0.5;

/// The conservative answer for input the search cannot reason about.
fn give_up() -> Option<Impact> {
    Some(Impact {
        toi: 0.0,
        toi_upper: 1.0,
        resolved: false,
        boxes: 0,
    })
}

type Corners = [[f64; 3]; 8];

fn solve(
    x0: &[Vec3; 4],
    x1: &[Vec3; 4],
    thickness: f64,
    options: &CcdOptions,
    corner: impl Fn(&[Vec3; 4], usize, usize) -> [f64; 3],
) -> Option<Impact> {
    let in_range = |x: &[Vec3; 4]| x.iter().all(|p| p.iter().all(|c| c.abs() <= MAX_COORD));
    // NaN compares false, so non-finite input is caught here too.
    let valid = in_range(x0) && in_range(x1) && thickness.abs() <= MAX_COORD;
    if !valid {
        return give_up();
    }
    let delta = thickness.max(0.0);
    let mut c: Corners = [[0.0; 3]; 8];
    for a in 0..2 {
        for b in 0..2 {
            c[2 * a + b] = corner(x0, a, b);
            c[4 + 2 * a + b] = corner(x1, a, b);
        }
    }
    let mut v = [0.0f64; 3];
    for k in &c {
        for i in 0..3 {
            v[i] = v[i].max(k[i].abs());
        }
    }
    let scale = v[0].max(v[1]).max(v[2]);
    let mut search = Search {
        err: v.map(|vk| 4.0 * UNIT_ROUNDOFF * vk + f64::powi(2.0, -1020)),
        delta_up: delta * (1.0 + f64::powi(2.0, -50)),
        ball: delta >= f64::powi(2.0, -400),
        delta2_up: delta * delta * (1.0 + f64::powi(2.0, -48)),
        tol: options.tolerance.max(0.0) * scale,
        max_boxes: options.max_boxes.max(1),
        boxes: 0,
        best: f64::INFINITY,
        best_upper: f64::INFINITY,
        resolved: true,
    };
    search.visit(&c, 0.0, 1.0, [0, 0, 0]);
    (search.best <= 1.0).then_some(Impact {
        toi: search.best,
        toi_upper: search.best_upper,
        resolved: search.resolved,
        boxes: search.boxes,
    })
}

/// State of one depth-first inclusion search.
struct Search {
    /// Per-axis error growth per level of depth (`c_k` of the module docs).
    err: [f64; 3],
    delta_up: f64,
    ball: bool,
    delta2_up: f64,
    tol: f64,
    max_boxes: u32,
    boxes: u32,
    best: f64,
    best_upper: f64,
    resolved: bool,
}

impl Search {
    fn accept(&mut self, t_lo: f64, t_w: f64, resolved: bool) {
        if t_lo < self.best {
            self.best = t_lo;
            self.best_upper = t_lo + t_w;
            self.resolved = resolved;
        }
    }

    /// Inclusion bounds `(lo, hi)` of a box at total split depth `levels - 1`, or `None` when the
    /// box provably holds no contact (see the module docs for the error bound).
    #[inline]
    fn include(&self, c: &Corners, levels: f64) -> Option<([f64; 3], [f64; 3])> {
        let mut lo = c[0];
        let mut hi = c[0];
        for k in &c[1..] {
            for i in 0..3 {
                lo[i] = lo[i].min(k[i]);
                hi[i] = hi[i].max(k[i]);
            }
        }
        let mut e = [0.0; 3];
        for i in 0..3 {
            e[i] = levels * self.err[i];
            let thr = self.delta_up + e[i];
            if lo[i] > thr || hi[i] < -thr {
                return None;
            }
        }
        if self.ball {
            // Lower bound of |F|^2 over the inclusion box widened by the error bound.
            let mut s = 0.0;
            for i in 0..3 {
                let g = (lo[i] - e[i]).max(-hi[i] - e[i]).max(0.0) * (1.0 - f64::powi(2.0, -50));
                s += g * g;
            }
            if s * (1.0 - f64::powi(2.0, -48)) > self.delta2_up {
                return None;
            }
        }
        Some((lo, hi))
    }

    /// Processes the box with corner values `c`, time interval `[t_lo, t_lo + t_w]` and
    /// split depths `depth` = (time, first, second parameter).
    fn visit(&mut self, c: &Corners, mut t_lo: f64, mut t_w: f64, mut depth: [u8; 3]) {
        let mut c = *c;
        loop {
            if t_lo >= self.best {
                return;
            }
            let levels = (depth[0] + depth[1] + depth[2]) as f64 + 1.0;
            let Some((lo, hi)) = self.include(&c, levels) else {
                return;
            };
            self.boxes += 1;
            let width = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(hi[2] - lo[2]);
            if width <= self.tol {
                self.accept(t_lo, t_w, true);
                return;
            }
            if self.boxes >= self.max_boxes {
                self.accept(t_lo, t_w, false);
                return;
            }
            // Once an answer exists, only the part of the box before it matters: if one time
            // half is provably empty (or starts after the answer), continue with the other half
            // alone. This keeps degenerate contacts (parallel edges meeting all along their
            // overlap at one instant) from being covered box by box at full resolution.
            if self.best < f64::INFINITY && depth[0] < MAX_DEPTH_T {
                let (lower, upper) = split(&c, 4);
                let h = t_w * 0.5;
                let lower_empty = self.include(&lower, levels + 1.0).is_none();
                let upper_empty =
                    t_lo + h >= self.best || self.include(&upper, levels + 1.0).is_none();
                if lower_empty || upper_empty {
                    if lower_empty && upper_empty {
                        return;
                    }
                    depth[0] += 1;
                    t_w = h;
                    if lower_empty {
                        c = upper;
                        t_lo += h;
                    } else {
                        c = lower;
                    }
                    continue;
                }
            }
            // Split along the parameter whose corner values spread most.
            let mut best_dim = usize::MAX;
            let mut best_spread = -1.0;
            for (dim, mask) in [(0usize, 4usize), (1, 2), (2, 1)] {
                let cap = if dim == 0 { MAX_DEPTH_T } else { MAX_DEPTH_UV };
                if depth[dim] >= cap {
                    continue;
                }
                let mut spread = 0.0f64;
                for k in 0..8 {
                    if k & mask == 0 {
                        for i in 0..3 {
                            spread = spread.max((c[k | mask][i] - c[k][i]).abs());
                        }
                    }
                }
                if spread > best_spread {
                    best_spread = spread;
                    best_dim = dim;
                }
            }
            if best_dim == usize::MAX {
                self.accept(t_lo, t_w, false);
                return;
            }
            let (lower, upper) = split(&c, [4usize, 2, 1][best_dim]);
            depth[best_dim] += 1;
            if best_dim == 0 {
                t_w *= 0.5;
                self.visit(&lower, t_lo, t_w, depth);
                t_lo += t_w;
            } else {
                self.visit(&lower, t_lo, t_w, depth);
            }
            c = upper;
        }
    }
}

/// Splits a box in half along the parameter whose corner-index bit is `mask`; the new corner
/// values are midpoints of parent values (exact in real arithmetic: `F` is affine along edges).
#[inline]
fn split(c: &Corners, mask: usize) -> (Corners, Corners) {
    let mut lower = *c;
    let mut upper = *c;
    for k in 0..8 {
        if k & mask == 0 {
            let j = k | mask;
            let mid = [
                (c[k][0] + c[j][0]) * 0.5,
                (c[k][1] + c[j][1]) * 0.5,
                (c[k][2] + c[j][2]) * 0.5,
            ];
            lower[j] = mid;
            upper[k] = mid;
        }
    }
    (lower, upper)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(x, y, z)
    }

    /// Unit right triangle in the plane z = 0.
    fn tri() -> [Vec3; 3] {
        [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]
    }

    fn vt(p0: Vec3, p1: Vec3, t0: [Vec3; 3], t1: [Vec3; 3], h: f64) -> Option<f64> {
        vertex_triangle_ccd(&[p0, t0[0], t0[1], t0[2]], &[p1, t1[0], t1[1], t1[2]], h)
    }

    fn ee(a0: [Vec3; 2], b0: [Vec3; 2], a1: [Vec3; 2], b1: [Vec3; 2], h: f64) -> Option<f64> {
        edge_edge_ccd(
            &[a0[0], a0[1], b0[0], b0[1]],
            &[a1[0], a1[1], b1[0], b1[1]],
            h,
        )
    }

    /// A conservative answer close to the expected one (within the default tolerance).
    fn near(got: Option<f64>, want: f64) {
        let t = got.unwrap_or_else(|| panic!("expected a hit at {want}"));
        assert!(t <= want && t >= want - 1e-5, "toi {t}, expected {want}");
    }

    #[test]
    fn vertex_through_face() {
        let t = tri();
        near(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, -1.0), t, t, 0.0), 0.5);
        // Passing beside the triangle.
        assert_eq!(vt(v(0.8, 0.8, 1.0), v(0.8, 0.8, -1.0), t, t, 0.0), None);
        // Face moving onto a static vertex.
        let up = t.map(|p| p + v(0.0, 0.0, 1.0));
        near(vt(v(0.1, 0.1, 0.25), v(0.1, 0.1, 0.25), t, up, 0.0), 0.25);
    }

    #[test]
    fn vertex_on_face_at_start_and_end() {
        let t = tri();
        near(vt(v(0.2, 0.2, 0.0), v(0.2, 0.2, 1.0), t, t, 0.0), 0.0);
        near(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.0), t, t, 0.0), 1.0);
        // On an edge and on a corner at t = 1.
        near(vt(v(0.5, 0.0, 1.0), v(0.5, 0.0, 0.0), t, t, 0.0), 1.0);
        near(vt(v(1.0, 0.0, 1.0), v(1.0, 0.0, 0.0), t, t, 0.0), 1.0);
        // Stopping just short of the face.
        assert_eq!(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 1e-3), t, t, 0.0), None);
    }

    #[test]
    fn vertex_sliding_in_face_plane() {
        let t = tri();
        // Entering the triangle from outside, in its plane: first contact on edge x = 0 at 0.5.
        near(vt(v(-1.0, 0.3, 0.0), v(1.0, 0.3, 0.0), t, t, 0.0), 0.5);
        // Sliding in the plane but beside the triangle.
        assert_eq!(vt(v(-1.0, 2.0, 0.0), v(2.0, 2.0, 0.0), t, t, 0.0), None);
        // Sliding inside the triangle all the time.
        near(vt(v(0.1, 0.1, 0.0), v(0.3, 0.1, 0.0), t, t, 0.0), 0.0);
    }

    #[test]
    fn zero_motion() {
        let t = tri();
        near(vt(v(0.2, 0.2, 0.0), v(0.2, 0.2, 0.0), t, t, 0.0), 0.0);
        assert_eq!(vt(v(0.2, 0.2, 0.5), v(0.2, 0.2, 0.5), t, t, 0.0), None);
        let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        let b = [v(0.5, -1.0, 0.5), v(0.5, 1.0, 0.5)];
        assert_eq!(ee(a, b, a, b, 0.0), None);
        near(ee(a, b, a, b, 0.5), 0.0);
    }

    #[test]
    fn thickness_exactly_reached() {
        let t = tri();
        // The vertex stops at distance exactly 0.25 = thickness at t = 1.
        near(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.25), t, t, 0.25), 1.0);
        assert_eq!(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.25), t, t, 0.2), None);
        // Reaches 0.5 at t = 0.5 (from 1 down to 0).
        near(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.0), t, t, 0.5), 0.5);
        // Passing beside the corner: the closest approach to corner (1,0,0) is exactly 0.5.
        near(vt(v(1.5, -1.0, 0.0), v(1.5, 1.0, 0.0), t, t, 0.5), 0.5);
        assert_eq!(vt(v(1.5, -1.0, 0.0), v(1.5, 1.0, 0.0), t, t, 0.49), None);
        // Beside a corner diagonally: the Euclidean (not max-norm) distance decides.
        let p = v(1.0 + 0.3, -0.3, 0.3); // distance 0.3 sqrt(3) ~ 0.52 from (1, 0, 0)
        assert_eq!(vt(p, p, t, t, 0.5), None);
        near(vt(p, p, t, t, 0.53), 0.0);
        // Edge-edge: crossing edges separated by exactly the thickness.
        let a = [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        let b = [v(0.0, -1.0, 0.75), v(0.0, 1.0, 0.75)];
        near(ee(a, b, a, b, 0.75), 0.0);
        assert_eq!(ee(a, b, a, b, 0.74), None);
    }

    #[test]
    fn toi_exactly_zero_and_one() {
        let a = [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        let b0 = [v(0.0, -1.0, 0.0), v(0.0, 1.0, 0.0)];
        let b1 = [v(0.0, -1.0, 1.0), v(0.0, 1.0, 1.0)];
        near(ee(a, b0, a, b1, 0.0), 0.0);
        near(ee(a, b1, a, b0, 0.0), 1.0);
        assert_eq!(ee(a, b1, a, b1, 0.0), None);
    }

    #[test]
    fn parallel_edges() {
        // Coplanar parallel edges approaching each other sideways: touch at t = 0.5.
        let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        let b0 = [v(0.5, 1.0, 0.0), v(1.5, 1.0, 0.0)];
        let b1 = [v(0.5, -1.0, 0.0), v(1.5, -1.0, 0.0)];
        near(ee(a, b0, a, b1, 0.0), 0.5);
        // Same but without overlap along the edge direction.
        let c0 = [v(1.5, 1.0, 0.0), v(2.5, 1.0, 0.0)];
        let c1 = [v(1.5, -1.0, 0.0), v(2.5, -1.0, 0.0)];
        assert_eq!(ee(a, c0, a, c1, 0.0), None);
        // Collinear, overlapping and sliding along each other.
        let d0 = [v(0.5, 0.0, 0.0), v(1.5, 0.0, 0.0)];
        let d1 = [v(2.5, 0.0, 0.0), v(3.5, 0.0, 0.0)];
        near(ee(a, d0, a, d1, 0.0), 0.0);
        // Collinear, sliding towards each other: endpoints meet at t = 0.5.
        let e0 = [v(2.0, 0.0, 0.0), v(3.0, 0.0, 0.0)];
        let e1 = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        near(ee(a, e0, a, e1, 0.0), 0.5);
        // Parallel at a fixed offset 1e-3 out of plane, sliding: never touch.
        let f0 = [v(0.5, 0.0, 1e-3), v(1.5, 0.0, 1e-3)];
        let f1 = [v(-0.5, 0.0, 1e-3), v(0.5, 0.0, 1e-3)];
        assert_eq!(ee(a, f0, a, f1, 0.0), None);
        near(ee(a, f0, a, f1, 1e-3), 0.0);
    }

    #[test]
    fn edges_touch_at_endpoint() {
        let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        // Endpoint of b reaches endpoint of a at t = 1.
        let b0 = [v(1.0, 0.0, 1.0), v(1.0, 1.0, 1.0)];
        let b1 = [v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0)];
        near(ee(a, b0, a, b1, 0.0), 1.0);
        // Shifted by a hair: never touch.
        let s = v(1e-9, 0.0, 0.0);
        assert_eq!(ee(a, b0.map(|p| p + s), a, b1.map(|p| p + s), 0.0), None);
        // Shared endpoint from the start.
        let c = [v(1.0, 0.0, 0.0), v(2.0, 1.0, 0.0)];
        near(ee(a, c, a, c, 0.0), 0.0);
    }

    #[test]
    fn degenerate_primitives() {
        // A triangle collapsed to a segment and an edge collapsed to a point.
        let flat = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0)];
        near(
            vt(v(0.5, 0.0, 1.0), v(0.5, 0.0, -1.0), flat, flat, 0.0),
            0.5,
        );
        let pt = [v(0.0, 0.0, 1.0), v(0.0, 0.0, 1.0)];
        let seg = [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        let pt1 = [v(0.0, 0.0, -1.0), v(0.0, 0.0, -1.0)];
        near(ee(pt, seg, pt1, seg, 0.0), 0.5);
    }

    #[test]
    fn invalid_input_is_conservative() {
        let t = tri();
        let p = v(5.0, 5.0, 5.0);
        assert_eq!(vt(v(f64::NAN, 0.0, 0.0), p, t, t, 0.0), Some(0.0));
        assert_eq!(vt(p, v(f64::INFINITY, 0.0, 0.0), t, t, 0.0), Some(0.0));
        assert_eq!(vt(p, p, t, t, f64::NAN), Some(0.0));
        assert_eq!(vt(p, p, t, t, -1.0), None); // negative thickness acts as zero
                                                // Huge but finite coordinates are still handled exactly.
        let s = 1e250;
        let big = t.map(|q| q * s);
        near(
            vt(v(0.2, 0.2, 1.0) * s, v(0.2, 0.2, -1.0) * s, big, big, 0.0),
            0.5,
        );
    }

    #[test]
    fn batch_matches_single() {
        let t = tri();
        let q: Vec<([Vec3; 4], [Vec3; 4])> = (0..600)
            .map(|i| {
                let x = i as f64 / 300.0 - 0.5;
                (
                    [v(x, 0.2, 1.0), t[0], t[1], t[2]],
                    [v(x, 0.2, -1.0), t[0], t[1], t[2]],
                )
            })
            .collect();
        let got = vertex_triangle_ccd_batch(&q, 0.0);
        for (i, (a, b)) in q.iter().enumerate() {
            assert_eq!(got[i], vertex_triangle_ccd(a, b, 0.0));
        }
        assert!(got.iter().any(|g| g.is_some()) && got.iter().any(|g| g.is_none()));
        let e: Vec<([Vec3; 4], [Vec3; 4])> = q
            .iter()
            .map(|(a, b)| {
                (
                    [a[0], a[0] + v(0.0, 1.0, 0.0), a[1], a[2]],
                    [b[0], b[0] + v(0.0, 1.0, 0.0), b[1], b[2]],
                )
            })
            .collect();
        let got = edge_edge_ccd_batch(&e, 0.0);
        for (i, (a, b)) in e.iter().enumerate() {
            assert_eq!(got[i], edge_edge_ccd(a, b, 0.0));
        }
    }
}
