//! Thin-plate radial basis function fits `R^2 -> R^2` (Wicke et al. 2006, Sec. 5.1, Eq. 2-3):
//!
//! ```text
//! d(x) = p(x) + Σ_j w_j φ(‖x − c_j‖),   φ(r) = r² log r,   p of degree one,
//! ```
//!
//! with `d(c_i) = v_i` at every centre and `Σ_j w_j q(c_j) = 0` for every polynomial `q` of
//! degree one (the side condition of the saddle-point system, Eq. 3). The paper adds random
//! noise to centres on a straight line (where the degree-one polynomial is not determined);
//! we keep the fit deterministic instead: coincident centres are merged, centres on a line
//! fit a polynomial in the coordinate along that line only, and one centre gives a translation.
//! Coordinates are centred and scaled before the solve, so the fit does not depend on the
//! units of the parameter space.

use crate::geom::Vec2;
use nalgebra::DMatrix;

/// The kernel `φ(r) = r² log r` (0 at `r = 0`).
#[inline]
pub fn thin_plate(r: f64) -> f64 {
    if r <= 0.0 {
        0.0
    } else {
        r * r * r.ln()
    }
}

/// A fitted map `d: R^2 -> R^2` (Eq. 2).
#[derive(Clone, Debug)]
pub struct ThinPlate {
    /// Centre of the normalised frame.
    origin: Vec2,
    /// Scale of the normalised frame: `y = (x - origin) / scale`.
    scale: f64,
    /// Centres in the normalised frame.
    centers: Vec<Vec2>,
    /// Kernel weights, one per centre (both output components).
    weights: Vec<Vec2>,
    /// Polynomial: `a[0] + a[1] y.x + a[2] y.y` in the normalised frame (or along `axis`).
    poly: [Vec2; 3],
    /// For centres on a line: the unit direction of that line; the polynomial is then
    /// `a[0] + a[1] (y · axis)` and `a[2]` is zero.
    axis: Option<Vec2>,
}

/// Relative distance under which two centres are merged (their values averaged).
const MERGE: f64 = 1e-9;
/// Smaller principal extent, relative to the larger, under which centres count as collinear.
const COLLINEAR: f64 = 1e-6;

impl ThinPlate {
    /// The fit with `d(centers[i]) = values[i]`. `None` when there is no centre, a coordinate
    /// is not finite, or the system cannot be solved (it can for any set of distinct centres
    /// not on a line, and the line and single-point cases are handled separately).
    pub fn fit(centers: &[Vec2], values: &[Vec2]) -> Option<ThinPlate> {
        if centers.is_empty() || centers.len() != values.len() {
            return None;
        }
        if centers
            .iter()
            .chain(values)
            .any(|p| !p.x.is_finite() || !p.y.is_finite())
        {
            return None;
        }
        let n0 = centers.len() as f64;
        let origin = centers.iter().fold(Vec2::zeros(), |s, c| s + c) / n0;
        let scale = centers
            .iter()
            .map(|c| (c - origin).amax())
            .fold(0.0, f64::max);
        let scale = if scale > 0.0 { scale } else { 1.0 };
        // Normalise, then merge coincident centres (in input order; values averaged).
        let mut cs: Vec<Vec2> = Vec::with_capacity(centers.len());
        let mut vs: Vec<(Vec2, f64)> = Vec::with_capacity(centers.len());
        for (c, v) in centers.iter().zip(values) {
            let y = (c - origin) / scale;
            match cs.iter().position(|z| (z - y).amax() <= MERGE) {
                Some(k) => {
                    vs[k].0 += v;
                    vs[k].1 += 1.0;
                }
                None => {
                    cs.push(y);
                    vs.push((*v, 1.0));
                }
            }
        }
        let vs: Vec<Vec2> = vs.iter().map(|(s, k)| s / *k).collect();
        let n = cs.len();
        if n == 1 {
            return Some(ThinPlate {
                origin,
                scale,
                centers: cs,
                weights: vec![Vec2::zeros()],
                poly: [vs[0], Vec2::zeros(), Vec2::zeros()],
                axis: None,
            });
        }
        let axis = collinear_axis(&cs);
        let m = if axis.is_some() { 2 } else { 3 };
        let size = n + m;
        let mut a = DMatrix::<f64>::zeros(size, size);
        for i in 0..n {
            for j in 0..i {
                let k = thin_plate((cs[i] - cs[j]).norm());
                a[(i, j)] = k;
                a[(j, i)] = k;
            }
            let row = poly_row(&cs[i], axis);
            for (k, &q) in row.iter().take(m).enumerate() {
                a[(i, n + k)] = q;
                a[(n + k, i)] = q;
            }
        }
        // The saddle-point system (zero block below the polynomial rows) needs row pivoting;
        // partial pivoting is enough for distinct, non-collinear centres.
        let mut b = DMatrix::<f64>::zeros(size, 2);
        for i in 0..n {
            b[(i, 0)] = vs[i].x;
            b[(i, 1)] = vs[i].y;
        }
        let sol = a.lu().solve(&b)?;
        if sol.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let weights = (0..n)
            .map(|i| Vec2::new(sol[(i, 0)], sol[(i, 1)]))
            .collect();
        let mut poly = [Vec2::zeros(); 3];
        for (k, p) in poly.iter_mut().enumerate().take(m) {
            *p = Vec2::new(sol[(n + k, 0)], sol[(n + k, 1)]);
        }
        Some(ThinPlate {
            origin,
            scale,
            centers: cs,
            weights,
            poly,
            axis,
        })
    }

