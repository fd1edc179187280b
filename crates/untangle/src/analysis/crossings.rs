//! Crossings: every edge `e` that passes through a triangle `t` not incident to it (Wicke et al.
//! 2006, Sec. 4, "intersections between cloth primitives"). Found once each, in parallel, with
//! the symbolically perturbed predicates, and returned sorted so the result is identical for any
//! thread count.
//!
//! Two passes share the work. Triangle pairs without a common vertex come from the BVH. Pairs that
//! share a vertex `v` always have touching boxes, are the bulk of all candidates on cloth, and can
//! only intersect if the fan of `v` folds over itself; a fan whose triangles all project with
//! positive orientation along the fan's normal and wind exactly once (or, at a boundary vertex,
//! less than once) around `v` is embedded in that projection, so none of its triangles can cross
//! another (their projections are disjoint away from `v`, also under the symbolic perturbation).
//! Only fans that fail this O(degree) certificate are tested pair by pair.

use super::input::{AnalysisMesh, ObjectKind};
use crate::broad::{Bvh, SweepAndPrune};
use crate::geom::tri_pair::{pair_crossings, PairOutcome, PreparedTriangle};
use crate::geom::tri_tri::{
    edge_crosses_triangle_filtered, edge_may_overlap_projected,
    straddling_edge_crosses_triangle_fast, triangles_may_overlap_projected, CertifiedPlane,
};
use crate::geom::{Aabb, Vec3};
use crate::mesh::topology::NONE;

/// Edge `edge` passes through triangle `triangle`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Crossing {
    /// Edge index in the analysis mesh's topology.
    pub edge: u32,
    /// Triangle index.
    pub triangle: u32,
}

/// Box of every triangle.
pub fn triangle_boxes(mesh: &AnalysisMesh, pos: &[Vec3]) -> Vec<Aabb> {
    mesh.triangles
        .iter()
        .map(|t| Aabb::from_points(t.iter().map(|&v| &pos[v as usize])))
        .collect()
}

/// The broad phase of the crossing search, chosen by size and density: sweep and prune for
/// small or dense meshes (a crumpled ball of a few hundred or thousand triangles: no tree to
/// build or traverse, and most pairs the sweep tests do overlap), the hierarchy with patch
/// culling otherwise. Both report every pair of overlapping triangle boxes, so the crossings
/// are the same either way.
#[derive(Clone, Debug)]
pub enum BroadPhase {
    /// Sweep and prune along x.
    Sweep(SweepAndPrune),
    /// Bounding volume hierarchy.
    Hierarchy(Bvh),
}

/// Meshes with at most this many triangles use the sweep if it tests at most
/// [`SWEEP_MAX_PAIRS_PER_TRIANGLE`] pairs per triangle (x intervals overlapping), whatever
/// their density: below it the hierarchy's hand-over to the pool costs more than it can save
/// (see `analysis::analyze_with`).
const SWEEP_SMALL_TRIANGLES: usize = 512;
/// See [`SWEEP_SMALL_TRIANGLES`].
const SWEEP_MAX_PAIRS_PER_TRIANGLE: usize = 128;
/// Larger meshes, up to this many triangles, use the sweep when it is dense: at most
/// [`SWEEP_DENSE_MAX_PAIRS_PER_TRIANGLE`] pairs tested per triangle, of which at least a
/// quarter overlap ([`SWEEP_DENSE_SHARE`]). Both are estimated on every
/// [`SWEEP_SAMPLE_STRIDE`]-th box alone, swept by itself (the pair counts of a sample of `m` of
/// `n` boxes scale by `(m / n)^2`, their ratio not at all), so a sheet that keeps the hierarchy
/// pays a sort of one box in 32, not of all of them. Measured (BENCHMARKS.md, "Broad phase
/// by density"): exploded balls of 800 and 1,568 triangles, where about 55 % of the tested pairs
/// overlap, take 18 % and 14 % less time in all (the crossing pass 28 % and 25 % less) with the
/// sweep, 3,200 triangles the same; folded sheets (3-8 % overlapping) keep the hierarchy, and
/// the one of 968 triangles, which the earlier rule swept, takes 16 % fewer instructions.
const SWEEP_MAX_TRIANGLES: usize = 4096;
/// See [`SWEEP_MAX_TRIANGLES`].
const SWEEP_DENSE_MAX_PAIRS_PER_TRIANGLE: usize = 512;
/// See [`SWEEP_MAX_TRIANGLES`]: overlapping pairs per tested pair, at least (1 / 4).
const SWEEP_DENSE_SHARE: (usize, usize) = (1, 4);
/// See [`SWEEP_MAX_TRIANGLES`].
const SWEEP_SAMPLE_STRIDE: usize = 32;

impl BroadPhase {
    /// The broad phase for triangle boxes `boxes`.
    pub fn new(boxes: &[Aabb]) -> Self {
        match Self::sweep(boxes) {
            Some(s) => BroadPhase::Sweep(s),
            None => Self::hierarchy(boxes),
        }
    }

