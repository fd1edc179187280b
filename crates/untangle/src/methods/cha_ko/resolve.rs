//! The simulation loop of Cha & Ko 2022, Fig. 1b: every step, intersection analysis and
//! colouring (Sec. 3), the uv-space mesh update (Alg. 2), then one simulator step whose
//! collision handling is the m-CCH policy of the step's colouring (Sec. 5.2-5.3).
//!
//! The loop stops when the cloth is free of intersections *and* every uv edit has been revoked
//! (the garment is back at its original rest shape), when `max_steps` is reached, or when it is
//! stuck: for `stuck_steps` consecutive steps the cloth still intersects and either the uv
//! update changed nothing (no operation could start or continue: e.g. only BLI paths) or the
//! number of intersecting triangle pairs never went below its best so far (operations keep
//! saturating and being abandoned). Every way of stopping is reported; it never loops silently.
//!
//! While the cloth intersects, every simulator step is checked by the divergence guard
//! ([`super::divergence`], on by default): a step whose energy grew more than
//! [`DivergenceGuard::ratio`] times is undone, the operations it came from are given up and
//! restored, and the step is run again.
//!
//! If the intersection analysis fails on a step (it reports an inconsistency instead of
//! guessing), the step is recorded with the error, the uv is left as it is, and the simulator
//! steps with the last good colouring's m-CCH policy (or plain CCH with `eps` on the first step).

use super::adaptive::{AdaptiveIntegrator, IntegratorSchedule, IntegratorSwitch};
use super::divergence::{self, DivergenceGuard, DivergenceReport};
use super::report::{FinesseStats, Stall, UvUpdateReport};
use super::subjects::{collision_mass_factors, subject_flags, HeavyScope};
use super::trial::{trial_step, BlockHistory, TrialReport};
use super::{regionless, slit, ChaKo, Params};
use crate::analysis::{analyze_with, Analysis, AnalysisMesh, Coloring};
use crate::error::Result;
use crate::geom::Vec3;
use crate::mesh::Garment;
use crate::sim::{Integrator, SimParams, Simulator, StepReport, UniformThickness, ZoneMotion};
use std::time::Instant;

