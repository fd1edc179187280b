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
//! Because `F` is affine in each parameter separately, its value anywhere in an axis-aligned
//! sub-box of parameters is a convex combination (with the multilinear interpolation weights) of
//! its values at the box's 8 corners. So the image of the box lies in the convex hull of the 8
//! corner values, and in particular in their bounding box (the *inclusion* of Wang et al. 2021,
//! Sec. 4.1). A box is discarded when it provably misses the `thickness` neighbourhood of the
//! origin, tested in this order:
//!
//! 1. the bounding box on one axis lies beyond `±thickness` (Wang et al.'s test);
//! 2. the bounding box misses the Euclidean ball of radius `thickness` (thickness > 0);
//! 3. all corner values lie beyond the thickness along a direction `n`: the face normals of the
//!    parallelepiped spanned by the box's mean edge vectors in image space (tight for small,
//!    nearly affine boxes: grazing contacts), and for thickness > 0 the closest-point direction
//!    of the primitives at the latest witness time (below) and the direction found by a few
//!    iterations of Gilbert's closest-point algorithm on the 8 corner values (Gilbert, Johnson,
//!    Keerthi 1988), which makes a thin time slab as tight as the exact distance between the
//!    primitives. Directions are only candidates; each exclusion is certified with rigorous
//!    error bounds.
//!
//! The search is best-first: it always refines the open box that starts earliest in time (ties:
//! the deepest box), splitting it in half in time when one time half can be discarded, and
//! otherwise along the parameter whose corner values spread most (time spreads weighted up, most
//! with a thickness: thin time slabs are tight, see test 3). It stops at the first box that is
//! *accepted*: its inclusion is narrower than the tolerance on every axis, or at its start time
//! the primitives are within `thickness (1 + thickness_tolerance) + tolerance * scale` of each
//! other (a *witness*, computed with [`super::distance`]; it decides acceptance, never
//! exclusion). Since every open box
//! starts no earlier than the accepted one, and discarded boxes hold no contact, the start time of
//! the accepted box is never later than the first contact. A box budget and depth limits bound
//! the work; when they are hit, the start time of the earliest open box is returned, which is
//! conservative for the same reason.
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
//! splits from the root, at most 172 here) is within `E_d = (d + 1) u V_k (1 + 10^-6) + d 2^-1075`
//! of the exact value of `F` at that corner, and its magnitude stays below `V_k (1 + 10^-6)`.
//! The code uses `E'_d = (d + 1) c_k` with `c_k = 4 u V_k + 2^-1020`, which exceeds `E_d` with a
//! margin that absorbs the rounding of the few operations that compute the thresholds themselves.
//!
//! - Test 1 discards a box only if on some axis `k` `min corner > thickness (1 + 2^-50) + E'_d`
//!   or `max corner < -(...)`: then `|F_k| > thickness` on the whole box (the exact corner values
//!   are within `E_d` of the computed ones and bound `F_k` on the box), so `|F| > thickness`.
//! - Test 2 (only for `thickness >= 2^-400`, so that squares stay normal) widens the bounding box
//!   by `E'_d`, shrinks the per-axis gaps by `2^-50` and compares squared sums with a relative
//!   margin of `2^-48`, which covers the rounding of the few operations involved.
//! - Test 3 discards only if `min_k fl(n . F~_k) > |n|_2 thickness + sum_i |n_i| (E'_d,i + 3u
//!   max_k |F~_k,i|)`, times `1 + 2^-40`, plus `2^-1020` (the rounding of the dot products, the
//!   corner errors, the rounding of the threshold, subnormal products); then `n . F > |n|
//!   thickness` on the hull, hence `|F| > thickness` on the box. Any `n` is valid, so `n` itself
//!   need not be computed exactly.
//!
//! Hence a discarded box never contains a contact, and the argument above shows the returned time
//! is never later than the first contact and a contact anywhere in `[0, 1]` always yields `Some`.
//! Time boxes are dyadic intervals of width at least `2^-52`, so their start times are exact.
//! Non-finite input, coordinates beyond `10^300` (where sums could overflow) and a non-finite
//! thickness return `Some(0.0)`, the always-conservative answer. The tests check all this against
//! the exact ground truth of the benchmark, exactly constructed contacts and sampled distances.
//!
//! # Accuracy of the answer (false positives)
//!
//! When a box is accepted by the tolerance test, its inclusion meets the thickness neighbourhood
//! and is at most `tol = tolerance * max_k V_k` wide on every axis; when accepted by a witness,
//! the primitives are within `thickness (1 + thickness_tolerance) + tol` at the returned time. In
//! both cases the primitives are within `sqrt(3) (thickness (1 + thickness_tolerance) + tol)` (up
//! to rounding) of each other at the returned time, so a false positive is a near miss at least
//! that close. With a thickness, a tangential approach may therefore be reported a little before
//! the distance reaches the thickness exactly (by design of `thickness_tolerance`, default
//! `1e-3`: cloth resting at the thickness is settled quickly); set it to 0 for an answer resolved
//! to `tolerance` only. [`Impact::resolved`] is false when the answer came from the box budget or a depth
//! limit instead (still conservative, possibly early).

