//! Boxes in lanes: the boxes of a hierarchy's leaf as six coordinate rows of [`BLOCK`] lanes (a
//! structure of arrays, aligned for vector loads), and the leaf-level overlap tests on them, a
//! leaf's boxes against another leaf's at once. With AVX2 (checked at run time) four boxes are
//! compared per instruction, in double precision with the comparisons of [`Aabb::overlaps`]
//! (`<=`, false with a NaN), so every CPU gets the same bits and the traversals the same pairs;
//! the plain version is the fallback and the reference.
//!
//! A block test returns a bit matrix, bit `BLOCK * i + j` for box `i` of the first block and box
//! `j` of the second, so that visiting the set bits in increasing order visits the pairs in
//! slot order of the first block, then of the second (the order of the traversals' plain loops).

use super::keys::{self, KeyBlock};
use crate::geom::Aabb;

/// Key blocks of the two sides of a block test and their numbers of keys per primitive (see
/// [`keys::without_shared`]).
pub type KeyPair<'a> = (&'a KeyBlock, usize, &'a KeyBlock, usize);

/// Most boxes in a block (the collision hierarchies' leaf size).
pub const BLOCK: usize = 8;

/// Up to [`BLOCK`] boxes as six coordinate rows: minimum x, maximum x, minimum y, maximum y,
/// minimum z, maximum z; the lanes after the last box hold NaN (they compare false, and the
/// tests mask them off as well).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Block {
    f: [[f64; BLOCK]; 6],
}

impl Block {
    /// The block of `boxes` (at most [`BLOCK`]), box `i` in lane `i`.
    pub fn new(boxes: &[Aabb]) -> Block {
        assert!(boxes.len() <= BLOCK, "at most BLOCK boxes");
        let mut block = Block {
            f: [[f64::NAN; BLOCK]; 6],
        };
        block.set(boxes);
        block
    }

    /// Stores `boxes` (at most [`BLOCK`]) in lanes `0..boxes.len()`; the other lanes keep their
    /// values (a refit of a leaf: the same number of boxes, the padding stays NaN).
    #[inline]
    pub fn set(&mut self, boxes: &[Aabb]) {
        for (i, b) in boxes.iter().take(BLOCK).enumerate() {
            self.f[0][i] = b.min.x;
            self.f[1][i] = b.max.x;
            self.f[2][i] = b.min.y;
            self.f[3][i] = b.max.y;
            self.f[4][i] = b.min.z;
            self.f[5][i] = b.max.z;
        }
    }

    /// Box `i`'s six bounds in lane order.
    #[inline(always)]
    fn bounds(&self, i: usize) -> [f64; 6] {
        std::array::from_fn(|k| self.f[k][i])
    }
}

/// A box's bounds in lane order.
#[inline(always)]
fn bounds_of(b: &Aabb) -> [f64; 6] {
    [b.min.x, b.max.x, b.min.y, b.max.y, b.min.z, b.max.z]
}

/// [`Aabb::overlaps`] on bounds in lane order (all six comparisons, no short circuit).
#[inline(always)]
fn overlap(a: &[f64; 6], b: &[f64; 6]) -> bool {
    (a[0] <= b[1])
        & (b[0] <= a[1])
        & (a[2] <= b[3])
        & (b[2] <= a[3])
        & (a[4] <= b[5])
        & (b[4] <= a[5])
}

/// Whether the CPU has AVX2 (the standard library caches the answer).
#[inline(always)]
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The overlapping pairs between the first `na` boxes of `a` and the first `nb` of `b`: bit
/// `BLOCK * i + j` when box `i` of `a` overlaps box `j` of `b`. `cull` must contain every box of
/// `b`'s (e.g. their union): a box of `a` apart from it is skipped without testing (it overlaps
/// none of them).
#[inline]
pub fn cross_block(a: &Block, na: usize, cull: &Aabb, b: &Block, nb: usize) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { avx::cross_block(a, na, cull, b, nb) };
    }
    cross_block_plain(a, na, cull, b, nb)
}

