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

/// Sorts `v` stably by `(bucket(x), key(x))`, where `bucket(x) < buckets`: a counting sort by
/// bucket, then a stable sort of each bucket by key (insertion sort for the small buckets of
/// sparse pair keys). Falls back to [`sort_by_key`] on `bucket * 2^32 + key` when there are many
/// more buckets than elements (the histogram would dominate).
pub fn sort_by_bucket_then_key<T: Copy + Default>(
    v: &mut Vec<T>,
    buckets: usize,
    bucket: impl Fn(&T) -> u32,
    key: impl Fn(&T) -> u32,
) {
    if v.len() < 64 || buckets > 4 * v.len() {
        sort_by_key(v, |x| ((bucket(x) as u64) << 32) | key(x) as u64);
        return;
    }
    let mut start = vec![0u32; buckets + 1];
    for x in v.iter() {
        start[bucket(x) as usize + 1] += 1;
    }
    for i in 1..=buckets {
        start[i] += start[i - 1];
    }
    let mut tmp = vec![T::default(); v.len()];
    let mut fill = start.clone();
    for x in v.iter() {
        let b = bucket(x) as usize;
        tmp[fill[b] as usize] = *x;
        fill[b] += 1;
    }
    for b in 0..buckets {
        let r = &mut tmp[start[b] as usize..start[b + 1] as usize];
        if r.len() <= 24 {
            // Stable insertion sort.
            for i in 1..r.len() {
                let x = r[i];
                let k = key(&x);
                let mut j = i;
                while j > 0 && key(&r[j - 1]) > k {
                    r[j] = r[j - 1];
                    j -= 1;
                }
                r[j] = x;
            }
        } else {
            r.sort_by_key(|x| key(x)); // stable
        }
    }
    *v = tmp;
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
        ) {
            let mut v: Vec<(u32, u32, u32)> = keys.iter().enumerate().map(|(i, &(b, k))| (b, k, i as u32)).collect();
            let mut w = v.clone();
            sort_by_bucket_then_key(&mut v, buckets, |x| x.0, |x| x.1);
            w.sort_by_key(|x| (x.0, x.1));
            prop_assert_eq!(v, w);
        }
    }
}
