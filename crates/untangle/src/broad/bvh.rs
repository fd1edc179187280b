//! Bounding volume hierarchy over axis-aligned boxes.
//!
//! Built top-down by median split on the longest centroid axis, stored in pre-order (children
//! after parents), so a refit is one reverse sweep. Traversals run in parallel with `rayon::join`
//! near the root and return results in a fixed order, so the output is identical for any thread
//! count.

use crate::geom::Aabb;

const LEAF_SIZE: usize = 4;
/// Subtrees with fewer primitives than this are traversed sequentially.
const PAR_CUTOFF: u32 = 2048;

#[derive(Clone, Copy, Debug)]
struct Node {
    aabb: Aabb,
    /// Leaf: first primitive slot; inner: index of the left child (right child = `right`).
    start: u32,
    /// Leaf: number of primitives (> 0); inner: 0.
    count: u32,
    /// Inner: index of the right child.
    right: u32,
    /// Number of primitives below.
    size: u32,
}

impl Node {
    #[inline]
    fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// A bounding volume hierarchy over a fixed set of primitives (indices `0..n`).
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    /// Primitive index of each leaf slot.
    order: Vec<u32>,
    /// Box of each leaf slot (copied for locality; updated by `refit`).
    slot_aabbs: Vec<Aabb>,
}

impl Bvh {
    /// Builds the hierarchy over `aabbs` (primitive `i` has box `aabbs[i]`).
    pub fn build(aabbs: &[Aabb]) -> Bvh {
        let n = aabbs.len();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let centers: Vec<[f64; 3]> = aabbs
            .iter()
            .map(|b| {
                let c = b.center();
                [c.x, c.y, c.z]
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * n / LEAF_SIZE + 2);
        if n > 0 {
            build_rec(&mut nodes, &mut order, 0, &centers, aabbs);
        }
        let slot_aabbs = order.iter().map(|&i| aabbs[i as usize]).collect();
        Bvh {
            nodes,
            order,
            slot_aabbs,
        }
    }

    /// Number of primitives.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether the hierarchy has no primitive.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Box of the whole hierarchy.
    pub fn root_aabb(&self) -> Aabb {
        self.nodes.first().map(|n| n.aabb).unwrap_or(Aabb::EMPTY)
    }

    /// Updates all boxes for moved primitives (same count and indices), keeping the tree shape.
    pub fn refit(&mut self, aabbs: &[Aabb]) {
        assert_eq!(
            aabbs.len(),
            self.order.len(),
            "refit with a different primitive count"
        );
        for (slot, &p) in self.slot_aabbs.iter_mut().zip(&self.order) {
            *slot = aabbs[p as usize];
        }
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            let b = if n.is_leaf() {
                self.slot_aabbs[n.start as usize..(n.start + n.count) as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |a, b| a.union(b))
            } else {
                self.nodes[n.start as usize]
                    .aabb
                    .union(&self.nodes[n.right as usize].aabb)
            };
            self.nodes[i].aabb = b;
        }
    }

    /// Calls `visit(i, j, out)` for every pair `i != j` of primitives whose boxes overlap, each
    /// unordered pair once, and returns everything pushed to `out`, in an order independent of the
    /// number of threads.
    pub fn self_pairs<T, F>(&self, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        if self.nodes.is_empty() {
            return Vec::new();
        }
        let mut out = Vec::new();
        self.self_rec(0, &visit, &mut out);
        out
    }

    fn self_rec<T: Send, F: Fn(u32, u32, &mut Vec<T>) + Sync>(
        &self,
        a: usize,
        visit: &F,
        out: &mut Vec<T>,
    ) {
        let n = self.nodes[a];
        if n.is_leaf() {
            let s = n.start as usize;
            let e = s + n.count as usize;
            for i in s..e {
                for j in i + 1..e {
                    if self.slot_aabbs[i].overlaps(&self.slot_aabbs[j]) {
                        visit(self.order[i], self.order[j], out);
                    }
                }
            }
            return;
        }
        let (l, r) = (n.start as usize, n.right as usize);
        if n.size >= PAR_CUTOFF {
            let ((mut o1, o2), o3) = rayon::join(
                || {
                    rayon::join(
                        || {
                            let mut o = Vec::new();
                            self.self_rec(l, visit, &mut o);
                            o
                        },
                        || {
                            let mut o = Vec::new();
                            self.self_rec(r, visit, &mut o);
                            o
                        },
                    )
                },
                || {
                    let mut o = Vec::new();
                    self.cross_rec(self, l, r, visit, &mut o);
                    o
                },
            );
            o1.extend(o2);
            o1.extend(o3);
            if out.is_empty() {
                *out = o1;
            } else {
                out.extend(o1);
            }
        } else {
            self.self_rec(l, visit, out);
            self.self_rec(r, visit, out);
            self.cross_rec(self, l, r, visit, out);
        }
    }

