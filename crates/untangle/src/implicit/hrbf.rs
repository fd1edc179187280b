//! Hermite radial basis function implicit surfaces (Macedo et al. 2011), as used by Buffet et al.
//! 2019, Sec. 4: `φ(r) = r³` with a linear polynomial,
//!
//! ```text
//! f(x) = Σ_j α_j φ(‖x − x_j‖) − β_j · ∇φ(x − x_j) + a · x + b,
//! ```
//!
//! with `f(x_j) = 0` and `∇f(x_j) = n_j` at every sample. The interpolation matrix of the
//! functionals (point evaluation and gradient) is the generalised Gram matrix of the kernel, which
//! is conditionally positive definite of order 2 for `r³`: restricted to coefficient vectors
//! orthogonal to the linear polynomials it is symmetric positive definite. The fit therefore
//! eliminates the polynomial by a QR factorisation of the polynomial block (null-space method)
//! and solves the reduced `(4n − 4)²` system by a blocked Cholesky factorisation whose trailing
//! updates are matrix products (fast enough for the ≤ 1 s precomputation budget at ~700 samples).

use crate::error::{Error, Result};
use crate::geom::Vec3;
use nalgebra::{DMatrix, DVector};

/// A fitted HRBF field.
#[derive(Clone, Debug)]
pub struct Hrbf {
    cx: Vec<f64>,
    cy: Vec<f64>,
    cz: Vec<f64>,
    alpha: Vec<f64>,
    bx: Vec<f64>,
    by: Vec<f64>,
    bz: Vec<f64>,
    /// Linear part `a`.
    pub a: Vec3,
    /// Constant part `b`.
    pub b: f64,
}

/// Value, gradient and Hessian of `φ(‖v‖) = ‖v‖³`.
#[inline]
fn kernel(v: &Vec3) -> (f64, Vec3, nalgebra::Matrix3<f64>) {
    let r = v.norm();
    let h = if r > 0.0 {
        (nalgebra::Matrix3::identity() * r + v * v.transpose() / r) * 3.0
    } else {
        nalgebra::Matrix3::zeros()
    };
    (r * r * r, v * (3.0 * r), h)
}

impl Hrbf {
    /// Fits the field to samples with unit normals (`f = 0`, `∇f = n`).
    pub fn fit(points: &[Vec3], normals: &[Vec3]) -> Result<Hrbf> {
        Self::fit_mixed(points, normals, &[], &[])
    }

