//! `untangle fix IN.obj... -o OUT.obj --method cha-ko [--max-steps N] [--body FILE|DIR]
//! [--pin SPEC] [--json PATH] [--frames DIR]`
//!
//! Removes self-intersections of a garment by simulation: Cha & Ko 2022 (intersection analysis
//! and colouring, uv-space pulls / shrinks / revokes, m-CCH) inside the implicit cloth simulator.
//! Several input files are analysed and simulated together as the panels of one garment.
//!
//! Exit code 0 when the output is free of intersections by the analysis (cloth-cloth, and
//! cloth-body with `--body`), 1 when the run stopped (step limit, or stuck) with tanglements left
//! (the JSON report's `final_analysis` says where and of what kind), 2 on error.

use super::simulate::{body_at, load_body, pin_spec, Body, Placement};
use crate::output::{check_output, Context};
use anyhow::{bail, Context as _, Result};
use std::path::{Path, PathBuf};
use untangle::analysis::{self, report::Report, Analysis, AnalysisMesh, ObjectKind};
use untangle::geom::Vec3;
use untangle::mesh::{obj, Garment, Mesh};
use untangle::methods::cha_ko::{
    AdaptiveIntegrator, DivergenceGuard, LoopStep, Outcome, ResolveParams, ResolveSummary, Resolver,
};
use untangle::methods::fewest::Fewest;
use untangle::sim::{Integrator, SimParams, Simulator, UniformThickness};

/// Resolution methods.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Cha & Ko 2022: uv-space vertex pull and triangle shrinkage with m-CCH.
    ChaKo,
    /// Wicke et al. 2006, Sec. 5: RBF correspondences and penalty forces (the peer Cha & Ko
    /// compare against; no convergence guarantee).
    Wicke,
    /// Ours: Wicke's forces until the pair count stops falling, Cha & Ko from the best state,
    /// Wicke again on what Cha & Ko leaves (`methods::combined`).
    Combined,
}

