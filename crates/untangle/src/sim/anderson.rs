//! Anderson acceleration of a fixed-point iteration `x <- G(x)` (Walker & Ni 2011; for the
//! local/global iterations of projective dynamics Peng et al. 2018, "Anderson Acceleration for
//! Geometry Optimization and Physics Simulation", Alg. 1-2): the next iterate is the
//! combination of the last `m + 1` values `G(x_j)` whose residuals `f_j = G(x_j) - x_j` combine
//! to the smallest norm,
//!
//! `theta = argmin |f_k - dF theta|`, `x_{k+1} = G(x_k) - dG theta`,
//!
//! with `dF`, `dG` the differences of consecutive residuals and values. The caller keeps Peng et
//! al.'s energy safeguard: an extrapolated iterate whose energy is above the last accepted one
//! is replaced by the plain `G(x_k)` ([`Anderson::plain`]) and the history restarts.

use std::collections::VecDeque;

use nalgebra::{DMatrix, DVector};

use crate::geom::Vec3;

/// History of one Anderson-accelerated fixed-point iteration.
#[derive(Clone, Debug, Default)]
pub struct Anderson {
    window: usize,
    /// Differences of consecutive residuals and of consecutive values, oldest first.
    df: VecDeque<Vec<Vec3>>,
    dg: VecDeque<Vec<Vec3>>,
    /// Residual and value `G(x_k)` of the last iteration.
    f: Vec<Vec3>,
    g: Vec<Vec3>,
    have_last: bool,
    /// The iterate `x_k` the current evaluation of `G` started from.
    x: Vec<Vec3>,
}

impl Anderson {
    /// An empty history of at most `window` differences (`m` in Peng et al.).
    pub fn new(window: usize) -> Anderson {
        Anderson {
            window,
            ..Default::default()
        }
    }

    /// Forgets the history (after a rejected extrapolation or a new system).
    pub fn reset(&mut self) {
        self.df.clear();
        self.dg.clear();
        self.have_last = false;
    }

    /// The last plain value `G(x_k)` (empty before the first [`Anderson::finish`]).
    pub fn plain(&self) -> &[Vec3] {
        &self.g
    }

    /// Records the iterate `x_k` that `G` is about to be evaluated at.
    pub fn begin(&mut self, x: &[Vec3]) {
        self.x.clear();
        self.x.extend_from_slice(x);
    }