/// Settings of the loop.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolveParams {
    /// The method's parameters (gamma, dt, epsilons, ...); `dt` is the simulator's step.
    pub cha_ko: Params,
    /// The simulator's parameters (its `dt` is replaced by `cha_ko.dt`).
    pub sim: SimParams,
    /// Step limit.
    pub max_steps: usize,
    /// Stop after this many consecutive steps without any uv change, or without a new lowest
    /// count of intersecting pairs, while intersecting.
    pub stuck_steps: usize,
    /// Run the uv-space update (off: m-CCH alone, for ablation experiments).
    pub uv_update: bool,
    /// Regionless-tanglement fallback (ours, [`super::regionless`]): after this many steps
    /// without a new lowest count of intersecting pairs while no vertex is red, the corners of
    /// the intersecting triangles of tanglements without a usable region are coloured red, and
    /// the stall may last `stuck_steps` more steps from then. 0 (the default) turns it off: at
    /// 30 it resolved 6 of 7 CROSS runs, but on `cross` only for values 25-40, and it made 2 of
    /// 12 exploded-handkerchief runs stuck (docs/cha-ko.md).
    pub regionless_after: usize,
    /// Slit ridges (ours, [`super::slit`]; on by default): in every step in which the cloth
    /// intersects, no vertex is red and `slit_stall` steps have passed without a new lowest
    /// count of intersecting pairs, the ridge vertices of partitioning paths that run out and
    /// back through the same triangles (no region) are coloured red, so the fold that pokes
    /// through the slit is pulled back across it. With it CROSS and the Untangling26 Cross unit
    /// resolve, and the exploded handkerchief resolves 99 / 100 seeds (1-100) against 98 without
    /// it, for a median of 113 steps against 111 (docs/cha-ko.md, "Slits"). `false` gives the
    /// loop of session 20.
    pub slit_ridges: bool,
    /// With `slit_ridges`: act only after this many steps without a new lowest count of
    /// intersecting pairs (default 10; 0: as soon as a slit is seen with no vertex red, which
    /// resolves CROSS sooner but gives the exploded handkerchief a median of 119 steps).
    pub slit_stall: usize,
    /// Heavy subjects (ours, [`super::subjects`]; 1 = off, the default): the mass factor, in the
    /// simulator's collision handling only, of the vertices of running operations that
    /// `heavy_scope` selects, so that CCD impulses and impact zones take less of a pull back.
    pub heavy_subjects: f64,
    /// Which vertices `heavy_subjects` makes heavy.
    pub heavy_scope: HeavyScope,
    /// Thin red-green pairs at the subjects (ours, [`super::subjects`]; 1 = off, the default):
    /// red-green pairs whose red primitive has a running operation's subject keep this
    /// fraction of `epsilon_RG` (never below `epsilon`); `epsilon_RG` itself is unchanged.
    pub subject_rg_scale: f64,
    /// Analysis options. By default BLI paths colour their cone regions red (Wicke's heuristic),
    /// which goes beyond the paper (Cha & Ko leave BLI out): their vertices are then pulled like
    /// any red region. With `bli_regions_red = false` a BLI-only tanglement is reported as a
    /// stall ("nothing to operate on") with its location and the loop stops as stuck. Paths
    /// that get no region from Wicke's rules on a garment (long interior BLIs, BI paths, cuts
    /// that do not separate) get the region of the generalized winding number
    /// (`winding_regions`, on by default; ours): the cloth that has passed into another tube of
    /// the same garment, coloured red and pulled out the same way.
    pub analysis: crate::analysis::Options,
    /// Cap of the CG iterations of one projective global step under contact terms, for the
    /// loop's simulator only (ours): when `sim.integrator` is [`Integrator::Projective`] it
    /// replaces `sim.projective_cg_iterations` (see [`SimParams::projective_cg_iterations`]);
    /// `None` keeps that value, and Baraff & Witkin ignores it. Plain simulation keeps its
    /// own full CG (cap 10). Default 1: one factor-preconditioned steepest-descent step per
    /// global step: -22 % instructions per loop step on the t-shirt benchmark, 43 / 50
    /// exploded-handkerchief seeds resolved against 38 / 50 with the full CG, the same
    /// resolved sets on the rudimentary cases and garments (BENCHMARKS.md, branch loop10).
    pub projective_cg_cap: Option<usize>,
    /// The adaptive integrator (ours, [`super::adaptive`]): when set, the loop's simulator
    /// starts with projective dynamics (whatever `sim.integrator` says) and switches to
    /// Baraff & Witkin for a stretch of steps when the intersecting-pair count stalls. `None`
    /// runs `sim.integrator` throughout.
    pub adaptive: Option<AdaptiveIntegrator>,
    /// The divergence guard (ours, [`super::divergence`]; on by default): a simulator step
    /// whose energy grew more than [`DivergenceGuard::ratio`] times is undone, and the
    /// operations at the triangles that grew are given up and restored. `None` turns it off.
    pub divergence: Option<DivergenceGuard>,
}

impl Default for ResolveParams {
    fn default() -> Self {
        ResolveParams {
            cha_ko: Params::default(),
            sim: SimParams {
                // The loop's cases were validated with every pair within reach as a contact.
                contacts_within_reach: true,
                // m-CCH's thicknesses are the paper's (epsilon_RG is tied to the edge length).
                near_pair_fraction: 0.0,
                // Soft impact zones (ours): a tangle under the large stretch forces of deep
                // pulls kept forming one rigid zone over nearly the whole cloth every step, so
                // it could not contract at all (exploded handkerchief: 49 / 50 seeds resolved
                // with soft zones against 47 / 50 rigid; BENCHMARKS.md, docs/cha-ko.md).
                zone_motion: ZoneMotion {
                    spin: true,
                    soft_levels: 4,
                },
                ..SimParams::default()
            },
            max_steps: 2000,
            stuck_steps: 100,
            uv_update: true,
            regionless_after: 0,
            slit_ridges: true,
            slit_stall: 10,
            heavy_subjects: 1.0,
            heavy_scope: HeavyScope::Subjects,
            subject_rg_scale: 1.0,
            analysis: crate::analysis::Options {
                bli_regions_red: true,
                winding_regions: true,
            },
            projective_cg_cap: Some(1),
            adaptive: None,
            divergence: Some(DivergenceGuard::default()),
        }
    }
}

