//! All edge-triangle crossings of a triangle pair decided at once, in floating point with
//! certified error bounds (the crossings of Wicke et al. 2006, Sec. 4, between two triangles
//! without a common vertex).
//!
//! When every corner of each triangle is certainly strictly on one side of the other's plane and
//! both triangles straddle the other's plane, the common line `L` of the two planes meets each
//! triangle in an interval whose ends lie on its two *straddling* edges. An edge `e` of one
//! triangle that straddles the other triangle `T` meets `T`'s plane in a point `X` of `L`; `X` is
//! inside `T` iff it lies between the two ends of `T`'s interval, i.e. iff the edge-edge
//! orientations `orient3d(e, f1)` and `orient3d(e, f2)` with `T`'s straddling edges `f1`, `f2` have
//! the same sign (the third orientation, with `T`'s non-straddling edge, then agrees as well:
//! the open interval lies inside `T`). Both directions use the same four orientations, so a pair
//! costs six plane sides and four orientations instead of up to twelve orientations edge by edge.
//! Whenever a sign is not certified the pair is [`PairOutcome::Undecided`] and the caller falls
//! back to the exact, symbolically perturbed tests; every certified answer equals the exact one,
//! so the results are identical.

use super::tri_tri::CertifiedPlane;
use super::{Real, Vec3};

/// A triangle with what the pair kernel needs: corners (by axis, so the three plane sides of a
/// pair are computed lane-wise), plane and error-bound factors.
#[derive(Clone, Copy, Debug)]
pub struct PreparedTriangle {
    /// Corner coordinates by axis: `x[i]` is corner `i`'s x; lane 3 repeats corner 0.
    x: [Real; 4],
    /// Corner y coordinates (lane 3 repeats corner 0).
    y: [Real; 4],
    /// Corner z coordinates (lane 3 repeats corner 0).
    z: [Real; 4],
    /// Unnormalised normal `(c1 - c0) x (c2 - c0)`.
    n: Vec3,
    /// Forward error factor of the plane side `n . (p - c0)` per unit of `|p - c0|_1`.
    k: Real,
    /// Largest L1 distance of a corner from `c0`.
    reach: Real,
    /// L1 length of edge `c[i] -> c[i + 1]`.
    edge_l1: [Real; 3],
}

/// What [`pair_crossings`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairOutcome {
    /// One triangle is certainly strictly on one side of the other's plane: no crossing.
    Apart,
    /// The exact answer for every edge: bit `i` = edge `i` of `a` crosses `b`, bit `3 + j` =
    /// edge `j` of `b` crosses `a` (edge `i` runs from corner `i` to corner `i + 1`).
    Crossings(u8),
    /// Not certified; the certified plane sides (`0` = too close to tell) of `a`'s corners with
    /// respect to `b`'s plane and of `b`'s corners with respect to `a`'s plane, in the sign
    /// convention of [`super::tri_tri::CertifiedPlane::side`].
    Undecided {
        /// Sides of `a`'s corners.
        sides_a: [i8; 3],
        /// Sides of `b`'s corners.
        sides_b: [i8; 3],
    },
}

#[inline]
fn l1(v: &Vec3) -> Real {
    v.x.abs() + v.y.abs() + v.z.abs()
}

/// Relative forward error bound used for the plane sides and the edge-edge orientations: a
/// triple product of rounded differences has a relative error of about 8 ulps of the product of
/// the L1 norms; 1e-14 leaves a wide margin (also for the rounding of the norms themselves).
const EPS: Real = 1e-14;

impl PreparedTriangle {
    /// Prepares triangle `(a, b, c)`.
    #[inline]
    pub fn new(a: &Vec3, b: &Vec3, c: &Vec3) -> Self {
        let (ab, ac, bc) = (b - a, c - a, c - b);
        let (lab, lac) = (l1(&ab), l1(&ac));
        PreparedTriangle {
            x: [a.x, b.x, c.x, a.x],
            y: [a.y, b.y, c.y, a.y],
            z: [a.z, b.z, c.z, a.z],
            n: ab.cross(&ac),
            k: EPS * lab * lac,
            reach: lab.max(lac),
            edge_l1: [lab, l1(&bc), lac],
        }
    }