/// Arguments of `fix`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Garment mesh(es) (OBJ with `vt` sewing-pattern coordinates; without `vt` the mesh is its
    /// own flat pattern: projected onto its best-fitting plane, or unfolded with its own edge
    /// lengths where the projection would squash or flip a triangle).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Write the untangled garment here (OBJ; original uv).
    #[arg(short = 'o', long)]
    pub out: PathBuf,
    /// Resolution method: `cha-ko` (the default; the options below without a method name are
    /// its own unless they say otherwise), `wicke`, or `combined` (Wicke's forces, then Cha &
    /// Ko, then Wicke on what is left; fewer steps on dense tangles, see BENCHMARKS.md).
    #[arg(long, value_enum, default_value = "cha-ko")]
    pub method: Method,
    /// Write the JSON report (summary, every step, every operation, what is left) here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the cloth coloured by the analysis (red / orange / green, intersection curves as
    /// `curve_N` polylines) as `frame_NNNN.obj` into this directory: frame 0 is the input,
    /// frame k the state after step k.
    #[arg(long)]
    pub frames: Option<PathBuf>,
    /// When the run ends with tanglements left, write its last state (by default the state
    /// with the fewest intersecting pairs is written, the input if no state had fewer; not
    /// with an animated body, which always gets the last state).
    #[arg(long)]
    pub output_last: bool,
    /// Steps between written frames (the last state is always written).
    #[arg(long, default_value_t = 1)]
    pub frame_every: usize,
    /// A body the cloth collides with: an OBJ file (static), or a directory of OBJ frames
    /// (sorted by name) played one frame every `--body-frame-steps` steps, interpolated
    /// linearly, the last one then held. A method that ends clean before the last frame hands
    /// over to plain simulation with full collision handling until the body has played out.
    #[arg(long)]
    pub body: Option<PathBuf>,
    /// How the body is placed: `--body-scale`, `--body-offset`, `--body-z-up`.
    #[command(flatten)]
    pub placement: Placement,
    /// Steps per body frame (with `--body DIR`).
    #[arg(long, default_value_t = 1)]
    pub body_frame_steps: usize,
    /// Body thickness (metres).
    #[arg(long, allow_negative_numbers = true, default_value_t = 2e-3)]
    pub body_thickness: f64,
    /// Pinned vertices (repeatable): `corners`, `top`, `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX`, or
    /// 1-based vertex numbers `I,J,K` as in the OBJ file.
    #[arg(long, allow_hyphen_values = true)]
    pub pin: Vec<String>,
    /// Pull / shrink scale per step (Cha & Ko's gamma).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.8)]
    pub gamma: f64,
    /// Time step (seconds).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.02)]
    pub dt: f64,
    /// Green-green collision thickness (epsilon_CCD).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1e-6)]
    pub eps: f64,
    /// Red-green thickness as a multiple of the average edge length (epsilon_RG).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.1)]
    pub eps_rg_factor: f64,
    /// Deepest pull / shrink level (rest length kept >= gamma^max_level).
    #[arg(long, default_value_t = 15)]
    pub max_level: u32,
    /// Step limit.
    #[arg(long, default_value_t = 2000)]
    pub max_steps: usize,
    /// Stop after this many steps without progress.
    #[arg(long, default_value_t = 100)]
    pub stuck_steps: usize,
    /// Gravity along -y (m/s^2); 0 keeps the garment in place while it untangles.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.0)]
    pub gravity: f64,
    /// Disable the fallbacks used when no fan passes the triangle inversion test.
    #[arg(long)]
    pub no_fallback: bool,
    /// Leave BLI paths uncoloured (the paper's method; by default their cone regions, Wicke's
    /// heuristic, are coloured red and pulled out like any other region).
    #[arg(long)]
    pub no_bli_regions: bool,
    /// Keep the epsilon_RG band at the loop vertex of a BLI path whose loop vertex is interior
    /// (the paper's m-CCH; by default, once such a path lies in the vertex's fan, red edges may
    /// pass the edges at that vertex, so the path can vanish there).
    #[arg(long)]
    pub no_open_bli_loops: bool,
    /// Do not shrink BLI paths with an interior loop vertex into that vertex (by default the
    /// cloth between the vertex and the pierced boundary edge, the path's "sector", is moved
    /// toward the vertex in uv, passes red cloth meanwhile, and the vertex's edges are open).
    #[arg(long)]
    pub no_bli_sectors: bool,
    /// Give no region to the paths Wicke's rules leave without one (by default, on a garment,
    /// the cloth that has passed into another tube of it, found by the generalized winding
    /// number, is coloured red and pulled out: a leg's wall inside the other leg, say).
    #[arg(long)]
    pub no_winding_regions: bool,
    /// Regionless-tanglement fallback (ours): after this many steps without progress while no
    /// vertex is red, colour red the corners of the intersecting triangles of tanglements that
    /// have no usable region (a fold pinched through itself, as CROSS ends up); 0 (the default)
    /// disables it. Try 30 when a run ends stuck with no red vertex left.
    #[arg(long, default_value_t = 0)]
    pub regionless_after: usize,
    /// Turn off slit ridges (ours, on by default: once no vertex is red and the loop has
    /// stalled for `--slit-stall` steps, the ridge vertices of a fold that pokes through a
    /// partitioning path running out and back through the same triangles (no region) are
    /// coloured red, so the fold is pulled back across it; this resolves CROSS; docs/cha-ko.md,
    /// "Slits").
    #[arg(long)]
    pub no_slit_ridges: bool,
    /// Slit ridges: steps without a new lowest count of intersecting pairs before it
    /// acts (0: at once).
    #[arg(long, default_value_t = ResolveParams::default().slit_stall)]
    pub slit_stall: usize,
    /// Levels (scalings by 1/gamma) an operation that is no longer warranted is revoked per
    /// step (Alg. 1 line 6 revokes by 1/gamma, i.e. 1, the default). More restores the uv
    /// sooner, so neighbours waiting for a fan in its original position start earlier: with 3
    /// and `--regionless-after 30` the exploded handkerchief needs ~20 % fewer steps over 100
    /// seeds with the same 98 / 100 resolved (docs/cha-ko.md, "Revoke rate").
    #[arg(long, default_value_t = 1)]
    pub revoke_levels: u32,
    /// Soft impact zones of the loop's simulator (ours, `sim::ZoneMotion::soft_levels`): a
    /// new impact zone keeps half its deformation, halved again each time it collides again,
    /// and turns rigid after this many halvings; 0 = Bridson's rigid zones. Zones are what
    /// most often keeps a pulled edge from shortening in a step. 16 instead of the default 4:
    /// exploded handkerchief seeds 1-50 median 105.5 steps (50 / 50) against 117, but seeds
    /// 51-100 115 (49 / 50) against 111, so over 100 seeds the same 99 / 100 and median 113
    /// (docs/cha-ko.md, "The simulator inside the loop").
    #[arg(long, default_value_t = ResolveParams::default().sim.zone_motion.soft_levels)]
    pub zone_soft_levels: u32,
    /// Heavy subjects (ours, `ResolveParams::heavy_subjects`; 1 = off): the running
    /// operations' subjects weigh this many times their mass in the collision handling only
    /// (impulses and impact zones), so m-CCH takes less of a pull's motion back; which pairs
    /// are kept apart is unchanged (docs/cha-ko.md, "Heavy subjects").
    #[arg(long, default_value_t = ResolveParams::default().heavy_subjects)]
    pub heavy_subjects: f64,
    /// With `--heavy-subjects`: the subjects' fans (neighbours) are heavy too.
    #[arg(long)]
    pub heavy_fans: bool,
    /// Thin red-green pairs at the subjects (ours, `ResolveParams::subject_rg_scale`; 1 =
    /// off): red-green pairs whose red primitive has a running operation's subject keep this
    /// fraction of epsilon_RG (at least epsilon).
    #[arg(long, default_value_t = ResolveParams::default().subject_rg_scale)]
    pub subject_rg_scale: f64,
    /// Levels revoked per step once nothing intersects (ours; 0, the default: as
    /// `--revoke-levels`; 200: everything at once, one step after the first clean step, but the
    /// output is left about twice as stretched). The loop's tail after the first clean step only revokes; m-CCH
    /// with an all-green colouring is full collision handling, so the cloth stays clean
    /// (docs/cha-ko.md, "Where the steps go").
    #[arg(long, default_value_t = untangle::methods::cha_ko::Params::default().revoke_levels_when_clean)]
    pub revoke_levels_when_clean: u32,
    /// Levels revoked per step for operations whose finesse finished (ours; 0: as
    /// `--revoke-levels`).
    #[arg(long, default_value_t = 0)]
    pub revoke_levels_finished: u32,
    /// Abandon a saturated operation early once the world distance from its subject to its
    /// target has not reached a new minimum for this many steps (ours; 0: off, hold the full
    /// 20 steps).
    #[arg(long, default_value_t = 0)]
    pub hold_progress: u32,
    /// The divergence guard (ours): a simulator step whose stretch-plus-kinetic energy grows
    /// more than this many times is undone, and the operations at the triangles that grew are
    /// given up and restored (0: off; docs/cha-ko.md, "Divergence guard").
    #[arg(long, allow_negative_numbers = true, default_value_t = untangle::methods::cha_ko::DivergenceGuard::default().ratio)]
    pub divergence_ratio: f64,
    /// Visit out-most red vertices with the fewest out-most red neighbours first (ours; more
    /// pulls start side by side; default: by index).
    #[arg(long)]
    pub pull_fewest_neighbours_first: bool,
    /// The loop's time integrator: `baraff-witkin` (the default: resolves the most),
    /// `projective` (projective dynamics: about 1.7x the steps per second, resolves fewer
    /// tangles; BENCHMARKS.md) or `adaptive` (projective dynamics, Baraff & Witkin from the
    /// first stall of `--adaptive-stall` steps on).
    #[arg(long, value_enum, default_value_t = LoopIntegrator::BaraffWitkin)]
    pub integrator: LoopIntegrator,
    /// With `--integrator adaptive`: stalled steps (intersecting, no new lowest count of
    /// intersecting pairs) after which Baraff & Witkin takes over.
    #[arg(long, default_value_t = AdaptiveIntegrator::default().stall_steps)]
    pub adaptive_stall: usize,
    /// `--method wicke`: the penalty force's stiffness `k` of Wicke's Eq. 4 and 6, as an
    /// acceleration per metre of penetration (1/s^2). `--dt`, `--eps` (the thickness of pairs
    /// that are not free), `--max-steps`, `--stuck-steps` and `--gravity` apply as well.
    #[arg(long, allow_negative_numbers = true, default_value_t = untangle::methods::wicke::ForceParams::default().stiffness)]
    pub wicke_stiffness: f64,
    /// `--method wicke`: the force's cap `f_max` (Eq. 4 and 6) as an acceleration (m/s^2).
    #[arg(long, allow_negative_numbers = true, default_value_t = untangle::methods::wicke::ForceParams::default().max_acceleration)]
    pub wicke_max_acceleration: f64,
}

