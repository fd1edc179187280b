//! A sparse Cholesky factorisation of a *scalar* matrix over the simulation nodes, applied to
//! each of the three coordinates: the constant global matrix of projective dynamics
//! (Bouaziz et al. 2014, Sec. 4, "the system matrix is constant ... pre-factored"), see
//! [`crate::sim::projective`].
//!
//! The symbolic analysis (approximate-minimum-degree ordering, supernodal structure) is done
//! once per sparsity pattern by the `faer` crate; numeric refactorisations (new rest shape, new
//! pin set) reuse it. `faer` is built without its `rayon` feature: the factorisation and each
//! double-precision solve run sequentially; a three-column solve is the `x` column and the
//! `y, z` pair side by side, always split the same way, so results are bit-identical for any
//! thread count. The single-precision solve of the projective global step's increments
//! ([`ScalarCholesky::solve_increment_with`]) is our own substitution on faer's supernodal
//! layout, the three coordinates as the lanes of one pass over the factor, each supernode's
//! rows below the diagonal block four at a time (faer's solve of one or two columns spends most
//! of its instructions outside the arithmetic at this size; branch sim9, BENCHMARKS.md), with
//! AVX two rows (forward) or two columns (backward) per 8-wide register, lane by lane the same
//! operations (branch sim11). With AVX, the forward step takes the rows below a block eight at
//! a time and the backward step the columns of a supernode of four or more columns eight at a
//! time, coordinate by coordinate (the `x`, `y`, `z` lanes of eight rows or columns in one
//! register each, so a column's or row's eight weights are one load; the backward step reads
//! a row-major copy of the rows below each such block, appended to the single-precision
//! factor), and the forward triangle two rows per register: the same operations per lane in
//! the same order, the same bits (branch sim12). Large
//! factors run it on two threads: the elimination tree is cut into a top and two parts of
//! hanging subtrees of about equal work, which are substituted side by side; the updates of
//! the top rows are logged and applied in supernode order, so every row sees the same
//! operations in the same order as in the sequential substitution (the same bits for any thread
//! count; branch sim10). The top's big supernodes are shared too: forward, their rows below
//! the diagonal block, backward, their columns' updates from those rows, in two shares run
//! side by side (each row or column still by one thread, with the same operations), the whole
//! substitution one task list that two workers take from with spin hand-offs, one rayon join
//! per solve (branch pd17). (A subtree-parallel substitution of our own in double precision, one
//! row at a time, was tried on branch sim7 and was not faster than faer's.)
//!
//! Pinned (fixed) nodes are eliminated: their rows and columns are replaced by the diagonal, so
//! that `S (B^-1 (x) I3) S` with the filter projection `S` is the exact inverse of the filtered
//! matrix `S (B (x) I3) S` on the free subspace.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use super::pcg::Filter;
use super::sparse::BsrPattern;
use crate::geom::Vec3;

/// Scratch of a solve: faer stacks for the `x` column and the `y, z` pair, and the `n x 3`
/// column-major right-hand-side buffer.
type SolveScratch = (MemBuffer, MemBuffer, Vec<f64>);

/// Scratch of the own single-precision solve: the permuted iterate, four lanes per row (the
/// right-hand sides are written straight into it), and the split's logs.
type LaneScratch = (Vec<[f32; 4]>, [Vec<[f32; 4]>; 2]);

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
    /// The same for the single-precision solves through faer (simplicial factors).
    solve_scratch32: std::sync::Mutex<(MemBuffer, MemBuffer, Vec<f32>)>,
    /// The supernodal layout of the factor for [`ScalarCholesky::solve_increment_with`]'s own
    /// solve (`None` for a simplicial factor, which faer solves).
    layout: Option<Layout>,
    /// Recomputes only the supernodes a matrix change reaches (`None`: simplicial factor or
    /// another product kernel; every factorisation is then a full one).
    partial: Option<super::refactor::PartialRefactor>,
    /// The matrix values of the held factor (to find the changed columns).
    prev_values: Vec<f64>,
    /// Supernodes recomputed by the last factorisation and their count (`None`: full).
    last_partial: Option<(usize, usize)>,
    /// Scratch of the own solve: the permuted iterate, four lanes (`x`, `y`, `z`, unused) per
    /// row, and the split's logs.
    lanes: std::sync::Mutex<LaneScratch>,
}

/// One supernode of faer's supernodal factor: columns `start..start + size` of the permuted
/// matrix, stored column-major from `values[val..]` with `size + m` rows per column (the
/// diagonal block, whose lower triangle holds `L`, then the rows `rows[pat..pat + m]`).
#[derive(Clone, Copy, Debug)]
struct Supernode {
    start: usize,
    size: usize,
    val: usize,
    pat: usize,
    m: usize,
    /// Where the rows below the diagonal block start in row-major order (`m` rows of `size`
    /// values, each padded with zeros to [`row_stride`]) in the values given to the solve,
    /// after the factor's own values; only for supernodes of [`BLOCK_COLUMNS`] and more
    /// columns (else `usize::MAX`).
    tval: usize,
}

/// Supernodes of at least this many columns have the AVX backward step's rows below the
/// diagonal block done eight columns at a time, coordinate by coordinate, from a row-major
/// copy ([`backward_cols8`]); those with fewer columns have no copy.
const BLOCK_COLUMNS: usize = 4;

/// Values per row of the row-major copy of a supernode of `size` columns (whole blocks of
/// eight).
fn row_stride(size: usize) -> usize {
    size.next_multiple_of(8)
}

/// A supernode's block of factor values and the iterate's rows, as the pieces of its
/// substitution steps read and write them ([`Layout::forward_triangle`],
/// [`Layout::forward_below`], [`Layout::backward_below`], [`Layout::backward_triangle`]): raw
/// pointers, no bounds checks, the accessors inlined into their (AVX) caller.
#[derive(Clone, Copy)]
struct NodeView {
    /// Values per column of the block: the diagonal block's `size`, then the `m` rows below.
    ld: usize,
    /// Columns of the supernode.
    size: usize,
    /// Its first column (and row of the iterate).
    start: usize,
    /// The block, column-major (`ld * size` values).
    bp: *const f32,
    /// The iterate, a row per matrix row.
    xp: *mut [f32; 4],
}

impl NodeView {
    /// The view of supernode `s`, whose block is in `l` (checked here), with the iterate `xp`.
    ///
    /// # Safety
    /// As [`Layout::run`]; and the caller passes to [`NodeView::at`], [`NodeView::put`] and
    /// [`NodeView::row`] only rows below `n` (the supernode's columns and its rows below,
    /// which `Layout::new` checked), to [`NodeView::w`] and [`NodeView::wp`] only `(c, r)` with
    /// `c < size` and `r < ld`, and reads no further through `wp` than the block's end.
    #[inline(always)]
    unsafe fn new(l: &[f32], xp: *mut [f32; 4], s: &Supernode) -> NodeView {
        let ld = s.size + s.m;
        let block = &l[s.val..s.val + ld * s.size];
        NodeView {
            ld,
            size: s.size,
            start: s.start,
            bp: block.as_ptr(),
            xp,
        }
    }

    /// Row `i` of the iterate.
    #[inline(always)]
    fn at(self, i: usize) -> Lane {
        // SAFETY: `NodeView::new`'s caller's (`i < n`).
        unsafe { Lane::load(self.xp.add(i)) }
    }

    /// Writes row `i` of the iterate.
    #[inline(always)]
    fn put(self, i: usize, v: Lane) {
        // SAFETY: `NodeView::new`'s caller's (`i < n`).
        unsafe { v.store(self.xp.add(i)) }
    }

    /// The block's value in column `c`, row `r`.
    #[inline(always)]
    fn w(self, c: usize, r: usize) -> f32 {
        debug_assert!(c < self.size && r < self.ld);
        // SAFETY: `NodeView::new`'s caller's (`c * ld + r < ld * size`).
        unsafe { *self.bp.add(c * self.ld + r) }
    }

    /// Where row `i` of the iterate is (for the AVX loops).
    ///
    /// # Safety
    /// `i < n`.
    #[inline(always)]
    unsafe fn row(self, i: usize) -> *mut [f32; 4] {
        // SAFETY: the caller's.
        unsafe { self.xp.add(i) }
    }

    /// Where the block's value in column `c`, row `r` is (for the AVX loops, which load
    /// several adjacent values).
    ///
    /// # Safety
    /// `c < size` and `r < ld`.
    #[inline(always)]
    unsafe fn wp(self, c: usize, r: usize) -> *const f32 {
        debug_assert!(c < self.size && r < self.ld);
        // SAFETY: the caller's.
        unsafe { self.bp.add(c * self.ld + r) }
    }
}

/// faer's supernodal structure in plain arrays, with the fill-reducing permutation.
#[derive(Debug)]
struct Layout {
    nodes: Vec<Supernode>,
    rows: Vec<u32>,
    /// Row `i` of the permuted system is row `fwd[i]` of the original one.
    fwd: Vec<u32>,
    /// The permuted row of each original row (the inverse of `fwd`).
    inv: Vec<u32>,
    /// The supernode holding each permuted row.
    owner: Vec<u32>,
    /// The parent of each supernode in the elimination tree (the one holding its first row
    /// below the diagonal block), `u32::MAX` at a root.
    parent: Vec<u32>,
    /// The two-thread schedule of the substitutions (`None`: sequential).
    split: Option<Split>,
}

/// A two-thread schedule of the substitutions along the supernodal elimination tree (the
/// parent of a supernode is the one holding its first row below the diagonal block; every row
/// below a supernode's diagonal block belongs to one of its ancestors). The tree is cut into a
/// *top* (a set of supernodes closed under taking ancestors) and the subtrees hanging below it,
/// which are dealt to two *parts* of about equal work. Forward: the two parts run side by side,
/// each updating the rows of its own supernodes in place and writing the updates of top rows to
/// a log; then, in supernode order, the top supernodes run and the logged updates are applied.
/// Backward: the top supernodes in reverse order, then the two parts side by side. A row's
/// updates are thus subtracted one by one in supernode order, exactly as in the sequential
/// substitution: the same bits for any thread count. The top phases are shared between the
/// two threads supernode by supernode ([`Split::tasks`]).
#[derive(Debug)]
struct Split {
    /// The supernodes of each part, ascending.
    parts: [Vec<u32>; 2],
    /// The top supernodes, ascending.
    top: Vec<u32>,
    /// Per supernode of a part: how many of its rows below the diagonal block belong to its
    /// own part (a prefix; the others are top rows).
    own: Vec<u32>,
    /// Per supernode of a part: where its logged updates start in its part's log.
    log_at: Vec<u32>,
    /// Length of each part's log.
    log_len: [usize; 2],
    /// The forward top phase in supernode order: `(supernode, part)`, part 2 = top (run it),
    /// 0 or 1 = apply its logged updates from that part's log.
    merge: Vec<(u32, u8)>,
    /// The two-thread schedule ([`Split::tasks`]).
    tasks: Vec<Step>,
    /// Per part, the permuted rows (ranges `start..end`) whose right-hand side it evaluates
    /// before its forward phase and whose solution it writes out after its backward phase: the
    /// rows of its own supernodes, and a share of the top's rows (dealt supernode by supernode
    /// to the part with the lighter estimated load, see [`RHS_ROW_COST`]).
    rows_of: [Vec<(u32, u32)>; 2],
}

/// Estimated cost of evaluating one right-hand-side row, in factor entries of a substitution
/// (for dealing the top's rows to the parts only: ~370 instructions per row of the projective
/// global step's residual against ~8.5 per factor entry and substitution).
const RHS_ROW_COST: usize = 40;

/// Most subtree expansions tried when the schedule of [`Split`] is chosen.
const SPLIT_EXPANSIONS: usize = 256;
/// A split is used only if its estimated time is below this fraction of the sequential one.
const SPLIT_GAIN: f64 = 0.85;
/// Factor entries below which the substitutions stay sequential (too little work to share).
const SPLIT_MIN_WORK: usize = 20_000;
/// Per-supernode overhead of a substitution step, in factor entries (for the schedule only).
const NODE_COST: usize = 8;

/// A raw pointer to rows (of the iterate, a log, a solution or its saved copy) written from
/// the two parts of a split substitution, which access disjoint rows (see [`Split`]): every
/// user promises that no two threads touch the same row at once.
#[derive(Clone, Copy)]
pub(crate) struct DisjointRows<T>(pub(crate) *mut T);
// SAFETY: the two parts of a split substitution access disjoint rows (see `Split`).
unsafe impl<T> Send for DisjointRows<T> {}
// SAFETY: as above.
unsafe impl<T> Sync for DisjointRows<T> {}

impl<T> DisjointRows<T> {
    /// Row `k` (a method, so closures capture the `Sync` wrapper, not the raw pointer).
    pub(crate) fn at(self, k: usize) -> *mut T {
        self.0.wrapping_add(k)
    }
}

/// The rows of the iterate or a log of a substitution.
type Rows = DisjointRows<[f32; 4]>;

