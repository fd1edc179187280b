//! Traversal fronts ("BVTT front tracking"): where the last self- or cross-traversal of
//! bounding volume hierarchies stopped, kept so that the next traversal of the same trees starts
//! there instead of at the roots.
//!
//! A traversal of two hierarchies (or of one with itself) walks a tree of node pairs. The pairs
//! where it stops, node pairs whose boxes were apart and leaf pairs (plus, for a self-traversal,
//! every leaf with itself), form a *front*: a cut through that tree which every primitive pair
//! lies below exactly once. Any such cut gives exactly the overlapping primitive pairs: an entry
//! whose boxes are apart has none below it, an entry whose boxes overlap is traversed from there
//! as usual (and replaced by the entries where that traversal stops). The front therefore stays
//! valid while the trees keep their shape ([`Bvh::refit`] and [`Bvh::refit_changed`] move boxes
//! only), and starting from the last one skips the inner node pairs above it, which a coherent
//! motion (cloth, one time step) leaves where they were. A rebuild changes the shape; the front
//! notices (build identifiers) and starts again from the roots.
//!
//! The front only moves down (entries are never merged back into their parents), so it grows
//! slowly between rebuilds; the collision hierarchies are rebuilt every few steps.

use rayon::prelude::*;

use super::bvh::{cross_children, par_cutoff, Bvh};

/// Entries per parallel task when a traversal starts from a front.
const CHUNK: usize = 512;

/// Where the last traversal of one hierarchy with itself ([`Bvh::self_pairs_tracked`]) or of two
/// hierarchies ([`Bvh::cross_pairs_tracked`]) stopped. Empty at first; a front made for other
/// trees (another build, or another pair of trees) is ignored and replaced.
#[derive(Clone, Debug, Default)]
pub struct Front {
    /// The trees' shape identifiers (`(tree, tree)` for a self-traversal).
    shapes: (u64, u64),
    /// Node pairs `(a, b)` (node of the first tree, node of the second); in a self front,
    /// `(a, a)` stands for the pairs within leaf `a`.
    entries: Vec<(u32, u32)>,
    /// Number of values the last traversal returned (kept across rebuilds): the next one
    /// reserves room for about as many, instead of growing its buffers by copying.
    found: usize,
}

impl Front {
    /// Number of node pairs in the front (0 before the first traversal).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no traversal has been recorded.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

/// Found pairs and front entries of a part of a traversal.
struct Acc<T> {
    out: Vec<T>,
    front: Vec<(u32, u32)>,
}

impl<T> Acc<T> {
    fn new() -> Self {
        Acc {
            out: Vec::new(),
            front: Vec::new(),
        }
    }

    fn append(&mut self, o: Acc<T>) {
        self.out.extend(o.out);
        self.front.extend(o.front);
    }
}

impl Bvh {
    /// The pairs of [`Bvh::self_pairs`] (`visit(i, j, out)` for every pair `i != j` of
    /// primitives whose boxes overlap, each unordered pair once), traversed from `front` when it
    /// was left by a traversal of this tree's shape, else from the root; `front` is replaced by
    /// where this traversal stopped. The order of the output does not depend on the number of
    /// threads, but it does depend on the front (callers that need a fixed order sort).
    pub fn self_pairs_tracked<T, F>(&self, front: &mut Front, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        let order = &self.order;
        let visit =
            |a: u32, b: u32, out: &mut Vec<T>| visit(order[a as usize], order[b as usize], out);
        let shapes = (self.shape_id, self.shape_id);
        if self.nodes.is_empty() {
            *front = Front::default();
            return Vec::new();
        }
        let acc = if front.shapes == shapes && !front.entries.is_empty() {
            from_entries(&front.entries, front.found, |&(a, b), acc: &mut Acc<T>| {
                if a == b {
                    self.leaf_self(&self.nodes[a as usize], &visit, &mut acc.out);
                    acc.front.push((a, a));
                } else {
                    self.cross_entry(self, a as usize, b as usize, u32::MAX, &visit, acc);
                }
            })
        } else {
            let mut acc = Acc::new();
            acc.out.reserve(room(front.found));
            acc.front.reserve(room(front.entries.len()));
            self.self_full(0, par_cutoff(), &visit, &mut acc);
            acc
        };
        front.shapes = shapes;
        front.entries = acc.front;
        front.found = acc.out.len();
        acc.out
    }