/// `fix --integrator` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopIntegrator {
    /// Baraff & Witkin 1998 throughout.
    BaraffWitkin,
    /// Projective dynamics (Bouaziz et al. 2014) throughout, with the loop's CG cap.
    Projective,
    /// Projective dynamics, Baraff & Witkin after a stall (`ResolveParams::adaptive`).
    Adaptive,
}

impl Args {
    /// The loop's parameters from the command line.
    pub fn params(&self) -> ResolveParams {
        let mut p = ResolveParams::default();
        p.cha_ko.gamma = self.gamma;
        p.cha_ko.dt = self.dt;
        p.cha_ko.eps = self.eps;
        p.cha_ko.eps_rg_factor = self.eps_rg_factor;
        p.cha_ko.max_level = self.max_level;
        p.cha_ko.fallback = !self.no_fallback;
        p.sim.gravity = Vec3::new(0.0, -self.gravity, 0.0);
        p.max_steps = self.max_steps;
        p.stuck_steps = self.stuck_steps;
        p.regionless_after = self.regionless_after;
        p.slit_ridges = !self.no_slit_ridges;
        p.slit_stall = self.slit_stall;
        p.cha_ko.revoke_levels_per_step = self.revoke_levels;
        p.sim.zone_motion.soft_levels = self.zone_soft_levels;
        p.heavy_subjects = self.heavy_subjects;
        if self.heavy_fans {
            p.heavy_scope = untangle::methods::cha_ko::subjects::HeavyScope::SubjectsAndFans;
        }
        p.subject_rg_scale = self.subject_rg_scale;
        p.cha_ko.revoke_levels_when_clean = self.revoke_levels_when_clean;
        p.cha_ko.revoke_levels_finished = self.revoke_levels_finished;
        p.cha_ko.hold_progress_steps = self.hold_progress;
        // Any value but 0 reaches the guard, which refuses what is not finite and positive.
        p.divergence = (self.divergence_ratio != 0.0).then(|| DivergenceGuard {
            ratio: self.divergence_ratio,
            ..DivergenceGuard::default()
        });
        if self.pull_fewest_neighbours_first {
            p.cha_ko.pull_order = untangle::methods::cha_ko::PullOrder::FewestOutmostNeighbours;
        }
        p.analysis.bli_regions_red = !self.no_bli_regions;
        p.cha_ko.open_bli_loops = !self.no_open_bli_loops;
        p.cha_ko.bli_sectors = !self.no_bli_sectors;
        p.analysis.winding_regions = !self.no_winding_regions;
        match self.integrator {
            LoopIntegrator::BaraffWitkin => p.sim.integrator = Integrator::BaraffWitkin,
            LoopIntegrator::Projective => p.sim.integrator = Integrator::Projective,
            LoopIntegrator::Adaptive => {
                p.adaptive = Some(AdaptiveIntegrator {
                    stall_steps: self.adaptive_stall,
                    ..AdaptiveIntegrator::default()
                })
            }
        }
        p
    }
}

/// What a run needs besides the garment and the loop's parameters.
pub struct Setup<'a> {
    /// The body, if any.
    pub body: Option<&'a Body>,
    /// Steps per body frame.
    pub body_frame_steps: usize,
    /// Body thickness.
    pub body_thickness: f64,
    /// Pinned garment vertices (0-based).
    pub pinned: &'a [u32],
    /// Frame directory and steps between frames.
    pub frames: Option<(&'a Path, usize)>,
    /// Write the last state even when an earlier one had fewer intersecting pairs
    /// ([`untangle::methods::fewest`]).
    pub output_last: bool,
}

/// Friction of the body in `fix` (as in `simulate`).
const BODY_FRICTION: f64 = 0.3;

