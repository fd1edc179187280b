//! Partial numeric refactorisation of a supernodal Cholesky factor after a local matrix change.
//!
//! The Cha & Ko loop (Cha & Ko 2022, Sec. 5.1) edits the rest shape of a few triangles every
//! step, so projective dynamics' constant matrix (Bouaziz et al. 2014, Sec. 4.4) changes in a
//! few hundred of its ~63k slots (the 4,950-vertex t-shirt), and the whole matrix used to be
//! refactored every step. In a left-looking supernodal factorisation (faer's), the block of
//! supernode `s` is computed from the matrix columns of `s` and the blocks of the supernodes `d`
//! whose row pattern meets the columns of `s` (its *updaters*, all descendants of `s` in the
//! supernodal elimination tree), by the same operations whatever the other blocks hold. So
//! after a change, only the supernodes that hold a changed column, and their ancestors, need
//! recomputing; every other block would come out bit for bit as it is.
//!
//! [`PartialRefactor::refactor`] recomputes exactly those, each with the operations and the
//! order of faer 0.24's `factorize_supernodal_numeric_llt` (scatter of the permuted lower
//! matrix into the zeroed block, the updates of its updaters in ascending order through the
//! same gather/scatter product kernel, dense `LL^T` of the diagonal block, triangular solve of
//! the rows below). The result is therefore the same bits as a full refactorisation; the test
//! `partial_refactor_gives_the_bits_of_a_full_one` (in `cholesky`) checks that against faer
//! for random grid patterns and changes, with the instruction set of the machine it runs on.
//! The replication is tied to faer 0.24's algorithm: after a faer upgrade that test decides.

use faer::dyn_stack::MemStack;
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, LltRegularization};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::{MatMut, Par};

/// Supernodes of a supernodal symbolic factor with what a partial refactorisation needs: the
/// permuted lower matrix by column, each supernode's parent and updaters.
pub struct PartialRefactor {
    /// `(row, entry)` of the permuted lower-triangular matrix, by permuted column
    /// (`col_ptr[j]..col_ptr[j + 1]`); `entry` indexes the caller's CSC values.
    col_ptr: Vec<usize>,
    entries: Vec<(usize, usize)>,
    /// New (permuted) index of each original node.
    new_index: Vec<usize>,
    /// Supernode of each permuted index.
    index_to_super: Vec<usize>,
    /// Parent supernode (`usize::MAX` for a root).
    parent: Vec<usize>,
    /// Updaters of each supernode, ascending (`upd_ptr[s]..upd_ptr[s + 1]`).
    upd_ptr: Vec<usize>,
    updaters: Vec<usize>,
    /// Scratch: local row of each global row in the current supernode; the update's indices.
    global_to_local: Vec<usize>,
    row_idx: Vec<usize>,
    col_idx: Vec<usize>,
    dirty: Vec<bool>,
}

