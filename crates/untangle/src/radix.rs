//! Stable LSD radix sort on 64-bit keys, for the large integer sorts of the analysis (Morton
//! codes, crossings, triangle-pair keys): linear time, and the order of equal keys is the input
//! order, so results are deterministic.

/// Sorts `v` by `key`, stably.
pub fn sort_by_key<T: Copy + Default>(v: &mut Vec<T>, key: impl Fn(&T) -> u64) {
    if v.len() < 64 {
        v.sort_by_key(|x| key(x)); // stable
        return;
    }
    let max = v.iter().map(&key).max().unwrap_or(0);
    let passes = (64 - max.leading_zeros()).div_ceil(8);
    let mut tmp = vec![T::default(); v.len()];
    for pass in 0..passes {
        let shift = 8 * pass;
        let mut count = [0usize; 257];
        for x in v.iter() {
            count[((key(x) >> shift) & 0xff) as usize + 1] += 1;
        }
        for k in 0..256 {
            count[k + 1] += count[k];
        }
        for x in v.iter() {
            let b = ((key(x) >> shift) & 0xff) as usize;
            tmp[count[b]] = *x;
            count[b] += 1;
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
        fn matches_a_stable_comparison_sort(keys in proptest::collection::vec(proptest::num::u64::ANY, 0..600), modulus in 1u64..1000) {
            let mut v: Vec<(u64, u32)> = keys.iter().enumerate().map(|(i, &k)| (k % modulus, i as u32)).collect();
            let mut w = v.clone();
            sort_by_key(&mut v, |x| x.0);
            w.sort_by_key(|x| x.0);
            prop_assert_eq!(v, w);
        }
    }
}
