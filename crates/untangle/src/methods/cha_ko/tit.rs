//! The triangle inversion test (TIT, Cha & Ko 2022, Sec. 5.1.2), made exact for the whole
//! course of an operation.
//!
//! During an operation every moved corner follows `p(s) = a + s (o - a)`: `o` its original uv,
//! `a` its anchor, `s = gamma^level` running from 1 down toward 0 (the "extremity", where a
//! pulled subject reaches its target). Twice the signed area of a fan triangle is then
//!
//! `f(s) = c0 + c1 s + c2 s^2`,
//!
//! affine in `s` when one corner moves (a pull: testing the extreme position suffices, as the
//! paper says) and quadratic when two corners move (a shrink moves both ends of the red edge;
//! the paper only says "in a similar way"). A triangle passes when, in its panel's orientation,
//! `f >= 0` on all of `[0, 1]` (zero is allowed only at the extremity: a triangle that contains
//! the target, or both shrink subjects, degenerates there and is not inverted) and `f` stays
//! above a small relative margin on `[gamma^max_level, 1]`, the levels actually used, so that
//! rounding of the computed positions can never flip it.

use super::state::MovedCopy;
use crate::geom::{cross2, Vec2};

/// Relative margin on the levels actually used (see the module text). With scales of at least
/// [`super::params::MIN_SCALE`] = 1e-6, a shrunk triangle keeps `s^2 f(1) >= 1e-12 f(1)`.
pub const MARGIN: f64 = 1e-13;

/// Coefficients `[c0, c1, c2]` of `f(s)` for a triangle with original corners `o` and anchors
/// `a` (a static corner has `a = o`).
pub fn area_polynomial(o: [Vec2; 3], a: [Vec2; 3]) -> [f64; 3] {
    let d = [o[0] - a[0], o[1] - a[1], o[2] - a[2]];
    let (aa, bb) = (a[1] - a[0], a[2] - a[0]);
    let (dd, ee) = (d[1] - d[0], d[2] - d[0]);
    let c = |u: Vec2, v: Vec2| u.x * v.y - u.y * v.x;
    [c(aa, bb), c(aa, ee) + c(dd, bb), c(dd, ee)]
}

/// Evaluates `c0 + c1 s + c2 s^2`.
#[inline]
pub fn eval(c: [f64; 3], s: f64) -> f64 {
    c[0] + s * (c[1] + s * c[2])
}

/// Minimum of the quadratic on `[lo, hi]`.
pub fn min_on(c: [f64; 3], lo: f64, hi: f64) -> f64 {
    let mut m = eval(c, lo).min(eval(c, hi));
    if c[2] > 0.0 {
        let s = -c[1] / (2.0 * c[2]);
        if s > lo && s < hi {
            m = m.min(eval(c, s));
        }
    }
    m
}

/// Whether a triangle with area polynomial `c` (reference orientation `sign`) stays
/// non-inverted for `s` in `[0, 1]` and strictly positive, with margin, on `[s_min, 1]`.
pub fn triangle_passes(c: [f64; 3], sign: f64, s_min: f64) -> bool {
    let g = [sign * c[0], sign * c[1], sign * c[2]];
    let at_one = eval(g, 1.0);
    at_one > 0.0 && min_on(g, 0.0, 1.0) >= 0.0 && min_on(g, s_min, 1.0) > MARGIN * at_one
}

/// Outcome of the test on a set of triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TitResult {
    /// Every tested triangle passes.
    pub pass: bool,
    /// Triangles that would invert (sorted).
    pub inverted: Vec<u32>,
    /// Smallest `f(s) / f(1)` over the tested triangles and `s` in `[s_min, 1]` (1 if none).
    pub worst_ratio: f64,
}

/// Runs the TIT for the uv triangles `triangles` (indices into `uv_triangles`) when the copies in
/// `moving` follow their anchors. `sign` is each triangle's reference orientation; triangles in
/// `skip` (degenerate or flipped in the input, sorted) are not tested.
pub fn tit(
    uv_triangles: &[[u32; 3]],
    orig: &[Vec2],
    sign: &[f64],
    skip: &[u32],
    triangles: &[u32],
    moving: &[MovedCopy],
    s_min: f64,
) -> TitResult {
    let mut res = TitResult {
        pass: true,
        inverted: Vec::new(),
        worst_ratio: 1.0,
    };
    for &t in triangles {
        if skip.binary_search(&t).is_ok() {
            continue;
        }
        let corners = uv_triangles[t as usize];
        let o = corners.map(|i| orig[i as usize]);
        let a = corners.map(|i| {
            moving
                .iter()
                .find(|m| m.uv == i)
                .map_or(orig[i as usize], |m| m.anchor)
        });
        let c = area_polynomial(o, a);
        let sg = sign[t as usize];
        let g = [sg * c[0], sg * c[1], sg * c[2]];
        let at_one = eval(g, 1.0);
        if at_one > 0.0 {
            res.worst_ratio = res.worst_ratio.min(min_on(g, s_min, 1.0) / at_one);
        }
        if !triangle_passes(c, sg, s_min) {
            res.pass = false;
            res.inverted.push(t);
        }
    }
    res.inverted.sort_unstable();
    res
}