    /// The hierarchy over `boxes` (what [`BroadPhase::new`] builds when the sweep is not chosen).
    pub fn hierarchy(boxes: &[Aabb]) -> Self {
        BroadPhase::Hierarchy(Bvh::build(boxes))
    }

    /// The sweep if [`BroadPhase::new`] chooses it (built on the calling thread), else `None`.
    pub fn sweep(boxes: &[Aabb]) -> Option<SweepAndPrune> {
        let n = boxes.len();
        let (num, den) = SWEEP_DENSE_SHARE;
        if n <= SWEEP_SMALL_TRIANGLES {
            let s = SweepAndPrune::build(boxes);
            let tested = s.x_pairs();
            if tested <= SWEEP_MAX_PAIRS_PER_TRIANGLE * n {
                return Some(s);
            }
            let (sampled, overlapping) = s.sampled_pairs(SWEEP_SAMPLE_STRIDE);
            let dense = tested <= SWEEP_DENSE_MAX_PAIRS_PER_TRIANGLE * n
                && overlapping * den >= sampled * num;
            return dense.then_some(s);
        }
        if n > SWEEP_MAX_TRIANGLES {
            return None;
        }
        let sample: Vec<Aabb> = boxes.iter().step_by(SWEEP_SAMPLE_STRIDE).copied().collect();
        let m = sample.len();
        let (tested, overlapping) = SweepAndPrune::build(&sample).sampled_pairs(1);
        // `tested * (n / m)^2` pairs in all, per triangle: `tested * n / m^2`.
        let dense = tested * n <= SWEEP_DENSE_MAX_PAIRS_PER_TRIANGLE * m * m
            && overlapping * den >= tested * num;
        dense.then(|| SweepAndPrune::build(boxes))
    }

    /// The triangle in each slot (the order the pair callbacks index).
    pub fn order(&self) -> &[u32] {
        match self {
            BroadPhase::Sweep(s) => s.order(),
            BroadPhase::Hierarchy(b) => b.order(),
        }
    }
}