impl Setup<'_> {
    /// Refuses settings no driver can run with.
    pub fn validate(&self) -> Result<()> {
        if self.body_frame_steps == 0 {
            bail!("--body-frame-steps must be at least 1");
        }
        Ok(())
    }

    /// Whether a stuck run may write its fewest-pair state instead of its last
    /// ([`untangle::methods::fewest`]): not asked otherwise, and no animated body.
    pub fn keeps_fewest(&self) -> bool {
        !self.output_last && self.body_span() == 0
    }

    /// Steps over which an animated body plays (0 for a static one or none).
    pub fn body_span(&self) -> usize {
        self.body.map_or(0, |b| {
            (b.frames.len().saturating_sub(1)) * self.body_frame_steps
        })
    }

    /// Where an animated body is after `k` steps (its last frame held after the span); `None`
    /// for a static body or none.
    pub fn animated_body_at(&self, k: usize) -> Option<Vec<Vec3>> {
        let span = self.body_span();
        self.body
            .filter(|b| b.frames.len() > 1)
            .map(|b| body_at(b, k.min(span), span))
    }

    /// The body as the simulator's obstacle, at its first frame.
    pub fn obstacle(&self) -> Result<Option<untangle::sim::Obstacle>> {
        Ok(match self.body {
            Some(b) => Some(untangle::sim::Obstacle::from_mesh(
                &b.mesh,
                self.body_thickness,
                BODY_FRICTION,
            )?),
            None => None,
        })
    }
}

/// The result of a run.
pub struct FixRun {
    /// The loop's summary.
    pub summary: ResolveSummary,
    /// `Some` when an earlier state with fewer intersecting pairs is the output instead of
    /// the last ([`untangle::methods::fewest`]); `final_pos` and `final_analysis` are then that state's.
    pub output_state: Option<OutputState>,
    /// Plain simulator steps run after the loop resolved, to play the rest of an animated body.
    pub body_tail_steps: usize,
    /// Every step.
    pub history: Vec<LoopStep>,
    /// The garment at its final positions (original uv).
    pub out_mesh: Mesh,
    /// The analysis mesh of the garment (and body), its final positions and analysis.
    pub final_am: AnalysisMesh,
    /// See `final_am`.
    pub final_pos: Vec<Vec3>,
    /// See `final_am`.
    pub final_analysis: Analysis,
    /// Cloth–body intersecting triangle pairs at the start (these cannot be resolved).
    pub input_body_pairs: usize,
    /// The analysis at the start (garment and body at their first positions).
    pub initial_analysis: Analysis,
    /// The positions analysed at the start.
    pub initial_pos: Vec<Vec3>,
    /// The JSON report.
    pub report: serde_json::Value,
}

/// An earlier state written instead of the last ([`untangle::methods::fewest`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutputState {
    /// Steps run before it (0 = the input).
    pub after_steps: usize,
    /// Intersecting triangle pairs of the last state.
    pub last_pairs: usize,
}

/// The report's `output_state`: which state the output is.
pub(crate) fn output_state_json(s: Option<&OutputState>, steps: usize) -> serde_json::Value {
    match s {
        Some(s) => serde_json::json!({
            "written": "fewest_pairs",
            "after_steps": s.after_steps,
            "last_state_intersecting_pairs": s.last_pairs,
        }),
        None => serde_json::json!({ "written": "last", "after_steps": steps }),
    }
}

/// Which state a run writes ([`untangle::methods::fewest`]): `scene.pos` holds the last state, analysed
/// in `final_analysis`. Unless the run resolved the cloth (body pairs may be left), the
/// fewest-pair state replaces both when it has fewer intersecting pairs; its description, or
/// `None` when the last state stays.
pub(crate) fn choose_output(
    scene: &mut Scene,
    fewest: &Fewest,
    resolved: bool,
    final_analysis: &mut Analysis,
) -> Result<Option<OutputState>> {
    let last_pairs = final_analysis.segments.len();
    let Some(b) = fewest.better_than(last_pairs).filter(|_| !resolved) else {
        return Ok(None);
    };
    let last_pos = scene.pos.clone();
    scene.pos[..b.positions.len()].copy_from_slice(&b.positions);
    let a = analysis::analyze(&scene.am, &scene.pos).context("intersection analysis")?;
    if a.segments.len() < last_pairs {
        *final_analysis = a;
        Ok(Some(OutputState {
            after_steps: b.after_steps,
            last_pairs,
        }))
    } else {
        scene.pos = last_pos;
        Ok(None)
    }
}

/// The summary line of an earlier state written instead of the last.
pub(crate) fn output_state_line(s: &OutputState, pairs: usize) -> String {
    let state = match s.after_steps {
        0 => "the input (no later state had fewer intersecting pairs)".to_string(),
        k => format!("the state after step {k}, the fewest intersecting pairs of the run"),
    };
    format!(
        "  written: {state} ({pairs}; the last state had {}, --output-last writes it)",
        s.last_pairs
    )
}

impl FixRun {
    /// Whether the output is free of intersections by the analysis.
    pub fn is_clean(&self) -> bool {
        self.final_analysis.is_clean()
    }
}

/// Garment and body together for the analysis of what is written.
pub(crate) struct Scene<'a> {
    pub(crate) am: AnalysisMesh,
    pub(crate) pos: Vec<Vec3>,
    garment: &'a Mesh,
}

