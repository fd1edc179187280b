//! Closest points between the primitives of a triangle mesh: point–triangle and segment–segment.
//!
//! These are the proximity kernels of cloth collision handling (Bridson, Fedkiw, Anderson 2002,
//! "Robust treatment of collisions, contact and friction for cloth animation", Sec. 6: repulsions
//! act between a point and a triangle or between two edges closer than the cloth thickness).
//!
//! Both functions minimise a convex quadratic over a polygonal parameter domain. Instead of a
//! chain of region tests, they evaluate every candidate that can hold the minimum (the interior
//! critical point when it is well defined and inside the domain, and the closest point on each
//! boundary piece) and keep the nearest one. A candidate computed inaccurately (nearly parallel
//! segments, a nearly degenerate triangle) can only lose the comparison, so the result stays
//! accurate for parallel and degenerate input, and the returned distance is always the distance
//! between the two returned points.

use super::{Real, Vec3};

/// Squared distance from `p` to the segment `(a, b)` and the parameter `s` of the closest point
/// `a + s (b - a)`, `s` in `[0, 1]`; a zero-length segment gives `s = 0`.
#[inline]
pub fn point_segment(p: &Vec3, a: &Vec3, b: &Vec3) -> (Real, Real) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let s = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    // A NaN from overflowing input stays NaN rather than being clamped into a fake answer.
    let s = if s.is_nan() { 0.0 } else { s };
    let q = a + ab * s;
    ((p - q).norm_squared(), s)
}

/// Closest point on the triangle `(a, b, c)` to `p`.
///
/// Returns `(squared distance, [u, v, w])` with the closest point `u a + v b + w c`, `u + v + w = 1`
/// and all three weights `>= 0`. Degenerate triangles (collinear or coincident corners) are
/// handled as the union of their edges.
pub fn point_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> (Real, [Real; 3]) {
    // Interior candidate: the orthogonal projection of p onto the plane, if it lies inside.
    let n = (b - a).cross(&(c - a));
    let nn = n.norm_squared();
    if nn > 0.0 && nn.is_finite() {
        // Barycentric weights of the projection as signed sub-areas (each divided by |n|^2).
        let wa = (b - p).cross(&(c - p)).dot(&n) / nn;
        let wb = (c - p).cross(&(a - p)).dot(&n) / nn;
        let wc = 1.0 - wa - wb;
        if wa >= 0.0 && wb >= 0.0 && wc >= 0.0 {
            let q = a * wa + b * wb + c * wc;
            let d_int = (p - q).norm_squared();
            // Near-degenerate triangles make the projection inaccurate: let the edges compete.
            let best = boundary_point_triangle(p, a, b, c);
            return if d_int <= best.0 {
                (d_int, [wa, wb, wc])
            } else {
                best
            };
        }
    }
    boundary_point_triangle(p, a, b, c)
}

/// Closest point to `p` on the boundary (three edges) of the triangle `(a, b, c)`.
fn boundary_point_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> (Real, [Real; 3]) {
    let (dab, s) = point_segment(p, a, b);
    let mut best = (dab, [1.0 - s, s, 0.0]);
    let (dbc, s) = point_segment(p, b, c);
    if dbc < best.0 {
        best = (dbc, [0.0, 1.0 - s, s]);
    }
    let (dca, s) = point_segment(p, c, a);
    if dca < best.0 {
        best = (dca, [s, 0.0, 1.0 - s]);
    }
    best
}

