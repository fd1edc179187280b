//! Preconditioned conjugate gradients with the constraint filter of Baraff & Witkin 1998
//! (Sec. 5.3, "modified PCG"): constrained nodes keep their prescribed value, the residual and
//! search directions are projected onto the free directions, and the stopping test is relative
//! to the filtered right-hand side. Block-Jacobi (3x3) preconditioner.
//!
//! All reductions are summed in a fixed chunk order, so results are bit-identical for any
//! number of threads.

use nalgebra::Matrix3;
use rayon::prelude::*;

use super::sparse::{dot, BsrMatrix, BsrPattern, CHUNK};
use crate::geom::Vec3;

/// Per-node constraint of the filter: the node's velocity change is either free or prescribed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// All three directions free.
    Free,
    /// All three directions prescribed (a pinned node).
    Fixed,
    /// The direction `n` (unit) prescribed, the plane orthogonal to it free.
    Normal(Vec3),
}

impl Filter {
    #[inline]
    fn apply(&self, v: Vec3) -> Vec3 {
        match self {
            Filter::Free => v,
            Filter::Fixed => Vec3::zeros(),
            Filter::Normal(n) => v - n * n.dot(&v),
        }
    }
}

/// Stopping rule of the solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PcgSettings {
    /// Relative tolerance on the preconditioned residual norm.
    pub tolerance: f64,
    /// Iteration cap.
    pub max_iterations: usize,
}

/// What a solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PcgResult {
    /// Iterations run.
    pub iterations: usize,
    /// Final relative residual (preconditioned norm, relative to the filtered right-hand side).
    pub relative_residual: f64,
    /// Whether the tolerance was reached (false: stopped at the iteration cap).
    pub converged: bool,
}

