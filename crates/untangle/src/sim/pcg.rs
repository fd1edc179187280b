//! Preconditioned conjugate gradients with the constraint filter of Baraff & Witkin 1998
//! (Sec. 5.3, "modified PCG"): constrained nodes keep their prescribed value, the residual and
//! search directions are projected onto the free directions, and the stopping test is relative
//! to the filtered right-hand side.
//!
//! Preconditioner: block-Jacobi (3x3), optionally plus an additive coarse-grid correction over
//! vertex aggregates ([`Aggregation`]; two-level additive Schwarz with piecewise-constant coarse
//! functions, as in smoothed-aggregation multigrid without the smoothing). Stiff cloth on a fine
//! mesh has `h^2 k / m` in the tens of thousands, so the smooth (nearly rigid) modes have tiny
//! eigenvalues after Jacobi scaling and block-Jacobi CG needs hundreds of iterations; the coarse
//! correction removes those modes. The coarse functions are filtered like everything else.
//!
//! All reductions are summed in a fixed chunk order, so results are bit-identical for any
//! number of threads.

use nalgebra::Matrix3;
use rayon::prelude::*;

use super::amg::AmgPreconditioner;
use super::cholesky::ScalarCholesky;
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
    /// Projects `v` onto the free directions.
    #[inline]
    pub fn apply(&self, v: Vec3) -> Vec3 {
        match self {
            Filter::Free => v,
            Filter::Fixed => Vec3::zeros(),
            Filter::Normal(n) => v - n * n.dot(&v),
        }
    }
}

/// A partition of the nodes into connected aggregates (breadth-first over the mesh graph), the
/// coarse level of the preconditioner.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aggregation {
    /// Aggregate of each node.
    pub of_node: Vec<u32>,
    /// Number of aggregates.
    pub count: usize,
}

impl Aggregation {
    /// Greedy breadth-first aggregation of `n` nodes with neighbours `neighbors(i)`, each
    /// aggregate at most `size` nodes (deterministic: seeds in node order).
    pub fn from_graph<'a>(n: usize, neighbors: impl Fn(usize) -> &'a [u32], size: usize) -> Self {
        let size = size.max(1);
        let mut of_node = vec![u32::MAX; n];
        let mut count = 0u32;
        let mut queue = std::collections::VecDeque::new();
        for seed in 0..n {
            if of_node[seed] != u32::MAX {
                continue;
            }
            let mut taken = 0;
            of_node[seed] = count;
            taken += 1;
            queue.clear();
            queue.push_back(seed);
            'bfs: while let Some(i) = queue.pop_front() {
                for &j in neighbors(i) {
                    if taken >= size {
                        break 'bfs;
                    }
                    if of_node[j as usize] == u32::MAX {
                        of_node[j as usize] = count;
                        taken += 1;
                        queue.push_back(j as usize);
                    }
                }
            }
            count += 1;
        }
        Aggregation {
            of_node,
            count: count as usize,
        }
    }
}

/// The factorised coarse matrix `P^T S A S P` (3 unknowns per aggregate, `S` the filter's
/// projection). Any SPD coarse matrix gives a valid preconditioner, so one factorisation can
/// serve several solves whose matrices or filters differ slightly.
pub struct CoarseLevel<'a> {
    agg: &'a Aggregation,
    chol: nalgebra::linalg::Cholesky<f64, nalgebra::Dyn>,
}

impl<'a> CoarseLevel<'a> {
    /// Assembles and factorises the coarse matrix of `a` under `filter` (the pair couplings
    /// outside the pattern are left out: the rest is still SPD); `None` when the aggregation is
    /// empty or the factorisation fails.
    pub fn new(
        agg: &'a Aggregation,
        pattern: &BsrPattern,
        a: &BsrMatrix,
        filter: &[Filter],
    ) -> Option<Self> {
        if agg.count == 0 {
            return None;
        }
        let proj: Vec<Matrix3<f64>> = filter
            .iter()
            .map(|f| match f {
                Filter::Free => Matrix3::identity(),
                Filter::Fixed => Matrix3::zeros(),
                Filter::Normal(nn) => Matrix3::identity() - nn * nn.transpose(),
            })
            .collect();
        let m = 3 * agg.count;
        let mut d = nalgebra::DMatrix::<f64>::zeros(m, m);
        for i in 0..pattern.rows() {
            let ai = agg.of_node[i] as usize;
            for slot in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                let j = pattern.cols[slot] as usize;
                let aj = agg.of_node[j] as usize;
                let blk = proj[i] * a.values[slot] * proj[j];
                let mut v = d.fixed_view_mut::<3, 3>(3 * ai, 3 * aj);
                v += blk;
            }
        }
        // Aggregates without free directions: identity rows (their correction is zero anyway).
        let top = (0..m).fold(0.0f64, |t, k| t.max(d[(k, k)]));
        for k in 0..m {
            if d[(k, k)] <= 1e-14 * top {
                for l in 0..m {
                    d[(k, l)] = 0.0;
                    d[(l, k)] = 0.0;
                }
                d[(k, k)] = top.max(1.0);
            }
        }
        d.cholesky().map(|chol| CoarseLevel { agg, chol })
    }

    /// `out += S P A_c^-1 P^T r` (r already filtered).
    fn add_correction(&self, r: &[Vec3], filter: &[Filter], out: &mut [Vec3]) {
        self.add_correction_dot(r, filter, out);
    }

    /// [`CoarseLevel::add_correction`], returning `r . (S P A_c^-1 P^T r)`.
    fn add_correction_dot(&self, r: &[Vec3], filter: &[Filter], out: &mut [Vec3]) -> f64 {
        let mut rc = nalgebra::DVector::<f64>::zeros(3 * self.agg.count);
        for (i, ri) in r.iter().enumerate() {
            let a = 3 * self.agg.of_node[i] as usize;
            rc[a] += ri.x;
            rc[a + 1] += ri.y;
            rc[a + 2] += ri.z;
        }
        self.chol.solve_mut(&mut rc);
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, o)| {
                let mut acc = 0.0;
                for (k, oi) in o.iter_mut().enumerate() {
                    let i = c * CHUNK + k;
                    let a = 3 * self.agg.of_node[i] as usize;
                    let d = filter[i].apply(Vec3::new(rc[a], rc[a + 1], rc[a + 2]));
                    *oi += d;
                    acc += r[i].dot(&d);
                }
                acc
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum()
    }
}