/// What one pass of the loop saw and did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoopStep {
    /// Step number.
    pub step: u64,
    /// Intersecting triangle pairs at the start of the step.
    pub intersecting_pairs: usize,
    /// Vertices the regionless-tanglement fallback coloured red this step (ours,
    /// [`super::regionless`]; 0 when it did not act). `red_vertices` includes them.
    pub regionless_red: usize,
    /// Slit ridge vertices coloured red this step (ours, [`super::slit`]; 0 when none).
    /// `red_vertices` includes them.
    pub slit_red: usize,
    /// BLI loop vertices whose edges m-CCH opened this step (ours,
    /// [`super::policy::open_bli_loops`]; 0 when none).
    pub open_bli_loops: usize,
    /// Paths whose inside region this step is a winding region (ours,
    /// [`crate::analysis::regions::RegionFinder::winding_region`]).
    pub winding_paths: usize,
    /// Red vertices at the start of the step.
    pub red_vertices: usize,
    /// Red triangles at the start of the step.
    pub red_triangles: usize,
    /// Tanglements (world-space intersection curves).
    pub tanglements: usize,
    /// The uv update.
    pub uv: UvUpdateReport,
    /// The trial step ([`Params::trial_retries`]): retries and blocked pairs.
    pub trial: TrialReport,
    /// The integrator of this step's simulator step.
    pub integrator: Integrator,
    /// Why the adaptive integrator ([`ResolveParams::adaptive`]) changed the integrator
    /// before this step (`None`: same as the previous step, or no adaptive integrator).
    pub integrator_switch: Option<IntegratorSwitch>,
    /// The divergence guard ([`ResolveParams::divergence`]): diverged tries and the
    /// operations given up.
    pub divergence: DivergenceReport,
    /// Whether the simulator's collision handling ended the step with an administrative quit.
    pub administrative_quit: bool,
    /// Impact zones the simulator needed.
    pub impact_zones: usize,
    /// The analysis error of this step, if it failed (the step then used the previous
    /// colouring and left the uv alone).
    pub analysis_error: Option<String>,
    /// Milliseconds in the analysis, the uv update, the simulator's rest-shape update and the
    /// simulator step.
    pub ms_analysis: f64,
    /// See `ms_analysis`.
    pub ms_uv: f64,
    /// See `ms_analysis`.
    pub ms_rest: f64,
    /// See `ms_analysis`.
    pub ms_sim: f64,
}

/// Why the loop stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Free of intersections and back at the original rest shape.
    Resolved,
    /// Step limit reached.
    StepLimit,
    /// No uv change, or no new lowest count of intersecting pairs, for `stuck_steps` steps.
    Stuck,
}

/// Summary of a run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ResolveSummary {
    /// Why it stopped.
    pub outcome: Outcome,
    /// Steps run.
    pub steps: u64,
    /// First step at whose start the cloth was free of intersections (and stayed so).
    pub clean_at: Option<u64>,
    /// Intersecting pairs and red vertices at the first and the last analysed step.
    pub initial_pairs: usize,
    /// See `initial_pairs`.
    pub initial_red_vertices: usize,
    /// See `initial_pairs`.
    pub final_pairs: usize,
    /// See `initial_pairs`.
    pub final_red_vertices: usize,
    /// The Table 1 analogue.
    pub finesse: FinesseStats,
    /// Every stall reported during the run.
    pub stalls: Vec<Stall>,
    /// Steps that ended with an administrative quit of the collision handling.
    pub administrative_quits: usize,
    /// Steps whose intersection analysis failed.
    pub analysis_errors: usize,
    /// Mean milliseconds per step of analysis, uv update (with the simulator's rest-shape
    /// update) and simulation.
    pub mean_ms: [f64; 3],
}

