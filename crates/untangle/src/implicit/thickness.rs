//! Cloth thickness by field offsets (Buffet et al. 2019, Sec. 6.2, eq. 13).
//!
//! Fields have unit gradient near their zero set, so adding `δ` to `f_j` moves layer `j` by
//! about `δ` along its normal. Seen from layer `i`, every other active layer `j` is shifted
//! towards `i` by the thickness between their centre surfaces: half of each of the two plus the
//! full thickness of every active layer between them.

use super::operators::{FieldVec, MAX_LAYERS};

/// The offsets `f̃_j − f_j` of eq. 13 for the layer at position `me` of the active layers, whose
/// thicknesses (in order, innermost first) are `t`.
pub fn offsets(me: usize, t: &[f64]) -> FieldVec {
    let mut out = [0.0; MAX_LAYERS];
    let mut acc = 0.0;
    for j in me + 1..t.len() {
        out[j] = acc + 0.5 * t[me] + 0.5 * t[j];
        acc += t[j];
    }
    let mut acc = 0.0;
    for j in (0..me).rev() {
        out[j] = -(acc + 0.5 * t[me] + 0.5 * t[j]);
        acc += t[j];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_follow_eq13() {
        let t = [0.0, 1.0, 2.0, 4.0, 8.0];
        let o = offsets(2, &t);
        assert_eq!(
            &o[..5],
            &[
                -(1.0 + 1.0 + 0.0),
                -(1.0 + 0.5),
                0.0,
                1.0 + 2.0,
                1.0 + 4.0 + 4.0
            ]
        );
        // Brute force: the distance between centre surfaces of layers me and j is the sum of the
        // half thicknesses of the ends plus everything strictly between.
        for me in 0..5 {
            let o = offsets(me, &t);
            for j in 0..5 {
                let (a, b) = (me.min(j), me.max(j));
                let expect: f64 = if a == b {
                    0.0
                } else {
                    (a..=b)
                        .map(|k| if k == a || k == b { t[k] / 2.0 } else { t[k] })
                        .sum()
                };
                assert_eq!(o[j].abs(), expect);
                assert!(j <= me || o[j] >= 0.0);
                assert!(j >= me || o[j] <= 0.0);
            }
        }
    }
}