impl<'a> Scene<'a> {
    pub(crate) fn new(garment: &'a Mesh, body: Option<&Body>) -> Result<Scene<'a>> {
        let mut parts = vec![(garment, ObjectKind::Cloth)];
        if let Some(b) = body {
            parts.push((&b.mesh, ObjectKind::Obstacle));
        }
        let (am, pos) = AnalysisMesh::new(&parts)?;
        Ok(Scene { am, pos, garment })
    }

    /// The analysis of the simulator's cloth (and its body at the start of the next step).
    pub(crate) fn analyse(&mut self, sim: &Simulator) -> Result<Analysis> {
        let n = sim.positions().len();
        self.pos[..n].copy_from_slice(sim.positions());
        if self.pos.len() > n {
            self.pos[n..].copy_from_slice(&sim.obstacles().start);
        }
        analysis::analyze(&self.am, &self.pos).context("intersection analysis")
    }

    /// The garment coloured by `a`, with the intersection curves as polylines.
    pub(crate) fn colored_obj(&self, a: &Analysis, header: &str) -> String {
        let n = self.garment.positions.len();
        let mut m = self.garment.clone();
        m.positions = self.pos[..n].to_vec();
        let colors = analysis::coloring::vertex_colors(&self.am, &a.coloring, &a.segments);
        let mut text = obj::format_obj(&m, Some(&colors[..n]), header);
        let curves = analysis::curves::tanglement_curves(&self.am, &self.pos, a);
        obj::append_polylines(&mut text, n, "curve_", &curves);
        text
    }
}

/// Runs the Cha & Ko loop on `garment` (with a progress bar showing the red vertices left),
/// writes frames if asked, analyses the result and builds the JSON report.
pub fn untangle(
    garment: &Garment,
    params: ResolveParams,
    setup: &Setup,
    ctx: &Context,
) -> Result<FixRun> {
    setup.validate()?;
    let max_steps = params.max_steps;
    let mut resolver = Resolver::new(garment, params).context("cha-ko")?;
    if let Some(o) = setup.obstacle()? {
        resolver.simulator_mut().add_obstacle(o)?;
    }
    for &v in setup.pinned {
        resolver.simulator_mut().set_pinned(v, true)?;
    }
    let mut scene = Scene::new(&garment.mesh, setup.body)?;
    let initial_analysis = scene.analyse(resolver.simulator())?;
    let initial_pos = scene.pos.clone();
    let initial_red = initial_analysis.coloring.num_red_vertices() as u64;
    let (input_body_pairs, pb) = begin(
        ctx,
        setup,
        &scene,
        &initial_analysis,
        "untangle fix: input",
        (initial_red, "red resolved"),
    )?;
    let mut fewest = Fewest::new(setup.keeps_fewest());
    let outcome = loop {
        if let Some(o) = resolver.stop_reason() {
            break o;
        }
        let k = resolver.history().len();
        if let Some(next) = setup.animated_body_at(k + 1) {
            resolver
                .simulator_mut()
                .set_obstacle_next_positions(0, &next)?;
        }
        let before = fewest.before_step(resolver.simulator().positions());
        let (rec, _) = resolver.step().context("cha-ko step")?;
        fewest.offer(rec.step as usize, rec.intersecting_pairs, before);
        pb.set_position(initial_red.saturating_sub(rec.red_vertices as u64));
        pb.set_message(format!(
            "step {}/{max_steps}: {} red, {} pairs",
            rec.step + 1,
            rec.red_vertices,
            rec.intersecting_pairs
        ));
        if let Some((dir, every)) = setup.frames {
            let done = resolver.stop_reason().is_some();
            if (k + 1) % every.max(1) == 0 || done {
                let a = scene.analyse(resolver.simulator())?;
                let text = scene.colored_obj(&a, &format!("untangle fix: after step {}", k + 1));
                write_frame(dir, k + 1, &text)?;
            }
        }
    };
    pb.finish_and_clear();
    let summary = resolver.summary(outcome);
    let tail = if outcome == Outcome::Resolved {
        play_rest_of_body(
            garment,
            resolver.simulator().positions(),
            resolver.simulator().params(),
            resolver.chako().params().eps,
            setup,
            &mut scene,
            resolver.history().len(),
        )?
    } else {
        None
    };
    let body_tail_steps = tail.as_ref().map_or(0, |t| t.1);
    let final_sim = tail.as_ref().map_or(resolver.simulator(), |t| &t.0);
    let mut final_analysis = scene.analyse(final_sim)?;
    let output_state = choose_output(
        &mut scene,
        &fewest,
        outcome == Outcome::Resolved,
        &mut final_analysis,
    )?;
    let final_pos = scene.pos.clone();
    let mut out_mesh = garment.mesh.clone();
    let n = out_mesh.positions.len();
    out_mesh.positions = final_pos[..n].to_vec();
    let history = resolver.history().to_vec();
    let final_report = Report::new(&scene.am, &final_pos, &final_analysis);
    let final_json: serde_json::Value = serde_json::from_str(&final_report.to_json())?;
    let report = serde_json::json!({
        "method": "cha-ko",
        "vertices": garment.mesh.positions.len(),
        "triangles": garment.mesh.triangles.len(),
        "pinned": setup.pinned.len(),
        "body": body_json(setup),
        "params": resolver.chako().params(),
        "eps_rg": resolver.chako().eps_rg(),
        "outcome": summary.outcome,
        "output_intersection_free": final_analysis.is_clean(),
        "output_intersecting_pairs": final_analysis.segments.len(),
        "output_state": output_state_json(output_state.as_ref(), history.len()),
        "input_body_intersecting_pairs": input_body_pairs,
        "summary": summary,
        "body_tail_steps": body_tail_steps,
        "steps": history.iter().map(step_json).collect::<Vec<_>>(),
        "final_analysis": final_json,
        "step_details": history,
        "operations": resolver.chako().finesse_log(),
    });
    Ok(FixRun {
        summary,
        output_state,
        body_tail_steps,
        history,
        out_mesh,
        final_am: scene.am,
        final_pos,
        final_analysis,
        initial_analysis,
        initial_pos,
        input_body_pairs,
        report,
    })
}

/// Plays the rest of an animated body after a method stopped clean at step `from`, before the
/// body reached its last frame ([`Setup::body_span`]): plain simulator steps with full
/// collision handling (`eps` for every pair), from `positions` at rest, with the loop's
/// simulator settings `params` and the pins, so the output fits the body's last frame instead
/// of the frame the method happened to stop at. The cloth stays free of
/// self-intersections by the simulator's guarantee; the caller's final analysis checks the body
/// too. With `--frames` it writes these steps' frames (and always the last). The simulator and
/// the steps taken; `None` without an animated body or when it has already played out.
pub(crate) fn play_rest_of_body(
    garment: &Garment,
    positions: &[Vec3],
    params: &SimParams,
    eps: f64,
    setup: &Setup,
    scene: &mut Scene,
    from: usize,
) -> Result<Option<(Simulator, usize)>> {
    let span = setup.body_span();
    let Some(start) = setup.animated_body_at(from).filter(|_| from < span) else {
        return Ok(None);
    };
    let g = garment.with_positions(positions).context("garment")?;
    let mut sim = Simulator::new(&g, params.clone()).context("simulator")?;
    for &v in setup.pinned {
        sim.set_pinned(v, true)?;
    }
    let Some(mut body) = setup.obstacle()? else {
        return Ok(None);
    };
    body.positions = start;
    sim.add_obstacle(body)?;
    let policy = UniformThickness(eps);
    for k in from..span {
        if let Some(next) = setup.animated_body_at(k + 1) {
            sim.set_obstacle_next_positions(0, &next)?;
        }
        sim.step(&policy);
        if let Some((dir, every)) = setup.frames {
            if (k + 1) % every.max(1) == 0 || k + 1 == span {
                let a = scene.analyse(&sim)?;
                let header = format!("untangle fix: body animation, step {}", k + 1);
                write_frame(dir, k + 1, &scene.colored_obj(&a, &header))?;
            }
        }
    }
    Ok(Some((sim, span - from)))
}

/// The body section of a fix report (null without `--body`).
pub(crate) fn body_json(setup: &Setup) -> serde_json::Value {
    serde_json::json!(setup.body.map(|b| serde_json::json!({
        "vertices": b.mesh.positions.len(),
        "triangles": b.mesh.triangles.len(),
        "frames": b.frames.len(),
    })))
}

/// What every fix driver does before its first step: frame 0 (with `--frames`), the note when
/// the input already penetrates the body, and the progress bar over `len` things (`what`).
/// Returns the input's cloth-body pairs and the bar.
pub(crate) fn begin(
    ctx: &Context,
    setup: &Setup,
    scene: &Scene,
    initial: &Analysis,
    header: &str,
    (len, what): (u64, &str),
) -> Result<(usize, indicatif::ProgressBar)> {
    if let Some((dir, _)) = setup.frames {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        write_frame(dir, 0, &scene.colored_obj(initial, header))?;
    }
    let input_body_pairs = body_pairs(&scene.am, &scene.pos, initial);
    if input_body_pairs > 0 {
        ctx.say(format!("note: {}", body_note(input_body_pairs)));
    }
    Ok((input_body_pairs, progress_bar(ctx, len, what)))
}

/// Cloth-body intersecting triangle pairs of analysis `a` of `am` at `pos`.
pub(crate) fn body_pairs(am: &AnalysisMesh, pos: &[Vec3], a: &Analysis) -> usize {
    Report::new(am, pos, a)
        .pairs_by_objects
        .iter()
        .filter(|g| g.relation == "cloth-obstacle")
        .map(|g| g.pairs)
        .sum()
}

/// The untangling progress bar: `done` of `len` things (`what`: "red resolved", ...).
pub(crate) fn progress_bar(ctx: &Context, len: u64, what: &str) -> indicatif::ProgressBar {
    let pb = ctx.progress(len.max(1), "untangling");
    pb.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "{{msg:34}} [{{bar:20}}] {{pos}}/{{len}} {what} {{elapsed}}"
        ))
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    pb
}

