//! Proximity repulsion (Bridson et al. 2002, Sec. 7.2), before any CCD: for each candidate pair
//! closer than its thickness, or predicted (along the closest-point normal, to first order) to
//! come closer than its thickness by the end of the step, an inelastic impulse removes the
//! approaching normal velocity, and pairs already inside their thickness are pushed apart at a
//! fraction of the overlap per step; Coulomb friction acts on the tangential relative velocity.
//!
//! The closest-point geometry at the start of the step is computed once per pair (in parallel,
//! by the shared screening pass, [`super::screen`]); the impulses are then applied in a fixed
//! pair order (Gauss-Seidel) for a few sweeps, so the result does not depend on the thread
//! count. Pairs that provably get no impulse while their nodes keep their start velocities
//! ([`dormant`]) have their closest points computed only if an impulse changes one of those
//! velocities: the same impulses, in the same order, as computing every pair at once.

use super::{closest, impulse, Closest, Pair, PairKind, Scene};
use crate::geom::Vec3;
use crate::sim::policy::ContactPolicy;

/// Fraction of a pair's overlap removed per step by the repulsion.
pub const PUSH_OUT: f64 = 0.25;
/// Gauss-Seidel sweeps over the close pairs.
pub const SWEEPS: usize = 4;

/// A pair proximity looks at: close, or within reach of the step's motion.
pub struct Near {
    pair: Pair,
    nodes: [u32; 4],
    geom: Closest,
    target: f64,
    mu: f64,
    active: bool,
    close: bool,
    /// Whether it received an impulse in the sweeps.
    impulsed: bool,
    /// 1 + the number of impulses applied when the sweeps last tested it (0: not yet).
    tested_at: u32,
}

/// Proximity's verdict on one candidate pair at the velocities the step starts with
/// ([`screen_pair`]).
pub enum Verdict {
    /// Neither close nor within reach: proximity ignores it.
    Far,
    /// Close or within reach: its closest-point geometry, in the Gauss-Seidel sweeps.
    Near(Near),
    /// Provably inert while its nodes keep their start velocities: not within twice its
    /// thickness, and farther from it than the largest *relative* motion of its nodes over the
    /// step, so its normal velocity cannot reach the impulse threshold (see [`dormant`]). The
    /// closest points are computed, exactly as for any pair, only if an impulse of the sweeps
    /// changes a node's velocity. Only without `within_reach`, where membership in the resting
    /// contacts depends on closeness and impulses alone. Holds the pair's nodes.
    Dormant([u32; 4]),
}

/// Whether, at positions `x` (the step's start) and velocities `v` of the nodes, a pair with
/// thickness `eps` is provably farther than `2 eps` and cannot receive a proximity impulse. The
/// relative normal velocity `sum_k w_k n . v_k` is, for closest-point weights (convex on each
/// side), at most the largest speed of a node of one primitive relative to a node of the other,
/// `rel`; an impulse needs it above `gap / h`, `gap` the distance minus `eps`. So a pair whose
/// lower distance bound (swept boxes at rest, bounding spheres) exceeds
/// `max(2 eps, eps + rel h)` (plus rounding slack) gets none.
#[inline]
pub fn dormant(x: &[Vec3; 4], vel: &[Vec3; 4], vt: bool, eps: f64, h: f64) -> bool {
    let (gap, scale) = (super::axis_gap(x, vt), super::coordinate_scale(x));
    dormant_given_gap(gap, scale, vel, vt, eps, h)
}

/// [`dormant`] with the pair's [`super::axis_gap`] and [`super::coordinate_scale`] given.
#[inline]
fn dormant_given_gap(gap: f64, scale: f64, vel: &[Vec3; 4], vt: bool, eps: f64, h: f64) -> bool {
    super::gap_exceeds(
        gap,
        scale,
        dormant_distance(eps, relative_speed(vel, vt), h),
    )
}

/// The largest speed of a node of one primitive relative to a node of the other (nodes
/// `[p, a, b, c]` when `vt`, else two edges), rounded up: a bound of the pair's relative
/// normal velocity at any closest points, and `h` times it a bound of how much the distance
/// can shrink over the step.
#[inline]
pub fn relative_speed(vel: &[Vec3; 4], vt: bool) -> f64 {
    relative_speed_given_max(vel, vt, super::abs_max(vel))
}

/// [`relative_speed`] given [`super::abs_max`] of the velocities, `vmax`.
#[inline(always)]
fn relative_speed_given_max(vel: &[Vec3; 4], vt: bool, vmax: f64) -> f64 {
    let d = |i: usize, j: usize| (vel[i] - vel[j]).norm_squared();
    // Unrolled; `max0` is `f64::max` for a non-NaN first argument (from 0, a NaN is skipped
    // either way), without the NaN selects of `f64::max`.
    let rel = if vt {
        max0(max0(max0(0.0, d(0, 1)), d(0, 2)), d(0, 3))
    } else {
        max0(max0(max0(max0(0.0, d(0, 2)), d(0, 3)), d(1, 2)), d(1, 3))
    };
    rel.sqrt() * (1.0 + 1e-9) + 1e-9 * vmax
}

/// The fastest node's speed of each primitive of a pair (nodes `[p, a, b, c]` when `vt`, else
/// two edges), at least 0: `max_k |v_k|` over each primitive's nodes, as a fold from 0 with
/// `f64::max` gives it (ours).
#[cfg(test)]
fn primitive_speeds(vel: &[Vec3; 4], vt: bool) -> (f64, f64) {
    primitive_speeds_of(vel.map(|w| w.norm()), vt)
}

/// [`primitive_speeds`] from the nodes' speeds `sp`.
#[inline(always)]
fn primitive_speeds_of(sp: [f64; 4], vt: bool) -> (f64, f64) {
    if vt {
        (max0(0.0, sp[0]), max0(max0(max0(0.0, sp[1]), sp[2]), sp[3]))
    } else {
        (max0(max0(0.0, sp[0]), sp[1]), max0(max0(0.0, sp[2]), sp[3]))
    }
}