/// All crossings, sorted by `(edge, triangle)`. Obstacle-obstacle pairs are skipped.
pub fn find_crossings(mesh: &AnalysisMesh, pos: &[Vec3], broad: &BroadPhase) -> Vec<Crossing> {
    let topo = &mesh.topology;
    let tris = &mesh.triangles;
    let has_obstacles = mesh.objects.iter().any(|o| o.kind == ObjectKind::Obstacle);
    let reporters = &mesh.reporters;
    // Triangles in slot order, prepared for the pair kernel: the traversal reads them from
    // contiguous memory.
    let order = broad.order();
    let slot_prep: Vec<PreparedTriangle> = order
        .iter()
        .map(|&t| {
            let t = tris[t as usize];
            PreparedTriangle::new(
                &pos[t[0] as usize],
                &pos[t[1] as usize],
                &pos[t[2] as usize],
            )
        })
        .collect();
    let slot_tris: Vec<SlotTriangle> = order
        .iter()
        .map(|&t| {
            let edges = topo.triangle_edges[t as usize];
            let v = tris[t as usize];
            let obstacle = has_obstacles && mesh.kind_of_triangle(t) == ObjectKind::Obstacle;
            SlotTriangle {
                vertices: [v[0], v[1], v[2], NONE],
                owned_edges: edges.map(|e| if reporters.reports(e, t) { e } else { NONE }),
                id: t,
                skip: obstacle as u8 | (reporters.silent[t as usize] as u8) << 1,
            }
        })
        .collect();
    let mut planes =
        vec![CertifiedPlane::from_parts(Vec3::zeros(), Vec3::zeros(), 0.0); tris.len()];
    for (p, &t) in slot_prep.iter().zip(order) {
        planes[t as usize] = p.plane();
    }
    let ctx = Ctx {
        mesh,
        pos,
        planes: &planes,
    };
    let pairs = SlotPairs {
        tris: &slot_tris,
        prep: &slot_prep,
        ctx: &ctx,
    };
    let visit = |sa: u32, sb: u32, out: &mut Vec<Crossing>| pairs.visit(sa, sb, out);
    // Slots the sweep need not pair with each other: silent triangles report nothing.
    let quiet = || -> Vec<bool> { slot_tris.iter().map(|t| t.skip & 2 != 0).collect() };
    // Triangles of a certified patch (hierarchy only): a fan entirely inside one patch is
    // embedded too.
    let mut patch_of = vec![u32::MAX; tris.len()];
    let mut out = match broad {
        // No patches: the fan pass does not wait for the pairs, so with several threads the two
        // run side by side (concatenated in a fixed order, and sorted below anyway). The sweep
        // only lists the pairs that reach the kernel, and the kernel runs over that list in
        // even shares: the sweep's own chunks of slots differ several-fold in work on a
        // crumpled ball (one of seven carried ~40 % of the pairs on the exploded handkerchief),
        // so one thread used to finish long after the other. The crossings are the same set
        // either way, and the sort below puts them in one order.
        // Called from outside rayon's pool (a small mesh: see `analysis::analyze_with`): the
        // calling thread works itself, with one pool worker as a helper (no hand-over of the
        // whole pass to the pool and back).
        BroadPhase::Sweep(sweep)
            if rayon::current_num_threads() > 1 && rayon::current_thread_index().is_none() =>
        {
            let quiet = quiet();
            let skipping = sweep.skipping(&quiet);
            // Each claim lists its pairs that reach the kernel, then runs the kernel over them
            // (as the in-pool pass does: a tighter kernel loop than calling it from the sweep).
            with_helper(
                sweep.len(),
                |range, list, out| {
                    list.clear();
                    skipping.pairs_in(
                        range,
                        |sa, sb, list| {
                            if pairs.reaches_kernel(sa, sb) {
                                list.push([sa, sb]);
                            }
                        },
                        list,
                    );
                    for &[sa, sb] in list.iter() {
                        pairs.kernel(sa, sb, out);
                    }
                },
                || fan_crossings(&ctx, has_obstacles, &patch_of),
            )
        }
        BroadPhase::Sweep(sweep) if rayon::current_num_threads() > 1 => {
            let (mut out, fans) = rayon::join(
                || {
                    let listed = sweep.self_slot_pairs_skipping(&quiet(), |sa, sb, list| {
                        if pairs.reaches_kernel(sa, sb) {
                            list.push([sa, sb]);
                        }
                    });
                    pairs.kernel_over(&listed)
                },
                || fan_crossings(&ctx, has_obstacles, &patch_of),
            );
            out.extend(fans);
            out
        }
        BroadPhase::Sweep(sweep) => {
            let mut out = sweep.self_slot_pairs_skipping(&quiet(), visit);
            out.extend(fan_crossings(&ctx, has_obstacles, &patch_of));
            out
        }
        BroadPhase::Hierarchy(bvh) => {
            let certifier = super::culling::PatchCertifier::new(tris, topo, pos, &planes, bvh);
            let certified = std::sync::Mutex::new(Vec::new());
            let mut out = bvh.self_slot_pairs_culled(visit, |node, first, len| {
                let ok = certifier.embedded(node, first, len);
                if ok {
                    certified
                        .lock()
                        .expect("no panics while held")
                        .push((first, len));
                }
                ok
            });
            for (p, &(first, len)) in certified
                .into_inner()
                .expect("no panics while held")
                .iter()
                .enumerate()
            {
                for &t in &order[first as usize..(first + len) as usize] {
                    patch_of[t as usize] = p as u32;
                }
            }
            out.extend(fan_crossings(&ctx, has_obstacles, &patch_of));
            out
        }
    };
    // Sorted by (edge, triangle).
    crate::radix::sort_by_bucket_then_key(
        &mut out,
        (topo.edge_triangles.len(), tris.len()),
        |c| c.edge,
        |c| c.triangle,
    );
    out
}

/// The pair loop: the triangles in slot order and what the undecided pairs need.
struct SlotPairs<'a> {
    tris: &'a [SlotTriangle],
    prep: &'a [PreparedTriangle],
    ctx: &'a Ctx<'a>,
}

impl SlotPairs<'_> {
    /// Crossings between the triangles in slots `sa` and `sb` (boxes overlapping), pushed to
    /// `out`; pairs with a common vertex are left to the fan pass. Inlined into the broad
    /// phase's loop (no call per pair); the rare undecided pairs go out of line.
    #[inline(always)]
    fn visit(&self, sa: u32, sb: u32, out: &mut Vec<Crossing>) {
        if self.reaches_kernel(sa, sb) {
            self.kernel(sa, sb, out);
        }
    }

    /// Whether the pair in slots `sa` and `sb` needs the kernel: not two obstacle triangles,
    /// not two silent ones (nothing to report), no common vertex (the fan pass decides those).
    #[inline(always)]
    fn reaches_kernel(&self, sa: u32, sb: u32) -> bool {
        let (ta, tb) = (&self.tris[sa as usize], &self.tris[sb as usize]);
        ta.skip & tb.skip == 0 && !shares_a_vertex(&ta.vertices, &tb.vertices)
    }

    /// [`SlotPairs::kernel`] over a list of slot pairs, in parallel shares of equal length;
    /// the crossings of the shares concatenated in list order.
    fn kernel_over(&self, listed: &[[u32; 2]]) -> Vec<Crossing> {
        use rayon::prelude::*;
        let shares: Vec<Vec<Crossing>> = listed
            .par_chunks(KERNEL_SHARE)
            .map(|share| {
                let mut out = Vec::new();
                for &[sa, sb] in share {
                    self.kernel(sa, sb, &mut out);
                }
                out
            })
            .collect();
        let mut out = Vec::with_capacity(shares.iter().map(Vec::len).sum());
        for s in shares {
            out.extend(s);
        }
        out
    }

    /// Crossings between the triangles in slots `sa` and `sb` (boxes overlapping; passed
    /// [`SlotPairs::reaches_kernel`]), pushed to `out`.
    #[inline(always)]
    fn kernel(&self, sa: u32, sb: u32, out: &mut Vec<Crossing>) {
        let (ta, tb) = (&self.tris[sa as usize], &self.tris[sb as usize]);
        match pair_crossings(&self.prep[sa as usize], &self.prep[sb as usize]) {
            PairOutcome::Apart | PairOutcome::Crossings(0) => {}
            PairOutcome::Crossings(mask) => {
                push_owned_edges(ta, tb.id, mask & 7, out);
                push_owned_edges(tb, ta.id, mask >> 3, out);
            }
            PairOutcome::Undecided { sides_a, sides_b } => {
                let tris = &self.ctx.mesh.triangles;
                self.ctx.pair_with_sides(
                    ta.id,
                    tb.id,
                    tris[ta.id as usize],
                    tris[tb.id as usize],
                    sides_a,
                    sides_b,
                    out,
                )
            }
        }
    }
}

