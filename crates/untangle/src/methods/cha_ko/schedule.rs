//! Algorithm 2 of Cha & Ko 2022 (Sec. 6): the uv-space mesh update with scheduling.
//!
//! ```text
//! 2: for all red* triangles T(xi, xj, xk)            (sorted; sequential)
//! 3:   if fan(E(xj, xk)) is in its original uv-position
//! 4:     if fan(E(xj, xk)) passes the TIT
//! 5:       perform triangle shrinkage                (applied at once, so line 3 sees it)
//! 6: for all out-most red vertices xr                (sorted; sequential)
//! 7:   if fan(xr) is in its original uv-position
//! 8:     if fan(xr) passes the TIT
//! 9:       perform vertex pull
//! 10-13: revoke by one level every displacement that is not a subject of a current operation
//! ```
//!
//! Red* triangles come first (Case 3 priority); because each operation is applied at once, a
//! later candidate whose fan contains an already displaced vertex waits (Case 1: adjacent
//! out-most red vertices; Case 2: adjacent red* triangles; Case 3: a pull next to a shrink).
//!
//! Our readings where the listing is silent:
//!
//! - "Original uv-position" concerns the fan's *contour* (see [`super::fan`]): an operation
//!   whose subjects are already displaced by *itself* continues (one more level per step) —
//!   that is the finesse. A subject displaced by another operation blocks the candidate.
//! - An operation continues with the target it started with while the colouring still warrants
//!   it (pull: subject out-most red, target green; shrink: the triangle is red* with the same
//!   red edge). Otherwise it has ended: it is revoked one level per step (line 13) until its
//!   subjects are exactly at their original uv, and only then may a new operation take them —
//!   so a pulled vertex whose target turned red is revoked and then pulled toward a new target.
//!   Revoking covers every such displacement, also of red vertices (Alg. 2 lists green ones
//!   only; a red vertex can be left displaced when it stops being out-most or its target turns
//!   red, which the paper's assumptions exclude but real input does not).
//! - "Not a subject vertex" (line 12): subject of an operation still warranted by the colouring.
//!   Such an operation that could not advance this step (level cap) is held, not revoked —
//!   for at most `hold_steps` steps: a finesse that has not finished by then is hindered
//!   (Sec. 5.5), and holding a tiny rest shape only stiffens the simulation. It is abandoned
//!   (revoked like an ended operation) and its subject-target pair, or its red* triangle, is
//!   barred for `2 hold_steps` steps, so another target or the red* triangle across the same red
//!   edge is tried; abandonment is reported as a stall.
//! - A red* triangle whose target (the corner opposite its red edge) is a *loop vertex* of an
//!   intersection path is not shrunk (ours; LL, EIGHT, CROSS have loop vertices). The EE-type
//!   finesse (Sec. 5.3, proof in Sec. 7, Fig. 11b) needs the penetrating edge to be held
//!   `eps_RG` away from the target's edges; at a loop vertex the triangle intersects another
//!   triangle *of the same fan*, along a segment that starts at the target itself. Shrinking
//!   toward the target scales that segment but never removes it: the operation can only
//!   saturate (it did, and held the LL case stuck). Such triangles are left to the pulls of the
//!   red region around them and to the red* triangle across the same red edge. As a *last
//!   resort* ([`super::Params::loop_target_last_resort`], on by default) they are shrunk after
//!   all: when nothing is in progress, no out-most red vertex exists and every red* triangle's
//!   target is a loop vertex, the loop would otherwise stop with nothing to do (CROSS); such a
//!   shrink continues while its triangle stays red*.
//! - Optionally ([`super::Params::avoid_loop_pull_targets`], off by default) and for the same
//!   reason a pull avoids a loop-vertex target (ours): among the green
//!   neighbours of an out-most red vertex, loop vertices are left out while another green
//!   neighbour is available, and a running pull whose target becomes a loop vertex ends (is
//!   revoked, then re-targeted) if the subject has such a neighbour. At a loop vertex the fan of
//!   the target intersects the subject's fan; the triangle the subject has to cross contains
//!   the target, which m-CCH does not hold `eps_RG` away from its own triangles, so the VT-type
//!   finesse (Sec. 7, Fig. 11a) cannot be completed by shortening the subject edge. Exploded
//!   handkerchief seed 13 stalled on exactly this: one red vertex pulled toward the two loop
//!   vertices of an LL path, saturating three times (world edge 8x its rest length).
//!   [`super::Params::avoid_loop_pull_targets_at_start`] (experiment, off) applies the rule to
//!   the target choice only: running pulls go on when their target becomes a loop vertex.
//! - A pull starts only toward a green neighbour across a *cut edge* (an edge that penetrates a
//!   triangle) or toward a loop vertex (ours, [`super::Params::pull_across_cut_edges`], on;
//!   needs the cut edges, which [`super::ChaKo::update_uv`] takes from the analysis). The
//!   VT-type finesse (Sec. 7, Fig. 11a) moves the subject across the triangle its edge to the
//!   target penetrates; with no such triangle there is nothing to cross and the pull can only
//!   saturate. In the paper's colouring every red-green edge is a cut edge (the inside region is
//!   a flood fill stopped only by cut edges and loop vertices), so this changes nothing there.
//!   It matters for the BLI cone regions of Wicke's heuristic, which are cut off by a geodesic
//!   disc as well: their rim vertices have green neighbours that no path separates. In the LL
//!   case such a rim vertex was pulled, saturated, abandoned and pulled again for 250 steps
//!   after the LL path had turned into a BLI; with the rule LL resolves (73 steps; 48 since
//!   such a BLI, its loop vertex on the boundary, gets a partition region instead of a cone:
//!   [`crate::analysis::regions::RegionFinder::bli_boundary_partition`]).
//! - Sec. 6.1 (no TIT-passable fan): a candidate whose every proposal fails the test yields its
//!   turn (lines 4 and 8). After both loops, such candidates whose subjects and fans are still
//!   untouched get a fallback operation ([`super::fallback`]), so a regular operation always has
//!   priority and a failing candidate does not wait forever; if the fallback fails too, or
//!   fallbacks are off, the subject is reported as a stall with its location. The report's
//!   `no_tit_passable_fan` flags the paper's halting condition (candidates tested, none passed,
//!   nothing continued).
//!
//! Everything runs in a fixed order over sorted lists, so the update is deterministic.

