//! Screening's cheap rejection tests four candidates at a time (Bridson et al. 2002, Sec. 7.2:
//! proximity only looks at pairs within reach; Sec. 7.3: the first CCD pass only at pairs whose
//! start gap the step's motion can close).
//!
//! For four cloth pairs of one kind, [`Lanes::reject4`] computes what [`super::proximity::screen_pair`]
//! computes before any closest points — the relative speed and the primitives' speeds, the
//! thresholds (dormant, far, CCD), the separating axes through the centres and along the normal,
//! and for edge pairs the in-plane axes — with the same floating-point operations in the same
//! order, one pair per lane of an AVX2 register (the selects of `f64::min` / `f64::max` and of
//! the scalar code's comparisons reproduced, NaNs included). A lane is *decided* when
//! `screen_pair` would return [`super::proximity::Verdict::Far`] or
//! [`super::proximity::Verdict::Dormant`] from these tests with the first CCD pass's test
//! settled too; every other pair (about a quarter on a swinging garment) takes the scalar path,
//! which gives it exactly what it gave before (test `lanes_decide_exactly_what_screen_pair_decides_early`).

/// Per cloth vertex, what screening reads (see [`super::screen`]): the start position (as
/// [`super::Scene::position`] gives it at `t = 0`), the velocity, and its
/// [`super::proximity::NodeStats`] (speed, largest absolute velocity and position coordinate).
/// Nine doubles in a row, so the lanes gather each field with one stride.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub struct Row {
    /// Start position.
    pub x: [f64; 3],
    /// Velocity.
    pub v: [f64; 3],
    /// `|v|`.
    pub speed: f64,
    /// Largest absolute coordinate of the velocity.
    pub vel_max: f64,
    /// Largest absolute coordinate of the start position.
    pub pos_max: f64,
}

/// Doubles per [`Row`].
const STRIDE: usize = 9;

/// The settings [`Lanes::reject4`] shares across lanes.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Step length.
    pub h: f64,
    /// CCD thickness over proximity thickness ([`super::Scene::ccd_ratio`]).
    pub ccd_ratio: f64,
    /// Whether inert pairs may be dormant (`screen_pair`'s `lazy`).
    pub lazy: bool,
}

/// What [`Lanes::reject4`] found, lane `l` in bit `l` of the masks and in entry `l` of the
/// arrays.
#[derive(Clone, Copy, Debug, Default)]
pub struct Early {
    /// Decided: `screen_pair` returns far or dormant before computing closest points, with the
    /// first CCD pass's test settled.
    pub decided: u32,
    /// Of the decided lanes, those that are dormant (the others are far).
    pub dormant: u32,
    /// Undecided by every cheap test: `screen_pair` goes on to the closest points
    /// ([`super::proximity::screen_closest`]) with the start gap `gap`, coordinate scale
    /// `scale` and `ccd_settled` as in `ccd_settled`. (Lanes in neither mask: a verdict without
    /// the CCD test settled; the scalar path takes them.)
    pub closest: u32,
    /// Whether the start gap settles the first CCD pass's test.
    pub ccd_settled: u32,
    /// The start gap (`screen_pair`'s lower distance bound before the in-plane axes).
    pub gap: [f64; 4],
    /// The coordinate scale.
    pub scale: [f64; 4],
}

/// Proof that the CPU runs [`Lanes::reject4`] (AVX2), detected once per screening pass.
#[derive(Clone, Copy, Debug)]
pub struct Lanes(());