/// Slot pairs per parallel task of the kernel when the sweep lists them first (a few dozen
/// microseconds of work each).
const KERNEL_SHARE: usize = 256;

/// Slots of the sweep per claim in [`with_helper`] (small: the work per slot varies several-fold
/// across a crumpled ball, and the last claims decide when both threads are done).
const CLAIM_SLOTS: usize = 8;

/// The sweep's crossings and the fan pass's from the calling thread (outside rayon's pool) and
/// one pool worker: `sweep(range, scratch, out)` runs the sweep and the kernel over the pairs
/// whose first slot is in `range`; both threads claim ranges of [`CLAIM_SLOTS`] slots from one
/// shared counter, so they finish within one claim of each other; the helper first takes the fan pass (`fans`) while
/// the caller starts sweeping, and the caller runs it at the end if the helper has not. The
/// caller waits for the helper only if the helper has started (otherwise the helper, once it
/// runs, returns at once). The crossings are the same set as on one thread, in an order that
/// depends on the claims; the caller sorts them.
fn with_helper<S>(
    slots: usize,
    sweep: S,
    fans: impl FnOnce() -> Vec<Crossing> + Send,
) -> Vec<Crossing>
where
    S: Fn(std::ops::Range<usize>, &mut Vec<[u32; 2]>, &mut Vec<Crossing>) + Sync,
{
    use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
    use std::sync::Mutex;
    // `state`: the helper has not started, runs, is done; the caller closed the pass.
    const IDLE: u8 = 0;
    const RUNNING: u8 = 1;
    const DONE: u8 = 2;
    const CLOSED: u8 = 3;
    let next = AtomicUsize::new(0);
    let fans = Mutex::new(Some(fans));
    let state = AtomicU8::new(IDLE);
    let helper_out: Mutex<Vec<Crossing>> = Mutex::new(Vec::new());
    let run_sweep = |out: &mut Vec<Crossing>| {
        let mut scratch = Vec::new();
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed) * CLAIM_SLOTS;
            if i >= slots {
                break;
            }
            sweep(i..i + CLAIM_SLOTS, &mut scratch, out);
        }
    };
    // Whoever takes the fan pass first runs it (the lock is taken once by each thread).
    let run_fans = |out: &mut Vec<Crossing>| {
        let f = fans.lock().expect("no panics while held").take();
        if let Some(f) = f {
            out.extend(f());
        }
    };
    rayon::in_place_scope(|s| {
        s.spawn(|_| {
            if state
                .compare_exchange(IDLE, RUNNING, Ordering::AcqRel, Ordering::Acquire)
                .is_err()
            {
                return; // the caller did everything
            }
            let mut out = Vec::new();
            run_fans(&mut out);
            run_sweep(&mut out);
            *helper_out.lock().expect("no panics while held") = out;
            state.store(DONE, Ordering::Release);
        });
        let mut out = Vec::new();
        run_sweep(&mut out);
        run_fans(&mut out);
        if state
            .compare_exchange(IDLE, CLOSED, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            // The helper runs: at most its last claim (or the fan pass) is left.
            let mut spins = 0u32;
            while state.load(Ordering::Acquire) != DONE {
                spins += 1;
                if spins % 1024 == 0 {
                    std::thread::yield_now();
                }
                std::hint::spin_loop();
            }
            out.extend(std::mem::take(
                &mut *helper_out.lock().expect("no panics while held"),
            ));
        }
        out
    })
}