    /// Corner `i`.
    #[inline]
    pub fn corner(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// The certified plane of the triangle (the same plane and bound as
    /// [`CertifiedPlane::new`] on its corners).
    #[inline]
    pub fn plane(&self) -> CertifiedPlane {
        CertifiedPlane::from_parts(self.n, self.corner(0), self.k)
    }
}

/// The L1 radius of a pair: every corner difference is bounded in L1 by the two reaches plus
/// the distance of the first corners.
#[inline(always)]
fn pair_reach(a: &PreparedTriangle, b: &PreparedTriangle) -> Real {
    let d0 = Vec3::new(a.x[0] - b.x[0], a.y[0] - b.y[0], a.z[0] - b.z[0]);
    a.reach + b.reach + l1(&d0)
}

/// Certified sides of `p`'s corners with respect to `plane`'s plane, with `|p_i - c0|_1 <= r`,
/// as two bit masks: bit `i` of the first = corner `i` certainly on the positive side, of the
/// second = certainly on the negative side. Each side is `n.x (x - o.x) + n.y (y - o.y) + n.z (z - o.z)`, rounded the
/// same way in both versions below (two lanes at a time with SSE2, the x86-64 baseline).
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline(always)]
fn side_masks(p: &PreparedTriangle, plane: &PreparedTriangle, r: Real) -> (u8, u8) {
    // SAFETY: SSE2 is enabled at compile time (the cfg above; it is part of the x86-64
    // baseline); the loads stay inside the corner arrays (see the body).
    unsafe { side_masks_sse2(p, plane, r) }
}

/// The SSE2 body of [`side_masks`].
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline(always)]
unsafe fn side_masks_sse2(p: &PreparedTriangle, plane: &PreparedTriangle, r: Real) -> (u8, u8) {
    use std::arch::x86_64::*;
    let (ox, oy, oz) = (
        _mm_set1_pd(plane.x[0]),
        _mm_set1_pd(plane.y[0]),
        _mm_set1_pd(plane.z[0]),
    );
    let (nx, ny, nz) = (
        _mm_set1_pd(plane.n.x),
        _mm_set1_pd(plane.n.y),
        _mm_set1_pd(plane.n.z),
    );
    // Lanes (corner 0, corner 1) and (corner 2, corner 0 again). SAFETY of the loads: each
    // coordinate array has four elements, so lanes `lo` and `lo + 1` are in bounds for lo <= 2.
    let side = |lo: usize| {
        let x = _mm_loadu_pd(p.x.as_ptr().add(lo));
        let y = _mm_loadu_pd(p.y.as_ptr().add(lo));
        let z = _mm_loadu_pd(p.z.as_ptr().add(lo));
        _mm_add_pd(
            _mm_add_pd(
                _mm_mul_pd(nx, _mm_sub_pd(x, ox)),
                _mm_mul_pd(ny, _mm_sub_pd(y, oy)),
            ),
            _mm_mul_pd(nz, _mm_sub_pd(z, oz)),
        )
    };
    let (s01, s23) = (side(0), side(2));
    let t = plane.k * r;
    let (tol, ntol) = (_mm_set1_pd(t), _mm_set1_pd(-t));
    // Ordered comparisons: false for NaN, so NaN is never certified.
    let pos =
        _mm_movemask_pd(_mm_cmpgt_pd(s01, tol)) | (_mm_movemask_pd(_mm_cmpgt_pd(s23, tol)) << 2);
    let neg =
        _mm_movemask_pd(_mm_cmplt_pd(s01, ntol)) | (_mm_movemask_pd(_mm_cmplt_pd(s23, ntol)) << 2);
    ((pos & 7) as u8, (neg & 7) as u8)
}

/// Portable version of the side masks above.
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
#[inline(always)]
fn side_masks(p: &PreparedTriangle, plane: &PreparedTriangle, r: Real) -> (u8, u8) {
    side_masks_scalar(p, plane, r)
}

/// The side masks one corner at a time (the reference for the SSE2 version).
#[cfg(any(test, not(all(target_arch = "x86_64", target_feature = "sse2"))))]
#[inline(always)]
fn side_masks_scalar(p: &PreparedTriangle, plane: &PreparedTriangle, r: Real) -> (u8, u8) {
    let tol = plane.k * r;
    let (ox, oy, oz) = (plane.x[0], plane.y[0], plane.z[0]);
    let n = plane.n;
    let (mut pos, mut neg) = (0u8, 0u8);
    for i in 0..3 {
        let s = n.x * (p.x[i] - ox) + n.y * (p.y[i] - oy) + n.z * (p.z[i] - oz);
        pos |= ((s > tol) as u8) << i;
        neg |= ((s < -tol) as u8) << i;
    }
    (pos, neg)
}

