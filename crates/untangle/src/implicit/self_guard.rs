//! Guard against self-intersections created while a garment moves (an addition to Buffet et
//! al. 2019, whose Sec. 7 / Fig. 12 leaves self-intersection out of scope).
//!
//! The projection and the repair move vertices in passes. [`SelfGuard`] remembers the pairs of
//! triangles of one mesh that intersect at the start (they are not the untangler's to fix) and,
//! after every pass, undoes the pass's moves of the vertices of every triangle pair that
//! intersects *and did not at the start*, by the exact crossing test of the intersection
//! analysis ([`triangles_intersect`], same symbolic perturbation, so "clean here" is "clean for
//! the analysis"). Undoing repeats until no such pair is left. If the positions at the start of
//! the pass had no new pair, neither have the positions after it: the output is never more
//! self-tangled than the input.

use crate::broad::Bvh;
use crate::geom::tri_tri::{triangles_intersect, triangles_may_intersect};
use crate::geom::{Aabb, Vec3};
use crate::mesh::Topology;
use rayon::prelude::*;

/// Sign of `orient3d(a, b, c, d)` when the floating-point value is certain (Shewchuk's
/// static error bound on the permanent), else 0.
fn certain_orient(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> i32 {
    let (u, v, w) = (a - d, b - d, c - d);
    let det = u.x * (v.y * w.z - v.z * w.y) - u.y * (v.x * w.z - v.z * w.x)
        + u.z * (v.x * w.y - v.y * w.x);
    let perm = u.x.abs() * ((v.y * w.z).abs() + (v.z * w.y).abs())
        + u.y.abs() * ((v.x * w.z).abs() + (v.z * w.x).abs())
        + u.z.abs() * ((v.x * w.y).abs() + (v.z * w.x).abs());
    // o3derrboundA = (7 + 56ε)ε ≈ 7.8e-16; doubled for safety.
    if det.abs() > 1.6e-15 * perm {
        if det > 0.0 {
            1
        } else {
            -1
        }
    } else {
        0
    }
}

/// Whether two triangles can intersect (conservative; exact test afterwards). Triangles
/// sharing an edge never do (crossing rule); for one shared vertex, only the edge opposite it
/// in either triangle can cross the other, which it cannot when both its ends are certainly
/// on the same side of the other's plane.
pub(crate) fn may_intersect(ta: [u32; 3], tb: [u32; 3], pos: &[Vec3]) -> bool {
    let shared = ta.iter().filter(|v| tb.contains(v)).count();
    if shared >= 2 {
        return false;
    }
    let (pa, pb) = (ta.map(|v| pos[v as usize]), tb.map(|v| pos[v as usize]));
    if shared == 0 {
        return triangles_may_intersect(&pa, &pb);
    }
    let opposite_may_cross = |t: [u32; 3], p: [Vec3; 3], q: [Vec3; 3], other: [u32; 3]| {
        // The two vertices of `t` not shared with `other` (one vertex is shared).
        let mut e = [0usize; 2];
        let mut m = 0;
        for k in 0..3 {
            if !other.contains(&t[k]) {
                e[m] = k;
                m += 1;
            }
        }
        let s0 = certain_orient(&q[0], &q[1], &q[2], &p[e[0]]);
        let s1 = certain_orient(&q[0], &q[1], &q[2], &p[e[1]]);
        !(s0 != 0 && s0 == s1)
    };
    opposite_may_cross(ta, pa, pb, tb) || opposite_may_cross(tb, pb, pa, ta)
}

/// Self-intersection guard of one mesh (see the module docs).
pub struct SelfGuard<'a> {
    triangles: &'a [[u32; 3]],
    topo: &'a Topology,
    /// Pairs `(a, b)`, `a < b`, intersecting at the start (sorted).
    initial: Vec<(u32, u32)>,
    bvh: Bvh,
    boxes: Vec<Aabb>,
}

fn boxes_of(triangles: &[[u32; 3]], pos: &[Vec3]) -> Vec<Aabb> {
    triangles
        .par_iter()
        .map(|t| Aabb::from_points(t.iter().map(|&v| &pos[v as usize])))
        .collect()
}

/// Every intersecting pair `(a, b)`, `a < b`, of triangles of one mesh (sorted).
pub fn self_pairs(triangles: &[[u32; 3]], pos: &[Vec3]) -> Vec<(u32, u32)> {
    let bvh = Bvh::build(&boxes_of(triangles, pos));
    let mut p = bvh.self_pairs(|a, b, out| {
        let (ta, tb) = (triangles[a as usize], triangles[b as usize]);
        if may_intersect(ta, tb, pos) && triangles_intersect(ta, tb, pos) {
            out.push((a.min(b), a.max(b)));
        }
    });
    p.sort_unstable();
    p.dedup();
    p
}

impl<'a> SelfGuard<'a> {
    /// Records the pairs intersecting at `start`.
    pub fn new(triangles: &'a [[u32; 3]], topo: &'a Topology, start: &[Vec3]) -> Self {
        let boxes = boxes_of(triangles, start);
        let bvh = Bvh::build(&boxes);
        SelfGuard {
            triangles,
            topo,
            initial: self_pairs(triangles, start),
            bvh,
            boxes,
        }
    }

    /// Pairs intersecting at the start.
    pub fn initial(&self) -> &[(u32, u32)] {
        &self.initial
    }