/// What the pair loop reads of a triangle, in BVH slot order (contiguous for the traversal).
#[derive(Clone, Copy)]
struct SlotTriangle {
    /// The three vertices and [`NONE`] (padding for the four-lane vertex test).
    vertices: [u32; 4],
    /// Edge `k` (corner `k` to `k + 1`) if this triangle reports its crossings
    /// ([`super::Reporters`]), else [`NONE`].
    owned_edges: [u32; 3],
    /// Triangle index.
    id: u32,
    /// Bit 0: the triangle belongs to an obstacle; bit 1: it is silent (reports no edge). A
    /// pair with a common bit is skipped: obstacle-obstacle pairs are not analysed, and two
    /// silent triangles have nothing to report.
    skip: u8,
}

/// Crossings of the edges `k` of `a` with bit `k` set in `mask` through triangle `b`, for the
/// edges that `a` reports.
#[inline(always)]
fn push_owned_edges(a: &SlotTriangle, b: u32, mask: u8, out: &mut Vec<Crossing>) {
    for (k, &e) in a.owned_edges.iter().enumerate() {
        if mask & (1 << k) != 0 && e != NONE {
            out.push(Crossing {
                edge: e,
                triangle: b,
            });
        }
    }
}

/// Whether two triangles (vertex lists padded to four lanes) have a common vertex: every lane of
/// `b` against each of `a`'s three vertices, lane 3 of `b` ignored (SSE2, the x86-64 baseline).
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline(always)]
fn shares_a_vertex(a: &[u32; 4], b: &[u32; 4]) -> bool {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is enabled at compile time (the cfg above); each load reads one whole
    // four-element array.
    unsafe {
        let va = _mm_loadu_si128(a.as_ptr() as *const __m128i);
        let vb = _mm_loadu_si128(b.as_ptr() as *const __m128i);
        let eq = _mm_or_si128(
            _mm_or_si128(
                _mm_cmpeq_epi32(vb, _mm_shuffle_epi32::<0x00>(va)),
                _mm_cmpeq_epi32(vb, _mm_shuffle_epi32::<0x55>(va)),
            ),
            _mm_cmpeq_epi32(vb, _mm_shuffle_epi32::<0xAA>(va)),
        );
        _mm_movemask_epi8(eq) & 0x0fff != 0
    }
}

/// Portable version of [`shares_a_vertex`].
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
#[inline(always)]
fn shares_a_vertex(a: &[u32; 4], b: &[u32; 4]) -> bool {
    shares_a_vertex_scalar(a, b)
}

/// Whether two triangles have a common vertex, one comparison at a time (the reference).
#[cfg(any(test, not(all(target_arch = "x86_64", target_feature = "sse2"))))]
#[inline(always)]
fn shares_a_vertex_scalar(a: &[u32; 4], b: &[u32; 4]) -> bool {
    let eq = |v: u32| (v == b[0]) | (v == b[1]) | (v == b[2]);
    eq(a[0]) | eq(a[1]) | eq(a[2])
}