/// Solves `A x = b` for the free directions, with `x = z` in the constrained ones. On input the
/// free directions of `x` are the initial guess (warm start); on output `x` is the solution; `A` must be symmetric positive definite on the free subspace.
pub fn solve(
    pattern: &BsrPattern,
    a: &BsrMatrix,
    b: &[Vec3],
    filter: &[Filter],
    z: &[Vec3],
    x: &mut [Vec3],
    settings: PcgSettings,
) -> PcgResult {
    let n = b.len();
    let pinv: Vec<Matrix3<f64>> = (0..n)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|i| {
            let d = a.values[pattern.diag[i] as usize];
            d.try_inverse()
                .filter(|m| m.iter().all(|v| v.is_finite()))
                .unwrap_or_else(|| {
                    let s = d
                        .diagonal()
                        .map(|v| if v.abs() > 0.0 { 1.0 / v } else { 0.0 });
                    Matrix3::from_diagonal(&s)
                })
        })
        .collect();
    let precond = |r: &[Vec3], out: &mut [Vec3]| {
        out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, o)| {
            for (k, oi) in o.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                *oi = filter[i].apply(pinv[i] * r[i]);
            }
        });
    };
    for i in 0..n {
        x[i] = match filter[i] {
            Filter::Free => x[i],
            Filter::Fixed => z[i],
            Filter::Normal(nn) => nn * nn.dot(&z[i]) + (x[i] - nn * nn.dot(&x[i])),
        };
    }
    let mut q = vec![Vec3::zeros(); n];
    a.mul(pattern, x, &mut q);
    let mut r: Vec<Vec3> = (0..n).map(|i| filter[i].apply(b[i] - q[i])).collect();
    let fb: Vec<Vec3> = (0..n).map(|i| filter[i].apply(b[i])).collect();
    let mut s = vec![Vec3::zeros(); n];
    precond(&fb, &mut s);
    let delta0 = dot(&fb, &s);
    let mut c = vec![Vec3::zeros(); n];
    precond(&r, &mut c);
    let mut delta_new = dot(&r, &c);
    let tol2 = settings.tolerance * settings.tolerance;
    let mut it = 0;
    let rel = |d: f64| {
        if delta0 > 0.0 {
            (d.max(0.0) / delta0).sqrt()
        } else {
            0.0
        }
    };
    while delta_new > tol2 * delta0 && it < settings.max_iterations {
        a.mul(pattern, &c, &mut q);
        q.par_chunks_mut(CHUNK).enumerate().for_each(|(ch, qs)| {
            for (k, qi) in qs.iter_mut().enumerate() {
                *qi = filter[ch * CHUNK + k].apply(*qi);
            }
        });
        let cq = dot(&c, &q);
        if cq.is_nan() || cq <= 0.0 {
            break;
        }
        let alpha = delta_new / cq;
        x.par_chunks_mut(CHUNK)
            .zip(r.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(ch, (xs, rs))| {
                for k in 0..xs.len() {
                    let i = ch * CHUNK + k;
                    xs[k] += alpha * c[i];
                    rs[k] -= alpha * q[i];
                }
            });
        precond(&r, &mut s);
        let delta_old = delta_new;
        delta_new = dot(&r, &s);
        let beta = delta_new / delta_old;
        c.par_chunks_mut(CHUNK).enumerate().for_each(|(ch, cs)| {
            for (k, ci) in cs.iter_mut().enumerate() {
                let i = ch * CHUNK + k;
                *ci = filter[i].apply(s[i] + beta * *ci);
            }
        });
        it += 1;
    }
    PcgResult {
        iterations: it,
        relative_residual: rel(delta_new),
        converged: delta_new <= tol2 * delta0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random SPD block system on a ring-with-chords pattern.
    fn random_system(n: usize, seed: u64) -> (BsrPattern, BsrMatrix, Vec<Vec3>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let pairs: Vec<(u32, u32)> = (0..n as u32)
            .map(|i| (i, (i + 1) % n as u32))
            .chain((0..n as u32).map(|i| (i, (i * 7 + 3) % n as u32)))
            .filter(|(i, j)| i != j)
            .collect();
        let p = BsrPattern::from_pairs(n, pairs.clone());
        let mut a = BsrMatrix::zeros(&p);
        // Sum of PSD element matrices (like springs) plus a mass diagonal: SPD.
        for &(i, j) in &pairs {
            let d = Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5);
            let k = d * d.transpose() * 50.0 + Matrix3::identity() * 0.3;
            for (r, c, s) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                let slot = p.slot(r, c).unwrap();
                a.values[slot] += k * s;
            }
        }
        for i in 0..n {
            a.values[p.diag[i] as usize] += Matrix3::identity() * rng.random_range(0.5..2.0);
        }
        let b = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        (p, a, b)
    }

    #[test]
    fn matches_dense_solve_with_and_without_constraints() {
        for seed in 0..6 {
            let n = 40 + seed as usize * 7;
            let (p, a, b) = random_system(n, seed);
            let mut filter = vec![Filter::Free; n];
            let mut z = vec![Vec3::zeros(); n];
            if seed % 2 == 1 {
                filter[3] = Filter::Fixed;
                z[3] = Vec3::new(0.1, -0.2, 0.3);
                filter[10] = Filter::Normal(Vec3::new(0.0, 0.6, 0.8));
                z[10] = Vec3::new(0.0, 0.6, 0.8) * 0.5;
            }
            let mut x = vec![Vec3::zeros(); n];
            let res = solve(
                &p,
                &a,
                &b,
                &filter,
                &z,
                &mut x,
                PcgSettings {
                    tolerance: 1e-12,
                    max_iterations: 10_000,
                },
            );
            assert!(res.converged, "{res:?}");
            // Oracle: dense solve of the reduced system S A S y = S (b - A z) on the free
            // subspace, with x = z_c + y.
            let d = a.to_dense(&p);
            let mut s = nalgebra::DMatrix::<f64>::identity(3 * n, 3 * n);
            let mut zc = nalgebra::DVector::<f64>::zeros(3 * n);
            for i in 0..n {
                let si = match filter[i] {
                    Filter::Free => Matrix3::identity(),
                    Filter::Fixed => Matrix3::zeros(),
                    Filter::Normal(nn) => Matrix3::identity() - nn * nn.transpose(),
                };
                s.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&si);
                let zi = (Matrix3::identity() - si) * z[i];
                zc.fixed_rows_mut::<3>(3 * i).copy_from(&zi);
            }
            let bd =
                nalgebra::DVector::from_iterator(3 * n, b.iter().flat_map(|v| [v.x, v.y, v.z]));
            let lhs = &s * &d * &s + (nalgebra::DMatrix::identity(3 * n, 3 * n) - &s);
            let rhs = &s * (bd - &d * &zc);
            let y = lhs.lu().solve(&rhs).unwrap();
            let xd = zc + y;
            for i in 0..3 * n {
                assert!(
                    (x[i / 3][i % 3] - xd[i]).abs() < 1e-8 * (1.0 + xd[i].abs()),
                    "seed {seed} entry {i}: {} vs {}",
                    x[i / 3][i % 3],
                    xd[i]
                );
            }
        }
    }

    #[test]
    fn iteration_cap_is_reported() {
        let (p, a, b) = random_system(200, 9);
        let mut x = vec![Vec3::zeros(); 200];
        let res = solve(
            &p,
            &a,
            &b,
            &vec![Filter::Free; 200],
            &vec![Vec3::zeros(); 200],
            &mut x,
            PcgSettings {
                tolerance: 1e-14,
                max_iterations: 3,
            },
        );
        assert_eq!(res.iterations, 3);
        assert!(!res.converged);
        assert!(res.relative_residual > 1e-14);
    }
}