use super::fan::{edge_fan, vertex_fan};
use super::operations::{Proposal, UvMesh};
use super::report::{EndReason, FallbackUse, FinesseRecord, Stall, StallReason, UvUpdateReport};
use super::seams::seam_kind;
use super::sectors::Sector;
use super::state::{Op, OpKind, UvState};
use super::ChaKo;
use crate::analysis::Coloring;
use crate::geom::Vec3;
use crate::mesh::topology::NONE;

impl ChaKo {
    /// Runs Algorithm 2 once on `col` (see the module text).
    pub(super) fn run_schedule(
        &mut self,
        col: &Coloring,
        positions: Option<&[Vec3]>,
    ) -> UvUpdateReport {
        let ChaKo {
            params,
            mesh,
            state,
            log,
            step,
            moved,
            tabu,
            closing,
            loop_vertices,
            last_resort_ops,
            cut_edge,
            sectors,
            ..
        } = self;
        let step = *step;
        let stamp = step + 1;
        let g = &mesh.garment;
        let topo = &g.topology;
        let nv = g.mesh.positions.len() as u32;
        let nt = g.mesh.triangles.len() as u32;
        let mut rep = UvUpdateReport {
            step,
            red_star_triangles: col.red_star.iter().filter(|&&t| t < nt).count(),
            outmost_red_vertices: col.outmost_red.iter().filter(|&&v| v < nv).count(),
            ..Default::default()
        };
        let mut touched = vec![false; log.len()];
        let mut tested = false;
        let mut regular_moves = 0usize;
        let mut stalls: Vec<Stall> = Vec::new();
        let mut deferred: Vec<Deferred> = Vec::new();

        // Operations held saturated for `hold_steps` are given up; their pair / triangle is
        // barred for twice as long so that an alternative gets a turn.
        tabu.retain(|_, until| *until > step);
        closing.retain(|id, _| state.ops.contains_key(id));
        if params.hold_steps > 0 {
            for op in state.ops.values() {
                let rec = &mut log[op.id as usize];
                let mut held = rec
                    .saturated_step
                    .is_some_and(|s| step >= s + params.hold_steps as u64);
                if let (Some(pos), Some(_), None, k @ 1..) = (
                    positions,
                    rec.saturated_step,
                    rec.end,
                    params.hold_progress_steps,
                ) {
                    let d = subject_target_distance(op, pos);
                    let best = closing.entry(op.id).or_insert((d, step));
                    if d < best.0 * (1.0 - 1e-3) {
                        *best = (d, step);
                    }
                    held |= step >= best.1 + k as u64;
                }
                if rec.end.is_none() && held {
                    rec.end = Some(EndReason::Abandoned);
                    rec.end_step = Some(step);
                    rep.abandoned += 1;
                    tabu.insert(TabuKey::of(op), step + 2 * params.hold_steps as u64);
                    let t = (op.triangle != NONE).then_some(op.triangle);
                    stalls.push(stall(
                        mesh,
                        StallReason::Abandoned,
                        Some(op.subjects[0]),
                        t,
                        positions,
                    ));
                }
            }
        }

        // (ours) Last resort: nothing is in progress and the only candidates are red*
        // triangles whose target is a loop vertex; then they are shrunk after all (see the
        // module text), and such a shrink continues while warranted.
        let target_of = |t: u32| -> Option<u32> {
            let tri = g.mesh.triangles[t as usize];
            let k = (0..3).find(|&k| col.red_edge[topo.triangle_edges[t as usize][k] as usize])?;
            Some(tri[(k + 2) % 3])
        };
        let last_resort = params.loop_target_last_resort
            && state.ops.is_empty()
            && !col.outmost_red.iter().any(|&x| x < nv)
            && col
                .red_star
                .iter()
                .filter(|&&t| t < nt)
                .filter_map(|&t| target_of(t))
                .all(|i| loop_vertices.binary_search(&i).is_ok());

        // (ours) BLI sectors first ([`super::sectors`]): the boundary strand of a BLI path with
        // an interior loop vertex shrinks into it; the vertex itself is held in place.
        for sec in sectors.iter() {
            let v = sec.vertex;
            if tabu.contains_key(&TabuKey::Sector(v)) {
                rep.blocked_tabu += 1;
                continue;
            }
            let running = state
                .ops
                .values()
                .find(|op| {
                    op.kind == OpKind::Sector && op.target == v && log[op.id as usize].end.is_none()
                })
                .map(|op| op.id);
            if let Some(id) = running {
                let subjects = state.ops[&id].subjects.clone();
                if subjects.iter().any(|&w| moved[w as usize] == stamp) {
                    rep.blocked_subject += 1;
                    continue;
                }
                touched[id as usize] = true;
                if state.advance(id) {
                    rep.sectors_continued += 1;
                    note_level(state, log, id);
                } else {
                    rep.paused += 1;
                }
                for w in subjects {
                    moved[w as usize] = stamp;
                }
                moved[v as usize] = stamp;
                continue;
            }
            if sec
                .subjects
                .iter()
                .any(|&w| moved[w as usize] == stamp || state.is_displaced(w))
                || moved[v as usize] == stamp
            {
                rep.blocked_subject += 1;
                continue;
            }
            tested = true;
            let p = mesh.sector(&state.orig, sec);
            if p.copies.is_empty() || !mesh.test(&state.orig, &p).pass {
                rep.tit_rejected += 1;
                continue;
            }
            regular_moves += 1;
            start(mesh, state, log, p, step, params.level_cap(), &mut rep);
            touched.push(true);
            rep.sectors_started += 1;
            for &w in &sec.subjects {
                moved[w as usize] = stamp;
            }
            moved[v as usize] = stamp;
        }

        // Lines 2-5: red* triangles.
        for &t in &col.red_star {
            if t >= nt {
                continue;
            }
            let tri = g.mesh.triangles[t as usize];
            let Some(k) =
                (0..3).find(|&k| col.red_edge[topo.triangle_edges[t as usize][k] as usize])
            else {
                continue;
            };
            let (j, kk, i) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let loop_target = loop_vertices.binary_search(&i).is_ok();
            if loop_target && !last_resort {
                let o = state.owner[j as usize];
                let running = o != NONE
                    && last_resort_ops.contains(&o)
                    && state.ops[&o].triangle == t
                    && log[o as usize].end.is_none();
                if !running {
                    rep.blocked_loop_target += 1;
                    continue;
                }
            }
            if moved[j as usize] == stamp || moved[kk as usize] == stamp {
                rep.blocked_subject += 1;
                continue;
            }
            if tabu.contains_key(&TabuKey::Shrink(t)) {
                rep.blocked_tabu += 1;
                continue;
            }
            let (oj, ok) = (state.owner[j as usize], state.owner[kk as usize]);
            let existing = if oj == NONE && ok == NONE {
                None
            } else if oj == ok
                && state.ops[&oj].kind == OpKind::Shrink
                && state.ops[&oj].triangle == t
                && log[oj as usize].end.is_none()
            {
                Some(oj)
            } else {
                rep.blocked_subject += 1;
                continue;
            };
            if !state.fan_is_original(&edge_fan(topo, j, kk)) {
                rep.blocked_fan += 1;
                continue;
            }
            match existing {
                Some(id) => {
                    touched[id as usize] = true;
                    if state.advance(id) {
                        rep.shrinks_continued += 1;
                        note_level(state, log, id);
                    } else {
                        rep.paused += 1;
                    }
                }
                None => {
                    tested = true;
                    let ch = mesh.choose_shrink(&state.orig, t, i, j, kk);
                    rep.tit_rejected += ch.rejected.len();
                    let Some(p) = ch.proposal else {
                        // Line 4: yield the turn; the fallback pass may come back to it.
                        deferred.push(Deferred {
                            fan: edge_fan(topo, j, kk),
                            rejected: ch.rejected,
                        });
                        continue;
                    };
                    regular_moves += 1;
                    let id = start(mesh, state, log, p, step, params.level_cap(), &mut rep);
                    if loop_target {
                        last_resort_ops.insert(id);
                        rep.loop_target_last_resort += 1;
                    }
                    touched.push(true);
                    rep.shrinks_started += 1;
                }
            }
            moved[j as usize] = stamp;
            moved[kk as usize] = stamp;
        }

        // Lines 6-9: out-most red vertices. A pull starts only across a cut edge or toward a
        // loop vertex (see the module text); once started it goes on like any other (ending it
        // when its edge stops being cut made the BLI case cycle: pull, revoke, pull again).
        let across_cut = |x: u32, w: u32| {
            !params.pull_across_cut_edges
                || cut_edge.is_empty()
                || loop_vertices.binary_search(&w).is_ok()
                || topo
                    .edge_between(x, w)
                    .is_some_and(|e| cut_edge[e as usize])
        };
        let order = pull_order(topo, col, params.pull_order, nv);
        for x in order {
            if moved[x as usize] == stamp {
                rep.blocked_subject += 1;
                continue;
            }
            let o = state.owner[x as usize];
            if o != NONE && (state.ops[&o].kind != OpKind::Pull || log[o as usize].end.is_some()) {
                rep.blocked_subject += 1;
                continue;
            }
            if !state.fan_is_original(vertex_fan(topo, x)) {
                rep.blocked_fan += 1;
                continue;
            }
            if o != NONE {
                // Continue the finesse while its target is green (and not a loop vertex that
                // can be avoided); otherwise it ends below.
                let target = state.ops[&o].target;
                let avoid = params.avoid_loop_pull_targets
                    && avoidable_loop_target(topo, col, loop_vertices, x, target);
                if !col.red_vertex[target as usize] && !avoid {
                    touched[o as usize] = true;
                    if state.advance(o) {
                        rep.pulls_continued += 1;
                        note_level(state, log, o);
                    } else {
                        rep.paused += 1;
                    }
                    moved[x as usize] = stamp;
                }
                continue;
            }
            let green: Vec<u32> = vertex_fan(topo, x)
                .iter()
                .copied()
                .filter(|&w| !col.red_vertex[w as usize] && across_cut(x, w))
                .collect();
            let candidates: Vec<u32> = green
                .iter()
                .copied()
                .filter(|&w| !tabu.contains_key(&TabuKey::Pull(x, w)))
                .collect();
            if candidates.len() < green.len() {
                rep.blocked_tabu += 1;
            }
            // (ours) Loop vertices are targets only when nothing else is green: see the
            // module text.
            let off_loop: Vec<u32> = candidates
                .iter()
                .copied()
                .filter(|w| loop_vertices.binary_search(w).is_err())
                .collect();
            let avoid_at_start =
                params.avoid_loop_pull_targets || params.avoid_loop_pull_targets_at_start;
            let candidates = if off_loop.is_empty() || !avoid_at_start {
                candidates
            } else {
                if off_loop.len() < candidates.len() {
                    rep.pull_loop_targets_skipped += 1;
                }
                off_loop
            };
            if candidates.is_empty() {
                continue;
            }
            tested = true;
            let ch = mesh.choose_pull(&state.orig, x, &candidates);
            rep.tit_rejected += ch.rejected.len();
            let Some(p) = ch.proposal else {
                // Line 8: yield to the next out-most red vertex.
                deferred.push(Deferred {
                    fan: vertex_fan(topo, x).to_vec(),
                    rejected: ch.rejected,
                });
                continue;
            };
            regular_moves += 1;
            start(mesh, state, log, p, step, params.level_cap(), &mut rep);
            touched.push(true);
            rep.pulls_started += 1;
            moved[x as usize] = stamp;
        }

        // Sec. 6.1: candidates that no regular operation could serve get a fallback, after
        // every regular operation of the step (shrinks before pulls, in order), if their
        // subjects and fans are still untouched; else they are reported.
        for d in deferred {
            let p0 = &d.rejected[0];
            let free = p0
                .subjects
                .iter()
                .all(|&v| moved[v as usize] != stamp && !state.is_displaced(v))
                && state.fan_is_original(&d.fan);
            if !free {
                continue;
            }
            let proposal = if params.fallback {
                mesh.fallback(&state.orig, &d.rejected)
            } else {
                None
            };
            let Some(p) = proposal else {
                let t = (p0.triangle != NONE).then_some(p0.triangle);
                stalls.push(stall(
                    mesh,
                    StallReason::NoTitPassableFan,
                    Some(p0.subjects[0]),
                    t,
                    positions,
                ));
                continue;
            };
            for &v in &p.subjects {
                moved[v as usize] = stamp;
            }
            match p.kind {
                OpKind::Pull => rep.pulls_started += 1,
                OpKind::Shrink => rep.shrinks_started += 1,
                OpKind::Sector => rep.sectors_started += 1,
            }
            start(mesh, state, log, p, step, params.level_cap(), &mut rep);
            touched.push(true);
        }

        // Lines 10-13: revoke what is no longer warranted.
        let ids: Vec<u32> = state.ops.keys().copied().collect();
        // Every intersecting triangle is red (Sec. 3), so an all-green garment is clean.
        let clean = !col.red_triangle[..nt as usize].iter().any(|&r| r);
        let base_rate = params.revoke_levels_per_step;
        let or_base = |k: u32| if k == 0 { base_rate } else { k };
        for id in ids {
            if touched[id as usize] {
                continue;
            }
            let op = &state.ops[&id];
            let avoid: &[u32] = if params.avoid_loop_pull_targets {
                loop_vertices
            } else {
                &[]
            };
            let (warranted, finished) = warranted(mesh, op, col, avoid, sectors);
            let warranted = warranted
                && !(op.kind == OpKind::Shrink
                    && loop_vertices.binary_search(&op.target).is_ok()
                    && !last_resort_ops.contains(&id));
            if warranted && log[id as usize].end.is_none() {
                rep.paused += 1;
                continue;
            }
            let rec = &mut log[id as usize];
            if rec.end.is_none() {
                rec.end = Some(if finished {
                    EndReason::Finished
                } else {
                    EndReason::Superseded
                });
                rec.end_step = Some(step);
            }
            let per_step = if clean {
                or_base(params.revoke_levels_when_clean)
            } else if rec.end == Some(EndReason::Finished) {
                or_base(params.revoke_levels_finished)
            } else {
                base_rate
            };
            rep.revoked_levels += op.level.min(per_step) as usize;
            if state.revoke(id, per_step) {
                rep.restored += 1;
                log[id as usize].restored_step = Some(step);
            }
        }

        // Saturated operations: reported once, when they first reach their cap.
        for op in state.ops.values() {
            let rec = &mut log[op.id as usize];
            if op.level >= op.level_cap && rec.end.is_none() {
                rep.saturated_ops += 1;
                if rec.saturated_step.is_none() {
                    rec.saturated_step = Some(step);
                    let t = (op.triangle != NONE).then_some(op.triangle);
                    stalls.push(stall(
                        mesh,
                        StallReason::Saturated,
                        Some(op.subjects[0]),
                        t,
                        positions,
                    ));
                }
            }
        }
        // Nothing to operate on although triangles are red (e.g. BLI): say where.
        if rep.red_star_triangles == 0 && rep.outmost_red_vertices == 0 && state.ops.is_empty() {
            if let Some(t) = (0..nt).find(|&t| col.red_triangle[t as usize]) {
                stalls.push(stall(
                    mesh,
                    StallReason::NothingToOperateOn,
                    None,
                    Some(t),
                    positions,
                ));
            }
        }
        rep.stalls = stalls;
        let continued = rep.pulls_continued + rep.shrinks_continued + rep.sectors_continued;
        rep.no_tit_passable_fan = tested && regular_moves == 0 && continued == 0;
        rep.active_ops = state.ops.len();
        rep.uv_changed = rep.pulls_started
            + rep.shrinks_started
            + rep.sectors_started
            + continued
            + rep.revoked_levels
            > 0;
        rep
    }
}

