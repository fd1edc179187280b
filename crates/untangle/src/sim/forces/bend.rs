//! Bending across interior edges with a flat rest shape: the quadratic bending model of
//! Bergou et al. 2006 ("A quadratic bending model for inextensible surfaces"), a linear
//! stencil per edge so that the energy is quadratic in the positions and its Hessian constant.
//!
//! For the edge `(x0, x1)` with opposite vertices `x2` (first triangle) and `x3` (second), the
//! stencil `k` satisfies `sum_i k_i x_i = 0` for every affine image of the flat rest shape (so
//! in-plane stretch causes no bending force), and is scaled so that a small dihedral angle
//! `theta` costs `E = kb/2 * 3 |e|^2 theta^2 / (A0 + A1)`, the discrete-shell energy of
//! Grinspun et al. 2003. The rest shape comes from each triangle's own uv, so seam edges (two
//! panels) are handled like any other edge. Heights are clamped at 5% of the edge length to keep
//! the stencil bounded when a rest triangle becomes very thin (Cha & Ko's triangle shrinkage).

use crate::geom::{cross2, Vec2, Vec3};

/// The stencil of one interior edge: vertices `[x0, x1, x2, x3]` and weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BendStencil {
    /// World vertices: the edge, then the vertex opposite in each triangle.
    pub vertices: [u32; 4],
    /// Weights `k_i` with `sum k_i = 0`.
    pub weights: [f64; 4],
}

impl BendStencil {
    /// The stencil from the uv positions of the edge ends and the opposite vertex, as seen by
    /// each of the two triangles (`uv0 = [x0, x1, x2]` in the first, `uv1 = [x0, x1, x3]` in the
    /// second).
    pub fn new(vertices: [u32; 4], uv0: [Vec2; 3], uv1: [Vec2; 3]) -> BendStencil {
        let side = |u: &[Vec2; 3]| {
            let e = u[1] - u[0];
            let l = e.norm().max(1e-300);
            let tau = (u[2] - u[0]).dot(&e) / (l * l);
            let h = (cross2(&u[0], &u[1], &u[2]).abs() / l).max(0.05 * l);
            (l, tau, h)
        };
        let (l0, t0, h0) = side(&uv0);
        let (l1, t1, h1) = side(&uv1);
        let l = 0.5 * (l0 + l1);
        let area = 0.5 * (l0 * h0 + l1 * h1);
        let c = l * (3.0 / area).sqrt();
        BendStencil {
            vertices,
            weights: [
                c * ((1.0 - t0) / h0 + (1.0 - t1) / h1),
                c * (t0 / h0 + t1 / h1),
                -c / h0,
                -c / h1,
            ],
        }
    }

    /// `sum_i k_i x_i`, which vanishes on the flat rest shape.
    #[inline]
    pub fn curvature(&self, x: &[Vec3]) -> Vec3 {
        (0..4).fold(Vec3::zeros(), |acc, i| {
            acc + x[self.vertices[i] as usize] * self.weights[i]
        })
    }

    /// Energy `kb/2 |sum_i k_i x_i|^2`.
    pub fn energy(&self, x: &[Vec3], kb: f64) -> f64 {
        0.5 * kb * self.curvature(x).norm_squared()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn hinge(theta: f64) -> ([Vec3; 4], BendStencil) {
        // Edge along x from (0,0) to (1,0); x2 above (uv y > 0), x3 below.
        let uv = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.3, 0.8),
            Vec2::new(0.6, -0.7),
        ];
        let s = BendStencil::new([0, 1, 2, 3], [uv[0], uv[1], uv[2]], [uv[0], uv[1], uv[3]]);
        // Rotate the second wing by theta around the edge.
        let x3 = Vec3::new(0.6, -0.7 * theta.cos(), 0.7 * theta.sin());
        (
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.3, 0.8, 0.0),
                x3,
            ],
            s,
        )
    }

    #[test]
    fn small_angles_cost_the_discrete_shell_energy() {
        for &theta in &[1e-3, 1e-2, 0.05] {
            let (x, s) = hinge(theta);
            let e = s.energy(&x, 1.0);
            // Discrete shells: 3 |e|^2 theta^2 / (A0 + A1), halved; A0 = 0.4, A1 = 0.35.
            let expect = 0.5 * 3.0 * theta * theta / 0.75;
            assert!(
                (e - expect).abs() < 0.01 * expect + 1e-12,
                "{theta}: {e} vs {expect}"
            );
        }
    }

    proptest! {
        /// Any affine image of the flat rest shape (in-plane stretch, shear, rotation,
        /// translation) has zero bending energy.
        #[test]
        fn affine_images_of_the_rest_shape_are_free(m in prop::array::uniform12(-2.0f64..2.0)) {
            let (x, s) = hinge(0.0);
            let a = nalgebra::Matrix3::new(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]);
            let t = Vec3::new(m[9], m[10], m[11]);
            let y: Vec<Vec3> = x.iter().map(|p| a * p + t).collect();
            prop_assert!(s.curvature(&y).norm() < 1e-9 * (1.0 + a.norm()));
            prop_assert!(s.weights.iter().sum::<f64>().abs() < 1e-12);
        }
    }
}
