//! A sparse direct Cholesky factorisation of the filtered implicit-step matrix, used as the CG
//! preconditioner ([`crate::sim::pcg::Preconditioner::Cholesky`]).
//!
//! The system of Baraff & Witkin 1998 (Sec. 5, `(M + h D + h^2 K) dv = ...`, solved by the
//! filtered "modified PCG" of their Sec. 5.3) is a shell: its smooth, nearly inextensional
//! bending modes have tiny eigenvalues after any local (block-Jacobi) scaling and are not
//! spanned by piecewise rigid coarse functions (see BENCHMARKS.md, "Simulation"), so local and
//! aggregation preconditioners leave CG at ~100-150 iterations on a curved garment. A complete
//! factorisation `L L^T = S A S + (I - S) d` (`S` the per-node filter projection, `d` the
//! diagonal scale) of the matrix of one step makes CG converge in a few iterations for that step
//! and stays a good preconditioner for the following steps while the matrix changes slowly; the
//! simulator refactorises when the iteration count grows ([`crate::sim::step`]).
//!
//! The symbolic analysis (approximate-minimum-degree ordering, supernodal structure) is done once
//! per sparsity pattern by the `faer` crate; every numeric factorisation reuses it. `faer` is
//! built without its `rayon` feature, so factorisation and solves run sequentially and are
//! bit-identical for any thread count.
//!
//! As a preconditioner `P = S (L L^T)^-1 S` is symmetric and positive definite on the free
//! subspace of *any* filter (the factor may come from an earlier matrix or filter), which is all
//! filtered CG needs. Contact-pair couplings outside the block pattern ([`super::sparse::PairTerms`])
//! are left out of the factor (their diagonal blocks are in it).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use nalgebra::Matrix3;

use super::pcg::Filter;
use super::sparse::{BsrMatrix, BsrPattern};
use crate::geom::Vec3;

/// The symbolic analysis of one block pattern plus the numeric factor of the last matrix given
/// to [`BlockCholesky::factor`].
pub struct BlockCholesky {
    /// Block rows.
    n: usize,
    /// Scalar lower-triangle CSC structure of the `3n x 3n` matrix.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Per scalar entry: the block slot holding it as `(j, i)` (row `j` = the entry's block
    /// column) and the index `3 c + r` of the entry inside that block's transpose.
    source: Vec<(u32, u8)>,
    symbolic: SymbolicCholesky<usize>,
    /// Scalar values of the filtered matrix (lower triangle).
    values: Vec<f64>,
    /// Values of the factor `L`.
    factor: Vec<f64>,
    /// Whether `factor` holds a valid factorisation.
    factored: bool,
    /// Scratch memory of the numeric factorisation.
    scratch: MemBuffer,
}

impl std::fmt::Debug for BlockCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BlockCholesky")
            .field("rows", &(3 * self.n))
            .field("matrix_entries", &self.row_idx.len())
            .field("factor_entries", &self.factor.len())
            .field("factored", &self.factored)
            .finish()
    }
}

