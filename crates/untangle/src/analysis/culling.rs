//! Node-level self-collision culling: a certificate that a patch of triangles cannot intersect
//! itself (after Wang et al. 2017, "unprojected normal cones", which Cha & Ko cite for their
//! simulator's CCD culling), in a form that is exact about what it certifies.
//!
//! For a set `S` of triangles, take `d` = the normalised sum of their normals and require
//! 1. every triangle of `S` projects along `d` with positive orientation (with a margin), and
//!    every edge shared by two triangles of `S` is traversed in opposite directions by them;
//! 2. the boundary of `S` (its half-edges whose other side is not in `S`) is a single cycle whose
//!    projection is a simple polygon (non-adjacent segments certainly apart).
//!
//! Then, for every point `x` of the plane, the number of triangles of `S` whose projection
//! contains `x` equals the winding number of the projected boundary around `x` (the interior
//! edges cancel), which is 0 or 1 for a simple polygon. So the projection is injective on `S`:
//! no two triangles of `S` meet except along shared edges or vertices, also under the symbolic
//! perturbation (the margins keep everything else apart). Pairs between `S` and other triangles
//! are not affected.

use crate::geom::tri_tri::CertifiedPlane;
use crate::geom::Vec3;
use crate::mesh::topology::{Topology, NONE};

/// Per BVH node: sum of unit normals and the box of unit normals, for an O(1) orientation bound.
#[derive(Clone, Copy)]
struct NormalSummary {
    sum: Vec3,
    lo: Vec3,
    hi: Vec3,
}

/// Checks patches given as BVH nodes (ranges of slots).
pub struct PatchCertifier<'a> {
    tris: &'a [[u32; 3]],
    topo: &'a Topology,
    pos: &'a [Vec3],
    order: &'a [u32],
    slot_of: Vec<u32>,
    summaries: Vec<NormalSummary>,
}

impl<'a> PatchCertifier<'a> {
    /// For triangles `tris` with `planes`, in the hierarchy `bvh`.
    pub fn new(
        tris: &'a [[u32; 3]],
        topo: &'a Topology,
        pos: &'a [Vec3],
        planes: &'a [CertifiedPlane],
        bvh: &'a crate::broad::Bvh,
    ) -> Self {
        let order = bvh.order();
        let mut slot_of = vec![0u32; tris.len()];
        for (s, &t) in order.iter().enumerate() {
            slot_of[t as usize] = s as u32;
        }
        let summaries = bvh.fold_up(
            |slots| {
                let mut m = NormalSummary {
                    sum: Vec3::zeros(),
                    lo: Vec3::repeat(f64::INFINITY),
                    hi: Vec3::repeat(f64::NEG_INFINITY),
                };
                for s in slots {
                    let n = planes[order[s as usize] as usize].normal();
                    let l = n.norm();
                    let u = if l > 0.0 {
                        n / l
                    } else {
                        Vec3::repeat(f64::NAN)
                    };
                    m.sum += u;
                    m.lo = m.lo.inf(&u);
                    m.hi = m.hi.sup(&u);
                }
                m
            },
            |a, b| NormalSummary {
                sum: a.sum + b.sum,
                lo: a.lo.inf(&b.lo),
                hi: a.hi.sup(&b.hi),
            },
        );
        PatchCertifier {
            tris,
            topo,
            pos,
            order,
            slot_of,
            summaries,
        }
    }