    /// Fits the field to Hermite samples (`f = 0`, `∇f = n`) plus value-only samples
    /// (`f(q_k) = v_k`): the same generalised interpolation with fewer functionals at the
    /// value-only points (their `β` is zero).
    pub fn fit_mixed(
        points: &[Vec3],
        normals: &[Vec3],
        value_points: &[Vec3],
        values: &[f64],
    ) -> Result<Hrbf> {
        let nh = points.len();
        let nvp = value_points.len();
        let n = nh + nvp;
        if n == 0 || normals.len() != nh || values.len() != nvp {
            return Err(Error::Parameter(
                "an HRBF needs at least one sample, with a normal or a value each".into(),
            ));
        }
        let m = 4 * nh + nvp;
        let all: Vec<Vec3> = points.iter().chain(value_points).copied().collect();
        // Centre and scale the samples for conditioning; undone at the end.
        let centre = all.iter().sum::<Vec3>() / n as f64;
        let scale = all
            .iter()
            .map(|p| (p - centre).norm())
            .fold(0.0, f64::max)
            .max(1e-12);
        let xs: Vec<Vec3> = all.iter().map(|p| (p - centre) / scale).collect();
        // Functionals: (point, None = value, Some(d) = d-th derivative); row of each point's value.
        let mut funcs: Vec<(usize, Option<usize>)> = Vec::with_capacity(m);
        for k in 0..nh {
            funcs.push((k, None));
            for d in 0..3 {
                funcs.push((k, Some(d)));
            }
        }
        for k in 0..nvp {
            funcs.push((nh + k, None));
        }
        // One kernel evaluation per pair of points, spread over their functionals' block.
        let first: Vec<usize> = (0..n)
            .map(|k| if k < nh { 4 * k } else { 4 * nh + (k - nh) })
            .collect();
        let mut a = DMatrix::<f64>::zeros(m, m);
        for j in 0..n {
            let cj = first[j];
            let nj = if j < nh { 4 } else { 1 };
            for k in 0..n {
                let rk = first[k];
                let nk = if k < nh { 4 } else { 1 };
                let (phi, g, h) = kernel(&(xs[k] - xs[j]));
                for dr in 0..nk {
                    for dc in 0..nj {
                        a[(rk + dr, cj + dc)] = match (dr, dc) {
                            (0, 0) => phi,
                            (0, e) => -g[e - 1],
                            (d, 0) => g[d - 1],
                            (d, e) => -h[(d - 1, e - 1)],
                        };
                    }
                }
            }
        }
        let mut p = DMatrix::<f64>::zeros(m, 4);
        let mut y = DVector::<f64>::zeros(m);
        for (r, &(k, dk)) in funcs.iter().enumerate() {
            match dk {
                None => {
                    p[(r, 0)] = 1.0;
                    for d in 0..3 {
                        p[(r, 1 + d)] = xs[k][d];
                    }
                    if k >= nh {
                        y[r] = values[k - nh];
                    }
                }
                Some(d) => {
                    p[(r, 1 + d)] = 1.0;
                    // In scaled coordinates the gradient scales by `scale` (f stays in world units).
                    y[r] = normals[k][d] * scale;
                }
            }
        }
        // Householder QR of P: Q^T P = [R; 0]. Apply the reflectors to A (both sides) and y.
        let mut reflectors = Vec::with_capacity(4);
        for c in 0..4 {
            let mut u = DVector::<f64>::zeros(m);
            for r in c..m {
                u[r] = p[(r, c)];
            }
            let alpha = -u[c].signum() * u.norm();
            u[c] -= alpha;
            let un = u.norm_squared();
            if un == 0.0 {
                reflectors.push(None);
                continue;
            }
            let tau = 2.0 / un;
            // P <- H P
            let w = p.tr_mul(&u);
            p.ger(-tau, &u, &w, 1.0);
            reflectors.push(Some((u, tau)));
        }
        for (u, tau) in reflectors.iter().flatten() {
            // A <- H A H ; y <- H y
            let w = a.tr_mul(u);
            a.ger(-tau, u, &w, 1.0);
            let w = &a * u;
            a.ger(-tau, &w, u, 1.0);
            let d = y.dot(u);
            y.axpy(-tau * d, u, 1.0);
        }
        let s = m - 4;
        let mut b22 = a.view((4, 4), (s, s)).clone_owned();
        let mut z = y.rows(4, s).clone_owned();
        if !cholesky_in_place(&mut b22) {
            return Err(Error::Parameter(
                "HRBF system is not positive definite (duplicate samples with different normals?)"
                    .into(),
            ));
        }
        b22.solve_lower_triangular_mut(&mut z);
        b22.tr_solve_lower_triangular_mut(&mut z);
        // Polynomial coefficients: R d = (Q^T y)_1 − B12 z.
        let rhs = y.rows(0, 4) - a.view((0, 4), (4, s)) * &z;
        let r = p.view((0, 0), (4, 4)).upper_triangle();
        let d = r
            .solve_upper_triangular(&rhs)
            .ok_or_else(|| Error::Parameter("degenerate HRBF polynomial block".into()))?;
        // c = Q [0; z] = H1 H2 H3 H4 [0; z].
        let mut c = DVector::<f64>::zeros(m);
        c.rows_mut(4, s).copy_from(&z);
        for (u, tau) in reflectors.iter().rev().flatten() {
            let dd = c.dot(u);
            c.axpy(-tau * dd, u, 1.0);
        }
        // Undo the scaling: x_s = (x − centre)/scale, f(x) = f_s(x_s).
        // α φ(‖x_s − c‖) = α/scale³ φ(‖x − C‖); β·∇φ(x_s − c) = β/scale² · ∇φ(x − C) … per term.
        let s3 = scale.powi(3);
        let s2 = scale.powi(2);
        let mut out = Hrbf {
            cx: Vec::with_capacity(n),
            cy: Vec::with_capacity(n),
            cz: Vec::with_capacity(n),
            alpha: Vec::with_capacity(n),
            bx: Vec::with_capacity(n),
            by: Vec::with_capacity(n),
            bz: Vec::with_capacity(n),
            a: Vec3::new(d[1], d[2], d[3]) / scale,
            b: 0.0,
        };
        out.b = d[0] - out.a.dot(&centre);
        for (r, &(k, dk)) in funcs.iter().enumerate() {
            if dk.is_none() {
                out.cx.push(all[k].x);
                out.cy.push(all[k].y);
                out.cz.push(all[k].z);
                out.alpha.push(c[r] / s3);
                let b = if k < nh {
                    [c[r + 1], c[r + 2], c[r + 3]]
                } else {
                    [0.0; 3]
                };
                out.bx.push(b[0] / s2);
                out.by.push(b[1] / s2);
                out.bz.push(b[2] / s2);
            }
        }
        Ok(out)
    }

