//! Smoothed-aggregation algebraic multigrid (Vaněk, Mandel & Brezina 1996) on the 3x3-block
//! system of the implicit step, used as the preconditioner of [`crate::sim::pcg`].
//!
//! Why: after block-Jacobi scaling the smooth (nearly rigid, nearly isometric) modes of stiff
//! cloth have tiny eigenvalues (`h^2 k / m` is in the tens of thousands), so Jacobi-preconditioned
//! CG needs hundreds of iterations; one V-cycle removes the error at every scale and brings CG to
//! a few tens of iterations.
//!
//! Hierarchy: nodes are grouped into aggregates of a node and its neighbours (Vaněk's greedy
//! aggregation over the matrix graph); the tentative prolongator maps each aggregate's three
//! translations to its nodes (block identities, the near null space of the elastic forces); the
//! smoothed prolongator is `P = S (I - omega D^-1 A) P0` (`S` the constraint filter's projection
//! on the finest level, `D` the block diagonal, `omega = 4 / (3 rho(D^-1 A))`); the coarse matrix
//! is the Galerkin product `P^T A P`, again 3x3 blocks, coarsened recursively until a level is
//! small enough for a dense Cholesky factorisation.
//!
//! Cycle: a symmetric V(nu, nu)-cycle with damped block-Jacobi smoothing (`omega_s = 1.1 /
//! lambda`, `lambda` a power-iteration estimate of `rho(D^-1 A)` raised by 10%); with a
//! convergent smoother and any symmetric positive definite coarse matrices the cycle is a
//! symmetric positive definite operator, so the hierarchy may be built from an older matrix (or
//! an older constraint filter) and reused: only the finest level's block diagonal follows the
//! current matrix. The finest level always uses the current matrix (with the contact-pair
//! couplings outside the pattern) and the current filter, so the preconditioned operator is
//! `S M S`.
//!
//! Symbolic work (aggregates, patterns of `P`, `A P`, `P^T A P` and the scatter maps of the
//! numeric products) depends only on the sparsity pattern and is done once; a numeric rebuild
//! costs two sparse products per level. Everything is row-parallel with per-row sums in a fixed
//! order: bit-identical for any thread count.

use nalgebra::Matrix3;
use rayon::prelude::*;

use super::pcg::Filter;
use super::sparse::{dot, BsrMatrix, BsrPattern, CHUNK};
use crate::geom::Vec3;

/// Strength-of-connection threshold of the aggregation (Vaněk et al.'s `theta`).
const STRENGTH: f64 = 0.08;

/// Shape of the hierarchy and of the cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmgSettings {
    /// A level with at most this many nodes is solved by a dense Cholesky factorisation.
    pub coarsest: usize,
    /// Most levels (the last one is solved directly whatever its size).
    pub max_levels: usize,
    /// Smoothing sweeps before and after the coarse correction.
    pub sweeps: usize,
}

impl Default for AmgSettings {
    fn default() -> Self {
        AmgSettings {
            coarsest: 96,
            max_levels: 8,
            sweeps: 1,
        }
    }
}

/// Vaněk's greedy aggregation of a graph given by adjacency lists (deterministic, node order):
/// (1) every node whose neighbourhood is still free starts an aggregate with its whole
/// neighbourhood; (2) each remaining node joins the aggregate of its first aggregated
/// neighbour; (3) what is left forms aggregates with its free neighbours. Returns the aggregate
/// of each node and the number of aggregates.
pub fn aggregate(adjacency: &[Vec<u32>]) -> (Vec<u32>, usize) {
    let n = adjacency.len();
    let mut of = vec![u32::MAX; n];
    let mut count = 0u32;
    for i in 0..n {
        if of[i] == u32::MAX && adjacency[i].iter().all(|&j| of[j as usize] == u32::MAX) {
            for &j in &adjacency[i] {
                of[j as usize] = count;
            }
            of[i] = count;
            count += 1;
        }
    }
    let mut joined = of.clone();
    for i in 0..n {
        if of[i] == u32::MAX {
            if let Some(&j) = adjacency[i].iter().find(|&&j| of[j as usize] != u32::MAX) {
                joined[i] = of[j as usize];
            }
        }
    }
    let mut of = joined;
    for i in 0..n {
        if of[i] == u32::MAX {
            for &j in &adjacency[i] {
                if of[j as usize] == u32::MAX {
                    of[j as usize] = count;
                }
            }
            of[i] = count;
            count += 1;
        }
    }
    (of, count as usize)
}

/// What a node's three unknowns mean for the rigid motions (the near null space): a
/// translation at a point, or a rotation vector scaled by a length.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Translation(Vec3),
    Rotation(f64),
}