/// Per node of a pair, what [`screen_pair`] needs besides its start position and velocity:
/// its speed `|v|` and [`super::vec_abs_max`] of its velocity and of its start position. The
/// same for every pair of a node, so screening tabulates them once per pass for the cloth
/// vertices ([`super::screen`]); the same bits as computing them per pair.
#[derive(Clone, Copy, Debug, Default)]
pub struct NodeStats {
    /// `|v|`.
    pub speed: f64,
    /// Largest absolute coordinate of the velocity.
    pub vel_max: f64,
    /// Largest absolute coordinate of the start position.
    pub pos_max: f64,
}

impl NodeStats {
    /// The statistics of a node at start position `x` with velocity `v`.
    #[inline]
    pub fn of(x: &Vec3, v: &Vec3) -> NodeStats {
        NodeStats {
            speed: v.norm(),
            vel_max: super::vec_abs_max(v),
            pos_max: super::vec_abs_max(x),
        }
    }
}

/// A pair's start positions, velocities and [`NodeStats`] at velocities `v`, computed from
/// the scene (screening reads the cloth vertices' from its table instead).
#[inline]
pub fn pair_inputs(
    scene: &Scene,
    v: &[Vec3],
    nodes: &[u32; 4],
) -> ([Vec3; 4], [Vec3; 4], [NodeStats; 4]) {
    let x = scene.positions(v, nodes, 0.0);
    let vel = nodes.map(|k| scene.velocity(v, k));
    let stats = [0, 1, 2, 3].map(|k| NodeStats::of(&x[k], &vel[k]));
    (x, vel, stats)
}

/// `f64::max(m, c)` for `m` not NaN (a NaN `c` leaves `m`, as `f64::max` does), in one
/// instruction.
#[inline(always)]
fn max0(m: f64, c: f64) -> f64 {
    if c > m {
        c
    } else {
        m
    }
}

/// The distance beyond which a pair with thickness `eps` and [`relative_speed`] `rel` is
/// dormant (see [`dormant`]).
#[inline]
fn dormant_distance(eps: f64, rel: f64, h: f64) -> f64 {
    (2.0 * eps).max(eps + rel * h * (1.0 + 1e-9))
}

/// A lower bound of the distance of two edges (nodes `x`: `[ea0, ea1, eb0, eb1]`) from the
/// separating axes along the component of the centre vector (midpoint to midpoint) orthogonal to
/// the first edge and to the second one: for parallel edges side by side each is the distance of
/// their lines, where [`super::centre_gap`] loses the edges' projections onto the centre vector.
/// Each axis is used as computed (the projections of all four nodes onto it, as in
/// [`super::axis_gap`]), so rounding in the axis does not matter; `-inf` when an edge is
/// degenerate.
#[inline]
pub fn in_plane_gap(x: &[Vec3; 4]) -> f64 {
    let c = (x[2] + x[3] - x[0] - x[1]) * 0.5;
    let (e, f) = (x[1] - x[0], x[3] - x[2]);
    let (le, lf) = (e.norm_squared(), f.norm_squared());
    if !(le > 0.0 && lf > 0.0) {
        return f64::NEG_INFINITY;
    }
    let (d1, d2, d3) = (e, x[2] - x[0], x[3] - x[0]);
    // The gap between the projections of the two edges onto `u` (relative to `x[0]`).
    let along = |u: Vec3| -> f64 {
        let l2 = u.norm_squared();
        if l2.is_nan() || l2 <= 0.0 {
            return f64::NEG_INFINITY;
        }
        let (a1, b2, b3) = (d1.dot(&u), d2.dot(&u), d3.dot(&u));
        let (a_lo, a_hi) = if a1 < 0.0 { (a1, 0.0) } else { (0.0, a1) };
        let (b_lo, b_hi) = if b2 < b3 { (b2, b3) } else { (b3, b2) };
        let g = if b_lo - a_hi > a_lo - b_hi {
            b_lo - a_hi
        } else {
            a_lo - b_hi
        };
        g / l2.sqrt()
    };
    let ge = along(c - e * (c.dot(&e) / le));
    let gf = along(c - f * (c.dot(&f) / lf));
    if ge > gf {
        ge
    } else {
        gf
    }
}

/// What screening learnt about a pair's start state, for the first CCD pass: its
/// [`super::axis_gap`] (or another lower distance bound) and [`super::coordinate_scale`] at the
/// start, and its start distance if the closest points were computed.
#[derive(Clone, Copy, Debug)]
pub struct StartState {
    /// Lower distance bound at the start.
    pub gap: f64,
    /// Coordinate scale at the start.
    pub scale: f64,
    /// Start distance, when known.
    pub distance: Option<f64>,
}