    /// Calls `visit(i, j, out)` for every primitive `i` of `self` and `j` of `other` whose boxes
    /// overlap; deterministic order as in [`Bvh::self_pairs`].
    pub fn cross_pairs<T, F>(&self, other: &Bvh, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        if self.nodes.is_empty() || other.nodes.is_empty() {
            return Vec::new();
        }
        let mut out = Vec::new();
        self.cross_rec(other, 0, 0, &visit, &mut out);
        out
    }

    fn cross_rec<T: Send, F: Fn(u32, u32, &mut Vec<T>) + Sync>(
        &self,
        other: &Bvh,
        a: usize,
        b: usize,
        visit: &F,
        out: &mut Vec<T>,
    ) {
        let (na, nb) = (self.nodes[a], other.nodes[b]);
        if !na.aabb.overlaps(&nb.aabb) {
            return;
        }
        if na.is_leaf() && nb.is_leaf() {
            for i in na.start..na.start + na.count {
                let bi = &self.slot_aabbs[i as usize];
                for j in nb.start..nb.start + nb.count {
                    if bi.overlaps(&other.slot_aabbs[j as usize]) {
                        visit(self.order[i as usize], other.order[j as usize], out);
                    }
                }
            }
            return;
        }
        // Descend the larger (or the only inner) node.
        let split_a = !na.is_leaf() && (nb.is_leaf() || na.aabb.half_area() >= nb.aabb.half_area());
        let parallel = na.size + nb.size >= PAR_CUTOFF;
        if split_a {
            let (l, r) = (na.start as usize, na.right as usize);
            if parallel {
                let (mut o1, o2) = rayon::join(
                    || {
                        let mut o = Vec::new();
                        self.cross_rec(other, l, b, visit, &mut o);
                        o
                    },
                    || {
                        let mut o = Vec::new();
                        self.cross_rec(other, r, b, visit, &mut o);
                        o
                    },
                );
                o1.extend(o2);
                out.extend(o1);
            } else {
                self.cross_rec(other, l, b, visit, out);
                self.cross_rec(other, r, b, visit, out);
            }
        } else {
            let (l, r) = (nb.start as usize, nb.right as usize);
            if parallel {
                let (mut o1, o2) = rayon::join(
                    || {
                        let mut o = Vec::new();
                        self.cross_rec(other, a, l, visit, &mut o);
                        o
                    },
                    || {
                        let mut o = Vec::new();
                        self.cross_rec(other, a, r, visit, &mut o);
                        o
                    },
                );
                o1.extend(o2);
                out.extend(o1);
            } else {
                self.cross_rec(other, a, l, visit, out);
                self.cross_rec(other, a, r, visit, out);
            }
        }
    }

    /// Calls `visit(i)` for every primitive whose box overlaps `query`.
    pub fn query(&self, query: &Aabb, mut visit: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let n = &self.nodes[stack[sp] as usize];
            if !n.aabb.overlaps(query) {
                continue;
            }
            if n.is_leaf() {
                for i in n.start..n.start + n.count {
                    if self.slot_aabbs[i as usize].overlaps(query) {
                        visit(self.order[i as usize]);
                    }
                }
            } else {
                stack[sp] = n.right;
                stack[sp + 1] = n.start;
                sp += 2;
            }
        }
    }
}