/// Why a run whose input already penetrates the body cannot end clean, and what to do.
pub(crate) fn body_note(pairs: usize) -> String {
    format!(
        "the input cloth already intersects the body ({pairs} triangle pairs): collision handling \
         keeps the cloth on the side of the body it starts on, so these stay; place the body \
         with --body-offset/--body-scale/--body-z-up, or push the garment out of it first with \
         `untangle layers`"
    )
}

pub(crate) fn write_frame(dir: &Path, k: usize, text: &str) -> Result<()> {
    untangle::fsio::write_atomic(&dir.join(format!("frame_{k:04}.obj")), text.as_bytes())?;
    Ok(())
}

/// The per-step entry of the report: what the analysis saw at the start of the step, what the
/// uv update applied, and the time.
pub(crate) fn step_json(s: &LoopStep) -> serde_json::Value {
    serde_json::json!({
        "step": s.step,
        "red_vertices": s.red_vertices,
        "red_triangles": s.red_triangles,
        "intersecting_pairs": s.intersecting_pairs,
        "tanglements": s.tanglements,
        "regionless_red": s.regionless_red,
        "slit_red": s.slit_red,
        "open_bli_loops": s.open_bli_loops,
        "winding_paths": s.winding_paths,
        "pulls": s.uv.pulls_started + s.uv.pulls_continued,
        "pulls_started": s.uv.pulls_started,
        "shrinks": s.uv.shrinks_started + s.uv.shrinks_continued,
        "shrinks_started": s.uv.shrinks_started,
        "sectors": s.uv.sectors_started + s.uv.sectors_continued,
        "sectors_started": s.uv.sectors_started,
        "revokes": s.uv.revoked_levels,
        "restored": s.uv.restored,
        "active_ops": s.uv.active_ops,
        "analysis_error": s.analysis_error,
        "integrator": s.integrator,
        "integrator_switch": s.integrator_switch,
        "divergence": s.divergence,
        "ms": step_ms(s),
        "ms_analysis": s.ms_analysis,
        "ms_uv": s.ms_uv + s.ms_rest,
        "ms_sim": s.ms_sim,
    })
}

