//! Sweep and prune along x: boxes sorted by their lower x bound; each box is tested against the
//! boxes that start before it ends. No tree to build or traverse, so on small, dense scenes (a
//! crumpled ball of a few hundred triangles, where most boxes overlap many others) it finds the
//! overlapping pairs with less work than [`super::Bvh`]; on large or spread-out meshes the
//! hierarchy wins (see [`SweepAndPrune::x_pairs`] for choosing).
//!
//! The order is a total order (lower x bound, then index), and parallel sweeps concatenate their
//! chunks in order, so the output is identical for any thread count.

use crate::geom::Aabb;
use std::cmp::Ordering;

/// Boxes sorted by lower x bound, for self-overlap queries.
#[derive(Clone, Debug, Default)]
pub struct SweepAndPrune {
    /// Primitive index of each slot (slots are in sweep order).
    order: Vec<u32>,
    /// Bounds of each slot by field (min x, max x, min y, max y, min z, max z), each padded by
    /// one slot so the two-lane loads stay in bounds. The lower x bounds (`lanes[0]`) are
    /// non-decreasing in the total order of `f64::total_cmp`.
    lanes: [Vec<f64>; 6],
}

/// Slots per parallel task of the sweep.
const CHUNK: usize = 64;

/// A `u64` whose unsigned order is the order of `f64::total_cmp`.
#[inline]
fn total_order_key(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 {
        !b
    } else {
        b | 1 << 63
    }
}

impl SweepAndPrune {
    /// Sorts `aabbs` (primitive `i` has box `aabbs[i]`) by lower x bound, ties by index.
    pub fn build(aabbs: &[Aabb]) -> Self {
        let mut keyed: Vec<(u64, u32)> = aabbs
            .iter()
            .enumerate()
            .map(|(i, b)| (total_order_key(b.min.x), i as u32))
            .collect();
        // Keys are distinct (the index breaks ties), so the order is total.
        keyed.sort_unstable();
        let order: Vec<u32> = keyed.iter().map(|k| k.1).collect();
        let field = |f: fn(&Aabb) -> f64| {
            let mut v: Vec<f64> = order.iter().map(|&i| f(&aabbs[i as usize])).collect();
            v.push(f64::NAN); // padding: never overlaps
            v
        };
        let lanes = [
            field(|b| b.min.x),
            field(|b| b.max.x),
            field(|b| b.min.y),
            field(|b| b.max.y),
            field(|b| b.min.z),
            field(|b| b.max.z),
        ];
        SweepAndPrune { order, lanes }
    }

    /// Number of primitives.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether there is no primitive.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// The primitive stored in each slot.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// How many pairs the sweep tests (pairs whose x intervals overlap): its cost, found by one
    /// binary search per box.
    pub fn x_pairs(&self) -> usize {
        let m = &self.lanes[0][..self.order.len()];
        (0..m.len())
            .map(|k| {
                let hi = self.lanes[1][k];
                // Boxes after k starting at or before k's upper bound.
                m[k + 1..].partition_point(|&x| x <= hi)
            })
            .sum()
    }

    /// The sweep's pairs whose first slot is a multiple of `stride`: `(x_pairs, overlapping)`,
    /// the pairs it tests (x intervals overlap) and those of them whose boxes overlap. Their
    /// ratio estimates how much of the sweep's work finds a pair: high on a crumpled ball, where
    /// the sweep beats the hierarchy, low on a sheet (most boxes in an x slab lie apart in y or
    /// z), where the hierarchy wins.
    pub fn sampled_pairs(&self, stride: usize) -> (usize, usize) {
        let n = self.len();
        let m = &self.lanes[0][..n];
        let (mut tested, mut found) = (0, 0);
        let mut count = Vec::new();
        for i in (0..n).step_by(stride.max(1)) {
            tested += m[i + 1..].partition_point(|&x| x <= self.lanes[1][i]);
            count.clear();
            self.sweep_range(
                None,
                i..i + 1,
                &|_, _, out: &mut Vec<()>| out.push(()),
                &mut count,
            );
            found += count.len();
        }
        (tested, found)
    }

    /// Calls `visit(i, j, out)` with *slot* indices `i < j` for every pair of boxes that overlap
    /// (as [`Aabb::overlaps`]), each pair once, and returns everything pushed to `out`, in an
    /// order independent of the number of threads.
    pub fn self_slot_pairs<T, F>(&self, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        self.pairs_impl(None, visit)
    }