/// The preconditioner of a solve.
#[derive(Clone, Copy)]
pub enum Preconditioner<'a> {
    /// Filtered 3x3 block-Jacobi, optionally plus the additive coarse-grid correction.
    BlockJacobi(Option<&'a CoarseLevel<'a>>),
    /// One smoothed-aggregation multigrid V-cycle ([`crate::sim::amg`]).
    Amg(&'a AmgPreconditioner<'a>),
    /// A sparse Cholesky factor of a scalar matrix `B`, applied as `S (B^-1 (x) I3) S` (the
    /// projective-dynamics global matrix, [`crate::sim::cholesky`], [`crate::sim::projective`]).
    Cholesky(&'a ScalarCholesky),
}

/// Stopping rule of the solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PcgSettings {
    /// Relative tolerance on the preconditioned residual norm.
    pub tolerance: f64,
    /// Absolute floor of the stopping threshold on the preconditioned residual norm
    /// `sqrt(r^T P r)` (≈ the energy norm of the error; 0: purely relative). The simulator uses
    /// `tolerance * |g| h * sqrt(total mass)`, an RMS velocity error of `tolerance` times what
    /// gravity adds in one step, so that a cloth near equilibrium (a tiny right-hand side) is not
    /// solved to a needlessly tiny absolute error.
    pub absolute: f64,
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
#[allow(clippy::too_many_arguments)]
pub fn solve(
    pattern: &BsrPattern,
    a: &BsrMatrix,
    b: &[Vec3],
    filter: &[Filter],
    z: &[Vec3],
    x: &mut [Vec3],
    settings: PcgSettings,
    preconditioner: Preconditioner,
) -> PcgResult {
    let (coarse, amg, chol) = match preconditioner {
        Preconditioner::BlockJacobi(c) => (c, None, None),
        Preconditioner::Amg(m) => (None, Some(m), None),
        Preconditioner::Cholesky(f) => (None, None, Some(f)),
    };
    let n = b.len();
    // Block-Jacobi inverses (not needed when another preconditioner replaces it).
    let pinv: Vec<Matrix3<f64>> = (0..if amg.is_some() || chol.is_some() {
        0
    } else {
        n
    })
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
        if let Some(m) = amg {
            m.apply(r, out);
            return;
        }
        if let Some(f) = chol {
            f.apply(r, filter, out);
            return;
        }
        out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, o)| {
            for (k, oi) in o.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                *oi = filter[i].apply(pinv[i] * r[i]);
            }
        });
        if let Some(c) = coarse {
            c.add_correction(r, filter, out);
        }
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
    if same_bits(&r, &fb) {
        // A cold start without prescribed values (`x = 0`, as in every projective global
        // step): the residual is the filtered right-hand side, whose preconditioned vector was
        // just computed (one solve with the factor saved per call).
        c.copy_from_slice(&s);
    } else {
        precond(&r, &mut c);
    }
    let mut delta_new = dot(&r, &c);
    let tol2 = settings.tolerance * settings.tolerance;
    let threshold = (tol2 * delta0).max(settings.absolute * settings.absolute);
    let mut it = 0;
    let rel = |d: f64| {
        if delta0 > 0.0 {
            (d.max(0.0) / delta0).sqrt()
        } else {
            0.0
        }
    };
    while delta_new > threshold && it < settings.max_iterations {
        // Fused passes (fewer parallel rounds per iteration); partial sums per fixed chunk,
        // added in chunk order, so results do not depend on the thread count.
        // q = S A c and c . q, in one pass when possible.
        let cq = a.mul_then_sum(pattern, &c, &mut q, |first, qs| {
            let mut acc = 0.0;
            for (k, qi) in qs.iter_mut().enumerate() {
                let i = first + k;
                *qi = filter[i].apply(*qi);
                acc += c[i].dot(qi);
            }
            acc
        });
        if cq.is_nan() || cq <= 0.0 {
            break;
        }
        let alpha = delta_new / cq;
        // x += alpha c, r -= alpha q, s = filtered block-Jacobi of r, and r . s.
        let mut rs_dot: f64 = if amg.is_some() || chol.is_some() {
            advance(x, &mut r, &c, &q, alpha);
            match (amg, chol) {
                (Some(m), _) => m.apply(&r, &mut s),
                (None, Some(f)) => f.apply(&r, filter, &mut s),
                (None, None) => unreachable!("checked above"),
            }
        } else {
            x.par_chunks_mut(CHUNK)
                .zip(r.par_chunks_mut(CHUNK))
                .zip(s.par_chunks_mut(CHUNK))
                .enumerate()
                .map(|(ch, ((xs, rs), ss))| {
                    let mut acc = 0.0;
                    for k in 0..xs.len() {
                        let i = ch * CHUNK + k;
                        xs[k] += alpha * c[i];
                        rs[k] -= alpha * q[i];
                        ss[k] = filter[i].apply(pinv[i] * rs[k]);
                        acc += rs[k].dot(&ss[k]);
                    }
                    acc
                })
                .collect::<Vec<f64>>()
                .iter()
                .sum()
        };
        if let Some(cl) = coarse {
            rs_dot += cl.add_correction_dot(&r, filter, &mut s);
        }
        if rs_dot.is_nan() || rs_dot < 0.0 {
            // Not positive definite (cannot happen with a convergent smoother): stop here.
            delta_new = f64::INFINITY;
            break;
        }
        let delta_old = delta_new;
        delta_new = rs_dot;
        let beta = delta_new / delta_old;
        new_direction(&mut c, &s, filter, beta);
        it += 1;
    }
    PcgResult {
        iterations: it,
        relative_residual: rel(delta_new),
        converged: delta_new <= threshold,
    }
}

