//! Stretch and shear of a triangle against its uv rest shape (Baraff & Witkin 1998, Sec. 4.2).
//!
//! The deformation map `w(u, v)` is linear on a triangle: `F = [w_u w_v] = Ds Dm^-1`, with `Ds`
//! the world edge vectors and `Dm` the uv edge vectors. The energy, per unit rest area, is
//! `k_s/2 ((|w_u| - 1)^2 + (|w_v| - 1)^2) + k_sh/2 (w_u . w_v)^2` — Baraff & Witkin's stretch and
//! shear conditions `C` with energy `k/2 C^2`. The Hessian keeps the Gauss-Newton part
//! `k dC/dx dC/dx^T` and the curvature term of the stretch condition only while stretched
//! (`|w| > 1`), so it is always positive semi-definite and CG applies.

use nalgebra::Matrix3;

use crate::error::{Error, Result};
use crate::geom::{cross2, Vec2, Vec3};

/// Rest data of one triangle: `w_u = sum_i a[i] x_i`, `w_v = sum_i b[i] x_i`, and its rest area.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleRest {
    /// Coefficients of `w_u` per corner.
    pub a: [f64; 3],
    /// Coefficients of `w_v` per corner.
    pub b: [f64; 3],
    /// Rest (uv) area, positive.
    pub area: f64,
}

impl TriangleRest {
    /// From the uv corners; an error for a degenerate (zero-area) or non-finite uv triangle.
    pub fn new(u0: &Vec2, u1: &Vec2, u2: &Vec2) -> Result<TriangleRest> {
        let det = cross2(u0, u1, u2);
        let (e1, e2) = (u1 - u0, u2 - u0);
        let scale = e1.norm_squared().max(e2.norm_squared());
        if !det.is_finite() || det.abs() <= 1e-12 * scale || scale == 0.0 {
            return Err(Error::Parameter(format!(
                "degenerate uv rest triangle ({}, {}), ({}, {}), ({}, {})",
                u0.x, u0.y, u1.x, u1.y, u2.x, u2.y
            )));
        }
        // Dm = [e1 e2]; Dm^-1 = 1/det [[e2.y, -e2.x], [-e1.y, e1.x]].
        let (a1, a2) = (e2.y / det, -e1.y / det);
        let (b1, b2) = (-e2.x / det, e1.x / det);
        Ok(TriangleRest {
            a: [-(a1 + a2), a1, a2],
            b: [-(b1 + b2), b1, b2],
            area: 0.5 * det.abs(),
        })
    }
}

/// Energy, gradient and (PSD) Hessian of one triangle.
#[derive(Clone, Copy, Debug)]
pub struct StretchTerms {
    /// Elastic energy.
    pub energy: f64,
    /// Gradient per corner (the force is its negative).
    pub gradient: [Vec3; 3],
    /// Hessian blocks `(i, j)` for `i <= j`, in the order 00, 11, 22, 01, 02, 12.
    pub hessian: [Matrix3<f64>; 6],
}

/// Index pairs of [`StretchTerms::hessian`].
pub const BLOCKS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// Evaluates the stretch/shear energy of a triangle with corners `x` (stiffnesses in N/m).
pub fn stretch_terms(
    rest: &TriangleRest,
    x: [&Vec3; 3],
    k_stretch: f64,
    k_shear: f64,
) -> StretchTerms {
    let (a, b) = (&rest.a, &rest.b);
    let wu = x[0] * a[0] + x[1] * a[1] + x[2] * a[2];
    let wv = x[0] * b[0] + x[1] * b[1] + x[2] * b[2];
    let (lu, lv) = (wu.norm().max(1e-12), wv.norm().max(1e-12));
    let (nu, nv) = (wu / lu, wv / lv);
    let (cu, cv) = (lu - 1.0, lv - 1.0);
    let s = wu.dot(&wv);
    let area = rest.area;
    let energy = area * (0.5 * k_stretch * (cu * cu + cv * cv) + 0.5 * k_shear * s * s);
    let g: [Vec3; 3] = [0, 1, 2].map(|i| wv * a[i] + wu * b[i]);
    let gradient = [0, 1, 2]
        .map(|i| area * (k_stretch * (nu * (cu * a[i]) + nv * (cv * b[i])) + k_shear * s * g[i]));
    let proj = |n: &Vec3, c: f64, l: f64| {
        let nn = n * n.transpose();
        if c > 0.0 {
            nn + (Matrix3::identity() - nn) * (c / l)
        } else {
            nn
        }
    };
    let hu = proj(&nu, cu, lu) * (area * k_stretch);
    let hv = proj(&nv, cv, lv) * (area * k_stretch);
    let hessian = BLOCKS.map(|(i, j)| {
        hu * (a[i] * a[j]) + hv * (b[i] * b[j]) + g[i] * g[j].transpose() * (area * k_shear)
    });
    StretchTerms {
        energy,
        gradient,
        hessian,
    }
}