/// The garment's out-most red vertices in the order of [`super::PullOrder`].
fn pull_order(
    topo: &crate::mesh::Topology,
    col: &Coloring,
    order: super::PullOrder,
    nv: u32,
) -> Vec<u32> {
    let mut xs: Vec<u32> = col
        .outmost_red
        .iter()
        .copied()
        .filter(|&x| x < nv)
        .collect();
    if order == super::PullOrder::FewestOutmostNeighbours {
        let outmost = |w: u32| col.outmost_red.binary_search(&w).is_ok();
        xs.sort_by_key(|&x| {
            let n = topo
                .vertex_neighbors
                .row(x as usize)
                .iter()
                .filter(|&&w| outmost(w))
                .count();
            (n, x)
        });
    }
    xs
}

/// World distance from an operation's subject (pull) or the midpoint of its two subjects
/// (shrink) to its target (see [`super::Params::hold_progress_steps`]).
fn subject_target_distance(op: &Op, pos: &[Vec3]) -> f64 {
    let s = op.subjects.iter().map(|&v| pos[v as usize]).sum::<Vec3>() / op.subjects.len() as f64;
    (s - pos[op.target as usize]).norm()
}

/// A recently abandoned operation, barred for a while.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum TabuKey {
    /// Pull of a subject toward a target.
    Pull(u32, u32),
    /// Shrink of a red* triangle.
    Shrink(u32),
    /// BLI sector at a loop vertex.
    Sector(u32),
}