use super::{Real, Vec3};
use std::cell::RefCell;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Options of the inclusion-based CCD search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdOptions {
    /// Distance tolerance relative to the size of the query (`scale`, the largest magnitude of
    /// the relative corner positions `p - a`, `ea_i - eb_j`, ...): the search stops at the
    /// earliest open box once the primitives are within `thickness + tolerance * scale` at its
    /// start time, or once its inclusion is narrower than `tolerance * scale` on every axis.
    /// Smaller values mean fewer false positives and more work.
    pub tolerance: Real,
    /// Maximum number of boxes refined before the search stops and conservatively reports the
    /// start time of the earliest box still open.
    pub max_boxes: u32,
    /// Extra tolerance relative to the thickness: a point closer than
    /// `thickness (1 + thickness_tolerance) + tolerance * scale` is a near contact (witness).
    /// Grazing approaches at the thickness (cloth sliding over cloth at rest distance) are then
    /// decided quickly instead of being resolved to `tolerance`; the answer stays conservative.
    pub thickness_tolerance: Real,
}

impl CcdOptions {
    /// The defaults, usable in `const` items: `CcdOptions { max_boxes: 2000, ..CcdOptions::DEFAULT }`.
    pub const DEFAULT: CcdOptions = CcdOptions {
        tolerance: 1e-6,
        max_boxes: 100_000,
        thickness_tolerance: 1e-3,
    };
}

impl Default for CcdOptions {
    fn default() -> Self {
        CcdOptions::DEFAULT
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
    /// True when the answer was accepted by the tolerance or witness test (the primitives are
    /// then within `sqrt(3) (thickness (1 + thickness_tolerance) + tolerance * scale)` of each
    /// other at `toi`, see the module docs); false when it came from the box budget, a depth
    /// limit or invalid input (conservative but possibly early).
    pub resolved: bool,
    /// Number of boxes the search refined (a machine-independent work measure).
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
    let closest = |x: &[Vec3; 4]| {
        let (_, w) = super::distance::point_triangle(&x[0], &x[1], &x[2], &x[3]);
        x[0] - (x[1] * w[0] + x[2] * w[1] + x[3] * w[2])
    };
    solve(x0, x1, thickness, options, corner, closest)
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
    let closest = |x: &[Vec3; 4]| {
        let (_, s, t) = super::distance::segment_segment(&x[0], &x[1], &x[2], &x[3]);
        (x[0] + (x[1] - x[0]) * s) - (x[2] + (x[3] - x[2]) * t)
    };
    solve(x0, x1, thickness, options, corner, closest)
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
    closest: fn(&[Vec3; 4]) -> Vec3,
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
    let inv_scale = if scale >= 1e-300 { 1.0 / scale } else { 1.0 };
    let search = Search {
        err: v.map(|vk| 4.0 * UNIT_ROUNDOFF * vk + f64::powi(2.0, -1020)),
        delta_up: delta * (1.0 + f64::powi(2.0, -50)),
        ball: delta >= f64::powi(2.0, -400),
        delta2_up: delta * delta * (1.0 + f64::powi(2.0, -48)),
        tol: options.tolerance.max(0.0) * scale,
        inv_scale,
        witness: delta * (1.0 + options.thickness_tolerance.max(0.0))
            + options.tolerance.max(0.0) * scale,
        x0: *x0,
        dx: [0, 1, 2, 3].map(|i| x1[i] - x0[i]),
        closest,
        // With a thickness the first contact lies on a curved boundary, where splitting the
        // barycentric parameters multiplies boxes while thin time slabs are already tight
        // (see `separated`); with zero thickness contacts are isolated points to localise.
        t_weight: if delta > 0.0 { 64.0 } else { 4.0 },
        max_boxes: options.max_boxes.max(1),
    };
    // Most queries are decided at the root (the swept boxes are apart): no queue needed.
    search.include(&c, 1.0, &[0.0; 3])?;
    SCRATCH.with(|s| {
        let mut s = s.borrow_mut();
        let answer = search.run(&c, &mut s);
        if s.cells.capacity() > SCRATCH_KEEP {
            // A rare huge search: do not keep its memory for the life of the thread.
            *s = Scratch::default();
        }
        answer
    })
}

/// Queue capacity (in boxes) kept between queries.
const SCRATCH_KEEP: usize = 4096;

/// One box of the search: corner values, time interval and split depth per parameter.
#[derive(Clone, Copy)]
struct Cell {
    c: Corners,
    t_lo: f64,
    t_w: f64,
    depth: [u8; 3],
}

/// Reusable per-thread storage of the search queue (no allocation per query).
#[derive(Default)]
struct Scratch {
    cells: Vec<Cell>,
    free: Vec<u32>,
    queue: BinaryHeap<Reverse<u128>>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// Parameters of one best-first inclusion search.
struct Search {
    /// Per-axis error growth per level of depth (`c_k` of the module docs).
    err: [f64; 3],
    delta_up: f64,
    ball: bool,
    delta2_up: f64,
    tol: f64,
    /// `1 / scale` (keeps the products of the direction tests finite).
    inv_scale: f64,
    /// `thickness (1 + thickness_tolerance) + tol`: primitives this close are a near contact.
    witness: f64,
    /// Positions at `t = 0` and their displacements to `t = 1` (for the witness distance).
    x0: [Vec3; 4],
    dx: [Vec3; 4],
    /// Vector between the closest points of the primitives at given positions (the value of
    /// `F` at the closest parameters).
    closest: fn(&[Vec3; 4]) -> Vec3,
    /// Weight of the time spread against the parameter spreads when choosing a split.
    t_weight: f64,
    max_boxes: u32,
}

impl Search {
    /// True when the primitives are within the witness distance of each other at time `t`
    /// (computed in floating point: this decides acceptance, never exclusion).
    /// Also returns the closest-point direction (scaled by `1 / scale`), a good candidate
    /// separating direction for boxes near time `t`.
    fn witness(&self, t: f64) -> (bool, [f64; 3]) {
        let x = [0, 1, 2, 3].map(|i| self.x0[i] + self.dx[i] * t);
        let f = (self.closest)(&x);
        let n = f * self.inv_scale;
        (f.norm() <= self.witness, [n.x, n.y, n.z])
    }

