//! Stable LSD radix sort on 64-bit keys, for the large integer sorts of the analysis (Morton
//! codes, crossings, triangle-pair keys): linear time, and the order of equal keys is the input
//! order, so results are deterministic.

/// Sorts `v` by `key`, stably.
pub fn sort_by_key<T: Copy + Default>(v: &mut Vec<T>, key: impl Fn(&T) -> u64) {
    if v.len() < 64 {
        v.sort_by_key(|x| key(x)); // stable
        return;
    }
    // One read pass builds the histograms of all eight key bytes; a byte that is the same for
    // every element (e.g. the unused high bits of a packed key) needs no pass.
    let mut counts = vec![[0usize; 256]; 8];
    for x in v.iter() {
        let k = key(x);
        for (b, c) in counts.iter_mut().enumerate() {
            c[((k >> (8 * b)) & 0xff) as usize] += 1;
        }
    }
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
    }
}