    /// Whether the triangles of BVH node `node` (slots `first..first + len`) certainly do not
    /// intersect each other. `false` means "not certified".
    pub fn embedded(&self, node: usize, first: u32, len: u32) -> bool {
        let range = first..first + len;
        let slots = &self.order[first as usize..(first + len) as usize];
        // 1. Orientation along the mean normal d: every unit normal lies in the node's box of
        //    unit normals, so the minimum of n . d over that box bounds every triangle's n . d
        //    from below (a NaN from a degenerate triangle makes the bound fail).
        let m = &self.summaries[node];
        let dl = m.sum.norm();
        if dl.is_nan() || dl <= 1e-9 * len as f64 {
            return false;
        }
        let d = m.sum / dl;
        let bound: f64 = (0..3).map(|k| (d[k] * m.lo[k]).min(d[k] * m.hi[k])).sum();
        if bound.is_nan() || bound <= 0.2 {
            return false;
        }
        // Boundary half-edges; interior edges must be traversed in opposite directions.
        let mut half: Vec<(u32, u32)> = Vec::new();
        for &t in slots {
            let tri = self.tris[t as usize];
            for k in 0..3 {
                let e = self.topo.triangle_edges[t as usize][k];
                let other = self.topo.other_triangle(e, t);
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if other == NONE || !range.contains(&self.slot_of[other as usize]) {
                    half.push((a, b));
                } else {
                    let o = self.tris[other as usize];
                    let j = o.iter().position(|&v| v == b).unwrap_or(0);
                    if o[(j + 1) % 3] != a {
                        return false; // inconsistent orientation across an interior edge
                    }
                }
            }
        }
        if half.len() < 3 {
            return false;
        }
        // 2. A single cycle: every boundary vertex starts exactly one half-edge, and walking
        //    from one returns after visiting all.
        half.sort_unstable();
        if half.windows(2).any(|w| w[0].0 == w[1].0) {
            return false;
        }
        let next = |v: u32| -> Option<u32> {
            half.binary_search_by_key(&v, |h| h.0)
                .ok()
                .map(|i| half[i].1)
        };
        let mut cycle = Vec::with_capacity(half.len());
        let start = half[0].0;
        let mut v = start;
        for _ in 0..half.len() {
            cycle.push(v);
            match next(v) {
                Some(w) => v = w,
                None => return false,
            }
        }
        if v != start {
            return false;
        }
        // Projected polygon must be simple.
        let e1 = if d.x.abs() < 0.9 {
            Vec3::x()
        } else {
            Vec3::y()
        };
        let e1 = (e1 - d * e1.dot(&d)).normalize();
        let e2 = d.cross(&e1);
        let pts: Vec<(f64, f64)> = cycle
            .iter()
            .map(|&v| {
                let p = self.pos[v as usize];
                (p.dot(&e1), p.dot(&e2))
            })
            .collect();
        simple_polygon(&pts)
    }
}

/// Whether the closed polygon `pts` is certainly simple: every two non-adjacent edges are
/// certainly disjoint (with a conservative floating-point margin). Sweep over x.
fn simple_polygon(pts: &[(f64, f64)]) -> bool {
    let n = pts.len();
    let mut scale = 0.0f64;
    for p in pts {
        scale = scale.max(p.0.abs()).max(p.1.abs());
    }
    let tol = 1e-12 * scale * scale;
    let seg = |i: usize| (pts[i], pts[(i + 1) % n]);
    let mut by_x: Vec<(f64, f64, usize)> = (0..n)
        .map(|i| {
            let (a, b) = seg(i);
            (a.0.min(b.0), a.0.max(b.0), i)
        })
        .collect();
    by_x.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
    let orient = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let apart = |i: usize, j: usize| {
        let ((p1, p2), (q1, q2)) = (seg(i), seg(j));
        if p1.1.max(p2.1) < q1.1.min(q2.1) - 1e-12 * scale
            || q1.1.max(q2.1) < p1.1.min(p2.1) - 1e-12 * scale
        {
            return true;
        }
        let (o1, o2) = (orient(p1, p2, q1), orient(p1, p2, q2));
        if (o1 > tol && o2 > tol) || (o1 < -tol && o2 < -tol) {
            return true;
        }
        let (o3, o4) = (orient(q1, q2, p1), orient(q1, q2, p2));
        (o3 > tol && o4 > tol) || (o3 < -tol && o4 < -tol)
    };
    let mut active: Vec<(f64, usize)> = Vec::new(); // (max x, segment)
    for &(lo, hi, i) in &by_x {
        active.retain(|&(mx, _)| mx >= lo - 1e-12 * scale);
        for &(_, j) in &active {
            let adjacent = (i + 1) % n == j || (j + 1) % n == i;
            if !adjacent && !apart(i, j) {
                return false;
            }
        }
        active.push((hi, i));
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simple_and_self_crossing_polygons() {
        let square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
        assert!(simple_polygon(&square));
        let bow_tie = [(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)];
        assert!(!simple_polygon(&bow_tie));
        // A polygon touching itself at a point is not certified.
        let touching = [
            (0.0, 0.0),
            (2.0, 0.0),
            (1.0, 1.0),
            (2.0, 2.0),
            (0.0, 2.0),
            (1.0, 1.0),
        ];
        assert!(!simple_polygon(&touching));
        let star: Vec<(f64, f64)> = (0..10)
            .map(|k| {
                let a = k as f64 * std::f64::consts::PI / 5.0;
                let r = if k % 2 == 0 { 1.0 } else { 0.4 };
                (r * a.cos(), r * a.sin())
            })
            .collect();
        assert!(simple_polygon(&star));
    }
}
