//! Edge-triangle crossings and triangle-triangle intersection, decided with the symbolically
//! perturbed predicates of [`super::predicates`].
//!
//! A crossing of edge `e` through triangle `t` (no shared vertex) is the elementary event of the
//! global intersection analysis (Wicke et al. 2006, Sec. 4): every intersection segment between
//! two triangles ends at two crossings, or at one crossing and a shared (loop) vertex.

use super::predicates::orient3d_sos;
use super::{Real, Vec3};

/// Whether the edge `(p, q)` crosses the triangle `(a, b, c)`, under the symbolic perturbation.
///
/// `ids` are the global indices of `[p, q, a, b, c]`; they must be pairwise distinct (an edge that
/// shares a vertex with the triangle can only touch it at that vertex and never crosses it).
/// Returns `false` when indices repeat.
#[inline]
pub fn edge_crosses_triangle(
    p: &Vec3,
    q: &Vec3,
    a: &Vec3,
    b: &Vec3,
    c: &Vec3,
    ids: [u32; 5],
) -> bool {
    let [ip, iq, ia, ib, ic] = ids;
    let sp = orient3d_sos([a, b, c, p], [ia, ib, ic, ip]);
    let sq = orient3d_sos([a, b, c, q], [ia, ib, ic, iq]);
    if sp == 0 || sq == 0 || sp == sq {
        return false;
    }
    let s1 = orient3d_sos([p, q, a, b], [ip, iq, ia, ib]);
    let s2 = orient3d_sos([p, q, b, c], [ip, iq, ib, ic]);
    if s1 != s2 || s1 == 0 {
        return false;
    }
    let s3 = orient3d_sos([p, q, c, a], [ip, iq, ic, ia]);
    s3 == s1
}

/// [`edge_crosses_triangle`] for an edge whose endpoints are already known to lie strictly on
/// opposite sides of the triangle's plane (e.g. from a certified floating-point test): only the
/// three side tests remain, with the same symbolic perturbation, so the answer is identical.
#[inline]
pub fn straddling_edge_crosses_triangle(
    p: &Vec3,
    q: &Vec3,
    a: &Vec3,
    b: &Vec3,
    c: &Vec3,
    ids: [u32; 5],
) -> bool {
    let [ip, iq, ia, ib, ic] = ids;
    let s1 = orient3d_sos([p, q, a, b], [ip, iq, ia, ib]);
    let s2 = orient3d_sos([p, q, b, c], [ip, iq, ib, ic]);
    if s1 != s2 || s1 == 0 {
        return false;
    }
    orient3d_sos([p, q, c, a], [ip, iq, ic, ia]) == s1
}