/// One phase of a (split) substitution, see [`Split`].
#[derive(Clone, Copy)]
enum Phase<'a> {
    /// The whole sequential substitution.
    All,
    /// Forward over the marked supernodes only, in order (the others have zero right-hand
    /// sides and receive no updates: see [`Layout::solve_sparse`]).
    ForwardMarked(&'a [bool]),
    /// Backward over all supernodes.
    BackwardAll,
    /// Forward over part `0` or `1`, logging top updates to the pointer.
    ForwardPart(usize, Rows),
    /// The forward top phase's merge entries `merge` (see [`Split::merge`]), with the two
    /// parts' logs; the last entry is a top supernode, of whose rows below only those in
    /// `rows` are updated.
    ForwardTop([Rows; 2], (u32, u32), (u32, u32)),
    /// The rows `.1` below top supernode `.0`'s diagonal block, forward.
    ForwardRows(u32, (u32, u32)),
    /// The updates of top supernode `.0`'s columns `.1` from the rows below, backward.
    BackwardCols(u32, (u32, u32)),
    /// The triangle of top supernode `.0`, backward.
    BackwardTriangle(u32),
    /// Backward over the top supernodes.
    BackwardTop,
    /// Backward over part `0` or `1`.
    BackwardPart(usize),
}

impl Layout {
    fn new(symbolic: &SymbolicCholesky<usize>, n: usize) -> Option<Layout> {
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return None;
        };
        let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
        let (row_ptr, val_ptr) = (sn.col_ptr_for_row_idx(), sn.col_ptr_for_val());
        let mut nodes = Vec::with_capacity(sn.n_supernodes());
        // The row-major copies follow the factor's values.
        let mut tval = val_ptr[sn.n_supernodes()];
        for s in 0..sn.n_supernodes() {
            let size = end[s] - begin[s];
            let len = val_ptr[s + 1] - val_ptr[s];
            // The block is (size + m) x size.
            let m = (len / size.max(1)).checked_sub(size)?;
            if size == 0 || len != (size + m) * size || row_ptr[s] + m > sn.row_idx().len() {
                return None;
            }
            nodes.push(Supernode {
                start: begin[s],
                size,
                val: val_ptr[s],
                pat: row_ptr[s],
                m,
                tval: if size >= BLOCK_COLUMNS {
                    tval += row_stride(size) * m;
                    tval - row_stride(size) * m
                } else {
                    usize::MAX
                },
            });
        }
        if nodes.iter().any(|s| s.start + s.size > n) || sn.row_idx().iter().any(|&r| r >= n) {
            return None;
        }
        let rows: Vec<u32> = sn.row_idx().iter().map(|&r| r as u32).collect();
        let fwd: Vec<u32> = match symbolic.perm() {
            Some(p) => p.arrays().0.iter().map(|&i| i as u32).collect(),
            None => (0..n as u32).collect(),
        };
        let mut inv = vec![u32::MAX; n];
        for (k, &i) in fwd.iter().enumerate() {
            *inv.get_mut(i as usize)? = k as u32;
        }
        let mut owner = vec![u32::MAX; n];
        for (k, s) in nodes.iter().enumerate() {
            owner[s.start..s.start + s.size].fill(k as u32);
        }
        if inv.contains(&u32::MAX) || owner.contains(&u32::MAX) {
            return None;
        }
        let parent: Vec<u32> = nodes
            .iter()
            .map(|s| {
                if s.m == 0 {
                    u32::MAX
                } else {
                    owner[rows[s.pat] as usize]
                }
            })
            .collect();
        // Every row below a diagonal block belongs to a later supernode (an ancestor).
        if parent
            .iter()
            .enumerate()
            .any(|(k, &p)| p != u32::MAX && p as usize <= k)
        {
            return None;
        }
        let split = Split::new(&nodes, &rows, n);
        Some(Layout {
            nodes,
            rows,
            fwd,
            inv,
            owner,
            parent,
            split,
        })
    }

    /// Appends to the single-precision factor values `l` the row-major copies of the rows below
    /// the diagonal blocks of the supernodes that have one (see [`Supernode::tval`]).
    fn append_row_major(&self, l: &mut Vec<f32>) {
        let base = l.len();
        let end = self
            .nodes
            .iter()
            .filter(|s| s.tval != usize::MAX)
            .map(|s| s.tval + row_stride(s.size) * s.m)
            .max()
            .unwrap_or(base);
        assert!(
            self.nodes
                .iter()
                .all(|s| s.tval == usize::MAX || s.tval >= base),
            "the copies follow the factor's values"
        );
        l.resize(end, 0.0);
        for s in 0..self.nodes.len() {
            self.copy_row_major(l, s);
        }
    }

    /// Writes the row-major copy of supernode `s` (if it has one) from its values in `l`
    /// (the single-precision factor values followed by the copies, see
    /// [`Layout::append_row_major`]).
    fn copy_row_major(&self, l: &mut [f32], s: usize) {
        let s = &self.nodes[s];
        if s.tval == usize::MAX {
            return;
        }
        let (ld, stride) = (s.size + s.m, row_stride(s.size));
        let (factor, copies) = l.split_at_mut(s.tval);
        let out = &mut copies[..stride * s.m];
        let block = &factor[s.val..s.val + ld * s.size];
        for (c, col) in block.chunks_exact(ld).enumerate() {
            for (o, &v) in out.iter_mut().skip(c).step_by(stride).zip(&col[s.size..]) {
                *o = v;
            }
        }
    }

    /// Solves `L L^T x = b` in place for the permuted right-hand sides `x` (four lanes per row:
    /// the coordinates) with the factor values `l`. Per supernode, forward: the dense triangle
    /// of the diagonal block, then the rows below four at a time, each row's update summed over
    /// the block's columns before it is subtracted; backward, in reverse: the rows below four
    /// at a time subtracted from the block's columns, then the triangle. Every factor value is
    /// read once per substitution for all three coordinates. With a [`Split`], on two threads
    /// (the same operations per row in the same order). `logs`: scratch of the split.
    ///
    /// Row `k` of `x` is first set to `rhs(fwd[k])` (the right-hand side's row in the original
    /// order), and at the end `emit(fwd[k], x[k])` is called once per row; with a split, both
    /// inside the parts' parallel phases (each part the rows of [`Split::rows_of`]), so `emit`
    /// is called from two threads at once, on distinct rows.
    fn solve(
        &self,
        l: &[f32],
        x: &mut [[f32; 4]],
        logs: &mut [Vec<[f32; 4]>; 2],
        rhs: impl Fn(usize) -> [f32; 4] + Sync,
        emit: impl Fn(usize, [f32; 4]) + Sync,
    ) {
        self.assert_fits(l, x);
        let Some(split) = &self.split else {
            let fwd = &self.fwd;
            x.par_chunks_mut(RHS_CHUNK).enumerate().for_each(|(c, xs)| {
                for (k, o) in xs.iter_mut().enumerate() {
                    *o = rhs(fwd[c * RHS_CHUNK + k] as usize);
                }
            });
            let xp = DisjointRows(x.as_mut_ptr());
            // SAFETY: `x` has a row per matrix row (asserted), one thread.
            unsafe { self.run(l, xp, Phase::All) };
            for (xi, &f) in x.iter().zip(fwd) {
                emit(f as usize, *xi);
            }
            return;
        };
        let xp = DisjointRows(x.as_mut_ptr());
        // The rows of part `p`: written (rhs) before its forward phase, read (emit) after its
        // backward phase; the parts' row sets are disjoint and cover all rows.
        let fill = |p: usize| {
            for &(a, b) in &split.rows_of[p] {
                for k in a as usize..b as usize {
                    // SAFETY: `k` < n (`Split::new` takes the ranges from the supernodes,
                    // which `Layout::new` checked); no other thread accesses row `k` now.
                    unsafe { *xp.at(k) = rhs(self.fwd[k] as usize) };
                }
            }
        };
        let out = |p: usize| {
            for &(a, b) in &split.rows_of[p] {
                for k in a as usize..b as usize {
                    // SAFETY: as in `fill`; rows are only read in the backward parts.
                    emit(self.fwd[k] as usize, unsafe { *xp.at(k) });
                }
            }
        };
        for (log, &len) in logs.iter_mut().zip(&split.log_len) {
            log.resize(len, [0.0; 4]);
        }
        let lp = [
            DisjointRows(logs[0].as_mut_ptr()),
            DisjointRows(logs[1].as_mut_ptr()),
        ];
        let tasks = &split.tasks;
        let done: Vec<AtomicBool> = tasks.iter().map(|_| AtomicBool::new(false)).collect();
        let next = AtomicUsize::new(0);
        // Waits until the first `upto` tasks are done (`seen`: how many are known done).
        let wait = |upto: usize, seen: &mut usize| {
            let mut spins = 0u32;
            while *seen < upto {
                if done[*seen].load(Ordering::Acquire) {
                    *seen += 1;
                } else if spins < SPIN_LIMIT {
                    spins += 1;
                    std::hint::spin_loop();
                } else {
                    std::thread::yield_now();
                }
            }
        };
        // Takes the next task until none is left; either thread may run any task, so one
        // worker alone runs them all in order.
        let worker = || {
            let mut seen = 0;
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(t) = tasks.get(i) else {
                    break;
                };
                wait(t.after as usize, &mut seen);
                // SAFETY: `x` has a row per matrix row and the logs their parts' lengths; a
                // task starts when those it depends on are done (`Step::after`), and two tasks
                // running side by side write disjoint rows and logs and read no rows the other
                // writes (see `Split::tasks`).
                unsafe {
                    match t.task {
                        Task::ForwardPart(p) => {
                            fill(p as usize);
                            self.run(l, xp, Phase::ForwardPart(p as usize, lp[p as usize]));
                        }
                        Task::ForwardTop(merge, rows) => {
                            self.run(l, xp, Phase::ForwardTop(lp, merge, rows))
                        }
                        Task::ForwardRows(k, rows) => self.run(l, xp, Phase::ForwardRows(k, rows)),
                        Task::BackwardCols(k, cols) => {
                            self.run(l, xp, Phase::BackwardCols(k, cols))
                        }
                        Task::BackwardTop(k, cols) => {
                            self.run(l, xp, Phase::BackwardCols(k, cols));
                            wait(i, &mut seen);
                            self.run(l, xp, Phase::BackwardTriangle(k));
                        }
                        Task::BackwardPart(p) => {
                            self.run(l, xp, Phase::BackwardPart(p as usize));
                            out(p as usize);
                        }
                    }
                }
                done[i].store(true, Ordering::Release);
            }
        };
        rayon::join(worker, worker);
    }

    /// The substitutions' preconditions (their unsafe row and value accesses rely on them): a
    /// row of `x` per matrix row, and `l` holding every supernode's values and row-major copy.
    fn assert_fits(&self, l: &[f32], x: &[[f32; 4]]) {
        assert_eq!(x.len(), self.fwd.len(), "one row per matrix row");
        assert!(
            self.nodes
                .last()
                .is_none_or(|s| s.val + (s.size + s.m) * s.size <= l.len()),
            "factor values of the layout"
        );
        assert!(
            self.nodes
                .iter()
                .all(|s| s.tval == usize::MAX || s.tval + row_stride(s.size) * s.m <= l.len()),
            "row-major copies of the layout"
        );
    }

    /// [`Layout::solve`] for a right-hand side that is zero outside the original rows `rows`
    /// (`rhs` is asked for those only; repeats are harmless): the forward substitution runs only
    /// over the supernodes holding such a row and their ancestors (the others would subtract
    /// zero updates from zero rows: every row of theirs stays `+0` and every update they send
    /// is `+0`, so skipping them leaves every row's bits unchanged), the backward one over all
    /// (with the split's two parts side by side). The same bits as [`Layout::solve`] with the
    /// zero rows given. `marked`: scratch.
    fn solve_sparse(
        &self,
        l: &[f32],
        x: &mut [[f32; 4]],
        marked: &mut Vec<bool>,
        rows: &[usize],
        rhs: impl Fn(usize) -> [f32; 4],
        emit: impl Fn(usize, [f32; 4]) + Sync,
    ) {
        self.assert_fits(l, x);
        x.fill([0.0; 4]);
        marked.clear();
        marked.resize(self.nodes.len(), false);
        for &i in rows {
            let k = self.inv[i] as usize;
            x[k] = rhs(i);
            let mut s = self.owner[k];
            while s != u32::MAX && !marked[s as usize] {
                marked[s as usize] = true;
                s = self.parent[s as usize];
            }
        }
        let xp = DisjointRows(x.as_mut_ptr());
        // SAFETY: `x` has a row per matrix row (asserted); the forward phase runs on this
        // thread alone, the backward phases as in `Layout::solve` (the parts write disjoint rows).
        unsafe {
            self.run(l, xp, Phase::ForwardMarked(marked));
            let Some(split) = &self.split else {
                self.run(l, xp, Phase::BackwardAll);
                for (k, &f) in self.fwd.iter().enumerate() {
                    emit(f as usize, *xp.at(k));
                }
                return;
            };
            let out = |p: usize| {
                for &(a, b) in &split.rows_of[p] {
                    for k in a as usize..b as usize {
                        emit(self.fwd[k] as usize, *xp.at(k));
                    }
                }
            };
            self.run(l, xp, Phase::BackwardTop);
            rayon::join(
                || {
                    self.run(l, xp, Phase::BackwardPart(0));
                    out(0)
                },
                || {
                    self.run(l, xp, Phase::BackwardPart(1));
                    out(1)
                },
            );
        }
    }

    /// Runs `phase` of the substitution, with AVX when the CPU has it.
    ///
    /// # Safety
    /// `xp` points to a row per matrix row, the phase's logs to their lengths; no other
    /// thread accesses the rows this phase writes, or writes the rows it reads.
    unsafe fn run(&self, l: &[f32], xp: Rows, phase: Phase<'_>) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX (checked above); the rest is the caller's.
            return unsafe { self.run_avx(l, xp, phase) };
        }
        // SAFETY: the caller's.
        unsafe { self.run_lanes::<false>(l, xp, phase) }
    }

    /// [`Layout::run`] compiled for AVX (VEX encodings, broadcasts from memory), two rows'
    /// lanes per 8-wide register in the loops over the rows below the diagonal blocks (see
    /// [`Wide`]): the same operations on every lane in the same order, so the same bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn run_avx(&self, l: &[f32], xp: Rows, phase: Phase<'_>) {
        // SAFETY: the caller's; the CPU has AVX (this function's feature).
        unsafe { self.run_lanes::<true>(l, xp, phase) }
    }

    /// The substitution phases; `WIDE`: the loops over the rows below the diagonal blocks with
    /// [`Wide`] (only inside a function compiled for AVX).
    #[inline(always)]
    unsafe fn run_lanes<const WIDE: bool>(&self, l: &[f32], xp: Rows, phase: Phase<'_>) {
        let nodes = &self.nodes;
        // SAFETY (all calls below): the caller's, and `Layout::new`/`Split::new` checked the
        // indices.
        unsafe {
            match phase {
                Phase::All => {
                    for s in nodes {
                        self.forward::<WIDE>(l, xp.0, s, s.m, std::ptr::null_mut());
                    }
                    for s in nodes.iter().rev() {
                        self.backward::<WIDE>(l, xp.0, s);
                    }
                }
                Phase::ForwardMarked(marked) => {
                    for (s, _) in nodes.iter().zip(marked).filter(|(_, &k)| k) {
                        self.forward::<WIDE>(l, xp.0, s, s.m, std::ptr::null_mut());
                    }
                }
                Phase::BackwardAll => {
                    for s in nodes.iter().rev() {
                        self.backward::<WIDE>(l, xp.0, s);
                    }
                }
                Phase::ForwardPart(part, log) => {
                    let sp = self.split.as_ref().expect("split");
                    for &k in &sp.parts[part] {
                        let k = k as usize;
                        let lg = log.0.add(sp.log_at[k] as usize);
                        self.forward::<WIDE>(l, xp.0, &nodes[k], sp.own[k] as usize, lg);
                    }
                }
                Phase::ForwardTop(logs, (a, b), (r0, r1)) => {
                    let sp = self.split.as_ref().expect("split");
                    for &(k, part) in &sp.merge[a as usize..b as usize] {
                        let (k, part) = (k as usize, part as usize);
                        let s = &nodes[k];
                        if part == 2 {
                            // (Only the last entry is a top supernode.)
                            let v = NodeView::new(l, xp.0, s);
                            self.forward_triangle::<WIDE>(v);
                            let rows = r0 as usize..r1 as usize;
                            let null = std::ptr::null_mut();
                            self.forward_below::<WIDE>(v, s, rows, s.m, null);
                            continue;
                        }
                        let own = sp.own[k] as usize;
                        let lg = logs[part].0.add(sp.log_at[k] as usize);
                        for (j, &i) in self.rows[s.pat + own..s.pat + s.m].iter().enumerate() {
                            let p = xp.0.add(i as usize);
                            Lane::load(p).sub(Lane::load(lg.add(j))).store(p);
                        }
                    }
                }
                Phase::ForwardRows(k, (r0, r1)) => {
                    let (s, null) = (&nodes[k as usize], std::ptr::null_mut());
                    let rows = r0 as usize..r1 as usize;
                    self.forward_below::<WIDE>(NodeView::new(l, xp.0, s), s, rows, s.m, null);
                }
                Phase::BackwardCols(k, (c0, c1)) => {
                    let (s, cols) = (&nodes[k as usize], c0 as usize..c1 as usize);
                    self.backward_below::<WIDE>(l, NodeView::new(l, xp.0, s), s, cols);
                }
                Phase::BackwardTriangle(k) => {
                    self.backward_triangle::<WIDE>(NodeView::new(l, xp.0, &nodes[k as usize]));
                }
                Phase::BackwardTop => {
                    let sp = self.split.as_ref().expect("split");
                    for &k in sp.top.iter().rev() {
                        self.backward::<WIDE>(l, xp.0, &nodes[k as usize]);
                    }
                }
                Phase::BackwardPart(part) => {
                    let sp = self.split.as_ref().expect("split");
                    for &k in sp.parts[part].iter().rev() {
                        self.backward::<WIDE>(l, xp.0, &nodes[k as usize]);
                    }
                }
            }
        }
    }

    /// The forward step of supernode `s`: the dense triangle, then the rows below; the updates
    /// of the first `own` rows below are subtracted in place, those of the others written to
    /// `log` in row order.
    ///
    /// # Safety
    /// As [`Layout::run`]; `log` has room for `s.m - own` rows.
    #[inline(always)]
    unsafe fn forward<const WIDE: bool>(
        &self,
        l: &[f32],
        xp: *mut [f32; 4],
        s: &Supernode,
        own: usize,
        log: *mut [f32; 4],
    ) {
        // SAFETY: the caller's.
        unsafe {
            let v = NodeView::new(l, xp, s);
            self.forward_triangle::<WIDE>(v);
            self.forward_below::<WIDE>(v, s, 0..s.m, own, log);
        }
    }

    /// The dense triangle of the forward step of `v`'s supernode (its columns solved).
    ///
    /// # Safety
    /// As [`NodeView::new`] for `v` (the rows read and written are the columns, the weights
    /// those of the diagonal block).
    #[inline(always)]
    unsafe fn forward_triangle<const WIDE: bool>(&self, v: NodeView) {
        let (size, start) = (v.size, v.start);
        for c in 0..size {
            let xc = v.at(start + c).div(v.w(c, c));
            v.put(start + c, xc);
            let mut r = c + 1;
            #[cfg(target_arch = "x86_64")]
            if WIDE {
                // The same updates two rows per 8-wide register (rows `start + r` and
                // `start + r + 1` are adjacent, and so are their weights in column `c`).
                // SAFETY: `run_avx` (the only caller with `WIDE`) has AVX; the reads and writes
                // are those of `v.w`, `v.at` and `v.put` below (`r + 1 < size`).
                unsafe {
                    let xw = Wide::broadcast(v.row(start + c));
                    while r + 4 <= size {
                        let (p, wr) = (v.row(start + r), v.wp(c, r));
                        let a = Wide::load(p).sub(Wide::pair(wr).mul(xw));
                        let b = Wide::load(p.add(2)).sub(Wide::pair(wr.add(2)).mul(xw));
                        a.store(p);
                        b.store(p.add(2));
                        r += 4;
                    }
                    if r + 2 <= size {
                        let p = v.row(start + r);
                        Wide::load(p).sub(Wide::pair(v.wp(c, r)).mul(xw)).store(p);
                        r += 2;
                    }
                }
            }
            for r in r..size {
                v.put(start + r, v.at(start + r).sub_scaled(v.w(c, r), xc));
            }
        }
    }

    /// The rows `rows` below supernode `s`'s diagonal block in its forward step (its columns
    /// solved): each row's update, summed over the block's columns, subtracted in place for
    /// the rows before `own`, written to `log` (at `q - own`) for the others. Every row gets
    /// the same operations whatever the range, as long as `rows.start` is a multiple of 8.
    ///
    /// # Safety
    /// As [`NodeView::new`] for `v`, the view of `s` (the rows read and written are the
    /// columns and the rows below, the weights `(c, size + q)` with `q < m`); `rows` inside
    /// `0..s.m`; `log` has room for `s.m - own` rows.
    #[inline(always)]
    unsafe fn forward_below<const WIDE: bool>(
        &self,
        v: NodeView,
        s: &Supernode,
        rows: std::ops::Range<usize>,
        own: usize,
        log: *mut [f32; 4],
    ) {
        let (size, start) = (v.size, v.start);
        let pat = &self.rows[s.pat..s.pat + s.m];
        let m = rows.end;
        debug_assert!(rows.start % 8 == 0 && m <= s.m);
        // Row `q` below the block: in place, or logged.
        let update = |q: usize, acc: Lane| {
            if q < own {
                let i = pat[q] as usize;
                v.put(i, v.at(i).sub(acc));
            } else {
                // SAFETY: the caller's (`q - own < s.m - own`).
                unsafe { acc.store(log.add(q - own)) }
            }
        };
        let mut q = rows.start;
        #[cfg(target_arch = "x86_64")]
        if WIDE {
            // The same sums as below, eight rows at a time coordinate by coordinate (the
            // rows' weights in column `c` are adjacent: one load per column and coordinate).
            while q + 8 <= m {
                // SAFETY: `run_avx` (the only caller with `WIDE`) has AVX; the reads are those
                // of `v.w` and `v.at` below for rows `q..q + 8` (`q + 8 <= m`).
                let acc = unsafe { forward_rows8(v.wp(0, size + q), v.ld, size, v.row(start)) };
                for (k, a) in acc.iter().enumerate() {
                    update(q + k, *a);
                }
                q += 8;
            }
            // Rows `q, q + 1` and `q + 2, q + 3` in the halves of two 8-wide accumulators.
            while q + 4 <= m {
                // SAFETY: `run_avx` (the only caller with `WIDE`) has AVX; the reads are those
                // of `v.w` and `v.at` below.
                let acc = unsafe {
                    let mut acc = [Wide::zero(); 2];
                    for c in 0..size {
                        let xc = Wide::broadcast(v.row(start + c));
                        let wq = v.wp(c, size + q);
                        acc[0] = acc[0].add(Wide::spread(wq, 0).mul(xc));
                        acc[1] = acc[1].add(Wide::spread(wq, 2).mul(xc));
                    }
                    [acc[0].low(), acc[0].high(), acc[1].low(), acc[1].high()]
                };
                for (k, a) in acc.iter().enumerate() {
                    update(q + k, *a);
                }
                q += 4;
            }
        }
        while q + 4 <= m {
            let mut acc = [Lane::zero(); 4];
            for c in 0..size {
                let xc = v.at(start + c);
                for (k, a) in acc.iter_mut().enumerate() {
                    *a = a.add_scaled(v.w(c, size + q + k), xc);
                }
            }
            for (k, a) in acc.iter().enumerate() {
                update(q + k, *a);
            }
            q += 4;
        }
        for q in q..m {
            let mut acc = Lane::zero();
            for c in 0..size {
                acc = acc.add_scaled(v.w(c, size + q), v.at(start + c));
            }
            update(q, acc);
        }
    }

    /// The backward step of supernode `s`: the rows below, then the triangle.
    ///
    /// # Safety
    /// As [`Layout::run`].
    #[inline(always)]
    unsafe fn backward<const WIDE: bool>(&self, l: &[f32], xp: *mut [f32; 4], s: &Supernode) {
        // SAFETY: the caller's.
        unsafe {
            let v = NodeView::new(l, xp, s);
            self.backward_below::<WIDE>(l, v, s, 0..s.size);
            self.backward_triangle::<WIDE>(v);
        }
    }

    /// The updates of supernode `s`'s columns `cols` from the rows below its diagonal block in
    /// its backward step. Every column gets the same operations whatever the range, as long as
    /// `cols.start` is a multiple of 8.
    ///
    /// # Safety
    /// As [`NodeView::new`] for `v`, the view of `s` in `l` (as in the forward step); `cols`
    /// inside `0..s.size`.
    #[inline(always)]
    unsafe fn backward_below<const WIDE: bool>(
        &self,
        l: &[f32],
        v: NodeView,
        s: &Supernode,
        cols: std::ops::Range<usize>,
    ) {
        let (start, m, xp) = (v.start, s.m, v.xp);
        let size = cols.end;
        debug_assert!(cols.start % 8 == 0 && size <= s.size);
        let pat = &self.rows[s.pat..s.pat + m];
        let r0 = s.size;
        let mut q = 0;
        // Columns `..c_lo` are done by `backward_cols8` (all rows below).
        let mut c_lo = cols.start;
        #[cfg(target_arch = "x86_64")]
        if WIDE && s.tval != usize::MAX {
            let stride = row_stride(s.size);
            let wt = l[s.tval..s.tval + stride * m].as_ptr();
            let rows: *const u32 = pat.as_ptr();
            for c in (cols.start..size).step_by(8) {
                let cols = (size - c).min(8);
                // SAFETY (both calls): `run_avx` (the only caller with `WIDE`) has AVX; the
                // row-major copy (checked in `Layout::solve`) has `m` rows of `stride >= c + 8`
                // values, `pat` holds `m` row indices below `n`, and rows
                // `start + c..start + c + cols` are columns of this supernode (the others of
                // the last block are zero rows of a local copy, their weights zeros).
                if cols == 8 {
                    unsafe { backward_cols8(wt.add(c), stride, rows, m, xp, v.row(start + c)) };
                } else {
                    let mut part = [[0.0f32; 4]; 8];
                    for (k, row) in part.iter_mut().take(cols).enumerate() {
                        *row = unsafe { *v.row(start + c + k) };
                    }
                    unsafe { backward_cols8(wt.add(c), stride, rows, m, xp, part.as_mut_ptr()) };
                    for (k, row) in part.iter().take(cols).enumerate() {
                        unsafe { *v.row(start + c + k) = *row };
                    }
                }
            }
            // No columns left for the loops below.
            (c_lo, q) = (size, m);
        }
        #[cfg(target_arch = "x86_64")]
        if WIDE {
            // The same sums as below for two columns at once (the halves of 8-wide registers),
            // the last column of an odd block alone.
            while q + 4 <= m {
                let r = r0 + q;
                // SAFETY: `run_avx` (the only caller with `WIDE`) has AVX; the reads and writes
                // are those of `v.w`, `v.at` and `v.put` below.
                unsafe {
                    // (No closures here: they would not inherit this function's AVX.)
                    let xr = [
                        Wide::broadcast(v.row(pat[q] as usize)),
                        Wide::broadcast(v.row(pat[q + 1] as usize)),
                        Wide::broadcast(v.row(pat[q + 2] as usize)),
                        Wide::broadcast(v.row(pat[q + 3] as usize)),
                    ];
                    let mut c = c_lo;
                    while c + 2 <= size {
                        let (wc, wn) = (v.wp(c, r), v.wp(c + 1, r));
                        let f = |k: i32| Wide::pick(wc, wn, k);
                        let sum = xr[0]
                            .mul(f(0))
                            .add(xr[1].mul(f(1)))
                            .add(xr[2].mul(f(2)).add(xr[3].mul(f(3))));
                        let p = v.row(start + c);
                        Wide::load(p).sub(sum).store(p);
                        c += 2;
                    }
                    let xr = [xr[0].low(), xr[1].low(), xr[2].low(), xr[3].low()];
                    for c in c..size {
                        let sum = xr[0]
                            .scaled(v.w(c, r))
                            .add(xr[1].scaled(v.w(c, r + 1)))
                            .add(xr[2].scaled(v.w(c, r + 2)).add(xr[3].scaled(v.w(c, r + 3))));
                        v.put(start + c, v.at(start + c).sub(sum));
                    }
                }
                q += 4;
            }
        }
        while q + 4 <= m {
            let xr = [0, 1, 2, 3].map(|k| v.at(pat[q + k] as usize));
            for c in c_lo..size {
                let r = r0 + q;
                let sum = xr[0]
                    .scaled(v.w(c, r))
                    .add(xr[1].scaled(v.w(c, r + 1)))
                    .add(xr[2].scaled(v.w(c, r + 2)).add(xr[3].scaled(v.w(c, r + 3))));
                v.put(start + c, v.at(start + c).sub(sum));
            }
            q += 4;
        }
        for q in q..m {
            let xr = v.at(pat[q] as usize);
            for c in c_lo..size {
                v.put(start + c, v.at(start + c).sub_scaled(v.w(c, r0 + q), xr));
            }
        }
    }

    /// The triangle of the backward step of `v`'s supernode (after the updates from the rows
    /// below).
    ///
    /// # Safety
    /// As [`NodeView::new`] for `v` (as in the forward step).
    #[inline(always)]
    unsafe fn backward_triangle<const WIDE: bool>(&self, v: NodeView) {
        let (size, start) = (v.size, v.start);
        for c in (0..size).rev() {
            let mut xc = v.at(start + c);
            for r in c + 1..size {
                xc = xc.sub_scaled(v.w(c, r), v.at(start + r));
            }
            v.put(start + c, xc.div(v.w(c, c)));
        }
    }
}

