//! The trial step (ours): a prediction of the colouring after a simulator step, by running it.
//!
//! Sec. 7 of Cha & Ko 2022 argues that the red-vertex count never increases (theorem, part 1:
//! "a green vertex can never become red", footnote 7). Our runs contradict it: when two red
//! *edges* cross, the intersection curves reconnect there, and the smaller side of a path can
//! then hold vertices that no curve swept over (docs/cha-ko.md, "Why the red-vertex count is not
//! monotone"). A rule fixed in advance (mixed edges never cross, persistent green) made the
//! count monotone but froze the resolution, because it cannot tell the harmful crossings from
//! the ones that resolve the tanglement.
//!
//! The trial step tells them apart after the fact: the loop takes the step, analyses the result,
//! and if the red-vertex count went up ([`TrialTrigger`]: or any vertex green at the start of the
//! step is red now), it rolls the simulator back and takes the step again with exactly the red-red pairs whose *new* crossings caused it
//! held apart ([`pairs_to_block`]): for every edge-triangle crossing of the result that was not
//! there before and touches a newly red vertex (the edge has it as an end, or the triangle as a
//! corner), the two vertex-triangle pairs (each end of the edge against the triangle) and the
//! three edge-edge pairs (the edge against each edge of the triangle) through which the crossing
//! must have appeared. When no new crossing touches a newly red vertex, every new crossing is
//! blocked. Everything else keeps the paper's m-CCH rule ([`super::policy`]). After
//! [`super::Params::trial_retries`] retries the step is accepted as it is and reported.
//!
//! Measured (docs/cha-ko.md, BENCHMARKS.md): the count becomes monotone only where the blocks
//! freeze the resolution (the increases are passages the resolution needs), so the trial step
//! is off by default.

use super::policy::{rule, MchPolicy, PairColour};
use super::Params;
use crate::analysis::{analyze_with, Analysis, AnalysisMesh, Crossing, Options};
use crate::error::Result;
use crate::geom::Vec3;
use crate::sim::policy::ObstaclePair;
use crate::sim::{Contact, ContactPolicy};
use crate::sim::{Simulator, StepReport};
use std::collections::BTreeMap;
use std::time::Instant;

/// How a blocked red-red pair is handled in the retried step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum TrialBlock {
    /// As a green-green pair: the ordinary `epsilon` (it may not cross).
    GreenGreen,
    /// As a red-green pair: `epsilon_RG`.
    RedGreen,
}

/// When a step is retried.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum TrialTrigger {
    /// Any vertex green at the start of the step is red after it (footnote 7's claim).
    AnyNewlyRed,
    /// The red-vertex count went up (the theorem's statement, part 1).
    CountIncrease,
}

/// Which new crossings at a newly red vertex are blocked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum TrialScope {
    /// Crossings whose edge ends at, or whose triangle has a corner at, a newly red vertex.
    EdgesAndTriangles,
    /// Only crossings whose edge ends at a newly red vertex (its *mixed* edges).
    Edges,
}

/// Red-red elementary pairs held apart in a retried step (sorted, no duplicates).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Blocked {
    /// (vertex, triangle) pairs.
    pub vertex_triangle: Vec<(u32, u32)>,
    /// (edge, edge) pairs, smaller index first (topology edge indices).
    pub edge_edge: Vec<(u32, u32)>,
}

impl Blocked {
    /// Whether nothing is blocked.
    pub fn is_empty(&self) -> bool {
        self.vertex_triangle.is_empty() && self.edge_edge.is_empty()
    }

    /// Number of blocked pairs.
    pub fn len(&self) -> usize {
        self.vertex_triangle.len() + self.edge_edge.len()
    }

    /// Removes the pairs for which `keep` is false.
    pub fn retain(&mut self, mut keep: impl FnMut(BlockedPair) -> bool) {
        self.vertex_triangle
            .retain(|&(v, t)| keep(BlockedPair::VertexTriangle(v, t)));
        self.edge_edge
            .retain(|&(a, b)| keep(BlockedPair::EdgeEdge(a, b)));
    }

