//! Shared-vertex keys: up to [`KEYS`] vertex indices per primitive (a vertex, an edge's two
//! ends, a triangle's corners), so that the traversals drop the pairs of primitives that share a
//! vertex at the leaves, a leaf's primitives against another leaf's at once, instead of handing
//! every such pair to the caller. On a cloth mesh most overlapping edge pairs are neighbours
//! (they always overlap), so most pairs a traversal finds are dropped this way.
//!
//! The keys of a leaf of at most [`BLOCK`] primitives are kept as [`KEYS`] rows of [`BLOCK`]
//! lanes (like the boxes of [`super::lanes`]); a primitive with fewer keys repeats its first one
//! in the rows after its last (a repeated key changes no "any key equal" test). The tests give a
//! bit matrix laid out as the box tests' (bit `BLOCK * i + j` for primitive `i` of the first
//! leaf and `j` of the second). [`without_shared`] is the plain reference; the leaf tests of
//! [`super::lanes`] compare eight keys per AVX2 instruction inside their row loops.

use super::lanes::BLOCK;

/// Most keys per primitive.
pub const KEYS: usize = 3;

/// The keys of one primitive, padded to [`KEYS`] by repeating its first key.
pub type Keys = [u32; KEYS];

/// The keys `k` (1 to [`KEYS`] of them) padded to [`KEYS`].
#[inline]
pub fn padded(k: &[u32]) -> Keys {
    assert!(!k.is_empty() && k.len() <= KEYS, "1 to KEYS keys");
    std::array::from_fn(|r| if r < k.len() { k[r] } else { k[0] })
}

/// Whether two primitives share a key.
#[inline(always)]
pub fn share(a: &Keys, b: &Keys) -> bool {
    a.iter().any(|k| b.contains(k))
}

/// The keys of up to [`BLOCK`] primitives as [`KEYS`] rows of [`BLOCK`] lanes (row `r`, lane
/// `i`: key `r` of primitive `i`; lanes after the last primitive hold `u32::MAX`, and the
/// callers only ask about bits of real primitives).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct KeyBlock {
    k: [[u32; BLOCK]; KEYS],
}

impl KeyBlock {
    /// The block of `keys` (at most [`BLOCK`]), primitive `i` in lane `i`.
    pub fn new(keys: &[Keys]) -> KeyBlock {
        assert!(keys.len() <= BLOCK, "at most BLOCK primitives");
        let mut k = [[u32::MAX; BLOCK]; KEYS];
        for (i, key) in keys.iter().enumerate() {
            for r in 0..KEYS {
                k[r][i] = key[r];
            }
        }
        KeyBlock { k }
    }

    /// Key row `r` (key `r` of every lane).
    #[inline(always)]
    pub(super) fn row(&self, r: usize) -> &[u32; BLOCK] {
        &self.k[r]
    }

    /// Primitive `i`'s keys.
    #[inline(always)]
    fn keys(&self, i: usize) -> Keys {
        std::array::from_fn(|r| self.k[r][i])
    }
}

/// The bits of `bits` (a bit matrix between the primitives of `a` and those of `b`, as the
/// block box tests give it) whose two primitives share no key: the pairs a traversal reports.
/// Only the rows of `a` with a bit set in `bits` are compared. The reference of the leaf tests
/// that compare keys in lanes (`super::lanes::cross_block_keyed`, `self_block_keyed`) and their
/// version for CPUs without AVX2. `ka` and `kb` (the numbers of keys the primitives were given)
/// are not needed here: the rows after them repeat the first key.
pub fn without_shared(bits: u64, a: &KeyBlock, ka: usize, b: &KeyBlock, kb: usize) -> u64 {
    debug_assert!(ka <= KEYS && kb <= KEYS);
    let mut out = bits;
    let mut rest = bits;
    while rest != 0 {
        let i = rest.trailing_zeros() as usize / BLOCK;
        rest &= !(ROW << (BLOCK * i));
        let keys = a.keys(i);
        for j in 0..BLOCK {
            if share(&keys, &b.keys(j)) {
                out &= !(1 << (BLOCK * i + j));
            }
        }
    }
    out
}

/// The eight bits of row `i` of a bit matrix.
const ROW: u64 = (1 << BLOCK) - 1;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// The block test clears exactly the bits
        /// of the pairs that share a key (brute force over the unpadded keys), and only those
        /// of `bits`; keys drawn from a small range so that sharing is frequent.
        #[test]
        fn drops_exactly_the_pairs_sharing_a_key(
            ka in proptest::collection::vec(proptest::collection::vec(0u32..12, 1..=KEYS), 0..=BLOCK),
            kb in proptest::collection::vec(proptest::collection::vec(0u32..12, 1..=KEYS), 0..=BLOCK),
            bits in any::<u64>(),
        ) {
            let pa: Vec<Keys> = ka.iter().map(|k| padded(k)).collect();
            let pb: Vec<Keys> = kb.iter().map(|k| padded(k)).collect();
            let (a, b) = (KeyBlock::new(&pa), KeyBlock::new(&pb));
            // Only bits of real primitives, as the box tests give.
            let mut real = 0u64;
            for i in 0..ka.len() {
                for j in 0..kb.len() {
                    real |= 1 << (BLOCK * i + j);
                }
            }
            let bits = bits & real;
            let mut want = 0u64;
            for (i, x) in ka.iter().enumerate() {
                for (j, y) in kb.iter().enumerate() {
                    let shared = x.iter().any(|k| y.contains(k));
                    if bits >> (BLOCK * i + j) & 1 == 1 && !shared {
                        want |= 1 << (BLOCK * i + j);
                    }
                }
            }
            // With the rows the keys fill (the most keys of either side), and with all of them.
            let ka_rows = ka.iter().map(|k| k.len()).max().unwrap_or(1);
            let kb_rows = kb.iter().map(|k| k.len()).max().unwrap_or(1);
            prop_assert_eq!(without_shared(bits, &a, ka_rows, &b, kb_rows), want);
            prop_assert_eq!(without_shared(bits, &a, KEYS, &b, KEYS), want);
        }
    }

    #[test]
    fn padding_repeats_the_first_key() {
        assert_eq!(padded(&[7]), [7, 7, 7]);
        assert_eq!(padded(&[7, 9]), [7, 9, 7]);
        assert_eq!(padded(&[1, 2, 3]), [1, 2, 3]);
        assert!(share(&padded(&[4, 5]), &padded(&[5])));
        assert!(!share(&padded(&[4, 5]), &padded(&[6, 7, 8])));
    }
}