/// The forward step's sums of eight rows below a diagonal block: for `k < 8`, lane by lane,
/// `0 + w[0 * ld + k] x[0] + ... + w[(size - 1) * ld + k] x[size - 1]` (each product added in
/// column order, separate multiply and add), as the four lanes of a row: the same operations
/// as [`Lane::add_scaled`] over the columns, the `x`, `y` and `z` lanes of the eight rows in
/// one 8-wide register each (the unused fourth lane is `0`, as `0 + w 0` is).
///
/// # Safety
/// The CPU has AVX; `w` points to `size` columns `ld` apart of eight readable `f32`, `x` to
/// `size` readable rows.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx")]
unsafe fn forward_rows8(w: *const f32, ld: usize, size: usize, x: *const [f32; 4]) -> [Lane; 8] {
    use std::arch::x86_64::*;
    let (mut ax, mut ay, mut az) = (
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
    );
    for c in 0..size {
        // SAFETY: the caller's.
        unsafe {
            let wc = _mm256_loadu_ps(w.add(c * ld));
            let xc = x.add(c) as *const f32;
            ax = _mm256_add_ps(ax, _mm256_mul_ps(wc, _mm256_broadcast_ss(&*xc)));
            ay = _mm256_add_ps(ay, _mm256_mul_ps(wc, _mm256_broadcast_ss(&*xc.add(1))));
            az = _mm256_add_ps(az, _mm256_mul_ps(wc, _mm256_broadcast_ss(&*xc.add(2))));
        }
    }
    // Transpose to rows `(x, y, z, 0)`: rows `k` and `k + 4` in the halves of `r[k]`.
    let zero = _mm256_setzero_ps();
    let (xy_lo, xy_hi) = (_mm256_unpacklo_ps(ax, ay), _mm256_unpackhi_ps(ax, ay));
    let (z_lo, z_hi) = (_mm256_unpacklo_ps(az, zero), _mm256_unpackhi_ps(az, zero));
    let r = [
        _mm256_shuffle_ps::<0x44>(xy_lo, z_lo),
        _mm256_shuffle_ps::<0xEE>(xy_lo, z_lo),
        _mm256_shuffle_ps::<0x44>(xy_hi, z_hi),
        _mm256_shuffle_ps::<0xEE>(xy_hi, z_hi),
    ];
    [
        Lane(_mm256_castps256_ps128(r[0])),
        Lane(_mm256_castps256_ps128(r[1])),
        Lane(_mm256_castps256_ps128(r[2])),
        Lane(_mm256_castps256_ps128(r[3])),
        Lane(_mm256_extractf128_ps::<1>(r[0])),
        Lane(_mm256_extractf128_ps::<1>(r[1])),
        Lane(_mm256_extractf128_ps::<1>(r[2])),
        Lane(_mm256_extractf128_ps::<1>(r[3])),
    ]
}