/// Crossings between triangles that share exactly one vertex, fan by fan.
/// Fans whose triangles all lie in one certified patch (`patch_of`) are skipped.
fn fan_crossings(ctx: &Ctx, has_obstacles: bool, patch_of: &[u32]) -> Vec<Crossing> {
    use rayon::prelude::*;
    let (mesh, pos) = (ctx.mesh, ctx.pos);
    let topo = &mesh.topology;
    let tris = &mesh.triangles;
    let silent = &mesh.reporters.silent;
    let fan = |mut out: Vec<Crossing>, v: u32| {
        let fan = topo.vertex_triangles.row(v as usize);
        let boundary = topo.boundary_vertex[v as usize];
        let p0 = fan
            .first()
            .map(|&t| patch_of[t as usize])
            .unwrap_or(u32::MAX);
        if p0 != u32::MAX && fan.iter().all(|&t| patch_of[t as usize] == p0) {
            return out;
        }
        if fan.len() < 3 || fan_is_embedded(v, fan, tris, pos, ctx.planes, boundary) {
            return out;
        }
        for (i, &a) in fan.iter().enumerate() {
            for &b in &fan[i + 1..] {
                let (ta, tb) = (tris[a as usize], tris[b as usize]);
                // Both contain `v`; skip the pairs sharing an edge as well.
                let shared = |x: u32| (x == tb[0]) | (x == tb[1]) | (x == tb[2]);
                if shared(ta[0]) as u8 + shared(ta[1]) as u8 + shared(ta[2]) as u8 != 1 {
                    continue;
                }
                if silent[a as usize] && silent[b as usize] {
                    continue; // neither reports an edge
                }
                if has_obstacles
                    && mesh.kind_of_triangle(a) == ObjectKind::Obstacle
                    && mesh.kind_of_triangle(b) == ObjectKind::Obstacle
                {
                    continue;
                }
                ctx.shared_vertex_pair(v, a, b, &mut out);
            }
        }
        out
    };
    let n = topo.num_vertices as u32;
    if n < PAR_VERTICES {
        return (0..n).fold(Vec::new(), fan);
    }
    (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .fold(Vec::new, fan)
        .reduce(Vec::new, |mut a, b| {
            a.extend(b);
            a
        })
}

/// Meshes with fewer vertices run the fan pass on the calling thread (no thread start-up cost).
const PAR_VERTICES: u32 = 8192;

/// Certificate that no two triangles of the fan of `v` intersect (see the module docs). `false`
/// means "not certified", never "intersecting".
fn fan_is_embedded(
    v: u32,
    fan: &[u32],
    tris: &[[u32; 3]],
    pos: &[Vec3],
    planes: &[CertifiedPlane],
    boundary: bool,
) -> bool {
    let pv = pos[v as usize];
    // Rotate each triangle so that v comes first: (v, x, y) keeps the orientation (and the plane
    // normal, which is invariant under cyclic rotation).
    let corners = |t: u32| {
        let tri = tris[t as usize];
        let k = tri.iter().position(|&w| w == v).unwrap_or(0);
        (
            pos[tri[(k + 1) % 3] as usize] - pv,
            pos[tri[(k + 2) % 3] as usize] - pv,
        )
    };
    let mut n = Vec3::zeros();
    for &t in fan {
        n += planes[t as usize].normal();
    }
    let nn = n.norm();
    // Written to be false for NaN as well.
    if nn.is_nan() || nn <= 0.0 || !nn.is_finite() {
        return false;
    }
    let n = n / nn;
    // A 2D frame of the projection plane.
    let e1 = if n.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let e1 = (e1 - n * e1.dot(&n)).normalize();
    let e2 = n.cross(&e1);
    let quadrant = |w: &Vec3| {
        let (a, b) = (w.dot(&e1), w.dot(&e2));
        match (a >= 0.0, b >= 0.0) {
            (true, true) => 0i32,
            (false, true) => 1,
            (false, false) => 2,
            (true, false) => 3,
        }
    };
    // Every projected sector turns counter-clockwise by less than pi, so the number of
    // quadrant boundaries it sweeps is (q(y) - q(x)) mod 4; their sum is four times the winding
    // number of the fan around v.
    let mut steps = 0;
    for &t in fan {
        let c = planes[t as usize].normal();
        let h = c.dot(&n);
        if h.is_nan() || h <= 1e-9 * c.norm() {
            return false;
        }
        let (x, y) = corners(t);
        steps += (quadrant(&y) - quadrant(&x)).rem_euclid(4);
    }
    if boundary {
        // An open fan winds less than once iff its sectors sweep fewer than four quadrant
        // boundaries... unless it sweeps almost a full turn; then only the angle sum can tell.
        if steps <= 2 {
            return true;
        }
        let mut total = 0.0;
        for &t in fan {
            let (x, y) = corners(t);
            let h = x.cross(&y).dot(&n);
            let (xp, yp) = (x - n * x.dot(&n), y - n * y.dot(&n));
            total += h.atan2(xp.dot(&yp));
        }
        total < std::f64::consts::TAU - 1e-6
    } else {
        steps == 4
    }
}

/// What the pair kernel needs.
struct Ctx<'a> {
    mesh: &'a AnalysisMesh,
    pos: &'a [Vec3],
    planes: &'a [CertifiedPlane],
}

