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

/// The weighted isotonic regression behind [`contact_blocks`]: per active layer, the first layer
/// of its block and the block's fitted position `ĉ_j` (non-decreasing in `j`).
///
/// Along the normal, layer `j`'s surface lies at `a_j = −f_j / |∇f_j|` from the point; with the
/// thickness rule, the untangled positions `b_j` must satisfy `b_j ≥ b_{j−1} + δ_{j−1}`. With
/// `c_j = a_j − Σ_{k<j} δ_k` that is the weighted isotonic regression of `c` (weights `w_j`,
/// the body's infinite weight pins its block), solved by pooling adjacent violators. The fitted
/// values are a Euclidean projection onto a convex cone, hence continuous in the fields even
/// where the blocks change.
pub fn isotonic_fit(
    x: &[f64],
    norm: &[f64],
    t: &[f64],
    w: &[f64],
) -> ([usize; MAX_LAYERS], [f64; MAX_LAYERS]) {
    let m = t.len();
    // Blocks: (first layer, weight sum, weighted sum, pinned value).
    let mut blocks: Vec<(usize, f64, f64, Option<f64>)> = Vec::with_capacity(m);
    let mut shift = 0.0;
    let value = |b: &(usize, f64, f64, Option<f64>)| b.3.unwrap_or(b.2 / b.1);
    for j in 0..m {
        if j > 0 {
            shift += 0.5 * (t[j - 1] + t[j]);
        }
        let c = -x[j] / norm[j] - shift;
        let mut b = if w[j].is_infinite() {
            (j, 0.0, 0.0, Some(c))
        } else {
            (j, w[j], w[j] * c, None)
        };
        while let Some(prev) = blocks.last() {
            if value(prev) <= value(&b) {
                break;
            }
            let prev = blocks.pop().expect("non-empty");
            b = (prev.0, prev.1 + b.1, prev.2 + b.2, prev.3.or(b.3));
        }
        blocks.push(b);
    }
    let mut first = [0usize; MAX_LAYERS];
    let mut fitted = [0.0; MAX_LAYERS];
    for (k, b) in blocks.iter().enumerate() {
        let end = blocks.get(k + 1).map_or(m, |n| n.0);
        for j in b.0..end {
            first[j] = b.0;
            fitted[j] = value(b);
        }
    }
    (first, fitted)
}

/// The layers that a locally linear model of the fields merges into one contact surface at the
/// point: per active layer, the index of the first layer of its *block* (the blocks of
/// [`isotonic_fit`]: the runs of layers that meet, the operators' runs of Sec. 5 for parallel
/// distance fields). Depends on the fields at the point only, not on the layer being evaluated.
pub fn contact_blocks(x: &[f64], norm: &[f64], t: &[f64], w: &[f64]) -> [usize; MAX_LAYERS] {
    isotonic_fit(x, norm, t, w).0
}

/// Membership of a layer in the tilt of a gap (see [`scaled_offsets`]) at fitted distance `s`
/// (in units of the blend width) from the gap's layers: 1 at 0 (same block), 0 from 1 on,
/// smoothstep in between (continuous with a continuous derivative).
fn membership(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    1.0 - s * s * (3.0 - 2.0 * s)
}

/// Width of the blend of [`scaled_offsets`], relative to the gap's thickness rule.
pub const TILT_BLEND: f64 = 0.5;