    /// Like [`SweepAndPrune::self_slot_pairs`], without the pairs of two *quiet* slots
    /// (`quiet[slot]`, one entry per slot): a quiet box is swept against the boxes that are not
    /// quiet only, kept in a second, compacted copy of the bounds.
    pub fn self_slot_pairs_skipping<T, F>(&self, quiet: &[bool], visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        assert_eq!(quiet.len(), self.len(), "one flag per slot");
        self.pairs_impl(Some(Loud::new(self, quiet)), visit)
    }

    /// The sweep of [`SweepAndPrune::self_slot_pairs_skipping`] prepared to run by ranges of
    /// first slots ([`Skipping::pairs_in`]), from any number of threads.
    pub fn skipping<'a>(&'a self, quiet: &'a [bool]) -> Skipping<'a> {
        assert_eq!(quiet.len(), self.len(), "one flag per slot");
        Skipping {
            sweep: self,
            loud: Loud::new(self, quiet),
        }
    }

    /// The sweep of [`SweepAndPrune::self_slot_pairs`]; with `loud`, quiet slots scan only the
    /// loud boxes after them.
    fn pairs_impl<T, F>(&self, loud: Option<Loud>, visit: F) -> Vec<T>
    where
        T: Send,
        F: Fn(u32, u32, &mut Vec<T>) + Sync,
    {
        use rayon::prelude::*;
        let n = self.len();
        let sweep = |range: std::ops::Range<usize>, out: &mut Vec<T>| {
            self.sweep_range(loud.as_ref(), range, &visit, out)
        };
        if rayon::current_num_threads() == 1 || n <= CHUNK {
            let mut out = Vec::new();
            sweep(0..n, &mut out);
            return out;
        }
        let chunks: Vec<Vec<T>> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let mut out = Vec::new();
                sweep(c * CHUNK..((c + 1) * CHUNK).min(n), &mut out);
                out
            })
            .collect();
        let mut out = Vec::with_capacity(chunks.iter().map(Vec::len).sum());
        for c in chunks {
            out.extend(c);
        }
        out
    }

    /// The pairs whose first slot is in `range` (see [`SweepAndPrune::pairs_impl`]).
    #[inline(always)]
    fn sweep_range<T, F>(
        &self,
        loud: Option<&Loud>,
        range: std::ops::Range<usize>,
        visit: &F,
        out: &mut Vec<T>,
    ) where
        F: Fn(u32, u32, &mut Vec<T>),
    {
        let n = self.len();
        for i in range {
            let max_x = self.lanes[1][i];
            let probe = self.probe(i);
            if let Some(loud) = loud.filter(|l| l.quiet[i]) {
                // Only the loud boxes after slot i.
                let m = loud.slots.len();
                let mut k = loud.first_after[i] as usize;
                while k < m && loud.lanes[0][k].partial_cmp(&max_x) != Some(Ordering::Greater) {
                    let mut bits = overlap_pair_in(&loud.lanes, &probe, k);
                    while bits != 0 {
                        let l = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        if k + l < m {
                            visit(i as u32, loud.slots[k + l], out);
                        }
                    }
                    k += 2;
                }
                continue;
            }
            let mut j = i + 1;
            // Later boxes start no earlier: once one starts after box i ends, none of the
            // rest reaches back to it.
            // (`partial_cmp` rather than `<=`: a NaN bound does not stop the sweep.)
            while j < n && self.lanes[0][j].partial_cmp(&max_x) != Some(Ordering::Greater) {
                let mut m = self.overlap_pair(&probe, j);
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if j + l < n {
                        visit(i as u32, (j + l) as u32, out);
                    }
                }
                j += 2;
            }
        }
    }
}

/// [`SweepAndPrune::self_slot_pairs_skipping`] by ranges of first slots (see
/// [`SweepAndPrune::skipping`]).
pub struct Skipping<'a> {
    sweep: &'a SweepAndPrune,
    loud: Loud<'a>,
}

impl Skipping<'_> {
    /// Calls `visit(i, j, out)` for the pairs of [`SweepAndPrune::self_slot_pairs_skipping`]
    /// whose first slot `i` lies in `range` (clamped to the slots), in that method's order.
    /// Ranges that cover the slots between them visit every pair once.
    pub fn pairs_in<T, F>(&self, range: std::ops::Range<usize>, visit: F, out: &mut Vec<T>)
    where
        F: Fn(u32, u32, &mut Vec<T>),
    {
        let n = self.sweep.len();
        let range = range.start.min(n)..range.end.min(n);
        self.sweep.sweep_range(Some(&self.loud), range, &visit, out)
    }
}