impl TabuKey {
    pub(super) fn of(op: &Op) -> TabuKey {
        match op.kind {
            OpKind::Pull => TabuKey::Pull(op.subjects[0], op.target),
            OpKind::Shrink => TabuKey::Shrink(op.triangle),
            OpKind::Sector => TabuKey::Sector(op.target),
        }
    }
}

/// A candidate whose every proposal failed the inversion test: its fan and the rejected
/// proposals, for the fallback pass.
struct Deferred {
    fan: Vec<u32>,
    rejected: Vec<super::operations::Proposal>,
}

/// Whether the pull of `x` toward `target` aims at a loop vertex while `x` has a green
/// neighbour that is not one (see the module text).
fn avoidable_loop_target(
    topo: &crate::mesh::Topology,
    col: &Coloring,
    loop_vertices: &[u32],
    x: u32,
    target: u32,
) -> bool {
    loop_vertices.binary_search(&target).is_ok()
        && topo
            .vertex_neighbors
            .row(x as usize)
            .iter()
            .any(|&w| !col.red_vertex[w as usize] && loop_vertices.binary_search(&w).is_err())
}

/// Whether the colouring still warrants `op`, and whether its finesse is complete.
fn warranted(
    mesh: &UvMesh,
    op: &Op,
    col: &Coloring,
    loop_vertices: &[u32],
    sectors: &[Sector],
) -> (bool, bool) {
    let topo = &mesh.garment.topology;
    match op.kind {
        OpKind::Pull => {
            let x = op.subjects[0];
            let red = col.red_vertex[x as usize];
            let outmost = red
                && topo
                    .vertex_neighbors
                    .row(x as usize)
                    .iter()
                    .any(|&w| !col.red_vertex[w as usize]);
            let target_ok = !col.red_vertex[op.target as usize]
                && !avoidable_loop_target(topo, col, loop_vertices, x, op.target);
            (outmost && target_ok, !red)
        }
        OpKind::Shrink => {
            let e = topo
                .edge_between(op.subjects[0], op.subjects[1])
                .expect("shrink subjects are adjacent");
            let edge_red = col.red_edge[e as usize];
            (
                edge_red && col.red_star.binary_search(&op.triangle).is_ok(),
                !edge_red,
            )
        }
        OpKind::Sector => {
            // Warranted while a BLI path still has its loop vertex there.
            let open = sectors.iter().any(|s| s.vertex == op.target);
            (open, !open)
        }
    }
}