    /// Every pair, vertex-triangle pairs first.
    pub fn pairs(&self) -> impl Iterator<Item = BlockedPair> + '_ {
        self.vertex_triangle
            .iter()
            .map(|&(v, t)| BlockedPair::VertexTriangle(v, t))
            .chain(
                self.edge_edge
                    .iter()
                    .map(|&(a, b)| BlockedPair::EdgeEdge(a, b)),
            )
    }

    /// Adds the pairs of `other`.
    pub fn extend(&mut self, other: &Blocked) {
        self.vertex_triangle
            .extend_from_slice(&other.vertex_triangle);
        self.edge_edge.extend_from_slice(&other.edge_edge);
        self.normalise();
    }

    fn normalise(&mut self) {
        self.vertex_triangle.sort_unstable();
        self.vertex_triangle.dedup();
        self.edge_edge.sort_unstable();
        self.edge_edge.dedup();
    }

    /// The pairs through which the crossing `c` (edge through triangle) of `mesh` can appear
    /// between two moments: an end of the edge passes through the triangle, or the edge passes
    /// through one of the triangle's edges.
    pub fn add_crossing(&mut self, mesh: &AnalysisMesh, c: Crossing) {
        let topo = &mesh.topology;
        let [p, q] = topo.edges[c.edge as usize];
        let t = c.triangle;
        self.vertex_triangle.push((p, t));
        self.vertex_triangle.push((q, t));
        for &e in &topo.triangle_edges[t as usize] {
            if e != c.edge {
                self.edge_edge.push((e.min(c.edge), e.max(c.edge)));
            }
        }
    }

    fn has_vt(&self, v: u32, t: u32) -> bool {
        !self.vertex_triangle.is_empty() && self.vertex_triangle.binary_search(&(v, t)).is_ok()
    }

    fn has_ee(&self, a: u32, b: u32) -> bool {
        !self.edge_edge.is_empty() && self.edge_edge.binary_search(&(a.min(b), a.max(b))).is_ok()
    }
}

/// One blocked elementary pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum BlockedPair {
    /// Vertex, triangle.
    VertexTriangle(u32, u32),
    /// Two edges, smaller index first.
    EdgeEdge(u32, u32),
}

/// Vertices green in `before` and red in `after` (sorted; the garment's vertices only, which
/// come first in an analysis mesh).
pub fn newly_red(before: &Analysis, after: &Analysis) -> Vec<u32> {
    before
        .coloring
        .red_vertex
        .iter()
        .zip(&after.coloring.red_vertex)
        .enumerate()
        .filter(|(_, (&b, &a))| !b && a)
        .map(|(v, _)| v as u32)
        .collect()
}

/// Which pairs to hold apart when the step from `before` to `after` turned the vertices
/// `newly_red` (sorted) red: the pairs of every crossing of `after` not in `before` that
/// touches a newly red vertex (an end of its edge or a corner of its triangle), or of every new
/// crossing if none touches one. Returns the pairs and whether the fallback (every new crossing)
/// was used.
pub fn pairs_to_block(
    mesh: &AnalysisMesh,
    before: &Analysis,
    after: &Analysis,
    newly_red: &[u32],
    scope: TrialScope,
) -> (Blocked, bool) {
    let is_new = |c: &Crossing| before.crossings.binary_search(c).is_err();
    let touches = |c: &Crossing| {
        let [p, q] = mesh.topology.edges[c.edge as usize];
        let t = mesh.triangles[c.triangle as usize];
        let k = match scope {
            TrialScope::EdgesAndTriangles => 5,
            TrialScope::Edges => 2,
        };
        [p, q, t[0], t[1], t[2]][..k]
            .iter()
            .any(|v| newly_red.binary_search(v).is_ok())
    };
    let fresh: Vec<Crossing> = after.crossings.iter().copied().filter(is_new).collect();
    let local: Vec<Crossing> = fresh.iter().copied().filter(touches).collect();
    let (chosen, fallback) = if local.is_empty() {
        (fresh, true)
    } else {
        (local, false)
    };
    let mut b = Blocked::default();
    for c in chosen {
        b.add_crossing(mesh, c);
    }
    b.normalise();
    (b, fallback)
}

