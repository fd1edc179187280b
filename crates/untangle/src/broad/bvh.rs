//! Bounding volume hierarchy over axis-aligned boxes.
//!
//! Built as a linear BVH: primitives are sorted along the Morton (Z-order) curve of their box
//! centres and the sorted range is split where the highest Morton bit changes (Karras 2012), at
//! the middle when all codes are equal. One integer sort plus a linear pass, in parallel near the
//! root; the tree does not depend on the thread count. Nodes are stored in pre-order (children
//! after parents), so a refit is one reverse sweep. Traversals run in parallel with `rayon::join`
//! near the root and return results in a fixed order, so the output is identical for any thread
//! count.

use super::keys::{self, KeyBlock, Keys};
use super::lanes::{self, Block, BLOCK};
use crate::geom::{Aabb, Vec3};

/// Most primitives per leaf of [`Bvh::build`].
pub const LEAF_SIZE: usize = 4;
/// Smallest subtree offered to the culling predicate (smaller ones are cheaper to traverse).
pub const CULL_MIN: u32 = 32;
/// Subtrees with fewer primitives than this are traversed sequentially.
const PAR_CUTOFF: u32 = 256;

#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    pub(super) aabb: Aabb,
    /// `aabb.half_area()`, kept with the box (the traversals compare it at every node pair).
    pub(super) half_area: f64,
    /// Leaf: first primitive slot; inner: index of the left child (right child = `right`).
    pub(super) start: u32,
    /// Leaf: number of primitives (> 0); inner: 0.
    pub(super) count: u32,
    /// Inner: index of the right child.
    pub(super) right: u32,
    /// Number of primitives below.
    pub(super) size: u32,
    /// First slot below (the subtree holds slots `first..first + size`).
    first: u32,
    /// Leaf of at most [`BLOCK`] primitives: index of its boxes in [`Bvh::blocks`]; else
    /// [`NO_BLOCK`].
    pub(super) block: u32,
}

/// [`Node::block`] of inner nodes and of leaves too large for a block.
const NO_BLOCK: u32 = u32::MAX;

impl Node {
    #[inline]
    pub(super) fn is_leaf(&self) -> bool {
        self.count > 0
    }

    /// A leaf's slots.
    #[inline]
    fn slots(&self) -> std::ops::Range<usize> {
        self.start as usize..(self.start + self.count) as usize
    }
}

/// A bounding volume hierarchy over a fixed set of primitives (indices `0..n`).
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub(super) nodes: Vec<Node>,
    /// Primitive index of each leaf slot.
    pub(super) order: Vec<u32>,
    /// Box of each leaf slot (copied for locality; updated by `refit`).
    pub(super) slot_aabbs: Vec<Aabb>,
    /// The slot boxes of each leaf of at most [`BLOCK`] primitives again, as coordinate rows for
    /// the leaves' block tests (`Node::block`; kept equal to `slot_aabbs` by every build and
    /// refit).
    pub(super) blocks: Vec<Block>,
    /// The leaf node of each block.
    block_leaf: Vec<u32>,
    /// Shared-vertex keys of each slot ([`Bvh::set_keys`]; empty: none).
    slot_keys: Vec<Keys>,
    /// The keys of each block's slots as lanes (parallel to `blocks`; empty: none).
    key_blocks: Vec<KeyBlock>,
    /// Keys per primitive given to [`Bvh::set_keys`] (0: none).
    key_count: usize,
    /// Distinct for every build (0: never built); kept by refits and clones, which keep the
    /// tree's shape (what a [`super::front::Front`] depends on).
    pub(super) shape_id: u64,
}

