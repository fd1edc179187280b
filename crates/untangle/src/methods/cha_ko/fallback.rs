//! What to do when no fan passes the triangle inversion test (Cha & Ko 2022, Sec. 6.1). The
//! paper halts and points to a convexification in its Appendix C, which is not available; we
//! use two fallbacks of our own, tried in order after the regular operations of the step (see
//! [`super::schedule`]), and report every use:
//!
//! 1. **Kernel target** (pulls of a vertex with one uv copy). The positions where the subject
//!    can sit without inverting any fan triangle form the *kernel* of its fan: the intersection
//!    of the half-planes left of each contour edge (a convex polygon that contains the subject's
//!    original uv in its interior). The subject is pulled toward the kernel point nearest to the
//!    target, moved a tenth of the way back toward the subject's original uv so it lies strictly
//!    inside. The whole segment stays in the kernel (convexity), so no triangle inverts at any
//!    level; the edge to the target shortens as far as the fan's shape allows.
//! 2. **Shortened anchors** (any operation, including shrinks and seam pulls). The anchors are
//!    moved toward the original uv by halves, `lambda = 1/2, 1/4, ..., 1/64`, until the test
//!    passes: a smaller step in the same direction.
//!
//! A fallback operation may saturate without finishing its finesse; it is then reported as
//! stalled, with its location.

use super::state::MovedCopy;
use crate::geom::{cross2, Vec2};

/// Which fallback an operation uses.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Fallback {
    /// Pulled toward the point of the fan kernel nearest to the target.
    KernelTarget,
    /// Anchors moved toward the original uv by the factor `lambda`.
    Shortened {
        /// The factor kept (1/2, 1/4, ...).
        lambda: f64,
    },
}

/// Factors tried by the shortened-anchor fallback.
pub const LAMBDAS: [f64; 6] = [0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625];

/// Anchors moved toward the original uv by `lambda`.
pub fn shortened(orig: &[Vec2], copies: &[MovedCopy], lambda: f64) -> Vec<MovedCopy> {
    copies
        .iter()
        .map(|c| {
            let o = orig[c.uv as usize];
            MovedCopy {
                uv: c.uv,
                anchor: o + (c.anchor - o) * lambda,
            }
        })
        .collect()
}

/// The kernel of the fan of the uv vertex at `center`: `contour` lists, for each fan triangle,
/// its two other corners `(a, b)` in the order in which the triangle is counter-clockwise in its
/// reference orientation (so the center must stay left of `a -> b`). `bound` is a box the result
/// is clipped to. Returns the kernel polygon (counter-clockwise), possibly empty.
pub fn kernel(contour: &[(Vec2, Vec2)], bound: (Vec2, Vec2)) -> Vec<Vec2> {
    let (lo, hi) = bound;
    let mut poly = vec![lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)];
    for &(a, b) in contour {
        if poly.is_empty() {
            break;
        }
        let side = |p: &Vec2| cross2(&a, &b, p);
        let mut out = Vec::with_capacity(poly.len() + 1);
        for i in 0..poly.len() {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            let (sp, sq) = (side(&p), side(&q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let t = sp / (sp - sq);
                out.push(p + (q - p) * t);
            }
        }
        poly = out;
    }
    poly
}

/// The point of the convex polygon `poly` (counter-clockwise) nearest to `p`.
pub fn nearest_point(poly: &[Vec2], p: Vec2) -> Option<Vec2> {
    if poly.is_empty() {
        return None;
    }
    let inside = poly.len() >= 3
        && (0..poly.len()).all(|i| cross2(&poly[i], &poly[(i + 1) % poly.len()], &p) >= 0.0);
    if inside {
        return Some(p);
    }
    let mut best = poly[0];
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let ab = b - a;
        let l2 = ab.norm_squared();
        let t = if l2 > 0.0 {
            ((p - a).dot(&ab) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = a + ab * t;
        if (q - p).norm_squared() < (best - p).norm_squared() {
            best = q;
        }
    }
    Some(best)
}

/// The kernel-target anchor for a subject at `origin` pulled toward `target` (see the module
/// text), or `None` when the kernel is empty (degenerate input).
pub fn kernel_anchor(contour: &[(Vec2, Vec2)], origin: Vec2, target: Vec2) -> Option<Vec2> {
    let mut lo = origin.inf(&target);
    let mut hi = origin.sup(&target);
    for (a, b) in contour {
        lo = lo.inf(a).inf(b);
        hi = hi.sup(a).sup(b);
    }
    let pad = (hi - lo).norm().max(1e-300);
    let pad = Vec2::new(pad, pad);
    let poly = kernel(contour, (lo - pad, hi + pad));
    let q = nearest_point(&poly, target)?;
    Some(q + (origin - q) * 0.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_of_a_square_fan_is_the_square() {
        // Center at the origin, contour square of half-size 1 (four triangles).
        let c = [
            Vec2::new(1.0, -1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(-1.0, 1.0),
            Vec2::new(-1.0, -1.0),
        ];
        let contour: Vec<(Vec2, Vec2)> = (0..4).map(|i| (c[i], c[(i + 1) % 4])).collect();
        let k = kernel(&contour, (Vec2::new(-5.0, -5.0), Vec2::new(5.0, 5.0)));
        let area: f64 = (0..k.len())
            .map(|i| cross2(&Vec2::zeros(), &k[i], &k[(i + 1) % k.len()]))
            .sum::<f64>()
            * 0.5;
        assert!((area - 4.0).abs() < 1e-12, "{area}");
        assert_eq!(
            nearest_point(&k, Vec2::new(3.0, 0.5)),
            Some(Vec2::new(1.0, 0.5))
        );
        assert_eq!(
            nearest_point(&k, Vec2::new(0.2, 0.5)),
            Some(Vec2::new(0.2, 0.5))
        );
    }

    #[test]
    fn shortened_moves_anchors_toward_the_origin() {
        let orig = vec![Vec2::new(2.0, 2.0)];
        let s = shortened(
            &orig,
            &[MovedCopy {
                uv: 0,
                anchor: Vec2::new(0.0, 0.0),
            }],
            0.25,
        );
        assert_eq!(s[0].anchor, Vec2::new(1.5, 1.5));
    }
}
