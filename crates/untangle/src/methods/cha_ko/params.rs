//! Parameters of the method (Cha & Ko 2022, Sec. 5.1, 5.3.1 and 9: gamma = 0.8, dt = 0.02 s,
//! epsilon_RG = 0.1 x average edge length, epsilon_CCD = 1e-6).

use super::policy::MixedEdges;
use super::trial::{TrialBlock, TrialScope, TrialTrigger};
use crate::error::{Error, Result};

/// The smallest scale `gamma^level` any operation reaches (a subject edge keeps at least this
/// fraction of its original uv length).
pub const MIN_SCALE: f64 = 1e-6;

/// Settings of the uv-space update and the m-CCH contact policy. All have the paper's defaults.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Params {
    /// Scale factor of one pull / shrink level, `0 < gamma < 1` (Sec. 5.1; paper: 0.8).
    pub gamma: f64,
    /// Time step of the simulator the update is used with, in seconds (Sec. 9; paper: 0.02). The
    /// uv update does not use it; it is carried for the integration loop.
    pub dt: f64,
    /// Ordinary collision thickness for green-green pairs (epsilon_CCD, Sec. 5.3.1; paper 1e-6).
    pub eps: f64,
    /// epsilon_RG as a multiple of the average rest (uv) edge length (Sec. 5.3.1; paper 0.1).
    pub eps_rg_factor: f64,
    /// epsilon_RG as an absolute value; overrides `eps_rg_factor` when set.
    pub eps_rg: Option<f64>,
    /// Deepest level of one operation: the rest length of a subject edge never drops below
    /// `gamma^max_level` of its original length (and never below [`MIN_SCALE`] of it, whatever
    /// `max_level` says, so that rounding cannot flip a shrunk triangle). An operation that
    /// reaches it without finishing its finesse is reported as saturated (edge shortening
    /// hindered, Sec. 5.5) and held there.
    pub max_level: u32,
    /// Steps a saturated operation is held before it is abandoned (revoked, and its subject-
    /// target pair or red* triangle barred for twice as many steps so that another target or
    /// the triangle across the red edge gets a turn). 0 = hold for ever.
    pub hold_steps: u32,
    /// Progress test for held operations (ours; 0 = off): a saturated operation is abandoned
    /// early, before `hold_steps`, once the world distance from its subjects to its target
    /// (pull: the subject vertex; shrink: the midpoint of the red edge) has not reached a new
    /// minimum (by 0.1 %) for this many steps. An operation still closing in keeps its full hold.
    pub hold_progress_steps: u32,
    /// Levels undone per step by a revoke (Sec. 5.1.1 scales by `1/gamma`, i.e. one level).
    pub revoke_levels_per_step: u32,
    /// Levels undone per step while no garment triangle is red, i.e. the analysed state is free
    /// of intersections (ours; 0, the default: as [`Params::revoke_levels_per_step`]; 200, at
    /// least any level cap: everything at once, which ends the loop one step after the first
    /// clean step but leaves the cloth about twice as stretched at the end). Once clean, Alg. 2 only revokes, and at one level per
    /// step the loop's tail lasts as many steps as the deepest remaining operation has levels.
    /// With an all-green colouring m-CCH is full collision handling, so undoing the edits at
    /// once cannot bring an intersection back (docs/cha-ko.md, "Where the steps go").
    pub revoke_levels_when_clean: u32,
    /// Levels undone per step for operations whose finesse *finished* (ours; 0: as
    /// [`Params::revoke_levels_per_step`]); superseded and abandoned ones keep that rate.
    pub revoke_levels_finished: u32,
    /// Order of the out-most red vertices in Alg. 2's second loop (ours; the paper sorts
    /// nothing; see [`PullOrder`]).
    pub pull_order: PullOrder,
    /// Use the fallbacks (kernel target, shortened anchors) when no fan passes the triangle
    /// inversion test (Sec. 6.1; the paper's Appendix C is not available). When off, such
    /// subjects are reported as stalled at once.
    pub fallback: bool,
    /// Persistent green (ours, see docs/cha-ko.md): a vertex that was green at the previous
    /// step stays green, whatever the analysis's region classification now says.
    pub persistent_green: bool,
    /// Shrink red* triangles toward a loop vertex when nothing else can be done (ours, see
    /// [`super::schedule`]): nothing in progress, no out-most red vertex, every red* triangle's
    /// target a loop vertex.
    pub loop_target_last_resort: bool,
    /// Pulls avoid loop-vertex targets while another green neighbour exists (ours, see
    /// [`super::schedule`]). Off by default: it removes one stall mode but re-targets running
    /// pulls whenever loop vertices move, and over the benchmarks it did not help overall.
    pub avoid_loop_pull_targets: bool,
    /// Like [`Params::avoid_loop_pull_targets`] but only when a pull *starts* (its target
    /// choice); a running pull whose target later becomes a loop vertex goes on (experiment,
    /// ours; off by default).
    pub avoid_loop_pull_targets_at_start: bool,
    /// A pull starts only toward a green neighbour across a *cut edge* (an edge that penetrates
    /// a triangle, so the path separates the two ends) or toward a loop vertex (ours, see
    /// [`super::schedule`]). In the paper's colouring (Sec. 3) every red-green edge is such an
    /// edge, so the rule changes nothing there; it matters for regions bounded elsewhere, such
    /// as the BLI cone regions of Wicke's heuristic, whose rim vertices have green neighbours
    /// that no path separates: pulling them saturates without moving anything across.
    pub pull_across_cut_edges: bool,
    /// Which edge-edge pairs with a *mixed* edge (one red, one green end) m-CCH lets cross
    /// (experiment, ours; see [`MixedEdges`]). Default: the paper's (such an edge is red).
    pub mixed_edges: MixedEdges,
    /// Open BLI loops (ours, on by default; used by [`super::Resolver`], see
    /// [`super::policy::open_bli_loops`]): when a BLI path with an interior loop vertex lies
    /// in that vertex's fan, a red edge may pass the edges at the vertex in m-CCH. Off, the
    /// `epsilon_RG` band along the pierced triangle's contour (Sec. 5.2, Fig. 7b) keeps the
    /// path's piercing point away from the loop vertex, the only place where such a path can
    /// vanish.
    pub open_bli_loops: bool,
    /// BLI sectors (ours, on by default; [`super::sectors`]): the boundary strand of a BLI path
    /// with an interior loop vertex is shrunk into that vertex, ahead of the colouring's
    /// operations, so that the path reaches the vertex's fan where the open loop lets it vanish.
    pub bli_sectors: bool,
    /// Trial step (ours, see [`super::trial`]; used by [`super::Resolver`]): after a simulator
    /// step that turned a green vertex red (against Sec. 7's theorem, part 1), roll it back and
    /// retry it with the red-red pairs of the new crossings at those vertices held apart, up to
    /// this many times; then accept it and report it. 0 = off (the paper's loop).
    pub trial_retries: u32,
    /// How the pairs blocked by a trial retry are held apart.
    pub trial_block: TrialBlock,
    /// When the trial step retries (default: the count went up; retrying whenever any vertex
    /// turned red froze the exploded handkerchief, BENCHMARKS.md).
    pub trial_trigger: TrialTrigger,
    /// Which new crossings at the newly red vertices it blocks.
    pub trial_scope: TrialScope,
    /// A pair blocked in this many consecutive steps is let cross again (0 = never released).
    pub trial_release_after: u32,
}

