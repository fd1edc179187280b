//! Forward and back substitution with a sparse Cholesky factor `L` (`P A P^T = L L^T`) for
//! three right-hand sides at once (the `x`, `y`, `z` columns of projective dynamics' global
//! step, Bouaziz et al. 2014, Sec. 4: "the system matrix is constant ... only back-substitution
//! is needed" per iteration), parallel over independent subtrees of the elimination tree.
//!
//! Layout: the factor's rows are renumbered so that a set of disjoint subtrees of the
//! elimination tree (the "groups") come first, each a contiguous range, and the remaining
//! nodes (their common ancestors, the "top") last. Row `i` of `L` only holds columns that are
//! descendants of `i`, and column `j` only rows that are ancestors of `j` (Liu 1990, "The role
//! of elimination trees in sparse factorization"), so
//! - forward (`L y = b`, column by column, scattering the column): the groups are independent,
//!   each adding its contributions to the top rows into a buffer of its own; then the top rows
//!   sum the buffers in group order and finish;
//! - back (`L^T x = y`, column by column from the last, a gather over the column): the top
//!   first, then the groups independently (they read only their own range and the top).
//!
//! Every value is computed by the same operations in the same order whatever the number of
//! threads: the results are bit-identical for any thread count. The right-hand side of each
//! row is a closure evaluated inside the forward pass, so a caller can fuse its assembly (the
//! local step's per-vertex gather) into the solve.

use rayon::prelude::*;

use crate::geom::Vec3;

/// A lower-triangular factor (strictly lower part by columns, plus the inverse diagonal),
/// renumbered for the subtree-parallel substitution (module docs).
#[derive(Clone, Debug, Default)]
pub struct TriangularFactor {
    n: usize,
    /// `perm[k]`: the original row (of `A`) of factor row `k`.
    perm: Vec<u32>,
    /// `inverse[i]`: the factor row of original row `i`.
    inverse: Vec<u32>,
    inv_diag: Vec<f64>,
    /// Strictly lower part by columns; column `k`'s entries before `col_mid[k]` are rows of
    /// its own group (stored relative to the group start), the rest top rows (relative to the
    /// first top row).
    col_ptr: Vec<u32>,
    col_mid: Vec<u32>,
    col_rows: Vec<u32>,
    col_vals: Vec<f64>,
    /// Group `g` is the row range `groups[g]..groups[g + 1]`; rows from the last entry on are
    /// the top.
    groups: Vec<u32>,
}

/// How finely [`TriangularFactor::new`] splits the elimination tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitParams {
    /// No splitting below this many stored entries (tiny systems run as one sequential pass).
    pub min_entries: usize,
    /// The tree is split until every subtree holds at most `1 / subtrees` of the work ...
    pub subtrees: usize,
    /// ... or the top holds this fraction of it.
    pub max_top: f64,
    /// Consecutive subtrees are merged into groups of about `1 / groups` of the work.
    pub groups: usize,
}

impl Default for SplitParams {
    fn default() -> Self {
        SplitParams {
            min_entries: 20_000,
            subtrees: 32,
            max_top: 0.5,
            groups: 8,
        }
    }
}

const NONE: u32 = u32::MAX;