/// The summary's integrator line, when a step ran projective dynamics: how many steps each
/// integrator took and where the adaptive integrator switched (`None` for the default, Baraff &
/// Witkin throughout).
fn integrator_line(history: &[LoopStep]) -> Option<String> {
    let pd = history
        .iter()
        .filter(|h| h.integrator == Integrator::Projective)
        .count();
    if pd == 0 {
        return None;
    }
    let mut line = format!(
        "integrator: projective dynamics {pd} steps, Baraff & Witkin {} steps",
        history.len() - pd
    );
    let switches: Vec<String> = history
        .iter()
        .filter_map(|h| {
            h.integrator_switch
                .map(|w| format!("{w:?} at step {}", h.step))
        })
        .collect();
    if !switches.is_empty() {
        line.push_str(&format!(" (switches: {})", switches.join(", ")));
    }
    Some(line)
}

/// The summary's divergence-guard line, when the guard acted
/// ([`untangle::methods::cha_ko::divergence`]): in how many steps a simulator step diverged,
/// the first (`steps` pairs each Cha & Ko step with its index in the whole run), how many
/// operations were given up and how many steps kept a diverged result.
pub(crate) fn divergence_line<'a>(
    steps: impl IntoIterator<Item = (usize, &'a LoopStep)>,
) -> Option<String> {
    let (mut diverged, mut first, mut given_up, mut kept) = (0, None, 0, 0);
    for (k, h) in steps {
        let d = &h.divergence;
        if d.diverged > 0 {
            diverged += 1;
            first = first.or(Some(k));
        }
        given_up += d.given_up.len();
        kept += d.kept_diverged as usize;
    }
    let first = first?;
    Some(format!(
        "divergence guard: the simulation diverged in {} (first at step {first}); {} given up and the {} run again{}",
        plural(diverged, "step"),
        plural(given_up, "operation"),
        if diverged == 1 { "step" } else { "steps" },
        if kept > 0 {
            format!(", {kept} kept diverged")
        } else {
            String::new()
        }
    ))
}

/// `n thing` or `n things`.
fn plural(n: usize, thing: &str) -> String {
    if n == 1 {
        format!("1 {thing}")
    } else {
        format!("{n} {thing}s")
    }
}

/// Milliseconds of one step: analysis, uv update, rest-shape update and simulation.
pub fn step_ms(s: &LoopStep) -> f64 {
    s.ms_analysis + s.ms_uv + s.ms_rest + s.ms_sim
}

/// Reads the garment: one file, or several files with uv merged into one garment.
pub fn read_garment(files: &[PathBuf]) -> Result<Garment> {
    let meshes: Vec<_> = files
        .iter()
        .map(|f| obj::read_obj(f))
        .collect::<untangle::Result<_>>()?;
    if meshes.len() == 1 {
        let name = files[0].display().to_string();
        return Garment::new(meshes[0].clone()).with_context(|| name);
    }
    if let Some(k) = meshes.iter().position(|m| m.uv.is_none()) {
        bail!(
            "{}: several inputs must all have uv (vt) coordinates",
            files[k].display()
        );
    }
    Ok(Garment::new(AnalysisMesh::merge_cloth(&meshes)?)?)
}

/// Runs `fix`; exit code 0 when the output is free of intersections, 1 otherwise.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    let mut inputs: Vec<&Path> = args.files.iter().map(|p| p.as_path()).collect();
    if let Some(b) = &args.body {
        inputs.push(b);
    }
    for out in std::iter::once(&args.out).chain(args.json.iter()) {
        check_output(out, &inputs)?;
    }
    if args.json.as_ref() == Some(&args.out) {
        bail!(
            "{}: the report and the mesh cannot be the same file",
            args.out.display()
        );
    }
    if args.frame_every == 0 {
        bail!("--frame-every must be at least 1");
    }
    if let Some(dir) = &args.frames {
        // Frames are `frame_NNNN.obj`: never over an input that happens to be named so.
        for i in &inputs {
            let name = i.file_name().map(|n| n.to_string_lossy().into_owned());
            if name.is_some_and(|n| n.starts_with("frame_")) {
                check_output(&dir.join(i.file_name().unwrap_or_default()), &inputs)?;
            }
        }
    }
    let garment = read_garment(&args.files)?;
    let body = match &args.body {
        Some(p) => Some(load_body(p, &args.placement)?),
        None => None,
    };
    let mut pinned = Vec::new();
    for spec in &args.pin {
        pinned.extend(pin_spec(
            spec,
            &garment.mesh.positions,
            &garment.topology.boundary_vertex,
        )?);
    }
    pinned.sort_unstable();
    pinned.dedup();
    let setup = Setup {
        body: body.as_ref(),
        body_frame_steps: args.body_frame_steps,
        body_thickness: args.body_thickness,
        pinned: &pinned,
        frames: args.frames.as_deref().map(|d| (d, args.frame_every)),
        output_last: args.output_last,
    };
    match args.method {
        Method::Wicke | Method::Combined => {
            return super::fix_wicke::run(&args, &garment, &setup, ctx)
        }
        Method::ChaKo => {}
    }
    let fix = untangle(&garment, args.params(), &setup, ctx)?;
    obj::write_obj(
        &args.out,
        &fix.out_mesh,
        None,
        &format!(
            "untangle fix --method cha-ko: {:?} after {} steps",
            fix.summary.outcome, fix.summary.steps
        ),
    )?;
    if let Some(j) = &args.json {
        let mut report = fix.report.clone();
        report["input"] = serde_json::json!(args
            .files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>());
        untangle::fsio::write_atomic(j, serde_json::to_string_pretty(&report)?.as_bytes())?;
    }
    if !ctx.quiet {
        print!("{}", text_summary(&fix));
        println!("wrote {}", args.out.display());
        if let Some(j) = &args.json {
            println!("wrote {}", j.display());
        }
        if let Some(d) = &args.frames {
            println!("wrote frames into {}", d.display());
        }
    }
    Ok(if fix.is_clean() { 0 } else { 1 })
}