    /// `x` holds `G(x_k)`: updates the history and, with `extrapolate`, replaces `x` by the
    /// accelerated iterate `G(x_k) - dG theta`. Returns whether it did (no history yet, or a
    /// singular least-squares problem, leave `x` as it is).
    pub fn finish(&mut self, x: &mut [Vec3], extrapolate: bool) -> bool {
        let n = x.len();
        let f: Vec<Vec3> = (0..n).map(|i| x[i] - self.x[i]).collect();
        if self.have_last {
            if self.df.len() == self.window {
                // Reuse the oldest buffers.
                let mut a = self.df.pop_front().unwrap_or_default();
                let mut b = self.dg.pop_front().unwrap_or_default();
                a.clear();
                b.clear();
                a.extend((0..n).map(|i| f[i] - self.f[i]));
                b.extend((0..n).map(|i| x[i] - self.g[i]));
                self.df.push_back(a);
                self.dg.push_back(b);
            } else {
                self.df
                    .push_back((0..n).map(|i| f[i] - self.f[i]).collect());
                self.dg
                    .push_back((0..n).map(|i| x[i] - self.g[i]).collect());
            }
        }
        self.f = f;
        self.g.clear();
        self.g.extend_from_slice(x);
        self.have_last = true;
        let m = self.df.len();
        if !extrapolate || m == 0 || self.window == 0 {
            return false;
        }
        // Normal equations of the small least-squares problem (in a fixed order: the result
        // does not depend on the thread count), slightly regularised.
        let dot = |a: &[Vec3], b: &[Vec3]| -> f64 { a.iter().zip(b).map(|(p, q)| p.dot(q)).sum() };
        let mut gram = DMatrix::<f64>::zeros(m, m);
        let mut rhs = DVector::<f64>::zeros(m);
        for a in 0..m {
            for b in a..m {
                let v = dot(&self.df[a], &self.df[b]);
                gram[(a, b)] = v;
                gram[(b, a)] = v;
            }
            rhs[a] = dot(&self.df[a], &self.f);
        }
        let scale = (0..m).map(|a| gram[(a, a)]).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return false;
        }
        for a in 0..m {
            gram[(a, a)] += 1e-10 * scale;
        }
        let Some(chol) = gram.cholesky() else {
            return false;
        };
        let theta = chol.solve(&rhs);
        if !theta.iter().all(|t| t.is_finite()) {
            return false;
        }
        for (a, t) in theta.iter().enumerate() {
            for (xi, d) in x.iter_mut().zip(&self.dg[a]) {
                *xi -= d * *t;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    /// `G(x) = M x + b` with `|M| < 1` on `3 n` unknowns.
    fn linear_map(seed: u64, n: usize, norm: f64) -> (DMatrix<f64>, DVector<f64>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let d = 3 * n;
        let m = DMatrix::<f64>::from_fn(d, d, |_, _| rng.random_range(-1.0..1.0));
        let s = m.clone().svd(false, false).singular_values.max();
        let b = DVector::<f64>::from_fn(d, |_, _| rng.random_range(-1.0..1.0));
        (m * (norm / s), b)
    }

    fn apply(m: &DMatrix<f64>, b: &DVector<f64>, x: &mut [Vec3]) {
        let v = DVector::from_iterator(x.len() * 3, x.iter().flat_map(|p| [p.x, p.y, p.z]));
        let y = m * v + b;
        for (i, p) in x.iter_mut().enumerate() {
            *p = Vec3::new(y[3 * i], y[3 * i + 1], y[3 * i + 2]);
        }
    }

    proptest! {
        /// On a linear contraction of dimension `d` with a window of `d`, Anderson acceleration
        /// is GMRES in disguise: it reaches the fixed point (oracle: a dense LU solve of
        /// `(I - M) x = b`) after `d + 2` evaluations, where the plain iteration of the same
        /// count is still far from it.
        #[test]
        fn linear_fixed_point_is_found(seed in 0u64..500, n in 1usize..3) {
            let (m, b) = linear_map(seed, n, 0.95);
            let d = 3 * n;
            let exact = (DMatrix::<f64>::identity(d, d) - &m).lu().solve(&b).unwrap();
            let err = |x: &[Vec3]| {
                (0..n).map(|i| (x[i] - Vec3::new(exact[3 * i], exact[3 * i + 1], exact[3 * i + 2])).norm())
                    .fold(0.0, f64::max)
            };
            let mut aa = Anderson::new(d);
            let mut x = vec![Vec3::zeros(); n];
            let mut plain = x.clone();
            for _ in 0..d + 2 {
                aa.begin(&x);
                apply(&m, &b, &mut x);
                aa.finish(&mut x, true);
                apply(&m, &b, &mut plain);
            }
            let scale = 1.0 + exact.amax();
            prop_assert!(err(&x) <= 1e-6 * scale, "accelerated error {}", err(&x));
            // The plain value G(x_k) is kept for the safeguard.
            let mut last = aa.x.clone();
            apply(&m, &b, &mut last);
            prop_assert_eq!(aa.plain(), &last[..]);
        }

        /// With the window 0 or without extrapolation the iteration is the plain one, bit for bit.
        #[test]
        fn without_extrapolation_it_is_plain(seed in 0u64..500, window in 0usize..4) {
            let (m, b) = linear_map(seed, 2, 0.9);
            let mut aa = Anderson::new(window);
            let mut x = vec![Vec3::zeros(); 2];
            let mut plain = x.clone();
            for k in 0..6 {
                aa.begin(&x);
                apply(&m, &b, &mut x);
                prop_assert!(!aa.finish(&mut x, window > 0 && k == 0));
                apply(&m, &b, &mut plain);
                prop_assert_eq!(&x, &plain);
            }
        }
    }
}