/// The side masks as signs (`+1`, `-1`, `0` = not certified).
#[inline]
fn signs((pos, neg): (u8, u8)) -> [i8; 3] {
    std::array::from_fn(|i| ((pos >> i) & 1) as i8 - ((neg >> i) & 1) as i8)
}

/// For a positive-side mask of a straddling triangle (1..=6, all corners certified): its two
/// straddling edges, i.e. the two edges at the corner alone on its side.
const STRADDLING: [[usize; 2]; 7] = [[0, 0], [2, 0], [0, 1], [1, 2], [1, 2], [0, 1], [2, 0]];

/// Decides every edge-triangle crossing between triangles `a` and `b`, which must not share a
/// vertex; see the module docs. A
/// certified answer is the exact one, also under the symbolic perturbation of
/// [`super::predicates::orient3d_sos`] (certified values are non-zero).
#[inline(always)]
pub fn pair_crossings(a: &PreparedTriangle, b: &PreparedTriangle) -> PairOutcome {
    let r = pair_reach(a, b);
    let ma = side_masks(a, b, r);
    if ma.0 == 7 || ma.1 == 7 {
        return PairOutcome::Apart;
    }
    let mb = side_masks(b, a, r);
    if mb.0 == 7 || mb.1 == 7 {
        return PairOutcome::Apart;
    }
    if (ma.0 | ma.1) != 7 || (mb.0 | mb.1) != 7 {
        return PairOutcome::Undecided {
            sides_a: signs(ma),
            sides_b: signs(mb),
        };
    }
    let (ia, ib) = (STRADDLING[ma.0 as usize], STRADDLING[mb.0 as usize]);
    let Some(pos) = orientations(a, b, ia, ib, r) else {
        return PairOutcome::Undecided {
            sides_a: signs(ma),
            sides_b: signs(mb),
        };
    };
    let mut mask = 0u8;
    for x in 0..2 {
        mask |= ((pos[x][0] == pos[x][1]) as u8) << ia[x];
    }
    for y in 0..2 {
        mask |= ((pos[0][y] == pos[1][y]) as u8) << (3 + ib[y]);
    }
    PairOutcome::Crossings(mask)
}

/// Next corner of each corner.
const NEXT: [usize; 3] = [1, 2, 0];

