//! The untangling loop of Wicke et al. 2006 (Sec. 3, Fig. 2) on our simulator: every step, the
//! global intersection analysis (Sec. 4), the correction forces of its paths ([`super::forces`],
//! Sec. 5.2-5.3) applied as a velocity change `dt F / m` before the step, and one simulator
//! step whose collision handling lets the free parts (inside regions and the intersecting
//! triangles) pass through each other while every other pair keeps the ordinary thickness.
//!
//! It stops when the analysis finds the cloth free of intersections, at `max_steps`, or when
//! the number of intersecting triangle pairs has not reached a new low for `stuck_steps`
//! steps. The paper gives no convergence guarantee (Cha & Ko 2022 report such loops leaving LL
//! cases unresolved); the loop reports how it ended either way.

use super::forces::{ForceContext, ForceParams, ForceReport};
use crate::analysis::{analyze, AnalysisMesh};
use crate::error::Result;
use crate::geom::Vec3;
use crate::mesh::Garment;
use crate::sim::{RedGreen, SimParams, Simulator, StepReport};
use std::time::Instant;

/// Settings of the loop.
#[derive(Clone, Debug, PartialEq)]
pub struct WickeParams {
    /// The correction forces.
    pub forces: ForceParams,
    /// Collision thickness of every pair that is not free (as Cha & Ko's `eps`).
    pub thickness: f64,
    /// The simulator (its `dt` is the loop's step).
    pub sim: SimParams,
    /// Step limit.
    pub max_steps: usize,
    /// Stop after this many steps without a new lowest count of intersecting pairs.
    pub stuck_steps: usize,
}

impl Default for WickeParams {
    fn default() -> Self {
        WickeParams {
            forces: ForceParams::default(),
            thickness: 1e-6,
            // Cha & Ko's loop's simulator (contacts within reach, soft impact zones, no
            // near-pair cap) at Cha & Ko's step, so the two methods are compared on one simulator.
            sim: SimParams {
                dt: 0.02,
                ..crate::methods::cha_ko::ResolveParams::default().sim
            },
            max_steps: 2000,
            stuck_steps: 100,
        }
    }
}

impl WickeParams {
    /// Checks every setting; the error names the bad one.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f64| {
            Err(crate::error::Error::Parameter(format!(
                "{what} must be a positive finite number (got {v})"
            )))
        };
        let f = &self.forces;
        if !(f.stiffness.is_finite() && f.stiffness > 0.0) {
            return bad("the Wicke force stiffness", f.stiffness);
        }
        if !(f.max_acceleration.is_finite() && f.max_acceleration > 0.0) {
            return bad("the Wicke force cap", f.max_acceleration);
        }
        if f.max_centers == 0 {
            return bad("the number of RBF centres", 0.0);
        }
        if !(self.thickness.is_finite() && self.thickness >= 0.0) {
            return Err(crate::error::Error::Parameter(format!(
                "the thickness must be a finite number >= 0 (got {})",
                self.thickness
            )));
        }
        self.sim.validate()
    }
}

/// How a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WickeOutcome {
    /// The analysis found no intersection.
    Resolved,
    /// `max_steps` ran out.
    StepLimit,
    /// No new lowest count of intersecting pairs for `stuck_steps` steps.
    Stuck,
}

/// One pass of the loop.
#[derive(Clone, Debug, PartialEq)]
pub struct WickeStep {
    /// Intersecting triangle pairs at the start of the step.
    pub intersecting_pairs: usize,
    /// Tanglements at the start of the step.
    pub tanglements: usize,
    /// What the forces acted on.
    pub forces: ForceReport,
    /// Milliseconds of analysis, force computation and simulation.
    pub ms: [f64; 3],
}

/// The loop over one garment.
pub struct WickeResolver {
    sim: Simulator,
    ctx: ForceContext,
    params: WickeParams,
    history: Vec<WickeStep>,
    clean: bool,
    best: usize,
    since_best: usize,
}