/// The slots that are not quiet, for [`SweepAndPrune::self_slot_pairs_skipping`].
struct Loud<'a> {
    /// Per slot, whether it is quiet.
    quiet: &'a [bool],
    /// The loud slots, ascending.
    slots: Vec<u32>,
    /// Their bounds by field, as [`SweepAndPrune`]'s (padded by one slot).
    lanes: [Vec<f64>; 6],
    /// Per slot, the position in `slots` of the first loud slot after it.
    first_after: Vec<u32>,
}

impl<'a> Loud<'a> {
    fn new(s: &SweepAndPrune, quiet: &'a [bool]) -> Self {
        let slots: Vec<u32> = (0..s.len() as u32)
            .filter(|&i| !quiet[i as usize])
            .collect();
        let lanes = std::array::from_fn(|f| {
            let mut v: Vec<f64> = slots.iter().map(|&i| s.lanes[f][i as usize]).collect();
            v.push(f64::NAN);
            v
        });
        let mut first_after = Vec::with_capacity(s.len());
        let mut k = 0u32;
        for i in 0..s.len() {
            if !quiet[i] {
                k += 1; // slot i is slots[k - 1]
            }
            first_after.push(k);
        }
        Loud {
            quiet,
            slots,
            lanes,
            first_after,
        }
    }
}

/// Whether the probed box overlaps boxes `j` and `j + 1` of `lanes` (bits 0 and 1;
/// [`Aabb::overlaps`], false with the NaN padding), two lanes at a time with SSE2 (the x86-64
/// baseline).
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline(always)]
fn overlap_pair_in(lanes: &[Vec<f64>; 6], a: &Probe, j: usize) -> u8 {
    use std::arch::x86_64::*;
    assert!(j + 1 < lanes[0].len());
    // SAFETY: SSE2 is enabled at compile time; `j + 1` is within every field (asserted
    // above; the fields have one slot of padding and equal lengths).
    unsafe {
        let l = |f: usize| _mm_loadu_pd(lanes[f].as_ptr().add(j));
        let m = _mm_and_pd(
            _mm_and_pd(
                _mm_and_pd(_mm_cmple_pd(a[0], l(1)), _mm_cmple_pd(l(0), a[1])),
                _mm_and_pd(_mm_cmple_pd(a[2], l(3)), _mm_cmple_pd(l(2), a[3])),
            ),
            _mm_and_pd(_mm_cmple_pd(a[4], l(5)), _mm_cmple_pd(l(4), a[5])),
        );
        _mm_movemask_pd(m) as u8
    }
}

/// Portable version of the two-lane test above.
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
#[inline(always)]
fn overlap_pair_in(lanes: &[Vec<f64>; 6], a: &Probe, j: usize) -> u8 {
    let ov = |k: usize| {
        let f = |f: usize| lanes[f][k];
        a[0] <= f(1) && f(0) <= a[1] && a[2] <= f(3) && f(2) <= a[3] && a[4] <= f(5) && f(4) <= a[5]
    };
    ov(j) as u8 | (ov(j + 1) as u8) << 1
}

/// Box `i`'s bounds, each in both lanes, for [`SweepAndPrune::overlap_pair`].
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
type Probe = [std::arch::x86_64::__m128d; 6];
/// Box `i`'s bounds (the portable version).
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
type Probe = [f64; 6];