/// One CG update of the iterate and the residual: `x += alpha c`, `r -= alpha q` (in fixed
/// chunks, so the result does not depend on the thread count).
fn advance(x: &mut [Vec3], r: &mut [Vec3], c: &[Vec3], q: &[Vec3], alpha: f64) {
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
}

/// The next CG search direction `c = S (s + beta c)` (Baraff & Witkin 1998, Sec. 5.3: the
/// filter keeps it in the free directions).
fn new_direction(c: &mut [Vec3], s: &[Vec3], filter: &[Filter], beta: f64) {
    c.par_chunks_mut(CHUNK).enumerate().for_each(|(ch, cs)| {
        for (k, ci) in cs.iter_mut().enumerate() {
            let i = ch * CHUNK + k;
            *ci = filter[i].apply(s[i] + beta * *ci);
        }
    });
}

/// `v = S v` (the constraint filter) and returns `w . v`, summed per fixed chunk in chunk order
/// (independent of the thread count).
fn filter_dot(v: &mut [Vec3], filter: &[Filter], w: &[Vec3]) -> f64 {
    let parts: Vec<f64> = v
        .par_chunks_mut(CHUNK)
        .enumerate()
        .map(|(ch, vs)| {
            let mut acc = 0.0;
            for (k, vi) in vs.iter_mut().enumerate() {
                let i = ch * CHUNK + k;
                *vi = filter[i].apply(*vi);
                acc += w[i].dot(vi);
            }
            acc
        })
        .collect();
    parts.iter().sum()
}

/// Which substitution applies the factor in [`solve_factored`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FactorSolve {
    /// faer's double-precision solve ([`ScalarCholesky::solve3`]).
    Double,
    /// The single-precision supernodal substitution ([`ScalarCholesky::solve_increment_with`]):
    /// half the bytes read and the three coordinates in one pass. The residual, the iterate
    /// and all reductions stay in double precision; only the preconditioner is rounded (a
    /// slightly perturbed preconditioner, not a perturbed system).
    Single,
}

/// The preconditioner `out = S (B^-1 (x) I3) S r` with the factor of `B` applied by `how`;
/// returns `r . out` (summed in fixed chunks, in order).
pub fn apply_factor(
    factor: &ScalarCholesky,
    how: FactorSolve,
    r: &[Vec3],
    filter: &[Filter],
    out: &mut [Vec3],
) -> f64 {
    match how {
        FactorSolve::Double => factor.apply(r, filter, out),
        FactorSolve::Single => {
            if factor.is_factored() {
                factor.solve_increment_with(|i| filter[i].apply(r[i]), out);
            } else {
                for (o, (ri, f)) in out.iter_mut().zip(r.iter().zip(filter)) {
                    *o = f.apply(*ri);
                }
            }
            filter_dot(out, filter, r)
        }
    }
}