    /// Best-first search: always refines the open box with the earliest start time (ties: the
    /// deepest), so the first box accepted starts no later than any contact.
    fn run(&self, root: &Corners, s: &mut Scratch) -> Option<Impact> {
        s.cells.clear();
        s.free.clear();
        s.queue.clear();
        let push = |s: &mut Scratch, cell: Cell| {
            let depth = cell.depth[0] as u128 + cell.depth[1] as u128 + cell.depth[2] as u128;
            let idx = match s.free.pop() {
                Some(i) => {
                    s.cells[i as usize] = cell;
                    i
                }
                None => {
                    s.cells.push(cell);
                    (s.cells.len() - 1) as u32
                }
            };
            // t_lo >= 0, so its bit pattern orders like its value.
            let key =
                ((cell.t_lo.to_bits() as u128) << 64) | ((0xffff - depth) << 32) | idx as u128;
            s.queue.push(Reverse(key));
        };
        push(
            s,
            Cell {
                c: *root,
                t_lo: 0.0,
                t_w: 1.0,
                depth: [0; 3],
            },
        );
        let mut boxes = 0u32;
        let mut witnessed = -1.0;
        let mut hint = [0.0; 3];
        while let Some(Reverse(key)) = s.queue.pop() {
            let idx = (key & 0xffff_ffff) as u32;
            let cell = s.cells[idx as usize];
            s.free.push(idx);
            boxes += 1;
            let impact = |resolved| {
                Some(Impact {
                    toi: cell.t_lo,
                    toi_upper: cell.t_lo + cell.t_w,
                    resolved,
                    boxes,
                })
            };
            let c = &cell.c;
            let mut lo = c[0];
            let mut hi = c[0];
            for k in &c[1..] {
                for i in 0..3 {
                    lo[i] = lo[i].min(k[i]);
                    hi[i] = hi[i].max(k[i]);
                }
            }
            let width = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(hi[2] - lo[2]);
            if width <= self.tol {
                return impact(true);
            }
            if cell.t_lo != witnessed {
                witnessed = cell.t_lo;
                let (near, dir) = self.witness(cell.t_lo);
                if near {
                    return impact(true);
                }
                hint = dir;
            }
            if boxes >= self.max_boxes {
                return impact(false);
            }
            let levels = (cell.depth[0] + cell.depth[1] + cell.depth[2]) as f64 + 2.0;
            // Time split first when one half is provably empty: progress in time for free. This
            // keeps degenerate contacts (parallel edges meeting all along their overlap at one
            // instant) from being covered box by box at full resolution.
            let mut tsplit = None;
            if cell.depth[0] < MAX_DEPTH_T {
                let (lower, upper) = split(c, 4);
                let lower_in = self.include(&lower, levels, &hint).is_some();
                let upper_in = self.include(&upper, levels, &hint).is_some();
                if !(lower_in && upper_in) {
                    let mut d = cell.depth;
                    d[0] += 1;
                    let h = cell.t_w * 0.5;
                    if lower_in {
                        push(
                            s,
                            Cell {
                                c: lower,
                                t_lo: cell.t_lo,
                                t_w: h,
                                depth: d,
                            },
                        );
                    }
                    if upper_in {
                        push(
                            s,
                            Cell {
                                c: upper,
                                t_lo: cell.t_lo + h,
                                t_w: h,
                                depth: d,
                            },
                        );
                    }
                    continue;
                }
                tsplit = Some((lower, upper));
            }
            // Otherwise split along the parameter whose corner values spread most.
            let mut best_dim = usize::MAX;
            let mut best_spread = -1.0;
            for (dim, mask) in [(0usize, 4usize), (1, 2), (2, 1)] {
                let cap = if dim == 0 { MAX_DEPTH_T } else { MAX_DEPTH_UV };
                if cell.depth[dim] >= cap {
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
                let spread = if dim == 0 {
                    spread * self.t_weight
                } else {
                    spread
                };
                if spread > best_spread {
                    best_spread = spread;
                    best_dim = dim;
                }
            }
            if best_dim == usize::MAX {
                return impact(false);
            }
            let mut d = cell.depth;
            d[best_dim] += 1;
            if best_dim == 0 {
                let (lower, upper) = tsplit.expect("time split computed above");
                let h = cell.t_w * 0.5;
                push(
                    s,
                    Cell {
                        c: lower,
                        t_lo: cell.t_lo,
                        t_w: h,
                        depth: d,
                    },
                );
                push(
                    s,
                    Cell {
                        c: upper,
                        t_lo: cell.t_lo + h,
                        t_w: h,
                        depth: d,
                    },
                );
            } else {
                let (lower, upper) = split(c, [4usize, 2, 1][best_dim]);
                for child in [lower, upper] {
                    if self.include(&child, levels, &hint).is_some() {
                        push(
                            s,
                            Cell {
                                c: child,
                                t_lo: cell.t_lo,
                                t_w: cell.t_w,
                                depth: d,
                            },
                        );
                    }
                }
            }
        }
        None
    }

    /// Inclusion bounds `(lo, hi)` of a box at total split depth `levels - 1`, or `None` when the
    /// box provably holds no contact (see the module docs for the error bound).
    #[inline]
    fn include(&self, c: &Corners, levels: f64, hint: &[f64; 3]) -> Option<([f64; 3], [f64; 3])> {
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
        if self.ball {
            // A corner within the thickness: the box cannot be excluded, skip the tests below.
            let d2 = self.delta_up * self.delta_up;
            if c.iter()
                .any(|k| k[0] * k[0] + k[1] * k[1] + k[2] * k[2] <= d2)
            {
                return Some((lo, hi));
            }
        }
        let fmax = [0, 1, 2].map(|i| lo[i].abs().max(hi[i].abs()));
        if self.separated(c, &fmax, &e, hint) {
            return None;
        }
        Some((lo, hi))
    }

    /// Separating-direction test beyond the coordinate axes. The image of the box lies in the
    /// convex hull of its 8 corner values (`F` is a convex combination of them with the
    /// multilinear weights), so the box holds no contact when that hull stays farther than the
    /// thickness from the origin. A direction is searched with a few iterations of Gilbert's
    /// closest-point algorithm on the 8 points (Gilbert, Johnson, Keerthi 1988); it is only a
    /// candidate: the exclusion is then certified by [`Search::beyond`] with rigorous bounds. For
    /// thin time slabs the hull is tight, so grazing approaches at the thickness are settled by
    /// splitting time alone instead of covering the nearly touching region box by box.
    fn separated(&self, c: &Corners, fmax: &[f64; 3], e: &[f64; 3], hint: &[f64; 3]) -> bool {
        let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        // Cheap candidates first: the face normals of the parallelepiped spanned by the mean
        // edge vectors of the image (tight for small, nearly affine boxes). Edge vectors are
        // scaled by 1 / scale so that the cross products stay finite.
        let f = self.inv_scale;
        let mut j = [[0.0f64; 3]; 3];
        for (dim, mask) in [(0usize, 4usize), (1, 2), (2, 1)] {
            for k in 0..8 {
                if k & mask == 0 {
                    for i in 0..3 {
                        j[dim][i] += (c[k | mask][i] - c[k][i]) * f;
                    }
                }
            }
        }
        let cross = |a: &[f64; 3], b: &[f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        for n in [
            cross(&j[1], &j[2]),
            cross(&j[0], &j[1]),
            cross(&j[0], &j[2]),
        ] {
            if self.beyond(c, &n, fmax, e, true) {
                return true;
            }
        }
        // With zero thickness, boxes that survive the normals nearly always contain the origin
        // in their hull, where the iteration below would only spend time.
        if self.delta_up == 0.0 {
            return false;
        }
        // The closest-point direction at the latest witness time is often right for nearby
        // boxes; otherwise search one.
        if self.beyond(c, hint, fmax, e, false) {
            return true;
        }
        let mut v = c[0];
        let mut vv = dot(&v, &v);
        for k in &c[1..] {
            let d = dot(k, k);
            if d < vv {
                vv = d;
                v = *k;
            }
        }
        let d2 = self.delta_up * self.delta_up;
        for _ in 0..6 {
            if vv <= d2 {
                return false; // a point of the hull is within the thickness
            }
            // Support point of the hull in direction -v.
            let mut w = c[0];
            let mut vw = dot(&v, &w);
            for k in &c[1..] {
                let d = dot(&v, k);
                if d < vw {
                    vw = d;
                    w = *k;
                }
            }
            if vw > 0.0 && vw * vw > vv * d2 {
                // The plane through the origin side of the hull at distance vw/|v| > thickness.
                let n = [
                    v[0] * self.inv_scale,
                    v[1] * self.inv_scale,
                    v[2] * self.inv_scale,
                ];
                return self.beyond(c, &n, fmax, e, false);
            }
            // Not yet separated: v <- closest point to the origin on the segment [v, w].
            let dvw = [w[0] - v[0], w[1] - v[1], w[2] - v[2]];
            let den = dot(&dvw, &dvw);
            let num = vv - vw;
            if den <= 0.0 || num <= 1e-12 * vv {
                return false; // converged without separation
            }
            let lambda = (num / den).min(1.0);
            v = [
                v[0] + lambda * dvw[0],
                v[1] + lambda * dvw[1],
                v[2] + lambda * dvw[2],
            ];
            vv = dot(&v, &v);
        }
        false
    }

    /// Rigorous check that every corner value `F_k` satisfies `n . F_k > |n| thickness` after
    /// accounting for all errors, so that `|F| > thickness` on the whole box. With `E_i` the
    /// corner error bound, `|n . (F_k - F~_k)| <= sum |n_i| E_i`, and the rounded dot product is
    /// off by at most `3u sum |n_i| |F~_k,i|`; the threshold adds both, bounds `|n|_2` from
    /// above, and adds a relative margin of `2^-40` for its own rounding and `2^-1020` for
    /// products in the subnormal range. Any `n` is valid, so `n` itself need not be exact. With
    /// `both`, the opposite direction `-n` is tried as well.
    fn beyond(&self, c: &Corners, n: &[f64; 3], fmax: &[f64; 3], e: &[f64; 3], both: bool) -> bool {
        // Products must stay finite: |n_i| <= 2^64 and coordinates below 1e300 guarantee it.
        let m = n[0].abs().max(n[1].abs()).max(n[2].abs());
        if !(m > 0.0 && m <= f64::powi(2.0, 64)) {
            return false;
        }
        let mut mn = f64::INFINITY;
        let mut mx = f64::NEG_INFINITY;
        for k in c {
            let d = n[0] * k[0] + n[1] * k[1] + n[2] * k[2];
            mn = mn.min(d);
            mx = mx.max(d);
        }
        let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let mut thr = norm * self.delta_up;
        for i in 0..3 {
            thr += n[i].abs() * (e[i] + 3.0 * UNIT_ROUNDOFF * fmax[i]);
        }
        let thr = thr * (1.0 + f64::powi(2.0, -40)) + f64::powi(2.0, -1020);
        mn > thr || (both && mx < -thr)
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
#[path = "ccd_tests.rs"]
mod tests;