/// The offsets of eq. 13 made exact to first order for fields that are not distance fields and
/// layers whose surfaces are not parallel (a deviation from Sec. 6.2, see below).
///
/// `me`, `t` as in [`offsets`]; `w` the weights (`∞` for the body), `x` the field values and
/// `g` the field gradients of the active layers at the point. Eq. 13 adds the same field offset
/// to every layer; the layers of a run `R` that end in contact meet on the plane
/// `Σ_R w_j f̃_j = 0` (Sec. 5), so the gap between two neighbours' corrected surfaces there is
/// `δ_a Σ_R w_j / |Σ_R w_j ∇f_j|` with `δ_a = t_a/2 + t_{a+1}/2`: it equals `δ_a` only for
/// unit, parallel gradients (the approximation whose error Table 3 reports). Here the part of
/// the offset that separates `a` from `a+1` is, in the units of layer `j`, `δ_a k_a |∇f_j|`
/// with the *tilt* `k_a = |Σ μ_j w_j ∇f_j| / Σ μ_j w_j |∇f_j|`, where `μ_j = 1` for `a`, `a+1`
/// and every layer of their blocks ([`isotonic_fit`]), so that for the block `B` that merges
/// there the gap is exactly `δ_a` for locally linear fields, and `μ_j` falls smoothly to 0 as
/// the fitted position of a layer outside the blocks moves [`TILT_BLEND`]` · δ_a` away from
/// them (the fitted positions are continuous, so the offsets are continuous where the blocks
/// change: a hard switch of `B` made some vertices of the projection oscillate between two
/// targets). The body (infinite weight) is left out of the tilt, and a gap next to it has
/// tilt 1 (its plane is `f_0` alone). Every quantity depends on the fields at the point only,
/// not on the layer being evaluated, so seen from layer `i+1` every field is shifted by the
/// same non-negative amounts `δ_i k_i |∇f_j|` as seen from layer `i`, as with eq. 13: the
/// layers stay in order. Gradient norms are clamped to [`GRADIENT_NORM_RANGE`], tilts to
/// `[MIN_TILT, 1]` (a clamp only widens the gap).
pub fn scaled_offsets(me: usize, t: &[f64], w: &[f64], x: &[f64], g: &[Vec3]) -> FieldVec {
    let m = t.len();
    let (lo, hi) = GRADIENT_NORM_RANGE;
    let mut norm = [0.0; MAX_LAYERS];
    for j in 0..m {
        norm[j] = g[j].norm().clamp(lo, hi);
    }
    let (_, fitted) = isotonic_fit(x, &norm[..m], t, w);
    // Field-free part of each gap: δ_a k_a between active layers a and a+1.
    let mut gap = [0.0; MAX_LAYERS];
    for a in 0..m.saturating_sub(1) {
        let delta = 0.5 * t[a] + 0.5 * t[a + 1];
        let k = if w[a].is_infinite() || w[a + 1].is_infinite() {
            1.0
        } else {
            let width = (TILT_BLEND * delta).max(1e-12);
            let (mut s, mut n) = (Vec3::zeros(), 0.0);
            for j in (0..m).filter(|&j| w[j].is_finite()) {
                let mu = if j < a {
                    membership((fitted[a] - fitted[j]) / width)
                } else if j > a + 1 {
                    membership((fitted[j] - fitted[a + 1]) / width)
                } else {
                    1.0
                };
                if mu > 0.0 {
                    s += g[j] * (mu * w[j]);
                    n += mu * w[j] * norm[j];
                }
            }
            if n > 0.0 {
                (s.norm() / n).clamp(MIN_TILT, 1.0)
            } else {
                1.0
            }
        };
        gap[a] = delta * k;
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
            let (a, b) = (offsets(me, &t), scaled_offsets(me, &t, &w, &[0.0; 5], &g));
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
        let b = scaled_offsets(2, &t, &w, &[0.0; 5], &g2);
        let a = offsets(2, &t);
        for j in 0..5 {
            assert!((b[j] - 2.0 * a[j]).abs() < 1e-12);
        }
        // Seen from the next layer out, every field is shifted by the same non-negative amount
        // per gap (nesting kept, Sec. 5): here for orthogonal unit gradients (tilt 1/√2).
        let g3 = [Vec3::x(), Vec3::y(), Vec3::x(), Vec3::y(), Vec3::x()];
        let x3 = [0.3, -0.2, 0.1, 0.5, -0.4];
        for me in 0..4 {
            let (a, b) = (
                scaled_offsets(me, &t, &w, &x3, &g3),
                scaled_offsets(me + 1, &t, &w, &x3, &g3),
            );
            for j in 0..5 {
                assert!(a[j] - b[j] >= 0.0);
                assert!((a[j] - b[j] - (a[0] - b[0])).abs() < 1e-12);
            }
        }
    }

    /// Brute force isotonic regression: every split into contiguous blocks, block values the
    /// weighted means, the feasible (non-decreasing) split of least weighted squared error.
    fn blocks_brute(c: &[f64], w: &[f64]) -> Vec<usize> {
        let m = c.len();
        let mut best = (f64::INFINITY, vec![]);
        for cuts in 0u32..(1 << (m - 1)) {
            let mut first = vec![0usize; m];
            let mut vals = vec![0.0; m];
            let mut start = 0;
            for j in 0..m {
                if j == m - 1 || cuts & (1 << j) != 0 {
                    let sw: f64 = w[start..=j].iter().sum();
                    let v = (start..=j).map(|k| w[k] * c[k]).sum::<f64>() / sw;
                    for k in start..=j {
                        first[k] = start;
                        vals[k] = v;
                    }
                    start = j + 1;
                }
            }
            if vals.windows(2).any(|p| p[1] < p[0]) {
                continue;
            }
            let e: f64 = (0..m).map(|k| w[k] * (vals[k] - c[k]).powi(2)).sum();
            if e < best.0 - 1e-12 {
                best = (e, first);
            }
        }
        best.1
    }

    /// Sweeps the fields linearly between two random configurations, so that blocks merge
    /// and split on the way, and checks that the offsets have no jump: the largest change
    /// between neighbouring samples shrinks with the sampling step (halving the step must
    /// roughly halve it). A jump of the tilt where a block changes (the previous rule) gives
    /// a change that does not shrink.
    #[test]
    fn scaled_offsets_are_continuous_across_block_changes() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut changes = 0;
        for _ in 0..200 {
            let m = rng.random_range(3..=7);
            let body = rng.random_bool(0.5);
            let t: Vec<f64> = (0..m)
                .map(|j| if body && j == 0 { 0.0 } else { 0.01 })
                .collect();
            let w: Vec<f64> = (0..m)
                .map(|j| {
                    if body && j == 0 {
                        f64::INFINITY
                    } else {
                        rng.random_range(0.3..3.0)
                    }
                })
                .collect();
            let rand_dir = |rng: &mut rand_chacha::ChaCha8Rng| {
                let v = Vec3::new(
                    rng.random_range(-0.6..0.6),
                    rng.random_range(-0.6..0.6),
                    1.0,
                );
                v.normalize() * rng.random_range(0.8..1.3)
            };
            let g: Vec<Vec3> = (0..m).map(|_| rand_dir(&mut rng)).collect();
            let x0: Vec<f64> = (0..m).map(|_| rng.random_range(-0.03..0.03)).collect();
            let x1: Vec<f64> = (0..m).map(|_| rng.random_range(-0.03..0.03)).collect();
            let me = rng.random_range(0..m);
            let at = |s: f64| {
                let x: Vec<f64> = (0..m).map(|j| x0[j] + s * (x1[j] - x0[j])).collect();
                (
                    scaled_offsets(me, &t, &w, &x, &g),
                    isotonic_fit(&x, &g.iter().map(|v| v.norm()).collect::<Vec<_>>(), &t, &w).0,
                )
            };
            let mut max_jump = |n: usize| {
                let mut prev = at(0.0);
                let mut worst: f64 = 0.0;
                for i in 1..=n {
                    let cur = at(i as f64 / n as f64);
                    if cur.1[..m] != prev.1[..m] {
                        changes += 1;
                    }
                    for j in 0..m {
                        worst = worst.max((cur.0[j] - prev.0[j]).abs());
                    }
                    prev = cur;
                }
                worst
            };
            let (coarse, fine) = (max_jump(2000), max_jump(4000));
            // Lipschitz-like: a continuous, piecewise smooth function of the sweep.
            assert!(
                fine <= 0.75 * coarse + 1e-12,
                "jump does not shrink: {coarse:e} -> {fine:e} (m {m}, me {me})"
            );
        }
        assert!(
            changes > 100,
            "the sweeps must cross block changes: {changes}"
        );
    }

    #[test]
    fn contact_blocks_match_brute_force_isotonic_regression() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..500 {
            let m = rng.random_range(1..=7);
            let x: Vec<f64> = (0..m).map(|_| rng.random_range(-0.1..0.1)).collect();
            let norm: Vec<f64> = (0..m).map(|_| rng.random_range(0.7..1.4)).collect();
            let t: Vec<f64> = (0..m).map(|_| rng.random_range(0.0..0.02)).collect();
            let w: Vec<f64> = (0..m).map(|_| rng.random_range(0.3..3.0)).collect();
            let mut shift = 0.0;
            let c: Vec<f64> = (0..m)
                .map(|j| {
                    if j > 0 {
                        shift += 0.5 * (t[j - 1] + t[j]);
                    }
                    -x[j] / norm[j] - shift
                })
                .collect();
            let got = contact_blocks(&x, &norm, &t, &w);
            assert_eq!(&got[..m], &blocks_brute(&c, &w)[..], "{c:?} {w:?}");
        }
        // The body (infinite weight) pins its block: a garment below its surface joins it.
        let b = contact_blocks(
            &[0.0, 0.02, -0.05],
            &[1.0; 3],
            &[0.0, 0.01, 0.01],
            &[f64::INFINITY, 1.0, 1.0],
        );
        assert_eq!(&b[..3], &[0, 0, 2]);
    }
}