impl PartialRefactor {
    /// The structure for `symbolic` (built from the lower CSC pattern `col_ptr`, `row_idx` of
    /// `n` rows); `None` for a simplicial factor or where the product kernel of faer's
    /// supernodal factorisation is not the one replicated here (x86-64 with AVX2 and FMA).
    pub fn new(
        symbolic: &SymbolicCholesky<usize>,
        col_ptr: &[usize],
        row_idx: &[usize],
    ) -> Option<PartialRefactor> {
        if !kernel_available() {
            return None;
        }
        let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
            return None;
        };
        let n = col_ptr.len() - 1;
        let new_index: Vec<usize> = match symbolic.perm() {
            Some(p) => p.arrays().1.to_vec(),
            None => (0..n).collect(),
        };
        // The permuted lower triangle: entry (i, j), i >= j, goes to (max, min) of the new
        // indices.
        let mut count = vec![0usize; n + 1];
        for j in 0..n {
            for &i in &row_idx[col_ptr[j]..col_ptr[j + 1]] {
                count[new_index[i].min(new_index[j]) + 1] += 1;
            }
        }
        for j in 0..n {
            count[j + 1] += count[j];
        }
        let pcol_ptr = count.clone();
        let mut entries = vec![(0, 0); row_idx.len()];
        for j in 0..n {
            for (k, &i) in row_idx
                .iter()
                .enumerate()
                .take(col_ptr[j + 1])
                .skip(col_ptr[j])
            {
                let (a, b) = (new_index[i], new_index[j]);
                let c = a.min(b);
                entries[count[c]] = (a.max(b), k);
                count[c] += 1;
            }
        }
        let ns = sym.n_supernodes();
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        let mut index_to_super = vec![0; n];
        for s in 0..ns {
            index_to_super[begin[s]..end[s]].fill(s);
        }
        let pattern = |s: usize| -> &[usize] {
            &sym.row_idx()[sym.col_ptr_for_row_idx()[s]..][..sym.nnz_per_super()[s]]
        };
        let parent: Vec<usize> = (0..ns)
            .map(|s| {
                pattern(s)
                    .first()
                    .map_or(usize::MAX, |&r| index_to_super[r])
            })
            .collect();
        let mut lists: Vec<Vec<usize>> = vec![Vec::new(); ns];
        for d in 0..ns {
            let mut last = usize::MAX;
            for &r in pattern(d) {
                let s = index_to_super[r];
                if s != last {
                    lists[s].push(d);
                    last = s;
                }
            }
        }
        let mut upd_ptr = Vec::with_capacity(ns + 1);
        upd_ptr.push(0);
        let mut updaters = Vec::new();
        for l in &lists {
            updaters.extend_from_slice(l);
            upd_ptr.push(updaters.len());
        }
        Some(PartialRefactor {
            col_ptr: pcol_ptr,
            entries,
            new_index,
            index_to_super,
            parent,
            upd_ptr,
            updaters,
            global_to_local: vec![usize::MAX; n],
            row_idx: Vec::new(),
            col_idx: Vec::new(),
            dirty: vec![false; ns],
        })
    }

    /// Number of supernodes.
    pub fn supernodes(&self) -> usize {
        self.parent.len()
    }

    /// The supernodes the last [`PartialRefactor::refactor`] recomputed, ascending.
    pub fn recomputed(&self) -> impl Iterator<Item = usize> + '_ {
        self.dirty
            .iter()
            .enumerate()
            .filter(|(_, &d)| d)
            .map(|(s, _)| s)
    }

    /// Recomputes in `factor` (faer's supernodal values of the factor of `old`) the supernodes
    /// that `values` (the caller's CSC values, same pattern) changes, giving the factor of
    /// `values` bit for bit as a full factorisation does. `changed` lists the original nodes
    /// whose column differs between the two. Returns the number of supernodes recomputed, or
    /// `None` if a diagonal block is not positive definite (the factor is then partly updated
    /// and must not be used). `stack`: scratch for faer's full numeric factorisation.
    pub fn refactor(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
        factor: &mut [f64],
        values: &[f64],
        changed: &[usize],
        stack: &mut MemStack,
    ) -> Option<usize> {
        let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
            return None;
        };
        let ns = sym.n_supernodes();
        self.dirty.fill(false);
        for &o in changed {
            self.dirty[self.index_to_super[self.new_index[o]]] = true;
        }
        // Supernodes are numbered children first: one ascending pass marks all ancestors.
        for s in 0..ns {
            if self.dirty[s] && self.parent[s] != usize::MAX {
                self.dirty[self.parent[s]] = true;
            }
        }
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        let cp_row = sym.col_ptr_for_row_idx();
        let cp_val = sym.col_ptr_for_val();
        let nnz = sym.nnz_per_super();
        let all_rows = sym.row_idx();
        let mut recomputed = 0;
        for s in 0..ns {
            if !self.dirty[s] {
                continue;
            }
            recomputed += 1;
            let (s_start, s_end) = (begin[s], end[s]);
            let s_pattern = &all_rows[cp_row[s]..][..nnz[s]];
            let s_ncols = s_end - s_start;
            let s_nrows = s_pattern.len() + s_ncols;
            for (k, &r) in s_pattern.iter().enumerate() {
                self.global_to_local[r] = k + s_ncols;
            }
            let (head, tail) = factor.split_at_mut(cp_val[s]);
            let ls = &mut tail[..cp_val[s + 1] - cp_val[s]];
            ls.fill(0.0);
            for j in s_start..s_end {
                for &(i, k) in &self.entries[self.col_ptr[j]..self.col_ptr[j + 1]] {
                    let row = if i >= s_end {
                        self.global_to_local[i]
                    } else {
                        i - s_start
                    };
                    ls[row + (j - s_start) * s_nrows] += values[k];
                }
            }
            for &d in &self.updaters[self.upd_ptr[s]..self.upd_ptr[s + 1]] {
                let (d_start, d_end) = (begin[d], end[d]);
                let d_pattern = &all_rows[cp_row[d]..][..nnz[d]];
                let d_ncols = d_end - d_start;
                let d_nrows = d_pattern.len() + d_ncols;
                let first = d_pattern.partition_point(|&r| r < s_start);
                let mid = d_pattern[first..].partition_point(|&r| r < s_end);
                let rows = d_pattern.len() - first;
                if rows == 0 || mid == 0 {
                    continue;
                }
                self.row_idx.clear();
                self.row_idx
                    .extend(d_pattern[first..].iter().enumerate().map(|(q, &r)| {
                        if q < mid {
                            r - s_start
                        } else {
                            self.global_to_local[r]
                        }
                    }));
                self.col_idx.clear();
                self.col_idx
                    .extend(d_pattern[first..first + mid].iter().map(|&r| r - s_start));
                // The rows of `d` from the first one in `s` down: the left factor, and its top
                // `mid` rows (those in `s`), transposed, the right one.
                let ld = &head[cp_val[d] + d_ncols + first..cp_val[d + 1]];
                debug_assert!(ld.len() >= (d_ncols - 1) * d_nrows + rows);
                // SAFETY: `ls` is `s_nrows x s_ncols` column-major and every index in `row_idx`
                // (< s_nrows) and `col_idx` (< s_ncols) is inside it; `ld` holds the `rows x
                // d_ncols` block with column stride `d_nrows` (checked above).
                unsafe {
                    update(
                        ls,
                        s_nrows,
                        &self.row_idx,
                        &self.col_idx,
                        ld,
                        d_ncols,
                        d_nrows,
                    );
                }
            }
            let lmat = MatMut::from_column_major_slice_mut(ls, s_nrows, s_ncols);
            let (mut top, bot) = lmat.split_at_row_mut(s_ncols);
            let ok = cholesky_in_place(
                top.rb_mut(),
                LltRegularization::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
            .is_ok();
            if !ok {
                for &r in s_pattern {
                    self.global_to_local[r] = usize::MAX;
                }
                return None;
            }
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                top.rb().conjugate(),
                bot.transpose_mut(),
                Par::Seq,
            );
            for &r in s_pattern {
                self.global_to_local[r] = usize::MAX;
            }
        }
        Some(recomputed)
    }
}