fn build_rec(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    offset: u32,
    centers: &[[f64; 3]],
    aabbs: &[Aabb],
) -> usize {
    let idx = nodes.len();
    let aabb = order
        .iter()
        .fold(Aabb::EMPTY, |a, &i| a.union(&aabbs[i as usize]));
    let size = order.len() as u32;
    nodes.push(Node {
        aabb,
        start: offset,
        count: size,
        right: 0,
        size,
    });
    if order.len() <= LEAF_SIZE {
        return idx;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &i in order.iter() {
        let c = centers[i as usize];
        for k in 0..3 {
            lo[k] = lo[k].min(c[k]);
            hi[k] = hi[k].max(c[k]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centers[a as usize][axis]
            .total_cmp(&centers[b as usize][axis])
            .then(a.cmp(&b))
    });
    let (left, right) = order.split_at_mut(mid);
    let l = build_rec(nodes, left, offset, centers, aabbs);
    let r = build_rec(nodes, right, offset + mid as u32, centers, aabbs);
    nodes[idx].start = l as u32;
    nodes[idx].count = 0;
    nodes[idx].right = r as u32;
    idx
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use proptest::prelude::*;

    fn boxes(raw: &[([f64; 3], [f64; 3])]) -> Vec<Aabb> {
        raw.iter()
            .map(|(c, e)| {
                let c = Vec3::new(c[0], c[1], c[2]);
                let e = Vec3::new(e[0], e[1], e[2]);
                Aabb {
                    min: c - e,
                    max: c + e,
                }
            })
            .collect()
    }

    proptest! {
        /// Self and cross traversal report exactly the overlapping pairs of a brute-force scan,
        /// also after a refit to moved boxes.
        #[test]
        fn matches_brute_force(
            raw in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 0..300),
            raw2 in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 0..100),
            shift in proptest::array::uniform3(-3.0f64..3.0),
        ) {
            let a = boxes(&raw);
            let b = boxes(&raw2);
            let brute_self = |a: &[Aabb]| {
                let mut v = Vec::new();
                for i in 0..a.len() { for j in i + 1..a.len() { if a[i].overlaps(&a[j]) { v.push((i as u32, j as u32)); } } }
                v
            };
            let mut bvh = Bvh::build(&a);
            let mut got: Vec<(u32, u32)> = bvh.self_pairs(|i, j, o| o.push((i.min(j), i.max(j))));
            got.sort();
            prop_assert_eq!(&got, &brute_self(&a));
            let bvh2 = Bvh::build(&b);
            let mut cross: Vec<(u32, u32)> = bvh.cross_pairs(&bvh2, |i, j, o| o.push((i, j)));
            cross.sort();
            let mut want = Vec::new();
            for i in 0..a.len() { for j in 0..b.len() { if a[i].overlaps(&b[j]) { want.push((i as u32, j as u32)); } } }
            prop_assert_eq!(cross, want);
            // Move half of the boxes, refit, compare again.
            let s = Vec3::new(shift[0], shift[1], shift[2]);
            let moved: Vec<Aabb> = a.iter().enumerate().map(|(i, b)| if i % 2 == 0 { Aabb { min: b.min + s, max: b.max + s } } else { *b }).collect();
            bvh.refit(&moved);
            let mut got: Vec<(u32, u32)> = bvh.self_pairs(|i, j, o| o.push((i.min(j), i.max(j))));
            got.sort();
            prop_assert_eq!(got, brute_self(&moved));
            if let Some(q) = moved.first() {
                let mut hits = Vec::new();
                bvh.query(q, |i| hits.push(i));
                hits.sort();
                let want: Vec<u32> = (0..moved.len() as u32).filter(|&i| moved[i as usize].overlaps(q)).collect();
                prop_assert_eq!(hits, want);
            }
        }
    }

    #[test]
    fn output_order_is_thread_independent() {
        let raw: Vec<([f64; 3], [f64; 3])> = (0..5000)
            .map(|i| {
                let x = (i as f64 * 0.618).fract() * 50.0;
                let y = (i as f64 * 0.414).fract() * 50.0;
                ([x, y, (i % 7) as f64], [0.8, 0.8, 0.8])
            })
            .collect();
        let a = boxes(&raw);
        let bvh = Bvh::build(&a);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| bvh.self_pairs(|i, j, o: &mut Vec<(u32, u32)>| o.push((i, j))))
        };
        let one = run(1);
        assert!(one.len() > 1000);
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
    }
}
