//! Cloth thickness by field offsets (Buffet et al. 2019, Sec. 6.2, eq. 13).
//!
//! Fields have unit gradient near their zero set, so adding `δ` to `f_j` moves layer `j` by
//! about `δ` along its normal. Seen from layer `i`, every other active layer `j` is shifted
//! towards `i` by the thickness between their centre surfaces: half of each of the two plus the
//! full thickness of every active layer between them.

use super::operators::{FieldVec, MAX_LAYERS};
use crate::geom::Vec3;

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

/// Bounds on the gradient norm used by [`scaled_offsets`]: a degenerate gradient (e.g. at a
/// grid's far-field fill or a medial point) must not cancel or blow up the thickness.
pub const GRADIENT_NORM_RANGE: (f64, f64) = (0.25, 4.0);

/// Smallest tilt factor of [`scaled_offsets`] (where two layers' gradients point apart, e.g.
/// far from both surfaces, the offsets are not shrunk below half).
pub const MIN_TILT: f64 = 0.5;

/// The offsets of eq. 13 made exact to first order for fields that are not distance fields and
/// layers whose surfaces are not parallel (a deviation from Sec. 6.2, see below).
///
/// `me`, `t` as in [`offsets`]; `w` the weights (`∞` for the body) and `g` the field gradients
/// of the active layers at the point. Eq. 13 adds the same field offset to every layer; two
/// layers `a`, `a+1` that end in contact meet on the plane `w_a f̃_a + w_{a+1} f̃_{a+1} = 0`
/// (Sec. 5), so the gap between the two layers' corrected surfaces is
/// `δ_a (w_a + w_{a+1}) / |w_a ∇f_a + w_{a+1} ∇f_{a+1}|` with `δ_a = t_a/2 + t_{a+1}/2`: it
/// equals `δ_a` only for unit, parallel gradients (the approximation whose error Table 3
/// reports). Here the part of the offset that separates `a` from `a+1` is, in the units of layer
/// `j`, `δ_a k_a |∇f_j|` with the *tilt* `k_a = |w_a ∇f_a + w_{a+1} ∇f_{a+1}| / (w_a |∇f_a| +
/// w_{a+1} |∇f_{a+1}|)` (1 when the body, of infinite weight, is one of the two), which makes
/// that gap exactly `δ_a` for locally linear fields. Every quantity depends on the fields at the
/// point only, not on the layer being evaluated, so seen from layer `i+1` every field is shifted
/// by the same non-negative amounts `δ_i k_i |∇f_j|` as seen from layer `i`, as with eq. 13:
/// the layers stay in order. Gradient norms are clamped to [`GRADIENT_NORM_RANGE`], tilts to
/// `[MIN_TILT, 1]` (a clamp only widens the gap).
pub fn scaled_offsets(me: usize, t: &[f64], w: &[f64], g: &[Vec3]) -> FieldVec {
    let m = t.len();
    let (lo, hi) = GRADIENT_NORM_RANGE;
    let mut norm = [0.0; MAX_LAYERS];
    for j in 0..m {
        norm[j] = g[j].norm().clamp(lo, hi);
    }
    // Field-free part of each gap: δ_a k_a between active layers a and a+1.
    let mut gap = [0.0; MAX_LAYERS];
    for a in 0..m.saturating_sub(1) {
        let k = if w[a].is_infinite() || w[a + 1].is_infinite() {
            1.0
        } else {
            let s = g[a] * w[a] + g[a + 1] * w[a + 1];
            (s.norm() / (w[a] * norm[a] + w[a + 1] * norm[a + 1])).clamp(MIN_TILT, 1.0)
        };
        gap[a] = (0.5 * t[a] + 0.5 * t[a + 1]) * k;
    }
    let mut out = [0.0; MAX_LAYERS];
    let mut acc = 0.0;
    for j in me + 1..m {
        acc += gap[j - 1];
        out[j] = acc * norm[j];
    }
    let mut acc = 0.0;
    for j in (0..me).rev() {
        acc += gap[j];
        out[j] = -acc * norm[j];
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

    #[test]
    fn scaled_offsets_reduce_to_eq13_for_unit_parallel_gradients() {
        let t = [0.0, 1.0, 2.0, 4.0, 8.0];
        let w = [f64::INFINITY, 1.0, 2.0, 0.5, 3.0];
        let g = [Vec3::z(); 5];
        for me in 0..5 {
            let (a, b) = (offsets(me, &t), scaled_offsets(me, &t, &w, &g));
            for j in 0..5 {
                assert!(
                    (a[j] - b[j]).abs() < 1e-12,
                    "{me} {j}: {} vs {}",
                    a[j],
                    b[j]
                );
            }
        }
        // Gradient norm 2 everywhere: twice the field offsets (same geometric gaps).
        let g2 = [Vec3::z() * 2.0; 5];
        let b = scaled_offsets(2, &t, &w, &g2);
        let a = offsets(2, &t);
        for j in 0..5 {
            assert!((b[j] - 2.0 * a[j]).abs() < 1e-12);
        }
        // Seen from the next layer out, every field is shifted by the same non-negative amount
        // per gap (nesting kept, Sec. 5): here for orthogonal unit gradients (tilt 1/√2).
        let g3 = [Vec3::x(), Vec3::y(), Vec3::x(), Vec3::y(), Vec3::x()];
        for me in 0..4 {
            let (a, b) = (
                scaled_offsets(me, &t, &w, &g3),
                scaled_offsets(me + 1, &t, &w, &g3),
            );
            for j in 0..5 {
                assert!(a[j] - b[j] >= 0.0);
                assert!((a[j] - b[j] - (a[0] - b[0])).abs() < 1e-12);
            }
        }
    }
}