/// [`solve`] preconditioned with a sparse Cholesky factor ([`Preconditioner::Cholesky`]) for
/// an operator given as a function, `apply(x, y)` writing `y = A x` (every row; `A` symmetric,
/// positive definite on the free subspace): the projective-dynamics global step under contact
/// terms, whose matrix is the factored scalar one plus a few rank-one terms and is never
/// assembled ([`crate::sim::projective::ContactTerms`]). The same filtered CG as [`solve`]
/// (Baraff & Witkin 1998, Sec. 5.3), with the factor applied by `how`. A start `x` that is zero
/// after filtering skips the first product (`A 0 = 0`). Reductions are summed in fixed chunks,
/// so the result does not depend on the thread count when `apply` does not.
#[allow(clippy::too_many_arguments)]
pub fn solve_factored(
    apply: &(dyn Fn(&[Vec3], &mut [Vec3]) + Sync),
    b: &[Vec3],
    filter: &[Filter],
    z: &[Vec3],
    x: &mut [Vec3],
    settings: PcgSettings,
    factor: &ScalarCholesky,
    how: FactorSolve,
) -> PcgResult {
    let n = b.len();
    for i in 0..n {
        x[i] = match filter[i] {
            Filter::Free => x[i],
            Filter::Fixed => z[i],
            Filter::Normal(nn) => nn * nn.dot(&z[i]) + (x[i] - nn * nn.dot(&x[i])),
        };
    }
    let mut q = vec![Vec3::zeros(); n];
    let cold = x.iter().all(|v| *v == Vec3::zeros());
    if !cold {
        apply(x, &mut q);
    }
    let mut r: Vec<Vec3> = (0..n).map(|i| filter[i].apply(b[i] - q[i])).collect();
    let fb: Vec<Vec3> = (0..n).map(|i| filter[i].apply(b[i])).collect();
    let mut s = vec![Vec3::zeros(); n];
    let delta0 = apply_factor(factor, how, &fb, filter, &mut s);
    let mut c = vec![Vec3::zeros(); n];
    let mut delta_new = if same_bits(&r, &fb) {
        c.copy_from_slice(&s);
        delta0
    } else {
        apply_factor(factor, how, &r, filter, &mut c)
    };
    let tol2 = settings.tolerance * settings.tolerance;
    let threshold = (tol2 * delta0).max(settings.absolute * settings.absolute);
    let mut it = 0;
    let rel = |d: f64| {
        if delta0 > 0.0 {
            (d.max(0.0) / delta0).sqrt()
        } else {
            0.0
        }
    };
    while delta_new > threshold && it < settings.max_iterations {
        apply(&c, &mut q);
        let cq = filter_dot(&mut q, filter, &c);
        if cq.is_nan() || cq <= 0.0 {
            break;
        }
        let alpha = delta_new / cq;
        advance(x, &mut r, &c, &q, alpha);
        if it + 1 == settings.max_iterations {
            // At the cap the next preconditioned residual would only serve the stopping test:
            // skip its factor solve (the same iterate; the residual reported is the one before
            // this iteration, and the solve counts as not converged).
            return PcgResult {
                iterations: it + 1,
                relative_residual: rel(delta_new),
                converged: false,
            };
        }
        let rs_dot = apply_factor(factor, how, &r, filter, &mut s);
        if rs_dot.is_nan() || rs_dot < 0.0 {
            delta_new = f64::INFINITY;
            break;
        }
        let delta_old = delta_new;
        delta_new = rs_dot;
        let beta = delta_new / delta_old;
        new_direction(&mut c, &s, filter, beta);
        it += 1;
    }
    PcgResult {
        iterations: it,
        relative_residual: rel(delta_new),
        converged: delta_new <= threshold,
    }
}

/// Galerkin correction of an approximate solution `x` of `A x = b` in the three global
/// translations (each restricted to the free directions by the filter): `x += S E c` with
/// `(E^T S A S E) c = E^T S (b - A x)`. Afterwards the filtered residual sums to zero.
///
/// Why: `K` (elasticity, contact springs) has the rigid translations in its null space, so for a
/// free cloth the exact solution changes the momentum only by the external impulse
/// (`sum_i (A dv)_i = c_m sum_i m_i dv_i`). With a block-Jacobi preconditioner the translations
/// are the slowest modes of CG, so a relative tolerance leaves most of the error exactly there:
/// a tangled cloth under large internal forces gained momentum every step (a gravity-free sheet
/// drifted away). The correction is an `A`-orthogonal projection, so it never increases the
/// energy norm of the error. Cost: four products with `A`. Returns `c`.
pub fn correct_translations(
    pattern: &BsrPattern,
    a: &BsrMatrix,
    b: &[Vec3],
    filter: &[Filter],
    x: &mut [Vec3],
) -> Vec3 {
    let modes = translation_modes(filter);
    match galerkin_correction(pattern, a, b, &modes, x) {
        Some(c) => Vec3::new(c[0], c[1], c[2]),
        None => Vec3::zeros(),
    }
}