/// [`cross_block`] without the pairs whose primitives share a key (`keys`: the key blocks of
/// `a` and `b`): the same bits as [`keys::without_shared`] of [`cross_block`]'s, with the keys
/// compared inside the row loop, for the rows with an overlap only.
#[inline]
pub fn cross_block_keyed(
    a: &Block,
    na: usize,
    cull: &Aabb,
    b: &Block,
    nb: usize,
    keys: KeyPair<'_>,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        let (ka, kb) = (keys.0, keys.2);
        // SAFETY: the CPU has AVX2.
        return unsafe {
            match (keys.1, keys.3) {
                (2, 2) => avx::cross_block_keyed::<2, 2>(a, na, cull, b, nb, ka, kb),
                (1, 3) => avx::cross_block_keyed::<1, 3>(a, na, cull, b, nb, ka, kb),
                (3, 1) => avx::cross_block_keyed::<3, 1>(a, na, cull, b, nb, ka, kb),
                (1, 1) => avx::cross_block_keyed::<1, 1>(a, na, cull, b, nb, ka, kb),
                _ => avx::cross_block_keyed::<{ keys::KEYS }, { keys::KEYS }>(
                    a, na, cull, b, nb, ka, kb,
                ),
            }
        };
    }
    let bits = cross_block_plain(a, na, cull, b, nb);
    keys::without_shared(bits, keys.0, keys.1, keys.2, keys.3)
}

/// [`self_block`] without the pairs whose primitives share a key (`keys`, `count`: the block's
/// key block and keys per primitive), as [`cross_block_keyed`].
#[inline]
pub fn self_block_keyed(a: &Block, n: usize, keys: &KeyBlock, count: usize) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe {
            match count {
                1 => avx::self_block_keyed::<1>(a, n, keys),
                2 => avx::self_block_keyed::<2>(a, n, keys),
                _ => avx::self_block_keyed::<{ keys::KEYS }>(a, n, keys),
            }
        };
    }
    keys::without_shared(self_block_plain(a, n), keys, count, keys, count)
}

/// The overlapping pairs among the first `n` boxes of `a`: bit `BLOCK * i + j` for `i < j` when
/// box `i` overlaps box `j`.
#[inline]
pub fn self_block(a: &Block, n: usize) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { avx::self_block(a, n) };
    }
    self_block_plain(a, n)
}

/// Which of the first `nb` boxes of `b` overlap `q`: bit `j` for box `j`.
#[inline]
pub fn row_block(q: &Aabb, b: &Block, nb: usize) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { avx::row_block(q, b, nb) };
    }
    row_block_plain(q, b, nb)
}

/// Bits `0..n` (`n` at most [`BLOCK`]; more count as [`BLOCK`]).
#[inline(always)]
fn mask(n: usize) -> u64 {
    (1u64 << n.min(BLOCK)) - 1
}

/// [`cross_block`] one pair at a time.
fn cross_block_plain(a: &Block, na: usize, cull: &Aabb, b: &Block, nb: usize) -> u64 {
    let c = bounds_of(cull);
    let mut out = 0;
    for i in 0..na.min(BLOCK) {
        let bi = a.bounds(i);
        if !overlap(&bi, &c) {
            continue;
        }
        for j in 0..nb.min(BLOCK) {
            if overlap(&bi, &b.bounds(j)) {
                out |= 1 << (BLOCK * i + j);
            }
        }
    }
    out
}

/// [`self_block`] one pair at a time.
fn self_block_plain(a: &Block, n: usize) -> u64 {
    let n = n.min(BLOCK);
    let mut out = 0;
    for i in 0..n {
        let bi = a.bounds(i);
        for j in i + 1..n {
            if overlap(&bi, &a.bounds(j)) {
                out |= 1 << (BLOCK * i + j);
            }
        }
    }
    out
}

/// [`row_block`] one box at a time.
fn row_block_plain(q: &Aabb, b: &Block, nb: usize) -> u64 {
    let q = bounds_of(q);
    (0..nb.min(BLOCK)).fold(0, |m, j| m | (overlap(&q, &b.bounds(j)) as u64) << j)
}