/// Whether faer's supernodal product uses the kernel [`update`] calls (its x86-64 path).
fn kernel_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `ls[row_idx[i], col_idx[j]] -= sum_k ld[i, k] ld[j, k]` over the destination's lower
/// triangle (`i` over the `row_idx.len()` rows of `ld`, `j` over its first `col_idx.len()`
/// rows), through the gather/scatter kernel faer's supernodal factorisation
/// calls (`spicy_matmul` with a lower-triangular destination), with the same arguments.
///
/// # Safety
/// `ls` is column-major with `ls_rows` rows and holds every `(row_idx[i], col_idx[j])`; `ld`
/// holds `row_idx.len()` rows of `depth` columns with column stride `ld_stride`.
#[allow(clippy::too_many_arguments)]
unsafe fn update(
    ls: &mut [f64],
    ls_rows: usize,
    row_idx: &[usize],
    col_idx: &[usize],
    ld: &[f64],
    depth: usize,
    ld_stride: usize,
) {
    #[cfg(target_arch = "x86_64")]
    {
        use private_gemm_x86::{Accum, DType, DstKind, IType, InstrSet};
        let instr = if std::arch::is_x86_feature_detected!("avx512f") {
            InstrSet::Avx512
        } else {
            InstrSet::Avx256
        };
        let alpha = -1.0f64;
        // SAFETY: the caller's.
        unsafe {
            private_gemm_x86::gemm(
                DType::F64,
                IType::U64,
                instr,
                row_idx.len(),
                col_idx.len(),
                depth,
                ls.as_mut_ptr() as _,
                1,
                ls_rows as isize,
                row_idx.as_ptr() as _,
                col_idx.as_ptr() as _,
                DstKind::Lower,
                Accum::Add,
                ld.as_ptr() as _,
                1,
                ld_stride as isize,
                false,
                std::ptr::null(),
                0,
                ld.as_ptr() as _,
                ld_stride as isize,
                1,
                true,
                &raw const alpha as _,
                Par::Seq.degree(),
            );
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (ls, ls_rows, row_idx, col_idx, ld, depth, ld_stride);
        unreachable!("kernel_available is false");
    }
}