    /// Number of samples (centres).
    pub fn len(&self) -> usize {
        self.alpha.len()
    }

    /// Whether the field has no centre.
    pub fn is_empty(&self) -> bool {
        self.alpha.is_empty()
    }

    /// Value and gradient at `x`.
    pub fn eval(&self, x: &Vec3) -> (f64, Vec3) {
        let (mut f, mut gx, mut gy, mut gz) = (0.0, 0.0, 0.0, 0.0);
        for j in 0..self.alpha.len() {
            let vx = x.x - self.cx[j];
            let vy = x.y - self.cy[j];
            let vz = x.z - self.cz[j];
            let (bx, by, bz) = (self.bx[j], self.by[j], self.bz[j]);
            let yz2 = vy * vy + vz * vz;
            let vbyz = vy * by + vz * bz;
            let r2 = vx * vx + yz2;
            let r = r2.sqrt();
            let inv = 1.0 / r.max(1e-300);
            let vb = vx * bx + vbyz;
            let al = self.alpha[j];
            // f += α r³ − 3 r (v·β)
            f += r * (al * r2 - 3.0 * vb);
            // ∇f += 3 α r v − 3 (r β + v (v·β)/r)
            let s = 3.0 * (al * r - vb * inv);
            let r3 = 3.0 * r;
            gx += s * vx - r3 * bx;
            gy += s * vy - r3 * by;
            gz += s * vz - r3 * bz;
        }
        (
            f + self.a.dot(x) + self.b,
            Vec3::new(gx + self.a.x, gy + self.a.y, gz + self.a.z),
        )
    }
}

/// Nodes evaluated together by [`Hrbf::eval_row`]: the inner loop over them has no reduction, so
/// it vectorises.
const BLOCK: usize = 16;

impl Hrbf {
    /// Values and gradients at the points `start + k * dx * e_x`, `k = 0..out.len()` (a grid row),
    /// bit-identical to [`Hrbf::eval`] per point order of summation, but vectorised: the centres
    /// are the outer loop and a block of points the inner one (with AVX2 when the CPU has it).
    pub fn eval_row(&self, start: &Vec3, dx: f64, out: &mut [(f64, Vec3)]) {
        self.eval_row_from(start, dx, 0, out);
    }