impl BlockCholesky {
    /// The symbolic analysis of `pattern` (fill-reducing ordering and supernodes); `None` if
    /// the analysis fails (out of memory).
    pub fn new(pattern: &BsrPattern) -> Option<BlockCholesky> {
        let n = pattern.rows();
        let mut col_ptr = Vec::with_capacity(3 * n + 1);
        let mut row_idx = Vec::new();
        let mut source = Vec::new();
        col_ptr.push(0);
        for j in 0..n {
            let (s, e) = (pattern.offsets[j] as usize, pattern.offsets[j + 1] as usize);
            for c in 0..3 {
                // Column 3j + c: rows 3i + r >= 3j + c of the blocks (i, j), i >= j. Block
                // (i, j) is the transpose of block (j, i), stored in row j's slots.
                for slot in s..e {
                    let i = pattern.cols[slot] as usize;
                    if i < j {
                        continue;
                    }
                    for r in 0..3 {
                        if 3 * i + r < 3 * j + c {
                            continue;
                        }
                        row_idx.push(3 * i + r);
                        // (A_ij)[r][c] = (A_ji)[c][r]; column-major index of (c, r) is c + 3r.
                        source.push((slot as u32, (c + 3 * r) as u8));
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let symbolic = {
            let a = SymbolicSparseColMatRef::new_checked(3 * n, 3 * n, &col_ptr, None, &row_idx);
            factorize_symbolic_cholesky(
                a,
                Side::Lower,
                SymmetricOrdering::Amd,
                CholeskySymbolicParams::default(),
            )
            .ok()?
        };
        let scratch = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        )
        .ok()?;
        let factor = vec![0.0; symbolic.len_val()];
        let values = vec![0.0; row_idx.len()];
        Some(BlockCholesky {
            n,
            col_ptr,
            row_idx,
            source,
            symbolic,
            values,
            factor,
            factored: false,
            scratch,
        })
    }

    /// Whether this analysis was made for `pattern`'s size (the simulator's pattern never
    /// changes, so the size identifies it).
    pub fn is_for(&self, pattern: &BsrPattern) -> bool {
        self.n == pattern.rows() && self.row_idx.len() == lower_entries(pattern)
    }

    /// Number of stored values of the factor `L` (fill-in included).
    pub fn factor_entries(&self) -> usize {
        self.factor.len()
    }

    /// Whether a factorisation is held.
    pub fn is_factored(&self) -> bool {
        self.factored
    }

    /// Factorises `S A S + (I - S) d` for the filter `filter` (`d` = the mean diagonal entry of
    /// the node's block). Pair couplings outside the pattern are left out. Returns `false` (and
    /// holds no factorisation) if the matrix is not numerically positive definite.
    pub fn factor(&mut self, pattern: &BsrPattern, a: &BsrMatrix, filter: &[Filter]) -> bool {
        let proj: Vec<Matrix3<f64>> = filter.iter().map(projection).collect();
        // Filtered blocks of the lower triangle, per block slot (only slots (j, i) with i >= j
        // are read).
        let mut filtered: Vec<Matrix3<f64>> = vec![Matrix3::zeros(); pattern.nnz()];
        for j in 0..self.n {
            for slot in pattern.offsets[j] as usize..pattern.offsets[j + 1] as usize {
                let i = pattern.cols[slot] as usize;
                if i < j {
                    continue;
                }
                let mut b = proj[j] * a.values[slot] * proj[i];
                if i == j {
                    let d = a.values[slot].trace() / 3.0;
                    b += (Matrix3::identity() - proj[j]) * d.abs().max(f64::MIN_POSITIVE);
                }
                filtered[slot] = b;
            }
        }
        for (v, &(slot, idx)) in self.values.iter_mut().zip(&self.source) {
            *v = filtered[slot as usize].as_slice()[idx as usize];
        }
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(
                3 * self.n,
                3 * self.n,
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
        ok
    }

    /// `out = S (L L^T)^-1 S r`; returns `r . out`. Needs a factorisation
    /// ([`BlockCholesky::is_factored`]); without one, `out = S r`.
    pub fn apply(&self, r: &[Vec3], filter: &[Filter], out: &mut [Vec3]) -> f64 {
        let mut buf: Vec<f64> = r
            .iter()
            .zip(filter)
            .flat_map(|(ri, f)| {
                let v = f.apply(*ri);
                [v.x, v.y, v.z]
            })
            .collect();
        if self.factored {
            let llt = faer::sparse::linalg::cholesky::LltRef::<'_, usize, f64>::new(
                &self.symbolic,
                &self.factor,
            );
            let mut mem = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
            llt.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(&mut buf, 3 * self.n, 1),
                Par::Seq,
                MemStack::new(&mut mem),
            );
        }
        let mut acc = 0.0;
        for (i, o) in out.iter_mut().enumerate() {
            *o = filter[i].apply(Vec3::new(buf[3 * i], buf[3 * i + 1], buf[3 * i + 2]));
            acc += r[i].dot(o);
        }
        acc
    }
}

/// The projection matrix `S_i` of a filter.
fn projection(f: &Filter) -> Matrix3<f64> {
    match f {
        Filter::Free => Matrix3::identity(),
        Filter::Fixed => Matrix3::zeros(),
        Filter::Normal(nn) => Matrix3::identity() - nn * nn.transpose(),
    }
}

/// Scalar entries of the lower triangle of a block pattern's `3n x 3n` matrix.
fn lower_entries(pattern: &BsrPattern) -> usize {
    let n = pattern.rows();
    let off = pattern.nnz() - n;
    // Each off-diagonal block pair contributes 9 lower entries, each diagonal block 6.
    9 * (off / 2) + 6 * n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::pcg::{solve, PcgSettings, Preconditioner};
    use nalgebra::{DMatrix, DVector};
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// An SPD block system on an `nx x ny` triangulated grid: stiff springs along random
    /// directions between neighbours (a sum of PSD element matrices) plus a mass diagonal, with
    /// contact-pair couplings outside the pattern when `pairs` is set.
    fn grid_system(
        nx: usize,
        ny: usize,
        k: f64,
        seed: u64,
        pairs: bool,
    ) -> (BsrPattern, BsrMatrix) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let id = |x: usize, y: usize| (y * nx + x) as u32;
        let mut edges = Vec::new();
        for y in 0..ny {
            for x in 0..nx {
                if x + 1 < nx {
                    edges.push((id(x, y), id(x + 1, y)));
                }
                if y + 1 < ny {
                    edges.push((id(x, y), id(x, y + 1)));
                }
                if x + 1 < nx && y + 1 < ny {
                    edges.push((id(x, y), id(x + 1, y + 1)));
                }
            }
        }
        let n = nx * ny;
        let p = BsrPattern::from_pairs(n, edges.iter().copied());
        let mut a = BsrMatrix::zeros(&p);
        for &(i, j) in &edges {
            let d = Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5);
            let blk = d * d.transpose() * k * rng.random_range(0.1..1.0);
            for (r, c, s) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                a.values[p.slot(r, c).unwrap()] += blk * s;
            }
        }
        for i in 0..n {
            a.values[p.diag[i] as usize] += Matrix3::identity() * rng.random_range(0.5..2.0);
        }
        if pairs {
            for c in 0..(n as u32 / 4) {
                let nn = Vec3::new(rng.random(), rng.random(), 1.0).normalize();
                let nodes = [c, (c * 7 + 5) % n as u32, (c * 3 + 11) % n as u32, u32::MAX];
                if nodes[0] == nodes[1] || nodes[1] == nodes[2] || nodes[0] == nodes[2] {
                    continue;
                }
                a.add_pair(&p, nodes, [1.0, -0.4, -0.6, 0.0], nn * nn.transpose() * k);
            }
        }
        a.finish_pairs(&p);
        (p, a)
    }

    fn random_filter(n: usize, seed: u64) -> Vec<Filter> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| match rng.random_range(0..8) {
                0 => Filter::Fixed,
                1 => Filter::Normal(
                    Vec3::new(rng.random::<f64>() - 0.5, rng.random(), 0.3).normalize(),
                ),
                _ => Filter::Free,
            })
            .collect()
    }

    fn flat(v: &[Vec3]) -> DVector<f64> {
        DVector::from_iterator(3 * v.len(), v.iter().flat_map(|p| [p.x, p.y, p.z]))
    }

    /// The dense projection `S` of a filter.
    fn dense_projection(filter: &[Filter]) -> DMatrix<f64> {
        let n = filter.len();
        let mut s = DMatrix::zeros(3 * n, 3 * n);
        for (i, f) in filter.iter().enumerate() {
            s.fixed_view_mut::<3, 3>(3 * i, 3 * i)
                .copy_from(&projection(f));
        }
        s
    }

    /// The dense oracle of the factorised matrix: `S A_p S + (I - S) d`, with `A_p` the pattern
    /// part of `a` (pair couplings outside the pattern removed) built from the blocks directly.
    fn dense_factored_matrix(p: &BsrPattern, a: &BsrMatrix, filter: &[Filter]) -> DMatrix<f64> {
        let n = p.rows();
        let mut d = DMatrix::zeros(3 * n, 3 * n);
        for i in 0..n {
            for slot in p.offsets[i] as usize..p.offsets[i + 1] as usize {
                let j = p.cols[slot] as usize;
                d.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                    .copy_from(&a.values[slot]);
            }
        }
        let s = dense_projection(filter);
        let mut m = &s * d * &s;
        for i in 0..n {
            let dd = a.values[p.diag[i] as usize].trace() / 3.0;
            let c = (Matrix3::identity() - projection(&filter[i])) * dd;
            let mut v = m.fixed_view_mut::<3, 3>(3 * i, 3 * i);
            v += c;
        }
        m
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// The preconditioner `r -> S (L L^T)^-1 S r` equals the dense solve with the filtered
        /// matrix (oracle: nalgebra's dense Cholesky of the independently built dense matrix),
        /// and is symmetric positive definite on the free subspace of the filter in use, also
        /// when the factor came from a different matrix and filter (reuse across steps).
        #[test]
        fn preconditioner_matches_dense_solve_and_is_spd(
            nx in 2usize..9,
            ny in 2usize..9,
            k in 1.0f64..1e5,
            seed in 0u64..10_000,
            reuse in proptest::bool::ANY,
        ) {
            let (p, a) = grid_system(nx, ny, k, seed, seed % 2 == 0);
            let n = p.rows();
            let filter = random_filter(n, seed + 1);
            let mut ch = BlockCholesky::new(&p).unwrap();
            prop_assert!(ch.is_for(&p));
            let (fa, ff) = if reuse {
                (grid_system(nx, ny, k * 0.3, seed + 9, false).1, random_filter(n, seed + 2))
            } else {
                (a.clone(), filter.clone())
            };
            prop_assert!(ch.factor(&p, &fa, &ff));
            prop_assert!(ch.is_factored());
            // Oracle of the action.
            let m = dense_factored_matrix(&p, &fa, &ff);
            let chol = m.clone().cholesky();
            prop_assert!(chol.is_some());
            let chol = chol.unwrap();
            let s = dense_projection(&filter);
            let mut rng = ChaCha8Rng::seed_from_u64(seed + 3);
            let r: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5))
                .collect();
            let mut out = vec![Vec3::zeros(); n];
            let rpr = ch.apply(&r, &filter, &mut out);
            let expect = &s * chol.solve(&(&s * flat(&r)));
            let scale = expect.amax().max(1e-300);
            prop_assert!((flat(&out) - &expect).amax() <= 1e-8 * scale);
            prop_assert!((rpr - flat(&r).dot(&expect)).abs() <= 1e-8 * rpr.abs().max(1e-300));
            // Symmetric: u . P w == w . P u.
            let w: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
                .collect();
            let (mut pw, mut pr) = (vec![Vec3::zeros(); n], vec![Vec3::zeros(); n]);
            ch.apply(&w, &filter, &mut pw);
            ch.apply(&r, &filter, &mut pr);
            let (a1, a2) = (flat(&r).dot(&flat(&pw)), flat(&w).dot(&flat(&pr)));
            prop_assert!((a1 - a2).abs() <= 1e-9 * (a1.abs() + a2.abs() + 1e-300));
            // Positive on the free subspace: r . P r > 0 whenever S r != 0.
            if (&s * flat(&r)).norm() > 1e-12 {
                prop_assert!(rpr > 0.0);
            }
        }

        /// Filtered CG with a Cholesky preconditioner (of this matrix, or of a different one)
        /// reaches the dense solution of the constrained system; with the factor of this very
        /// matrix and no couplings outside the pattern it needs at most two iterations.
        #[test]
        fn cg_with_the_factor_solves_the_constrained_system(
            nx in 3usize..10,
            ny in 3usize..10,
            k in 10.0f64..1e5,
            seed in 0u64..10_000,
            reuse in proptest::bool::ANY,
            pairs in proptest::bool::ANY,
        ) {
            let (p, a) = grid_system(nx, ny, k, seed, pairs);
            let n = p.rows();
            let filter = random_filter(n, seed + 1);
            let mut ch = BlockCholesky::new(&p).unwrap();
            let (fa, ff) = if reuse {
                (grid_system(nx, ny, k * 2.0, seed + 5, !pairs).1, random_filter(n, seed + 4))
            } else {
                (a.clone(), filter.clone())
            };
            prop_assert!(ch.factor(&p, &fa, &ff));
            let mut rng = ChaCha8Rng::seed_from_u64(seed + 6);
            let b: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5))
                .collect();
            let z: Vec<Vec3> = (0..n)
                .map(|i| if filter[i] == Filter::Free { Vec3::zeros() } else { Vec3::new(0.1, -0.2, 0.05) })
                .collect();
            let mut x = vec![Vec3::zeros(); n];
            let res = solve(
                &p,
                &a,
                &b,
                &filter,
                &z,
                &mut x,
                PcgSettings { tolerance: 1e-12, absolute: 0.0, max_iterations: 1000 },
                Preconditioner::Cholesky(&ch),
            );
            prop_assert!(res.converged, "{:?}", res);
            if !reuse && !pairs {
                prop_assert!(res.iterations <= 2, "{:?}", res);
            }
            // Oracle: dense solve of S A S y = S (b - A z_c) on the free subspace, x = z_c + y.
            let s = dense_projection(&filter);
            let id = DMatrix::<f64>::identity(3 * n, 3 * n);
            let zc = (&id - &s) * flat(&z);
            let d = a.to_dense(&p);
            let lhs = &s * &d * &s + (&id - &s);
            let rhs = &s * (flat(&b) - &d * &zc);
            let xd = zc + lhs.lu().solve(&rhs).unwrap();
            let scale = xd.amax().max(1e-300);
            prop_assert!((flat(&x) - &xd).amax() <= 1e-7 * scale, "{}", (flat(&x) - &xd).amax() / scale);
        }
    }

    /// A matrix that is not positive definite is refused (no factor is held), and `apply`
    /// then only filters.
    #[test]
    fn indefinite_matrix_is_refused() {
        let (p, mut a) = grid_system(4, 4, 100.0, 1, false);
        let n = p.rows();
        a.values[p.diag[5] as usize] -= Matrix3::identity() * 1e4;
        let mut ch = BlockCholesky::new(&p).unwrap();
        let filter = vec![Filter::Free; n];
        assert!(!ch.factor(&p, &a, &filter));
        assert!(!ch.is_factored());
        let r: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f64, 1.0, -1.0)).collect();
        let mut out = vec![Vec3::zeros(); n];
        ch.apply(&r, &filter, &mut out);
        assert_eq!(out, r);
        // Fixing the node makes it definite again (its row is replaced by the diagonal scale).
        let mut filter = filter;
        filter[5] = Filter::Fixed;
        a.values[p.diag[5] as usize] = Matrix3::identity() * 1.0;
        assert!(ch.factor(&p, &a, &filter));
    }

    /// The scalar structure has the expected size, and an analysis is recognised as belonging
    /// to its pattern only.
    #[test]
    fn structure_matches_the_pattern() {
        let (p, _) = grid_system(5, 4, 1.0, 0, false);
        let ch = BlockCholesky::new(&p).unwrap();
        assert_eq!(ch.row_idx.len(), lower_entries(&p));
        assert!(ch.factor_entries() >= ch.row_idx.len());
        assert!(ch.is_for(&p));
        let (r, _) = grid_system(6, 4, 1.0, 0, false);
        assert!(!ch.is_for(&r));
    }
}