/// The signs of the three side orientations of edge `pq` with the edges of triangle `(a, b, c)`:
/// with `A, B, C` the corners relative to `p` and `d = q - p`, the signs of `d . (A x B)`,
/// `d . (B x C)`, `d . (C x A)` (up to one common sign) in floating point, `0` where a forward
/// error bound cannot certify the sign.
#[inline]
fn certified_side_signs(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> [i8; 3] {
    let d = q - p;
    let (pa, pb, pc) = (a - p, b - p, c - p);
    let t = [
        d.dot(&pa.cross(&pb)),
        d.dot(&pb.cross(&pc)),
        d.dot(&pc.cross(&pa)),
    ];
    let l1 = |v: &Vec3| v.x.abs() + v.y.abs() + v.z.abs();
    let (ld, la, lb, lc) = (l1(&d), l1(&pa), l1(&pb), l1(&pc));
    // Each term is a sum of six triple products of rounded differences; 1e-14 is far above the
    // accumulated relative error (about 10 ulps) of that evaluation.
    let k = 1e-14 * ld;
    let e = [k * la * lb, k * lb * lc, k * lc * la];
    let sign = |i: usize| (t[i] > e[i]) as i8 - (t[i] < -e[i]) as i8;
    [sign(0), sign(1), sign(2)]
}

/// [`straddling_edge_crosses_triangle`] with a floating-point fast path: with `A, B, C` the
/// triangle's corners relative to `p` and `d = q - p`, the three side orientations are the signs
/// of `d . (A x B)`, `d . (B x C)`, `d . (C x A)` (up to one common sign). When all three are
/// certainly non-zero (forward error bound) the answer is whether they agree; otherwise the
/// exact, symbolically perturbed test decides. The answer is always the exact one.
#[inline]
pub fn straddling_edge_crosses_triangle_fast(
    p: &Vec3,
    q: &Vec3,
    a: &Vec3,
    b: &Vec3,
    c: &Vec3,
    ids: [u32; 5],
) -> bool {
    let s = certified_side_signs(p, q, a, b, c);
    if !s.contains(&0) {
        return s[0] == s[1] && s[1] == s[2];
    }
    straddling_edge_crosses_triangle(p, q, a, b, c, ids)
}

/// [`edge_crosses_triangle`] with a floating-point rejection first: when two of the three side
/// orientations of the edge with the triangle's edges are certainly non-zero with opposite signs,
/// the exact test would answer `false` (it requires all three to agree), so no exact arithmetic
/// is needed. This decides, e.g., an edge with an endpoint exactly in the triangle's plane but
/// outside the triangle. The answer is always the exact one.
#[inline]
pub fn edge_crosses_triangle_filtered(
    p: &Vec3,
    q: &Vec3,
    a: &Vec3,
    b: &Vec3,
    c: &Vec3,
    ids: [u32; 5],
) -> bool {
    let s = certified_side_signs(p, q, a, b, c);
    if s.contains(&1) && s.contains(&-1) {
        return false;
    }
    edge_crosses_triangle(p, q, a, b, c, ids)
}

/// A triangle's plane with a certified floating-point side test.
#[derive(Clone, Copy, Debug)]
pub struct CertifiedPlane {
    n: Vec3,
    a: Vec3,
    k: Real,
}

impl CertifiedPlane {
    /// The plane of triangle `(a, b, c)`.
    #[inline]
    pub fn new(a: &Vec3, b: &Vec3, c: &Vec3) -> Self {
        let l1 = |d: &Vec3| d.x.abs() + d.y.abs() + d.z.abs();
        let (ab, ac) = (b - a, c - a);
        CertifiedPlane {
            n: ab.cross(&ac),
            a: *a,
            // Forward error bound of n . (p - a), over |p - a|_1 (generously rounded up).
            k: 1e-14 * l1(&ab) * l1(&ac),
        }
    }

    /// The plane with normal `n = (b - a) x (c - a)` (as computed), corner `a` and error factor
    /// `k`, as [`CertifiedPlane::new`] computes them.
    #[inline]
    pub(crate) fn from_parts(n: Vec3, a: Vec3, k: Real) -> Self {
        CertifiedPlane { n, a, k }
    }

    /// The (unnormalised) normal `(b - a) x (c - a)`.
    #[inline]
    pub fn normal(&self) -> Vec3 {
        self.n
    }

    /// `+1` or `-1` when `p` is certainly strictly on that side (matching the sign of the exact
    /// `n . (p - a)`, which is `-orient3d(a, b, c, p)`), `0` when too close to tell.
    #[inline]
    pub fn side(&self, p: &Vec3) -> i8 {
        let d = p - self.a;
        let s = self.n.dot(&d);
        let tol = self.k * (d.x.abs() + d.y.abs() + d.z.abs());
        if s > tol {
            1
        } else if s < -tol {
            -1
        } else {
            0
        }
    }
}

/// A quick floating-point rejection test for `edge_crosses_triangle`: returns `false` only when
/// both edge endpoints are certainly strictly on the same side of the triangle's plane.
///
/// Uses a conservative forward error bound, so it never rejects a true crossing.
#[inline]
pub fn edge_may_cross_plane(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> bool {
    let n = (b - a).cross(&(c - a));
    let dp = n.dot(&(p - a));
    let dq = n.dot(&(q - a));
    if (dp > 0.0) != (dq > 0.0) || dp == 0.0 || dq == 0.0 {
        return true;
    }
    // Error bound of the dot-of-cross evaluation (a few ulps of the magnitude products).
    let mag = |d: &Vec3| d.x.abs() + d.y.abs() + d.z.abs();
    let scale = mag(&(b - a)) * mag(&(c - a));
    let bound = 1e-14 * scale * (mag(&(p - a)) + mag(&(q - a)));
    dp.abs() <= bound || dq.abs() <= bound
}

/// A quick floating-point rejection test in the projection onto the coordinate plane most
/// parallel to the triangle: returns `false` only when the projections of segment `(p, q)` and
/// triangle `(a, b, c)` are certainly disjoint (separated by a triangle edge or by the segment's
/// line, with a conservative error margin). Disjoint projections mean disjoint sets, so the edge
/// cannot cross the triangle under any infinitesimal perturbation either. This is the test that
/// decides exactly coplanar configurations (flat cloth) without exact arithmetic.
#[inline]
pub fn edge_may_overlap_projected(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> bool {
    let n = (b - a).cross(&(c - a));
    let (ax, ay, az) = (n.x.abs(), n.y.abs(), n.z.abs());
    // Drop the dominant axis.
    let (u, v) = if az >= ax && az >= ay {
        (0, 1)
    } else if ax >= ay {
        (1, 2)
    } else {
        (2, 0)
    };
    let pr = |x: &Vec3| (x[u], x[v]);
    let (p2, q2, a2, b2, c2) = (pr(p), pr(q), pr(a), pr(b), pr(c));
    let o = |o: (f64, f64), x: (f64, f64), y: (f64, f64)| {
        (x.0 - o.0) * (y.1 - o.1) - (x.1 - o.1) * (y.0 - o.0)
    };
    // Conservative error margin: a few ulps of the squared coordinate range involved.
    let mut m = 0.0f64;
    for w in [p2, q2, a2, b2, c2] {
        m = m.max(w.0.abs()).max(w.1.abs());
    }
    let tol = 1e-13 * m * m;
    let area = o(a2, b2, c2);
    if area.abs() <= tol {
        return true; // the projection is too thin to judge: let the exact test decide
    }
    let s = area.signum();
    for (x, y) in [(a2, b2), (b2, c2), (c2, a2)] {
        if s * o(x, y, p2) < -tol && s * o(x, y, q2) < -tol {
            return false;
        }
    }
    let (da, db, dc) = (o(p2, q2, a2), o(p2, q2, b2), o(p2, q2, c2));
    if (da > tol && db > tol && dc > tol) || (da < -tol && db < -tol && dc < -tol) {
        return false;
    }
    true
}

/// A quick floating-point rejection test for a triangle pair: returns `false` only when the
/// closed triangles are certainly disjoint — one lies strictly on one side of the other's plane,
/// or their projections onto the coordinate plane most parallel to `b` are separated along one of
/// the six edge normals (both with conservative error margins). Disjoint closed triangles have no
/// crossing under any infinitesimal perturbation, so this never rejects what
/// [`edge_crosses_triangle`] would accept.
#[inline]
pub fn triangles_may_intersect(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    let l1 = |d: &Vec3| d.x.abs() + d.y.abs() + d.z.abs();
    let separated_by_plane = |p: &[Vec3; 3], q: &[Vec3; 3]| {
        let n = (q[1] - q[0]).cross(&(q[2] - q[0]));
        let d = [
            n.dot(&(p[0] - q[0])),
            n.dot(&(p[1] - q[0])),
            n.dot(&(p[2] - q[0])),
        ];
        let reach = l1(&(p[0] - q[0]))
            .max(l1(&(p[1] - q[0])))
            .max(l1(&(p[2] - q[0])));
        let tol = 1e-14 * l1(&(q[1] - q[0])) * l1(&(q[2] - q[0])) * reach;
        (d[0] > tol && d[1] > tol && d[2] > tol) || (d[0] < -tol && d[1] < -tol && d[2] < -tol)
    };
    if separated_by_plane(a, b) || separated_by_plane(b, a) {
        return false;
    }
    triangles_may_overlap_projected(a, b)
}

/// The projected half of [`triangles_may_intersect`]: `false` only when the projections of the
/// two triangles onto the coordinate plane most parallel to `b` are certainly separated along one
/// of their six edge normals. Decides exactly coplanar pairs (flat cloth) without exact arithmetic.
#[inline]
pub fn triangles_may_overlap_projected(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    let n = (b[1] - b[0]).cross(&(b[2] - b[0]));
    let (ax, ay, az) = (n.x.abs(), n.y.abs(), n.z.abs());
    let (u, v) = if az >= ax && az >= ay {
        (0, 1)
    } else if ax >= ay {
        (1, 2)
    } else {
        (2, 0)
    };
    let pa = [(a[0][u], a[0][v]), (a[1][u], a[1][v]), (a[2][u], a[2][v])];
    let pb = [(b[0][u], b[0][v]), (b[1][u], b[1][v]), (b[2][u], b[2][v])];
    let mut m = 0.0f64;
    for w in pa.iter().chain(pb.iter()) {
        m = m.max(w.0.abs()).max(w.1.abs());
    }
    let tol = 1e-13 * m * m;
    for tri in [&pa, &pb] {
        for k in 0..3 {
            let (x, y) = (tri[k], tri[(k + 1) % 3]);
            let (nx, ny) = (y.1 - x.1, x.0 - y.0);
            let f = |w: &(f64, f64)| nx * (w.0 - x.0) + ny * (w.1 - x.1);
            let (mut alo, mut ahi, mut blo, mut bhi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for w in &pa {
                let t = f(w);
                alo = alo.min(t);
                ahi = ahi.max(t);
            }
            for w in &pb {
                let t = f(w);
                blo = blo.min(t);
                bhi = bhi.max(t);
            }
            if ahi < blo - tol || bhi < alo - tol {
                return false;
            }
        }
    }
    true
}

/// Parameter `s` in `[0, 1]` along `(p, q)` and barycentric coordinates `(u, v, w)` on `(a, b, c)`
/// of the point where the edge meets the triangle's plane (floating point; used for positions
/// and reports, never for decisions). Degenerate input is clamped to finite values.
pub fn edge_triangle_point(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> (Real, [Real; 3]) {
    let n = (b - a).cross(&(c - a));
    let dp = n.dot(&(p - a));
    let dq = n.dot(&(q - a));
    let s = if dp != dq { dp / (dp - dq) } else { 0.5 };
    let s = if s.is_finite() {
        s.clamp(0.0, 1.0)
    } else {
        0.5
    };
    let x = p + (q - p) * s;
    (s, barycentric(&x, a, b, c))
}

/// Barycentric coordinates of the projection of `x` onto the plane of `(a, b, c)`.
pub fn barycentric(x: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> [Real; 3] {
    let v0 = b - a;
    let v1 = c - a;
    let v2 = x - a;
    let d00 = v0.dot(&v0);
    let d01 = v0.dot(&v1);
    let d11 = v1.dot(&v1);
    let d20 = v2.dot(&v0);
    let d21 = v2.dot(&v1);
    let den = d00 * d11 - d01 * d01;
    if den.abs() <= Real::MIN_POSITIVE || !den.is_finite() {
        return [1.0 / 3.0; 3];
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    [1.0 - v - w, v, w]
}

/// Whether two triangles intersect, by the crossing rule: some edge of one crosses the other,
/// with edges incident to a shared vertex skipped. Triangles sharing an edge never intersect.
///
/// This is the definition used throughout the analysis; it is written independently of the
/// analysis pipeline so it can serve as its brute-force oracle.
pub fn triangles_intersect(t1: [u32; 3], t2: [u32; 3], pos: &[Vec3]) -> bool {
    let shared = t1.iter().filter(|v| t2.contains(v)).count();
    if shared >= 2 {
        return false;
    }
    let test = |ta: [u32; 3], tb: [u32; 3]| {
        (0..3).any(|k| {
            let (i, j) = (ta[k], ta[(k + 1) % 3]);
            if tb.contains(&i) || tb.contains(&j) {
                return false;
            }
            edge_crosses_triangle(
                &pos[i as usize],
                &pos[j as usize],
                &pos[tb[0] as usize],
                &pos[tb[1] as usize],
                &pos[tb[2] as usize],
                [i, j, tb[0], tb[1], tb[2]],
            )
        })
    };
    test(t1, t2) || test(t2, t1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(x, y, z)
    }

    #[test]
    fn simple_crossing_and_miss() {
        let (a, b, c) = (v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.));
        let ids = [3, 4, 0, 1, 2];
        assert!(edge_crosses_triangle(
            &v(0.2, 0.2, -1.),
            &v(0.2, 0.2, 1.),
            &a,
            &b,
            &c,
            ids
        ));
        assert!(!edge_crosses_triangle(
            &v(0.8, 0.8, -1.),
            &v(0.8, 0.8, 1.),
            &a,
            &b,
            &c,
            ids
        ));
        assert!(!edge_crosses_triangle(
            &v(0.2, 0.2, 0.5),
            &v(0.2, 0.2, 1.),
            &a,
            &b,
            &c,
            ids
        ));
        let (s, bc) = edge_triangle_point(&v(0.2, 0.2, -1.), &v(0.2, 0.2, 1.), &a, &b, &c);
        assert!((s - 0.5).abs() < 1e-12);
        assert!((bc[1] - 0.2).abs() < 1e-12 && (bc[2] - 0.2).abs() < 1e-12);
    }

    /// Exact rational crossing test for generic input (no ties): the oracle for the fast path.
    fn exact_generic(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Option<bool> {
        let o =
            |x: &Vec3, y: &Vec3, z: &Vec3, w: &Vec3| super::super::predicates::orient3d(x, y, z, w);
        let (sp, sq) = (o(a, b, c, p), o(a, b, c, q));
        let (s1, s2, s3) = (o(p, q, a, b), o(p, q, b, c), o(p, q, c, a));
        if [sp, sq, s1, s2, s3].contains(&0.0) {
            return None;
        }
        Some(sp.signum() != sq.signum() && s1.signum() == s2.signum() && s2.signum() == s3.signum())
    }

    proptest! {
        #[test]
        fn agrees_with_exact_test_on_generic_input(
            pts in proptest::array::uniform5(proptest::array::uniform3(-1.0f64..1.0))
        ) {
            let p: Vec<Vec3> = pts.iter().map(|c| v(c[0], c[1], c[2])).collect();
            if let Some(expected) = exact_generic(&p[0], &p[1], &p[2], &p[3], &p[4]) {
                let got = edge_crosses_triangle(&p[0], &p[1], &p[2], &p[3], &p[4], [0, 1, 2, 3, 4]);
                prop_assert_eq!(got, expected);
                if got {
                    prop_assert!(edge_may_cross_plane(&p[0], &p[1], &p[2], &p[3], &p[4]));
                    prop_assert!(edge_may_overlap_projected(&p[0], &p[1], &p[2], &p[3], &p[4]));
                }
            }
        }

        /// Certified plane sides agree with the exact orientation, and the straddling shortcut
        /// agrees with the full test whenever the sides are certified opposite.
        #[test]
        fn certified_sides_and_straddling_shortcut(
            pts in proptest::array::uniform5(proptest::array::uniform3(-1.0f64..1.0)),
            lattice in proptest::array::uniform5(proptest::array::uniform3(-2i32..=2)),
        ) {
            for p in [
                pts.iter().map(|c| v(c[0], c[1], c[2])).collect::<Vec<_>>(),
                lattice.iter().map(|c| v(c[0] as f64, c[1] as f64, c[2] as f64)).collect::<Vec<_>>(),
            ] {
                let plane = CertifiedPlane::new(&p[2], &p[3], &p[4]);
                let exact = |x: &Vec3| -super::super::predicates::orient3d(&p[2], &p[3], &p[4], x).signum();
                for x in [&p[0], &p[1]] {
                    let s = plane.side(x);
                    if s != 0 {
                        prop_assert_eq!(s as f64, exact(x));
                    }
                }
                let (sp, sq) = (plane.side(&p[0]), plane.side(&p[1]));
                if sp != 0 && sq != 0 && sp != sq {
                    prop_assert_eq!(
                        straddling_edge_crosses_triangle(&p[0], &p[1], &p[2], &p[3], &p[4], [0, 1, 2, 3, 4]),
                        edge_crosses_triangle(&p[0], &p[1], &p[2], &p[3], &p[4], [0, 1, 2, 3, 4])
                    );
                }
            }
        }

        /// The fast straddling test always gives the exact answer.
        #[test]
        fn fast_straddling_test_is_exact(
            pts in proptest::array::uniform5(proptest::array::uniform3(-1.0f64..1.0)),
            lattice in proptest::array::uniform5(proptest::array::uniform3(-2i32..=2)),
            tiny in 1e-12f64..1e-6,
        ) {
            let near: Vec<Vec3> = pts.iter().enumerate().map(|(i, c)| {
                // Nearly degenerate: the edge almost through a triangle corner.
                if i == 1 { v(pts[2][0], pts[2][1], pts[2][2]) * 2.0 - v(pts[0][0], pts[0][1], pts[0][2]) + v(tiny, -tiny, tiny) } else { v(c[0], c[1], c[2]) }
            }).collect();
            for p in [
                pts.iter().map(|c| v(c[0], c[1], c[2])).collect::<Vec<_>>(),
                lattice.iter().map(|c| v(c[0] as f64, c[1] as f64, c[2] as f64)).collect::<Vec<_>>(),
                near,
            ] {
                let ids = [0, 1, 2, 3, 4];
                prop_assert_eq!(
                    straddling_edge_crosses_triangle_fast(&p[0], &p[1], &p[2], &p[3], &p[4], ids),
                    straddling_edge_crosses_triangle(&p[0], &p[1], &p[2], &p[3], &p[4], ids)
                );
            }
        }

        /// The filtered exact test equals the exact test, on random, lattice (ties) and
        /// near-degenerate input (an endpoint on or near the triangle's plane).
        #[test]
        fn filtered_test_is_exact(
            pts in proptest::array::uniform5(proptest::array::uniform3(-1.0f64..1.0)),
            lattice in proptest::array::uniform5(proptest::array::uniform3(-2i32..=2)),
            tiny in prop_oneof![Just(0.0), 1e-17f64..1e-12],
        ) {
            let rnd: Vec<Vec3> = pts.iter().map(|c| v(c[0], c[1], c[2])).collect();
            let mut onplane = rnd.clone();
            let n = (rnd[3] - rnd[2]).cross(&(rnd[4] - rnd[2]));
            let d = n.dot(&(rnd[0] - rnd[2])) / n.norm_squared();
            onplane[0] = rnd[0] - n * d + v(tiny, 0.0, -tiny);
            for p in [
                rnd,
                lattice.iter().map(|c| v(c[0] as f64, c[1] as f64, c[2] as f64)).collect::<Vec<_>>(),
                onplane,
            ] {
                let ids = [0, 1, 2, 3, 4];
                prop_assert_eq!(
                    edge_crosses_triangle_filtered(&p[0], &p[1], &p[2], &p[3], &p[4], ids),
                    edge_crosses_triangle(&p[0], &p[1], &p[2], &p[3], &p[4], ids)
                );
            }
        }

        /// The pair filter never rejects an intersecting pair, generic or with ties.
        #[test]
        fn pair_filter_never_rejects_an_intersection(
            pts in proptest::array::uniform6(proptest::array::uniform3(-2i32..=2)),
            jitter in proptest::bool::ANY,
        ) {
            let mut p: Vec<Vec3> = pts.iter().map(|c| v(c[0] as f64, c[1] as f64, c[2] as f64)).collect();
            if jitter {
                for (i, q) in p.iter_mut().enumerate() {
                    *q += v(0.013 * i as f64, -0.007 * i as f64, 0.011);
                }
            }
            if triangles_intersect([0, 1, 2], [3, 4, 5], &p) {
                prop_assert!(triangles_may_intersect(&[p[0], p[1], p[2]], &[p[3], p[4], p[5]]));
                prop_assert!(triangles_may_intersect(&[p[3], p[4], p[5]], &[p[0], p[1], p[2]]));
            }
        }

        /// The filters never reject a crossing decided with ties (integer lattice, many exactly
        /// coplanar configurations).
        #[test]
        fn filters_never_reject_a_crossing_with_ties(
            pts in proptest::array::uniform5(proptest::array::uniform3(-2i32..=2)),
        ) {
            let p: Vec<Vec3> = pts.iter().map(|c| v(c[0] as f64, c[1] as f64, c[2] as f64)).collect();
            if edge_crosses_triangle(&p[0], &p[1], &p[2], &p[3], &p[4], [0, 1, 2, 3, 4]) {
                prop_assert!(edge_may_cross_plane(&p[0], &p[1], &p[2], &p[3], &p[4]));
                prop_assert!(edge_may_overlap_projected(&p[0], &p[1], &p[2], &p[3], &p[4]));
            }
        }

        /// A closed polyline crosses the closed surface of a tetrahedron an even number of times,
        /// however degenerate the coordinates: the tie rule is globally consistent.
        #[test]
        fn closed_curve_crosses_closed_surface_evenly(
            tet in proptest::array::uniform4(proptest::array::uniform3(-2i32..=2)),
            curve in proptest::collection::vec(proptest::array::uniform3(-2i32..=2), 3..7),
        ) {
            let mut pos: Vec<Vec3> = tet.iter().map(|c| v(c[0] as f64, c[1] as f64, c[2] as f64)).collect();
            let base = pos.len() as u32;
            pos.extend(curve.iter().map(|c| v(c[0] as f64, c[1] as f64, c[2] as f64)));
            let faces = [[0u32, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]];
            let n = curve.len() as u32;
            let mut count = 0;
            for k in 0..n {
                let (i, j) = (base + k, base + (k + 1) % n);
                for f in faces {
                    if edge_crosses_triangle(&pos[i as usize], &pos[j as usize], &pos[f[0] as usize], &pos[f[1] as usize], &pos[f[2] as usize], [i, j, f[0], f[1], f[2]]) {
                        count += 1;
                    }
                }
            }
            prop_assert_eq!(count % 2, 0);
        }
    }
}