/// Proximity's verdict on candidate `p` (nodes `nodes`, start positions `x`, thickness `eps`)
/// at the velocities `vel` of its nodes the step starts with (`stats`: their [`NodeStats`]),
/// what it learnt about the start state (shared with the first CCD pass), and whether the
/// start gap already shows that CCD with thickness `ccd_eps` finds nothing (the gap exceeds
/// `ccd_eps` plus the largest relative displacement of the pair's nodes over the step). With
/// `lazy` (allowed only without `within_reach`), inert pairs are [`Verdict::Dormant`] instead
/// of having their closest points computed.
#[allow(clippy::too_many_arguments)]
pub fn screen_pair(
    scene: &Scene,
    p: Pair,
    eps: f64,
    nodes: &[u32; 4],
    x: &[Vec3; 4],
    vel: &[Vec3; 4],
    stats: &[NodeStats; 4],
    lazy: bool,
    ccd_eps: f64,
) -> (Verdict, StartState, bool) {
    let vt = p.is_vertex_triangle();
    let h = scene.h;
    // `relative_speed`, `primitive_speeds` and `coordinate_scale` from the nodes' statistics.
    let rel = relative_speed_given_max(vel, vt, super::max_of_abs_maxes(&stats.map(|s| s.vel_max)));
    // Cheap rejection: the reach below is at most the fastest node of each primitive's speed
    // times h, and the distance at least the axis gap (a pair rejected here would be found
    // neither close nor active by its closest points either).
    let (speed_a, speed_b) = primitive_speeds_of(stats.map(|s| s.speed), vt);
    let reach_max = (speed_a + speed_b) * h;
    let far = (2.0 * eps).max(eps + 2.0 * reach_max);
    let dormant_at = if lazy {
        dormant_distance(eps, rel, h)
    } else {
        f64::INFINITY
    };
    let ccd_at = ccd_eps + rel * h * (1.0 + 1e-9);
    // The centre axis settles most pairs; the normal axis only when it does not.
    let scale = super::max_of_abs_maxes(&stats.map(|s| s.pos_max));
    let mut gap = super::centre_gap(x, vt);
    if !super::gap_exceeds(gap, scale, dormant_at.min(far).max(ccd_at)) {
        gap = gap.max(super::normal_gap(x, vt));
    }
    let start = StartState {
        gap,
        scale,
        distance: None,
    };
    let ccd_settled = super::gap_exceeds(gap, scale, ccd_at);
    if super::gap_exceeds(gap, scale, dormant_at) {
        return (Verdict::Dormant(*nodes), start, ccd_settled);
    }
    if super::gap_exceeds(gap, scale, far) {
        return (Verdict::Far, start, ccd_settled);
    }
    // Two edges side by side on one sheet (opposite sides of a quad, the bulk of the edge pairs
    // that get this far) are separated along the centre vector's component orthogonal to either
    // edge much better than along the centre vector itself when the quad is skewed. These axes
    // decide dormant or far (what the closest points would also decide), and settle the first
    // CCD pass's test when they exceed its thickness plus the relative motion (a valid lower
    // distance bound, like the start gap: conservative advancement would find nothing either,
    // test `screened_collisions_are_those_of_a_full_ccd_pass`); the start gap handed to the CCD
    // stays the one above.
    if !vt {
        let extra = in_plane_gap(x);
        let settled = ccd_settled || super::gap_exceeds(extra, scale, ccd_at);
        if super::gap_exceeds(extra, scale, dormant_at) {
            return (Verdict::Dormant(*nodes), start, settled);
        }
        if super::gap_exceeds(extra, scale, far) {
            return (Verdict::Far, start, settled);
        }
    }
    screen_closest(scene, p, eps, nodes, x, stats, start, ccd_settled)
}

/// The end of [`screen_pair`] for a pair that none of its cheap tests decided: the verdict from
/// the closest points at the start, `start` (what the cheap tests learnt, without a distance)
/// completed with the start distance, and `ccd_settled` as the start gap left it. Screening's
/// lanes (module `rejection`) call it directly for the pairs they find undecided, with the
/// `start` and `ccd_settled` that [`screen_pair`] would have passed.
#[allow(clippy::too_many_arguments)]
pub fn screen_closest(
    scene: &Scene,
    p: Pair,
    eps: f64,
    nodes: &[u32; 4],
    x: &[Vec3; 4],
    stats: &[NodeStats; 4],
    mut start: StartState,
    ccd_settled: bool,
) -> (Verdict, StartState, bool) {
    let (vt, h) = (p.is_vertex_triangle(), scene.h);
    let geom = closest(x, vt);
    start.distance = Some(geom.distance);
    // Only pairs that could come within eps during the step matter.
    let reach: f64 = (0..4)
        .map(|k| geom.weights[k].abs() * stats[k].speed)
        .sum::<f64>()
        * h;
    let gap = geom.distance - eps;
    let close = geom.distance < 2.0 * eps;
    let active = gap <= 2.0 * reach;
    if !active && !close {
        return (Verdict::Far, start, ccd_settled);
    }
    // Target normal velocity: approach no closer than eps by the end of the step; inside eps,
    // move out at PUSH_OUT of the overlap per step.
    let target = if gap >= 0.0 {
        -gap / h
    } else {
        -PUSH_OUT * gap / h
    };
    (
        Verdict::Near(Near {
            pair: p,
            nodes: *nodes,
            geom,
            target,
            mu: scene.friction_of(p),
            active,
            close,
            impulsed: false,
            tested_at: 0,
        }),
        start,
        ccd_settled,
    )
}

/// The proximity pairs of a step in candidate order: each either looked at ([`Near`]) or
/// dormant (evaluated on demand), as [`screen_pair`] decided. Kept as the parts screening
/// produced for consecutive chunks of candidates, one after the other (not copied into one).
#[derive(Default)]
pub struct NearList {
    parts: Vec<Part>,
}

/// The pairs of one chunk of candidates.
#[derive(Default)]
struct Part {
    /// Per kept candidate: the pair and the index of its [`Near`] in `nears`, or [`DORMANT`]
    /// plus the index of its nodes in `dormant` until evaluated, [`FAR`] once evaluated as far.
    slots: Vec<(Pair, u32)>,
    nears: Vec<Near>,
    /// The nodes of the dormant pairs (what the sweeps look at to decide whether to wake one).
    dormant: Vec<[u32; 4]>,
}

/// Slot marker bit: dormant, not evaluated (the low bits index `Part::dormant`).
const DORMANT: u32 = 1 << 31;
/// Slot marker: evaluated on demand, far.
const FAR: u32 = u32::MAX;

impl NearList {
    /// Appends a dormant candidate with nodes `nodes` (in candidate order): what
    /// [`NearList::push`] does with [`Verdict::Dormant`], without moving a whole verdict.
    #[inline]
    pub fn push_dormant(&mut self, pair: Pair, nodes: [u32; 4]) {
        if self.parts.is_empty() {
            self.parts.push(Part::default());
        }
        let part = self.parts.last_mut().expect("a part");
        debug_assert!(part.dormant.len() < (DORMANT - 1) as usize);
        part.slots.push((pair, DORMANT | part.dormant.len() as u32));
        part.dormant.push(nodes);
    }