/// The tentative prolongator of one level: for each node, its blocks towards its aggregate's
/// translation and rotation nodes, such that every rigid motion of the coarse level
/// interpolates exactly to the rigid motion of this level; plus the next level's node kinds.
fn tentative(kind: &[Kind], agg: &[u32], aggregates: usize) -> (Vec<[Matrix3<f64>; 2]>, Vec<Kind>) {
    let mut centre = vec![Vec3::zeros(); aggregates];
    let mut count = vec![0usize; aggregates];
    for (k, &a) in kind.iter().zip(agg) {
        if let Kind::Translation(p) = k {
            centre[a as usize] += p;
            count[a as usize] += 1;
        }
    }
    for (c, &m) in centre.iter_mut().zip(&count) {
        if m > 0 {
            *c /= m as f64;
        }
    }
    let mut r2 = vec![0.0f64; aggregates];
    let mut members = vec![0usize; aggregates];
    for (k, &a) in kind.iter().zip(agg) {
        let a = a as usize;
        members[a] += 1;
        r2[a] += match k {
            Kind::Translation(p) => (p - centre[a]).norm_squared(),
            Kind::Rotation(r) => r * r,
        };
    }
    let radius: Vec<f64> = r2
        .iter()
        .zip(&members)
        .map(|(&s, &m)| {
            let r = (s / m.max(1) as f64).sqrt();
            if r > 0.0 && r.is_finite() {
                r
            } else {
                1.0
            }
        })
        .collect();
    let p0 = kind
        .iter()
        .zip(agg)
        .map(|(k, &a)| {
            let a = a as usize;
            match k {
                Kind::Translation(p) => {
                    let d = (p - centre[a]) / radius[a];
                    [Matrix3::identity(), -d.cross_matrix()]
                }
                Kind::Rotation(r) => [Matrix3::zeros(), Matrix3::identity() * (r / radius[a])],
            }
        })
        .collect();
    let next = (0..aggregates)
        .flat_map(|a| [Kind::Translation(centre[a]), Kind::Rotation(radius[a])])
        .collect();
    (p0, next)
}

/// Pattern-only data of one level's transfer and Galerkin product.
#[derive(Clone, Debug)]
struct Symbolic {
    /// Prolongator pattern: block rows = fine nodes, columns = aggregates (sorted per row).
    p_offsets: Vec<u32>,
    p_cols: Vec<u32>,
    /// For each fine slot `s` (row `i`, column `j`), the P slot of row `i` holding column
    /// `agg(j)`.
    p_of_fine_slot: Vec<u32>,
    /// Per aggregate, the P slots of its column (transpose, in row order): `(row, slot)`.
    pt_offsets: Vec<u32>,
    pt_entries: Vec<(u32, u32)>,
    /// Pattern of `A P` (fine rows x aggregates) and, in the order `(fine slot s, P slot t of
    /// row cols[s])`, the `A P` slot each product goes to.
    ap_offsets: Vec<u32>,
    ap_dest: Vec<u32>,
    /// Start of each fine row's products in `ap_dest`.
    ap_row_start: Vec<u32>,
    /// Coarse pattern and, in the order `(P^T entry (i, slot), A P slot u of row i)`, the coarse
    /// slot each product goes to.
    coarse: BsrPattern,
    ac_dest: Vec<u32>,
    /// Start of each coarse row's products in `ac_dest`.
    ac_row_start: Vec<u32>,
}

