//! A sparse Cholesky factorisation of a *scalar* matrix over the simulation nodes, applied to
//! each of the three coordinates: the constant global matrix of projective dynamics
//! (Bouaziz et al. 2014, Sec. 4, "the system matrix is constant ... pre-factored"), see
//! [`crate::sim::projective`].
//!
//! The symbolic analysis (approximate-minimum-degree ordering, supernodal structure) is done
//! once per sparsity pattern by the `faer` crate; numeric refactorisations (new rest shape, new
//! pin set) reuse it. `faer` is built without its `rayon` feature: the factorisation and each
//! solve run sequentially; a three-column solve is the `x` column and the `y, z` pair side by
//! side, always split the same way, so results are bit-identical for any thread count. (A subtree-parallel substitution of
//! our own, three coordinates interleaved, was tried on branch sim7 and was not faster: the
//! solve is bound by reading the factor; BENCHMARKS.md.)
//!
//! Pinned (fixed) nodes are eliminated: their rows and columns are replaced by the diagonal, so
//! that `S (B^-1 (x) I3) S` with the filter projection `S` is the exact inverse of the filtered
//! matrix `S (B (x) I3) S` on the free subspace.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use rayon::prelude::*;

use super::pcg::Filter;
use super::sparse::BsrPattern;
use crate::geom::Vec3;

/// Scratch of a solve: faer stacks for the `x` column and the `y, z` pair, and the `n x 3`
/// column-major right-hand-side buffer.
type SolveScratch = (MemBuffer, MemBuffer, Vec<f64>);

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
    /// The factor rounded to single precision (half the bytes a solve reads), for increments.
    factor32: Vec<f32>,
    factored: bool,
    scratch: MemBuffer,
    /// Scratch of the solves: faer's stack and the right-hand sides column by column.
    solve_scratch: std::sync::Mutex<SolveScratch>,
    /// The same for the single-precision solves.
    solve_scratch32: std::sync::Mutex<(MemBuffer, MemBuffer, Vec<f32>)>,
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
        Self::with_threshold(pattern, SupernodalThreshold::default())
    }

    /// [`ScalarCholesky::new`] with faer's supernodal/simplicial choice given (the tests cover
    /// both factor layouts).
    pub fn with_threshold(
        pattern: &BsrPattern,
        supernodal: SupernodalThreshold,
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
        let solve_scratch =
            MemBuffer::try_new(symbolic.solve_in_place_scratch::<f64>(2, Par::Seq)).ok()?;
        let solve_scratch_x =
            MemBuffer::try_new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)).ok()?;
        let scratch32 = (
            MemBuffer::try_new(symbolic.solve_in_place_scratch::<f32>(1, Par::Seq)).ok()?,
            MemBuffer::try_new(symbolic.solve_in_place_scratch::<f32>(2, Par::Seq)).ok()?,
            Vec::new(),
        );
        Some(ScalarCholesky {
            n,
            values: vec![0.0; row_idx.len()],
            factor: vec![0.0; symbolic.len_val()],
            factor32: Vec::new(),
            col_ptr,
            row_idx,
            source,
            symbolic,
            factored: false,
            scratch,
            solve_scratch: std::sync::Mutex::new((solve_scratch_x, solve_scratch, Vec::new())),
            solve_scratch32: std::sync::Mutex::new(scratch32),
        })
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
        self.factored = ok;
        self.factor32.clear();
        if ok {
            self.factor32.extend(self.factor.iter().map(|&v| v as f32));
        }
        ok
    }

    /// Solves `B X = R` in place for the three columns of `r` (`x`, `y`, `z` coordinates).
    pub fn solve3(&self, r: &mut [Vec3]) {
        let Some(mut guard) = self.solve_buffers() else {
            return;
        };
        let n = self.n;
        let (stack_x, stack, buf) = &mut *guard;
        for (i, v) in r.iter().enumerate() {
            (buf[i], buf[n + i], buf[2 * n + i]) = (v.x, v.y, v.z);
        }
        self.solve_columns(stack_x, stack, buf, r);
    }

    /// Solves `B X = R` into `out` with row `i` of `R` given by `rhs(i)` (evaluated in parallel
    /// straight into the solver's buffer, then the two faer solves side by side). Without a
    /// factor `out` is left unchanged.
    pub fn solve_with<F>(&self, rhs: F, out: &mut [Vec3])
    where
        F: Fn(usize) -> Vec3 + Sync,
    {
        let Some(mut guard) = self.solve_buffers() else {
            return;
        };
        let n = self.n;
        let (stack_x, stack, buf) = &mut *guard;
        fill_columns(buf, n, |v| v, rhs);
        self.solve_columns(stack_x, stack, buf, out);
    }

    /// [`ScalarCholesky::solve_with`] with the factor in single precision: for increments
    /// `dx = B^-1 r` of an iteration that recomputes its residual `r` in double precision, so
    /// the rounding (relative ~1e-7 times the condition number, of the increment only) does not
    /// accumulate: the iteration's fixed point is the double-precision one. Reads half the
    /// bytes of the factor.
    pub fn solve_increment_with<F>(&self, rhs: F, out: &mut [Vec3])
    where
        F: Fn(usize) -> Vec3 + Sync,
    {
        if !self.factored {
            return;
        }
        let n = self.n;
        let mut guard = self
            .solve_scratch32
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        let (stack_x, stack, buf) = &mut *guard;
        buf.resize(3 * n, 0.0);
        fill_columns(buf, n, |v| v as f32, rhs);
        let llt = LltRef::<'_, usize, f32>::new(&self.symbolic, &self.factor32);
        solve_x_and_yz(llt, stack_x, stack, buf, n);
        for (i, v) in out.iter_mut().enumerate() {
            *v = Vec3::new(buf[i] as f64, buf[n + i] as f64, buf[2 * n + i] as f64);
        }
    }

    /// The solve scratch (two faer stacks and the `n x 3` column buffer, sized), or `None`
    /// without a factor.
    fn solve_buffers(&self) -> Option<std::sync::MutexGuard<'_, SolveScratch>> {
        if !self.factored {
            return None;
        }
        let mut guard = self.solve_scratch.lock().unwrap_or_else(|e| e.into_inner());
        guard.2.resize(3 * self.n, 0.0);
        Some(guard)
    }

    /// faer's solve of the three columns of `buf` (column-major, `n x 3`), written to `out`:
    /// the `x` column and the `y, z` pair as two solves side by side (`rayon::join`; always split
    /// the same way, so the arithmetic does not depend on the number of threads).
    fn solve_columns(
        &self,
        stack_x: &mut MemBuffer,
        stack: &mut MemBuffer,
        buf: &mut [f64],
        out: &mut [Vec3],
    ) {
        let n = self.n;
        let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.factor);
        solve_x_and_yz(llt, stack_x, stack, buf, n);
        for (i, v) in out.iter_mut().enumerate() {
            *v = Vec3::new(buf[i], buf[n + i], buf[2 * n + i]);
        }
    }

    /// Solves `B X = R` in place for `k` scalar columns stored column-major in `cols` (`n x k`):
    /// the first `k / 2` and the other columns as two faer solves side by side (always split the
    /// same way, so the result does not depend on the thread count). Without a factor `cols` is
    /// left unchanged.
    pub fn solve_many(&self, cols: &mut [f64]) {
        let n = self.n;
        if !self.factored || n == 0 {
            return;
        }
        let k = cols.len() / n;
        let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.factor);
        let solve = |c: &mut [f64]| {
            let m = c.len() / n;
            if m == 0 {
                return;
            }
            let mut stack =
                MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(m, Par::Seq));
            llt.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(c, n, m),
                Par::Seq,
                MemStack::new(&mut stack),
            );
        };
        let (a, b) = cols[..k * n].split_at_mut(k / 2 * n);
        rayon::join(|| solve(a), || solve(b));
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