/// Starts a proposal as a new operation and logs it; returns its id.
fn start(
    mesh: &UvMesh,
    state: &mut UvState,
    log: &mut Vec<FinesseRecord>,
    p: Proposal,
    step: u64,
    max_level: u32,
    rep: &mut UvUpdateReport,
) -> u32 {
    let id = log.len() as u32;
    if let Some(f) = p.fallback {
        rep.fallbacks.push(FallbackUse {
            op: id,
            vertex: p.subjects[0],
            fallback: f,
        });
    }
    log.push(FinesseRecord {
        id,
        kind: p.kind,
        subjects: p.subjects.clone(),
        target: p.target,
        triangle: (p.triangle != NONE).then_some(p.triangle),
        seam: seam_kind(&mesh.garment, &p.subjects),
        virtual_copies: p.virtual_copies,
        unsupported_copies: p.unsupported,
        fallback: p.fallback,
        start_step: step,
        end_step: None,
        end: None,
        restored_step: None,
        max_level: 1,
        saturated_step: None,
    });
    state.start(Op {
        id,
        kind: p.kind,
        subjects: p.subjects,
        target: p.target,
        triangle: p.triangle,
        copies: p.copies,
        level: 0,
        level_cap: max_level,
    });
    id
}

fn note_level(state: &UvState, log: &mut [FinesseRecord], id: u32) {
    let rec = &mut log[id as usize];
    rec.max_level = rec.max_level.max(state.ops[&id].level);
}

/// A stall entry with the location of vertex `v` (else the centroid of triangle `t`).
pub(super) fn stall(
    mesh: &UvMesh,
    reason: StallReason,
    v: Option<u32>,
    t: Option<u32>,
    positions: Option<&[Vec3]>,
) -> Stall {
    let g = &mesh.garment;
    let position = positions.and_then(|p| {
        let q = match (v, t) {
            (Some(v), _) => p[v as usize],
            (None, Some(t)) => {
                g.mesh.triangles[t as usize]
                    .iter()
                    .map(|&w| p[w as usize])
                    .sum::<Vec3>()
                    / 3.0
            }
            (None, None) => return None,
        };
        Some([q.x, q.y, q.z])
    });
    let panel = match (v, t) {
        (Some(v), _) => g
            .uv_copies
            .row(v as usize)
            .first()
            .map(|&c| g.panel_of_uv[c as usize]),
        (None, Some(t)) => Some(g.panel_of_triangle[t as usize]),
        _ => None,
    };
    Stall {
        reason,
        vertex: v,
        triangle: t,
        position,
        panel,
    }
}