/// A contact policy that answers like `inner` except for the blocked pairs, which `inner`
/// lets cross (red-red) and this policy holds apart as [`TrialBlock`] says.
pub struct TrialPolicy<'a, P: ContactPolicy> {
    /// The step's m-CCH policy.
    pub inner: &'a P,
    /// The pairs held apart.
    pub blocked: &'a Blocked,
    /// How they are held apart.
    pub block: TrialBlock,
    /// Ordinary thickness (green-green).
    pub eps: f64,
    /// Red-green thickness.
    pub eps_rg: f64,
}

impl<P: ContactPolicy> TrialPolicy<'_, P> {
    fn held(&self) -> Contact {
        match self.block {
            TrialBlock::GreenGreen => rule(PairColour::GreenGreen, self.eps, self.eps_rg),
            TrialBlock::RedGreen => rule(PairColour::RedGreen, self.eps, self.eps_rg),
        }
    }
}

impl<P: ContactPolicy> ContactPolicy for TrialPolicy<'_, P> {
    fn max_thickness(&self) -> f64 {
        self.inner
            .max_thickness()
            .max(self.eps)
            .max(match self.block {
                TrialBlock::GreenGreen => self.eps,
                TrialBlock::RedGreen => self.eps_rg,
            })
    }

    fn vertex_triangle(&self, vertex: u32, triangle: u32) -> Contact {
        match self.inner.vertex_triangle(vertex, triangle) {
            Contact::Skip if self.blocked.has_vt(vertex, triangle) => self.held(),
            c => c,
        }
    }

    fn edge_edge(&self, edge_a: u32, edge_b: u32) -> Contact {
        match self.inner.edge_edge(edge_a, edge_b) {
            Contact::Skip if self.blocked.has_ee(edge_a, edge_b) => self.held(),
            c => c,
        }
    }

    fn obstacle(&self, pair: ObstaclePair, obstacle_thickness: f64) -> Contact {
        self.inner.obstacle(pair, obstacle_thickness)
    }
}

/// What the trial step did in one pass of the loop (all zero when it is off or nothing turned
/// red).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct TrialReport {
    /// Retries (simulator steps rolled back and taken again).
    pub retries: u32,
    /// Vertices green at the start that were red after the first attempt.
    pub newly_red_first: usize,
    /// Vertices green at the start that are red after the accepted attempt (non-zero only when
    /// the retries ran out: the step was accepted with an increase).
    pub newly_red_accepted: usize,
    /// How far the red-vertex count went up in the accepted attempt (non-zero only when the
    /// retries ran out or found nothing more to block).
    pub red_increase_accepted: usize,
    /// Pairs held apart in the accepted attempt.
    pub blocked_pairs: usize,
    /// Whether some retry had no new crossing at a newly red vertex and blocked every new
    /// crossing instead.
    pub blocked_all_new: bool,
    /// Whether the retries stopped because the last attempt gave no pair that was not blocked
    /// already (a further retry would repeat it).
    pub nothing_new_to_block: bool,
    /// Pairs not blocked because they had been blocked in
    /// [`super::Params::trial_release_after`] consecutive steps.
    pub released: usize,
    /// Milliseconds in the analyses of the attempts (the accepted attempt's analysis is reused
    /// at the start of the next step).
    pub ms_analysis: f64,
}

/// Pairs blocked in the previous step with the number of consecutive steps they have been
/// blocked (for [`Params::trial_release_after`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BlockHistory(pub BTreeMap<BlockedPair, u32>);