    /// `d(x)` (Eq. 2).
    pub fn eval(&self, x: &Vec2) -> Vec2 {
        let y = (x - self.origin) / self.scale;
        let row = poly_row(&y, self.axis);
        let mut d = self.poly[0] * row[0] + self.poly[1] * row[1] + self.poly[2] * row[2];
        for (c, w) in self.centers.iter().zip(&self.weights) {
            d += w * thin_plate((y - c).norm());
        }
        d
    }

    /// Number of distinct centres of the fit.
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// Whether the fit has no centre (never: [`ThinPlate::fit`] refuses that).
    pub fn is_empty(&self) -> bool {
        self.centers.is_empty()
    }
}

/// The monomials `[1, y.x, y.y]`, or `[1, y · axis, 0]` for collinear centres.
#[inline]
fn poly_row(y: &Vec2, axis: Option<Vec2>) -> [f64; 3] {
    match axis {
        Some(u) => [1.0, y.dot(&u), 0.0],
        None => [1.0, y.x, y.y],
    }
}

/// The direction of the line the (normalised, distinct, at least two) centres lie on, if they
/// do: the principal axis of their covariance when the smaller principal extent is below
/// [`COLLINEAR`] times the larger.
fn collinear_axis(cs: &[Vec2]) -> Option<Vec2> {
    let n = cs.len() as f64;
    let mean = cs.iter().fold(Vec2::zeros(), |s, c| s + c) / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for c in cs {
        let d = c - mean;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let tr = 0.5 * (sxx + syy);
    let det = sxx * syy - sxy * sxy;
    let disc = (tr * tr - det).max(0.0).sqrt();
    let (big, small) = (tr + disc, (tr - disc).max(0.0));
    if big <= 0.0 || small.sqrt() > COLLINEAR * big.sqrt() {
        return None;
    }
    // Eigenvector of the larger eigenvalue.
    let v = if sxy.abs() > 0.0 {
        Vec2::new(big - syy, sxy)
    } else if sxx >= syy {
        Vec2::new(1.0, 0.0)
    } else {
        Vec2::new(0.0, 1.0)
    };
    Some(v / v.norm())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: &Vec2, b: &Vec2, tol: f64) -> bool {
        (a - b).norm() <= tol * (1.0 + b.norm())
    }

    #[test]
    fn kernel_is_r2_log_r() {
        assert_eq!(thin_plate(0.0), 0.0);
        assert_eq!(thin_plate(1.0), 0.0);
        assert!((thin_plate(2.0) - 4.0 * 2f64.ln()).abs() < 1e-15);
        assert!(thin_plate(0.5) < 0.0);
    }

    #[test]
    fn one_centre_is_a_translation_and_a_line_interpolates() {
        let f = ThinPlate::fit(&[Vec2::new(1.0, 2.0)], &[Vec2::new(3.0, 4.0)]).unwrap();
        assert_eq!(f.eval(&Vec2::new(-5.0, 7.0)), Vec2::new(3.0, 4.0));
        // Centres on the line y = x: interpolated, finite elsewhere.
        let cs: Vec<Vec2> = (0..6).map(|i| Vec2::new(i as f64, i as f64)).collect();
        let vs: Vec<Vec2> = cs.iter().map(|c| Vec2::new(c.x * c.x, 1.0 - c.y)).collect();
        let f = ThinPlate::fit(&cs, &vs).unwrap();
        for (c, v) in cs.iter().zip(&vs) {
            assert!(close(&f.eval(c), v, 1e-9), "{:?} vs {v:?}", f.eval(c));
        }
        assert!(f.eval(&Vec2::new(3.0, -2.0)).iter().all(|x| x.is_finite()));
        // Coincident centres are merged, values averaged.
        let f = ThinPlate::fit(
            &[
                Vec2::new(0.0, 0.0),
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
            ],
            &[
                Vec2::new(1.0, 0.0),
                Vec2::new(3.0, 0.0),
                Vec2::new(5.0, 0.0),
            ],
        )
        .unwrap();
        assert_eq!(f.len(), 2);
        assert!(close(
            &f.eval(&Vec2::new(0.0, 0.0)),
            &Vec2::new(2.0, 0.0),
            1e-12
        ));
    }

    #[test]
    fn refuses_empty_and_non_finite_input() {
        assert!(ThinPlate::fit(&[], &[]).is_none());
        assert!(ThinPlate::fit(&[Vec2::new(f64::NAN, 0.0)], &[Vec2::zeros()]).is_none());
        assert!(ThinPlate::fit(&[Vec2::zeros()], &[Vec2::new(0.0, f64::INFINITY)]).is_none());
    }

    /// The fit against an independent evaluation of Eq. 2-3: the side conditions hold, and
    /// the interpolant equals a direct sum of the kernel with the solved weights.
    #[test]
    fn satisfies_the_side_conditions_of_eq_3() {
        let cs = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.1),
            Vec2::new(0.3, 0.9),
            Vec2::new(0.8, 0.7),
            Vec2::new(0.45, 0.4),
        ];
        let vs: Vec<Vec2> = cs
            .iter()
            .map(|c| Vec2::new((3.0 * c.x).sin(), c.x * c.y))
            .collect();
        let f = ThinPlate::fit(&cs, &vs).unwrap();
        let sum_w = f.weights.iter().fold(Vec2::zeros(), |s, w| s + w);
        let sum_wx = f
            .weights
            .iter()
            .zip(&f.centers)
            .fold(Vec2::zeros(), |s, (w, c)| s + w * c.x);
        let sum_wy = f
            .weights
            .iter()
            .zip(&f.centers)
            .fold(Vec2::zeros(), |s, (w, c)| s + w * c.y);
        for s in [sum_w, sum_wx, sum_wy] {
            assert!(s.norm() < 1e-9, "{s:?}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        /// Random centres (3-30, as the paper's 5-30): the fit interpolates every value, and
        /// reproduces an affine map exactly everywhere (the polynomial part absorbs it).
        #[test]
        fn interpolates_and_reproduces_affine_maps(
            pts in prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 3..30),
            m in prop::array::uniform4(-2.0f64..2.0),
            b in prop::array::uniform2(-1.0f64..1.0),
            s in 0.001f64..100.0,
            probe in (-2.0f64..2.0, -2.0f64..2.0),
        ) {
            let cs: Vec<Vec2> = pts.iter().map(|&(x, y)| Vec2::new(x, y) * s).collect();
            let affine = |c: &Vec2| Vec2::new(m[0] * c.x + m[1] * c.y + b[0], m[2] * c.x + m[3] * c.y + b[1]);
            let vs: Vec<Vec2> = cs.iter().map(affine).collect();
            let f = ThinPlate::fit(&cs, &vs).unwrap();
            for (c, v) in cs.iter().zip(&vs) {
                prop_assert!(close(&f.eval(c), v, 1e-6), "{:?} vs {:?}", f.eval(c), v);
            }
            let p = Vec2::new(probe.0, probe.1) * s;
            prop_assert!(close(&f.eval(&p), &affine(&p), 1e-5), "{:?} vs {:?}", f.eval(&p), affine(&p));
            // Non-affine values: still interpolated.
            let ws: Vec<Vec2> = cs.iter().map(|c| Vec2::new((c.x / s * 3.0).sin(), (c.y / s).powi(2))).collect();
            let g = ThinPlate::fit(&cs, &ws).unwrap();
            for (c, v) in cs.iter().zip(&ws) {
                prop_assert!(close(&g.eval(c), v, 1e-6), "{:?} vs {:?}", g.eval(c), v);
            }
        }
    }
}
