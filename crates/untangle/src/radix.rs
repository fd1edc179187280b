//! Stable LSD radix sort on 64-bit keys, for the large integer sorts of the analysis (Morton
//! codes, crossings, triangle-pair keys): linear time, and the order of equal keys is the input
//! order, so results are deterministic.

/// Sorts `v` by `key`, stably.
pub fn sort_by_key<T: Copy + Default>(v: &mut Vec<T>, key: impl Fn(&T) -> u64) {
    if v.len() < 64 {
        v.sort_by_key(|x| key(x)); // stable
        return;
    }
    // Keys below 2^32 (packed pairs of indices) need at most four byte histograms.
    let small = v.iter().all(|x| key(x) >> 32 == 0);
    let counts = if small {
        histograms::<T, 4>(v, &key)
    } else {
        histograms::<T, 8>(v, &key)
    };
    let n = v.len();
    let mut tmp = vec![T::default(); n];
    for (pass, count) in counts.iter().enumerate() {
        if count.contains(&n) {
            continue;
        }
        let shift = 8 * pass;
        let mut start = [0usize; 256];
        let mut sum = 0;
        for (s, &c) in start.iter_mut().zip(count.iter()) {
            *s = sum;
            sum += c;
        }
        for x in v.iter() {
            let b = ((key(x) >> shift) & 0xff) as usize;
            tmp[start[b]] = *x;
            start[b] += 1;
        }
        std::mem::swap(v, &mut tmp);
    }
}

/// Sorts `v` stably by `(bucket(x), key(x))`, where `bucket(x) < buckets` and
/// `key(x) < keys`: two stable counting sorts (by key, then by bucket), linear in
/// `v.len() + buckets + keys`. Falls back to [`sort_by_key`] on `bucket * 2^32 + key` when the
/// ranges are much larger than `v` (the histograms would dominate).
pub fn sort_by_bucket_then_key<T: Copy + Default>(
    v: &mut Vec<T>,
    (buckets, keys): (usize, usize),
    bucket: impl Fn(&T) -> u32,
    key: impl Fn(&T) -> u32,
) {
    if v.len() < 64 || buckets + keys > 8 * v.len() {
        sort_by_key(v, |x| ((bucket(x) as u64) << 32) | key(x) as u64);
        return;
    }
    let tmp = counting_sorted(v, keys, &key);
    counting_sort(&tmp, v, buckets, &bucket);
}

/// A vector of `n` elements, each written once by `fill` (no zeroing first: the large scatter
/// buffers of the counting sorts are otherwise filled twice).
///
/// # Safety
/// `fill` must initialise every one of the `n` elements of the slice it is given.
#[inline(always)]
pub(crate) unsafe fn written_once<T: Copy>(
    n: usize,
    fill: impl FnOnce(&mut [std::mem::MaybeUninit<T>]),
) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    fill(&mut v.spare_capacity_mut()[..n]);
    // SAFETY: the caller guarantees that `fill` initialised all `n` elements.
    unsafe { v.set_len(n) };
    v
}

/// Stable counting sort of `from` by `digit(x) < range` into a new vector.
fn counting_sorted<T: Copy>(from: &[T], range: usize, digit: &impl Fn(&T) -> u32) -> Vec<T> {
    let mut start = vec![0u32; range + 1];
    for x in from {
        start[digit(x) as usize + 1] += 1;
    }
    for i in 1..=range {
        start[i] += start[i - 1];
    }
    // SAFETY: bucket `d` receives exactly its count of elements at the consecutive positions
    // from its start, so the positions written are exactly `0..from.len()`, each once.
    unsafe {
        written_once(from.len(), |to| {
            for x in from {
                let d = digit(x) as usize;
                to[start[d] as usize].write(*x);
                start[d] += 1;
            }
        })
    }
}

/// Stable counting sort of `from` into `to` by `digit(x) < range`.
fn counting_sort<T: Copy>(from: &[T], to: &mut [T], range: usize, digit: &impl Fn(&T) -> u32) {
    let mut start = vec![0u32; range + 1];
    for x in from {
        start[digit(x) as usize + 1] += 1;
    }
    for i in 1..=range {
        start[i] += start[i - 1];
    }
    for x in from {
        let d = digit(x) as usize;
        to[start[d] as usize] = *x;
        start[d] += 1;
    }
}

/// Histograms of the low `B` key bytes, in one read pass (fixed `B`: the loop unrolls).
fn histograms<T, const B: usize>(v: &[T], key: &impl Fn(&T) -> u64) -> Vec<[usize; 256]> {
    let mut counts = [[0usize; 256]; B];
    for x in v {
        let k = key(x);
        for (b, c) in counts.iter_mut().enumerate() {
            c[((k >> (8 * b)) & 0xff) as usize] += 1;
        }
    }
    counts.to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn matches_a_stable_comparison_sort(keys in proptest::collection::vec(proptest::num::u64::ANY, 0..600), modulus in 1u64..u64::MAX, shift in 0u32..64) {
            let mut v: Vec<(u64, u32)> = keys.iter().enumerate().map(|(i, &k)| ((k % modulus) << shift, i as u32)).collect();
            let mut w = v.clone();
            sort_by_key(&mut v, |x| x.0);
            w.sort_by_key(|x| x.0);
            prop_assert_eq!(v, w);
        }

        #[test]
        fn bucket_sort_matches_a_stable_comparison_sort(
            keys in proptest::collection::vec((0u32..50, 0u32..40), 0..700),
            buckets in 50usize..3000,
            key_range in 40usize..3000,
        ) {
            let mut v: Vec<(u32, u32, u32)> = keys.iter().enumerate().map(|(i, &(b, k))| (b, k, i as u32)).collect();
            let mut w = v.clone();
            sort_by_bucket_then_key(&mut v, (buckets, key_range), |x| x.0, |x| x.1);
            w.sort_by_key(|x| (x.0, x.1));
            prop_assert_eq!(v, w);
        }
    }
}