/// The backward step's updates of eight columns of a supernode from all rows below its
/// diagonal block: per column `c` and lane, for each group of four rows `r..r + 4` in order
/// `x_c - ((w_{c,r} x_r + w_{c,r+1} x_{r+1}) + (w_{c,r+2} x_{r+2} + w_{c,r+3} x_{r+3}))`,
/// then for each remaining row `x_c - w_{c,r} x_r`: the operations of [`Layout::backward`]'s
/// loops, with the `x`, `y`, `z` (and unused) lanes of the eight columns in one 8-wide register
/// each and the weights of one row for the eight columns loaded together from the row-major
/// copy.
///
/// # Safety
/// The CPU has AVX; `wt` points to `m` rows `stride` apart of eight readable `f32`, `rows` to
/// `m` row indices of rows of `x` that `xc` (eight rows) does not overlap.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx")]
unsafe fn backward_cols8(
    wt: *const f32,
    stride: usize,
    rows: *const u32,
    m: usize,
    x: *const [f32; 4],
    xc: *mut [f32; 4],
) {
    use std::arch::x86_64::*;
    // SAFETY (all pointer reads and writes): the caller's.
    unsafe {
        // (Macros, not closures: closures would not inherit this function's AVX.)
        // Rows `k` and `k + 4` in the halves, then transposed to lanes.
        macro_rules! half {
            ($k:expr) => {
                _mm256_loadu2_m128(xc.add($k + 4) as *const f32, xc.add($k) as *const f32)
            };
        }
        let (m0, m1, m2, m3) = (half!(0), half!(1), half!(2), half!(3));
        let (t0, t1) = (_mm256_unpacklo_ps(m0, m1), _mm256_unpackhi_ps(m0, m1));
        let (t2, t3) = (_mm256_unpacklo_ps(m2, m3), _mm256_unpackhi_ps(m2, m3));
        let mut v = [
            _mm256_shuffle_ps::<0x44>(t0, t2),
            _mm256_shuffle_ps::<0xEE>(t0, t2),
            _mm256_shuffle_ps::<0x44>(t1, t3),
        ];
        let unused = _mm256_shuffle_ps::<0xEE>(t1, t3);
        // Lane `d` of row `i` of `x` in all eight lanes.
        macro_rules! lane {
            ($i:expr, $d:expr) => {
                _mm256_broadcast_ss(&*(x.add($i as usize) as *const f32).add($d))
            };
        }
        let mut q = 0;
        while q + 4 <= m {
            let w0 = _mm256_loadu_ps(wt.add(q * stride));
            let w1 = _mm256_loadu_ps(wt.add((q + 1) * stride));
            let w2 = _mm256_loadu_ps(wt.add((q + 2) * stride));
            let w3 = _mm256_loadu_ps(wt.add((q + 3) * stride));
            let (r0, r1, r2, r3) = (
                *rows.add(q),
                *rows.add(q + 1),
                *rows.add(q + 2),
                *rows.add(q + 3),
            );
            for (d, vd) in v.iter_mut().enumerate() {
                let p01 = _mm256_add_ps(
                    _mm256_mul_ps(lane!(r0, d), w0),
                    _mm256_mul_ps(lane!(r1, d), w1),
                );
                let p23 = _mm256_add_ps(
                    _mm256_mul_ps(lane!(r2, d), w2),
                    _mm256_mul_ps(lane!(r3, d), w3),
                );
                *vd = _mm256_sub_ps(*vd, _mm256_add_ps(p01, p23));
            }
            q += 4;
        }
        for q in q..m {
            let (w, r) = (_mm256_loadu_ps(wt.add(q * stride)), *rows.add(q));
            for (d, vd) in v.iter_mut().enumerate() {
                *vd = _mm256_sub_ps(*vd, _mm256_mul_ps(lane!(r, d), w));
            }
        }
        let (xy_lo, xy_hi) = (
            _mm256_unpacklo_ps(v[0], v[1]),
            _mm256_unpackhi_ps(v[0], v[1]),
        );
        let (zu_lo, zu_hi) = (
            _mm256_unpacklo_ps(v[2], unused),
            _mm256_unpackhi_ps(v[2], unused),
        );
        let out = [
            _mm256_shuffle_ps::<0x44>(xy_lo, zu_lo),
            _mm256_shuffle_ps::<0xEE>(xy_lo, zu_lo),
            _mm256_shuffle_ps::<0x44>(xy_hi, zu_hi),
            _mm256_shuffle_ps::<0xEE>(xy_hi, zu_hi),
        ];
        for (k, o) in out.iter().enumerate() {
            _mm256_storeu2_m128(xc.add(k + 4) as *mut f32, xc.add(k) as *mut f32, *o);
        }
    }
}

/// One task of a split substitution on two threads (see [`Split::tasks`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Task {
    /// Part `.0`'s right-hand-side rows and forward phase.
    ForwardPart(u8),
    /// The merge entries `.0` of the forward top phase (logged updates applied), ending with
    /// a top supernode's triangle and its rows `.1` below.
    ForwardTop((u32, u32), (u32, u32)),
    /// The rows `.1` below top supernode `.0`, forward.
    ForwardRows(u32, (u32, u32)),
    /// Top supernode `.0`'s columns `.1`, backward, from the rows below.
    BackwardCols(u32, (u32, u32)),
    /// Top supernode `.0`'s columns `.1`, backward, from the rows below; then, when every
    /// earlier task is done, its triangle.
    BackwardTop(u32, (u32, u32)),
    /// Part `.0`'s backward phase and solution rows.
    BackwardPart(u8),
}

/// A task and the number of leading tasks that must be done before it starts.
#[derive(Clone, Copy, Debug)]
struct Step {
    task: Task,
    after: u32,
}

/// Spins of a waiting thread before it yields its core at each further check.
const SPIN_LIMIT: u32 = 128;

/// Top supernodes with fewer factor entries below their diagonal block than this have their
/// rows below (forward) or their columns (backward) done by one thread.
const SHARE_MIN: usize = 2048;