/// What [`trial_step`] returns.
#[derive(Debug)]
pub struct TrialStep {
    /// The simulator's report of the accepted attempt.
    pub step: StepReport,
    /// Retries and blocked pairs.
    pub trial: TrialReport,
    /// The positions after the accepted attempt with their analysis (the next step's; `None`
    /// if that analysis failed).
    pub analysed: Option<(Vec<Vec3>, Analysis)>,
}

/// One simulator step under `policy` as a trial (see [`super::trial`]): if a vertex green in
/// `before` is red after it, the simulator is rolled back and the step retried with the pairs
/// of the new crossings at those vertices held apart, up to `params.trial_retries` times. Returns
/// the accepted step's report, the trial report and the accepted positions with their analysis.
/// `history` carries the pairs blocked in the previous step (for
/// [`Params::trial_release_after`]); a new loop starts with `BlockHistory::default()`.
pub fn trial_step(
    sim: &mut Simulator,
    am: &AnalysisMesh,
    before: &Analysis,
    policy: &MchPolicy<'_>,
    params: &Params,
    options: &Options,
    history: &mut BlockHistory,
) -> Result<TrialStep> {
    let blocked_for = &mut history.0;
    let snap = sim.snapshot();
    let release = params.trial_release_after;
    let before_red = before.coloring.num_red_vertices();
    // Counts of consecutive blocked steps: pairs blocked in the accepted attempt go on, the
    // others start again.
    fn finish(
        blocked_for: &mut BTreeMap<BlockedPair, u32>,
        blocked: &Blocked,
        rep: &mut TrialReport,
    ) {
        let mut next = BTreeMap::new();
        for p in blocked.pairs() {
            next.insert(p, blocked_for.get(&p).copied().unwrap_or(0) + 1);
        }
        *blocked_for = next;
        rep.blocked_pairs = blocked.len();
    }
    let mut sr = sim.step(policy);
    let mut blocked = Blocked::default();
    let mut rep = TrialReport::default();
    loop {
        let pos = sim.positions().to_vec();
        let t = Instant::now();
        let after = analyze_with(am, &pos, options);
        rep.ms_analysis += t.elapsed().as_secs_f64() * 1e3;
        let Ok(after) = after else {
            finish(blocked_for, &blocked, &mut rep);
            return Ok(TrialStep {
                step: sr,
                trial: rep,
                analysed: None,
            });
        };
        let red = newly_red(before, &after);
        if rep.retries == 0 {
            rep.newly_red_first = red.len();
        }
        let triggered = match params.trial_trigger {
            TrialTrigger::AnyNewlyRed => !red.is_empty(),
            TrialTrigger::CountIncrease => after.coloring.num_red_vertices() > before_red,
        };
        rep.newly_red_accepted = red.len();
        rep.red_increase_accepted = after.coloring.num_red_vertices().saturating_sub(before_red);
        if !triggered || rep.retries >= params.trial_retries {
            finish(blocked_for, &blocked, &mut rep);
            return Ok(TrialStep {
                step: sr,
                trial: rep,
                analysed: Some((pos, after)),
            });
        }
        let (mut more, all) = pairs_to_block(am, before, &after, &red, params.trial_scope);
        if release > 0 {
            let n = more.len();
            more.retain(|p| blocked_for.get(&p).is_none_or(|&k| k < release));
            rep.released += n - more.len();
        }
        rep.blocked_all_new |= all;
        let n = blocked.len();
        blocked.extend(&more);
        if blocked.len() == n {
            rep.nothing_new_to_block = true;
            finish(blocked_for, &blocked, &mut rep);
            return Ok(TrialStep {
                step: sr,
                trial: rep,
                analysed: Some((pos, after)),
            });
        }
        sim.restore(&snap)?;
        rep.retries += 1;
        let held = TrialPolicy {
            inner: policy,
            blocked: &blocked,
            block: params.trial_block,
            eps: policy.eps,
            eps_rg: policy.eps_rg,
        };
        sr = sim.step(&held);
    }
}