/// Closest points of the segments `(p0, p1)` and `(q0, q1)`.
///
/// Returns `(squared distance, s, t)`: the closest points are `p0 + s (p1 - p0)` and
/// `q0 + t (q1 - q0)` with `s, t` in `[0, 1]`. Parallel, overlapping and zero-length segments are
/// handled: the minimum of the convex distance function over the unit square lies either at the
/// interior critical point (skew segments) or on the square's boundary, where it reduces to four
/// point–segment problems; every candidate is evaluated and the nearest kept.
pub fn segment_segment(p0: &Vec3, p1: &Vec3, q0: &Vec3, q1: &Vec3) -> (Real, Real, Real) {
    let d1 = p1 - p0;
    let d2 = q1 - q0;
    let eval = |s: Real, t: Real| ((p0 + d1 * s) - (q0 + d2 * t)).norm_squared();

    // Boundary candidates: s = 0, s = 1, t = 0, t = 1.
    let (d, t) = point_segment(p0, q0, q1);
    let mut best = (d, 0.0, t);
    let (d, t) = point_segment(p1, q0, q1);
    if d < best.0 {
        best = (d, 1.0, t);
    }
    let (d, s) = point_segment(q0, p0, p1);
    if d < best.0 {
        best = (d, s, 0.0);
    }
    let (d, s) = point_segment(q1, p0, p1);
    if d < best.0 {
        best = (d, s, 1.0);
    }

    // Interior candidate: the stationary point of |p(s) - q(t)|^2 when the lines are skew.
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let b = d1.dot(&d2);
    let r = p0 - q0;
    let c = d1.dot(&r);
    let f = d2.dot(&r);
    let den = a * e - b * b;
    if den > 0.0 && den.is_finite() {
        let s = (b * f - c * e) / den;
        let t = (a * f - b * c) / den;
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            let d = eval(s, t);
            if d < best.0 {
                best = (d, s, t);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(x, y, z)
    }

    /// Brute-force minimum of `f` over the unit square sampled on an `n x n` grid, followed by a
    /// shrinking pattern search around the best sample (an oracle that knows nothing about the
    /// geometry of the problem).
    fn brute_min(n: usize, inside: impl Fn(f64, f64) -> bool, f: impl Fn(f64, f64) -> f64) -> f64 {
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for i in 0..=n {
            for j in 0..=n {
                let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
                if inside(s, t) {
                    let d = f(s, t);
                    if d < best.0 {
                        best = (d, s, t);
                    }
                }
            }
        }
        let mut h = 1.0 / n as f64;
        while h > 1e-9 {
            let mut improved = false;
            for (ds, dt) in [
                (1.0, 0.0),
                (-1.0, 0.0),
                (0.0, 1.0),
                (0.0, -1.0),
                (1.0, 1.0),
                (-1.0, -1.0),
                (1.0, -1.0),
                (-1.0, 1.0),
            ] {
                let (s, t) = (best.1 + ds * h, best.2 + dt * h);
                let (s, t) = (s.clamp(0.0, 1.0), t.clamp(0.0, 1.0));
                if inside(s, t) {
                    let d = f(s, t);
                    if d < best.0 {
                        best = (d, s, t);
                        improved = true;
                    }
                }
            }
            if !improved {
                h *= 0.5;
            }
        }
        best.0
    }

    fn coord() -> impl Strategy<Value = f64> {
        // Small integer grid values make degenerate configurations (parallel, collinear,
        // coincident) frequent; the continuous range covers the generic case.
        prop_oneof![(-3i32..=3).prop_map(|k| k as f64), -2.0..2.0f64]
    }

    fn point() -> impl Strategy<Value = Vec3> {
        (coord(), coord(), coord()).prop_map(|(x, y, z)| v(x, y, z))
    }

    fn check_point_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) {
        let (d, w) = point_triangle(p, a, b, c);
        assert!(w.iter().all(|&x| x >= 0.0), "{w:?}");
        assert!((w[0] + w[1] + w[2] - 1.0).abs() < 1e-12, "{w:?}");
        let q = a * w[0] + b * w[1] + c * w[2];
        assert!(((p - q).norm_squared() - d).abs() <= 1e-12 * (1.0 + d));
        let brute = brute_min(
            40,
            |s, t| s + t <= 1.0,
            |s, t| (p - (a * (1.0 - s - t) + b * s + c * t)).norm_squared(),
        );
        let scale = 1.0 + (p - a).norm_squared() + (b - a).norm_squared() + (c - a).norm_squared();
        assert!(d <= brute + 1e-12 * scale, "d={d} brute={brute}");
        assert!(d >= brute - 1e-7 * scale, "d={d} brute={brute}");
    }

    fn check_segment_segment(p0: &Vec3, p1: &Vec3, q0: &Vec3, q1: &Vec3) {
        let (d, s, t) = segment_segment(p0, p1, q0, q1);
        assert!((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t));
        let x = p0 + (p1 - p0) * s - (q0 + (q1 - q0) * t);
        assert!((x.norm_squared() - d).abs() <= 1e-12 * (1.0 + d));
        let brute = brute_min(
            40,
            |_, _| true,
            |s, t| (p0 + (p1 - p0) * s - (q0 + (q1 - q0) * t)).norm_squared(),
        );
        let scale =
            1.0 + (p1 - p0).norm_squared() + (q1 - q0).norm_squared() + (q0 - p0).norm_squared();
        assert!(d <= brute + 1e-12 * scale, "d={d} brute={brute}");
        assert!(d >= brute - 1e-7 * scale, "d={d} brute={brute}");
    }

    #[test]
    fn point_triangle_regions() {
        let (a, b, c) = (v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0));
        // Interior: distance is the height.
        let (d, w) = point_triangle(&v(0.25, 0.25, 2.0), &a, &b, &c);
        assert_eq!(d, 4.0);
        assert_eq!(w, [0.5, 0.25, 0.25]);
        // Vertex region of b.
        let (d, w) = point_triangle(&v(2.0, -1.0, 0.0), &a, &b, &c);
        assert_eq!(d, 2.0);
        assert_eq!(w, [0.0, 1.0, 0.0]);
        // Edge region of bc.
        let (d, w) = point_triangle(&v(1.0, 1.0, 0.0), &a, &b, &c);
        assert!((d - 0.5).abs() < 1e-15);
        assert!((w[1] - 0.5).abs() < 1e-15 && (w[2] - 0.5).abs() < 1e-15);
        // Point on the face.
        let (d, _) = point_triangle(&v(0.1, 0.2, 0.0), &a, &b, &c);
        assert!(d < 1e-30);
        // Degenerate triangles: collinear and a single point.
        let (d, _) = point_triangle(&v(0.5, 1.0, 0.0), &a, &b, &v(2.0, 0.0, 0.0));
        assert_eq!(d, 1.0);
        let (d, w) = point_triangle(&v(0.0, 3.0, 4.0), &a, &a, &a);
        assert_eq!(d, 25.0);
        assert_eq!(w.iter().sum::<f64>(), 1.0);
    }

    #[test]
    fn segment_segment_cases() {
        // Skew, crossing at distance 1.
        let (d, s, t) = segment_segment(
            &v(-1.0, 0.0, 0.0),
            &v(1.0, 0.0, 0.0),
            &v(0.0, -1.0, 1.0),
            &v(0.0, 1.0, 1.0),
        );
        assert_eq!((d, s, t), (1.0, 0.5, 0.5));
        // Parallel overlapping: distance 2 anywhere on the overlap.
        let (d, s, t) = segment_segment(
            &v(0.0, 0.0, 0.0),
            &v(2.0, 0.0, 0.0),
            &v(1.0, 2.0, 0.0),
            &v(3.0, 2.0, 0.0),
        );
        assert_eq!(d, 4.0);
        assert!(s >= 0.5 && (t - (2.0 * s - 1.0) / 2.0).abs() < 1e-15);
        // Collinear disjoint: gap of 1 between endpoints.
        let (d, s, t) = segment_segment(
            &v(0.0, 0.0, 0.0),
            &v(1.0, 0.0, 0.0),
            &v(3.0, 0.0, 0.0),
            &v(2.0, 0.0, 0.0),
        );
        assert_eq!((d, s, t), (1.0, 1.0, 1.0));
        // Touching at an endpoint.
        let (d, s, _) = segment_segment(
            &v(0.0, 0.0, 0.0),
            &v(1.0, 0.0, 0.0),
            &v(1.0, 0.0, 0.0),
            &v(1.0, 1.0, 5.0),
        );
        assert_eq!((d, s), (0.0, 1.0));
        // Both zero length.
        let (d, s, t) = segment_segment(
            &v(1.0, 1.0, 1.0),
            &v(1.0, 1.0, 1.0),
            &v(1.0, 3.0, 1.0),
            &v(1.0, 3.0, 1.0),
        );
        assert_eq!((d, s, t), (4.0, 0.0, 0.0));
        // One zero length.
        let (d, _, t) = segment_segment(
            &v(0.5, 1.0, 0.0),
            &v(0.5, 1.0, 0.0),
            &v(0.0, 0.0, 0.0),
            &v(1.0, 0.0, 0.0),
        );
        assert_eq!((d, t), (1.0, 0.5));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        #[test]
        fn point_triangle_matches_brute_force(p in point(), a in point(), b in point(), c in point()) {
            check_point_triangle(&p, &a, &b, &c);
        }

        #[test]
        fn segment_segment_matches_brute_force(p0 in point(), p1 in point(), q0 in point(), q1 in point()) {
            check_segment_segment(&p0, &p1, &q0, &q1);
        }

        #[test]
        fn segment_segment_parallel_brute_force(p0 in point(), dir in point(), k in -2.0..2.0f64, off in point(), len in -2.0..2.0f64) {
            let p1 = p0 + dir;
            let q0 = off;
            let q1 = off + dir * (k + 1e-3 * len);
            check_segment_segment(&p0, &p1, &q0, &q1);
        }
    }
}