/// Source of [`Bvh::shape_id`]s.
static SHAPES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl Bvh {
    /// Builds the hierarchy over `aabbs` (primitive `i` has box `aabbs[i]`).
    pub fn build(aabbs: &[Aabb]) -> Bvh {
        Bvh::build_with_leaf_size(aabbs, LEAF_SIZE)
    }

    /// [`Bvh::build`] with at most `leaf_size` (>= 1) primitives per leaf: the same pairs from
    /// every traversal, in a different order (larger leaves: fewer node visits, more box tests).
    pub fn build_with_leaf_size(aabbs: &[Aabb], leaf_size: usize) -> Bvh {
        let leaf_size = leaf_size.max(1);
        let n = aabbs.len();
        if n == 0 {
            return Bvh::default();
        }
        let bounds = aabbs.iter().fold(Aabb::EMPTY, |a, b| {
            let c = b.center();
            let mut a = a;
            a.grow(&c);
            a
        });
        let ext = bounds.extent();
        let scale = |e: f64| {
            if e > 0.0 {
                ((1u64 << 21) - 1) as f64 / e
            } else {
                0.0
            }
        };
        let (sx, sy, sz) = (scale(ext.x), scale(ext.y), scale(ext.z));
        let mut keyed: Vec<(u64, u32)> = aabbs
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let c = b.center() - bounds.min;
                let q = |v: f64, s: f64| ((v * s) as u64).min((1 << 21) - 1);
                (morton3(q(c.x, sx), q(c.y, sy), q(c.z, sz)), i as u32)
            })
            .collect();
        crate::radix::sort_by_key(&mut keyed, |k| k.0);
        let codes: Vec<u64> = keyed.iter().map(|k| k.0).collect();
        let order: Vec<u32> = keyed.iter().map(|k| k.1).collect();
        let slot_aabbs: Vec<Aabb> = order.iter().map(|&i| aabbs[i as usize]).collect();
        let mut nodes = build_subtree(&codes, &slot_aabbs, 0, 0, leaf_size);
        // Blocks in pre-order of their leaves (which is slot order).
        let leaves = nodes.len() / 2 + 1;
        let mut blocks = Vec::with_capacity(leaves);
        let mut block_leaf = Vec::with_capacity(leaves);
        for (i, n) in nodes.iter_mut().enumerate() {
            if n.is_leaf() && n.count as usize <= BLOCK {
                n.block = blocks.len() as u32;
                blocks.push(Block::new(&slot_aabbs[n.slots()]));
                block_leaf.push(i as u32);
            }
        }
        Bvh {
            nodes,
            order,
            blocks,
            block_leaf,
            slot_aabbs,
            slot_keys: Vec::new(),
            key_blocks: Vec::new(),
            key_count: 0,
            shape_id: SHAPES.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// Gives primitive `p` the vertex keys `keys[p]` (1 to [`keys::KEYS`] of them: a vertex, an
    /// edge's ends, a triangle's corners): from then on the self and cross traversals
    /// ([`Bvh::self_pairs`], [`Bvh::cross_pairs`] and their slot, culled and tracked forms)
    /// skip the pairs of primitives that share a key, a cross traversal only when both
    /// hierarchies have keys. Refits keep the keys; a build starts without them. Queries
    /// ([`Bvh::query`]) ignore them.
    pub fn set_keys<const K: usize>(&mut self, keys: &[[u32; K]]) {
        assert_eq!(keys.len(), self.order.len(), "one key set per primitive");
        assert!(
            (1..=keys::KEYS).contains(&K),
            "1 to KEYS keys per primitive"
        );
        self.key_count = K;
        self.slot_keys = self
            .order
            .iter()
            .map(|&p| keys::padded(&keys[p as usize]))
            .collect();
        let (nodes, slot_keys) = (&self.nodes, &self.slot_keys);
        self.key_blocks = self
            .block_leaf
            .iter()
            .map(|&leaf| KeyBlock::new(&slot_keys[nodes[leaf as usize].slots()]))
            .collect();
    }

    /// Whether [`Bvh::set_keys`] gave the primitives keys (since the build).
    pub fn has_keys(&self) -> bool {
        !self.slot_keys.is_empty()
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
        use rayon::prelude::*;
        self.slot_aabbs
            .par_iter_mut()
            .with_min_len(4096)
            .zip(self.order.par_iter())
            .for_each(|(slot, &p)| *slot = aabbs[p as usize]);
        let (nodes, slots) = (&self.nodes, &self.slot_aabbs);
        self.blocks
            .par_iter_mut()
            .with_min_len(1024)
            .zip(self.block_leaf.par_iter())
            .for_each(|(b, &leaf)| b.set(&slots[nodes[leaf as usize].slots()]));
        if !self.nodes.is_empty() {
            let cutoff = par_cutoff().saturating_mul(4);
            refit_subtree(&mut self.nodes, 0, &self.slot_aabbs, cutoff);
        }
    }

    /// [`Bvh::refit`] when only the primitives `p` with `changed[p]` may have new boxes since
    /// the last refit (or the build): only their slots are copied, and only the nodes above them
    /// are recomputed; every other node keeps its box, which is the union of the same slot boxes
    /// (ours). The same boxes as [`Bvh::refit`] bit for bit (unions of boxes are exact).
    pub fn refit_changed(&mut self, aabbs: &[Aabb], changed: &[bool]) {
        assert_eq!(
            aabbs.len(),
            self.order.len(),
            "refit with a different primitive count"
        );
        assert_eq!(changed.len(), self.order.len(), "one flag per primitive");
        // Dirty slots before each slot: a subtree (slots `first..first + size`) needs a refit
        // iff the count grows over it.
        let mut dirty = Vec::with_capacity(self.order.len() + 1);
        dirty.push(0u32);
        let mut count = 0;
        for (slot, &p) in self.slot_aabbs.iter_mut().zip(&self.order) {
            if changed[p as usize] {
                *slot = aabbs[p as usize];
                count += 1;
            }
            dirty.push(count);
        }
        if count > 0 && !self.nodes.is_empty() {
            refit_dirty(
                &mut self.nodes,
                0,
                &self.slot_aabbs,
                &mut self.blocks,
                &dirty,
            );
        }
    }

    /// Calls `visit(i, j, out)` for every pair `i != j` of primitives whose boxes overlap (and
    /// that share no key, after [`Bvh::set_keys`]), each unordered pair once, and returns everything pushed to `out`, in an order independent of the
    /// number of threads.
    pub fn self_pairs<T, F>(&self, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        let order = &self.order;
        self.self_slot_pairs(|a, b, out| visit(order[a as usize], order[b as usize], out))
    }

    /// Like [`Bvh::self_pairs`], but passes *slot* indices (positions in [`Bvh::order`]), so a
    /// caller can keep per-primitive data in slot order and read it from contiguous memory.
    pub fn self_slot_pairs<T, F>(&self, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        self.self_slot_pairs_culled(visit, |_, _, _| false)
    }

    /// Like [`Bvh::self_slot_pairs`], skipping the pairs *within* every subtree (of at least
    /// [`CULL_MIN`] primitives) for which `cull(node, first_slot, len)` certifies that no two of
    /// its primitives need visiting. Pairs between a culled subtree and the rest are still
    /// visited. `node` indexes the values of [`Bvh::fold_up`].
    pub fn self_slot_pairs_culled<T, F, C>(&self, visit: F, cull: C) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
        C: Fn(usize, u32, u32) -> bool + Sync,
    {
        if self.nodes.is_empty() {
            return Vec::new();
        }
        let mut out = Vec::new();
        self.self_rec(0, par_cutoff(), &visit, &cull, &mut out);
        out
    }

    /// A value per node computed bottom-up: `leaf(slots)` for a leaf's primitive slots,
    /// `merge(left, right)` for an inner node. Indexed like the `node` argument of the culling
    /// predicate of [`Bvh::self_slot_pairs_culled`].
    pub fn fold_up<V: Clone>(
        &self,
        leaf: impl Fn(std::ops::Range<u32>) -> V,
        merge: impl Fn(&V, &V) -> V,
    ) -> Vec<V> {
        let mut vals: Vec<Option<V>> = vec![None; self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            let v = if n.is_leaf() {
                leaf(n.start..n.start + n.count)
            } else {
                let (l, r) = (
                    vals[n.start as usize].as_ref(),
                    vals[n.right as usize].as_ref(),
                );
                merge(
                    l.expect("children after parents"),
                    r.expect("children after parents"),
                )
            };
            vals[i] = Some(v);
        }
        vals.into_iter()
            .map(|v| v.expect("every node folded"))
            .collect()
    }

    /// The primitive stored in each slot (slots are leaf order, close primitives are close).
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// The overlapping pairs within leaf `n` (slot indices), in slot order.
    #[inline(always)]
    pub(super) fn leaf_self<T, F: Fn(u32, u32, &mut Vec<T>)>(
        &self,
        n: &Node,
        visit: &F,
        out: &mut Vec<T>,
    ) {
        let s = n.start as usize;
        let keyed = self.has_keys();
        if n.block != NO_BLOCK {
            let (b, c) = (n.block as usize, n.count as usize);
            let bits = if keyed {
                lanes::self_block_keyed(&self.blocks[b], c, &self.key_blocks[b], self.key_count)
            } else {
                lanes::self_block(&self.blocks[b], c)
            };
            visit_bits(bits, s, s, visit, out);
            return;
        }
        let slots = &self.slot_aabbs[s..s + n.count as usize];
        for (di, bi) in slots.iter().enumerate() {
            for (dj, bj) in slots[di + 1..].iter().enumerate() {
                let (i, j) = (s + di, s + di + 1 + dj);
                if overlap(bi, bj)
                    && !(keyed && keys::share(&self.slot_keys[i], &self.slot_keys[j]))
                {
                    visit(i as u32, j as u32, out);
                }
            }
        }
    }

    /// The overlapping pairs between leaf `na` of `self` and leaf `nb` of `other` (slot
    /// indices), in slot order of `na`, then of `nb`.
    #[inline(always)]
    pub(super) fn leaf_cross<T, F: Fn(u32, u32, &mut Vec<T>)>(
        &self,
        other: &Bvh,
        na: &Node,
        nb: &Node,
        visit: &F,
        out: &mut Vec<T>,
    ) {
        let (sa, sb) = (na.start as usize, nb.start as usize);
        let keyed = self.has_keys() && other.has_keys();
        if na.block != NO_BLOCK && nb.block != NO_BLOCK {
            let (ka, kb) = (na.block as usize, nb.block as usize);
            let (ba, bb) = (&self.blocks[ka], &other.blocks[kb]);
            let (ca, cb) = (na.count as usize, nb.count as usize);
            let bits = if keyed {
                let keys = (
                    &self.key_blocks[ka],
                    self.key_count,
                    &other.key_blocks[kb],
                    other.key_count,
                );
                lanes::cross_block_keyed(ba, ca, &nb.aabb, bb, cb, keys)
            } else {
                lanes::cross_block(ba, ca, &nb.aabb, bb, cb)
            };
            visit_bits(bits, sa, sb, visit, out);
            return;
        }
        let boxes_b = &other.slot_aabbs[sb..sb + nb.count as usize];
        for (di, bi) in self.slot_aabbs[sa..sa + na.count as usize]
            .iter()
            .enumerate()
        {
            // A box apart from the union of `b`'s boxes overlaps none of them.
            if !overlap(bi, &nb.aabb) {
                continue;
            }
            for (dj, bj) in boxes_b.iter().enumerate() {
                let (i, j) = (sa + di, sb + dj);
                if overlap(bi, bj)
                    && !(keyed && keys::share(&self.slot_keys[i], &other.slot_keys[j]))
                {
                    visit(i as u32, j as u32, out);
                }
            }
        }
    }

    fn self_rec<
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
        C: Fn(usize, u32, u32) -> bool + Sync,
    >(
        &self,
        a: usize,
        cutoff: u32,
        visit: &F,
        cull: &C,
        out: &mut Vec<T>,
    ) {
        let n = &self.nodes[a];
        if n.size >= CULL_MIN && cull(a, n.first, n.size) {
            return;
        }
        if n.is_leaf() {
            self.leaf_self(n, visit, out);
            return;
        }
        // Pairs within the left subtree, within the right one, then between them (the order
        // of the output); the parallel split only changes who computes which part.
        let (l, r) = (n.start as usize, n.right as usize);
        let cross = self.nodes[l].aabb.overlaps(&self.nodes[r].aabb);
        if n.size >= cutoff {
            let ((), (o2, o3)) = rayon::join(
                || self.self_rec(l, cutoff, visit, cull, out),
                || {
                    rayon::join(
                        || {
                            let mut o = Vec::new();
                            self.self_rec(r, cutoff, visit, cull, &mut o);
                            o
                        },
                        || {
                            let mut o = Vec::new();
                            if cross {
                                self.cross_overlapping(self, l, r, cutoff, visit, &mut o);
                            }
                            o
                        },
                    )
                },
            );
            out.extend(o2);
            out.extend(o3);
        } else {
            self.self_rec(l, cutoff, visit, cull, out);
            self.self_rec(r, cutoff, visit, cull, out);
            if cross {
                self.cross_overlapping(self, l, r, cutoff, visit, out);
            }
        }
    }

    /// Calls `visit(i, j, out)` for every primitive `i` of `self` and `j` of `other` whose boxes
    /// overlap (and that share no key, when both have keys: [`Bvh::set_keys`]); deterministic
    /// order as in [`Bvh::self_pairs`].
    pub fn cross_pairs<T, F>(&self, other: &Bvh, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        if self.nodes.is_empty() || other.nodes.is_empty() {
            return Vec::new();
        }
        let (oa, ob) = (&self.order, &other.order);
        let visit = |i: u32, j: u32, out: &mut Vec<T>| visit(oa[i as usize], ob[j as usize], out);
        let mut out = Vec::new();
        self.cross_rec_slots(other, 0, 0, par_cutoff(), &visit, &mut out);
        out
    }

    /// Cross traversal reporting slot indices of `self` and `other`.
    fn cross_rec_slots<T: Send, F: Fn(u32, u32, &mut Vec<T>) + Sync>(
        &self,
        other: &Bvh,
        a: usize,
        b: usize,
        cutoff: u32,
        visit: &F,
        out: &mut Vec<T>,
    ) {
        if self.nodes[a].aabb.overlaps(&other.nodes[b].aabb) {
            self.cross_overlapping(other, a, b, cutoff, visit, out);
        }
    }

    /// [`Bvh::cross_rec_slots`] for nodes `a` and `b` whose boxes overlap. Descends the larger
    /// node (by half area; the node of `self` on ties, the inner one if the other is a leaf),
    /// its first child before its second, testing each child's box before descending into it:
    /// the output order is that of the plain recursion, which tests on entry.
    fn cross_overlapping<T: Send, F: Fn(u32, u32, &mut Vec<T>) + Sync>(
        &self,
        other: &Bvh,
        a: usize,
        b: usize,
        cutoff: u32,
        visit: &F,
        out: &mut Vec<T>,
    ) {
        let (na, nb) = (&self.nodes[a], &other.nodes[b]);
        if na.is_leaf() && nb.is_leaf() {
            self.leaf_cross(other, na, nb, visit, out);
            return;
        }
        let parallel = na.size + nb.size >= cutoff;
        let (first, second) = cross_children(na, nb, a, b);
        let hits = |(x, y): (usize, usize)| self.nodes[x].aabb.overlaps(&other.nodes[y].aabb);
        let (h1, h2) = (hits(first), hits(second));
        if parallel && h1 && h2 {
            let ((), o2) = rayon::join(
                || self.cross_overlapping(other, first.0, first.1, cutoff, visit, out),
                || {
                    let mut o = Vec::new();
                    self.cross_overlapping(other, second.0, second.1, cutoff, visit, &mut o);
                    o
                },
            );
            out.extend(o2);
        } else {
            if h1 {
                self.cross_overlapping(other, first.0, first.1, cutoff, visit, out);
            }
            if h2 {
                self.cross_overlapping(other, second.0, second.1, cutoff, visit, out);
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
                let (s, c) = (n.start as usize, n.count as usize);
                if n.block != NO_BLOCK {
                    let mut bits = lanes::row_block(query, &self.blocks[n.block as usize], c);
                    while bits != 0 {
                        visit(self.order[s + bits.trailing_zeros() as usize]);
                        bits &= bits - 1;
                    }
                    continue;
                }
                for i in s..s + c {
                    if self.slot_aabbs[i].overlaps(query) {
                        visit(self.order[i]);
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

/// Calls `visit(a + i, b + j, out)` for every bit `BLOCK * i + j` of a block test's `bits`, in
/// increasing order (slot order of the first block, then of the second).
#[inline(always)]
fn visit_bits<T, F: Fn(u32, u32, &mut Vec<T>)>(
    mut bits: u64,
    a: usize,
    b: usize,
    visit: &F,
    out: &mut Vec<T>,
) {
    while bits != 0 {
        let k = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        visit((a + k / BLOCK) as u32, (b + k % BLOCK) as u32, out);
    }
}

/// Subtree size from which traversals split into parallel tasks: [`PAR_CUTOFF`], or never with a
/// single worker thread (the split only adds task and buffer overhead there). The output order is
/// the same either way.
pub(super) fn par_cutoff() -> u32 {
    if rayon::current_num_threads() > 1 {
        PAR_CUTOFF
    } else {
        u32::MAX
    }
}

/// The box of leaf `n`'s slot boxes.
#[inline]
fn leaf_box(n: &Node, slots: &[Aabb]) -> Aabb {
    slots[n.start as usize..(n.start + n.count) as usize]
        .iter()
        .fold(Aabb::EMPTY, |a, b| a.union(b))
}

/// Stores `b` (and its half area) as the box of `node`; returns `b`.
#[inline]
fn set_box(node: &mut Node, b: Aabb) -> Aabb {
    node.aabb = b;
    node.half_area = b.half_area();
    b
}

/// Refits the subtree whose nodes are `nodes` (pre-order, so a subtree is contiguous: its
/// root, then the left subtree, then the right one; `offset` = global index of `nodes[0]`)
/// from the slot boxes; returns its box. Subtrees of at least `cutoff` primitives refit their
/// halves in parallel (the same boxes for any thread count).
fn refit_subtree(nodes: &mut [Node], offset: usize, slots: &[Aabb], cutoff: u32) -> Aabb {
    let n = nodes[0];
    let b = if n.is_leaf() {
        leaf_box(&n, slots)
    } else {
        let (l, r) = (n.start as usize - offset, n.right as usize - offset);
        let (left, right) = nodes[l..].split_at_mut(r - l);
        let (bl, br) = if n.size >= cutoff {
            rayon::join(
                || refit_subtree(left, offset + l, slots, cutoff),
                || refit_subtree(right, offset + r, slots, cutoff),
            )
        } else {
            (
                refit_subtree(left, offset + l, slots, cutoff),
                refit_subtree(right, offset + r, slots, cutoff),
            )
        };
        bl.union(&br)
    };
    set_box(&mut nodes[0], b)
}

/// [`refit_subtree`] (sequential) of only the subtrees with a dirty slot (`dirty[s]`: dirty
/// slots before slot `s`); the others keep their boxes. Returns the subtree's box.
fn refit_dirty(
    nodes: &mut [Node],
    offset: usize,
    slots: &[Aabb],
    blocks: &mut [Block],
    dirty: &[u32],
) -> Aabb {
    let n = nodes[0];
    if dirty[(n.first + n.size) as usize] == dirty[n.first as usize] {
        return n.aabb;
    }
    let b = if n.is_leaf() {
        if n.block != NO_BLOCK {
            blocks[n.block as usize].set(&slots[n.slots()]);
        }
        leaf_box(&n, slots)
    } else {
        let (l, r) = (n.start as usize - offset, n.right as usize - offset);
        let (left, right) = nodes[l..].split_at_mut(r - l);
        let bl = refit_dirty(left, offset + l, slots, blocks, dirty);
        let br = refit_dirty(right, offset + r, slots, blocks, dirty);
        bl.union(&br)
    };
    set_box(&mut nodes[0], b)
}

/// The two node pairs a cross-traversal of the overlapping nodes `a` (node `na` of the first
/// tree) and `b` (`nb` of the second), not both leaves, descends into, in output order: the
/// larger node by half area is split (the first tree's on ties, the inner one if the other is a
/// leaf), its first child before its second. Shared by [`Bvh::cross_pairs`] and the front
/// traversal (`broad::front`), whose fronts rely on the same order.
#[inline(always)]
pub(super) fn cross_children(
    na: &Node,
    nb: &Node,
    a: usize,
    b: usize,
) -> ((usize, usize), (usize, usize)) {
    if !na.is_leaf() && (nb.is_leaf() || na.half_area >= nb.half_area) {
        ((na.start as usize, b), (na.right as usize, b))
    } else {
        ((a, nb.start as usize), (a, nb.right as usize))
    }
}

/// [`Aabb::overlaps`] without short-circuiting (the six comparisons are cheaper than the
/// branches in the traversals' innermost loops; same result).
#[inline(always)]
pub(super) fn overlap(a: &Aabb, b: &Aabb) -> bool {
    (a.min.x <= b.max.x)
        & (b.min.x <= a.max.x)
        & (a.min.y <= b.max.y)
        & (b.min.y <= a.max.y)
        & (a.min.z <= b.max.z)
        & (b.min.z <= a.max.z)
}

/// The indices of `points` sorted along the Morton (Z-order) curve over their bounding box
/// (21 bits per axis; ties by index, a stable radix sort), with their codes in that order.
pub(crate) fn morton_sorted(points: &[Vec3]) -> (Vec<u64>, Vec<u32>) {
    let Some(first) = points.first() else {
        return (Vec::new(), Vec::new());
    };
    let (lo, hi) = points
        .iter()
        .fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    let ext = hi - lo;
    const TOP: u64 = (1 << 21) - 1;
    let q = |v: f64, e: f64| {
        if e > 0.0 {
            ((v / e * TOP as f64) as u64).min(TOP)
        } else {
            0
        }
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let c = p - lo;
            (
                morton3(q(c.x, ext.x), q(c.y, ext.y), q(c.z, ext.z)),
                i as u32,
            )
        })
        .collect();
    crate::radix::sort_by_key(&mut keyed, |k| k.0);
    keyed.into_iter().unzip()
}

/// Interleaves the low 21 bits of x, y, z.
pub(crate) fn morton3(x: u64, y: u64, z: u64) -> u64 {
    fn spread(mut v: u64) -> u64 {
        v &= 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        v = (v | v << 2) & 0x1249_2492_4924_9249;
        v
    }
    spread(x) | spread(y) << 1 | spread(z) << 2
}

/// Where the sorted range `codes` is split: after the last code that shares the first code's
/// highest differing bit with the last code; the middle when all codes are equal.
pub(crate) fn split_point(codes: &[u64]) -> usize {
    let (first, last) = (codes[0], codes[codes.len() - 1]);
    if first == last {
        return codes.len() / 2;
    }
    let bit = 63 - (first ^ last).leading_zeros();
    // First index whose code has `bit` set (codes are sorted and agree above `bit`).
    let p = codes.partition_point(|&c| (c >> bit) & 1 == 0);
    p.clamp(1, codes.len() - 1)
}

/// Builds the subtree over slots `offset..offset + codes.len()` in pre-order, node indices local
/// to the returned vector (the root is element 0). The top `PAR_DEPTH` levels build their two
/// halves in parallel and concatenate them, shifting child indices; the result does not depend on
/// the thread count.
fn build_subtree(
    codes: &[u64],
    boxes: &[Aabb],
    offset: u32,
    depth: u32,
    leaf_size: usize,
) -> Vec<Node> {
    const PAR_DEPTH: u32 = 3;
    if depth < PAR_DEPTH && codes.len() as u32 >= 4 * PAR_CUTOFF {
        let size = codes.len() as u32;
        let m = split_point(codes);
        let (mut left, right) = rayon::join(
            || build_subtree(&codes[..m], &boxes[..m], offset, depth + 1, leaf_size),
            || {
                build_subtree(
                    &codes[m..],
                    &boxes[m..],
                    offset + m as u32,
                    depth + 1,
                    leaf_size,
                )
            },
        );
        let shift = |nodes: &mut [Node], by: u32| {
            for n in nodes.iter_mut() {
                if !n.is_leaf() {
                    n.start += by;
                    n.right += by;
                }
            }
        };
        let (nl, nr) = (left.len() as u32, right.len() as u32);
        let mut nodes = Vec::with_capacity((1 + nl + nr) as usize);
        let aabb = left[0].aabb.union(&right[0].aabb);
        nodes.push(Node {
            aabb,
            half_area: aabb.half_area(),
            start: 1,
            count: 0,
            right: 1 + nl,
            size,
            first: offset,
            block: NO_BLOCK,
        });
        shift(&mut left, 1);
        nodes.extend(left);
        let base = nodes.len();
        nodes.extend(right);
        shift(&mut nodes[base..], 1 + nl);
        debug_assert_eq!(nodes.len() as u32, 1 + nl + nr);
        return nodes;
    }
    let mut nodes = Vec::with_capacity(2 * codes.len() / leaf_size + 1);
    build_sequential(&mut nodes, codes, boxes, offset, leaf_size);
    nodes
}

/// Pre-order build appending to `nodes`; returns the index of the subtree root.
fn build_sequential(
    nodes: &mut Vec<Node>,
    codes: &[u64],
    boxes: &[Aabb],
    offset: u32,
    leaf_size: usize,
) -> usize {
    let idx = nodes.len();
    let size = codes.len() as u32;
    if codes.len() <= leaf_size {
        let aabb = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        nodes.push(Node {
            aabb,
            half_area: aabb.half_area(),
            start: offset,
            count: size,
            right: 0,
            size,
            first: offset,
            block: NO_BLOCK,
        });
        return idx;
    }
    nodes.push(Node {
        aabb: Aabb::EMPTY,
        half_area: 0.0,
        start: 0,
        count: 0,
        right: 0,
        size,
        first: offset,
        block: NO_BLOCK,
    });
    let m = split_point(codes);
    let l = build_sequential(nodes, &codes[..m], &boxes[..m], offset, leaf_size);
    let r = build_sequential(
        nodes,
        &codes[m..],
        &boxes[m..],
        offset + m as u32,
        leaf_size,
    );
    nodes[idx].aabb = nodes[l].aabb.union(&nodes[r].aabb);
    nodes[idx].half_area = nodes[idx].aabb.half_area();
    nodes[idx].start = l as u32;
    nodes[idx].right = r as u32;
    idx
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use proptest::prelude::*;

    use crate::broad::test_boxes as boxes;

    proptest! {
        /// Self and cross traversal report exactly the overlapping pairs of a brute-force scan,
        /// also after a refit to moved boxes, for any leaf size.
        #[test]
        fn matches_brute_force(
            raw in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 0..300),
            raw2 in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 0..100),
            shift in proptest::array::uniform3(-3.0f64..3.0),
            leaf in 1usize..20,
        ) {
            let a = boxes(&raw);
            let b = boxes(&raw2);
            let brute_self = |a: &[Aabb]| {
                let mut v = Vec::new();
                for i in 0..a.len() { for j in i + 1..a.len() { if a[i].overlaps(&a[j]) { v.push((i as u32, j as u32)); } } }
                v
            };
            // Any leaf size gives the same pairs (the default one most of the time).
            let leaf = if leaf < 10 { LEAF_SIZE } else { leaf - 9 };
            let mut bvh = Bvh::build_with_leaf_size(&a, leaf);
            let mut got: Vec<(u32, u32)> = bvh.self_pairs(|i, j, o| o.push((i.min(j), i.max(j))));
            got.sort();
            prop_assert_eq!(&got, &brute_self(&a));
            let bvh2 = Bvh::build_with_leaf_size(&b, leaf);
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

    proptest! {
        /// With vertex keys ([`Bvh::set_keys`]: random vertex indices from a small range, one to
        /// three per primitive) the self and cross traversals report exactly the overlapping
        /// pairs that share no key (brute force), for any leaf size (leaves with and without
        /// blocks), also after a refit; a cross traversal with a tree without keys drops none.
        #[test]
        fn keyed_traversals_drop_exactly_the_pairs_sharing_a_key(
            raw in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..3.0)), 0..300),
            raw2 in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..3.0)), 0..100),
            seed in any::<u64>(),
            leaf in 1usize..20,
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let (a, b) = (boxes(&raw), boxes(&raw2));
            let verts = 1 + a.len().max(b.len()) as u32 / 2;
            let ka: Vec<[u32; 2]> = (0..a.len()).map(|_| [rng.random_range(0..verts), rng.random_range(0..verts)]).collect();
            let kb: Vec<[u32; 3]> = (0..b.len()).map(|_| std::array::from_fn(|_| rng.random_range(0..verts))).collect();
            let leaf = if leaf < 10 { 8 } else { leaf - 9 };
            let mut t = Bvh::build_with_leaf_size(&a, leaf);
            t.set_keys(&ka);
            let mut u = Bvh::build_with_leaf_size(&b, leaf);
            let plain = u.clone();
            u.set_keys(&kb);
            let share = |x: &[u32], y: &[u32]| x.iter().any(|k| y.contains(k));
            for round in 0..2 {
                let a = if round == 0 { a.clone() } else {
                    let moved: Vec<Aabb> = a.iter().map(|b| Aabb { min: b.min * 0.9, max: b.max * 0.9 }).collect();
                    t.refit(&moved);
                    moved
                };
                let mut got: Vec<(u32, u32)> = t.self_pairs(|i, j, o| o.push((i.min(j), i.max(j))));
                got.sort();
                let mut want = Vec::new();
                for i in 0..a.len() { for j in i + 1..a.len() {
                    if a[i].overlaps(&a[j]) && !share(&ka[i], &ka[j]) { want.push((i as u32, j as u32)); }
                } }
                prop_assert_eq!(got, want);
                let mut got: Vec<(u32, u32)> = t.cross_pairs(&u, |i, j, o| o.push((i, j)));
                got.sort();
                let mut want = Vec::new();
                let mut all = Vec::new();
                for i in 0..a.len() { for j in 0..b.len() {
                    if a[i].overlaps(&b[j]) {
                        all.push((i as u32, j as u32));
                        if !share(&ka[i], &kb[j]) { want.push((i as u32, j as u32)); }
                    }
                } }
                prop_assert_eq!(got, want);
                let mut got: Vec<(u32, u32)> = t.cross_pairs(&plain, |i, j, o| o.push((i, j)));
                got.sort();
                prop_assert_eq!(got, all);
            }
        }
    }

    proptest! {
        /// A refit of only the changed primitives gives the same node boxes (and half areas) as
        /// a full refit, bit for bit, over several rounds of random moves.
        #[test]
        fn changed_refit_equals_a_full_refit(
            raw in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 1..300),
            rounds in proptest::collection::vec((any::<u64>(), 0.0f64..1.0, proptest::array::uniform3(-3.0f64..3.0)), 1..4),
            leaf in 1usize..12,
        ) {
            use rand::{Rng, SeedableRng};
            let mut a = boxes(&raw);
            let mut full = Bvh::build_with_leaf_size(&a, leaf);
            let mut part = full.clone();
            for (seed, share, shift) in rounds {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
                let changed: Vec<bool> = (0..a.len()).map(|_| rng.random::<f64>() < share).collect();
                for (b, &c) in a.iter_mut().zip(&changed) {
                    if c {
                        let s = Vec3::new(shift[0], shift[1], shift[2]) * rng.random::<f64>();
                        *b = Aabb { min: b.min + s, max: b.max + s * 1.5 };
                    }
                }
                full.refit(&a);
                part.refit_changed(&a, &changed);
                prop_assert_eq!(full.nodes.len(), part.nodes.len());
                for (x, y) in full.nodes.iter().zip(&part.nodes) {
                    prop_assert_eq!(x.aabb, y.aabb);
                    prop_assert_eq!(x.half_area.to_bits(), y.half_area.to_bits());
                }
                for (x, y) in full.slot_aabbs.iter().zip(&part.slot_aabbs) {
                    prop_assert_eq!(x, y);
                }
            }
        }
    }

    /// The plain sequential recursion the traversals implement (boxes tested on entry, half
    /// areas computed afresh, the larger node descended, the node of `a` on ties): the order
    /// oracle for [`Bvh::self_slot_pairs`] and [`Bvh::cross_pairs`].
    fn reference_self(t: &Bvh, a: usize, out: &mut Vec<(u32, u32)>) {
        let n = t.nodes[a];
        if n.is_leaf() {
            for i in n.start..n.start + n.count {
                for j in i + 1..n.start + n.count {
                    if t.slot_aabbs[i as usize].overlaps(&t.slot_aabbs[j as usize]) {
                        out.push((i, j));
                    }
                }
            }
            return;
        }
        reference_self(t, n.start as usize, out);
        reference_self(t, n.right as usize, out);
        reference_cross(t, t, n.start as usize, n.right as usize, out);
    }

    fn reference_cross(t: &Bvh, u: &Bvh, a: usize, b: usize, out: &mut Vec<(u32, u32)>) {
        let (na, nb) = (t.nodes[a], u.nodes[b]);
        if !na.aabb.overlaps(&nb.aabb) {
            return;
        }
        if na.is_leaf() && nb.is_leaf() {
            for i in na.start..na.start + na.count {
                for j in nb.start..nb.start + nb.count {
                    if t.slot_aabbs[i as usize].overlaps(&u.slot_aabbs[j as usize]) {
                        out.push((i, j));
                    }
                }
            }
            return;
        }
        if !na.is_leaf() && (nb.is_leaf() || na.aabb.half_area() >= nb.aabb.half_area()) {
            reference_cross(t, u, na.start as usize, b, out);
            reference_cross(t, u, na.right as usize, b, out);
        } else {
            reference_cross(t, u, a, nb.start as usize, out);
            reference_cross(t, u, a, nb.right as usize, out);
        }
    }

    /// Random boxes of random sizes scattered in a cube of side `side`.
    fn scattered(seed: u64, n: usize, side: f64) -> Vec<Aabb> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let c = Vec3::new(
                    rng.random_range(0.0..side),
                    rng.random_range(0.0..side),
                    rng.random_range(0.0..side),
                );
                let e = Vec3::new(
                    rng.random_range(0.0..1.0),
                    rng.random_range(0.0..1.0),
                    rng.random_range(0.0..1.0),
                );
                Aabb {
                    min: c - e,
                    max: c + e,
                }
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]
        /// The traversals report their pairs in exactly the order of the plain recursion
        /// ([`reference_self`], [`reference_cross`]), with one and with two threads, after a
        /// build and after a refit to moved boxes (the callers' results, e.g. the order of the
        /// collision candidates, depend on it).
        #[test]
        fn output_order_is_that_of_the_plain_recursion(
            seed in any::<u64>(),
            n in 1usize..2500,
            m in 1usize..800,
            side in 5.0f64..40.0,
        ) {
            let a = scattered(seed, n, side);
            let b = scattered(seed ^ 1, m, side);
            let mut t = Bvh::build(&a);
            let u = Bvh::build(&b);
            for round in 0..2 {
                if round == 1 {
                    t.refit(&scattered(seed ^ 2, n, side));
                }
                let mut want = Vec::new();
                reference_self(&t, 0, &mut want);
                let mut want_cross = Vec::new();
                reference_cross(&t, &u, 0, 0, &mut want_cross);
                let want_cross: Vec<(u32, u32)> = want_cross
                    .iter()
                    .map(|&(i, j)| (t.order[i as usize], u.order[j as usize]))
                    .collect();
                for threads in [1, 2] {
                    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    let got = pool.install(|| t.self_slot_pairs(|i, j, o: &mut Vec<(u32, u32)>| o.push((i, j))));
                    prop_assert_eq!(&got, &want);
                    let got = pool.install(|| t.cross_pairs(&u, |i, j, o: &mut Vec<(u32, u32)>| o.push((i, j))));
                    prop_assert_eq!(&got, &want_cross);
                }
            }
        }
    }

    #[test]
    fn culled_subtrees_lose_exactly_their_inner_pairs() {
        let raw: Vec<([f64; 3], [f64; 3])> = (0..600)
            .map(|i| {
                (
                    [(i % 30) as f64 * 0.5, (i / 30) as f64 * 0.5, 0.0],
                    [0.4, 0.4, 0.4],
                )
            })
            .collect();
        let a = boxes(&raw);
        let bvh = Bvh::build(&a);
        let all: Vec<(u32, u32)> = bvh.self_slot_pairs(|i, j, o| o.push((i, j)));
        // Cull every subtree lying in the first half of the slots.
        let half = (a.len() / 2) as u32;
        let culled: Vec<(u32, u32)> =
            bvh.self_slot_pairs_culled(|i, j, o| o.push((i, j)), |_, f, n| f + n <= half);
        // fold_up: sizes computed bottom-up equal the subtree sizes.
        let sizes = bvh.fold_up(|r| r.len() as u32, |a, b| a + b);
        assert_eq!(sizes[0], a.len() as u32);
        let mut want: Vec<(u32, u32)> = all
            .iter()
            .copied()
            .filter(|&(i, j)| !(i < half && j < half))
            .collect();
        let mut got = culled.clone();
        want.sort();
        got.sort();
        // Pairs inside the culled half may only disappear if their whole subtree was culled;
        // every pair with a slot outside it must remain.
        assert!(want.iter().all(|p| got.contains(p)));
        assert!(got.len() < all.len());
        for p in &got {
            assert!(all.contains(p));
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