/// Twice the signed area of a uv triangle at given positions (for checks and reports).
pub fn signed_area(coords: &[Vec2], tri: [u32; 3]) -> f64 {
    cross2(
        &coords[tri[0] as usize],
        &coords[tri[1] as usize],
        &coords[tri[2] as usize],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn at(o: [Vec2; 3], a: [Vec2; 3], s: f64) -> f64 {
        let p = [0, 1, 2].map(|k| a[k] + (o[k] - a[k]) * s);
        cross2(&p[0], &p[1], &p[2])
    }

    #[test]
    fn polynomial_matches_direct_area() {
        let o = [
            Vec2::new(0.1, 0.2),
            Vec2::new(1.3, -0.4),
            Vec2::new(0.7, 1.9),
        ];
        let a = [o[0], Vec2::new(0.5, 0.5), Vec2::new(-0.2, 0.8)];
        let c = area_polynomial(o, a);
        for k in 0..=10 {
            let s = k as f64 / 10.0;
            assert!((eval(c, s) - at(o, a, s)).abs() < 1e-12);
        }
    }

    #[test]
    fn triangle_with_the_target_degenerates_but_passes() {
        // Subject 1 pulled onto target 0: f(s) = s f(1), zero only at the extremity.
        let o = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        let a = [o[0], o[0], o[2]];
        let c = area_polynomial(o, a);
        assert_eq!(c[0], 0.0);
        assert!(triangle_passes(c, 1.0, 1e-3));
        // Pulled through the opposite edge instead: inverted.
        let a2 = [o[0], Vec2::new(-1.0, 2.0), o[2]];
        assert!(!triangle_passes(area_polynomial(o, a2), 1.0, 1e-3));
    }

    #[test]
    fn quadratic_dip_below_zero_is_caught() {
        // Two corners move so that the area is positive at both ends but negative in between:
        // f(s) = 1 - 4 s + 3.5 s^2 (f(1) = 0.5, minimum -1/7 at s = 4/7).
        let a = [Vec2::zeros(), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)];
        let o = [Vec2::zeros(), Vec2::new(-1.0, 1.0), Vec2::new(0.5, -1.0)];
        let c = area_polynomial(o, a);
        // Independent check by dense sampling.
        let dense_min = (0..=10_000)
            .map(|k| at(o, a, k as f64 / 10_000.0))
            .fold(f64::INFINITY, f64::min);
        assert!(at(o, a, 0.0) > 0.0 && at(o, a, 1.0) > 0.0 && dense_min < 0.0);
        assert!(!triangle_passes(c, 1.0, 1e-3));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// The exact test agrees with dense sampling wherever the sampled minimum is clearly
        /// away from zero.
        #[test]
        fn agrees_with_dense_sampling(
            coords in proptest::collection::vec(-2.0f64..2.0, 12),
            moving in 0usize..2,
        ) {
            let p = |i: usize| Vec2::new(coords[2 * i], coords[2 * i + 1]);
            let o = [p(0), p(1), p(2)];
            prop_assume!(cross2(&o[0], &o[1], &o[2]) > 0.05);
            // One moving corner (a pull) or two (a shrink).
            let mut a = o;
            for k in 0..1 + moving % 2 {
                a[k + 1] = p(3 + k);
            }
            let c = area_polynomial(o, a);
            let s_min = 1e-3;
            let samples: Vec<f64> = (0..=20_000).map(|k| at(o, a, k as f64 / 20_000.0)).collect();
            let min_all = samples.iter().copied().fold(f64::INFINITY, f64::min);
            let f1 = at(o, a, 1.0);
            if min_all < -1e-6 {
                prop_assert!(!triangle_passes(c, 1.0, s_min));
            } else if min_all > 1e-6 * f1 {
                prop_assert!(triangle_passes(c, 1.0, s_min));
            }
        }
    }
}