/// The four certified edge-edge orientations of a straddling pair: `o[x][y]` is whether
/// `det[q - p, s - p, t - p] > 0` for `a`'s straddling edge `ia[x]` = `(p, q)` and `b`'s
/// straddling edge `ib[y]` = `(s, t)`; `None` when one of them is within its error bound
/// `EPS r |q - p|_1 |t - s|_1` (or NaN). Two lanes (`y = 0, 1`) at a time with SSE2 (the x86-64
/// baseline), the same operations in the same order as the scalar reference below.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline(always)]
fn orientations(
    a: &PreparedTriangle,
    b: &PreparedTriangle,
    ia: [usize; 2],
    ib: [usize; 2],
    r: Real,
) -> Option<[[bool; 2]; 2]> {
    use std::arch::x86_64::*;
    let (j0, j1) = (ib[0], ib[1]);
    let (n0, n1) = (NEXT[j0], NEXT[j1]);
    let ca = |i: usize| (a.x[i], a.y[i], a.z[i]);
    let ea = |i: usize| {
        let n = NEXT[i];
        (a.x[n] - a.x[i], a.y[n] - a.y[i], a.z[n] - a.z[i])
    };
    let er = EPS * r;
    let (la0, la1) = (er * a.edge_l1[ia[0]], er * a.edge_l1[ia[1]]);
    let (ea0, ea1, p0, p1) = (ea(ia[0]), ea(ia[1]), ca(ia[0]), ca(ia[1]));
    // SAFETY: SSE2 is enabled at compile time (the cfg above); only register operations.
    let bits = unsafe {
        // Lane y holds b's straddling edge ib[y]: start s, direction t - s, L1 length.
        let lanes = |v: &[Real; 4], i: usize, k: usize| _mm_set_pd(v[k], v[i]);
        let (sx, sy, sz) = (
            lanes(&b.x, j0, j1),
            lanes(&b.y, j0, j1),
            lanes(&b.z, j0, j1),
        );
        let (ebx, eby, ebz) = (
            _mm_sub_pd(lanes(&b.x, n0, n1), sx),
            _mm_sub_pd(lanes(&b.y, n0, n1), sy),
            _mm_sub_pd(lanes(&b.z, n0, n1), sz),
        );
        let lb = _mm_set_pd(b.edge_l1[j1], b.edge_l1[j0]);
        let sign = _mm_set1_pd(-0.0);
        let zero = _mm_setzero_pd();
        let row = |(ex, ey, ez): (Real, Real, Real), (px, py, pz): (Real, Real, Real), la: Real| {
            let (eax, eay, eaz) = (_mm_set1_pd(ex), _mm_set1_pd(ey), _mm_set1_pd(ez));
            let (rx, ry, rz) = (
                _mm_sub_pd(sx, _mm_set1_pd(px)),
                _mm_sub_pd(sy, _mm_set1_pd(py)),
                _mm_sub_pd(sz, _mm_set1_pd(pz)),
            );
            // (t - s) x (q - p), then dotted with s - p.
            let cx = _mm_sub_pd(_mm_mul_pd(eby, eaz), _mm_mul_pd(ebz, eay));
            let cy = _mm_sub_pd(_mm_mul_pd(ebz, eax), _mm_mul_pd(ebx, eaz));
            let cz = _mm_sub_pd(_mm_mul_pd(ebx, eay), _mm_mul_pd(eby, eax));
            let o = _mm_add_pd(
                _mm_add_pd(_mm_mul_pd(rx, cx), _mm_mul_pd(ry, cy)),
                _mm_mul_pd(rz, cz),
            );
            let bound = _mm_mul_pd(_mm_set1_pd(la), lb);
            // Ordered comparison: NaN is never certified.
            let certified = _mm_movemask_pd(_mm_cmpgt_pd(_mm_andnot_pd(sign, o), bound));
            let positive = _mm_movemask_pd(_mm_cmpgt_pd(o, zero));
            (certified, positive)
        };
        let (c0, s0) = row(ea0, p0, la0);
        let (c1, s1) = row(ea1, p1, la1);
        (c0 & c1, s0 | s1 << 2)
    };
    if bits.0 != 3 {
        return None;
    }
    let s = bits.1;
    Some([[s & 1 != 0, s & 2 != 0], [s & 4 != 0, s & 8 != 0]])
}

/// Portable version of [`orientations`].
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
#[inline(always)]
fn orientations(
    a: &PreparedTriangle,
    b: &PreparedTriangle,
    ia: [usize; 2],
    ib: [usize; 2],
    r: Real,
) -> Option<[[bool; 2]; 2]> {
    orientations_scalar(a, b, ia, ib, r)
}

/// The orientations one at a time (the reference for the SSE2 version).
#[cfg(any(test, not(all(target_arch = "x86_64", target_feature = "sse2"))))]
#[inline(always)]
fn orientations_scalar(
    a: &PreparedTriangle,
    b: &PreparedTriangle,
    ia: [usize; 2],
    ib: [usize; 2],
    r: Real,
) -> Option<[[bool; 2]; 2]> {
    let edge = |t: &PreparedTriangle, i: usize| {
        let j = NEXT[i];
        [t.x[j] - t.x[i], t.y[j] - t.y[i], t.z[j] - t.z[i]]
    };
    let er = EPS * r;
    let mut pos = [[false; 2]; 2];
    for x in 0..2 {
        let i = ia[x];
        let (ea, p) = (edge(a, i), [a.x[i], a.y[i], a.z[i]]);
        let la = er * a.edge_l1[i];
        for y in 0..2 {
            let j = ib[y];
            let eb = edge(b, j);
            let rr = [b.x[j] - p[0], b.y[j] - p[1], b.z[j] - p[2]];
            let c = [
                eb[1] * ea[2] - eb[2] * ea[1],
                eb[2] * ea[0] - eb[0] * ea[2],
                eb[0] * ea[1] - eb[1] * ea[0],
            ];
            let o = (rr[0] * c[0] + rr[1] * c[1]) + rr[2] * c[2];
            let bound = la * b.edge_l1[j];
            // NaN is never certified.
            let certified = o.abs() > bound;
            if !certified {
                return None;
            }
            pos[x][y] = o > 0.0;
        }
    }
    Some(pos)
}