/// Galerkin correction of an approximate solution `x` of `A x = b` in the six rigid motions of
/// the cloth at `positions` (three translations, three rotations about the centroid, each
/// restricted to the free directions by the filter), as [`correct_translations`] does for the
/// translations alone; afterwards the filtered residual has no force and no torque about the
/// centroid. Falls back to the translations alone when the 6 x 6 Galerkin matrix is singular
/// (e.g. a cloth whose free vertices are collinear).
///
/// Why: the rotations are almost in the null space of `K` too (exactly for an unstressed cloth;
/// the stress adds the geometric stiffness), so CG leaves its error there as well. In a tangled
/// cloth whose rest shape Cha & Ko's pulls have shrunk (rest edges 0.003 against world edges
/// 0.5, stretch energies of 10^8 J), that error is a large spurious angular momentum every step;
/// a rigid impact zone keeps it and turns it into spin, whose linearised rotation inflates the
/// zone by `sqrt(1 + (h |omega|)^2)` per step, raising the stretch forces further: the
/// exploded-handkerchief seeds 28 and 38 (with `avoid_loop_pull_targets`) grew to edges of
/// 10^40 m. An `A`-orthogonal projection: it never increases the energy norm of the error.
/// Cost: seven products with `A`. Returns the coefficients (translations, then rotations).
pub fn correct_rigid_motions(
    pattern: &BsrPattern,
    a: &BsrMatrix,
    b: &[Vec3],
    filter: &[Filter],
    positions: &[Vec3],
    x: &mut [Vec3],
) -> Option<[f64; 6]> {
    let n = b.len();
    let mut modes = translation_modes(filter);
    let free = filter
        .iter()
        .filter(|f| !matches!(f, Filter::Fixed))
        .count();
    if free > 0 {
        let c = (0..n)
            .filter(|&i| !matches!(filter[i], Filter::Fixed))
            .fold(Vec3::zeros(), |s, i| s + positions[i])
            / free as f64;
        for axis in [Vec3::x(), Vec3::y(), Vec3::z()] {
            let u: Vec<Vec3> = (0..n)
                .map(|i| filter[i].apply(axis.cross(&(positions[i] - c))))
                .collect();
            // Unit length: the Galerkin matrix then mixes modes of comparable scale.
            let l = dot(&u, &u).sqrt();
            if l > 0.0 && l.is_finite() {
                modes.push(u.into_iter().map(|v| v / l).collect());
            }
        }
    }
    if modes.len() == 6 {
        let mut trial = x.to_vec();
        if let Some(c) = galerkin_correction(pattern, a, b, &modes, &mut trial) {
            x.copy_from_slice(&trial);
            return Some([c[0], c[1], c[2], c[3], c[4], c[5]]);
        }
    }
    modes.truncate(3);
    galerkin_correction(pattern, a, b, &modes, x).map(|c| [c[0], c[1], c[2], 0.0, 0.0, 0.0])
}

/// The three global translations restricted by the filter.
fn translation_modes(filter: &[Filter]) -> Vec<Vec<Vec3>> {
    [Vec3::x(), Vec3::y(), Vec3::z()]
        .iter()
        .map(|e| filter.iter().map(|f| f.apply(*e)).collect())
        .collect()
}

/// `x += U c` with `(U^T A U) c = U^T (b - A x)` for the (already filtered) modes `U`; `None`
/// (and `x` unchanged) when the Galerkin matrix is not positive definite or `c` not finite.
fn galerkin_correction(
    pattern: &BsrPattern,
    a: &BsrMatrix,
    b: &[Vec3],
    modes: &[Vec<Vec3>],
    x: &mut [Vec3],
) -> Option<nalgebra::DVector<f64>> {
    let n = b.len();
    let m = modes.len();
    let mut ax = vec![Vec3::zeros(); n];
    a.mul(pattern, x, &mut ax);
    // The modes are filtered, so `U^T r` only sees the free directions of `b - A x`.
    let r: Vec<Vec3> = (0..n).map(|i| b[i] - ax[i]).collect();
    let au: Vec<Vec<Vec3>> = modes
        .iter()
        .map(|ud| {
            let mut y = vec![Vec3::zeros(); n];
            a.mul(pattern, ud, &mut y);
            y
        })
        .collect();
    let mut g = nalgebra::DMatrix::<f64>::zeros(m, m);
    let mut rhs = nalgebra::DVector::<f64>::zeros(m);
    for d in 0..m {
        rhs[d] = dot(&modes[d], &r);
        for e in 0..m {
            g[(d, e)] = dot(&modes[d], &au[e]);
        }
    }
    let g = (&g + g.transpose()) * 0.5;
    let c = g.cholesky()?.solve(&rhs);
    if !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    x.par_chunks_mut(CHUNK).enumerate().for_each(|(ch, xs)| {
        for (k, xi) in xs.iter_mut().enumerate() {
            let i = ch * CHUNK + k;
            for (d, u) in modes.iter().enumerate() {
                *xi += u[i] * c[d];
            }
        }
    });
    Some(c)
}