impl Split {
    /// The tasks of the two-thread substitution, in an order in which one thread alone may
    /// run them: the two parts' forward phases; per top supernode in order, its merge entries
    /// and triangle, then its rows below in two shares of about equal size (a multiple of 8
    /// rows first: the same operations per row as in one pass) side by side; per top
    /// supernode in reverse order, its columns' updates from the rows below in two shares
    /// (a multiple of 8 columns first) side by side, then its triangle (the second share's
    /// task waits for the first one and runs it); the two parts'
    /// backward phases. Each top row's updates are thus still subtracted in supernode order
    /// by one thread at a time: the bits of the sequential substitution. Supernodes with fewer
    /// than `share_min` factor entries below their diagonal block are not shared
    /// ([`SHARE_MIN`] but in tests).
    fn tasks(nodes: &[Supernode], top: &[u32], merge: &[(u32, u8)], share_min: usize) -> Vec<Step> {
        let at = |t: &Vec<Step>| t.len() as u32;
        let mut t = vec![
            Step {
                task: Task::ForwardPart(0),
                after: 0,
            },
            Step {
                task: Task::ForwardPart(1),
                after: 0,
            },
        ];
        let mut a = 0;
        for (i, &(k, part)) in merge.iter().enumerate() {
            if part != 2 {
                continue;
            }
            let s = &nodes[k as usize];
            // Half the rows, to the nearest multiple of 8.
            let h = (s.m / 2 + 4) / 8 * 8;
            let h = if s.size * s.m >= share_min && 0 < h && h < s.m {
                h
            } else {
                s.m
            };
            let (m, after) = (s.m as u32, at(&t));
            let merge = (a, i as u32 + 1);
            if h < s.m {
                t.push(Step {
                    task: Task::ForwardTop(merge, (0, 0)),
                    after,
                });
                for rows in [(0, h as u32), (h as u32, m)] {
                    t.push(Step {
                        task: Task::ForwardRows(k, rows),
                        after: after + 1,
                    });
                }
            } else {
                t.push(Step {
                    task: Task::ForwardTop(merge, (0, m)),
                    after,
                });
            }
            a = i as u32 + 1;
        }
        debug_assert_eq!(
            a as usize,
            merge.len(),
            "the merge ends with a top supernode"
        );
        for &k in top.iter().rev() {
            let s = &nodes[k as usize];
            let c = (s.size / 2 + 4) / 8 * 8;
            let c = if s.size * s.m >= share_min && c < s.size {
                c
            } else {
                0
            };
            let after = at(&t);
            if c > 0 {
                t.push(Step {
                    task: Task::BackwardCols(k, (0, c as u32)),
                    after,
                });
            }
            t.push(Step {
                task: Task::BackwardTop(k, (c as u32, s.size as u32)),
                after,
            });
        }
        let after = at(&t);
        for p in 0..2 {
            t.push(Step {
                task: Task::BackwardPart(p),
                after,
            });
        }
        t
    }

    /// The schedule for the supernodes `nodes` (rows below their blocks in `rows`, `n`
    /// matrix rows), or `None` when it would not be worth a second thread (small systems,
    /// a tree without two heavy independent branches). Estimated work of a supernode: its
    /// factor entries plus [`NODE_COST`]. The top grows by the heaviest hanging subtree's root,
    /// one at a time ([`SPLIT_EXPANSIONS`] at most); the hanging subtrees are dealt heaviest
    /// first to the lighter part; the cut with the least `top + max(part)` is kept.
    fn new(nodes: &[Supernode], rows: &[u32], n: usize) -> Option<Split> {
        let ns = nodes.len();
        let mut owner = vec![u32::MAX; n];
        for (k, s) in nodes.iter().enumerate() {
            owner[s.start..s.start + s.size].fill(k as u32);
        }
        if owner.contains(&u32::MAX) {
            return None;
        }
        let parent: Vec<usize> = nodes
            .iter()
            .map(|s| {
                if s.m == 0 {
                    usize::MAX
                } else {
                    owner[rows[s.pat] as usize] as usize
                }
            })
            .collect();
        if parent
            .iter()
            .enumerate()
            .any(|(k, &p)| p != usize::MAX && p <= k)
        {
            return None;
        }
        let work: Vec<usize> = nodes
            .iter()
            .map(|s| s.size * (s.size + 1) / 2 + s.size * s.m + NODE_COST)
            .collect();
        let total: usize = work.iter().sum();
        if total < SPLIT_MIN_WORK {
            return None;
        }
        let mut sub = work.clone();
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); ns];
        for k in 0..ns {
            if parent[k] != usize::MAX {
                sub[parent[k]] += sub[k];
                children[parent[k]].push(k);
            }
        }
        // Deals the hanging subtrees heaviest first (ties: lower index) to the lighter part
        // (ties: part 0); returns each subtree's part and the heavier part's work.
        let deal = |hanging: &[usize]| -> (Vec<(usize, u8)>, usize) {
            let mut h = hanging.to_vec();
            h.sort_unstable_by_key(|&r| (std::cmp::Reverse(sub[r]), r));
            let mut load = [0usize; 2];
            let out = h
                .into_iter()
                .map(|r| {
                    let p = usize::from(load[1] < load[0]);
                    load[p] += sub[r];
                    (r, p as u8)
                })
                .collect();
            (out, load[0].max(load[1]))
        };
        let mut hanging: Vec<usize> = (0..ns).filter(|&k| parent[k] == usize::MAX).collect();
        let mut expanded = Vec::new();
        let mut top_work = 0;
        let mut best = (total, usize::MAX);
        for step in 0..=SPLIT_EXPANSIONS {
            let cost = top_work + deal(&hanging).1;
            if cost < best.0 {
                best = (cost, step);
            }
            let Some((i, &r)) = hanging
                .iter()
                .enumerate()
                .max_by_key(|&(_, &r)| (sub[r], std::cmp::Reverse(r)))
            else {
                break;
            };
            hanging.swap_remove(i);
            top_work += work[r];
            expanded.push(r);
            hanging.extend(&children[r]);
        }
        if best.1 == usize::MAX || (best.0 as f64) > SPLIT_GAIN * total as f64 {
            return None;
        }
        let mut is_top = vec![false; ns];
        for &r in &expanded[..best.1] {
            is_top[r] = true;
        }
        let hanging: Vec<usize> = (0..ns)
            .filter(|&k| !is_top[k] && (parent[k] == usize::MAX || is_top[parent[k]]))
            .collect();
        const TOP: u8 = 2;
        let mut part = vec![TOP; ns];
        for (r, p) in deal(&hanging).0 {
            part[r] = p;
        }
        for k in (0..ns).rev() {
            if !is_top[k] && part[k] == TOP {
                // Not a hanging root: its parent (higher index) has its part already.
                part[k] = part[parent[k]];
            }
        }
        let mut own = vec![0u32; ns];
        let mut log_at = vec![0u32; ns];
        let mut log_len = [0usize; 2];
        let mut parts: [Vec<u32>; 2] = [Vec::new(), Vec::new()];
        let mut top = Vec::new();
        let mut merge = Vec::new();
        let mut rows_of: [Vec<(u32, u32)>; 2] = [Vec::new(), Vec::new()];
        // Estimated load of each part's first phase (right-hand side rows and forward steps).
        let mut load = [0usize; 2];
        for (k, s) in nodes.iter().enumerate() {
            if part[k] != TOP {
                let p = part[k] as usize;
                rows_of[p].push((s.start as u32, (s.start + s.size) as u32));
                load[p] += s.size * RHS_ROW_COST + work[k];
            }
        }
        for (k, s) in nodes.iter().enumerate() {
            if part[k] == TOP {
                let p = usize::from(load[1] < load[0]);
                rows_of[p].push((s.start as u32, (s.start + s.size) as u32));
                load[p] += s.size * RHS_ROW_COST;
                top.push(k as u32);
                merge.push((k as u32, TOP));
                continue;
            }
            let pat = &rows[s.pat..s.pat + s.m];
            let p = part[k] as usize;
            // The rows below belong to ancestors: the own part's first, then the top's.
            let h = pat
                .iter()
                .take_while(|&&i| part[owner[i as usize] as usize] != TOP)
                .count();
            if pat[..h]
                .iter()
                .any(|&i| part[owner[i as usize] as usize] as usize != p)
                || pat[h..]
                    .iter()
                    .any(|&i| part[owner[i as usize] as usize] != TOP)
            {
                return None;
            }
            own[k] = h as u32;
            log_at[k] = log_len[p] as u32;
            log_len[p] += s.m - h;
            parts[p].push(k as u32);
            if h < s.m {
                merge.push((k as u32, p as u8));
            }
        }
        if merge.last().is_some_and(|&(_, p)| p != TOP) {
            return None;
        }
        Some(Split {
            tasks: Split::tasks(nodes, &top, &merge, SHARE_MIN),
            parts,
            top,
            own,
            log_at,
            log_len,
            merge,
            rows_of,
        })
    }
}

/// Four single-precision lanes (one row's `x`, `y`, `z` and an unused lane): SSE on x86_64,
/// plain arrays elsewhere; the same operations lane by lane either way.
#[derive(Clone, Copy)]
struct Lane(
    #[cfg(target_arch = "x86_64")] std::arch::x86_64::__m128,
    #[cfg(not(target_arch = "x86_64"))] [f32; 4],
);

#[cfg(target_arch = "x86_64")]
impl Lane {
    #[inline(always)]
    fn zero() -> Lane {
        // SAFETY: SSE is part of the x86_64 baseline.
        Lane(unsafe { std::arch::x86_64::_mm_setzero_ps() })
    }
    /// # Safety
    /// `p` points to four readable `f32`.
    #[inline(always)]
    unsafe fn load(p: *const [f32; 4]) -> Lane {
        // SAFETY: the caller's.
        Lane(unsafe { std::arch::x86_64::_mm_loadu_ps(p as *const f32) })
    }
    /// # Safety
    /// `p` points to four writable `f32`.
    #[inline(always)]
    unsafe fn store(self, p: *mut [f32; 4]) {
        // SAFETY: the caller's.
        unsafe { std::arch::x86_64::_mm_storeu_ps(p as *mut f32, self.0) }
    }
    /// `self - w b`.
    #[inline(always)]
    fn sub_scaled(self, w: f32, b: Lane) -> Lane {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of the x86_64 baseline.
        Lane(unsafe { _mm_sub_ps(self.0, _mm_mul_ps(_mm_set1_ps(w), b.0)) })
    }
    /// `w self`.
    #[inline(always)]
    fn scaled(self, w: f32) -> Lane {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of the x86_64 baseline.
        Lane(unsafe { _mm_mul_ps(_mm_set1_ps(w), self.0) })
    }
    /// `self + w b`.
    #[inline(always)]
    fn add_scaled(self, w: f32, b: Lane) -> Lane {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of the x86_64 baseline.
        Lane(unsafe { _mm_add_ps(self.0, _mm_mul_ps(_mm_set1_ps(w), b.0)) })
    }
    #[inline(always)]
    fn add(self, b: Lane) -> Lane {
        // SAFETY: SSE is part of the x86_64 baseline.
        Lane(unsafe { std::arch::x86_64::_mm_add_ps(self.0, b.0) })
    }
    #[inline(always)]
    fn sub(self, b: Lane) -> Lane {
        // SAFETY: SSE is part of the x86_64 baseline.
        Lane(unsafe { std::arch::x86_64::_mm_sub_ps(self.0, b.0) })
    }
    #[inline(always)]
    fn div(self, d: f32) -> Lane {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of the x86_64 baseline.
        Lane(unsafe { _mm_div_ps(self.0, _mm_set1_ps(d)) })
    }
}