/// The energy of [`stretch_terms`] alone (no derivatives), for reports.
pub fn stretch_energy(rest: &TriangleRest, x: [&Vec3; 3], k_stretch: f64, k_shear: f64) -> f64 {
    let (a, b) = (&rest.a, &rest.b);
    let wu = x[0] * a[0] + x[1] * a[1] + x[2] * a[2];
    let wv = x[0] * b[0] + x[1] * b[1] + x[2] * b[2];
    let (cu, cv) = (wu.norm() - 1.0, wv.norm() - 1.0);
    let s = wu.dot(&wv);
    rest.area * (0.5 * k_stretch * (cu * cu + cv * cv) + 0.5 * k_shear * s * s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn energy(rest: &TriangleRest, x: &[Vec3; 3]) -> f64 {
        stretch_terms(rest, [&x[0], &x[1], &x[2]], 700.0, 90.0).energy
    }

    proptest! {
        /// Gradient against central finite differences of the energy; the rest shape placed
        /// rigidly in 3D has zero energy and zero gradient.
        #[test]
        fn gradient_matches_finite_differences(
            u in prop::array::uniform6(-1.0f64..1.0),
            x in prop::array::uniform9(-1.0f64..1.0),
        ) {
            let uv = [Vec2::new(u[0], u[1]), Vec2::new(u[2], u[3]), Vec2::new(u[4], u[5])];
            prop_assume!(cross2(&uv[0], &uv[1], &uv[2]).abs() > 0.05);
            let rest = TriangleRest::new(&uv[0], &uv[1], &uv[2]).unwrap();
            let xs = [Vec3::new(x[0], x[1], x[2]), Vec3::new(x[3], x[4], x[5]), Vec3::new(x[6], x[7], x[8])];
            let t = stretch_terms(&rest, [&xs[0], &xs[1], &xs[2]], 700.0, 90.0);
            let e = stretch_energy(&rest, [&xs[0], &xs[1], &xs[2]], 700.0, 90.0);
            prop_assert!((e - t.energy).abs() <= 1e-12 * (1.0 + e.abs()));
            let h = 1e-6;
            for i in 0..3 {
                for d in 0..3 {
                    let mut p = xs; p[i][d] += h;
                    let mut m = xs; m[i][d] -= h;
                    let fd = (energy(&rest, &p) - energy(&rest, &m)) / (2.0 * h);
                    prop_assert!((fd - t.gradient[i][d]).abs() <= 1e-4 * (1.0 + fd.abs()),
                        "corner {} dir {}: fd {} vs {}", i, d, fd, t.gradient[i][d]);
                }
            }
            // Rigid placement of the rest shape: zero energy and gradient.
            let rot = nalgebra::Rotation3::from_euler_angles(x[0], x[1], x[2]);
            let placed = uv.map(|p| rot * Vec3::new(p.x, p.y, 0.0) + Vec3::new(x[3], x[4], x[5]));
            let t0 = stretch_terms(&rest, [&placed[0], &placed[1], &placed[2]], 700.0, 90.0);
            prop_assert!(t0.energy.abs() < 1e-9);
            for gi in t0.gradient { prop_assert!(gi.norm() < 1e-6); }
            // The assembled 9x9 Hessian is positive semi-definite.
            let mut hm = nalgebra::SMatrix::<f64, 9, 9>::zeros();
            for (k, &(i, j)) in BLOCKS.iter().enumerate() {
                hm.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&t.hessian[k]);
                hm.fixed_view_mut::<3, 3>(3 * j, 3 * i).copy_from(&t.hessian[k].transpose());
            }
            let ev = nalgebra::SymmetricEigen::new(hm).eigenvalues;
            let scale = ev.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            prop_assert!(ev.iter().all(|&v| v >= -1e-9 * scale));
        }
    }

    /// Where the Hessian is exact (stretched, no shear: the dropped terms vanish) it matches
    /// finite differences of the gradient.
    #[test]
    fn hessian_matches_finite_differences_when_stretched_without_shear() {
        let uv = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        let rest = TriangleRest::new(&uv[0], &uv[1], &uv[2]).unwrap();
        let xs = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.3, 0.0, 0.0),
            Vec3::new(0.0, 1.2, 0.0),
        ];
        let t = stretch_terms(&rest, [&xs[0], &xs[1], &xs[2]], 700.0, 0.0);
        let h = 1e-6;
        for (k, &(i, j)) in BLOCKS.iter().enumerate() {
            for d in 0..3 {
                let mut p = xs;
                p[j][d] += h;
                let mut m = xs;
                m[j][d] -= h;
                let gp = stretch_terms(&rest, [&p[0], &p[1], &p[2]], 700.0, 0.0).gradient[i];
                let gm = stretch_terms(&rest, [&m[0], &m[1], &m[2]], 700.0, 0.0).gradient[i];
                let col = (gp - gm) / (2.0 * h);
                for r in 0..3 {
                    assert!(
                        (col[r] - t.hessian[k][(r, d)]).abs() < 1e-4,
                        "block {k} ({r},{d})"
                    );
                }
            }
        }
    }

    #[test]
    fn degenerate_rest_triangle_is_an_error() {
        let z = Vec2::new(0.0, 0.0);
        assert!(TriangleRest::new(&z, &Vec2::new(1.0, 0.0), &Vec2::new(2.0, 0.0)).is_err());
        assert!(TriangleRest::new(&z, &Vec2::new(f64::NAN, 0.0), &Vec2::new(0.0, 1.0)).is_err());
    }
}