    /// Intersecting pairs not present at the start with a triangle of a vertex in `changed`.
    fn new_pairs(&mut self, pos: &[Vec3], changed: &[usize]) -> Vec<(u32, u32)> {
        let mut cand: Vec<u32> = changed
            .iter()
            .flat_map(|&v| self.topo.vertex_triangles.row(v).iter().copied())
            .collect();
        cand.sort_unstable();
        cand.dedup();
        if cand.is_empty() {
            return Vec::new();
        }
        for &t in &cand {
            let tri = self.triangles[t as usize];
            self.boxes[t as usize] = Aabb::from_points(tri.iter().map(|&v| &pos[v as usize]));
        }
        self.bvh.refit(&self.boxes);
        let (tris, bvh, boxes, initial) = (self.triangles, &self.bvh, &self.boxes, &self.initial);
        let mut pairs: Vec<(u32, u32)> = cand
            .par_iter()
            .flat_map_iter(|&a| {
                let mut out = Vec::new();
                let ta = tris[a as usize];
                bvh.query(&boxes[a as usize], |b| {
                    if b == a {
                        return;
                    }
                    let tb = tris[b as usize];
                    let key = (a.min(b), a.max(b));
                    if may_intersect(ta, tb, pos)
                        && triangles_intersect(ta, tb, pos)
                        && initial.binary_search(&key).is_err()
                    {
                        out.push(key);
                    }
                });
                out
            })
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        pairs
    }

    /// Undoes the moves (from `before` to `pos`) of the vertices of every new intersecting
    /// pair, until none is left; `changed` lists the vertices that may differ. Returns the
    /// vertices put back.
    pub fn revert_new(
        &mut self,
        before: &[Vec3],
        pos: &mut [Vec3],
        changed: &[usize],
    ) -> Vec<usize> {
        let mut changed: Vec<usize> = changed
            .iter()
            .copied()
            .filter(|&v| pos[v] != before[v])
            .collect();
        let mut reverted = Vec::new();
        let mut touched = changed.clone();
        loop {
            let pairs = self.new_pairs(pos, &changed);
            if pairs.is_empty() {
                break;
            }
            let mut back = Vec::new();
            for (a, b) in pairs {
                for t in [a, b] {
                    for &v in &self.triangles[t as usize] {
                        let v = v as usize;
                        if pos[v] != before[v] {
                            pos[v] = before[v];
                            back.push(v);
                        }
                    }
                }
            }
            if back.is_empty() {
                // Only triangles that did not move: cannot happen when the positions at
                // `before` had no new pair; stop rather than loop.
                break;
            }
            back.sort_unstable();
            back.dedup();
            reverted.extend_from_slice(&back);
            changed.retain(|&v| pos[v] != before[v]);
            // The reverted vertices' triangles must be tested again (against moved ones).
            changed.extend_from_slice(&back);
            changed.sort_unstable();
            changed.dedup();
            touched.extend_from_slice(&back);
        }
        // Keep the cached boxes of every touched triangle current.
        if !reverted.is_empty() {
            for &v in &touched {
                for &t in self.topo.vertex_triangles.row(v) {
                    let tri = self.triangles[t as usize];
                    self.boxes[t as usize] =
                        Aabb::from_points(tri.iter().map(|&u| &pos[u as usize]));
                }
            }
            self.bvh.refit(&self.boxes);
        }
        reverted.sort_unstable();
        reverted.dedup();
        reverted
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::handkerchief;
    use proptest::prelude::*;

    /// Brute force: every pair of triangles, exact test.
    fn brute(tris: &[[u32; 3]], pos: &[Vec3]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for a in 0..tris.len() {
            for b in a + 1..tris.len() {
                if triangles_intersect(tris[a], tris[b], pos) {
                    out.push((a as u32, b as u32));
                }
            }
        }
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]
        /// A flat sheet whose vertices take random moves: after the guard, no pair intersects
        /// that did not before (brute-force oracle), and vertices not put back moved as asked.
        #[test]
        fn random_moves_never_create_self_intersections(
            seed in 0u64..1000, amp in 0.05f64..0.6,
        ) {
            use rand::{Rng, SeedableRng};
            let m = handkerchief("h", 8, 8, 1.0, 1.0, |uv| Vec3::new(uv.x, uv.y, 0.0));
            let topo = Topology::new(&m).unwrap();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            // A crumpled start (may self-intersect), then a random pass.
            let start: Vec<Vec3> = m.positions.iter().map(|p| p + Vec3::new(0.0, 0.0,
                rng.random_range(-0.05..0.05))).collect();
            let mut guard = SelfGuard::new(&m.triangles, &topo, &start);
            prop_assert_eq!(guard.initial().to_vec(), brute(&m.triangles, &start));
            let mut before = start.clone();
            for _ in 0..3 {
                let target: Vec<Vec3> = before.iter().map(|p| p + Vec3::new(
                    rng.random_range(-amp..amp) * 0.2, rng.random_range(-amp..amp) * 0.2,
                    rng.random_range(-amp..amp))).collect();
                let mut pos = target.clone();
                let changed: Vec<usize> = (0..pos.len()).collect();
                let back = guard.revert_new(&before, &mut pos, &changed);
                let now = brute(&m.triangles, &pos);
                for p in &now {
                    prop_assert!(guard.initial().binary_search(p).is_ok(), "new pair {:?}", p);
                }
                for v in 0..pos.len() {
                    if back.binary_search(&v).is_err() {
                        prop_assert_eq!(pos[v], target[v]);
                    } else {
                        prop_assert_eq!(pos[v], before[v]);
                    }
                }
                before = pos;
            }
        }
    }
}