impl SweepAndPrune {
    /// Box `i`'s bounds prepared for [`SweepAndPrune::overlap_pair`].
    #[inline(always)]
    fn probe(&self, i: usize) -> Probe {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        {
            // SAFETY: SSE2 is enabled at compile time (the cfg above).
            std::array::from_fn(|f| unsafe { std::arch::x86_64::_mm_set1_pd(self.lanes[f][i]) })
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        {
            std::array::from_fn(|f| self.lanes[f][i])
        }
    }

    /// Whether the probed box overlaps boxes `j` and `j + 1` (bits 0 and 1; [`Aabb::overlaps`],
    /// false with the NaN padding).
    #[inline(always)]
    fn overlap_pair(&self, a: &Probe, j: usize) -> u8 {
        overlap_pair_in(&self.lanes, a, j)
    }

    /// Whether box `i` overlaps boxes `j` and `j + 1`, one box at a time with
    /// [`Aabb::overlaps`] (the reference).
    #[cfg(test)]
    fn overlap_pair_reference(&self, i: usize, j: usize) -> u8 {
        let bx = |k: usize| Aabb {
            min: crate::geom::Vec3::new(self.lanes[0][k], self.lanes[2][k], self.lanes[4][k]),
            max: crate::geom::Vec3::new(self.lanes[1][k], self.lanes[3][k], self.lanes[5][k]),
        };
        bx(i).overlaps(&bx(j)) as u8 | (bx(i).overlaps(&bx(j + 1)) as u8) << 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use crate::broad::test_boxes as boxes;

    proptest! {
        /// Exactly the overlapping pairs of a brute-force scan, also with many equal lower
        /// bounds and touching boxes (coordinates on a coarse lattice), the same with one and
        /// with two worker threads; the pair count bounds the overlaps. With quiet slots, the
        /// same pairs without those of two quiet slots.
        #[test]
        fn matches_brute_force(
            raw in proptest::collection::vec((proptest::array::uniform3(-10.0f64..10.0), proptest::array::uniform3(0.0f64..1.5)), 0..300),
            lattice in proptest::bool::ANY,
            quiet_bits in proptest::collection::vec(proptest::bool::ANY, 1..40),
        ) {
            let raw: Vec<([f64; 3], [f64; 3])> = if lattice {
                raw.iter().map(|(c, e)| (c.map(f64::round), e.map(|x| x.round()))).collect()
            } else {
                raw
            };
            let a = boxes(&raw);
            let mut want = Vec::new();
            for i in 0..a.len() {
                for j in i + 1..a.len() {
                    if a[i].overlaps(&a[j]) {
                        want.push((i as u32, j as u32));
                    }
                }
            }
            let s = SweepAndPrune::build(&a);
            let order = s.order().to_vec();
            let mut sorted = order.clone();
            sorted.sort();
            prop_assert_eq!(sorted, (0..a.len() as u32).collect::<Vec<_>>());
            let run = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| s.self_slot_pairs(|i, j, o: &mut Vec<(u32, u32)>| o.push((i, j))))
            };
            let one = run(1);
            prop_assert_eq!(&one, &run(2));
            let mut got: Vec<(u32, u32)> = one
                .iter()
                .map(|&(i, j)| {
                    let (p, q) = (order[i as usize], order[j as usize]);
                    (p.min(q), p.max(q))
                })
                .collect();
            got.sort();
            prop_assert!(s.x_pairs() >= got.len());
            // The sample of every slot is the whole sweep; a sparser one is part of it.
            prop_assert_eq!(s.sampled_pairs(1), (s.x_pairs(), got.len()));
            let (t3, f3) = s.sampled_pairs(3);
            prop_assert!(f3 <= t3 && t3 <= s.x_pairs() && f3 <= got.len());
            prop_assert_eq!(got, want);
            // Skipping the pairs of two quiet slots: exactly the other pairs, in the same
            // order for one and two threads.
            let quiet: Vec<bool> = (0..a.len()).map(|i| quiet_bits[i % quiet_bits.len()]).collect();
            let run_q = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| s.self_slot_pairs_skipping(&quiet, |i, j, o: &mut Vec<(u32, u32)>| o.push((i, j))))
            };
            let one_q = run_q(1);
            prop_assert_eq!(&one_q, &run_q(2));
            let mut got_q = one_q.clone();
            got_q.sort();
            let mut want_q: Vec<(u32, u32)> = one
                .iter()
                .copied()
                .filter(|&(i, j)| !(quiet[i as usize] && quiet[j as usize]))
                .collect();
            want_q.sort();
            prop_assert_eq!(got_q, want_q);
            prop_assert!(one_q.iter().all(|&(i, j)| i < j));
            // By ranges of first slots (of any length, past the end too): the same pairs in the
            // same order when the ranges are taken in order.
            let skipping = s.skipping(&quiet);
            let mut by_ranges = Vec::new();
            let step = 1 + quiet_bits.len() % 9;
            for start in (0..a.len() + step).step_by(step) {
                skipping.pairs_in(start..start + step, |i, j, o: &mut Vec<(u32, u32)>| o.push((i, j)), &mut by_ranges);
            }
            prop_assert_eq!(&by_ranges, &one_q);
            // The two-lane box test equals the one-box-at-a-time one (padding lane included).
            for i in 0..a.len() {
                for j in i + 1..a.len() {
                    prop_assert_eq!(s.overlap_pair(&s.probe(i), j), s.overlap_pair_reference(i, j));
                }
            }
        }
    }

    #[test]
    fn total_order_key_is_monotone() {
        let xs = [
            f64::NEG_INFINITY,
            -1e300,
            -1.0,
            -1e-300,
            -0.0,
            0.0,
            1e-300,
            1.0,
            1e300,
            f64::INFINITY,
        ];
        for w in xs.windows(2) {
            assert!(total_order_key(w[0]) < total_order_key(w[1]), "{w:?}");
        }
    }
}