/// Two rows' [`Lane`]s in one 8-wide AVX register (low half, high half), for
/// [`Layout::run_avx`]: every operation acts on each lane exactly as [`Lane`]'s (separate
/// multiply and add, no fused multiply-add), so the results are the same bits.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Wide(std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
impl Wide {
    #[inline]
    #[target_feature(enable = "avx")]
    fn zero() -> Wide {
        Wide(std::arch::x86_64::_mm256_setzero_ps())
    }
    /// One row's four lanes in both halves.
    ///
    /// # Safety
    /// `p` points to four readable `f32`.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn broadcast(p: *const [f32; 4]) -> Wide {
        use std::arch::x86_64::*;
        // SAFETY: the caller's.
        Wide(unsafe { _mm256_broadcast_ps(&*(p as *const __m128)) })
    }
    /// Two consecutive rows.
    ///
    /// # Safety
    /// `p` points to eight readable `f32`.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn load(p: *const [f32; 4]) -> Wide {
        // SAFETY: the caller's.
        Wide(unsafe { std::arch::x86_64::_mm256_loadu_ps(p as *const f32) })
    }
    /// # Safety
    /// `p` points to eight writable `f32`.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn store(self, p: *mut [f32; 4]) {
        // SAFETY: the caller's.
        unsafe { std::arch::x86_64::_mm256_storeu_ps(p as *mut f32, self.0) }
    }
    /// `w[k]` in the low half's lanes and `w[k + 1]` in the high half's.
    ///
    /// # Safety
    /// `w` points to four readable `f32`; `k` is 0, 1 or 2.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn spread(w: *const f32, k: i32) -> Wide {
        use std::arch::x86_64::*;
        // SAFETY: the caller's.
        let both = unsafe { _mm256_broadcast_ps(&*(w as *const __m128)) };
        let pick = _mm256_setr_epi32(k, k, k, k, k + 1, k + 1, k + 1, k + 1);
        Wide(_mm256_permutevar_ps(both, pick))
    }
    /// `w[0]` in the low half's lanes and `w[1]` in the high half's.
    ///
    /// # Safety
    /// `w` points to two readable `f32`.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn pair(w: *const f32) -> Wide {
        use std::arch::x86_64::*;
        // SAFETY: the caller's (eight bytes, read unaligned).
        let two = unsafe { std::ptr::read_unaligned(w as *const f64) };
        let both = _mm256_castpd_ps(_mm256_set1_pd(two));
        Wide(_mm256_permutevar_ps(
            both,
            _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1),
        ))
    }
    /// `a[k]` in the low half's lanes and `b[k]` in the high half's.
    ///
    /// # Safety
    /// `a` and `b` point to four readable `f32`; `k` is below 4.
    #[inline]
    #[target_feature(enable = "avx")]
    unsafe fn pick(a: *const f32, b: *const f32, k: i32) -> Wide {
        use std::arch::x86_64::*;
        // SAFETY: the caller's.
        let ab = unsafe { _mm256_loadu2_m128(b, a) };
        Wide(_mm256_permutevar_ps(ab, _mm256_set1_epi32(k)))
    }
    #[inline]
    #[target_feature(enable = "avx")]
    fn mul(self, b: Wide) -> Wide {
        Wide(std::arch::x86_64::_mm256_mul_ps(self.0, b.0))
    }
    #[inline]
    #[target_feature(enable = "avx")]
    fn add(self, b: Wide) -> Wide {
        Wide(std::arch::x86_64::_mm256_add_ps(self.0, b.0))
    }
    #[inline]
    #[target_feature(enable = "avx")]
    fn sub(self, b: Wide) -> Wide {
        Wide(std::arch::x86_64::_mm256_sub_ps(self.0, b.0))
    }
    #[inline]
    #[target_feature(enable = "avx")]
    fn low(self) -> Lane {
        Lane(std::arch::x86_64::_mm256_castps256_ps128(self.0))
    }
    #[inline]
    #[target_feature(enable = "avx")]
    fn high(self) -> Lane {
        Lane(std::arch::x86_64::_mm256_extractf128_ps::<1>(self.0))
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl Lane {
    #[inline(always)]
    fn zero() -> Lane {
        Lane([0.0; 4])
    }
    /// # Safety
    /// `p` points to four readable `f32`.
    #[inline(always)]
    unsafe fn load(p: *const [f32; 4]) -> Lane {
        // SAFETY: the caller's.
        Lane(unsafe { *p })
    }
    /// # Safety
    /// `p` points to four writable `f32`.
    #[inline(always)]
    unsafe fn store(self, p: *mut [f32; 4]) {
        // SAFETY: the caller's.
        unsafe { *p = self.0 }
    }
    #[inline(always)]
    fn sub_scaled(self, w: f32, b: Lane) -> Lane {
        Lane(std::array::from_fn(|k| self.0[k] - w * b.0[k]))
    }
    #[inline(always)]
    fn scaled(self, w: f32) -> Lane {
        Lane(std::array::from_fn(|k| w * self.0[k]))
    }
    #[inline(always)]
    fn add_scaled(self, w: f32, b: Lane) -> Lane {
        Lane(std::array::from_fn(|k| self.0[k] + w * b.0[k]))
    }
    #[inline(always)]
    fn add(self, b: Lane) -> Lane {
        Lane(std::array::from_fn(|k| self.0[k] + b.0[k]))
    }
    #[inline(always)]
    fn sub(self, b: Lane) -> Lane {
        Lane(std::array::from_fn(|k| self.0[k] - b.0[k]))
    }
    #[inline(always)]
    fn div(self, d: f32) -> Lane {
        Lane(std::array::from_fn(|k| self.0[k] / d))
    }
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
        let layout = Layout::new(&symbolic, n);
        let partial = super::refactor::PartialRefactor::new(&symbolic, &col_ptr, &row_idx);
        Some(ScalarCholesky {
            partial,
            prev_values: Vec::new(),
            last_partial: None,
            layout,
            lanes: std::sync::Mutex::new((Vec::new(), [Vec::new(), Vec::new()])),
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
    ///
    /// After a successful factorisation, only the supernodes that the changed columns reach are
    /// recomputed ([`super::refactor`]): the same bits as a full factorisation.
    pub fn factor(&mut self, pattern: &BsrPattern, values: &[f64], fixed: &[bool]) -> bool {
        std::mem::swap(&mut self.values, &mut self.prev_values);
        self.values.resize(self.row_idx.len(), 0.0);
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
        self.last_partial = None;
        if self.factored && self.prev_values.len() == self.values.len() {
            if let Some(partial) = &mut self.partial {
                let mut changed = Vec::new();
                for j in 0..self.n {
                    for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                        if self.values[k].to_bits() != self.prev_values[k].to_bits() {
                            changed.push(j);
                            changed.push(self.row_idx[k]);
                        }
                    }
                }
                let recomputed = partial.refactor(
                    &self.symbolic,
                    &mut self.factor,
                    &self.values,
                    &changed,
                    MemStack::new(&mut self.scratch),
                );
                if let Some(r) = recomputed {
                    self.last_partial = Some((r, partial.supernodes()));
                    // Only the recomputed supernodes' values changed: check and round those.
                    let SymbolicCholeskyRaw::Supernodal(sn) = self.symbolic.raw() else {
                        unreachable!("a partial refactorisation is supernodal");
                    };
                    let val = sn.col_ptr_for_val();
                    let ok = partial.recomputed().all(|s| {
                        self.factor[val[s]..val[s + 1]]
                            .iter()
                            .all(|v| v.is_finite())
                    });
                    self.factored = ok;
                    if !ok {
                        self.factor32.clear();
                        return false;
                    }
                    for s in partial.recomputed() {
                        let (f, f32s) = (&self.factor[val[s]..val[s + 1]], &mut self.factor32);
                        for (o, &v) in f32s[val[s]..val[s + 1]].iter_mut().zip(f) {
                            *o = v as f32;
                        }
                        if let Some(layout) = &self.layout {
                            layout.copy_row_major(&mut self.factor32, s);
                        }
                    }
                    return true;
                }
            }
        }
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
            .is_ok();
        self.finish_factor(ok)
    }

    /// Supernodes recomputed by the last [`ScalarCholesky::factor`] and the supernode count, if
    /// it was a partial refactorisation (`None`: a full one).
    pub fn last_partial(&self) -> Option<(usize, usize)> {
        self.last_partial
    }

    /// The end of [`ScalarCholesky::factor`]: checks the values, rounds them for the
    /// single-precision solves.
    fn finish_factor(&mut self, ok: bool) -> bool {
        let ok = ok && self.factor.iter().all(|v| v.is_finite());
        self.factored = ok;
        self.factor32.clear();
        if ok {
            self.factor32.extend(self.factor.iter().map(|&v| v as f32));
            if let Some(layout) = &self.layout {
                layout.append_row_major(&mut self.factor32);
            }
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
    /// bytes of the factor. A supernodal factor is solved by our own substitution
    /// (module docs, the same for any thread count), a simplicial one by faer.
    pub fn solve_increment_with<F>(&self, rhs: F, out: &mut [Vec3])
    where
        F: Fn(usize) -> Vec3 + Sync,
    {
        self.increment(|i, _| rhs(i), out, |_, _, d| d);
    }

    /// [`ScalarCholesky::solve_increment_with`] adding the increment to `x` (`x += B^-1 r`),
    /// with row `i` of `r` given by `rhs(i, x)` from the `x` before the update. With our own
    /// substitution the right-hand side is evaluated and the increment added inside the
    /// substitution's parallel parts (no separate passes over the rows); the same bits as
    /// `solve_increment_with` into a buffer followed by `x[i] += dx[i]`.
    pub fn add_increment_with<F>(&self, rhs: F, x: &mut [Vec3])
    where
        F: Fn(usize, &[Vec3]) -> Vec3 + Sync,
    {
        self.increment(rhs, x, |_, o, d| o + d);
    }

    /// [`ScalarCholesky::add_increment_with`] with row `i` of the result mapped: `x[i]` becomes
    /// `map(i, x[i], x[i] + dx[i])` (`x[i]` the row before the update), called once per row
    /// where the increment is added (from two threads at once with a split, on distinct rows).
    pub fn add_increment_map<F, G>(&self, rhs: F, x: &mut [Vec3], map: G)
    where
        F: Fn(usize, &[Vec3]) -> Vec3 + Sync,
        G: Fn(usize, Vec3, Vec3) -> Vec3 + Sync,
    {
        self.increment(rhs, x, |i, o, d| map(i, o, o + d));
    }

    /// The solve of [`ScalarCholesky::solve_increment_with`] and
    /// [`ScalarCholesky::add_increment_with`]: row `i` of `out` becomes `fin(i, out[i], dx[i])`.
    fn increment<F, G>(&self, rhs: F, out: &mut [Vec3], fin: G)
    where
        F: Fn(usize, &[Vec3]) -> Vec3 + Sync,
        G: Fn(usize, Vec3, Vec3) -> Vec3 + Sync,
    {
        if !self.factored {
            return;
        }
        let n = self.n;
        assert_eq!(out.len(), n, "one row per matrix row");
        if let Some(layout) = &self.layout {
            // Our own supernodal substitutions on faer's factor layout, the three coordinates
            // as lanes of one pass over the factor (faer's solve per column group spends most
            // of its time outside the arithmetic at this size).
            let mut guard = scratch(&self.lanes, Default::default);
            let (x, logs) = &mut *guard;
            x.resize(n, [0.0; 4]);
            let op = DisjointRows::<Vec3>(out.as_mut_ptr());
            // SAFETY: `out` has `n` rows (asserted) and outlives the solve; `rhs` reads it only
            // while no row is written: `Layout::solve` calls `emit` (the only writes) after
            // every `rhs` call has returned, once per row, and on distinct rows when from two
            // threads at once.
            let current = unsafe { std::slice::from_raw_parts(op.0 as *const Vec3, n) };
            layout.solve(
                &self.factor32,
                x,
                logs,
                |i| {
                    let v = rhs(i, current);
                    [v.x as f32, v.y as f32, v.z as f32, 0.0]
                },
                |i, xi| {
                    let d = Vec3::new(xi[0] as f64, xi[1] as f64, xi[2] as f64);
                    // SAFETY: see above (`i` < n: a row of the permutation).
                    let o = unsafe { &mut *op.at(i) };
                    *o = fin(i, *o, d);
                },
            );
            return;
        }
        let mut guard = scratch(&self.solve_scratch32, || {
            (
                MemBuffer::new(self.symbolic.solve_in_place_scratch::<f32>(1, Par::Seq)),
                MemBuffer::new(self.symbolic.solve_in_place_scratch::<f32>(2, Par::Seq)),
                Vec::new(),
            )
        });
        let (stack_x, stack, buf) = &mut *guard;
        buf.resize(3 * n, 0.0);
        let current = &*out;
        fill_columns(buf, n, |v| v as f32, |i| rhs(i, current));
        let llt = LltRef::<'_, usize, f32>::new(&self.symbolic, &self.factor32);
        solve_x_and_yz(llt, stack_x, stack, buf, n);
        for (i, v) in out.iter_mut().enumerate() {
            let d = Vec3::new(buf[i] as f64, buf[n + i] as f64, buf[2 * n + i] as f64);
            *v = fin(i, *v, d);
        }
    }

    /// The solve scratch (two faer stacks and the `n x 3` column buffer, sized), or `None`
    /// without a factor.
    fn solve_buffers(&self) -> Option<Scratch<'_, SolveScratch>> {
        if !self.factored {
            return None;
        }
        let mut guard = scratch(&self.solve_scratch, || {
            (
                MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)),
                MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(2, Par::Seq)),
                Vec::new(),
            )
        });
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

    /// [`ScalarCholesky::solve_many`] with the single-precision factor of
    /// [`ScalarCholesky::solve_increment_with`], three columns per substitution (one per
    /// coordinate lane): for columns that only shape an iteration whose residual is evaluated
    /// in double precision (the low-rank contact correction), so their rounding changes the
    /// convergence rate, not the fixed point.
    pub fn solve_many_single(&self, cols: &mut [f64]) {
        let n = self.n;
        if !self.factored || n == 0 {
            return;
        }
        let k = cols.len() / n;
        if let Some(layout) = &self.layout {
            // Columns of a few nonzeros (the low-rank correction's node weights): the forward
            // substitution only along their elimination-tree paths, the same bits.
            let mut guard = scratch(&self.lanes, Default::default);
            let (x, _) = &mut *guard;
            x.resize(n, [0.0; 4]);
            let (mut rows, mut marked) = (Vec::new(), Vec::new());
            for c0 in (0..k).step_by(3) {
                let m = (k - c0).min(3);
                let cs = &mut cols[c0 * n..(c0 + m) * n];
                rows.clear();
                rows.extend((0..n).filter(|&i| (0..m).any(|j| cs[j * n + i].to_bits() != 0)));
                let out = DisjointRows::<f64>(cs.as_mut_ptr());
                // SAFETY: `j < m`, `i < n`: inside `cs`; read only before any row is emitted.
                let lane = |j: usize, i: usize| {
                    if j < m {
                        unsafe { *out.at(j * n + i) }
                    } else {
                        0.0
                    }
                };
                layout.solve_sparse(
                    &self.factor32,
                    x,
                    &mut marked,
                    &rows,
                    |i| {
                        let v = Vec3::new(lane(0, i), lane(1, i), lane(2, i));
                        [v.x as f32, v.y as f32, v.z as f32, 0.0]
                    },
                    |i, xi| {
                        for (j, &v) in xi.iter().take(m).enumerate() {
                            // SAFETY: `j < m`, `i < n`: inside `cs`; each row is emitted once,
                            // after every `rhs` call has returned.
                            unsafe { *out.at(j * n + i) = v as f64 };
                        }
                    },
                );
            }
            return;
        }
        let mut out = vec![Vec3::zeros(); n];
        for c0 in (0..k).step_by(3) {
            let m = (k - c0).min(3);
            {
                let cs = &cols[c0 * n..(c0 + m) * n];
                let lane = |j: usize, i: usize| if j < m { cs[j * n + i] } else { 0.0 };
                self.solve_increment_with(
                    |i| Vec3::new(lane(0, i), lane(1, i), lane(2, i)),
                    &mut out,
                );
            }
            for j in 0..m {
                for (c, o) in cols[(c0 + j) * n..(c0 + j + 1) * n].iter_mut().zip(&out) {
                    *c = o[j];
                }
            }
        }
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

/// A solve's scratch: the factor's own (locked), or a fresh one.
enum Scratch<'a, T> {
    Locked(std::sync::MutexGuard<'a, T>),
    Fresh(T),
}

impl<T> std::ops::Deref for Scratch<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        match self {
            Scratch::Locked(g) => g,
            Scratch::Fresh(t) => t,
        }
    }
}

impl<T> std::ops::DerefMut for Scratch<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        match self {
            Scratch::Locked(g) => g,
            Scratch::Fresh(t) => t,
        }
    }
}