impl Ctx<'_> {
    /// All crossings between triangles `a` and `b` (no common vertex) that the pair kernel left
    /// undecided, given the certified sides of each one's corners with respect to the other's
    /// plane. Each edge is tested only by its reporter ([`super::Reporters`]), so
    /// every crossing is found exactly once.
    ///
    /// Pairs that look coplanar go through a 2D separating-axis test (a conservative filter);
    /// an edge with certified opposite sides needs only the three side tests.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    #[cold]
    fn pair_with_sides(
        &self,
        a: u32,
        b: u32,
        ta: [u32; 3],
        tb: [u32; 3],
        da: [i8; 3],
        db: [i8; 3],
        out: &mut Vec<Crossing>,
    ) {
        let p = |v: u32| &self.pos[v as usize];
        // Only (nearly) coplanar pairs, with undecided corners on both sides, need the 2D
        // filter; otherwise the per-edge filters below are cheaper.
        if (da.contains(&0) && db.contains(&0))
            && !triangles_may_overlap_projected(&ta.map(|v| *p(v)), &tb.map(|v| *p(v)))
        {
            return;
        }
        self.edges(a, b, ta, tb, da, out);
        self.edges(b, a, tb, ta, db, out);
    }

    /// Crossings between triangles `a` and `b` whose only common vertex is `v`: only the edge
    /// of each opposite `v` can cross the other triangle.
    #[inline]
    fn shared_vertex_pair(&self, v: u32, a: u32, b: u32, out: &mut Vec<Crossing>) {
        let tris = &self.mesh.triangles;
        let topo = &self.mesh.topology;
        let pos = self.pos;
        for (x, y) in [(a, b), (b, a)] {
            let (tx, ty) = (tris[x as usize], tris[y as usize]);
            // Edge `k` runs from corner `k` to corner `k + 1`: the one after `v`'s corner is
            // opposite `v`.
            let Some(kv) = tx.iter().position(|&w| w == v) else {
                continue;
            };
            let k = (kv + 1) % 3;
            let e = topo.triangle_edges[x as usize][k];
            if !self.mesh.reporters.reports(e, x) {
                continue;
            }
            let (i, j) = (tx[k], tx[(k + 1) % 3]);
            let (p, q) = (&pos[i as usize], &pos[j as usize]);
            let plane = &self.planes[y as usize];
            let (sp, sq) = (plane.side(p), plane.side(q));
            if sp != 0 && sp == sq {
                continue;
            }
            let (pa, pb, pc) = (
                &pos[ty[0] as usize],
                &pos[ty[1] as usize],
                &pos[ty[2] as usize],
            );
            let ids = [i, j, ty[0], ty[1], ty[2]];
            if edge_crosses_given_sides(p, q, [pa, pb, pc], ids, sp, sq) {
                out.push(Crossing {
                    edge: e,
                    triangle: y,
                });
            }
        }
    }

    /// Edges of `a` (reported by `a`, not incident to `b`) against triangle `b`; `sides` are the
    /// certified sides of `a`'s corners with respect to `b`'s plane.
    #[inline]
    fn edges(
        &self,
        a: u32,
        b: u32,
        ta: [u32; 3],
        tb: [u32; 3],
        sides: [i8; 3],
        out: &mut Vec<Crossing>,
    ) {
        let topo = &self.mesh.topology;
        let pos = self.pos;
        let edges = topo.triangle_edges[a as usize];
        let (pa, pb, pc) = (
            &pos[tb[0] as usize],
            &pos[tb[1] as usize],
            &pos[tb[2] as usize],
        );
        for k in 0..3 {
            let (sp, sq) = (sides[k], sides[(k + 1) % 3]);
            if sp != 0 && sp == sq {
                continue;
            }
            let e = edges[k];
            if !self.mesh.reporters.reports(e, a) {
                continue;
            }
            let (i, j) = (ta[k], ta[(k + 1) % 3]);
            if tb.contains(&i) || tb.contains(&j) {
                continue;
            }
            let (p, q) = (&pos[i as usize], &pos[j as usize]);
            let ids = [i, j, tb[0], tb[1], tb[2]];
            if edge_crosses_given_sides(p, q, [pa, pb, pc], ids, sp, sq) {
                out.push(Crossing {
                    edge: e,
                    triangle: b,
                });
            }
        }
    }
}