/// The loop: a [`ChaKo`] updater and a [`Simulator`] over the same garment.
pub struct Resolver {
    chako: ChaKo,
    sim: Simulator,
    am: AnalysisMesh,
    params: ResolveParams,
    history: Vec<LoopStep>,
    clean_at: Option<u64>,
    idle: usize,
    best_pairs: usize,
    since_best: usize,
    /// The stall length at which the regionless fallback first acted in the current stall.
    regionless_fired_at: Option<usize>,
    /// The stall length at which the adaptive integrator switched to Baraff & Witkin in the
    /// current stall ([`AdaptiveIntegrator::restart_stall`]).
    switched_at: Option<usize>,
    last_clean: bool,
    last_coloring: Option<Coloring>,
    /// The analysis of the positions a trial step accepted, reused at the start of the next
    /// step (with the positions it is of, in case the caller moved the cloth in between).
    analysed: Option<(Vec<Vec3>, Analysis)>,
    /// Pairs the trial step blocked in the last step, with the number of consecutive steps
    /// they have been blocked ([`Params::trial_release_after`]).
    blocked_for: BlockHistory,
    /// The adaptive integrator's state ([`ResolveParams::adaptive`]).
    schedule: Option<IntegratorSchedule>,
    /// [`divergence::energy_floor`] of the garment.
    energy_floor: f64,
}

/// Sets the loop simulator's integrator, with the loop's CG cap of projective global steps
/// ([`ResolveParams::projective_cg_cap`]) when it is projective dynamics.
fn set_integrator(sp: &mut SimParams, integrator: Integrator, cap: Option<usize>) {
    sp.integrator = integrator;
    if let (Integrator::Projective, Some(k)) = (integrator, cap) {
        sp.projective_cg_iterations = k;
    }
}

impl Resolver {
    /// A loop for `garment` starting at its current positions, at rest.
    pub fn new(garment: &Garment, params: ResolveParams) -> Result<Resolver> {
        if let Some(g) = &params.divergence {
            g.validate()?;
        }
        let mut sp = params.sim.clone();
        sp.dt = params.cha_ko.dt;
        let schedule = params.adaptive.map(IntegratorSchedule::new);
        let integrator = schedule.as_ref().map_or(sp.integrator, |s| s.current());
        set_integrator(&mut sp, integrator, params.projective_cg_cap);
        let sim = Simulator::new(garment, sp)?;
        let chako = ChaKo::new(garment, params.cha_ko.clone())?;
        let (am, _) = AnalysisMesh::single(&garment.mesh)?;
        let energy_floor = divergence::energy_floor(garment, params.sim.stretch_stiffness);
        Ok(Resolver {
            chako,
            sim,
            am,
            params,
            history: Vec::new(),
            clean_at: None,
            idle: 0,
            best_pairs: usize::MAX,
            since_best: 0,
            regionless_fired_at: None,
            switched_at: None,
            last_clean: false,
            last_coloring: None,
            analysed: None,
            blocked_for: Default::default(),
            schedule,
            energy_floor,
        })
    }

    /// The uv updater.
    pub fn chako(&self) -> &ChaKo {
        &self.chako
    }

    /// The simulator (pin vertices, add obstacles, read positions).
    pub fn simulator(&self) -> &Simulator {
        &self.sim
    }

    /// Mutable access to the simulator.
    pub fn simulator_mut(&mut self) -> &mut Simulator {
        &mut self.sim
    }

    /// Every step so far.
    pub fn history(&self) -> &[LoopStep] {
        &self.history
    }

    /// Whether the last analysed state was free of intersections and the uv is restored.
    pub fn is_resolved(&self) -> bool {
        self.last_clean && self.chako.is_restored()
    }

    /// One pass of Fig. 1b: analysis, uv update, simulator step with m-CCH. Returns the pass's
    /// record and the simulator's step report.
    pub fn step(&mut self) -> Result<(LoopStep, StepReport)> {
        crate::pool::in_pool(|| self.step_in_pool())
    }