/// Rows per parallel task when the right-hand side is evaluated.
const RHS_CHUNK: usize = 1024;

/// Writes row `i` of the `n x 3` column-major `buf` from `rhs(i)`, in parallel chunks,
/// converting each coordinate with `convert`.
fn fill_columns<T: Send>(
    buf: &mut [T],
    n: usize,
    convert: impl Fn(f64) -> T + Sync,
    rhs: impl Fn(usize) -> Vec3 + Sync,
) {
    let (bx, rest) = buf.split_at_mut(n);
    let (by, bz) = rest.split_at_mut(n);
    bx.par_chunks_mut(RHS_CHUNK)
        .zip(by.par_chunks_mut(RHS_CHUNK))
        .zip(bz.par_chunks_mut(RHS_CHUNK))
        .enumerate()
        .for_each(|(c, ((xs, ys), zs))| {
            for k in 0..xs.len() {
                let v = rhs(c * RHS_CHUNK + k);
                xs[k] = convert(v.x);
                ys[k] = convert(v.y);
                zs[k] = convert(v.z);
            }
        });
}

/// faer's solve of the `n x 3` column-major `buf` in place: the `x` column and the `y, z` pair
/// as two solves side by side (`rayon::join`; always split the same way, so the arithmetic does
/// not depend on the number of threads).
fn solve_x_and_yz<T: faer::traits::ComplexField>(
    llt: LltRef<'_, usize, T>,
    stack_x: &mut MemBuffer,
    stack: &mut MemBuffer,
    buf: &mut [T],
    n: usize,
) {
    let (bx, byz) = buf.split_at_mut(n);
    rayon::join(
        || {
            llt.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(bx, n, 1),
                Par::Seq,
                MemStack::new(stack_x),
            )
        },
        || {
            llt.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(byz, n, 2),
                Par::Seq,
                MemStack::new(stack),
            )
        },
    );
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
        fn solves_match_dense_lu(seed in 0u64..1000, n in 2usize..30) {
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
            // faer's choice and both layouts forced; `solve3` and `solve_with` agree.
            for threshold in [
                SupernodalThreshold::AUTO,
                SupernodalThreshold::FORCE_SIMPLICIAL,
                SupernodalThreshold::FORCE_SUPERNODAL,
            ] {
                let mut chol = ScalarCholesky::with_threshold(&pattern, threshold).unwrap();
                prop_assert!(chol.factor(&pattern, &values, &fixed));
                let mut x = r.clone();
                chol.solve3(&mut x);
                let mut y = vec![Vec3::zeros(); n];
                chol.solve_with(|i| r[i], &mut y);
                prop_assert_eq!(&x, &y);
                // Single precision: within f32 rounding times the (small) condition number.
                let mut z = vec![Vec3::zeros(); n];
                chol.solve_increment_with(|i| r[i], &mut z);
                for i in 0..n {
                    prop_assert!((z[i] - x[i]).norm() <= 1e-5 * (1.0 + x[i].norm()),
                        "{} vs {}", z[i], x[i]);
                }
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