    /// Appends a candidate's verdict (in candidate order).
    pub fn push(&mut self, pair: Pair, verdict: Verdict) {
        if self.parts.is_empty() {
            self.parts.push(Part::default());
        }
        let part = self.parts.last_mut().expect("a part");
        match verdict {
            Verdict::Far => {}
            Verdict::Dormant(nodes) => self.push_dormant(pair, nodes),
            Verdict::Near(n) => {
                debug_assert!(part.nears.len() < DORMANT as usize);
                part.slots.push((pair, part.nears.len() as u32));
                part.nears.push(n);
            }
        }
    }

    /// An empty list with room for the verdicts of `candidates` pairs.
    pub fn with_capacity(candidates: usize) -> NearList {
        NearList {
            parts: vec![Part {
                slots: Vec::with_capacity(candidates),
                nears: Vec::with_capacity(candidates / 2),
                dormant: Vec::with_capacity(candidates / 2),
            }],
        }
    }

    /// The lists of consecutive chunks of candidates, one after the other (the parts are moved,
    /// not copied).
    pub fn concat(lists: Vec<NearList>) -> NearList {
        NearList {
            parts: lists.into_iter().flat_map(|l| l.parts).collect(),
        }
    }

    /// Pairs kept for the sweeps (close or within reach, `Near`); pairs whose closest points
    /// were computed and found far are not counted.
    pub fn evaluated(&self) -> usize {
        self.parts.iter().map(|p| p.nears.len()).sum()
    }

    /// Dormant pairs never evaluated.
    pub fn dormant(&self) -> usize {
        self.slots()
            .filter(|(_, i)| *i != FAR && *i & DORMANT != 0)
            .count()
    }

    /// Every slot in candidate order, with its dormant pair's nodes or its [`Near`]'s fields
    /// as bits (tests compare lists with it).
    #[cfg(test)]
    pub(super) fn fingerprint(&self) -> Vec<(Pair, Vec<u64>)> {
        let mut out = Vec::new();
        for part in &self.parts {
            for &(pair, i) in &part.slots {
                let bits = if i != FAR && i & DORMANT != 0 {
                    part.dormant[(i & !DORMANT) as usize]
                        .iter()
                        .map(|&k| k as u64)
                        .collect()
                } else if i == FAR {
                    vec![u64::MAX]
                } else {
                    let n = &part.nears[i as usize];
                    let g = &n.geom;
                    let mut b: Vec<u64> = [g.distance, n.target, n.mu]
                        .iter()
                        .chain(g.normal.iter())
                        .chain(g.weights.iter())
                        .map(|x| x.to_bits())
                        .collect();
                    b.extend(n.nodes.iter().map(|&k| k as u64));
                    b.extend([n.active as u64, n.close as u64]);
                    b
                };
                out.push((pair, bits));
            }
        }
        out
    }

    /// Every slot, in candidate order.
    fn slots(&self) -> impl Iterator<Item = &(Pair, u32)> {
        self.parts.iter().flat_map(|p| p.slots.iter())
    }
}

/// Applies proximity impulses to `v` (equal to `v_start` on entry) on candidates already
/// screened ([`screen_pair`] at `v_start`, in candidate order, see [`super::screen`]): the
/// Gauss-Seidel sweeps, dormant pairs evaluated (with the start velocities, as [`screen_pair`]
/// would have) once an impulse changed a velocity of one of their nodes. The impulses, their
/// order and the resting contacts are those of screening every pair eagerly. Returns the number
/// of impulses applied and the cloth-cloth pairs that started within twice their thickness or
/// received an impulse, and with `within_reach` also those that could come within it during the
/// step (contacts the next step treats inside the implicit solve, see [`crate::sim::contact`]).
pub fn repel_screened(
    scene: &Scene,
    v: &mut [Vec3],
    v_start: &[Vec3],
    near: NearList,
    policy: &dyn ContactPolicy,
    within_reach: bool,
) -> (usize, Vec<Pair>) {
    let (applied, near) = sweeps(scene, v, v_start, near, policy);
    (applied, resting_of(&near, within_reach))
}

/// The resting contacts for the next step after the sweeps: pairs that start close, and pairs
/// whose approach an impulse just stopped (they end the step near their thickness), cloth-cloth
/// only, in candidate order. Pairs that were merely within reach of fast motion are not, unless
/// `within_reach`: linearised at the next step's start, far pairs of fast cloth would all look
/// like contacts. (Dormant pairs are neither close nor impulsed.)
fn resting_of(near: &NearList, within_reach: bool) -> Vec<Pair> {
    near.parts
        .iter()
        .flat_map(|part| {
            part.slots
                .iter()
                .filter(|(_, i)| *i & DORMANT == 0)
                .map(|(_, i)| &part.nears[*i as usize])
        })
        .filter(|n| {
            matches!(n.pair.kind, PairKind::VertexTriangle | PairKind::EdgeEdge)
                && (n.impulsed || n.close || within_reach)
        })
        .map(|n| n.pair)
        .collect()
}