/// `agg[i]` = aggregate of node `i`; aggregate `a` has the two coarse nodes `2a` (its
/// translation) and `2a + 1` (its rotation).
fn symbolic(pattern: &BsrPattern, agg: &[u32], aggregates: usize) -> Symbolic {
    let n = pattern.rows();
    let count = 2 * aggregates;
    let row = |i: usize| pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize;
    // P pattern: aggregates of the row's neighbours (the smoothing spreads one ring).
    let mut p_offsets = vec![0u32; n + 1];
    let mut p_cols = Vec::new();
    let mut p_of_fine_slot = vec![0u32; pattern.nnz()];
    for i in 0..n {
        let start = p_cols.len();
        let mut cs: Vec<u32> = row(i)
            .flat_map(|s| {
                let a = agg[pattern.cols[s] as usize];
                [2 * a, 2 * a + 1]
            })
            .collect();
        cs.sort_unstable();
        cs.dedup();
        p_cols.extend(&cs);
        for s in row(i) {
            let a = 2 * agg[pattern.cols[s] as usize];
            p_of_fine_slot[s] = (start + cs.binary_search(&a).expect("present")) as u32;
        }
        p_offsets[i + 1] = p_cols.len() as u32;
    }
    // Transpose.
    let mut pt_offsets = vec![0u32; count + 1];
    for &c in &p_cols {
        pt_offsets[c as usize + 1] += 1;
    }
    for a in 0..count {
        pt_offsets[a + 1] += pt_offsets[a];
    }
    let mut fill = pt_offsets.clone();
    let mut pt_entries = vec![(0u32, 0u32); p_cols.len()];
    for i in 0..n {
        for t in p_offsets[i] as usize..p_offsets[i + 1] as usize {
            let a = p_cols[t] as usize;
            pt_entries[fill[a] as usize] = (i as u32, t as u32);
            fill[a] += 1;
        }
    }
    // A P.
    let mut ap_offsets = vec![0u32; n + 1];
    let mut ap_cols: Vec<u32> = Vec::new();
    let mut ap_dest = Vec::new();
    let mut ap_row_start = vec![0u32; n];
    for i in 0..n {
        ap_row_start[i] = ap_dest.len() as u32;
        let start = ap_cols.len();
        let mut cs: Vec<u32> = Vec::new();
        for s in row(i) {
            let j = pattern.cols[s] as usize;
            cs.extend(&p_cols[p_offsets[j] as usize..p_offsets[j + 1] as usize]);
        }
        cs.sort_unstable();
        cs.dedup();
        ap_cols.extend(&cs);
        for s in row(i) {
            let j = pattern.cols[s] as usize;
            for t in p_offsets[j] as usize..p_offsets[j + 1] as usize {
                ap_dest.push((start + cs.binary_search(&p_cols[t]).expect("present")) as u32);
            }
        }
        ap_offsets[i + 1] = ap_cols.len() as u32;
    }
    // P^T A P: coarse row a gathers the A P rows of the fine rows in its P column.
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for a in 0..count {
        for &(i, _) in &pt_entries[pt_offsets[a] as usize..pt_offsets[a + 1] as usize] {
            let i = i as usize;
            for &b in &ap_cols[ap_offsets[i] as usize..ap_offsets[i + 1] as usize] {
                if (a as u32) < b {
                    pairs.push((a as u32, b));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    let coarse = BsrPattern::from_pairs(count, pairs);
    let mut ac_dest = Vec::new();
    let mut ac_row_start = vec![0u32; count];
    for a in 0..count {
        ac_row_start[a] = ac_dest.len() as u32;
        for &(i, _) in &pt_entries[pt_offsets[a] as usize..pt_offsets[a + 1] as usize] {
            let i = i as usize;
            for &b in &ap_cols[ap_offsets[i] as usize..ap_offsets[i + 1] as usize] {
                ac_dest.push(coarse.slot(a as u32, b).expect("in coarse pattern") as u32);
            }
        }
    }
    Symbolic {
        p_offsets,
        p_cols,
        p_of_fine_slot,
        pt_offsets,
        pt_entries,
        ap_offsets,
        ap_dest,
        ap_row_start,
        coarse,
        ac_dest,
        ac_row_start,
    }
}

/// One level below the finest: its operator, smoother and the transfer from the level above.
#[derive(Clone, Debug)]
struct Level {
    sym: Symbolic,
    /// Aggregate of each node of the level above, and the number of aggregates.
    agg: Vec<u32>,
    aggregates: usize,
    /// Prolongator values from this level's coarse space to the level above (per P slot).
    p: Vec<Matrix3<f64>>,
    /// The Galerkin matrix of this level (over `sym.coarse`).
    values: Vec<Matrix3<f64>>,
    /// Inverse diagonal blocks and damping of the Jacobi smoother (unused on the last level).
    dinv: Vec<Matrix3<f64>>,
    omega: f64,
}

/// The multigrid hierarchy (see the module documentation). Build with [`Amg::build`], then
/// precondition solves with [`Amg::preconditioner`]; rebuild when the matrix has drifted.
#[derive(Clone, Debug, Default)]
pub struct Amg {
    settings: Option<AmgSettings>,
    /// Finest pattern the symbolic data belongs to: (rows, nnz).
    shape: (usize, usize),
    levels: Vec<Level>,
    /// Dense Cholesky factor of the last level (lower triangle, row-major `m x m`).
    chol: Option<nalgebra::linalg::Cholesky<f64, nalgebra::Dyn>>,
    /// Damping of the finest level's smoother (estimated at build).
    fine_omega: f64,
}

/// Inverse of a symmetric positive (semi)definite 3x3 block, regularised by a tiny multiple of
/// its trace so that directions without unknowns (filtered coarse translations) stay finite.
fn block_inverse(d: &Matrix3<f64>) -> Matrix3<f64> {
    let tr = d.trace().abs().max(1e-300);
    let m = (d + d.transpose()) * 0.5 + Matrix3::identity() * (1e-12 * tr);
    m.cholesky()
        .map(|c| c.inverse())
        .filter(|m| m.iter().all(|v| v.is_finite()))
        .unwrap_or_else(|| {
            let s = m.diagonal().map(|v| if v > 1e-300 { 1.0 / v } else { 0.0 });
            Matrix3::from_diagonal(&s)
        })
}

fn projection(f: &Filter) -> Matrix3<f64> {
    match f {
        Filter::Free => Matrix3::identity(),
        Filter::Fixed => Matrix3::zeros(),
        Filter::Normal(n) => Matrix3::identity() - n * n.transpose(),
    }
}

fn bsr_mul(pattern: &BsrPattern, values: &[Matrix3<f64>], x: &[Vec3], y: &mut [Vec3]) {
    y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
        for (k, yi) in ys.iter_mut().enumerate() {
            let i = c * CHUNK + k;
            let (s, e) = (pattern.offsets[i] as usize, pattern.offsets[i + 1] as usize);
            let mut acc = Vec3::zeros();
            for (m, &j) in values[s..e].iter().zip(&pattern.cols[s..e]) {
                acc += m * x[j as usize];
            }
            *yi = acc;
        }
    });
}

/// A deterministic start vector for power iterations.
fn start_vector(n: usize) -> Vec<Vec3> {
    (0..n)
        .map(|i| {
            let h = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let f = |s: u32| ((h >> s) & 0xffff) as f64 / 65535.0 - 0.5;
            Vec3::new(1.0 + f(0), 1.0 + f(16), 1.0 + f(32))
        })
        .collect()
}

/// Estimate of the largest eigenvalue of `D^-1 A` (`A` symmetric positive definite, `D` its
/// block diagonal): power iteration on `D^-1 A` with the generalised Rayleigh quotient
/// `x^T A x / x^T D x` (a lower bound), raised by 10%.
fn spectral_radius(
    n: usize,
    apply_a: &dyn Fn(&[Vec3], &mut [Vec3]),
    dinv: &[Matrix3<f64>],
    iters: usize,
) -> f64 {
    let mut x = start_vector(n);
    let mut y = vec![Vec3::zeros(); n];
    // D x is known after the first step (x = z / |z| with D z = A x_prev).
    let mut dx: Option<Vec<Vec3>> = None;
    let mut lambda = 0.0f64;
    for _ in 0..iters {
        apply_a(&x, &mut y);
        if let Some(dx) = &dx {
            let (xax, xdx) = (dot(&x, &y), dot(&x, dx));
            if xdx > 0.0 && xax.is_finite() {
                lambda = lambda.max(xax / xdx);
            }
        }
        let z: Vec<Vec3> = (0..n).map(|i| dinv[i] * y[i]).collect();
        let norm = dot(&z, &z).sqrt();
        if norm <= 0.0 || !norm.is_finite() {
            break;
        }
        // |D^-1 A x| for a unit x also approaches the largest eigenvalue (from either side);
        // the larger of the two estimates is the safer one for a smoother.
        if dx.is_some() {
            lambda = lambda.max(norm);
        }
        x = z.iter().map(|v| v / norm).collect();
        dx = Some(y.iter().map(|v| v / norm).collect());
    }
    1.1 * lambda
}

impl Amg {
    /// An empty hierarchy (build it before use).
    pub fn new(settings: AmgSettings) -> Amg {
        Amg {
            settings: Some(settings),
            ..Default::default()
        }
    }

    /// Whether [`Amg::build`] has run for a pattern of this shape.
    pub fn is_built_for(&self, pattern: &BsrPattern) -> bool {
        self.chol.is_some() && self.shape == (pattern.rows(), pattern.nnz())
    }

    /// Number of levels including the finest.
    pub fn levels(&self) -> usize {
        self.levels.len() + 1
    }

    /// Nodes per level, finest first.
    pub fn level_sizes(&self, fine: usize) -> Vec<usize> {
        std::iter::once(fine)
            .chain(self.levels.iter().map(|l| l.sym.coarse.rows()))
            .collect()
    }

    /// Builds (or rebuilds numerically) the hierarchy for the matrix `a` under `filter`. The
    /// contact-pair couplings outside the pattern enter the finest smoother and residuals, not
    /// the coarse matrices (any SPD coarse matrix keeps the preconditioner SPD). Returns `false`
    /// (and leaves no hierarchy) if a level cannot be factorised.
    pub fn build(
        &mut self,
        pattern: &BsrPattern,
        a: &BsrMatrix,
        filter: &[Filter],
        positions: &[Vec3],
    ) -> bool {
        let settings = self.settings.unwrap_or_default();
        self.settings = Some(settings);
        let n = pattern.rows();
        let shape = (n, pattern.nnz());
        let reuse = self.shape == shape && !self.levels.is_empty();
        if !reuse {
            self.levels.clear();
        }
        self.shape = shape;
        self.chol = None;
        // The filtered finest matrix S A S + (I - S) on the pattern.
        let proj: Vec<Matrix3<f64>> = filter.iter().map(projection).collect();
        let fine: Vec<Matrix3<f64>> = (0..n)
            .into_par_iter()
            .with_min_len(CHUNK)
            .flat_map_iter(|i| {
                let (s, e) = (pattern.offsets[i] as usize, pattern.offsets[i + 1] as usize);
                let pr = &proj;
                (s..e).map(move |slot| {
                    let j = pattern.cols[slot] as usize;
                    let mut m = pr[i] * a.values[slot] * pr[j];
                    if i == j {
                        m += Matrix3::identity() - pr[i];
                    }
                    m
                })
            })
            .collect();
        let fine_dinv: Vec<Matrix3<f64>> = (0..n)
            .map(|i| block_inverse(&fine[pattern.diag[i] as usize]))
            .collect();
        // Finest smoother damping from the true operator (with the pair couplings).
        let apply_fine = |x: &[Vec3], y: &mut [Vec3]| {
            a.mul(pattern, x, y);
            for i in 0..n {
                y[i] = proj[i] * y[i] + (x[i] - proj[i] * x[i]);
            }
        };
        let lam_fine = spectral_radius(n, &apply_fine, &fine_dinv, 12);
        self.fine_omega = if lam_fine > 0.0 { 1.1 / lam_fine } else { 0.5 };
        let mut cur_pattern = pattern.clone();
        let mut cur_values = fine;
        let mut cur_dinv = fine_dinv;
        let mut cur_proj = Some(proj);
        let mut cur_kind: Vec<Kind> = positions.iter().map(|&p| Kind::Translation(p)).collect();
        let mut lvl = 0;
        loop {
            let m = cur_pattern.rows();
            if m <= settings.coarsest || lvl + 1 >= settings.max_levels {
                break;
            }
            if !(reuse && lvl < self.levels.len()) {
                // Aggregation over super-nodes (a coarse level's translation and rotation nodes
                // stay together); on the finest level over the strong couplings
                // |A_ij| >= theta sqrt(|A_ii| |A_jj|) (Frobenius norms).
                let supers = if lvl == 0 { m } else { m / 2 };
                let sup = |i: usize| if lvl == 0 { i } else { i / 2 };
                let diag_norm: Vec<f64> = (0..m)
                    .map(|i| cur_values[cur_pattern.diag[i] as usize].norm())
                    .collect();
                let mut adjacency = vec![Vec::new(); supers];
                for i in 0..m {
                    for s in cur_pattern.offsets[i] as usize..cur_pattern.offsets[i + 1] as usize {
                        let j = cur_pattern.cols[s] as usize;
                        let strong = lvl > 0
                            || cur_values[s].norm()
                                >= STRENGTH * (diag_norm[i] * diag_norm[j]).sqrt();
                        if strong && sup(i) != sup(j) {
                            adjacency[sup(i)].push(sup(j) as u32);
                        }
                    }
                }
                for l in adjacency.iter_mut() {
                    l.sort_unstable();
                    l.dedup();
                }
                let (agg_super, count) = aggregate(&adjacency);
                if 2 * count >= m || count == 0 {
                    break;
                }
                let agg: Vec<u32> = (0..m).map(|i| agg_super[sup(i)]).collect();
                let sym = symbolic(&cur_pattern, &agg, count);
                self.levels.truncate(lvl);
                self.levels.push(Level {
                    sym,
                    agg,
                    aggregates: count,
                    p: Vec::new(),
                    values: Vec::new(),
                    dinv: Vec::new(),
                    omega: 0.0,
                });
            }
            let (p0, next_kind) = tentative(
                &cur_kind,
                &self.levels[lvl].agg,
                self.levels[lvl].aggregates,
            );
            // P smoothing with omega = 4 / (3 rho(D^-1 A)) on this level's (filtered) matrix.
            let lam = {
                let (pt, vs) = (&cur_pattern, &cur_values);
                let apply = |x: &[Vec3], y: &mut [Vec3]| bsr_mul(pt, vs, x, y);
                spectral_radius(m, &apply, &cur_dinv, 10)
            };
            let omega_p = if lam > 0.0 { 4.0 / (3.0 * lam) } else { 0.0 };
            let level = &mut self.levels[lvl];
            let sym = &level.sym;
            let p: Vec<Matrix3<f64>> = {
                // Row-local: P_i = I at agg(i) - omega D_i^-1 A_ij for each j, then filtered.
                let cp = &cur_pattern;
                let cv = &cur_values;
                let cd = &cur_dinv;
                let proj = cur_proj.as_deref();
                let off = &sym.p_offsets;
                let pos = &sym.p_of_fine_slot;
                let rows: Vec<Vec<Matrix3<f64>>> = (0..m)
                    .into_par_iter()
                    .with_min_len(256)
                    .map(|i| {
                        let ps = off[i] as usize;
                        let mut r = vec![Matrix3::zeros(); off[i + 1] as usize - ps];
                        // P_i = P0_i - omega D_i^-1 sum_j A_ij P0_j; P0_j's two blocks go to the
                        // translation and rotation nodes of agg(j) (adjacent columns).
                        for s in cp.offsets[i] as usize..cp.offsets[i + 1] as usize {
                            let j = cp.cols[s] as usize;
                            let da = cd[i] * cv[s] * omega_p;
                            let at = pos[s] as usize - ps;
                            r[at] -= da * p0[j][0];
                            r[at + 1] -= da * p0[j][1];
                        }
                        let own = pos[cp.diag[i] as usize] as usize - ps;
                        r[own] += p0[i][0];
                        r[own + 1] += p0[i][1];
                        if let Some(pr) = proj {
                            for b in r.iter_mut() {
                                *b = pr[i] * *b;
                            }
                        }
                        r
                    })
                    .collect();
                rows.concat()
            };
            // A P, row-parallel, products in the fixed symbolic order.
            let ap: Vec<Matrix3<f64>> = {
                let cp = &cur_pattern;
                let cv = &cur_values;
                let p = &p;
                let rows: Vec<Vec<Matrix3<f64>>> = (0..m)
                    .into_par_iter()
                    .with_min_len(256)
                    .map(|i| {
                        let base = sym.ap_offsets[i] as usize;
                        let mut r = vec![Matrix3::zeros(); sym.ap_offsets[i + 1] as usize - base];
                        let mut k = sym.ap_row_start[i] as usize;
                        for s in cp.offsets[i] as usize..cp.offsets[i + 1] as usize {
                            let j = cp.cols[s] as usize;
                            for t in sym.p_offsets[j] as usize..sym.p_offsets[j + 1] as usize {
                                r[sym.ap_dest[k] as usize - base] += cv[s] * p[t];
                                k += 1;
                            }
                        }
                        r
                    })
                    .collect();
                rows.concat()
            };
            // P^T (A P).
            let nc = sym.coarse.rows();
            let mut ac: Vec<Matrix3<f64>> = {
                let p = &p;
                let ap = &ap;
                let rows: Vec<Vec<Matrix3<f64>>> = (0..nc)
                    .into_par_iter()
                    .with_min_len(64)
                    .map(|a_| {
                        let base = sym.coarse.offsets[a_] as usize;
                        let mut r =
                            vec![Matrix3::zeros(); sym.coarse.offsets[a_ + 1] as usize - base];
                        let mut k = sym.ac_row_start[a_] as usize;
                        for &(i, t) in &sym.pt_entries
                            [sym.pt_offsets[a_] as usize..sym.pt_offsets[a_ + 1] as usize]
                        {
                            let i = i as usize;
                            let pt = p[t as usize].transpose();
                            for u in sym.ap_offsets[i] as usize..sym.ap_offsets[i + 1] as usize {
                                r[sym.ac_dest[k] as usize - base] += pt * ap[u];
                                k += 1;
                            }
                        }
                        r
                    })
                    .collect();
                rows.concat()
            };
            // Symmetrise (rounding) and regularise empty directions.
            let cpat = sym.coarse.clone();
            // Directions without unknowns (aggregates of constrained nodes) get a tiny
            // decoupled diagonal, relative to the level's scale.
            let top = (0..nc).fold(0.0f64, |t, a_| t.max(ac[cpat.diag[a_] as usize].trace()));
            let delta = 1e-12 * top.max(f64::MIN_POSITIVE);
            for a_ in 0..nc {
                let d = cpat.diag[a_] as usize;
                ac[d] = (ac[d] + ac[d].transpose()) * 0.5 + Matrix3::identity() * delta;
            }
            let dinv: Vec<Matrix3<f64>> = (0..nc)
                .map(|a_| block_inverse(&ac[cpat.diag[a_] as usize]))
                .collect();
            level.p = p;
            level.values = ac.clone();
            level.dinv = dinv.clone();
            cur_pattern = cpat;
            cur_values = ac;
            cur_dinv = dinv;
            cur_proj = None;
            cur_kind = next_kind;
            lvl += 1;
        }
        self.levels.truncate(lvl);
        // Smoother damping of each coarse level (not needed on the last).
        for l in 0..self.levels.len().saturating_sub(1) {
            let level = &self.levels[l];
            let lam = {
                let (pt, vs) = (&level.sym.coarse, &level.values);
                let apply = |x: &[Vec3], y: &mut [Vec3]| bsr_mul(pt, vs, x, y);
                spectral_radius(pt.rows(), &apply, &level.dinv, 10)
            };
            self.levels[l].omega = if lam > 0.0 { 1.1 / lam } else { 0.5 };
        }
        // Dense factorisation of the last level.
        let m = cur_pattern.rows();
        let mut d = nalgebra::DMatrix::<f64>::zeros(3 * m, 3 * m);
        for i in 0..m {
            for slot in cur_pattern.offsets[i] as usize..cur_pattern.offsets[i + 1] as usize {
                let j = cur_pattern.cols[slot] as usize;
                d.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                    .copy_from(&cur_values[slot]);
            }
        }
        let d = (&d + d.transpose()) * 0.5;
        let top = (0..3 * m).fold(0.0f64, |t, k| t.max(d[(k, k)]));
        let mut d = d;
        for k in 0..3 * m {
            d[(k, k)] += 1e-12 * top.max(f64::MIN_POSITIVE);
        }
        self.chol = d.cholesky();
        self.chol.is_some()
    }

    /// The preconditioner for a solve with matrix `a` under `filter` (the hierarchy may come
    /// from an earlier matrix or filter). `None` if the hierarchy is not built for this pattern.
    pub fn preconditioner<'a>(
        &'a self,
        pattern: &'a BsrPattern,
        a: &'a BsrMatrix,
        filter: &'a [Filter],
    ) -> Option<AmgPreconditioner<'a>> {
        if !self.is_built_for(pattern) {
            return None;
        }
        let n = pattern.rows();
        let proj: Vec<Matrix3<f64>> = filter.iter().map(projection).collect();
        let dinv: Vec<Matrix3<f64>> = (0..n)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|i| {
                let p = proj[i];
                let d = p * a.values[pattern.diag[i] as usize] * p + (Matrix3::identity() - p);
                block_inverse(&d)
            })
            .collect();
        Some(AmgPreconditioner {
            amg: self,
            pattern,
            a,
            filter,
            dinv,
        })
    }
}