impl Lanes {
    /// `Some` when the CPU has AVX2; without it screening takes the scalar path for every
    /// pair.
    pub fn detect() -> Option<Lanes> {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                return Some(Lanes(()));
            }
        }
        None
    }

    /// The early verdicts of four cloth pairs of one kind (vertex-triangle when `VT`, else
    /// edge-edge) with nodes `nodes` (rows of `rows`) and thicknesses `eps` (see [`Early`]).
    /// `None` when a node is not a row of `rows`.
    #[inline]
    pub fn reject4<const VT: bool>(
        self,
        rows: &[Row],
        nodes: &[[u32; 4]; 4],
        eps: [f64; 4],
        s: Settings,
    ) -> Option<Early> {
        // (The lanes check every node against the rows before reading them.)
        if rows.is_empty() || rows.len() > (i64::MAX as usize) / STRIDE {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: `Lanes` exists only with AVX2.
            unsafe { avx::reject4::<VT>(rows, nodes, eps, s) }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = (eps, s);
            unreachable!("no lanes without x86-64")
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    //! [`super::Lanes::reject4`] in AVX2 registers: lane `l` is pair `l`; every operation is the
    //! scalar one of `screen_pair` (and of the helpers it calls) on each lane.
    use super::{Early, Row, Settings, STRIDE};
    use std::arch::x86_64::*;

    /// Four lanes of a 3-vector.
    type V3 = [__m256d; 3];

    #[inline]
    #[target_feature(enable = "avx2")]
    fn add(a: &V3, b: &V3) -> V3 {
        [
            _mm256_add_pd(a[0], b[0]),
            _mm256_add_pd(a[1], b[1]),
            _mm256_add_pd(a[2], b[2]),
        ]
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn sub(a: &V3, b: &V3) -> V3 {
        [
            _mm256_sub_pd(a[0], b[0]),
            _mm256_sub_pd(a[1], b[1]),
            _mm256_sub_pd(a[2], b[2]),
        ]
    }

    /// `a * k` (nalgebra: each coordinate times `k`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn times(a: &V3, k: __m256d) -> V3 {
        [
            _mm256_mul_pd(a[0], k),
            _mm256_mul_pd(a[1], k),
            _mm256_mul_pd(a[2], k),
        ]
    }

    /// `a / k` (nalgebra: each coordinate divided by `k`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn div(a: &V3, k: __m256d) -> V3 {
        [
            _mm256_div_pd(a[0], k),
            _mm256_div_pd(a[1], k),
            _mm256_div_pd(a[2], k),
        ]
    }

    /// nalgebra's `dot` of 3-vectors: `(ax bx + ay by) + az bz`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn dot(a: &V3, b: &V3) -> __m256d {
        _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(a[0], b[0]), _mm256_mul_pd(a[1], b[1])),
            _mm256_mul_pd(a[2], b[2]),
        )
    }

    /// nalgebra's `cross`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn cross(a: &V3, b: &V3) -> V3 {
        [
            _mm256_sub_pd(_mm256_mul_pd(a[1], b[2]), _mm256_mul_pd(a[2], b[1])),
            _mm256_sub_pd(_mm256_mul_pd(a[2], b[0]), _mm256_mul_pd(a[0], b[2])),
            _mm256_sub_pd(_mm256_mul_pd(a[0], b[1]), _mm256_mul_pd(a[1], b[0])),
        ]
    }

    /// `m` if `c` is NaN or not above `m`, else `c`: the scalar `if c > m { c } else { m }`
    /// (`max0` of the screening code; also `f64::max(m, c)` for `m` not NaN).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn max0(m: __m256d, c: __m256d) -> __m256d {
        // MAXPD returns its first operand when it is greater, else the second.
        _mm256_max_pd(c, m)
    }

    /// `f64::min(m, c)` for `m` not NaN.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn min0(m: __m256d, c: __m256d) -> __m256d {
        _mm256_min_pd(c, m)
    }

    /// `f64::max(a, b)` for any `a` and `b` (the other one when one is NaN).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn fmax(a: __m256d, b: __m256d) -> __m256d {
        _mm256_blendv_pd(_mm256_max_pd(b, a), b, _mm256_cmp_pd::<_CMP_UNORD_Q>(a, a))
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn splat(x: f64) -> __m256d {
        _mm256_set1_pd(x)
    }

    /// `super::super::gap_exceeds(gap, scale, d)`: `gap > d (1 + 1e-9) + 1e-9 scale`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn exceeds(gap: __m256d, scale: __m256d, d: __m256d) -> __m256d {
        let bound = _mm256_add_pd(
            _mm256_mul_pd(d, splat(1.0 + 1e-9)),
            _mm256_mul_pd(splat(1e-9), scale),
        );
        _mm256_cmp_pd::<_CMP_GT_OQ>(gap, bound)
    }

    /// `separation_along` (module `collision`) of the four lanes' nodes `x`, split after node
    /// `split` (1 or 2), along `u`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn separation_along(x: &[V3; 4], split: usize, u: &V3) -> __m256d {
        let l = _mm256_sqrt_pd(dot(u, u));
        // `l == 0 || !l.is_finite()` gives -inf: ordered comparisons, false for NaN.
        let ok = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_NEQ_OQ>(l, _mm256_setzero_pd()),
            _mm256_cmp_pd::<_CMP_LT_OQ>(l, splat(f64::INFINITY)),
        );
        let (mut lo_a, mut hi_a) = (splat(f64::INFINITY), splat(f64::NEG_INFINITY));
        let (mut lo_b, mut hi_b) = (lo_a, hi_a);
        for (k, p) in x.iter().enumerate() {
            let s = dot(&sub(p, &x[0]), u);
            // The running bounds start at -+inf and are never NaN.
            if k < split {
                lo_a = min0(lo_a, s);
                hi_a = max0(hi_a, s);
            } else {
                lo_b = min0(lo_b, s);
                hi_b = max0(hi_b, s);
            }
        }
        let g = _mm256_div_pd(
            fmax(_mm256_sub_pd(lo_b, hi_a), _mm256_sub_pd(lo_a, hi_b)),
            l,
        );
        _mm256_blendv_pd(splat(f64::NEG_INFINITY), g, ok)
    }

    /// `proximity::in_plane_gap` of the four lanes' edge pairs.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn in_plane_gap(x: &[V3; 4], c: &V3) -> __m256d {
        let zero = _mm256_setzero_pd();
        let neg_inf = splat(f64::NEG_INFINITY);
        let (e, f) = (sub(&x[1], &x[0]), sub(&x[3], &x[2]));
        let (le, lf) = (dot(&e, &e), dot(&f, &f));
        let ok = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GT_OQ>(le, zero),
            _mm256_cmp_pd::<_CMP_GT_OQ>(lf, zero),
        );
        let (d2, d3) = (sub(&x[2], &x[0]), sub(&x[3], &x[0]));
        let along = |u: V3| -> __m256d {
            let l2 = dot(&u, &u);
            let (a1, b2, b3) = (dot(&e, &u), dot(&d2, &u), dot(&d3, &u));
            let neg = _mm256_cmp_pd::<_CMP_LT_OQ>(a1, zero);
            let (a_lo, a_hi) = (
                _mm256_blendv_pd(zero, a1, neg),
                _mm256_blendv_pd(a1, zero, neg),
            );
            let lt = _mm256_cmp_pd::<_CMP_LT_OQ>(b2, b3);
            let (b_lo, b_hi) = (_mm256_blendv_pd(b3, b2, lt), _mm256_blendv_pd(b2, b3, lt));
            // `if p > q { p } else { q }`.
            let g = _mm256_max_pd(_mm256_sub_pd(b_lo, a_hi), _mm256_sub_pd(a_lo, b_hi));
            let g = _mm256_div_pd(g, _mm256_sqrt_pd(l2));
            // `l2.is_nan() || l2 <= 0` gives -inf.
            _mm256_blendv_pd(neg_inf, g, _mm256_cmp_pd::<_CMP_GT_OQ>(l2, zero))
        };
        let ge = along(sub(c, &times(&e, _mm256_div_pd(dot(c, &e), le))));
        let gf = along(sub(c, &times(&f, _mm256_div_pd(dot(c, &f), lf))));
        // `if ge > gf { ge } else { gf }`.
        _mm256_blendv_pd(neg_inf, _mm256_max_pd(ge, gf), ok)
    }

    /// [`super::Lanes::reject4`] (AVX2 required; `rows` not empty, its length times `STRIDE`
    /// an `i64`).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn reject4<const VT: bool>(
        rows: &[Row],
        nodes: &[[u32; 4]; 4],
        eps: [f64; 4],
        s: Settings,
    ) -> Option<Early> {
        let base = rows.as_ptr() as *const f64;
        // Per node of the pairs, its row's offset in doubles, lane by lane.
        let offsets: [__m256i; 4] = std::array::from_fn(|k| {
            let o = |l: usize| (nodes[l][k] as usize * STRIDE) as i64;
            _mm256_set_epi64x(o(3), o(2), o(1), o(0))
        });
        // Every offset at most the last row's (`rows` is not empty, and its length times
        // `STRIDE` fits an `i64`), else no lanes.
        let last = _mm256_set1_epi64x(((rows.len() - 1) * STRIDE) as i64);
        let beyond = offsets.map(|o| _mm256_cmpgt_epi64(o, last));
        let beyond = _mm256_or_si256(
            _mm256_or_si256(beyond[0], beyond[1]),
            _mm256_or_si256(beyond[2], beyond[3]),
        );
        if _mm256_movemask_epi8(beyond) != 0 {
            return None;
        }
        // SAFETY (all gathers): the offsets index rows of `rows` (checked above), and
        // `field < STRIDE` stays inside the row (`Row` is `repr(C)`, nine doubles).
        let gather = |k: usize, field: usize| unsafe {
            _mm256_i64gather_pd::<8>(base.add(field), offsets[k])
        };
        let zero = _mm256_setzero_pd();
        let (h, eps) = (splat(s.h), _mm256_loadu_pd(eps.as_ptr()));

        // `relative_speed_given_max`: the largest squared velocity difference across the
        // primitives (a fold from 0), its root, rounded up.
        let vel: [V3; 4] = std::array::from_fn(|k| [gather(k, 3), gather(k, 4), gather(k, 5)]);
        let d = |i: usize, j: usize| {
            let w = sub(&vel[i], &vel[j]);
            dot(&w, &w)
        };
        let rel2 = if VT {
            max0(max0(max0(zero, d(0, 1)), d(0, 2)), d(0, 3))
        } else {
            max0(max0(max0(max0(zero, d(0, 2)), d(0, 3)), d(1, 2)), d(1, 3))
        };
        let stat = |field: usize| -> [__m256d; 4] { std::array::from_fn(|k| gather(k, field)) };
        let vm = stat(7);
        let vmax = max0(max0(max0(max0(zero, vm[0]), vm[1]), vm[2]), vm[3]);
        let rel = _mm256_add_pd(
            _mm256_mul_pd(_mm256_sqrt_pd(rel2), splat(1.0 + 1e-9)),
            _mm256_mul_pd(splat(1e-9), vmax),
        );
        // `primitive_speeds_of`.
        let sp = stat(6);
        let (speed_a, speed_b) = if VT {
            (
                max0(zero, sp[0]),
                max0(max0(max0(zero, sp[1]), sp[2]), sp[3]),
            )
        } else {
            (
                max0(max0(zero, sp[0]), sp[1]),
                max0(max0(zero, sp[2]), sp[3]),
            )
        };
        let reach_max = _mm256_mul_pd(_mm256_add_pd(speed_a, speed_b), h);
        let two_eps = _mm256_mul_pd(splat(2.0), eps);
        // `(2 eps).max(..)`: `2 eps` is never NaN (a policy thickness is finite).
        let far = max0(
            two_eps,
            _mm256_add_pd(eps, _mm256_mul_pd(splat(2.0), reach_max)),
        );
        let rel_h = _mm256_mul_pd(_mm256_mul_pd(rel, h), splat(1.0 + 1e-9));
        let dormant_at = if s.lazy {
            max0(two_eps, _mm256_add_pd(eps, rel_h))
        } else {
            splat(f64::INFINITY)
        };
        let ccd_at = _mm256_add_pd(_mm256_mul_pd(eps, splat(s.ccd_ratio)), rel_h);
        let pm = stat(8);
        let scale = max0(max0(max0(max0(zero, pm[0]), pm[1]), pm[2]), pm[3]);

        // The separating axes.
        let x: [V3; 4] = std::array::from_fn(|k| [gather(k, 0), gather(k, 1), gather(k, 2)]);
        let (split, centre, normal) = if VT {
            (
                1,
                sub(&x[0], &div(&add(&add(&x[1], &x[2]), &x[3]), splat(3.0))),
                cross(&sub(&x[2], &x[1]), &sub(&x[3], &x[1])),
            )
        } else {
            (
                2,
                times(&sub(&sub(&add(&x[2], &x[3]), &x[0]), &x[1]), splat(0.5)),
                cross(&sub(&x[1], &x[0]), &sub(&x[3], &x[2])),
            )
        };
        let centre_gap = separation_along(&x, split, &centre);
        // `dormant_at.min(far).max(ccd_at)`: neither `dormant_at` nor `far` is NaN.
        let first = max0(min0(dormant_at, far), ccd_at);
        let gap = _mm256_blendv_pd(
            fmax(centre_gap, separation_along(&x, split, &normal)),
            centre_gap,
            exceeds(centre_gap, scale, first),
        );
        let (dormant_g, far_g, ccd_g) = (
            exceeds(gap, scale, dormant_at),
            exceeds(gap, scale, far),
            exceeds(gap, scale, ccd_at),
        );
        let by_gap = _mm256_or_pd(dormant_g, far_g);
        // `tested`: a cheap test gave a verdict (far or dormant).
        let (decided, dormant, tested) = if VT {
            (_mm256_and_pd(by_gap, ccd_g), dormant_g, by_gap)
        } else {
            let extra = in_plane_gap(&x, &centre);
            let (dormant_e, far_e, ccd_e) = (
                exceeds(extra, scale, dormant_at),
                exceeds(extra, scale, far),
                exceeds(extra, scale, ccd_at),
            );
            let by_extra = _mm256_or_pd(dormant_e, far_e);
            (
                _mm256_blendv_pd(
                    _mm256_and_pd(by_extra, _mm256_or_pd(ccd_g, ccd_e)),
                    ccd_g,
                    by_gap,
                ),
                // Dormant by the gap, or neither dormant nor far by it and dormant by the
                // in-plane axes.
                _mm256_or_pd(dormant_g, _mm256_andnot_pd(far_g, dormant_e)),
                _mm256_or_pd(by_gap, by_extra),
            )
        };
        let mut out = Early {
            decided: _mm256_movemask_pd(decided) as u32,
            dormant: _mm256_movemask_pd(dormant) as u32,
            closest: !_mm256_movemask_pd(tested) as u32 & 0xf,
            ccd_settled: _mm256_movemask_pd(ccd_g) as u32,
            ..Early::default()
        };
        // SAFETY: four doubles each.
        unsafe {
            _mm256_storeu_pd(out.gap.as_mut_ptr(), gap);
            _mm256_storeu_pd(out.scale.as_mut_ptr(), scale);
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use crate::sim::collision::coordinate_for_tests as coordinate;
    use crate::sim::collision::obstacle_free_scene_for_tests as scene_of;
    use crate::sim::collision::proximity::{screen_pair, NodeStats, Verdict};
    use crate::sim::collision::{Pair, PairKind};
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A row at start position `x` with velocity `v` (its statistics as screening tabulates
    /// them).
    fn row(x: [f64; 3], v: [f64; 3]) -> Row {
        let s = NodeStats::of(&Vec3::from(x), &Vec3::from(v));
        Row {
            x,
            v,
            speed: s.speed,
            vel_max: s.vel_max,
            pos_max: s.pos_max,
        }
    }

    /// Oracle: lane by lane, [`screen_pair`] on the same inputs. A lane must be decided exactly
    /// when `screen_pair` returns far or dormant without closest points (no start distance)
    /// and with the first CCD pass's test settled, and then with the same verdict: the lanes
    /// never reject a pair the scalar path keeps, and reject every pair the scalar path
    /// rejects this early. Returns the number of decided lanes (0 without AVX2).
    fn check(rows: &[Row], nodes: &[[u32; 4]; 4], eps: [f64; 4], s: Settings, vt: bool) -> u32 {
        let Some(lanes) = Lanes::detect() else {
            return 0;
        };
        let got = if vt {
            lanes.reject4::<true>(rows, nodes, eps, s)
        } else {
            lanes.reject4::<false>(rows, nodes, eps, s)
        };
        let early = got.expect("nodes are rows");
        let (decided, dormant) = (early.decided, early.dormant);
        let obstacles = Default::default();
        let mut scene = scene_of(&[], &[], &[], &[], &obstacles, &[]);
        scene.h = s.h;
        scene.ccd_ratio = s.ccd_ratio;
        let kind = if vt {
            PairKind::VertexTriangle
        } else {
            PairKind::EdgeEdge
        };
        for l in 0..4 {
            let r = nodes[l].map(|k| rows[k as usize]);
            let x = r.map(|r| Vec3::from(r.x));
            let vel = r.map(|r| Vec3::from(r.v));
            let stats = r.map(|r| NodeStats {
                speed: r.speed,
                vel_max: r.vel_max,
                pos_max: r.pos_max,
            });
            let p = Pair { kind, a: 0, b: 0 };
            let ccd_eps = eps[l] * scene.ccd_ratio;
            let (verdict, start, settled) = screen_pair(
                &scene, p, eps[l], &nodes[l], &x, &vel, &stats, s.lazy, ccd_eps,
            );
            let (settles, is_dormant) = match verdict {
                Verdict::Far => (start.distance.is_none() && settled, false),
                Verdict::Dormant(_) => (start.distance.is_none() && settled, true),
                Verdict::Near(_) => (false, false),
            };
            assert_eq!(
                decided >> l & 1 != 0,
                settles,
                "lane {l}: decided {decided:b}, screen_pair early {settles} ({x:?} {vel:?} {eps:?} {s:?})"
            );
            if settles {
                assert_eq!(dormant >> l & 1 != 0, is_dormant, "lane {l}: {x:?} {vel:?}");
            }
            // The lanes that go on to the closest points, with what `screen_pair` passes on.
            assert_eq!(
                early.closest >> l & 1 != 0,
                start.distance.is_some(),
                "lane {l}"
            );
            if start.distance.is_some() {
                assert_eq!(early.ccd_settled >> l & 1 != 0, settled, "lane {l}");
                let g = early.gap[l];
                assert!(
                    g == start.gap || (g.is_nan() && start.gap.is_nan()),
                    "lane {l}: {g} vs {}",
                    start.gap
                );
                assert_eq!(early.scale[l].to_bits(), start.scale.to_bits(), "lane {l}");
            }
        }
        decided.count_ones()
    }

    /// Four pairs over sixteen rows (pair `l` has rows `4 l..4 l + 4`).
    const NODES: [[u32; 4]; 4] = [[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11], [12, 13, 14, 15]];

    fn settings(h: f64, ccd_ratio: f64, lazy: bool) -> Settings {
        Settings { h, ccd_ratio, lazy }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]
        /// [`check`] on arbitrary coordinates, now and then a signed zero, an infinity, a NaN
        /// or a huge or tiny value, for either kind, lazy or not.
        #[test]
        fn lanes_decide_exactly_what_screen_pair_decides_early(
            x in prop::array::uniform16(prop::array::uniform3(coordinate())),
            v in prop::array::uniform16(prop::array::uniform3(coordinate())),
            eps in prop::array::uniform4(0.0f64..0.5),
            h in 1e-3f64..0.05,
            ccd_ratio in 0.0f64..1.5,
            lazy in any::<bool>(),
            vt in any::<bool>(),
        ) {
            let rows: Vec<Row> = (0..16).map(|k| row(x[k], v[k])).collect();
            check(&rows, &NODES, eps, settings(h, ccd_ratio, lazy), vt);
        }

        /// [`check`] on degenerate pairs: nodes snapped onto a few positions (coincident
        /// nodes, zero-length edges, collapsed triangles), or onto a line or a plane (parallel
        /// and collinear edges, a vertex in its triangle's plane), with velocities that are
        /// often equal.
        #[test]
        fn lanes_decide_exactly_on_degenerate_pairs(
            x in prop::array::uniform16(prop::array::uniform3(-0.05f64..0.05)),
            v in prop::array::uniform16(prop::array::uniform3(-1.0f64..1.0)),
            snap in prop::array::uniform16(0usize..6),
            shape in 0usize..4,
            eps in prop::array::uniform4(1e-4f64..1e-2),
            h in 1e-3f64..0.05,
            lazy in any::<bool>(),
            vt in any::<bool>(),
        ) {
            let x: Vec<[f64; 3]> = (0..16)
                .map(|k| {
                    let p = if snap[k] < 2 { x[k & !3 | snap[k]] } else { x[k] };
                    match shape {
                        // On a line.
                        0 => [p[0], 0.5 * p[0], -p[0]],
                        // In the plane z = 0.
                        1 => [p[0], p[1], 0.0],
                        _ => p,
                    }
                })
                .collect();
            let rows: Vec<Row> = (0..16)
                .map(|k| row(x[k], if snap[k] == 5 { v[0] } else { v[k] }))
                .collect();
            check(&rows, &NODES, eps, settings(h, 0.5, lazy), vt);
        }
    }

    /// [`check`] on neighbours on a sheet (a wavy grid, the pairs a swinging garment's broad
    /// phase finds), moving with a common swing plus noise: the lanes decide most pairs, and
    /// every decision is `screen_pair`'s.
    #[test]
    fn lanes_decide_most_neighbours_on_a_sheet() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (mut decided, mut total) = (0, 0);
        let grid = |i: i32, j: i32| {
            let (u, w) = (0.01 * i as f64, 0.01 * j as f64);
            [u, 0.004 * (300.0 * u).sin() * (200.0 * w).cos(), w]
        };
        for round in 0..2000 {
            let swing = [
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ];
            let mut rows = Vec::new();
            let vt = round % 2 == 0;
            for _ in 0..4 {
                let (i, j) = (rng.random_range(0..40), rng.random_range(0..40));
                // A vertex and a nearby triangle, or two nearby edges.
                let (di, dj) = (rng.random_range(-2..3), rng.random_range(-2..3));
                let at: [[i32; 2]; 4] = if vt {
                    [
                        [i, j],
                        [i + di, j + dj],
                        [i + di + 1, j + dj],
                        [i + di, j + dj + 1],
                    ]
                } else {
                    [[i, j], [i + 1, j], [i + di, j + dj], [i + di, j + dj + 1]]
                };
                for [a, b] in at {
                    let noise = 0.1 * rng.random_range(-1.0..1.0);
                    rows.push(row(
                        grid(a, b),
                        [swing[0] + noise, swing[1] - noise, swing[2]],
                    ));
                }
            }
            let lazy = round % 3 != 0;
            decided += check(&rows, &NODES, [2e-3; 4], settings(0.02, 0.5, lazy), vt);
            total += 4;
        }
        if Lanes::detect().is_some() {
            assert!(
                decided * 2 > total,
                "{decided} of {total} decided: too few to matter"
            );
        }
    }

    /// A node that is not a row: no lanes (the scalar path reports the bad index).
    #[test]
    fn out_of_range_nodes_are_refused() {
        let Some(lanes) = Lanes::detect() else {
            return;
        };
        let rows = vec![Row::default(); 15];
        let s = settings(0.02, 0.5, true);
        assert!(lanes.reject4::<true>(&rows, &NODES, [1e-3; 4], s).is_none());
        assert!(lanes
            .reject4::<false>(&rows[..], &[[0; 4]; 4], [1e-3; 4], s)
            .is_some());
    }
}