    /// [`Resolver::step`]'s body, run inside rayon's pool ([`crate::pool::in_pool`]: one
    /// hand-over to a worker thread per loop step).
    fn step_in_pool(&mut self) -> Result<(LoopStep, StepReport)> {
        let integrator_switch = self.apply_schedule()?;
        let t0 = Instant::now();
        let pos: Vec<Vec3> = self.sim.positions().to_vec();
        let analysis = match self.analysed.take() {
            Some((p, a)) if p == pos => Ok(a),
            _ => analyze_with(&self.am, &pos, &self.params.analysis),
        };
        let t1 = Instant::now();
        let ms = |x: Instant, y: Instant| (y - x).as_secs_f64() * 1e3;
        let mut a = match analysis {
            Ok(a) => a,
            Err(e) => {
                return Ok(self.step_without_analysis(
                    format!("{e:?}"),
                    ms(t0, t1),
                    integrator_switch,
                ))
            }
        };
        self.chako.persist_coloring(&self.am, &mut a);
        let clean = a.is_clean();
        let slit_red = if self.params.slit_ridges
            && !clean
            && self.since_best >= self.params.slit_stall
            && a.coloring.num_red_vertices() == 0
        {
            slit::color_slits(&self.am, &mut a)
        } else {
            0
        };
        let regionless_red = if self.params.regionless_after > 0
            && !clean
            && self.since_best >= self.params.regionless_after
            && a.coloring.num_red_vertices() == 0
        {
            let n = regionless::color_regionless(&self.am, &mut a);
            if n > 0 && self.regionless_fired_at.is_none() {
                self.regionless_fired_at = Some(self.since_best);
            }
            n
        } else {
            0
        };
        let mut uv = if self.params.uv_update {
            self.chako.update_uv(&self.am, &a, &pos)?
        } else {
            UvUpdateReport::default()
        };
        let t_rest = Instant::now();
        if uv.uv_changed {
            self.sim.set_rest_uv(self.chako.current_uv())?;
        }
        let t2 = Instant::now();
        let mut open_loops = if !clean && self.chako.params().open_bli_loops {
            super::policy::open_bli_loops(&self.am, &a)
        } else {
            Vec::new()
        };
        // The running BLI sectors open their loop vertex too ([`super::sectors`]).
        if !clean {
            open_loops.extend(self.chako.running_sectors().map(|op| op.target));
            open_loops.sort_unstable();
            open_loops.dedup();
        }
        let open_bli_loops = open_loops.len();
        let open_edges = super::policy::edges_at(&self.am, &open_loops);
        let guard = self.params.divergence.filter(|_| !clean);
        let snap = guard.map(|_| self.sim.snapshot());
        let (mut sr, mut trial) = self.simulate(&a, open_edges.as_deref())?;
        let mut divergence = DivergenceReport::default();
        if let (Some(g), Some(snap)) = (guard, snap) {
            for round in 0..=g.rounds {
                let start = sr.energy.stretch + sr.energy.kinetic;
                let end_tri = self.sim.stretch_energies(self.sim.positions())?;
                let end = end_tri.iter().sum::<f64>() + self.sim.kinetic_energy();
                divergence.growth = divergence::growth(start, end, self.energy_floor);
                if !divergence::diverged(start, end, g.ratio, self.energy_floor) {
                    break;
                }
                divergence.diverged += 1;
                divergence.max_growth = divergence.max_growth.max(divergence.growth);
                let before = self.sim.stretch_energies(snap.positions())?;
                let growth: Vec<f64> = end_tri.iter().zip(&before).map(|(e, b)| e - b).collect();
                let ids = divergence::charged(
                    self.chako.operations(),
                    &self.chako.garment().topology,
                    &growth,
                    g.share,
                );
                if ids.is_empty() || round == g.rounds {
                    divergence.kept_diverged = true;
                    break;
                }
                let stalls = self.chako.give_up(&ids, Some(&pos));
                uv.abandoned += ids.len();
                uv.stalls.extend(stalls);
                uv.active_ops = self.chako.operations().count();
                divergence.given_up.extend(ids);
                self.sim.restore(&snap)?;
                self.sim.set_rest_uv(self.chako.current_uv())?;
                (sr, trial) = self.simulate(&a, open_edges.as_deref())?;
            }
        }
        let t3 = Instant::now();
        let index = self.history.len() as u64;
        if clean && self.clean_at.is_none() {
            self.clean_at = Some(index);
        } else if !clean {
            self.clean_at = None;
        }
        self.last_clean = clean;
        self.idle = if !clean && !uv.uv_changed {
            self.idle + 1
        } else {
            0
        };
        if a.segments.len() < self.best_pairs {
            self.best_pairs = a.segments.len();
            self.since_best = 0;
            self.regionless_fired_at = None;
            self.switched_at = None;
        } else {
            self.since_best += 1;
        }
        let rec = LoopStep {
            step: index,
            intersecting_pairs: a.segments.len(),
            regionless_red,
            slit_red,
            open_bli_loops,
            winding_paths: a.winding_region_paths.len(),
            red_vertices: a.coloring.num_red_vertices(),
            red_triangles: a.coloring.num_red_triangles(),
            tanglements: a.tanglements.len(),
            uv,
            trial,
            integrator: self.sim.params().integrator,
            integrator_switch,
            divergence,
            administrative_quit: sr.administrative_quit(),
            impact_zones: sr.collisions.impact_zones,
            analysis_error: None,
            ms_analysis: ms(t0, t1),
            ms_uv: ms(t1, t_rest),
            ms_rest: ms(t_rest, t2),
            ms_sim: ms(t2, t3),
        };
        self.last_coloring = Some(a.coloring);
        if let Some(s) = &mut self.schedule {
            s.observe(rec.intersecting_pairs);
        }
        self.history.push(rec.clone());
        Ok((rec, sr))
    }