/// The short human summary of a run.
pub fn text_summary(fix: &FixRun) -> String {
    use std::fmt::Write;
    let s = &fix.summary;
    let mut t = String::new();
    let outcome = match s.outcome {
        Outcome::Resolved if fix.is_clean() => "resolved",
        Outcome::Resolved => "cloth tanglements resolved",
        Outcome::StepLimit => "step limit reached",
        Outcome::Stuck => "stuck",
    };
    let _ = writeln!(
        t,
        "cha-ko: {outcome} after {} step{}: {} -> {} intersecting triangle pairs, {} -> {} red vertices",
        s.steps,
        if s.steps == 1 { "" } else { "s" },
        s.initial_pairs, s.final_pairs, s.initial_red_vertices, s.final_red_vertices
    );
    if fix.body_tail_steps > 0 {
        let _ = writeln!(
            t,
            "then {} steps with full collision handling to play the rest of the body animation",
            fix.body_tail_steps
        );
    }
    if fix.is_clean() {
        let _ = writeln!(t, "output: free of intersections");
    } else {
        let fa = &fix.final_analysis;
        let _ = writeln!(
            t,
            "output: {} intersecting triangle pairs in {} tanglements left",
            fa.segments.len(),
            fa.tanglements.len()
        );
        let r = Report::new(&fix.final_am, &fix.final_pos, fa);
        let kinds: Vec<String> = r
            .tanglements_by_kind
            .iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        let _ = writeln!(
            t,
            "  left: {} (locations in the JSON report)",
            kinds.join(", ")
        );
        if let Some(o) = &fix.output_state {
            let _ = writeln!(t, "{}", output_state_line(o, fa.segments.len()));
        }
        if fix.input_body_pairs > 0 {
            let _ = writeln!(
                t,
                "  the input already intersected the body in {} triangle pairs",
                fix.input_body_pairs
            );
        }
    }
    let ops: (usize, usize, usize) = fix.history.iter().fold((0, 0, 0), |a, h| {
        (
            a.0 + h.uv.pulls_started + h.uv.pulls_continued,
            a.1 + h.uv.shrinks_started + h.uv.shrinks_continued,
            a.2 + h.uv.revoked_levels,
        )
    });
    let _ = writeln!(
        t,
        "uv edits: {} pull levels, {} shrink levels, {} revoked levels",
        ops.0, ops.1, ops.2
    );
    let winding_steps = fix.history.iter().filter(|h| h.winding_paths > 0).count();
    if winding_steps > 0 {
        let _ = writeln!(
            t,
            "  winding regions (cloth inside another tube of the garment) coloured red in {winding_steps} steps"
        );
    }
    if let Some(line) = divergence_line(fix.history.iter().map(|h| (h.step as usize, h))) {
        let _ = writeln!(t, "  {line}");
    }
    for r in &s.finesse.rows {
        if r.count + r.unfinished > 0 {
            let _ = writeln!(
                t,
                "  {:?}: {} finesses, {:.2} steps each ({} unfinished)",
                r.seam, r.count, r.mean_steps, r.unfinished
            );
        }
    }
    for st in s.stalls.iter().take(5) {
        let mut line = format!("  stall: {:?}", st.reason);
        if let Some(v) = st.vertex {
            let _ = write!(line, " at vertex {v}");
        }
        if let Some(tri) = st.triangle {
            let _ = write!(line, " triangle {tri}");
        }
        if let Some(p) = st.position {
            let _ = write!(line, " near ({:.4}, {:.4}, {:.4})", p[0], p[1], p[2]);
        }
        let _ = writeln!(t, "{line}");
    }
    if s.stalls.len() > 5 {
        let _ = writeln!(
            t,
            "  ... {} stalls in all (see the JSON report)",
            s.stalls.len()
        );
    }
    if s.administrative_quits + s.analysis_errors > 0 {
        let _ = writeln!(
            t,
            "  {} administrative quits of the collision handling, {} failed analyses",
            s.administrative_quits, s.analysis_errors
        );
    }
    if let Some(line) = integrator_line(&fix.history) {
        let _ = writeln!(t, "{line}");
    }
    let total: f64 = fix.history.iter().map(step_ms).sum();
    let _ = writeln!(
        t,
        "time: {:.2} s ({:.2} ms/step: analysis {:.2}, uv update {:.2}, simulation {:.2})",
        total / 1e3,
        total / s.steps.max(1) as f64,
        s.mean_ms[0],
        s.mean_ms[1],
        s.mean_ms[2]
    );
    t
}