#[cfg(test)]
mod tests {
    use super::super::tri_tri::edge_crosses_triangle;
    use super::*;
    use proptest::prelude::*;

    fn v(c: [f64; 3]) -> Vec3 {
        Vec3::new(c[0], c[1], c[2])
    }

    /// The exact, symbolically perturbed answer for every edge of the pair (the oracle).
    fn exact_mask(p: &[Vec3; 6]) -> u8 {
        let mut mask = 0;
        for (off, (x, y)) in [(0u8, (0usize, 3usize)), (3, (3, 0))] {
            for i in 0..3 {
                let (e0, e1) = (x + i, x + (i + 1) % 3);
                let ids = [e0 as u32, e1 as u32, y as u32, y as u32 + 1, y as u32 + 2];
                if edge_crosses_triangle(&p[e0], &p[e1], &p[y], &p[y + 1], &p[y + 2], ids) {
                    mask |= 1 << (off + i as u8);
                }
            }
        }
        mask
    }

    /// The kernel's L1 radius of a pair (reaches plus the distance of the first corners).
    fn pts_reach(p: &[Vec3; 6]) -> f64 {
        let l1 = |v: Vec3| v.x.abs() + v.y.abs() + v.z.abs();
        let reach = |q: &[Vec3]| l1(q[1] - q[0]).max(l1(q[2] - q[0]));
        reach(&p[..3]) + reach(&p[3..]) + l1(p[0] - p[3])
    }

    fn prep(p: &[Vec3; 6]) -> (PreparedTriangle, PreparedTriangle) {
        (
            PreparedTriangle::new(&p[0], &p[1], &p[2]),
            PreparedTriangle::new(&p[3], &p[4], &p[5]),
        )
    }

    fn check(p: &[Vec3; 6]) -> Result<(), TestCaseError> {
        let (a, b) = prep(p);
        for i in 0..3 {
            prop_assert_eq!(a.corner(i), p[i]);
            prop_assert_eq!(b.corner(i), p[3 + i]);
        }
        // The SSE2 plane sides equal the scalar ones, for the kernel's radius and for zero
        // tolerance (the plain signs, exact ties included).
        for r in [1.0, 0.0, pts_reach(p)] {
            prop_assert_eq!(side_masks(&a, &b, r), side_masks_scalar(&a, &b, r));
            prop_assert_eq!(side_masks(&b, &a, r), side_masks_scalar(&b, &a, r));
        }
        prop_assert_eq!(
            a.plane().normal(),
            CertifiedPlane::new(&p[0], &p[1], &p[2]).normal()
        );
        // The SSE2 orientations equal the scalar ones, for every pair of edge pairs (elsewhere
        // `orientations` is the scalar one).
        #[cfg(target_arch = "x86_64")]
        for ia in [[0, 1], [1, 2], [2, 0]] {
            let r = pair_reach(&a, &b);
            for ib in [[0, 1], [1, 2], [2, 0]] {
                prop_assert_eq!(
                    orientations(&a, &b, ia, ib, r),
                    orientations_scalar(&a, &b, ia, ib, r)
                );
            }
        }
        let exact = exact_mask(p);
        match pair_crossings(&a, &b) {
            PairOutcome::Apart => prop_assert_eq!(exact, 0),
            PairOutcome::Crossings(m) => prop_assert_eq!(m, exact),
            PairOutcome::Undecided { sides_a, sides_b } => {
                // Certified sides agree with the exact plane sides (the sign convention of
                // `CertifiedPlane::side`: that of `-orient3d`).
                let exact_side = |q: &[Vec3], x: &Vec3| {
                    -super::super::predicates::orient3d(&q[0], &q[1], &q[2], x).signum() as i8
                };
                for i in 0..3 {
                    if sides_a[i] != 0 {
                        prop_assert_eq!(sides_a[i], exact_side(&p[3..], &p[i]));
                    }
                    if sides_b[i] != 0 {
                        prop_assert_eq!(sides_b[i], exact_side(&p[..3], &p[3 + i]));
                    }
                    let (pa, pb) = (
                        CertifiedPlane::new(&p[0], &p[1], &p[2]),
                        CertifiedPlane::new(&p[3], &p[4], &p[5]),
                    );
                    // Never certified where the per-corner test is not (same convention).
                    if sides_a[i] != 0 && pb.side(&p[i]) != 0 {
                        prop_assert_eq!(sides_a[i], pb.side(&p[i]));
                    }
                    if sides_b[i] != 0 && pa.side(&p[3 + i]) != 0 {
                        prop_assert_eq!(sides_b[i], pa.side(&p[3 + i]));
                    }
                }
            }
        }
        Ok(())
    }