    /// Like [`Hrbf::eval_row`] for the points `start + (first + k) * dx * e_x`: part of a row,
    /// bit-identical to the same points of the whole row.
    pub fn eval_row_from(&self, start: &Vec3, dx: f64, first: usize, out: &mut [(f64, Vec3)]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU supports AVX-512F (checked just above).
                unsafe { self.eval_row_avx512(start, dx, first, out) };
                return;
            }
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                unsafe { self.eval_row_avx2(start, dx, first, out) };
                return;
            }
        }
        self.eval_row_generic(start, dx, first, out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn eval_row_avx512(&self, start: &Vec3, dx: f64, first: usize, out: &mut [(f64, Vec3)]) {
        self.eval_row_generic(start, dx, first, out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn eval_row_avx2(&self, start: &Vec3, dx: f64, first: usize, out: &mut [(f64, Vec3)]) {
        self.eval_row_generic(start, dx, first, out);
    }

    #[inline(always)]
    fn eval_row_generic(&self, start: &Vec3, dx: f64, first: usize, out: &mut [(f64, Vec3)]) {
        for (b, chunk) in out.chunks_mut(BLOCK).enumerate() {
            let mut px = [0.0f64; BLOCK];
            for (k, x) in px.iter_mut().enumerate() {
                *x = start.x + ((first + b * BLOCK + k) as f64) * dx;
            }
            let (py, pz) = (start.y, start.z);
            let mut f = [0.0f64; BLOCK];
            let mut gx = [0.0f64; BLOCK];
            let mut gy = [0.0f64; BLOCK];
            let mut gz = [0.0f64; BLOCK];
            for j in 0..self.alpha.len() {
                let (cx, cy, cz) = (self.cx[j], self.cy[j], self.cz[j]);
                let (bx, by, bz, al) = (self.bx[j], self.by[j], self.bz[j], self.alpha[j]);
                let vy = py - cy;
                let vz = pz - cz;
                let yz2 = vy * vy + vz * vz;
                let vbyz = vy * by + vz * bz;
                for k in 0..BLOCK {
                    let vx = px[k] - cx;
                    let r2 = vx * vx + yz2;
                    let r = r2.sqrt();
                    let inv = 1.0 / r.max(1e-300);
                    let vb = vx * bx + vbyz;
                    f[k] += r * (al * r2 - 3.0 * vb);
                    let s = 3.0 * (al * r - vb * inv);
                    let r3 = 3.0 * r;
                    gx[k] += s * vx - r3 * bx;
                    gy[k] += s * vy - r3 * by;
                    gz[k] += s * vz - r3 * bz;
                }
            }
            for (k, o) in chunk.iter_mut().enumerate() {
                let p = Vec3::new(px[k], py, pz);
                *o = (
                    f[k] + self.a.dot(&p) + self.b,
                    Vec3::new(gx[k] + self.a.x, gy[k] + self.a.y, gz[k] + self.a.z),
                );
            }
        }
    }
}

/// Lower Cholesky factor in place (the upper triangle is left as garbage), blocked so that the
/// trailing updates are matrix products. Returns false if the matrix is not positive definite.
pub fn cholesky_in_place(a: &mut DMatrix<f64>) -> bool {
    let s = a.nrows();
    const NB: usize = 96;
    let mut k = 0;
    while k < s {
        let kb = NB.min(s - k);
        let d = a.view((k, k), (kb, kb)).clone_owned();
        let Some(ch) = d.cholesky() else {
            return false;
        };
        let l11 = ch.unpack();
        a.view_mut((k, k), (kb, kb)).copy_from(&l11);
        let rest = s - k - kb;
        if rest > 0 {
            let mut pt = a.view((k + kb, k), (rest, kb)).transpose();
            l11.solve_lower_triangular_mut(&mut pt);
            let panel = pt.transpose();
            a.view_mut((k + kb, k), (rest, kb)).copy_from(&panel);
            let mut j = 0;
            while j < rest {
                let jb = NB.min(rest - j);
                let lhs = panel.rows(j, rest - j);
                let rhs = panel.rows(j, jb).transpose();
                let mut target = a.view_mut((k + kb + j, k + kb + j), (rest - j, jb));
                target.gemm(-1.0, &lhs, &rhs, 1.0);
                j += jb;
            }
        }
        k += kb;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn row_evaluation_is_identical_to_pointwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let pts: Vec<Vec3> = (0..40)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let nrm: Vec<Vec3> = pts
            .iter()
            .map(|p| (p - Vec3::repeat(0.5)).normalize())
            .collect();
        let h = Hrbf::fit(&pts, &nrm).unwrap();
        let start = Vec3::new(-0.3, 0.2, 0.4);
        let mut row = vec![(0.0, Vec3::zeros()); 37];
        h.eval_row(&start, 0.05, &mut row);
        for (k, r) in row.iter().enumerate() {
            let p = start + Vec3::x() * (k as f64 * 0.05);
            assert_eq!(*r, h.eval(&p));
        }
    }

    #[test]
    fn mixed_fit_interpolates_values_and_hermite_data() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let pts: Vec<Vec3> = (0..30)
            .map(|_| Vec3::new(rng.random(), rng.random(), 0.0))
            .collect();
        let nrm = vec![Vec3::z(); pts.len()];
        let q: Vec<Vec3> = (0..20)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random_range(0.2..1.0)))
            .collect();
        let v: Vec<f64> = q.iter().map(|p| p.z * 0.7).collect();
        let h = Hrbf::fit_mixed(&pts, &nrm, &q, &v).unwrap();
        for p in &pts {
            let (f, g) = h.eval(p);
            assert!(f.abs() < 1e-8 && (g - Vec3::z()).norm() < 1e-6);
        }
        for (p, val) in q.iter().zip(&v) {
            assert!((h.eval(p).0 - val).abs() < 1e-8);
        }
    }

    #[test]
    fn blocked_cholesky_matches_nalgebra() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let n = 250;
        let b = DMatrix::<f64>::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let a = &b * b.transpose() + DMatrix::identity(n, n);
        let mut ours = a.clone();
        assert!(cholesky_in_place(&mut ours));
        let l = a.clone().cholesky().unwrap().unpack();
        let ours = ours.lower_triangle();
        assert!((ours - l).amax() < 1e-9);
    }

    #[test]
    fn interpolates_values_and_normals_of_a_sphere() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let centre = Vec3::new(0.3, -0.2, 1.0);
        let (mut pts, mut nrm) = (Vec::new(), Vec::new());
        for _ in 0..150 {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            pts.push(centre + v * 0.5);
            nrm.push(v);
        }
        let h = Hrbf::fit(&pts, &nrm).unwrap();
        for (p, n) in pts.iter().zip(&nrm) {
            let (f, g) = h.eval(p);
            assert!(f.abs() < 1e-7, "{f}");
            assert!((g - n).norm() < 1e-6, "{g:?} vs {n:?}");
        }
        // Inside negative, outside positive, close to the signed distance near the surface.
        assert!(h.eval(&centre).0 < 0.0);
        assert!(h.eval(&(centre + Vec3::new(2.0, 0.0, 0.0))).0 > 0.0);
        for _ in 0..50 {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            for d in [-0.02, 0.02] {
                let (f, _) = h.eval(&(centre + v * (0.5 + d)));
                assert!((f - d).abs() < 0.1 * d.abs() + 2e-3, "{f} vs {d}");
            }
        }
        // Gradient of eval matches finite differences.
        let x = Vec3::new(0.1, 0.2, 0.7);
        let (_, g) = h.eval(&x);
        let e = 1e-6;
        for d in 0..3 {
            let mut dx = Vec3::zeros();
            dx[d] = e;
            let fd = (h.eval(&(x + dx)).0 - h.eval(&(x - dx)).0) / (2.0 * e);
            assert!((fd - g[d]).abs() < 1e-5);
        }
    }
}
