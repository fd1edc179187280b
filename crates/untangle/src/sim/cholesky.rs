//! A sparse Cholesky factorisation of a *scalar* matrix over the simulation nodes, applied to
//! each of the three coordinates: the constant global matrix of projective dynamics
//! (Bouaziz et al. 2014, Sec. 4, "the system matrix is constant ... pre-factored"), see
//! [`crate::sim::projective`].
//!
//! The symbolic analysis (approximate-minimum-degree ordering, supernodal structure) is done
//! once per sparsity pattern by the `faer` crate; numeric refactorisations (new rest shape, new
//! pin set) reuse it. `faer` is built without its `rayon` feature: the factorisation runs
//! sequentially. The solves use the factor copied into a [`TriangularFactor`] (subtree-parallel
//! substitution with the three coordinates together, bit-identical for any thread count): on
//! the 5k-vertex t-shirt faer's supernodal solve spent most of its time in small dense kernels.
//!
//! Pinned (fixed) nodes are eliminated: their rows and columns are replaced by the diagonal, so
//! that `S (B^-1 (x) I3) S` with the filter projection `S` is the exact inverse of the filtered
//! matrix `S (B (x) I3) S` on the free subspace.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw,
    SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};

use super::pcg::Filter;
use super::sparse::BsrPattern;
use super::triangular::{SplitParams, TriangularFactor};
use crate::geom::Vec3;

/// The symbolic analysis of one node pattern plus the numeric factor of the last matrix given
/// to [`ScalarCholesky::factor`].
pub struct ScalarCholesky {
    n: usize,
    /// Lower-triangle CSC structure (column `j`: rows `i >= j` of pattern row `j`).
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Pattern slot of each CSC entry.
    source: Vec<u32>,
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    factor: Vec<f64>,
    factored: bool,
    scratch: MemBuffer,
    /// The numeric factor as used by the solves.
    triangular: TriangularFactor,
    split: SplitParams,
    /// Scratch of the solves: a copy of the right-hand side, the permuted work vector.
    solve_scratch: std::sync::Mutex<(Vec<Vec3>, Vec<Vec3>)>,
}

impl std::fmt::Debug for ScalarCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScalarCholesky")
            .field("rows", &self.n)
            .field("matrix_entries", &self.row_idx.len())
            .field("factor_entries", &self.factor.len())
            .field("factored", &self.factored)
            .finish()
    }
}

impl ScalarCholesky {
    /// The symbolic analysis of `pattern` (one scalar per block slot); `None` if it fails (out
    /// of memory).
    pub fn new(pattern: &BsrPattern) -> Option<ScalarCholesky> {
        Self::with_params(
            pattern,
            SupernodalThreshold::default(),
            SplitParams::default(),
        )
    }

    /// [`ScalarCholesky::new`] with faer's supernodal/simplicial choice and the solve's
    /// subtree split given (the tests cover both factor layouts and small splits).
    pub fn with_params(
        pattern: &BsrPattern,
        supernodal: SupernodalThreshold,
        split: SplitParams,
    ) -> Option<ScalarCholesky> {
        let n = pattern.rows();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut source = Vec::new();
        col_ptr.push(0);
        for j in 0..n {
            for slot in pattern.offsets[j] as usize..pattern.offsets[j + 1] as usize {
                let i = pattern.cols[slot] as usize;
                if i >= j {
                    row_idx.push(i);
                    source.push(slot as u32);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let symbolic = factorize_symbolic_cholesky(
            SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx),
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: supernodal,
                ..Default::default()
            },
        )
        .ok()?;
        let scratch = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        )
        .ok()?;
        Some(ScalarCholesky {
            n,
            values: vec![0.0; row_idx.len()],
            factor: vec![0.0; symbolic.len_val()],
            col_ptr,
            row_idx,
            source,
            symbolic,
            factored: false,
            scratch,
            triangular: TriangularFactor::default(),
            split,
            solve_scratch: std::sync::Mutex::new((Vec::new(), Vec::new())),
        })
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.n
    }

    /// Stored values of the factor `L` (fill-in included).
    pub fn factor_entries(&self) -> usize {
        self.factor.len()
    }

    /// Whether a factorisation is held.
    pub fn is_factored(&self) -> bool {
        self.factored
    }