    /// The pairs of [`Bvh::cross_pairs`] (`visit(i, j, out)` for every primitive `i` of `self`
    /// and `j` of `other` whose boxes overlap), traversed from `front` as in
    /// [`Bvh::self_pairs_tracked`].
    pub fn cross_pairs_tracked<T, F>(&self, other: &Bvh, front: &mut Front, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        let (oa, ob) = (&self.order, &other.order);
        let visit = |i: u32, j: u32, out: &mut Vec<T>| visit(oa[i as usize], ob[j as usize], out);
        let shapes = (self.shape_id, other.shape_id);
        if self.nodes.is_empty() || other.nodes.is_empty() {
            *front = Front::default();
            return Vec::new();
        }
        let acc = if front.shapes == shapes && !front.entries.is_empty() {
            from_entries(&front.entries, front.found, |&(a, b), acc: &mut Acc<T>| {
                self.cross_entry(other, a as usize, b as usize, u32::MAX, &visit, acc);
            })
        } else {
            let mut acc = Acc::new();
            acc.out.reserve(room(front.found));
            acc.front.reserve(room(front.entries.len()));
            self.cross_entry(other, 0, 0, par_cutoff(), &visit, &mut acc);
            acc
        };
        front.shapes = shapes;
        front.entries = acc.front;
        front.found = acc.out.len();
        acc.out
    }

    /// Self-traversal of the subtree at `a` from its root, recording the front; halves of at
    /// least `cutoff` primitives in parallel (the output is concatenated in a fixed order).
    fn self_full<T: Send, F: Fn(u32, u32, &mut Vec<T>) + Sync>(
        &self,
        a: usize,
        cutoff: u32,
        visit: &F,
        acc: &mut Acc<T>,
    ) {
        let n = &self.nodes[a];
        if n.is_leaf() {
            self.leaf_self(n, visit, &mut acc.out);
            acc.front.push((a as u32, a as u32));
            return;
        }
        let (l, r) = (n.start as usize, n.right as usize);
        if n.size >= cutoff {
            let ((), (o2, o3)) = rayon::join(
                || self.self_full(l, cutoff, visit, acc),
                || {
                    rayon::join(
                        || {
                            let mut o = Acc::new();
                            self.self_full(r, cutoff, visit, &mut o);
                            o
                        },
                        || {
                            let mut o = Acc::new();
                            self.cross_entry(self, l, r, cutoff, visit, &mut o);
                            o
                        },
                    )
                },
            );
            acc.append(o2);
            acc.append(o3);
        } else {
            self.self_full(l, cutoff, visit, acc);
            self.self_full(r, cutoff, visit, acc);
            self.cross_entry(self, l, r, cutoff, visit, acc);
        }
    }