/// Whether edge `pq` crosses triangle `t` (exact, with the analysis's tie rule; `ids` as in
/// [`edge_crosses_triangle`]), given the certified sides `sp`, `sq` of its endpoints with respect
/// to the triangle's plane (not both the same non-zero side): a straddling edge takes the
/// floating-point fast path, an edge touching the plane the projected-overlap filter first.
#[inline]
fn edge_crosses_given_sides(
    p: &Vec3,
    q: &Vec3,
    [pa, pb, pc]: [&Vec3; 3],
    ids: [u32; 5],
    sp: i8,
    sq: i8,
) -> bool {
    if sp != 0 && sq != 0 {
        straddling_edge_crosses_triangle_fast(p, q, pa, pb, pc, ids)
    } else {
        edge_may_overlap_projected(p, q, pa, pb, pc)
            && edge_crosses_triangle_filtered(p, q, pa, pb, pc, ids)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::AnalysisMesh;
    use crate::geom::tri_tri::edge_crosses_triangle;
    use proptest::prelude::*;

    /// Every crossing by testing every edge against every triangle not touching it, sorted
    /// (the oracle).
    fn brute_crossings(mesh: &AnalysisMesh, pos: &[Vec3]) -> Vec<Crossing> {
        let topo = &mesh.topology;
        let mut out = Vec::new();
        for (e, &[i, j]) in topo.edges.iter().enumerate() {
            for (t, tri) in mesh.triangles.iter().enumerate() {
                if tri.contains(&i) || tri.contains(&j) {
                    continue;
                }
                let [a, b, c] = tri.map(|v| &pos[v as usize]);
                let ids = [i, j, tri[0], tri[1], tri[2]];
                if edge_crosses_triangle(&pos[i as usize], &pos[j as usize], a, b, c, ids) {
                    out.push(Crossing {
                        edge: e as u32,
                        triangle: t as u32,
                    });
                }
            }
        }
        out.sort_unstable();
        out
    }

    /// [`find_crossings`] in a pool of `threads` threads.
    fn crossings_with(threads: usize, mesh: &AnalysisMesh, pos: &[Vec3]) -> Vec<Crossing> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let boxes = triangle_boxes(mesh, pos);
            let broad = BroadPhase::new(&boxes);
            assert!(
                matches!(broad, BroadPhase::Sweep(_)),
                "small, dense: the sweep"
            );
            find_crossings(mesh, pos, &broad)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]

        /// Exploded handkerchiefs (dense, crumpled): with one thread (the kernel inside the
        /// sweep) and with two (the sweep lists the pairs, the kernel runs over the list in
        /// shares), the crossings are the brute-force ones, in the same order.
        #[test]
        fn sweep_crossings_match_brute_force_for_one_and_two_threads(
            seed in 0u64..1_000_000,
            n in 4usize..12,
        ) {
            let s = crate::scenes::exploded::exploded(seed, n);
            let (mesh, pos) = AnalysisMesh::single(&s.meshes[0]).expect("valid");
            let brute = brute_crossings(&mesh, &pos);
            prop_assert_eq!(&crossings_with(1, &mesh, &pos), &brute);
            prop_assert_eq!(&crossings_with(2, &mesh, &pos), &brute);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]

        /// Called from a thread outside rayon's pool (the test thread), the sweep's pass runs on
        /// the caller with a pool worker helping when the global pool has more than one thread
        /// (sharing the kernel by claims, the fan pass taken by whoever comes first): the
        /// crossings are the brute-force ones, in the same order, run after run.
        #[test]
        fn sweep_crossings_from_outside_the_pool_match_brute_force(
            seed in 0u64..1_000_000,
            n in 4usize..12,
        ) {
            prop_assert!(rayon::current_thread_index().is_none(), "the test thread");
            let s = crate::scenes::exploded::exploded(seed, n);
            let (mesh, pos) = AnalysisMesh::single(&s.meshes[0]).expect("valid");
            let brute = brute_crossings(&mesh, &pos);
            let boxes = triangle_boxes(&mesh, &pos);
            let sweep = BroadPhase::sweep(&boxes).expect("small, dense: the sweep");
            let broad = BroadPhase::Sweep(sweep);
            for _ in 0..3 {
                prop_assert_eq!(&find_crossings(&mesh, &pos, &broad), &brute);
            }
        }
    }

    /// The broad phase follows the density, not the size alone: a crumpled ball of 800 or 1,152
    /// triangles is swept, a folded sheet of 968 triangles (which sweeps many more pairs than
    /// overlap) takes the hierarchy, as does anything above 4,096 triangles.
    #[test]
    fn dense_balls_are_swept_and_sheets_take_the_hierarchy() {
        let broad = |m: &crate::mesh::Mesh| {
            let (mesh, pos) = AnalysisMesh::single(m).expect("valid");
            BroadPhase::new(&triangle_boxes(&mesh, &pos))
        };
        for n in [20, 24] {
            let s = crate::scenes::exploded::exploded(0, n);
            assert!(
                matches!(broad(&s.meshes[0]), BroadPhase::Sweep(_)),
                "ball {n}"
            );
        }
        for n in [22, 48] {
            let s = crate::scenes::folded::folded(n, 4);
            assert!(
                matches!(broad(&s.meshes[0]), BroadPhase::Hierarchy(_)),
                "sheet {n}"
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6))]

        /// Past the small-mesh rule (more than 512 triangles), a dense ball is swept by the
        /// density rule; its crossings are the brute-force ones, and the hierarchy's.
        #[test]
        fn dense_ball_sweep_matches_brute_force_and_the_hierarchy(seed in 0u64..1_000_000) {
            let s = crate::scenes::exploded::exploded(seed, 17);
            let (mesh, pos) = AnalysisMesh::single(&s.meshes[0]).expect("valid");
            prop_assert!(mesh.triangles.len() > 512);
            let brute = brute_crossings(&mesh, &pos);
            prop_assert_eq!(&crossings_with(2, &mesh, &pos), &brute);
            let boxes = triangle_boxes(&mesh, &pos);
            let bvh = BroadPhase::hierarchy(&boxes);
            prop_assert_eq!(&find_crossings(&mesh, &pos, &bvh), &brute);
        }
    }

    proptest! {
        /// The four-lane vertex test equals the comparison-by-comparison one (small ids, so that
        /// zero to three shared vertices all occur).
        #[test]
        fn shared_vertex_test_matches_the_scalar_one(
            a in proptest::array::uniform3(0u32..6),
            b in proptest::array::uniform3(0u32..6),
            big in 0u32..3,
        ) {
            let lift = |v: [u32; 3]| [v[0] + big * (u32::MAX / 4), v[1], v[2], NONE];
            let (a, b) = (lift(a), lift(b));
            let brute = a[..3].iter().any(|v| b[..3].contains(v));
            prop_assert_eq!(shares_a_vertex(&a, &b), brute);
            prop_assert_eq!(shares_a_vertex_scalar(&a, &b), brute);
            prop_assert_eq!(shares_a_vertex(&b, &a), brute);
        }
    }
}