/// In which order Alg. 2's second loop visits the out-most red vertices (lines 6-9). A pull
/// blocks every later candidate whose fan contains its subject (Case 1), so the order decides how
/// many pulls run side by side.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PullOrder {
    /// By vertex index (deterministic; the default).
    #[default]
    Index,
    /// Fewest out-most red neighbours first, ties by index: a greedy maximal independent set
    /// that lets more non-adjacent pulls start in one step.
    FewestOutmostNeighbours,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            gamma: 0.8,
            dt: 0.02,
            eps: 1e-6,
            eps_rg_factor: 0.1,
            eps_rg: None,
            max_level: 15,
            hold_steps: 20,
            hold_progress_steps: 0,
            revoke_levels_per_step: 1,
            revoke_levels_when_clean: 0,
            revoke_levels_finished: 0,
            pull_order: PullOrder::Index,
            fallback: true,
            persistent_green: false,
            loop_target_last_resort: true,
            avoid_loop_pull_targets: false,
            avoid_loop_pull_targets_at_start: false,
            pull_across_cut_edges: true,
            mixed_edges: MixedEdges::Red,
            open_bli_loops: true,
            bli_sectors: true,
            trial_retries: 0,
            trial_block: TrialBlock::GreenGreen,
            trial_trigger: TrialTrigger::CountIncrease,
            trial_scope: TrialScope::EdgesAndTriangles,
            trial_release_after: 0,
        }
    }
}

impl Params {
    /// Checks every value's range.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Parameter(m));
        if !(self.gamma > 0.0 && self.gamma < 1.0) {
            return bad(format!("gamma must be in (0, 1), got {}", self.gamma));
        }
        if !(self.dt > 0.0 && self.dt.is_finite()) {
            return bad(format!("dt must be positive, got {}", self.dt));
        }
        if !(self.eps >= 0.0 && self.eps.is_finite()) {
            return bad(format!("eps must be >= 0, got {}", self.eps));
        }
        if !(self.eps_rg_factor >= 0.0 && self.eps_rg_factor.is_finite()) {
            return bad(format!(
                "eps_rg_factor must be >= 0, got {}",
                self.eps_rg_factor
            ));
        }
        if let Some(e) = self.eps_rg {
            if !(e >= 0.0 && e.is_finite()) {
                return bad(format!("eps_rg must be >= 0, got {e}"));
            }
        }
        if self.max_level == 0 || self.max_level > 200 {
            return bad(format!(
                "max_level must be in 1..=200, got {}",
                self.max_level
            ));
        }
        if self.revoke_levels_per_step == 0 {
            return bad("revoke_levels_per_step must be at least 1".into());
        }
        Ok(())
    }

    /// The deepest level an operation reaches: `max_level`, or less if `gamma^max_level` would
    /// fall below [`MIN_SCALE`].
    pub fn level_cap(&self) -> u32 {
        let floor = (MIN_SCALE.ln() / self.gamma.ln()).floor().max(1.0) as u32;
        self.max_level.min(floor)
    }

    /// The smallest scale an operation reaches, `gamma^level_cap`.
    pub fn min_scale(&self) -> f64 {
        self.gamma.powi(self.level_cap() as i32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_valid() {
        let p = Params::default();
        assert_eq!((p.gamma, p.dt, p.eps_rg_factor), (0.8, 0.02, 0.1));
        p.validate().unwrap();
        for bad in [0.0, 1.0, -0.5, f64::NAN] {
            let q = Params {
                gamma: bad,
                ..Params::default()
            };
            assert!(q.validate().is_err(), "gamma {bad}");
        }
        assert!(Params {
            max_level: 0,
            ..Params::default()
        }
        .validate()
        .is_err());
        assert_eq!(p.level_cap(), 15);
        let half = Params {
            gamma: 0.5,
            max_level: 100,
            ..Params::default()
        };
        assert_eq!(half.level_cap(), 19);
        assert!(half.min_scale() >= MIN_SCALE && half.min_scale() * 0.5 < MIN_SCALE);
    }
}