    /// Cross-traversal from the node pair `(a, b)` (node of `self`, node of `other`): an entry
    /// of the front if their boxes are apart, else traversed as in [`Bvh::cross_pairs`] (the
    /// larger node split first, children tested before descending), recording where it stops.
    fn cross_entry<T: Send, F: Fn(u32, u32, &mut Vec<T>) + Sync>(
        &self,
        other: &Bvh,
        a: usize,
        b: usize,
        cutoff: u32,
        visit: &F,
        acc: &mut Acc<T>,
    ) {
        let (na, nb) = (&self.nodes[a], &other.nodes[b]);
        if !na.aabb.overlaps(&nb.aabb) {
            acc.front.push((a as u32, b as u32));
            return;
        }
        if na.is_leaf() && nb.is_leaf() {
            self.leaf_cross(other, na, nb, visit, &mut acc.out);
            acc.front.push((a as u32, b as u32));
            return;
        }
        let (first, second) = cross_children(na, nb, a, b);
        if na.size + nb.size >= cutoff {
            let ((), o2) = rayon::join(
                || self.cross_entry(other, first.0, first.1, cutoff, visit, acc),
                || {
                    let mut o = Acc::new();
                    self.cross_entry(other, second.0, second.1, cutoff, visit, &mut o);
                    o
                },
            );
            acc.append(o2);
        } else {
            self.cross_entry(other, first.0, first.1, cutoff, visit, acc);
            self.cross_entry(other, second.0, second.1, cutoff, visit, acc);
        }
    }
}

/// Room for the values of a traversal when the last one found `found`: an eighth more (the
/// buffers then rarely grow).
fn room(found: usize) -> usize {
    found + found / 8
}

/// Runs `step` over the front `entries` (in chunks in parallel when there are several worker
/// threads) and concatenates the results in entry order; the last traversal from these entries
/// found `found` values (room is reserved for a share of them per chunk).
fn from_entries<T: Send>(
    entries: &[(u32, u32)],
    found: usize,
    step: impl Fn(&(u32, u32), &mut Acc<T>) + Sync,
) -> Acc<T> {
    let run = |chunk: &[(u32, u32)]| {
        let mut acc = Acc::new();
        acc.front.reserve(room(chunk.len()));
        acc.out
            .reserve(room(found).saturating_mul(chunk.len()) / entries.len());
        for e in chunk {
            step(e, &mut acc);
        }
        acc
    };
    if par_cutoff() == u32::MAX || entries.len() <= CHUNK {
        return run(entries);
    }
    let parts: Vec<Acc<T>> = entries.par_chunks(CHUNK).map(run).collect();
    let mut acc = Acc::new();
    acc.out
        .reserve(parts.iter().map(|p| p.out.len()).sum::<usize>());
    acc.front
        .reserve(parts.iter().map(|p| p.front.len()).sum::<usize>());
    for p in parts {
        acc.append(p);
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::broad::test_boxes as boxes;
    use crate::geom::{Aabb, Vec3};
    use proptest::prelude::*;

    /// The boxes moved by `d * (k mod 7 - 3)` along a direction depending on `k` (a coherent,
    /// non-uniform motion).
    fn moved(b: &[Aabb], d: f64, step: usize) -> Vec<Aabb> {
        b.iter()
            .enumerate()
            .map(|(k, b)| {
                let s = d * (((k + step) % 7) as f64 - 3.0);
                let v = Vec3::new(s, -0.5 * s, 0.25 * s);
                Aabb {
                    min: b.min + v,
                    max: b.max + v,
                }
            })
            .collect()
    }

    fn brute_self(b: &[Aabb]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for i in 0..b.len() {
            for j in i + 1..b.len() {
                if b[i].overlaps(&b[j]) {
                    out.push((i as u32, j as u32));
                }
            }
        }
        out
    }

    fn brute_cross(a: &[Aabb], b: &[Aabb]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for i in 0..a.len() {
            for j in 0..b.len() {
                if a[i].overlaps(&b[j]) {
                    out.push((i as u32, j as u32));
                }
            }
        }
        out
    }

    fn sorted(mut v: Vec<(u32, u32)>) -> Vec<(u32, u32)> {
        v.sort_unstable();
        v
    }

    proptest! {
        /// Over a sequence of refits (and a rebuild in the middle), the tracked traversals
        /// report exactly the brute-force overlaps, each once, whatever front they start from;
        /// 1 and 2 threads give the same sequence.
        #[test]
        fn tracked_pairs_are_the_brute_force_overlaps(
            raw in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 0..300),
            raw2 in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 0..200),
            d in 0.0f64..0.8,
            leaf in 1usize..10,
            rebuild_at in 0usize..5,
        ) {
            let (b0, c0) = (boxes(&raw), boxes(&raw2));
            let mut t = Bvh::build_with_leaf_size(&b0, leaf);
            let mut u = Bvh::build_with_leaf_size(&c0, leaf);
            let (mut fs, mut fc) = (Front::default(), Front::default());
            let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            let (p1, p2) = (pool(1), pool(2));
            for step in 0..5 {
                let (b, c) = (moved(&b0, d, step), moved(&c0, d, 2 * step));
                if step == rebuild_at {
                    t = Bvh::build_with_leaf_size(&b, leaf);
                } else {
                    t.refit(&b);
                }
                u.refit(&c);
                let push = |i: u32, j: u32, o: &mut Vec<(u32, u32)>| o.push((i.min(j), i.max(j)));
                let (mut fs2, mut fc2) = (fs.clone(), fc.clone());
                let got = p1.install(|| t.self_pairs_tracked(&mut fs, push));
                let got2 = p2.install(|| t.self_pairs_tracked(&mut fs2, push));
                prop_assert_eq!(&got, &got2);
                prop_assert_eq!(&fs.entries, &fs2.entries);
                prop_assert_eq!(sorted(got), brute_self(&b));
                let cross = |i: u32, j: u32, o: &mut Vec<(u32, u32)>| o.push((i, j));
                let got = p1.install(|| t.cross_pairs_tracked(&u, &mut fc, cross));
                let got2 = p2.install(|| t.cross_pairs_tracked(&u, &mut fc2, cross));
                prop_assert_eq!(&got, &got2);
                prop_assert_eq!(sorted(got), brute_cross(&b, &c));
            }
        }
    }

    /// A front left by one pair of trees is not used for another.
    #[test]
    fn a_front_of_other_trees_is_ignored() {
        let raw: Vec<([f64; 3], [f64; 3])> = (0..200)
            .map(|k| {
                let x = k as f64;
                (
                    [(x * 0.37) % 10.0, (x * 0.61) % 10.0, (x * 0.13) % 10.0],
                    [0.6; 3],
                )
            })
            .collect();
        let b = boxes(&raw);
        let (t, u) = (Bvh::build(&b), Bvh::build(&b[..150]));
        let mut f = Front::default();
        let push = |i: u32, j: u32, o: &mut Vec<(u32, u32)>| o.push((i.min(j), i.max(j)));
        let mut got = t.self_pairs_tracked(&mut f, push);
        assert!(!f.is_empty());
        got.sort_unstable();
        assert_eq!(got, brute_self(&b));
        // The same front for the smaller tree (node indices beyond it) is started over.
        let mut got = u.self_pairs_tracked(&mut f, push);
        got.sort_unstable();
        assert_eq!(got, brute_self(&b[..150]));
        let cross = |i: u32, j: u32, o: &mut Vec<(u32, u32)>| o.push((i, j));
        let mut got = u.cross_pairs_tracked(&t, &mut f, cross);
        got.sort_unstable();
        assert_eq!(got, brute_cross(&b[..150], &b));
    }
}