impl WickeResolver {
    /// A loop for `garment` (analysed as `am`, from [`AnalysisMesh::single`]) starting at its
    /// current positions, at rest.
    pub fn new(garment: &Garment, am: &AnalysisMesh, params: WickeParams) -> Result<WickeResolver> {
        params.validate()?;
        let sim = Simulator::new(garment, params.sim.clone())?;
        Ok(WickeResolver {
            sim,
            ctx: ForceContext::new(garment, am),
            params,
            history: Vec::new(),
            clean: false,
            best: usize::MAX,
            since_best: 0,
        })
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
    pub fn history(&self) -> &[WickeStep] {
        &self.history
    }

    /// Whether the last analysis found the cloth free of intersections.
    pub fn is_resolved(&self) -> bool {
        self.clean
    }

    /// One pass: analysis; if the cloth intersects, forces and a simulator step. Returns the
    /// pass's record and, when it stepped, the simulator's report. An analysis that finds an
    /// inconsistency is an error.
    pub fn step(&mut self) -> Result<(WickeStep, Option<StepReport>)> {
        crate::pool::in_pool(|| self.step_in_pool())
    }

    /// [`WickeResolver::step`]'s body, run inside rayon's pool ([`crate::pool::in_pool`]: one
    /// hand-over to a worker per step instead of one per parallel loop, as Cha & Ko's loop).
    fn step_in_pool(&mut self) -> Result<(WickeStep, Option<StepReport>)> {
        let t0 = Instant::now();
        let pos = self.sim.positions().to_vec();
        let a = analyze(&self.ctx.mesh, &pos).map_err(|e| {
            crate::error::Error::Parameter(format!("intersection analysis failed: {e:?}"))
        })?;
        let t1 = Instant::now();
        let ms = |x: Instant, y: Instant| (y - x).as_secs_f64() * 1e3;
        let pairs = a.segments.len();
        if pairs < self.best {
            self.best = pairs;
            self.since_best = 0;
        } else {
            self.since_best += 1;
        }
        if a.is_clean() {
            self.clean = true;
            let s = WickeStep {
                intersecting_pairs: 0,
                tanglements: 0,
                forces: ForceReport::default(),
                ms: [ms(t0, t1), 0.0, 0.0],
            };
            self.history.push(s.clone());
            return Ok((s, None));
        }
        self.clean = false;
        let (acc, free, forces) =
            self.ctx
                .accelerations(&a, &pos, self.sim.masses(), &self.params.forces);
        let h = self.params.sim.dt;
        let v: Vec<Vec3> = self
            .sim
            .velocities()
            .iter()
            .zip(&acc)
            .map(|(v, a)| v + a * h)
            .collect();
        self.sim.set_velocities(&v)?;
        let policy = free_policy(&self.ctx, free, self.params.thickness);
        let t2 = Instant::now();
        let report = self.sim.step(&policy);
        let t3 = Instant::now();
        let s = WickeStep {
            intersecting_pairs: pairs,
            tanglements: a.tanglements.len(),
            forces,
            ms: [ms(t0, t1), ms(t1, t2), ms(t2, t3)],
        };
        self.history.push(s.clone());
        Ok((s, Some(report)))
    }

    /// Why the loop would stop now, if it would.
    pub fn stop_reason(&self) -> Option<WickeOutcome> {
        if self.clean {
            Some(WickeOutcome::Resolved)
        } else if self.history.len() >= self.params.max_steps {
            Some(WickeOutcome::StepLimit)
        } else if self.since_best >= self.params.stuck_steps {
            Some(WickeOutcome::Stuck)
        } else {
            None
        }
    }

    /// Steps until the loop stops; `on_step` sees every pass.
    pub fn run(&mut self, mut on_step: impl FnMut(&WickeStep)) -> Result<WickeOutcome> {
        loop {
            if let Some(o) = self.stop_reason() {
                return Ok(o);
            }
            let (s, _) = self.step()?;
            on_step(&s);
        }
    }
}

/// The collision policy of a step: free vertices, the edges and triangles with a free vertex,
/// pass through each other (as Cha & Ko's red-red pairs); every other pair keeps `thickness`.
pub fn free_policy(ctx: &ForceContext, free: Vec<bool>, thickness: f64) -> RedGreen {
    let g = &ctx.garment;
    RedGreen {
        red_edge: g
            .topology
            .edges
            .iter()
            .map(|e| free[e[0] as usize] || free[e[1] as usize])
            .collect(),
        red_triangle: g
            .mesh
            .triangles
            .iter()
            .map(|t| t.iter().any(|&v| free[v as usize]))
            .collect(),
        red_vertex: free,
        epsilon: thickness,
        epsilon_rg: thickness,
    }
}