/// Whether `a` and `b` hold the same values bit for bit (`0.0` and `-0.0` differ), so that a
/// function of `a` may be reused for `b` without changing any result.
fn same_bits(a: &[Vec3], b: &[Vec3]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| {
            p.iter()
                .zip(q.iter())
                .all(|(x, y)| x.to_bits() == y.to_bits())
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `same_bits` tells `0.0` from `-0.0` and NaN payloads apart, unlike `==` on floats.
    #[test]
    fn same_bits_is_bitwise() {
        let a = vec![Vec3::new(1.0, 0.0, -2.5); 3];
        assert!(same_bits(&a, &a.clone()));
        let mut b = a.clone();
        b[1].y = -0.0;
        assert!(b == a, "float equality ignores the sign of zero");
        assert!(!same_bits(&a, &b));
        let nan = vec![Vec3::new(f64::NAN, 0.0, 0.0)];
        assert!(same_bits(&nan, &nan.clone()));
        assert!(!same_bits(&a, &a[..2]));
    }

    /// [`solve_factored`] capped at `k` iterations (tolerance 0, so the cap stops it; at the
    /// cap it skips the stopping test's solve) gives the `k`-th iterate of a textbook PCG with
    /// the same preconditioner, written out here; also when `A` is not the factored matrix.
    #[test]
    fn capped_factored_solve_is_the_kth_textbook_iterate() {
        for seed in 0..6u64 {
            let n = 40;
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let pairs = ring_with_chords(n);
            let p = BsrPattern::from_pairs(n, pairs.clone());
            // A scalar Laplacian plus a mass diagonal (SPD), factored.
            let mut values = vec![0.0; p.cols.len()];
            for &(i, j) in &pairs {
                let k = rng.random_range(0.5..3.0);
                for (r, c, sgn) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                    values[p.slot(r, c).unwrap()] += k * sgn;
                }
            }
            for i in 0..n {
                values[p.diag[i] as usize] += rng.random_range(0.5..2.0);
            }
            let mut chol = ScalarCholesky::new(&p).unwrap();
            assert!(chol.factor(&p, &values, &vec![false; n]));
            // A = B (x) I3 + a rank-one term (so that the factor is only a preconditioner).
            let w: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5))
                .collect();
            let apply = |x: &[Vec3], y: &mut [Vec3]| {
                let mut d = 0.0;
                for i in 0..n {
                    let mut s = Vec3::zeros();
                    for slot in p.offsets[i] as usize..p.offsets[i + 1] as usize {
                        s += x[p.cols[slot] as usize] * values[slot];
                    }
                    y[i] = s;
                    d += w[i].dot(&x[i]);
                }
                for i in 0..n {
                    y[i] += w[i] * (5.0 * d);
                }
            };
            let b: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
                .collect();
            let filter = vec![Filter::Free; n];
            let precond = |r: &[Vec3]| {
                let mut z = vec![Vec3::zeros(); n];
                apply_factor(&chol, FactorSolve::Double, r, &filter, &mut z);
                z
            };
            let dotv = |a: &[Vec3], c: &[Vec3]| a.iter().zip(c).map(|(x, y)| x.dot(y)).sum::<f64>();
            for k in 1..4 {
                // Textbook PCG from zero, exactly k iterations.
                let mut x = vec![Vec3::zeros(); n];
                let mut r = b.clone();
                let mut z = precond(&r);
                let mut d = z.clone();
                let mut rz = dotv(&r, &z);
                for _ in 0..k {
                    let mut q = vec![Vec3::zeros(); n];
                    apply(&d, &mut q);
                    let alpha = rz / dotv(&d, &q);
                    for i in 0..n {
                        x[i] += d[i] * alpha;
                        r[i] -= q[i] * alpha;
                    }
                    z = precond(&r);
                    let rz_new = dotv(&r, &z);
                    for i in 0..n {
                        d[i] = z[i] + d[i] * (rz_new / rz);
                    }
                    rz = rz_new;
                }
                let mut got = vec![Vec3::zeros(); n];
                let settings = PcgSettings {
                    tolerance: 0.0,
                    absolute: 0.0,
                    max_iterations: k,
                };
                let res = solve_factored(
                    &apply,
                    &b,
                    &filter,
                    &vec![Vec3::zeros(); n],
                    &mut got,
                    settings,
                    &chol,
                    FactorSolve::Double,
                );
                assert_eq!(res.iterations, k);
                assert!(!res.converged);
                let scale = x.iter().map(|v| v.norm()).fold(0.0, f64::max);
                for i in 0..n {
                    assert!(
                        (got[i] - x[i]).norm() <= 1e-10 * scale,
                        "seed {seed} k {k} vertex {i}: {:?} vs {:?}",
                        got[i],
                        x[i]
                    );
                }
            }
        }
    }

    /// The off-diagonal pairs of a ring of `n` vertices with chords `i -> 7 i + 3 (mod n)`.
    fn ring_with_chords(n: usize) -> Vec<(u32, u32)> {
        (0..n as u32)
            .map(|i| (i, (i + 1) % n as u32))
            .chain((0..n as u32).map(|i| (i, (i * 7 + 3) % n as u32)))
            .filter(|(i, j)| i != j)
            .collect()
    }

    /// A random SPD block system on a ring-with-chords pattern.
    fn random_system(n: usize, seed: u64) -> (BsrPattern, BsrMatrix, Vec<Vec3>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let pairs = ring_with_chords(n);
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
        for seed in 0..12 {
            let n = 40 + seed as usize * 7;
            let (mut p, mut a, b) = random_system(n, seed);
            // Half the cases with contact-pair couplings outside the pattern, half with the
            // coarse-grid correction (ring aggregates of 6 nodes; one aggregate fully fixed).
            if seed % 4 >= 2 {
                let (p2, a2, _) = random_system(n, seed + 100);
                p = p2;
                a = a2;
                for c in 0..5u32 {
                    let v = Vec3::new(0.3, 1.0, c as f64 * 0.2).normalize();
                    let nodes = [c, c + 17, (c * 5 + 23) % n as u32, u32::MAX];
                    a.add_pair(&p, nodes, [1.0, -0.5, -0.5, 0.0], v * v.transpose() * 40.0);
                }
                a.finish_pairs(&p);
            }
            let ring: Vec<Vec<u32>> = (0..n as u32)
                .map(|i| vec![(i + n as u32 - 1) % n as u32, (i + 1) % n as u32])
                .collect();
            let agg = Aggregation::from_graph(n, |i| &ring[i], 6);
            assert_eq!(agg.count, n.div_ceil(6));

            let mut filter = vec![Filter::Free; n];
            let mut z = vec![Vec3::zeros(); n];
            if seed % 3 != 0 {
                filter[3] = Filter::Fixed;
                z[3] = Vec3::new(0.1, -0.2, 0.3);
                filter[10] = Filter::Normal(Vec3::new(0.0, 0.6, 0.8));
                z[10] = Vec3::new(0.0, 0.6, 0.8) * 0.5;
                for (i, f) in filter.iter_mut().enumerate().skip(24).take(6) {
                    *f = Filter::Fixed;
                    z[i] = Vec3::new(0.0, 0.01 * i as f64, 0.0);
                }
            }
            let coarse = if seed % 2 == 0 {
                let c = CoarseLevel::new(&agg, &p, &a, &filter);
                assert!(c.is_some());
                c
            } else {
                None
            };
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
                    absolute: 0.0,
                    max_iterations: 10_000,
                },
                Preconditioner::BlockJacobi(coarse.as_ref()),
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
                absolute: 0.0,
                max_iterations: 3,
            },
            Preconditioner::BlockJacobi(None),
        );
        assert_eq!(res.iterations, 3);
        assert!(!res.converged);
        assert!(res.relative_residual > 1e-14);
    }

    /// A random system (`random_system(30 + 5 seed, seed)`), constrained for odd seeds (vertex 2
    /// fixed, vertex 7 free only in a plane), with its exact solution (CG to 1e-13): the oracle
    /// of the Galerkin corrections below.
    struct CorrectionCase {
        n: usize,
        p: BsrPattern,
        a: BsrMatrix,
        b: Vec<Vec3>,
        filter: Vec<Filter>,
        exact: Vec<Vec3>,
    }

    impl CorrectionCase {
        fn new(seed: u64) -> Self {
            let n = 30 + 5 * seed as usize;
            let (p, a, b) = random_system(n, seed);
            let mut filter = vec![Filter::Free; n];
            if seed % 2 == 1 {
                filter[2] = Filter::Fixed;
                filter[7] = Filter::Normal(Vec3::new(0.6, 0.0, 0.8));
            }
            let z = vec![Vec3::zeros(); n];
            let mut exact = vec![Vec3::zeros(); n];
            let settings = PcgSettings {
                tolerance: 1e-13,
                absolute: 0.0,
                max_iterations: 10_000,
            };
            let pre = Preconditioner::BlockJacobi(None);
            assert!(solve(&p, &a, &b, &filter, &z, &mut exact, settings, pre).converged);
            CorrectionCase {
                n,
                p,
                a,
                b,
                filter,
                exact,
            }
        }

        /// `e^T A e` for the error `e = x - exact`.
        fn energy_error(&self, x: &[Vec3]) -> f64 {
            let e: Vec<Vec3> = (0..self.n).map(|i| x[i] - self.exact[i]).collect();
            let mut ae = vec![Vec3::zeros(); self.n];
            self.a.mul(&self.p, &e, &mut ae);
            dot(&e, &ae)
        }

        /// The filtered residual `S (b - A x)` and the sum of its norms (a scale for checks).
        fn filtered_residual(&self, x: &[Vec3]) -> (Vec<Vec3>, f64) {
            let mut ax = vec![Vec3::zeros(); self.n];
            self.a.mul(&self.p, x, &mut ax);
            let r: Vec<Vec3> = (0..self.n)
                .map(|i| self.filter[i].apply(self.b[i] - ax[i]))
                .collect();
            let scale = r.iter().map(|v| v.norm()).sum::<f64>() + 1e-300;
            (r, scale)
        }

        /// The constrained directions of `x` are those of the exact solution.
        fn assert_constraints_kept(&self, x: &[Vec3], seed: u64) {
            if seed % 2 == 1 {
                assert_eq!(x[2], self.exact[2], "seed {seed}");
                let nn = Vec3::new(0.6, 0.0, 0.8);
                assert!((nn.dot(&x[7]) - nn.dot(&self.exact[7])).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn translation_correction_is_a_galerkin_projection() {
        for seed in 0..6 {
            let c = CorrectionCase::new(seed);
            let (n, filter, exact) = (c.n, &c.filter, &c.exact);
            let mut rng = ChaCha8Rng::seed_from_u64(seed + 50);
            // An approximation whose error is a filtered translation plus noise.
            let shift = Vec3::new(0.3, -0.7, 0.2);
            let mut x: Vec<Vec3> = (0..n)
                .map(|i| {
                    let noise = Vec3::new(rng.random(), rng.random(), rng.random()) * 1e-3;
                    exact[i] + filter[i].apply(shift + noise)
                })
                .collect();
            let before = c.energy_error(&x);
            let t = correct_translations(&c.p, &c.a, &c.b, filter, &mut x);
            let after = c.energy_error(&x);
            assert!(
                after <= before * (1.0 + 1e-12),
                "seed {seed}: {after} > {before}"
            );
            assert!(after < 1e-3 * before, "seed {seed}: {after} vs {before}");
            assert!((t + shift).norm() < 0.01, "seed {seed}: {t}");
            // The filtered residual has no component along the filtered translations.
            let (r, scale) = c.filtered_residual(&x);
            for e in [Vec3::x(), Vec3::y(), Vec3::z()] {
                let u: Vec<Vec3> = filter.iter().map(|f| f.apply(e)).collect();
                assert!(dot(&u, &r).abs() < 1e-10 * scale, "seed {seed}");
            }
            // Constrained directions are untouched.
            c.assert_constraints_kept(&x, seed);
        }
    }

    /// Oracle: the exact solution (CG to 1e-13). An approximation whose error is a filtered
    /// rigid motion (translation plus rotation about a random point) plus noise: the correction
    /// removes nearly all of the error, never increases its energy norm, leaves a residual with
    /// no force and no torque, and keeps the constrained directions.
    #[test]
    fn rigid_motion_correction_is_a_galerkin_projection() {
        for seed in 0..6 {
            let c = CorrectionCase::new(seed);
            let (n, filter, exact) = (c.n, &c.filter, &c.exact);
            let mut rng = ChaCha8Rng::seed_from_u64(seed + 70);
            let pos: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0)
                .collect();
            let shift = Vec3::new(0.3, -0.7, 0.2);
            let spin = Vec3::new(-0.4, 0.9, 0.5);
            let centre = Vec3::new(0.5, 1.5, -0.3);
            let mut x: Vec<Vec3> = (0..n)
                .map(|i| {
                    let noise = Vec3::new(rng.random(), rng.random(), rng.random()) * 1e-3;
                    exact[i] + filter[i].apply(shift + spin.cross(&(pos[i] - centre)) + noise)
                })
                .collect();
            let before = c.energy_error(&x);
            let mut only_translations = x.clone();
            correct_translations(&c.p, &c.a, &c.b, filter, &mut only_translations);
            let coef = correct_rigid_motions(&c.p, &c.a, &c.b, filter, &pos, &mut x);
            assert!(coef.is_some(), "seed {seed}: six independent modes");
            let after = c.energy_error(&x);
            assert!(after <= before * (1.0 + 1e-12), "seed {seed}");
            assert!(after < 1e-3 * before, "seed {seed}: {after} vs {before}");
            // The translations alone cannot remove a rotation error.
            assert!(
                c.energy_error(&only_translations) > 10.0 * after,
                "seed {seed}"
            );
            let (r, scale) = c.filtered_residual(&x);
            let c0 = pos.iter().sum::<Vec3>() / n as f64;
            for e in [Vec3::x(), Vec3::y(), Vec3::z()] {
                let ut: Vec<Vec3> = filter.iter().map(|f| f.apply(e)).collect();
                assert!(dot(&ut, &r).abs() < 1e-9 * scale, "seed {seed}: force");
                let ur: Vec<Vec3> = (0..n)
                    .map(|i| filter[i].apply(e.cross(&(pos[i] - c0))))
                    .collect();
                assert!(
                    dot(&ur, &r).abs() < 1e-9 * scale * 4.0,
                    "seed {seed}: torque"
                );
            }
            c.assert_constraints_kept(&x, seed);
        }
    }

    /// Collinear free vertices have no rotation about their line: the six-mode system is
    /// singular and the correction falls back to the translations.
    #[test]
    fn rigid_motion_correction_falls_back_on_collinear_vertices() {
        let n = 12;
        let (p, a, b) = random_system(n, 3);
        let pos: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f64, 0.0, 0.0)).collect();
        let filter = vec![Filter::Free; n];
        let mut x = vec![Vec3::zeros(); n];
        let mut y = x.clone();
        let c = correct_rigid_motions(&p, &a, &b, &filter, &pos, &mut x).unwrap();
        let t = correct_translations(&p, &a, &b, &filter, &mut y);
        assert_eq!(&c[3..], &[0.0; 3]);
        assert!((Vec3::new(c[0], c[1], c[2]) - t).norm() <= 1e-12 * (1.0 + t.norm()));
    }
}