    proptest! {
        /// Random pairs: every decided pair matches the exact edge-by-edge test.
        #[test]
        fn decided_pairs_match_the_exact_test(
            pts in proptest::array::uniform6(proptest::array::uniform3(-1.0f64..1.0)),
            scale in 1e-3f64..1e3,
            shift in proptest::array::uniform3(-100.0f64..100.0),
        ) {
            let s = v(shift);
            let p: [Vec3; 6] = std::array::from_fn(|i| v(pts[i]) * scale + s);
            check(&p)?;
        }

        /// Near-degenerate pairs: an edge through (almost) a corner or an edge of the other
        /// triangle, corners (almost) in the other plane, and integer lattices with exact ties.
        #[test]
        fn near_degenerate_pairs_match_the_exact_test(
            pts in proptest::array::uniform6(proptest::array::uniform3(-1.0f64..1.0)),
            lattice in proptest::array::uniform6(proptest::array::uniform3(-2i32..=2)),
            tiny in prop_oneof![Just(0.0), 1e-17f64..1e-15, 1e-15f64..1e-9],
            which in 0usize..6,
            t in 0.0f64..1.0,
        ) {
            let p: [Vec3; 6] = std::array::from_fn(|i| v(pts[i]));
            // Corner `which` moved onto (near) a point of the other triangle's edge 0, or onto
            // (near) the other triangle's plane.
            let other = if which < 3 { 3 } else { 0 };
            let on_edge = p[other] + (p[other + 1] - p[other]) * t;
            let mut q = p;
            q[which] = on_edge + Vec3::new(tiny, -tiny, 0.5 * tiny);
            check(&q)?;
            let n = (p[other + 1] - p[other]).cross(&(p[other + 2] - p[other]));
            let mut r = p;
            let d = n.dot(&(p[which] - p[other])) / n.norm_squared();
            r[which] = p[which] - n * d + Vec3::new(tiny, tiny, -tiny);
            check(&r)?;
            let l: [Vec3; 6] = std::array::from_fn(|i| {
                Vec3::new(lattice[i][0] as f64, lattice[i][1] as f64, lattice[i][2] as f64)
            });
            check(&l)?;
        }
    }

    /// The kernel decides almost every random pair (so the tests above exercise it), and every
    /// decision matches the oracle.
    #[test]
    fn random_pairs_are_mostly_decided() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut crossing, mut apart, mut undecided) = (0, 0, 0);
        for _ in 0..4000 {
            let p: [Vec3; 6] = std::array::from_fn(|_| {
                Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
            });
            let (a, b) = prep(&p);
            match pair_crossings(&a, &b) {
                PairOutcome::Crossings(m) => {
                    assert_eq!(m, exact_mask(&p));
                    crossing += (m != 0) as usize;
                }
                PairOutcome::Apart => {
                    assert_eq!(exact_mask(&p), 0);
                    apart += 1;
                }
                PairOutcome::Undecided { .. } => undecided += 1,
            }
        }
        assert!(crossing > 500 && apart > 500, "{crossing} {apart}");
        assert!(undecided < 10, "{undecided}");
    }

    #[test]
    fn a_piercing_pair_is_decided_exactly() {
        // Triangle b pierces a through its interior: b's edges 1 and 2 cross a.
        let p = [
            v([0.0, 0.0, 0.0]),
            v([1.0, 0.0, 0.0]),
            v([0.0, 1.0, 0.0]),
            v([0.2, 0.2, 1.0]),
            v([0.3, 0.2, -1.0]),
            v([0.2, 0.3, -1.0]),
        ];
        let (a, b) = prep(&p);
        assert_eq!(
            pair_crossings(&a, &b),
            PairOutcome::Crossings(exact_mask(&p))
        );
        assert_eq!(exact_mask(&p), 0b101000);
        // Far apart along z.
        let far: [Vec3; 6] =
            std::array::from_fn(|i| p[i] + Vec3::new(0.0, 0.0, 3.0 * (i / 3) as f64));
        let (a2, b2) = prep(&far);
        assert_eq!(pair_crossings(&a2, &b2), PairOutcome::Apart);
    }
}