    /// The simulator step of a pass with the m-CCH policy of `a` (with the heavy subjects and
    /// thin red-green pairs of the operations in progress, the open BLI loops' `open_edges`,
    /// and the trial step when on).
    fn simulate(
        &mut self,
        a: &Analysis,
        open_edges: Option<&[bool]>,
    ) -> Result<(StepReport, TrialReport)> {
        if self.params.heavy_subjects != 1.0 {
            let n = self.sim.positions().len();
            let f = collision_mass_factors(
                self.chako.operations(),
                &self.chako.garment().topology,
                n,
                self.params.heavy_subjects,
                self.params.heavy_scope,
            );
            self.sim.set_collision_mass_factors(f)?;
        }
        let subjects: Vec<bool>;
        let mut policy = self.chako.contact_policy(&self.am, a);
        policy.open_edges = open_edges;
        let transparent = super::sectors::transparency(
            self.chako.running_sectors(),
            self.chako.sectors(),
            self.sim.positions().len(),
        );
        policy.transparent = transparent.as_ref().map(|(s, p)| (&s[..], &p[..]));
        if self.params.subject_rg_scale != 1.0 {
            subjects = subject_flags(self.chako.operations(), self.sim.positions().len());
            let t =
                (self.chako.eps_rg() * self.params.subject_rg_scale).max(self.chako.params().eps);
            policy.thin_rg = Some((&subjects, t));
        }
        Ok(if self.params.cha_ko.trial_retries > 0 && !a.is_clean() {
            let t = trial_step(
                &mut self.sim,
                &self.am,
                a,
                &policy,
                &self.params.cha_ko,
                &self.params.analysis,
                &mut self.blocked_for,
            )?;
            self.analysed = t.analysed;
            (t.step, t.trial)
        } else {
            (self.sim.step(&policy), TrialReport::default())
        })
    }

    /// Puts the adaptive integrator's choice into the simulator; returns why it changed.
    fn apply_schedule(&mut self) -> Result<Option<IntegratorSwitch>> {
        let Some(s) = &self.schedule else {
            return Ok(None);
        };
        let want = s.current();
        if s.pending_switch() == Some(IntegratorSwitch::Stalled)
            && s.params().restart_stall
            && self.switched_at.is_none()
        {
            self.switched_at = Some(self.since_best);
        }
        if self.sim.params().integrator != want {
            let mut sp = self.sim.params().clone();
            set_integrator(&mut sp, want, self.params.projective_cg_cap);
            self.sim.set_params(sp)?;
        }
        Ok(s.pending_switch())
    }