/// One V-cycle of an [`Amg`] hierarchy against the current matrix and filter.
pub struct AmgPreconditioner<'a> {
    amg: &'a Amg,
    pattern: &'a BsrPattern,
    a: &'a BsrMatrix,
    filter: &'a [Filter],
    /// Inverse filtered diagonal blocks of the current matrix.
    dinv: Vec<Matrix3<f64>>,
}

impl AmgPreconditioner<'_> {
    /// `out = S M^-1 S r` (one V-cycle from a zero guess), returning `r . out`.
    pub fn apply(&self, r: &[Vec3], out: &mut [Vec3]) -> f64 {
        let n = r.len();
        let f = self.filter;
        let rf: Vec<Vec3> = (0..n).map(|i| f[i].apply(r[i])).collect();
        let sweeps = self.amg.settings.unwrap_or_default().sweeps.max(1);
        let omega = self.amg.fine_omega;
        let apply_fine = |x: &[Vec3], y: &mut [Vec3]| {
            self.a.mul(self.pattern, x, y);
            y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
                for (k, yi) in ys.iter_mut().enumerate() {
                    *yi = f[c * CHUNK + k].apply(*yi);
                }
            });
        };
        // Vectors stay in the range of S, where S A S + (I - S) acts as S A.
        v_cycle(
            &rf,
            out,
            &apply_fine,
            &self.dinv,
            omega,
            sweeps,
            Some(f),
            &self.amg.levels,
            self.amg.chol.as_ref().expect("built"),
        );
        dot(&rf, out)
    }
}