    /// Factorises the matrix with value `values[slot]` per pattern slot (symmetric), the rows
    /// and columns of nodes with `fixed[i]` replaced by their diagonal. Returns `false` (and
    /// holds no factor) if it is not numerically positive definite.
    pub fn factor(&mut self, pattern: &BsrPattern, values: &[f64], fixed: &[bool]) -> bool {
        for j in 0..self.n {
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let i = self.row_idx[k];
                let v = values[self.source[k] as usize];
                self.values[k] = if i != j && (fixed[i] || fixed[j]) {
                    0.0
                } else {
                    v
                };
            }
        }
        debug_assert_eq!(pattern.rows(), self.n);
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(
                self.n,
                self.n,
                &self.col_ptr,
                None,
                &self.row_idx,
            ),
            &self.values,
        );
        let ok = self
            .symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.factor,
                a,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut self.scratch),
                Default::default(),
            )
            .is_ok()
            && self.factor.iter().all(|v| v.is_finite());
        self.factored = ok && self.build_triangular();
        self.factored
    }

    /// Copies faer's factor (simplicial or supernodal layout) into the solve's
    /// [`TriangularFactor`]; `false` if it is not a valid factor.
    fn build_triangular(&mut self) -> bool {
        let n = self.n;
        let perm: Vec<usize> = match self.symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        let mut diag = vec![0.0; n];
        let mut lower: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                let (cp, ri) = (s.col_ptr(), s.row_idx());
                for j in 0..n {
                    for k in cp[j]..cp[j + 1] {
                        let (i, v) = (ri[k], self.factor[k]);
                        if i == j {
                            diag[j] = v;
                        } else if v != 0.0 {
                            lower[j].push((i as u32, v));
                        }
                    }
                }
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                for sn in 0..s.n_supernodes() {
                    let (b, e) = (s.supernode_begin()[sn], s.supernode_end()[sn]);
                    let pattern =
                        &s.row_idx()[s.col_ptr_for_row_idx()[sn]..][..s.nnz_per_super()[sn]];
                    let ncols = e - b;
                    let nrows = ncols + pattern.len();
                    let vals = &self.factor[s.col_ptr_for_val()[sn]..s.col_ptr_for_val()[sn + 1]];
                    for c in 0..ncols {
                        let col = &vals[c * nrows..(c + 1) * nrows];
                        diag[b + c] = col[c];
                        for (r, &v) in col.iter().enumerate().skip(c + 1) {
                            let i = if r < ncols { b + r } else { pattern[r - ncols] };
                            if v != 0.0 {
                                lower[b + c].push((i as u32, v));
                            }
                        }
                    }
                }
            }
        }
        match TriangularFactor::new(&perm, &diag, &lower, self.split) {
            Some(t) => {
                self.triangular = t;
                true
            }
            None => false,
        }
    }

    /// Solves `B X = R` in place for the three columns of `r` (`x`, `y`, `z` coordinates).
    pub fn solve3(&self, r: &mut [Vec3]) {
        if !self.factored {
            return;
        }
        let mut guard = self.solve_scratch.lock().unwrap_or_else(|e| e.into_inner());
        let (copy, work) = &mut *guard;
        copy.clear();
        copy.extend_from_slice(r);
        self.triangular.solve(|i| copy[i], r, work);
    }

    /// Solves `B X = R` into `out` with row `i` of `R` given by `rhs(i)`, evaluated inside the
    /// (parallel) forward substitution. Without a factor `out` is left unchanged.
    pub fn solve_with<F>(&self, rhs: F, out: &mut [Vec3])
    where
        F: Fn(usize) -> Vec3 + Sync,
    {
        if !self.factored {
            return;
        }
        let mut guard = self.solve_scratch.lock().unwrap_or_else(|e| e.into_inner());
        self.triangular.solve(rhs, out, &mut guard.1);
    }

    /// Stored entries of `L` strictly below the diagonal as used by the solves.
    pub fn lower_entries(&self) -> usize {
        self.triangular.entries()
    }

    /// The solve's schedule: independent groups, the fractions of the work in the sequential
    /// top and in the largest group ([`TriangularFactor::schedule`]).
    pub fn schedule(&self) -> (usize, f64, f64) {
        self.triangular.schedule()
    }

    /// The preconditioner `out = S (B^-1 (x) I3) S r`; returns `r . out`. Without a factor,
    /// `out = S r`.
    pub fn apply(&self, r: &[Vec3], filter: &[Filter], out: &mut [Vec3]) -> f64 {
        for (o, (ri, f)) in out.iter_mut().zip(r.iter().zip(filter)) {
            *o = f.apply(*ri);
        }
        self.solve3(out);
        let mut acc = 0.0;
        for (i, o) in out.iter_mut().enumerate() {
            *o = filter[i].apply(*o);
            acc += r[i].dot(o);
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    proptest! {
        /// On random sparse SPD matrices (a random graph, diagonally dominant values) with random
        /// fixed nodes, `solve3` matches a dense nalgebra solve of the same (eliminated) matrix.
        #[test]
        fn solves_match_dense_lu(seed in 0u64..1000, n in 2usize..60) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut pairs = Vec::new();
            for i in 0..n as u32 {
                for _ in 0..2 {
                    let j = rng.random_range(0..n as u32);
                    if j != i { pairs.push((i, j)); }
                }
            }
            let pattern = BsrPattern::from_pairs(n, pairs);
            let mut dense = DMatrix::<f64>::zeros(n, n);
            let mut values = vec![0.0; pattern.nnz()];
            for i in 0..n {
                for s in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                    let j = pattern.cols[s] as usize;
                    if j < i {
                        let v: f64 = rng.random_range(-1.0..1.0);
                        dense[(i, j)] = v;
                        dense[(j, i)] = v;
                    }
                }
            }
            let fixed: Vec<bool> = (0..n).map(|_| rng.random_bool(0.2)).collect();
            for i in 0..n {
                let row: f64 = (0..n).map(|j| dense[(i, j)].abs()).sum();
                dense[(i, i)] = row + rng.random_range(0.1..2.0);
            }
            for i in 0..n {
                for s in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                    values[s] = dense[(i, pattern.cols[s] as usize)];
                }
            }
            for i in 0..n {
                for j in 0..n {
                    if i != j && (fixed[i] || fixed[j]) { dense[(i, j)] = 0.0; }
                }
            }
            let r: Vec<Vec3> = (0..n).map(|_| Vec3::new(rng.random(), rng.random(), rng.random())).collect();
            let lu = dense.clone().lu();
            // faer's choice, both layouts forced, and the solve split into small groups.
            let small = SplitParams { min_entries: 0, subtrees: 8, max_top: 0.5, groups: 3 };
            for (threshold, split) in [
                (SupernodalThreshold::AUTO, SplitParams::default()),
                (SupernodalThreshold::FORCE_SIMPLICIAL, small),
                (SupernodalThreshold::FORCE_SUPERNODAL, small),
            ] {
                let mut chol = ScalarCholesky::with_params(&pattern, threshold, split).unwrap();
                prop_assert!(chol.factor(&pattern, &values, &fixed));
                let mut x = r.clone();
                chol.solve3(&mut x);
                let mut y = vec![Vec3::zeros(); n];
                chol.solve_with(|i| r[i], &mut y);
                prop_assert_eq!(&x, &y);
                for c in 0..3 {
                    let b = nalgebra::DVector::from_iterator(n, r.iter().map(|v| v[c]));
                    let want = lu.solve(&b).unwrap();
                    for i in 0..n {
                        prop_assert!((want[i] - x[i][c]).abs() <= 1e-9 * (1.0 + want[i].abs()));
                    }
                }
            }
        }
    }

    #[test]
    fn indefinite_matrix_is_reported() {
        let pattern = BsrPattern::from_pairs(2, [(0, 1)]);
        let mut values = vec![0.0; pattern.nnz()];
        values[pattern.slot(0, 0).unwrap()] = 1.0;
        values[pattern.slot(1, 1).unwrap()] = 1.0;
        values[pattern.slot(0, 1).unwrap()] = 2.0;
        values[pattern.slot(1, 0).unwrap()] = 2.0;
        let mut chol = ScalarCholesky::new(&pattern).unwrap();
        assert!(!chol.factor(&pattern, &values, &[false, false]));
        assert!(!chol.is_factored());
    }
}