/// The Gauss-Seidel sweeps of [`repel_screened`] (`v` equal to `v_start` on entry): impulses
/// applied, and the list with the dormant pairs it had to evaluate and, per [`Near`], whether it
/// received an impulse.
///
/// A pair's relative normal velocity depends only on its nodes' velocities, so a pair that got
/// no impulse is tested again only once one of them has changed since (per node, the count of
/// impulses when it last changed; per pair, the count when it was last tested): the same
/// impulses in the same order as testing every pair in every sweep (test
/// `lazy_screening_repels_exactly_like_eager_screening`).
fn sweeps(
    scene: &Scene,
    v: &mut [Vec3],
    v_start: &[Vec3],
    mut near: NearList,
    policy: &dyn ContactPolicy,
) -> (usize, NearList) {
    debug_assert!(v == v_start);
    // Per node, the number of impulses applied when its velocity last changed (0: never).
    let mut changed_at = vec![0u32; v.len()];
    // Whether a cloth node of `nodes` changed at impulse `since` or later.
    let changed_since = |changed_at: &[u32], nodes: &[u32; 4], since: u32| {
        nodes
            .iter()
            .any(|&k| k & super::OBSTACLE == 0 && changed_at[k as usize] >= since)
    };
    let mut applied = 0;
    for _ in 0..SWEEPS {
        let mut any = false;
        for part in &mut near.parts {
            for s in 0..part.slots.len() {
                let (pair, mut index) = part.slots[s];
                if index == FAR {
                    continue;
                }
                if index & DORMANT != 0 {
                    if applied == 0 {
                        // No velocity has changed yet.
                        continue;
                    }
                    let nodes = part.dormant[(index & !DORMANT) as usize];
                    if !changed_since(&changed_at, &nodes, 1) {
                        continue;
                    }
                    // A node moved: the pair's verdict as eager screening would have given it.
                    let eps = scene
                        .thickness(pair, policy)
                        .expect("dormant pairs have a thickness");
                    let (x, vel, stats) = pair_inputs(scene, v_start, &nodes);
                    index =
                        match screen_pair(scene, pair, eps, &nodes, &x, &vel, &stats, false, 0.0).0
                        {
                            Verdict::Near(n) => {
                                part.nears.push(n);
                                (part.nears.len() - 1) as u32
                            }
                            _ => FAR,
                        };
                    part.slots[s].1 = index;
                    if index == FAR {
                        continue;
                    }
                }
                let n = &mut part.nears[index as usize];
                if !n.active {
                    continue;
                }
                // Tested before, and none of its nodes changed since: still no impulse.
                if n.tested_at != 0 && !changed_since(&changed_at, &n.nodes, n.tested_at) {
                    continue;
                }
                n.tested_at = applied + 1;
                let g = &n.geom;
                let vn: f64 = (0..4)
                    .map(|k| g.weights[k] * g.normal.dot(&scene.velocity(v, n.nodes[k])))
                    .sum();
                if vn >= n.target - 1e-12 * n.target.abs() {
                    continue;
                }
                if let Some(dv) = impulse(
                    scene,
                    v,
                    &n.nodes,
                    &g.weights,
                    &g.normal,
                    n.target - vn,
                    n.mu,
                ) {
                    applied += 1;
                    for k in 0..4 {
                        if n.nodes[k] & super::OBSTACLE == 0 {
                            v[n.nodes[k] as usize] += dv[k];
                            changed_at[n.nodes[k] as usize] = applied;
                        }
                    }
                    any = true;
                    n.impulsed = true;
                }
            }
        }
        if !any {
            break;
        }
    }
    (applied as usize, near)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec2;
    use crate::mesh::Topology;
    use crate::sim::collision::coordinate_for_tests as coordinate;
    use crate::sim::collision::obstacle_free_scene_for_tests as scene_of;
    use crate::sim::policy::UniformThickness;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn v3(a: [f64; 3]) -> Vec3 {
        Vec3::new(a[0], a[1], a[2])
    }

    /// The node split of a pair: nodes `..split` are one primitive (the vertex when `vt`, else
    /// the first edge), `split..4` the other.
    fn split_of(vt: bool) -> usize {
        if vt {
            1
        } else {
            2
        }
    }

    /// Plain `f64::max` fold of `amax` over four vectors (from 0).
    fn amax_fold(p: &[Vec3; 4]) -> f64 {
        p.iter().fold(0.0f64, |m, w| m.max(w.amax()))
    }

    /// Plain oracle of [`relative_speed`]: the loop over node pairs with `f64::max`.
    fn plain_relative_speed(vel: &[Vec3; 4], vt: bool) -> f64 {
        let split = split_of(vt);
        let mut rel = 0.0f64;
        for i in 0..split {
            for j in split..4 {
                rel = rel.max((vel[i] - vel[j]).norm_squared());
            }
        }
        rel.sqrt() * (1.0 + 1e-9) + 1e-9 * amax_fold(vel)
    }

    /// Plain oracle of [`primitive_speeds`]: each primitive's fastest node, a `f64::max` fold
    /// from 0.
    fn plain_primitive_speeds(vel: &[Vec3; 4], vt: bool) -> (f64, f64) {
        let split = split_of(vt);
        let speed = |r: std::ops::Range<usize>| r.map(|k| vel[k].norm()).fold(0.0f64, f64::max);
        (speed(0..split), speed(split..4))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Oracle for the unrolled [`relative_speed`]: the previous loop with `f64::max`
        /// (written out here) gives the same bits, also with signed zeros, infinities and NaNs.
        #[test]
        fn relative_speed_equals_the_max_fold(
            v in prop::array::uniform4(prop::array::uniform3(coordinate())),
            vt in any::<bool>(),
        ) {
            let vel = v.map(v3);
            let want = plain_relative_speed(&vel, vt);
            let got = relative_speed(&vel, vt);
            prop_assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "{got} vs {want}");
            let (a, b) = primitive_speeds(&vel, vt);
            let (wa, wb) = plain_primitive_speeds(&vel, vt);
            prop_assert_eq!((a.to_bits(), b.to_bits()), (wa.to_bits(), wb.to_bits()));
            let scale = crate::sim::collision::abs_max(&vel);
            prop_assert_eq!(scale.to_bits(), amax_fold(&vel).to_bits());
        }

        /// Oracle for the per-node statistics [`screen_pair`] reads (tabulated per vertex by
        /// screening): the relative speed, the primitives' speeds and the coordinate scale they
        /// give equal, bit for bit, the plain per-pair formulas (`f64::max` folds of the
        /// velocity differences, the speeds and `amax`), also with signed zeros, infinities
        /// and NaNs.
        #[test]
        fn node_stats_give_the_per_pair_bits(
            v in prop::array::uniform4(prop::array::uniform3(coordinate())),
            x in prop::array::uniform4(prop::array::uniform3(coordinate())),
            vt in any::<bool>(),
        ) {
            let (vel, x) = (v.map(v3), x.map(v3));
            let stats = [0, 1, 2, 3].map(|k| NodeStats::of(&x[k], &vel[k]));
            let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
            let want = plain_relative_speed(&vel, vt);
            let vmax = crate::sim::collision::max_of_abs_maxes(&stats.map(|s| s.vel_max));
            let got = relative_speed_given_max(&vel, vt, vmax);
            prop_assert!(same(got, want), "{got} vs {want}");
            let (a, b) = primitive_speeds_of(stats.map(|s| s.speed), vt);
            let (wa, wb) = plain_primitive_speeds(&vel, vt);
            prop_assert_eq!((a.to_bits(), b.to_bits()), (wa.to_bits(), wb.to_bits()));
            let scale = crate::sim::collision::max_of_abs_maxes(&stats.map(|s| s.pos_max));
            prop_assert_eq!(scale.to_bits(), amax_fold(&x).to_bits());
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Oracle for [`dormant`]: a dormant pair is farther than twice its thickness and its
        /// relative normal velocity at the closest points (computed exactly as the sweeps do)
        /// does not reach the impulse threshold.
        #[test]
        fn dormant_pairs_are_not_close_and_get_no_impulse(
            vt in any::<bool>(),
            x in prop::array::uniform4(prop::array::uniform3(-0.05f64..0.05)),
            v in prop::array::uniform4(prop::array::uniform3(-2.0f64..2.0)),
            eps in 1e-4f64..5e-3,
            h in 1e-3f64..0.05,
        ) {
            let x = x.map(v3);
            let vel = v.map(v3);
            if dormant(&x, &vel, vt, eps, h) {
                let g = closest(&x, vt);
                prop_assert!(g.distance >= 2.0 * eps);
                let gap = g.distance - eps;
                let target = -gap / h;
                let vn: f64 = (0..4).map(|k| g.weights[k] * g.normal.dot(&vel[k])).sum();
                prop_assert!(vn >= target - 1e-12 * target.abs(), "vn {vn} target {target}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Oracle for [`in_plane_gap`]: never above the edges' distance (closest points), on
        /// random edges and on nearly parallel edges side by side (where it is tight).
        #[test]
        fn in_plane_gap_never_exceeds_the_distance(
            x in prop::array::uniform4(prop::array::uniform3(-0.05f64..0.05)),
            side in any::<bool>(),
            skew in -1e-3f64..1e-3,
        ) {
            let mut x = x.map(v3);
            if side {
                // Opposite sides of a (skewed, bent) quad, 1 cm apart.
                let e = x[1] - x[0];
                let o = e.cross(&Vec3::z()).try_normalize(1e-9).unwrap_or(Vec3::x()) * 0.01;
                x[2] = x[0] + o + e * (skew / 0.01) + Vec3::z() * (0.3 * skew);
                x[3] = x[1] + o - e * (skew / 0.01) + Vec3::z() * skew;
            }
            let d = closest(&x, false).distance;
            let g = in_plane_gap(&x);
            let scale = crate::sim::collision::coordinate_scale(&x);
            prop_assert!(g <= d * (1.0 + 1e-12) + 1e-12 * scale, "gap {g} distance {d}");
            if side && (x[1] - x[0]).norm() > 0.02 {
                prop_assert!(g > 0.5 * d, "not tight: gap {g} distance {d}");
            }
        }
    }

    /// [`dormant`] is not vacuous: nearby pairs moving together are dormant, the same pairs
    /// approaching each other fast are not.
    #[test]
    fn dormant_accepts_coherent_motion_and_rejects_approach() {
        let x = [
            Vec3::new(0.0, 0.0, 0.02),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.02, 0.0, 0.0),
            Vec3::new(0.0, 0.02, 0.0),
        ];
        let same = [Vec3::new(1.0, -0.5, 0.3); 4];
        assert!(dormant(&x, &same, true, 2e-3, 0.02));
        let mut approach = same;
        approach[0].z -= 1.0;
        assert!(!dormant(&x, &approach, true, 2e-3, 0.02));
    }

    /// Lazy screening (dormant pairs evaluated on demand) against eager screening (every pair's
    /// closest points at once), and eager screening against plain sweeps that test every pair
    /// in every sweep ([`plain_sweeps`], the oracle of the sweeps' skipping of pairs whose nodes
    /// did not change): on crumpled sheets with random velocities, strong enough for many
    /// impulses, the velocities after proximity, the impulse count and the resting contacts are
    /// identical, bit for bit.
    #[test]
    fn lazy_screening_repels_exactly_like_eager_screening() {
        let (mut woke, mut in_plane, mut busy_sweeps) = (0, 0, 0);
        // (seed, layers, layer gap, share of kicked vertices, largest kick): two layers with
        // sparse kicks wake dormant pairs; three layers 4 mm apart (within twice the
        // thickness), the outer ones squeezing the middle one, chain impulses over sweeps.
        let cases = (0..8u64)
            .map(|seed| (seed, 2, 7e-3, 0.05, 0.8))
            .chain((8..12u64).map(|seed| (seed, 3, 4e-3, 0.5, 2.0)));
        for (seed, layers, layer_gap, kicked, kick_max) in cases {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            // Wavy sheets `layer_gap` apart (thickness 3 mm: at 7 mm the layers' pairs are
            // beyond twice the thickness), moving together with a smooth swing; a share of the
            // vertices gets a random kick across the gap (with three layers, the outer ones
            // towards the middle one).
            let a = crate::scenes::handkerchief("a", 12, 12, 0.2, 0.2, |uv: Vec2| {
                Vec3::new(uv.x, 0.01 * (30.0 * uv.x).sin() * (20.0 * uv.y).cos(), uv.y)
            });
            let na = a.positions.len() as u32;
            let (mut positions, mut triangles) = (Vec::new(), Vec::new());
            for l in 0..layers {
                let shift = Vec3::new(0.0, layer_gap * l as f64, 0.0);
                positions.extend(a.positions.iter().map(|p| p + shift));
                triangles.extend(a.triangles.iter().map(|t| t.map(|k| k + na * l)));
            }
            let sheet = crate::mesh::Mesh::new("two", positions, triangles).unwrap();
            let topo = Topology::new(&sheet).unwrap();
            let n = sheet.positions.len();
            let x0 = sheet.positions.clone();
            let (hinge, inv_mass) = (vec![[u32::MAX; 3]; sheet.triangles.len()], vec![1.0; n]);
            let obstacles = Default::default();
            let scene = scene_of(
                &x0,
                &sheet.triangles,
                &topo.edges,
                &hinge,
                &obstacles,
                &inv_mass,
            );
            let swing = Vec3::new(rng.random_range(-1.0..1.0), 0.3, 0.5);
            let v0: Vec<Vec3> = x0
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let kick = if rng.random_bool(kicked) {
                        // Squeezing: the bottom layer up, the top one down (of three).
                        let l = i as u32 / na;
                        let k: f64 = rng.random_range(-kick_max..kick_max);
                        let k = match (layers, l) {
                            (3, 0) => k.abs(),
                            (3, 2) => -k.abs(),
                            _ => k,
                        };
                        Vec3::new(0.0, k, 0.0)
                    } else {
                        Vec3::zeros()
                    };
                    swing * (1.0 + p.x) + kick
                })
                .collect();
            let policy = UniformThickness(3e-3);
            let margin = policy.0 * 1.0001;
            let mut broad = super::super::broad::BroadPhase::default();
            broad.update(&scene, &v0, margin, true);
            let cands = broad.candidates(&scene, &v0, margin);
            for within_reach in [false, true] {
                let mut eager = NearList::default();
                let mut plain = Vec::new();
                for &p in &cands {
                    if let Some(eps) = scene.thickness(p, &policy) {
                        eager.push(p, oracle_verdict(&scene, &v0, p, eps));
                        if let Verdict::Near(n) = oracle_verdict(&scene, &v0, p, eps) {
                            plain.push(n);
                        }
                    }
                }
                let mut va = v0.clone();
                let (ia, ra) = repel_screened(&scene, &mut va, &v0, eager, &policy, within_reach);
                // Against the plain Gauss-Seidel sweeps (every pair tested in every sweep).
                let mut vp = v0.clone();
                let (ip, rp, busy) = plain_sweeps(&scene, &mut vp, plain, within_reach);
                busy_sweeps = busy_sweeps.max(busy);
                assert_eq!(ia, ip, "seed {seed}");
                assert_eq!(ra, rp, "seed {seed}");
                assert!(
                    va == vp,
                    "seed {seed}: velocities differ from the plain sweeps"
                );
                // The real path: the shared screening pass, then the sweeps.
                let lazy_list =
                    super::super::screen::screen(&scene, &v0, &cands, &policy, Some(within_reach))
                        .near;
                let dormant_before = lazy_list.dormant();
                if !within_reach {
                    assert!(
                        dormant_before > 0 || layer_gap < 5e-3,
                        "seed {seed}: no dormant pair"
                    );
                    // Edge pairs made dormant by the in-plane axes alone (the axis gap would
                    // have needed their closest points).
                    for &(p, i) in lazy_list.slots() {
                        if i != FAR && i & DORMANT != 0 && !p.is_vertex_triangle() {
                            let nodes = scene.nodes(p);
                            let x = scene.positions(&v0, &nodes, 0.0);
                            let vel = nodes.map(|k| scene.velocity(&v0, k));
                            in_plane += !dormant(&x, &vel, false, policy.0, scene.h) as usize;
                        }
                    }
                }
                let mut vb = v0.clone();
                let mut lazy = lazy_list;
                let before = lazy.evaluated();
                let (ib, after) = sweeps(&scene, &mut vb, &v0, lazy, &policy);
                lazy = after;
                woke += lazy.evaluated() - before;
                let rb = resting_of(&lazy, within_reach);
                assert!(ia > 0, "seed {seed}: no impulse");
                assert_eq!(ia, ib, "seed {seed}");
                assert_eq!(ra, rb, "seed {seed}");
                assert!(va == vb, "seed {seed}: velocities differ");
            }
        }
        assert!(woke > 0, "no dormant pair was ever woken");
        assert!(
            busy_sweeps >= 3,
            "impulses in {busy_sweeps} sweeps: too few to test"
        );
        assert!(
            in_plane > 0,
            "no edge pair was made dormant by the in-plane axes"
        );
    }

    /// The sweeps' skipping (a pair that got no impulse is tested again only once a node of it
    /// changed) against [`plain_sweeps`] (every active pair in every sweep), on
    /// random pair lists over few nodes (pairs share nodes with many others, so impulses chain
    /// within and across sweeps, and often still change velocities in the last sweep):
    /// the same impulses, velocities (bit for bit) and resting contacts. Some nodes are pinned
    /// (an impulse that changes no velocity).
    #[test]
    fn sweeps_apply_the_impulses_of_plain_gauss_seidel() {
        let (mut chained, mut cut) = (0, 0);
        for seed in 0..1000u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let n = rng.random_range(5..60usize);
            let x0 = vec![Vec3::zeros(); n];
            let inv_mass: Vec<f64> = (0..n)
                .map(|_| {
                    if rng.random_bool(0.1) {
                        0.0
                    } else {
                        rng.random_range(0.5..2.0)
                    }
                })
                .collect();
            let obstacles = Default::default();
            let scene = scene_of(&x0, &[], &[], &[], &obstacles, &inv_mass);
            let rv = |rng: &mut ChaCha8Rng| {
                Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
            };
            let v0: Vec<Vec3> = (0..n).map(|_| rv(&mut rng)).collect();
            let mut nears = Vec::new();
            let count = rng.random_range(1..60u32);
            // Some lists with few impulses in the first sweep (chains start later).
            let low = if rng.random_bool(0.5) { -0.5 } else { -2.0 };
            for i in 0..count {
                let mut nodes = [0u32; 4];
                let mut k = 0;
                while k < 4 {
                    let c = rng.random_range(0..n as u32);
                    if !nodes[..k].contains(&c) {
                        nodes[k] = c;
                        k += 1;
                    }
                }
                let (b0, b1): (f64, f64) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
                let (b0, b1) = if b0 + b1 > 1.0 {
                    (1.0 - b0, 1.0 - b1)
                } else {
                    (b0, b1)
                };
                let normal = rv(&mut rng).try_normalize(1e-9).unwrap_or(Vec3::z());
                nears.push(Near {
                    pair: Pair {
                        kind: if i % 2 == 0 {
                            PairKind::VertexTriangle
                        } else {
                            PairKind::EdgeEdge
                        },
                        a: i,
                        b: i,
                    },
                    nodes,
                    geom: Closest {
                        distance: 1e-3,
                        normal,
                        weights: [1.0, -b0, -b1, -(1.0 - b0 - b1)],
                    },
                    target: rng.random_range(low..0.5),
                    mu: 0.1,
                    active: rng.random_bool(0.9),
                    close: rng.random_bool(0.3),
                    impulsed: false,
                    tested_at: 0,
                });
            }
            for within_reach in [false, true] {
                let mut list = NearList::default();
                for near in &nears {
                    list.push(near.pair, Verdict::Near(Near { ..*near }));
                }
                let mut va = v0.clone();
                let (ia, ra) =
                    repel_screened(&scene, &mut va, &v0, list, &NoContacts, within_reach);
                let mut vp = v0.clone();
                let copies = nears.iter().map(|near| Near { ..*near }).collect();
                let (ip, rp, busy) = plain_sweeps(&scene, &mut vp, copies, within_reach);
                assert_eq!(ia, ip, "seed {seed}");
                assert_eq!(ra, rp, "seed {seed}");
                assert!(
                    va == vp,
                    "seed {seed}: velocities differ from the plain sweeps"
                );
                chained += (busy >= 3) as usize;
                cut += (busy == SWEEPS) as usize;
            }
        }
        assert!(
            chained > 50 && cut > 10,
            "{chained} chained, {cut} cut: too few to test"
        );
    }

    /// A policy for lists without dormant pairs (never asked).
    struct NoContacts;

    impl ContactPolicy for NoContacts {
        fn max_thickness(&self) -> f64 {
            0.0
        }
        fn vertex_triangle(&self, _: u32, _: u32) -> crate::sim::policy::Contact {
            unreachable!("no dormant pair")
        }
        fn edge_edge(&self, _: u32, _: u32) -> crate::sim::policy::Contact {
            unreachable!("no dormant pair")
        }
    }

    /// Plain Gauss-Seidel sweeps over the close or active pairs `nears` (in candidate order):
    /// every active pair tested in every sweep, until a sweep applies no impulse. Returns the
    /// impulses applied, the resting contacts (as [`resting_of`] defines them) and the number
    /// of sweeps that applied impulses.
    fn plain_sweeps(
        scene: &Scene,
        v: &mut [Vec3],
        nears: Vec<Near>,
        within_reach: bool,
    ) -> (usize, Vec<Pair>, usize) {
        let mut hit = vec![false; nears.len()];
        let (mut applied, mut busy) = (0, 0);
        for _ in 0..SWEEPS {
            let mut any = false;
            for (i, n) in nears.iter().enumerate() {
                if !n.active {
                    continue;
                }
                let g = &n.geom;
                let vn: f64 = (0..4)
                    .map(|k| g.weights[k] * g.normal.dot(&scene.velocity(v, n.nodes[k])))
                    .sum();
                if vn >= n.target - 1e-12 * n.target.abs() {
                    continue;
                }
                let dv = impulse(
                    scene,
                    v,
                    &n.nodes,
                    &g.weights,
                    &g.normal,
                    n.target - vn,
                    n.mu,
                );
                if let Some(dv) = dv {
                    for k in 0..4 {
                        if n.nodes[k] & super::super::OBSTACLE == 0 {
                            v[n.nodes[k] as usize] += dv[k];
                        }
                    }
                    applied += 1;
                    any = true;
                    hit[i] = true;
                }
            }
            if !any {
                break;
            }
            busy += 1;
        }
        let resting = nears
            .iter()
            .zip(&hit)
            .filter(|(n, h)| {
                matches!(n.pair.kind, PairKind::VertexTriangle | PairKind::EdgeEdge)
                    && (**h || n.close || within_reach)
            })
            .map(|(n, _)| n.pair)
            .collect();
        (applied, resting, busy)
    }

    /// The definition of proximity's verdict, with every pair's closest points (no bound, no
    /// shortcut): close (within twice the thickness) or active (could come within it by the
    /// end of the step, to first order with the nodes' speeds), else far.
    fn oracle_verdict(scene: &Scene, v: &[Vec3], p: Pair, eps: f64) -> Verdict {
        let vt = p.is_vertex_triangle();
        let nodes = scene.nodes(p);
        let x = scene.positions(v, &nodes, 0.0);
        let geom = closest(&x, vt);
        let reach: f64 = (0..4)
            .map(|k| geom.weights[k].abs() * scene.velocity(v, nodes[k]).norm())
            .sum::<f64>()
            * scene.h;
        let gap = geom.distance - eps;
        let (close, active) = (geom.distance < 2.0 * eps, gap <= 2.0 * reach);
        if !close && !active {
            return Verdict::Far;
        }
        let target = if gap >= 0.0 {
            -gap / scene.h
        } else {
            -PUSH_OUT * gap / scene.h
        };
        Verdict::Near(Near {
            pair: p,
            nodes,
            geom,
            target,
            mu: scene.friction_of(p),
            active,
            close,
            impulsed: false,
            tested_at: 0,
        })
    }
}