/// Damped Jacobi `x += omega D^-1 (r - A x)` (with `ax = A x` given), filtered.
fn jacobi(
    x: &mut [Vec3],
    r: &[Vec3],
    ax: Option<&[Vec3]>,
    dinv: &[Matrix3<f64>],
    omega: f64,
    filter: Option<&[Filter]>,
) {
    x.par_chunks_mut(CHUNK).enumerate().for_each(|(c, xs)| {
        for (k, xi) in xs.iter_mut().enumerate() {
            let i = c * CHUNK + k;
            let res = match ax {
                Some(ax) => r[i] - ax[i],
                None => r[i],
            };
            let d = dinv[i] * res * omega;
            *xi += match filter {
                Some(f) => f[i].apply(d),
                None => d,
            };
        }
    });
}

#[allow(clippy::too_many_arguments)]
fn v_cycle(
    r: &[Vec3],
    x: &mut [Vec3],
    apply: &dyn Fn(&[Vec3], &mut [Vec3]),
    dinv: &[Matrix3<f64>],
    omega: f64,
    sweeps: usize,
    filter: Option<&[Filter]>,
    below: &[Level],
    chol: &nalgebra::linalg::Cholesky<f64, nalgebra::Dyn>,
) {
    let n = r.len();
    if below.is_empty() {
        // Last level: dense solve.
        let mut rc =
            nalgebra::DVector::<f64>::from_iterator(3 * n, r.iter().flat_map(|v| [v.x, v.y, v.z]));
        chol.solve_mut(&mut rc);
        for i in 0..n {
            x[i] = Vec3::new(rc[3 * i], rc[3 * i + 1], rc[3 * i + 2]);
        }
        return;
    }
    let level = &below[0];
    let sym = &level.sym;
    x.iter_mut().for_each(|v| *v = Vec3::zeros());
    let mut ax = vec![Vec3::zeros(); n];
    // Pre-smoothing (the first sweep from zero needs no product).
    jacobi(x, r, None, dinv, omega, filter);
    for _ in 1..sweeps {
        apply(x, &mut ax);
        jacobi(x, r, Some(&ax), dinv, omega, filter);
    }
    // Restrict the residual.
    apply(x, &mut ax);
    let res: Vec<Vec3> = (0..n).map(|i| r[i] - ax[i]).collect();
    let nc = sym.coarse.rows();
    let rc: Vec<Vec3> = (0..nc)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|a_| {
            let mut acc = Vec3::zeros();
            for &(i, t) in
                &sym.pt_entries[sym.pt_offsets[a_] as usize..sym.pt_offsets[a_ + 1] as usize]
            {
                acc += level.p[t as usize].tr_mul(&res[i as usize]);
            }
            acc
        })
        .collect();
    let mut ec = vec![Vec3::zeros(); nc];
    let apply_c = |xx: &[Vec3], yy: &mut [Vec3]| bsr_mul(&sym.coarse, &level.values, xx, yy);
    v_cycle(
        &rc,
        &mut ec,
        &apply_c,
        &level.dinv,
        level.omega,
        sweeps,
        None,
        &below[1..],
        chol,
    );
    // Prolongate (P rows are filtered already; the filter may have changed since the build).
    x.par_chunks_mut(CHUNK).enumerate().for_each(|(c, xs)| {
        for (k, xi) in xs.iter_mut().enumerate() {
            let i = c * CHUNK + k;
            let mut acc = Vec3::zeros();
            for t in sym.p_offsets[i] as usize..sym.p_offsets[i + 1] as usize {
                acc += level.p[t] * ec[sym.p_cols[t] as usize];
            }
            *xi += match filter {
                Some(f) => f[i].apply(acc),
                None => acc,
            };
        }
    });
    // Post-smoothing.
    for _ in 0..sweeps {
        apply(x, &mut ax);
        jacobi(x, r, Some(&ax), dinv, omega, filter);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::pcg::{solve, PcgSettings, Preconditioner};
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A stiff spring-and-mass system on an `nx x ny` grid with diagonals (like cloth: springs
    /// `k` along random-ish directions in the plane, small masses), SPD.
    fn grid_system(nx: usize, ny: usize, k: f64, mass: f64, seed: u64) -> (BsrPattern, BsrMatrix) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let id = |x: usize, y: usize| (y * nx + x) as u32;
        let mut pairs = Vec::new();
        for y in 0..ny {
            for x in 0..nx {
                if x + 1 < nx {
                    pairs.push((id(x, y), id(x + 1, y)));
                }
                if y + 1 < ny {
                    pairs.push((id(x, y), id(x, y + 1)));
                }
                if x + 1 < nx && y + 1 < ny {
                    pairs.push((id(x, y), id(x + 1, y + 1)));
                }
            }
        }
        let n = nx * ny;
        let p = BsrPattern::from_pairs(n, pairs.iter().copied());
        let mut a = BsrMatrix::zeros(&p);
        for &(i, j) in &pairs {
            let (xi, yi) = ((i as usize % nx) as f64, (i as usize / nx) as f64);
            let (xj, yj) = ((j as usize % nx) as f64, (j as usize / nx) as f64);
            let d = Vec3::new(xj - xi, yj - yi, rng.random_range(-0.05..0.05)).normalize();
            let blk = d * d.transpose() * k + Matrix3::identity() * (1e-3 * k);
            for (r, c, s) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                a.values[p.slot(r, c).unwrap()] += blk * s;
            }
        }
        for i in 0..n {
            a.values[p.diag[i] as usize] += Matrix3::identity() * mass;
        }
        a.finish_pairs(&p);
        (p, a)
    }

    fn dense_of(apply: &dyn Fn(&[Vec3], &mut [Vec3]), n: usize) -> nalgebra::DMatrix<f64> {
        let mut m = nalgebra::DMatrix::zeros(3 * n, 3 * n);
        let mut e = vec![Vec3::zeros(); n];
        let mut y = vec![Vec3::zeros(); n];
        for c in 0..3 * n {
            e.iter_mut().for_each(|v| *v = Vec3::zeros());
            e[c / 3][c % 3] = 1.0;
            apply(&e, &mut y);
            for r in 0..3 * n {
                m[(r, c)] = y[r / 3][r % 3];
            }
        }
        m
    }

    /// Fixed and normal-constrained nodes at seeded places.
    fn random_filter(n: usize, seed: u64) -> Vec<Filter> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| match rng.random_range(0..10) {
                0 => Filter::Fixed,
                1 => Filter::Normal(
                    Vec3::new(
                        rng.random::<f64>(),
                        rng.random::<f64>(),
                        rng.random::<f64>() + 0.1,
                    )
                    .normalize(),
                ),
                _ => Filter::Free,
            })
            .collect()
    }

    fn positions(nx: usize, ny: usize) -> Vec<Vec3> {
        (0..nx * ny)
            .map(|i| {
                let (x, y) = ((i % nx) as f64, (i / nx) as f64);
                // A curved sheet (rotation modes are not trivial).
                Vec3::new(x, y, 0.1 * (x * x + y * y))
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]
        /// The preconditioner action `r -> S M^-1 S r` is symmetric, and positive definite on
        /// the free subspace, on random SPD block systems with random constraints; also when
        /// the hierarchy was built for a different matrix and filter (reuse across steps).
        #[test]
        fn preconditioner_is_symmetric_positive_definite(
            nx in 5usize..11,
            ny in 5usize..11,
            k in 10.0f64..1e5,
            seed in 0u64..1000,
            reuse in proptest::bool::ANY,
        ) {
            let (p, a) = grid_system(nx, ny, k, 1.0, seed);
            let n = p.rows();
            let filter = random_filter(n, seed + 1);
            let mut amg = Amg::new(AmgSettings { coarsest: 4, ..Default::default() });
            if reuse {
                let (_, old) = grid_system(nx, ny, k * 0.5, 2.0, seed + 7);
                prop_assert!(amg.build(&p, &old, &random_filter(n, seed + 2), &positions(nx, ny)));
            } else {
                prop_assert!(amg.build(&p, &a, &filter, &positions(nx, ny)));
            }
            prop_assert!(amg.levels() >= 2);
            let pre = amg.preconditioner(&p, &a, &filter).unwrap();
            let m = dense_of(&|r, o| { pre.apply(r, o); }, n);
            let scale = m.amax();
            prop_assert!(scale > 0.0);
            // Symmetric up to rounding (amplified by nearly singular coarse directions, which
            // the regularisation keeps at a condition number of ~1e12).
            prop_assert!((&m - m.transpose()).amax() <= 1e-6 * scale);
            // Positive definite on the free subspace: S M S + (I - S) has a Cholesky factor.
            let mut sd = nalgebra::DMatrix::<f64>::zeros(3 * n, 3 * n);
            for i in 0..n {
                sd.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&projection(&filter[i]));
            }
            let id = nalgebra::DMatrix::<f64>::identity(3 * n, 3 * n);
            let reduced = &sd * &m * &sd / scale + (&id - &sd);
            let eig = nalgebra::SymmetricEigen::new((&reduced + reduced.transpose()) * 0.5);
            prop_assert!(eig.eigenvalues.min() > 0.0, "min eigenvalue {}", eig.eigenvalues.min());
        }
    }

    /// CG with the multigrid preconditioner solves the filtered system (oracle: a tight
    /// block-Jacobi solve, itself checked against a dense solve in `pcg`), in far fewer
    /// iterations on a stiff system.
    #[test]
    fn multigrid_cg_matches_and_needs_fewer_iterations() {
        for seed in 0..3 {
            let (nx, ny) = (40, 30);
            let (p, a) = grid_system(nx, ny, 1e4, 1.0, seed);
            let n = p.rows();
            let mut filter = vec![Filter::Free; n];
            filter[0] = Filter::Fixed;
            filter[nx - 1] = Filter::Fixed;
            filter[n / 2] = Filter::Normal(Vec3::new(0.0, 0.6, 0.8));
            let mut z = vec![Vec3::zeros(); n];
            z[0] = Vec3::new(0.1, 0.0, -0.2);
            let b: Vec<Vec3> = (0..n)
                .map(|i| Vec3::new(1.0, (i % 7) as f64 - 3.0, -1.0))
                .collect();
            let mut amg = Amg::new(AmgSettings::default());
            assert!(amg.build(&p, &a, &filter, &positions(nx, ny)));
            assert!(amg.levels() >= 3, "{:?}", amg.level_sizes(n));
            let pre = amg.preconditioner(&p, &a, &filter).unwrap();
            let st = PcgSettings {
                tolerance: 1e-10,
                absolute: 0.0,
                max_iterations: 5000,
            };
            let mut x = vec![Vec3::zeros(); n];
            let r1 = solve(
                &p,
                &a,
                &b,
                &filter,
                &z,
                &mut x,
                st,
                Preconditioner::Amg(&pre),
            );
            let mut y = vec![Vec3::zeros(); n];
            let r2 = solve(
                &p,
                &a,
                &b,
                &filter,
                &z,
                &mut y,
                st,
                Preconditioner::BlockJacobi(None),
            );
            assert!(r1.converged && r2.converged, "{r1:?} {r2:?}");
            assert!(5 * r1.iterations < r2.iterations, "{r1:?} {r2:?}");
            let scale = y.iter().map(|v| v.amax()).fold(0.0, f64::max);
            for i in 0..n {
                assert!((x[i] - y[i]).amax() <= 1e-6 * scale, "seed {seed} node {i}");
            }
            assert_eq!(x[0], z[0]);
        }
    }
}