/// The scratch in `m` if it is free, else `fresh()`. A solve holds its scratch across
/// `rayon::join` (the right-hand side's parallel evaluation, the two halves of a split
/// substitution, faer's two column groups), and a thread waiting in `join` runs other tasks,
/// which may solve with the same factor: waiting for the lock there would deadlock (and two
/// threads solving at once would wait for each other). Every solve writes its scratch before
/// reading it, so the results do not depend on which scratch it gets.
fn scratch<T>(m: &std::sync::Mutex<T>, fresh: impl FnOnce() -> T) -> Scratch<'_, T> {
    match m.try_lock() {
        Ok(g) => Scratch::Locked(g),
        Err(std::sync::TryLockError::Poisoned(e)) => Scratch::Locked(e.into_inner()),
        Err(std::sync::TryLockError::WouldBlock) => Scratch::Fresh(fresh()),
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

    /// A random symmetric, strictly diagonally dominant matrix on `pattern`: off-diagonal values
    /// drawn from `off`, each node fixed with probability `p_fixed`, each diagonal entry the
    /// row's absolute sum plus a draw from `diag`. Returns the dense matrix with the fixed rows
    /// and columns eliminated (what the factor solves), the pattern's values and the fixed flags.
    fn random_spd(
        pattern: &BsrPattern,
        rng: &mut impl Rng,
        off: std::ops::Range<f64>,
        p_fixed: f64,
        diag: std::ops::Range<f64>,
    ) -> (DMatrix<f64>, Vec<f64>, Vec<bool>) {
        let n = pattern.offsets.len() - 1;
        let mut dense = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            for s in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                let j = pattern.cols[s] as usize;
                if j < i {
                    let v: f64 = rng.random_range(off.clone());
                    dense[(i, j)] = v;
                    dense[(j, i)] = v;
                }
            }
        }
        let fixed: Vec<bool> = (0..n).map(|_| rng.random_bool(p_fixed)).collect();
        for i in 0..n {
            let row: f64 = (0..n).map(|j| dense[(i, j)].abs()).sum();
            dense[(i, i)] = row + rng.random_range(diag.clone());
        }
        let mut values = vec![0.0; pattern.nnz()];
        for i in 0..n {
            for s in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                values[s] = dense[(i, pattern.cols[s] as usize)];
            }
        }
        for i in 0..n {
            for j in 0..n {
                if i != j && (fixed[i] || fixed[j]) {
                    dense[(i, j)] = 0.0;
                }
            }
        }
        (dense, values, fixed)
    }

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
            let (dense, values, fixed) = random_spd(&pattern, &mut rng, -1.0..1.0, 0.2, 0.1..2.0);
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
                // Added in place (whichever solve the factor has): the same bits as `r + z`.
                let mut added = r.clone();
                chol.add_increment_with(|i, _| r[i], &mut added);
                for i in 0..n {
                    prop_assert_eq!(added[i], r[i] + z[i]);
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

    proptest! {
        /// The own single-precision supernodal solve on grid-graph matrices (wide supernodes,
        /// row counts not multiples of four) against a dense nalgebra solve in double precision:
        /// within single-precision rounding times the (small) condition number.
        #[test]
        fn single_precision_supernodal_solve_matches_dense_lu(seed in 0u64..1000, w in 3usize..14, h in 3usize..14) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let n = w * h;
            let id = |x: usize, y: usize| (y * w + x) as u32;
            let mut pairs = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                        if x + dx < w && y + dy < h {
                            pairs.push((id(x, y), id(x + dx, y + dy)));
                            pairs.push((id(x + dx, y + dy), id(x, y)));
                        }
                    }
                }
            }
            let pattern = BsrPattern::from_pairs(n, pairs);
            let (dense, values, fixed) = random_spd(&pattern, &mut rng, -1.0..0.0, 0.1, 0.1..1.0);
            let r: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
                .collect();
            let mut chol = ScalarCholesky::with_threshold(&pattern, SupernodalThreshold::FORCE_SUPERNODAL).unwrap();
            prop_assert!(chol.layout.is_some());
            prop_assert!(chol.factor(&pattern, &values, &fixed));
            let mut z = vec![Vec3::zeros(); n];
            chol.solve_increment_with(|i| r[i], &mut z);
            // Added in place, the right-hand side read from the start: the same bits.
            let mut added = r.clone();
            chol.add_increment_with(|i, x| x[i], &mut added);
            for i in 0..n {
                prop_assert_eq!(added[i], r[i] + z[i]);
            }
            let lu = dense.clone().lu();
            let cond = {
                let e = dense.symmetric_eigenvalues();
                e.max() / e.min()
            };
            for c in 0..3 {
                let b = nalgebra::DVector::from_iterator(n, r.iter().map(|v| v[c]));
                let want = lu.solve(&b).unwrap();
                let scale = want.amax();
                for i in 0..n {
                    prop_assert!((want[i] - z[i][c]).abs() <= 1e-6 * cond * scale,
                        "row {} coordinate {}: {} vs {} (cond {})", i, c, z[i][c], want[i], cond);
                }
            }
        }
    }
    /// `n` right-hand sides with coordinates uniform in [-1, 1).
    fn random_rhs(rng: &mut rand_chacha::ChaCha8Rng, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|_| {
                Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
            })
            .collect()
    }

    /// A grid-graph pattern of `w x h` nodes (each joined to its right, upper and upper-right
    /// neighbours), like the triangle meshes of the simulator.
    fn grid_pattern(w: usize, h: usize) -> BsrPattern {
        let id = |x: usize, y: usize| (y * w + x) as u32;
        let mut pairs = Vec::new();
        for y in 0..h {
            for x in 0..w {
                for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                    if x + dx < w && y + dy < h {
                        pairs.push((id(x, y), id(x + dx, y + dy)));
                        pairs.push((id(x + dx, y + dy), id(x, y)));
                    }
                }
            }
        }
        BsrPattern::from_pairs(w * h, pairs)
    }

    /// The columns of [`ScalarCholesky::solve_many_single`] with a few nonzeros each (the
    /// forward substitution only along their elimination-tree paths) against the full
    /// substitution of each three columns ([`ScalarCholesky::solve_increment_with`], every row
    /// given): the same bits, on pools of one and two threads, with split and sequential
    /// layouts, for 1 to 7 columns (a last pass of one, two or three), columns on fixed
    /// nodes (all zero) and repeated nodes.
    #[test]
    fn sparse_columns_give_the_bits_of_the_full_substitution() {
        for (seed, (w, h)) in [(40usize, 40usize), (33, 51), (6, 5)]
            .into_iter()
            .enumerate()
        {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(100 + seed as u64);
            let n = w * h;
            let pattern = grid_pattern(w, h);
            let (_, values, fixed) = random_spd(&pattern, &mut rng, -1.0..0.0, 0.05, 0.1..1.0);
            let mut chol =
                ScalarCholesky::with_threshold(&pattern, SupernodalThreshold::FORCE_SUPERNODAL)
                    .unwrap();
            assert!(chol.factor(&pattern, &values, &fixed));
            let layout = chol.layout.as_ref().unwrap();
            assert_eq!(layout.split.is_some(), n > 100, "grid {w}x{h}");
            for k in 1..=7 {
                let mut cols = vec![0.0; n * k];
                for col in cols.chunks_mut(n) {
                    for _ in 0..4 {
                        let i = rng.random_range(0..n);
                        if !fixed[i] {
                            col[i] += rng.random_range(-1.0..1.0);
                        }
                    }
                }
                // One column on the nodes of another, one (if any) on fixed nodes only.
                if k >= 2 {
                    let (a, b) = cols.split_at_mut(n);
                    b[..n].copy_from_slice(a);
                    b[..n].iter_mut().for_each(|v| *v *= 0.5);
                }
                if k >= 3 {
                    cols[2 * n..3 * n].fill(0.0);
                }
                let mut want = cols.clone();
                let mut out = vec![Vec3::zeros(); n];
                for c0 in (0..k).step_by(3) {
                    let m = (k - c0).min(3);
                    let cs = &want[c0 * n..(c0 + m) * n];
                    let lane = |j: usize, i: usize| if j < m { cs[j * n + i] } else { 0.0 };
                    chol.solve_increment_with(
                        |i| Vec3::new(lane(0, i), lane(1, i), lane(2, i)),
                        &mut out,
                    );
                    for j in 0..m {
                        for (c, o) in want[(c0 + j) * n..(c0 + j + 1) * n].iter_mut().zip(&out) {
                            *c = o[j];
                        }
                    }
                }
                for threads in [1, 2] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut got = cols.clone();
                    pool.install(|| chol.solve_many_single(&mut got));
                    for (q, (g, w)) in got.iter().zip(&want).enumerate() {
                        assert_eq!(
                            g.to_bits(),
                            w.to_bits(),
                            "grid {w}x{h}, {k} columns, {threads} threads, entry {q}"
                        );
                    }
                }
            }
        }
    }

    /// The solve (two-thread substitution of a [`Split`], 8-wide AVX loops when the CPU has
    /// AVX) against the plain sequential one on the same factor (the whole substitution in
    /// supernode order on one thread, one row's four lanes at a time): the same bits, on a
    /// pool of one thread and of two; and against faer's double-precision solve within
    /// single-precision rounding. Grids large enough for a split, with fixed nodes, and with
    /// supernodes of two and more columns over four and more rows below (the 8-wide loops').
    /// The oracle of the split substitution's tests: the plain sequential substitution of
    /// `r` with a supernodal single-precision factor, one row's four lanes at a time (not the
    /// 8-wide AVX loops the solve uses when the CPU has AVX).
    fn sequential_substitution(chol: &ScalarCholesky, r: &[Vec3]) -> Vec<Vec3> {
        let layout = chol.layout.as_ref().expect("a supernodal factor");
        let mut x: Vec<[f32; 4]> = layout
            .fwd
            .iter()
            .map(|&f| {
                let v = r[f as usize];
                [v.x as f32, v.y as f32, v.z as f32, 0.0]
            })
            .collect();
        // SAFETY: a row per matrix row, one thread.
        unsafe {
            layout.run_lanes::<false>(&chol.factor32, DisjointRows(x.as_mut_ptr()), Phase::All)
        };
        let mut want = vec![Vec3::zeros(); r.len()];
        for (xi, &f) in x.iter().zip(&layout.fwd) {
            want[f as usize] = Vec3::new(xi[0] as f64, xi[1] as f64, xi[2] as f64);
        }
        want
    }

    #[test]
    fn split_substitution_equals_the_sequential_one() {
        for (seed, (w, h)) in [(40usize, 40usize), (70, 25), (33, 51)]
            .into_iter()
            .enumerate()
        {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed as u64);
            let n = w * h;
            let pattern = grid_pattern(w, h);
            let (_, values, fixed) = random_spd(&pattern, &mut rng, -1.0..0.0, 0.05, 0.1..1.0);
            let r = random_rhs(&mut rng, n);
            let mut chol =
                ScalarCholesky::with_threshold(&pattern, SupernodalThreshold::FORCE_SUPERNODAL)
                    .unwrap();
            assert!(chol.factor(&pattern, &values, &fixed));
            // Every top supernode with enough rows (columns) shared between the threads.
            let layout = chol.layout.as_mut().unwrap();
            let split = layout.split.as_mut().expect("a split at this size");
            split.tasks = Split::tasks(&layout.nodes, &split.top, &split.merge, 0);
            let layout = chol.layout.as_ref().unwrap();
            let split = layout.split.as_ref().expect("a split at this size");
            assert!(split.parts.iter().all(|p| !p.is_empty()) && !split.top.is_empty());
            // Top rows and columns shared between the threads.
            assert!(split
                .tasks
                .iter()
                .any(|t| matches!(t.task, Task::ForwardRows(..))));
            assert!(split
                .tasks
                .iter()
                .any(|t| matches!(t.task, Task::BackwardCols(..))));
            assert!(layout.nodes.iter().any(|s| s.size == 3 && s.m >= 4));
            assert!(layout
                .nodes
                .iter()
                .any(|s| (BLOCK_COLUMNS..8).contains(&s.size) && s.m % 4 != 0));
            assert!(layout.nodes.iter().any(|s| s.size == 2 && s.m >= 4));
            assert!(layout
                .nodes
                .iter()
                .any(|s| s.size >= 2 && s.m >= 8 && s.m % 8 >= 4));
            assert!(layout
                .nodes
                .iter()
                .any(|s| s.size > 8 && s.size % 8 != 0 && s.m >= 4));
            assert!(layout.nodes.iter().any(|s| s.size >= 8 && s.m % 4 != 0));
            let want = sequential_substitution(&chol, &r);
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut got = vec![Vec3::zeros(); n];
                pool.install(|| chol.solve_increment_with(|i| r[i], &mut got));
                for i in 0..n {
                    for c in 0..3 {
                        assert_eq!(
                            got[i][c].to_bits(),
                            want[i][c].to_bits(),
                            "grid {w}x{h}, {threads} threads, row {i}"
                        );
                    }
                }
                // Added in place from a start `x0`, the right-hand side read from `x0`
                // (`r - x0 / 2`): the same bits as the solve into a buffer, then `x0 + dx`.
                let x0 = random_rhs(&mut rng, n);
                let rhs = |i: usize, x: &[Vec3]| r[i] - x[i] * 0.5;
                let mut dx = vec![Vec3::zeros(); n];
                chol.solve_increment_with(|i| rhs(i, &x0), &mut dx);
                let mut x = x0.clone();
                pool.install(|| chol.add_increment_with(rhs, &mut x));
                for i in 0..n {
                    let want = x0[i] + dx[i];
                    for c in 0..3 {
                        assert_eq!(
                            x[i][c].to_bits(),
                            want[c].to_bits(),
                            "added, grid {w}x{h}, {threads} threads, row {i}"
                        );
                    }
                }
            }
            // The parts' rows are disjoint and cover every row.
            let mut seen = vec![0u8; n];
            for &(a, b) in split.rows_of.iter().flatten() {
                seen[a as usize..b as usize]
                    .iter_mut()
                    .for_each(|c| *c += 1);
            }
            assert!(seen.iter().all(|&c| c == 1), "rows dealt once");
            let mut exact = r.clone();
            chol.solve3(&mut exact);
            let scale = exact.iter().fold(0.0f64, |m, v| m.max(v.amax()));
            for i in 0..n {
                assert!((want[i] - exact[i]).amax() <= 1e-4 * scale, "row {i}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// The two-thread schedule of a split substitution ([`Split::tasks`], the top
        /// supernodes' rows and columns shared between the threads) on random sparse SPD
        /// patterns (grid graphs of random size with random extra edges between nearby nodes,
        /// random fixed nodes): the same bits as the plain sequential substitution, on one
        /// thread and on two (repeated, so the threads take the tasks in varying order); every
        /// task list is one a single thread can run in order, and top rows are shared only in
        /// shares starting at a multiple of 8.
        #[test]
        fn shared_top_schedule_gives_the_sequential_bits(
            seed in 0u64..1000, w in 40usize..64, h in 40usize..64, extra in 0usize..400,
            share_all in any::<bool>(),
        ) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let n = w * h;
            let id = |x: usize, y: usize| (y * w + x) as u32;
            let mut pairs = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                        if x + dx < w && y + dy < h {
                            pairs.push((id(x, y), id(x + dx, y + dy)));
                        }
                    }
                }
            }
            for _ in 0..extra {
                let (x, y) = (rng.random_range(0..w), rng.random_range(0..h));
                let (x2, y2) = (
                    (x + rng.random_range(0..4)).min(w - 1),
                    (y + rng.random_range(0..4)).min(h - 1),
                );
                pairs.push((id(x, y), id(x2, y2)));
            }
            let sym: Vec<(u32, u32)> = pairs
                .iter()
                .filter(|(a, b)| a != b)
                .flat_map(|&(a, b)| [(a, b), (b, a)])
                .collect();
            let pattern = BsrPattern::from_pairs(n, sym);
            let (_, values, fixed) = random_spd(&pattern, &mut rng, -1.0..0.0, 0.05, 0.1..1.0);
            let r = random_rhs(&mut rng, n);
            let mut chol =
                ScalarCholesky::with_threshold(&pattern, SupernodalThreshold::FORCE_SUPERNODAL)
                    .unwrap();
            prop_assert!(chol.factor(&pattern, &values, &fixed));
            if share_all {
                // Every top supernode with rows (columns) enough for two shares shared.
                let layout = chol.layout.as_mut().unwrap();
                let split = layout.split.as_mut().expect("a split at this size");
                split.tasks = Split::tasks(&layout.nodes, &split.top, &split.merge, 0);
            }
            let layout = chol.layout.as_ref().unwrap();
            let split = layout.split.as_ref().expect("a split at this size");
            // The schedule: dependencies only on earlier tasks, shares aligned.
            for (i, t) in split.tasks.iter().enumerate() {
                prop_assert!(t.after as usize <= i);
                match t.task {
                    Task::ForwardRows(k, (a, b)) => {
                        prop_assert!(a % 8 == 0 && a < b && b as usize <= layout.nodes[k as usize].m);
                    }
                    Task::BackwardCols(k, (a, b)) | Task::BackwardTop(k, (a, b)) => {
                        prop_assert!(a % 8 == 0 && a <= b && b as usize <= layout.nodes[k as usize].size);
                    }
                    _ => {}
                }
            }
            let want = sequential_substitution(&chol, &r);
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                for _ in 0..3 {
                    let mut got = vec![Vec3::zeros(); n];
                    pool.install(|| chol.solve_increment_with(|i| r[i], &mut got));
                    for i in 0..n {
                        for c in 0..3 {
                            prop_assert_eq!(got[i][c].to_bits(), want[i][c].to_bits(),
                                "{} threads, row {}", threads, i);
                        }
                    }
                }
            }
        }
    }

    /// A solve started while another solve with the same factor holds its scratch (here from
    /// the outer solve's right-hand side, as a task run by a thread waiting in `rayon::join`
    /// would): no deadlock, and both give the bits of the same solve run alone. Supernodal
    /// (own substitution, with a split) and simplicial (faer) factors, single and double
    /// precision, on one thread and on two.
    #[test]
    fn solves_nested_in_a_solve_give_the_same_bits() {
        let (w, h) = (40, 40);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let n = w * h;
        let pattern = grid_pattern(w, h);
        let (_, values, fixed) = random_spd(&pattern, &mut rng, -1.0..0.0, 0.05, 0.1..1.0);
        let r = random_rhs(&mut rng, n);
        let s: Vec<Vec3> = r.iter().map(|v| Vec3::new(v.z, -v.x, 0.5 * v.y)).collect();
        for supernodal in [
            SupernodalThreshold::FORCE_SUPERNODAL,
            SupernodalThreshold::FORCE_SIMPLICIAL,
        ] {
            let mut chol = ScalarCholesky::with_threshold(&pattern, supernodal).unwrap();
            assert!(chol.factor(&pattern, &values, &fixed));
            for increment in [true, false] {
                let solve = |rhs: &(dyn Fn(usize) -> Vec3 + Sync), out: &mut [Vec3]| {
                    if increment {
                        chol.solve_increment_with(rhs, out)
                    } else {
                        chol.solve_with(rhs, out)
                    }
                };
                let (mut want_r, mut want_s) = (vec![Vec3::zeros(); n], vec![Vec3::zeros(); n]);
                solve(&|i| r[i], &mut want_r);
                solve(&|i| s[i], &mut want_s);
                for threads in [1, 2] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let inner = std::sync::Mutex::new(vec![Vec3::zeros(); n]);
                    let mut outer = vec![Vec3::zeros(); n];
                    pool.install(|| {
                        solve(
                            &|i| {
                                if i == n / 2 {
                                    solve(&|j| s[j], &mut inner.lock().unwrap());
                                }
                                r[i]
                            },
                            &mut outer,
                        )
                    });
                    let inner = inner.into_inner().unwrap();
                    for i in 0..n {
                        for c in 0..3 {
                            assert_eq!(outer[i][c].to_bits(), want_r[i][c].to_bits());
                            assert_eq!(inner[i][c].to_bits(), want_s[i][c].to_bits());
                        }
                    }
                }
            }
        }
    }

    /// Partial refactorisation (`sim::refactor`) against a full one by faer of the same new
    /// matrix: the same bits in the double- and single-precision factors, after changes of a few
    /// nearby nodes' rows and columns (as the Cha & Ko loop's rest edits make), of fixed flags,
    /// and of every value; fewer supernodes recomputed for a local change; a change that makes
    /// the matrix indefinite is reported, and the next factorisation is right again.
    #[test]
    fn partial_refactor_gives_the_bits_of_a_full_one() {
        for (seed, (w, h)) in [(40usize, 40usize), (70, 25), (9, 7)]
            .into_iter()
            .enumerate()
        {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(100 + seed as u64);
            let n = w * h;
            let pattern = grid_pattern(w, h);
            let (_, mut values, mut fixed) =
                random_spd(&pattern, &mut rng, -1.0..0.0, 0.05, 0.1..1.0);
            let mut chol =
                ScalarCholesky::with_threshold(&pattern, SupernodalThreshold::FORCE_SUPERNODAL)
                    .unwrap();
            if chol.partial.is_none() {
                // Not x86-64 with AVX2 and FMA: every factorisation is a full one.
                return;
            }
            assert!(chol.factor(&pattern, &values, &fixed));
            assert_eq!(chol.last_partial(), None);
            for round in 0..8 {
                match round {
                    // Every value scaled.
                    5 => values.iter_mut().for_each(|v| *v *= 1.5),
                    // A fixed flag flipped.
                    6 => {
                        let i = rng.random_range(0..n);
                        fixed[i] = !fixed[i];
                    }
                    // Indefinite: one diagonal entry negative; the next round repairs it.
                    7 => {
                        let i = rng.random_range(0..n);
                        values[pattern.diag[i] as usize] = -1.0;
                        assert!(!chol.factor(&pattern, &values, &fixed));
                        let mut full = ScalarCholesky::with_threshold(
                            &pattern,
                            SupernodalThreshold::FORCE_SUPERNODAL,
                        )
                        .unwrap();
                        assert!(!full.factor(&pattern, &values, &fixed));
                        values[pattern.diag[i] as usize] = 1e3;
                    }
                    // A few nearby nodes' rows and columns (symmetric).
                    _ => {
                        let c = rng.random_range(0..n);
                        for i in [c, (c + 1) % n, (c + w) % n] {
                            for k in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                                let j = pattern.cols[k] as usize;
                                if j != i {
                                    let v = values[k] * rng.random_range(0.5..1.5);
                                    values[k] = v;
                                    let t = (pattern.offsets[j] as usize
                                        ..pattern.offsets[j + 1] as usize)
                                        .find(|&t| pattern.cols[t] as usize == i)
                                        .unwrap();
                                    values[t] = v;
                                }
                            }
                            values[pattern.diag[i] as usize] *= rng.random_range(1.0..2.0);
                        }
                    }
                }
                assert!(
                    chol.factor(&pattern, &values, &fixed),
                    "seed {seed} round {round}"
                );
                let mut full =
                    ScalarCholesky::with_threshold(&pattern, SupernodalThreshold::FORCE_SUPERNODAL)
                        .unwrap();
                assert!(full.factor(&pattern, &values, &fixed));
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&chol.factor),
                    bits(&full.factor),
                    "seed {seed} round {round}"
                );
                assert!(chol
                    .factor32
                    .iter()
                    .zip(&full.factor32)
                    .all(|(a, b)| a.to_bits() == b.to_bits()));
                assert_eq!(chol.factor32.len(), full.factor32.len());
                if round == 7 {
                    // After a failed factorisation the next one is full.
                    assert_eq!(chol.last_partial(), None);
                    continue;
                }
                let (recomputed, total) = chol.last_partial().expect("a partial refactorisation");
                if round < 5 && n > 100 {
                    assert!(recomputed < total / 2, "{recomputed} of {total}");
                }
                if round == 5 {
                    assert_eq!(recomputed, total);
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