impl TriangularFactor {
    /// The factor `L` of `P A P^T` given by columns: `perm[k]` is the original row of factor
    /// row `k`, `diag[j]` the diagonal of column `j`, `lower[j]` its entries `(row, value)`
    /// strictly below the diagonal (rows `> j`). Returns `None` if a diagonal is not positive
    /// or an entry is not below the diagonal.
    pub fn new(
        perm: &[usize],
        diag: &[f64],
        lower: &[Vec<(u32, f64)>],
        split: SplitParams,
    ) -> Option<TriangularFactor> {
        let n = diag.len();
        if perm.len() != n
            || lower.len() != n
            || diag
                .iter()
                .any(|d| d.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
        {
            return None;
        }
        if lower
            .iter()
            .enumerate()
            .any(|(j, c)| c.iter().any(|&(i, _)| i as usize <= j || i as usize >= n))
        {
            return None;
        }
        // Elimination tree: the parent of `j` is the first row below the diagonal of column j.
        let parent: Vec<u32> = lower
            .iter()
            .map(|c| c.iter().map(|e| e.0).min().unwrap_or(NONE))
            .collect();
        // Both substitutions go over the columns.
        let work: Vec<usize> = (0..n).map(|j| 1 + lower[j].len()).collect();
        let total: usize = work.iter().sum();
        // Subtree work (children precede parents).
        let mut sub = work.clone();
        for j in 0..n {
            if parent[j] != NONE {
                sub[parent[j] as usize] += sub[j];
            }
        }
        let mut child_ptr = vec![0usize; n + 1];
        for &p in &parent {
            if p != NONE {
                child_ptr[p as usize + 1] += 1;
            }
        }
        for j in 0..n {
            child_ptr[j + 1] += child_ptr[j];
        }
        let mut fill = child_ptr.clone();
        let mut children = vec![0u32; child_ptr[n]];
        for (j, &p) in parent.iter().enumerate() {
            if p != NONE {
                children[fill[p as usize]] = j as u32;
                fill[p as usize] += 1;
            }
        }
        // Split the heaviest subtree (its root joins the top) while it is too heavy.
        let mut top = vec![false; n];
        let mut candidates: Vec<u32> = (0..n as u32)
            .filter(|&j| parent[j as usize] == NONE)
            .collect();
        if total >= split.min_entries {
            let limit = total / split.subtrees.max(1);
            let max_top = (split.max_top * total as f64) as usize;
            let mut top_work = 0;
            let mut heap: std::collections::BinaryHeap<(usize, u32)> =
                candidates.iter().map(|&j| (sub[j as usize], j)).collect();
            while let Some(&(w, j)) = heap.peek() {
                if w <= limit || top_work + work[j as usize] > max_top {
                    break;
                }
                heap.pop();
                top[j as usize] = true;
                top_work += work[j as usize];
                for &c in &children[child_ptr[j as usize]..child_ptr[j as usize + 1]] {
                    heap.push((sub[c as usize], c));
                }
            }
            candidates = heap.into_iter().map(|(_, j)| j).collect();
            candidates.sort_unstable();
        } else {
            // One sequential pass: everything is "top".
            top.iter_mut().for_each(|t| *t = true);
            candidates.clear();
        }
        // New numbering: candidate subtrees (each ascending = topological), then the top.
        let mut order: Vec<u32> = Vec::with_capacity(n);
        let mut groups = vec![0u32];
        let task_work: usize = candidates.iter().map(|&j| sub[j as usize]).sum();
        let group_target = task_work / split.groups.max(1);
        let mut acc = 0;
        let mut stack = Vec::new();
        for &r in &candidates {
            let start = order.len();
            stack.push(r);
            while let Some(j) = stack.pop() {
                order.push(j);
                stack
                    .extend_from_slice(&children[child_ptr[j as usize]..child_ptr[j as usize + 1]]);
            }
            order[start..].sort_unstable();
            acc += sub[r as usize];
            if acc >= group_target {
                groups.push(order.len() as u32);
                acc = 0;
            }
        }
        if *groups.last().unwrap() as usize != order.len() {
            groups.push(order.len() as u32);
        }
        if groups.len() == 1 {
            groups.clear();
            groups.push(0);
        }
        order.extend((0..n as u32).filter(|&j| top[j as usize]));
        debug_assert_eq!(order.len(), n);
        let mut q = vec![0u32; n];
        for (k, &j) in order.iter().enumerate() {
            q[j as usize] = k as u32;
        }
        // Both storages in the new numbering; indices stored relative to where the solve
        // reads them (module docs): a group row's columns and a group column's own rows
        // relative to the group start, a column's top rows relative to `split`.
        let split = *groups.last().unwrap() as usize;
        let mut base = vec![split as u32; n];
        for g in groups.windows(2) {
            base[g[0] as usize..g[1] as usize].fill(g[0]);
        }
        let mut col_ptr = vec![0u32; n + 1];
        for (j, c) in lower.iter().enumerate() {
            col_ptr[q[j] as usize + 1] = c.len() as u32;
        }
        for k in 0..n {
            col_ptr[k + 1] += col_ptr[k];
        }
        let nnz = col_ptr[n] as usize;
        let mut col_rows = vec![0u32; nnz];
        let mut col_vals = vec![0.0; nnz];
        let mut col_mid = vec![0u32; n];
        let mut inv_diag = vec![0.0; n];
        for (j, c) in lower.iter().enumerate() {
            let k = q[j] as usize;
            inv_diag[k] = 1.0 / diag[j];
            let mut e: Vec<(u32, f64)> = c.iter().map(|&(i, v)| (q[i as usize], v)).collect();
            e.sort_unstable_by_key(|x| x.0);
            col_mid[k] = col_ptr[k];
            for (s, &(i, v)) in e.iter().enumerate() {
                let i = i as usize;
                if i <= k || (k < split && i < split && base[i] != base[k]) {
                    return None;
                }
                let at = col_ptr[k] as usize + s;
                if i < split {
                    col_rows[at] = (i - base[k] as usize) as u32;
                    col_mid[k] += 1;
                } else {
                    col_rows[at] = (i - split) as u32;
                }
                col_vals[at] = v;
            }
        }
        let new_perm: Vec<u32> = order.iter().map(|&j| perm[j as usize] as u32).collect();
        let mut inverse = vec![0u32; n];
        for (k, &i) in new_perm.iter().enumerate() {
            inverse[i as usize] = k as u32;
        }
        Some(TriangularFactor {
            n,
            perm: new_perm,
            inverse,
            inv_diag,
            col_ptr,
            col_mid,
            col_rows,
            col_vals,
            groups,
        })
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.n
    }

    /// Stored entries strictly below the diagonal.
    pub fn entries(&self) -> usize {
        self.col_rows.len()
    }

    /// The substitution's schedule: the number of independent groups, and the fractions of
    /// the work (stored entries) in the sequential top and in the largest group.
    pub fn schedule(&self) -> (usize, f64, f64) {
        let work = |a: usize, b: usize| (self.col_ptr[b] - self.col_ptr[a]) as usize + (b - a);
        let total = work(0, self.n).max(1) as f64;
        let split = *self.groups.last().unwrap_or(&0) as usize;
        let largest = self
            .groups
            .windows(2)
            .map(|g| work(g[0] as usize, g[1] as usize))
            .max()
            .unwrap_or(0);
        (
            self.groups.len().saturating_sub(1),
            work(split, self.n) as f64 / total,
            largest as f64 / total,
        )
    }

    /// Solves `A x = b` (`A = P^T L L^T P`) with `b[i] = rhs(i)` for original row `i`, into
    /// `out` (original order); `work` is scratch (resized).
    pub fn solve<F>(&self, rhs: F, out: &mut [Vec3], work: &mut Vec<Vec3>)
    where
        F: Fn(usize) -> Vec3 + Sync,
    {
        let n = self.n;
        let split = *self.groups.last().unwrap_or(&0) as usize;
        let top = n - split;
        let groups = self.groups.len().saturating_sub(1);
        // `work` = [y (n rows)] [one buffer of top-row contributions per group].
        work.clear();
        work.resize(n + groups * top, Vec3::zeros());
        let (y, buffers) = work.split_at_mut(n);
        let (low, high) = y.split_at_mut(split);
        // Forward, groups (column by column, scattering): a group's columns hold rows of the
        // group (updated in place) and top rows (summed into the group's own buffer).
        let mut pieces = Vec::with_capacity(groups);
        let mut rest = &mut *buffers;
        for piece in self.group_slices(low) {
            let (buf, tail) = rest.split_at_mut(top);
            pieces.push((piece, buf));
            rest = tail;
        }
        pieces.into_par_iter().for_each(|((lo, y), buf)| {
            for (kk, yk) in y.iter_mut().enumerate() {
                *yk = rhs(self.perm[lo + kk] as usize);
            }
            for kk in 0..y.len() {
                let k = lo + kk;
                let yk = y[kk] * self.inv_diag[k];
                y[kk] = yk;
                let (a, m, b) = (
                    self.col_ptr[k] as usize,
                    self.col_mid[k] as usize,
                    self.col_ptr[k + 1] as usize,
                );
                for (&i, &v) in self.col_rows[a..m].iter().zip(&self.col_vals[a..m]) {
                    y[i as usize] -= yk * v;
                }
                for (&i, &v) in self.col_rows[m..b].iter().zip(&self.col_vals[m..b]) {
                    buf[i as usize] -= yk * v;
                }
            }
        });
        // Forward, top: the groups' contributions in group order, then the top columns.
        for (kk, yk) in high.iter_mut().enumerate() {
            let mut acc = rhs(self.perm[split + kk] as usize);
            for g in 0..groups {
                acc += buffers[g * top + kk];
            }
            *yk = acc;
        }
        for kk in 0..top {
            let k = split + kk;
            let yk = high[kk] * self.inv_diag[k];
            high[kk] = yk;
            let r = self.col_ptr[k] as usize..self.col_ptr[k + 1] as usize;
            for (&i, &v) in self.col_rows[r.clone()].iter().zip(&self.col_vals[r]) {
                high[i as usize] -= yk * v;
            }
        }
        // Back, top (reads only the top).
        for kk in (0..top).rev() {
            let k = split + kk;
            let r = self.col_ptr[k] as usize..self.col_ptr[k + 1] as usize;
            let mut acc = high[kk];
            for (&i, &v) in self.col_rows[r.clone()].iter().zip(&self.col_vals[r]) {
                acc -= high[i as usize] * v;
            }
            high[kk] = acc * self.inv_diag[k];
        }
        // Back, groups: read their own range and the (final) top.
        let high = &*high;
        let pieces = self.group_slices(low);
        pieces.into_par_iter().for_each(|(lo, x)| {
            for kk in (0..x.len()).rev() {
                let k = lo + kk;
                let (a, m, b) = (
                    self.col_ptr[k] as usize,
                    self.col_mid[k] as usize,
                    self.col_ptr[k + 1] as usize,
                );
                let mut acc = x[kk];
                for (&i, &v) in self.col_rows[m..b].iter().zip(&self.col_vals[m..b]) {
                    acc -= high[i as usize] * v;
                }
                for (&i, &v) in self.col_rows[a..m].iter().zip(&self.col_vals[a..m]) {
                    acc -= x[i as usize] * v;
                }
                x[kk] = acc * self.inv_diag[k];
            }
        });
        let y = &work[..n];
        for (o, &k) in out.iter_mut().zip(&self.inverse) {
            *o = y[k as usize];
        }
    }

    fn group_slices<'a>(&self, mut low: &'a mut [Vec3]) -> Vec<(usize, &'a mut [Vec3])> {
        let mut pieces = Vec::with_capacity(self.groups.len());
        for g in self.groups.windows(2) {
            let (a, rest) = low.split_at_mut((g[1] - g[0]) as usize);
            pieces.push((g[0] as usize, a));
            low = rest;
        }
        pieces
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    /// A random lower-triangular factor with the structure of a Cholesky factor (column `j`'s
    /// rows are ancestors in a random tree), a random permutation, and its dense `A`.
    type Columns = Vec<Vec<(u32, f64)>>;

    fn random_factor(seed: u64, n: usize) -> (Vec<usize>, Vec<f64>, Columns) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let parent: Vec<Option<usize>> = (0..n)
            .map(|j| (j + 1 < n && rng.random_bool(0.95)).then(|| rng.random_range(j + 1..n)))
            .collect();
        let mut lower = vec![Vec::new(); n];
        for (j, col) in lower.iter_mut().enumerate() {
            // A random subset of the ancestors, always including the parent.
            let mut a = parent[j];
            let mut first = true;
            while let Some(p) = a {
                if first || rng.random_bool(0.3) {
                    col.push((p as u32, rng.random_range(-1.0..1.0)));
                }
                first = false;
                a = parent[p];
            }
        }
        let diag: Vec<f64> = (0..n).map(|_| rng.random_range(0.5..2.0)).collect();
        let mut perm: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            perm.swap(i, rng.random_range(0..=i));
        }
        (perm, diag, lower)
    }

    proptest! {
        /// The subtree-parallel solve equals a dense solve of `P^T L L^T P x = b` for every
        /// split (from one sequential pass to many small groups), and one thread gives the same
        /// bits as the pool.
        #[test]
        fn solve_matches_dense(seed in 0u64..500, n in 1usize..120, subtrees in 1usize..40,
                               groups in 1usize..10) {
            let (perm, diag, lower) = random_factor(seed, n);
            let mut l = DMatrix::<f64>::zeros(n, n);
            for j in 0..n {
                l[(j, j)] = diag[j];
                for &(i, v) in &lower[j] {
                    l[(i as usize, j)] = v;
                }
            }
            let mut p = DMatrix::<f64>::zeros(n, n);
            for (k, &i) in perm.iter().enumerate() {
                p[(k, i)] = 1.0;
            }
            let a = p.transpose() * &l * l.transpose() * &p;
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 7);
            let b: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
                .collect();
            let split = SplitParams { min_entries: 0, subtrees, max_top: 0.5, groups };
            let f = TriangularFactor::new(&perm, &diag, &lower, split).unwrap();
            let mut x = vec![Vec3::zeros(); n];
            let mut work = Vec::new();
            f.solve(|i| b[i], &mut x, &mut work);
            let lu = a.clone().lu();
            for c in 0..3 {
                let bc = nalgebra::DVector::from_iterator(n, b.iter().map(|v| v[c]));
                let want = lu.solve(&bc).unwrap();
                for i in 0..n {
                    let scale = 1.0 + want.amax();
                    prop_assert!((want[i] - x[i][c]).abs() <= 1e-8 * scale,
                        "row {i} coord {c}: {} vs {}", x[i][c], want[i]);
                }
            }
            // Same factor, one thread vs the pool: bit-identical.
            let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            let mut x1 = vec![Vec3::zeros(); n];
            pool.install(|| f.solve(|i| b[i], &mut x1, &mut Vec::new()));
            prop_assert_eq!(x1, x);
        }
    }

    #[test]
    fn splits_a_long_tree_into_groups() {
        // A balanced binary tree of 2^10 - 1 nodes: the top is small, the groups many.
        let n = 1023;
        let perm: Vec<usize> = (0..n).collect();
        let diag = vec![1.0; n];
        // Heap layout reversed so that parents have larger indices: node k's parent is
        // n - 1 - ((n - 1 - k) - 1) / 2.
        let lower: Vec<Vec<(u32, f64)>> = (0..n)
            .map(|k| {
                let h = n - 1 - k;
                if h == 0 {
                    Vec::new()
                } else {
                    vec![((n - 1 - (h - 1) / 2) as u32, 0.1)]
                }
            })
            .collect();
        let split = SplitParams {
            min_entries: 0,
            subtrees: 16,
            max_top: 0.25,
            groups: 4,
        };
        let f = TriangularFactor::new(&perm, &diag, &lower, split).unwrap();
        let (groups, top, largest) = f.schedule();
        assert!(groups >= 2, "{groups} groups");
        assert!(top < 0.05, "top fraction {top}");
        assert!(largest < 0.5, "largest group {largest}");
    }

    #[test]
    fn rejects_bad_factors() {
        let s = SplitParams::default();
        assert!(TriangularFactor::new(&[0, 1], &[1.0, 0.0], &[vec![], vec![]], s).is_none());
        assert!(
            TriangularFactor::new(&[0, 1], &[1.0, 1.0], &[vec![], vec![(0, 1.0)]], s).is_none()
        );
    }
}