    /// A step whose analysis failed: no uv update, the last good colouring's policy.
    fn step_without_analysis(
        &mut self,
        error: String,
        ms_analysis: f64,
        integrator_switch: Option<IntegratorSwitch>,
    ) -> (LoopStep, StepReport) {
        let t2 = Instant::now();
        let sr = match &self.last_coloring {
            Some(c) => {
                let p = &self.chako.params;
                let mut policy = super::MchPolicy::new(&self.am, c, p.eps, self.chako.eps_rg);
                policy.mixed_edges = p.mixed_edges;
                self.sim.step(&policy)
            }
            None => self.sim.step(&UniformThickness(self.chako.params.eps)),
        };
        let ms_sim = (Instant::now() - t2).as_secs_f64() * 1e3;
        let prev = self.history.last();
        let rec = LoopStep {
            step: self.history.len() as u64,
            intersecting_pairs: prev.map_or(0, |s| s.intersecting_pairs),
            regionless_red: 0,
            slit_red: 0,
            open_bli_loops: 0,
            winding_paths: 0,
            red_vertices: prev.map_or(0, |s| s.red_vertices),
            red_triangles: prev.map_or(0, |s| s.red_triangles),
            tanglements: prev.map_or(0, |s| s.tanglements),
            uv: UvUpdateReport {
                step: self.chako.steps(),
                active_ops: self.chako.operations().count(),
                ..Default::default()
            },
            trial: TrialReport::default(),
            integrator: self.sim.params().integrator,
            integrator_switch,
            divergence: DivergenceReport::default(),
            administrative_quit: sr.administrative_quit(),
            impact_zones: sr.collisions.impact_zones,
            analysis_error: Some(error),
            ms_analysis,
            ms_uv: 0.0,
            ms_rest: 0.0,
            ms_sim,
        };
        self.last_clean = false;
        self.idle += 1;
        self.since_best += 1;
        if let Some(s) = &mut self.schedule {
            s.observe(rec.intersecting_pairs);
        }
        self.history.push(rec.clone());
        (rec, sr)
    }

    /// Whether the loop should stop before another step, and why (see the module text):
    /// resolved, stuck, or at the step limit. Callers driving the loop themselves with
    /// [`Resolver::step`] (to move obstacles or write frames between steps) stop on it.
    pub fn stop_reason(&self) -> Option<Outcome> {
        if self.is_resolved() {
            return Some(Outcome::Resolved);
        }
        if !self.history.is_empty()
            && !self.last_clean
            && (self.idle >= self.params.stuck_steps
                || self.since_best
                    >= self
                        .regionless_fired_at
                        .max(self.switched_at)
                        .map_or(self.params.stuck_steps, |f| f + self.params.stuck_steps))
        {
            return Some(Outcome::Stuck);
        }
        if self.history.len() >= self.params.max_steps {
            return Some(Outcome::StepLimit);
        }
        None
    }

    /// Runs until resolved, stuck or `max_steps` (see the module text); `on_step` sees every
    /// pass (for progress bars and logs).
    pub fn run(&mut self, mut on_step: impl FnMut(&LoopStep)) -> Result<ResolveSummary> {
        let outcome = loop {
            if let Some(o) = self.stop_reason() {
                break o;
            }
            let (rec, _) = self.step()?;
            on_step(&rec);
        };
        Ok(self.summary(outcome))
    }

    /// The summary of the run so far.
    pub fn summary(&self, outcome: Outcome) -> ResolveSummary {
        let h = &self.history;
        let n = h.len().max(1) as f64;
        let mean = |f: fn(&LoopStep) -> f64| h.iter().map(f).sum::<f64>() / n;
        ResolveSummary {
            outcome,
            steps: h.len() as u64,
            clean_at: self.clean_at,
            initial_pairs: h.first().map_or(0, |s| s.intersecting_pairs),
            initial_red_vertices: h.first().map_or(0, |s| s.red_vertices),
            final_pairs: h.last().map_or(0, |s| s.intersecting_pairs),
            final_red_vertices: h.last().map_or(0, |s| s.red_vertices),
            finesse: self.chako.finesse_stats(),
            stalls: h.iter().flat_map(|s| s.uv.stalls.iter().cloned()).collect(),
            administrative_quits: h.iter().filter(|s| s.administrative_quit).count(),
            analysis_errors: h.iter().filter(|s| s.analysis_error.is_some()).count(),
            mean_ms: [
                mean(|s| s.ms_analysis),
                mean(|s| s.ms_uv + s.ms_rest),
                mean(|s| s.ms_sim),
            ],
        }
    }
}