#[cfg(target_arch = "x86_64")]
mod avx {
    //! The block tests with AVX2: four boxes of a block per instruction (two registers per
    //! coordinate row), against one box broadcast to every lane.
    use super::{bounds_of, mask, Block, KeyBlock, BLOCK};
    use crate::geom::Aabb;
    use std::arch::x86_64::*;

    /// Bounds of four boxes (lane order), or of one box in every lane.
    type Four = [__m256d; 6];

    /// Boxes `h * 4..h * 4 + 4` of `a` (`h` is 0 or 1).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn half(a: &Block, h: usize) -> Four {
        let r = |k: usize| {
            let row: &[f64; 4] = a.f[k][4 * h..4 * h + 4].try_into().expect("four lanes");
            // SAFETY: `row` holds four doubles, 32-byte aligned (the block is 64-byte aligned
            // and rows and halves are multiples of 32 bytes).
            unsafe { _mm256_load_pd(row.as_ptr()) }
        };
        [r(0), r(1), r(2), r(3), r(4), r(5)]
    }

    /// One box in every lane.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn splat(b: &[f64; 6]) -> Four {
        [
            _mm256_set1_pd(b[0]),
            _mm256_set1_pd(b[1]),
            _mm256_set1_pd(b[2]),
            _mm256_set1_pd(b[3]),
            _mm256_set1_pd(b[4]),
            _mm256_set1_pd(b[5]),
        ]
    }

    /// Bit `l` when box `l` of `x` overlaps box `l` of `y` (the six comparisons of
    /// [`Aabb::overlaps`], ordered and quiet: false with a NaN).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn overlaps(x: &Four, y: &Four) -> u64 {
        let m = _mm256_and_pd(
            _mm256_and_pd(
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_LE_OQ>(x[0], y[1]),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(y[0], x[1]),
                ),
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_LE_OQ>(x[2], y[3]),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(y[2], x[3]),
                ),
            ),
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_LE_OQ>(x[4], y[5]),
                _mm256_cmp_pd::<_CMP_LE_OQ>(y[4], x[5]),
            ),
        );
        _mm256_movemask_pd(m) as u64
    }

    /// Which boxes of `a` overlap `r`: bit `j` for box `j` (all eight lanes).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn row(a: &Block, r: &Four) -> u64 {
        overlaps(&half(a, 0), r) | overlaps(&half(a, 1), r) << 4
    }

    /// [`super::cross_block`] (AVX2 required).
    #[target_feature(enable = "avx2")]
    pub(super) fn cross_block(a: &Block, na: usize, cull: &Aabb, b: &Block, nb: usize) -> u64 {
        let mut rows = row(a, &splat(&bounds_of(cull))) & mask(na);
        let cols = mask(nb);
        let mut out = 0;
        while rows != 0 {
            let i = rows.trailing_zeros() as usize;
            rows &= rows - 1;
            out |= (row(b, &splat(&a.bounds(i))) & cols) << (BLOCK * i);
        }
        out
    }

    /// The `KB` key rows of `k`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn key_rows<const KB: usize>(k: &KeyBlock) -> [__m256i; KB] {
        // SAFETY: each row is eight `u32`s, 32-byte aligned (the block is, and rows are 32
        // bytes long).
        std::array::from_fn(|r| unsafe { _mm256_load_si256(k.row(r).as_ptr().cast()) })
    }

    /// Bit `j` when one of the first `KA` keys of primitive `i` of `ka` equals one of `rows`'.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn shared<const KA: usize, const KB: usize>(
        ka: &KeyBlock,
        i: usize,
        rows: &[__m256i; KB],
    ) -> u64 {
        let mut eq = _mm256_setzero_si256();
        for r in 0..KA {
            let key = _mm256_set1_epi32(ka.row(r)[i] as i32);
            for row in rows {
                eq = _mm256_or_si256(eq, _mm256_cmpeq_epi32(key, *row));
            }
        }
        _mm256_movemask_ps(_mm256_castsi256_ps(eq)) as u32 as u64
    }

    /// [`super::cross_block_keyed`] with `KA` and `KB` keys per primitive (AVX2 required).
    #[target_feature(enable = "avx2")]
    pub(super) fn cross_block_keyed<const KA: usize, const KB: usize>(
        a: &Block,
        na: usize,
        cull: &Aabb,
        b: &Block,
        nb: usize,
        ka: &KeyBlock,
        kb: &KeyBlock,
    ) -> u64 {
        let mut rows = row(a, &splat(&bounds_of(cull))) & mask(na);
        let cols = mask(nb);
        let keys = key_rows::<KB>(kb);
        let mut out = 0;
        while rows != 0 {
            let i = rows.trailing_zeros() as usize;
            rows &= rows - 1;
            let hit = row(b, &splat(&a.bounds(i))) & cols;
            if hit != 0 {
                out |= (hit & !shared::<KA, KB>(ka, i, &keys)) << (BLOCK * i);
            }
        }
        out
    }

    /// [`super::self_block_keyed`] with `K` keys per primitive (AVX2 required).
    #[target_feature(enable = "avx2")]
    pub(super) fn self_block_keyed<const K: usize>(a: &Block, n: usize, k: &KeyBlock) -> u64 {
        let n = n.min(BLOCK);
        let keys = key_rows::<K>(k);
        let mut out = 0;
        for i in 0..n.saturating_sub(1) {
            let later = mask(n) & !mask(i + 1);
            let hit = row(a, &splat(&a.bounds(i))) & later;
            if hit != 0 {
                out |= (hit & !shared::<K, K>(k, i, &keys)) << (BLOCK * i);
            }
        }
        out
    }

    /// [`super::self_block`] (AVX2 required).
    #[target_feature(enable = "avx2")]
    pub(super) fn self_block(a: &Block, n: usize) -> u64 {
        let n = n.min(BLOCK);
        let mut out = 0;
        for i in 0..n.saturating_sub(1) {
            // Boxes after `i` only.
            let later = mask(n) & !mask(i + 1);
            out |= (row(a, &splat(&a.bounds(i))) & later) << (BLOCK * i);
        }
        out
    }

    /// [`super::row_block`] (AVX2 required).
    #[target_feature(enable = "avx2")]
    pub(super) fn row_block(q: &Aabb, b: &Block, nb: usize) -> u64 {
        row(b, &splat(&bounds_of(q))) & mask(nb)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use proptest::prelude::*;

    /// Coordinates that make touching boxes (shared bounds), signed zeros, infinities and huge
    /// and tiny magnitudes likely.
    fn coord() -> impl Strategy<Value = f64> {
        prop_oneof![
            (-4i32..4).prop_map(|k| k as f64 * 0.5),
            Just(-0.0),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(f64::MAX),
            Just(f64::MIN),
            Just(f64::MIN_POSITIVE),
            Just(-f64::MIN_POSITIVE),
            Just(5e-324),
            (-1e300f64..1e300),
            (-1e-300f64..1e-300),
            (-10.0f64..10.0),
        ]
    }

    /// A box from two random corners (sorted per axis, so it may be flat; sometimes left
    /// unsorted, an empty box).
    fn a_box() -> impl Strategy<Value = Aabb> {
        (proptest::array::uniform6(coord()), any::<u8>()).prop_map(|(c, sort)| {
            let s = |lo: f64, hi: f64| {
                if sort % 8 != 0 && lo > hi {
                    (hi, lo)
                } else {
                    (lo, hi)
                }
            };
            let (x0, x1) = s(c[0], c[1]);
            let (y0, y1) = s(c[2], c[3]);
            let (z0, z1) = s(c[4], c[5]);
            Aabb {
                min: Vec3::new(x0, y0, z0),
                max: Vec3::new(x1, y1, z1),
            }
        })
    }

    /// A refit's `set` replaces the boxes the block tests see; the lanes after them stay empty.
    #[test]
    fn set_replaces_the_boxes() {
        let unit = |x: f64| Aabb {
            min: Vec3::new(x, 0.0, 0.0),
            max: Vec3::new(x + 1.0, 1.0, 1.0),
        };
        let everything = Aabb {
            min: Vec3::repeat(f64::NEG_INFINITY),
            max: Vec3::repeat(f64::INFINITY),
        };
        let mut a = Block::new(&[unit(0.0), unit(5.0), unit(10.0)]);
        assert_eq!(row_block(&unit(5.5), &a, 3), 0b010);
        a.set(&[unit(5.2), unit(0.0), unit(10.0)]);
        assert_eq!(row_block(&unit(5.5), &a, 3), 0b001);
        assert_eq!(row_block(&everything, &a, BLOCK), 0b111);
        assert_eq!(row_block_plain(&everything, &a, BLOCK), 0b111);
    }

    /// Bit matrix of a block test by [`Aabb::overlaps`] (the oracle).
    fn brute(a: &[Aabb], b: &[Aabb], upper: bool) -> u64 {
        let mut out = 0;
        for (i, x) in a.iter().enumerate() {
            for (j, y) in b.iter().enumerate() {
                if (!upper || j > i) && x.overlaps(y) {
                    out |= 1 << (BLOCK * i + j);
                }
            }
        }
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// Every block test (with AVX2 when the CPU has it, and the plain version) gives exactly
        /// the pairs of [`Aabb::overlaps`], for blocks of 0-8 boxes, with a cull box that
        /// contains the second block or is that block's union.
        #[test]
        fn block_tests_are_the_exact_overlaps(
            xa in proptest::collection::vec(a_box(), 0..=BLOCK),
            xb in proptest::collection::vec(a_box(), 0..=BLOCK),
            wide_cull in any::<bool>(),
        ) {
            let (a, b) = (Block::new(&xa), Block::new(&xb));
            let (na, nb) = (xa.len(), xb.len());
            let cull = if wide_cull {
                Aabb {
                    min: Vec3::repeat(f64::NEG_INFINITY),
                    max: Vec3::repeat(f64::INFINITY),
                }
            } else {
                xb.iter().fold(Aabb::EMPTY, |u, x| u.union(x))
            };
            let want = brute(&xa, &xb, false);
            prop_assert_eq!(cross_block(&a, na, &cull, &b, nb), want);
            prop_assert_eq!(cross_block_plain(&a, na, &cull, &b, nb), want);
            let want = brute(&xa, &xa, true);
            prop_assert_eq!(self_block(&a, na), want);
            prop_assert_eq!(self_block_plain(&a, na), want);
            // The keyed tests drop exactly the pairs sharing a key (keys from a small range, so
            // that sharing is frequent; one to three keys per primitive).
            let keyed = |x: &[Aabb], salt: u64| -> (KeyBlock, usize, Vec<keys::Keys>) {
                let count = 1 + (salt % 3) as usize;
                let ks: Vec<keys::Keys> = (0..x.len() as u64)
                    .map(|i| {
                        let k: Vec<u32> = (0..count as u64)
                            .map(|r| ((i * 7 + r * 5 + salt) % 11) as u32)
                            .collect();
                        keys::padded(&k)
                    })
                    .collect();
                (KeyBlock::new(&ks), count, ks)
            };
            let drop_shared = |bits: u64, ka: &[keys::Keys], kb: &[keys::Keys]| {
                let mut out = bits;
                for (i, x) in ka.iter().enumerate() {
                    for (j, y) in kb.iter().enumerate() {
                        if keys::share(x, y) {
                            out &= !(1 << (BLOCK * i + j));
                        }
                    }
                }
                out
            };
            let (kab, ca, ka) = keyed(&xa, na as u64);
            let (kbb, cb, kb) = keyed(&xb, 7 + nb as u64);
            let want = drop_shared(brute(&xa, &xb, false), &ka, &kb);
            prop_assert_eq!(cross_block_keyed(&a, na, &cull, &b, nb, (&kab, ca, &kbb, cb)), want);
            let want = drop_shared(brute(&xa, &xa, true), &ka, &ka);
            prop_assert_eq!(self_block_keyed(&a, na, &kab, ca), want);
            for q in xa.iter().take(4) {
                let want = brute(std::slice::from_ref(q), &xb, false);
                prop_assert_eq!(row_block(q, &b, nb), want);
                prop_assert_eq!(row_block_plain(q, &b, nb), want);
            }
        }
    }
}
