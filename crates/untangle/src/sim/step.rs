//! The simulator and its time step: implicit Euler (Baraff & Witkin 1998, Sec. 5) followed by
//! the full-proof collision handling.
//!
//! One step with step length `h`, masses `M`, forces `f(x, v)`, stiffness `K = -df/dx`
//! (stretch/shear and bending) and Rayleigh damping `D = alpha M + beta K` solves
//! `(M + h D + h^2 K) dv = h (f - D v - h K v)` by filtered PCG (pinned vertices prescribed),
//! then hands the new velocities to the collision handling, which changes them so that the
//! straight-line motion over the step creates no intersection; finally `x += h v`.

use std::time::Instant;

use nalgebra::Matrix3;
use rayon::prelude::*;

use super::amg::{Amg, AmgSettings};
use super::anderson::Anderson;
use super::cholesky::ScalarCholesky;
use super::collision::impact_zones::ZoneMotion;
use super::collision::{self, broad::BroadPhase, CollisionSettings, Scene};
use super::collision::{Pair, PairKind};
use super::contact::ObstacleContact;
use super::contact::{self, ContactFinder};
use super::forces::stretch::{stretch_energy, stretch_terms, StretchTerms, BLOCKS};
use super::low_rank;
use super::near::NearCapped;
use super::obstacle::{Obstacle, Obstacles};
use super::pcg::{self, Aggregation, CoarseLevel, Filter, PcgResult, PcgSettings};
use super::policy::Contact;
use super::policy::ContactPolicy;
use super::projective::{self, Elastic, Projective, ProjectiveResult, StepProblem};
use super::report::{CollisionShift, Energy, StepReport, StepTiming};
use super::rest::{bend_terms, resum_slots, RestEdit, RestIndex, RestShape};
use super::sparse::{BsrMatrix, BsrPattern};
use crate::error::{Error, Result};
use crate::geom::{Vec2, Vec3};
use crate::mesh::{Garment, Topology};
use std::sync::Arc;

/// Rounds of releasing pulling obstacle contacts and solving again.
const MAX_RELEASE_ROUNDS: usize = 3;
/// Meshes from this many vertices on get the coarse-grid CG preconditioner.
const COARSE_MIN_VERTICES: usize = 200;
/// Target number of coarse aggregates (the coarse matrix is dense, `3 x` this many unknowns).
const COARSE_AGGREGATES: usize = 64;
/// Smallest aggregate.
const COARSE_MIN_SIZE: usize = 16;
/// The multigrid hierarchy is rebuilt when a solve needs more than this many times the
/// iterations of the first solve after the last build (plus [`AMG_REBUILD_SLACK`]).
const AMG_REBUILD_FACTOR: usize = 2;
/// Iterations added to the rebuild threshold (small counts fluctuate).
const AMG_REBUILD_SLACK: usize = 6;
/// Steps after which the hierarchy is rebuilt anyway.
const AMG_MAX_AGE: u64 = 50;
/// Largest friction damping per step as a multiple of the vertex mass (sticking).
const FRICTION_CAP: f64 = 100.0;

/// Material, integrator and collision parameters. Units: SI (metres, kilograms, seconds).
#[derive(Clone, Debug, PartialEq)]
pub struct SimParams {
    /// Step length (s). Cha & Ko use 0.02.
    pub dt: f64,
    /// Area density (kg/m^2).
    pub density: f64,
    /// Stretch stiffness (N/m), Baraff & Witkin's `k` of the stretch condition per unit area.
    pub stretch_stiffness: f64,
    /// Shear stiffness (N/m).
    pub shear_stiffness: f64,
    /// Bending stiffness (N m).
    pub bend_stiffness: f64,
    /// Mass-proportional damping `alpha` (1/s).
    pub damping_mass: f64,
    /// Stiffness-proportional damping `beta` (s).
    pub damping_stiffness: f64,
    /// Gravity (m/s^2).
    pub gravity: Vec3,
    /// Cloth-cloth friction coefficient.
    pub friction: f64,
    /// Tolerance of CG: relative to the right-hand side, with an absolute floor of this times
    /// the velocity gravity adds in one step (RMS, mass-weighted; see [`PcgSettings::absolute`]).
    pub cg_tolerance: f64,
    /// Iteration cap of CG.
    pub cg_max_iterations: usize,
    /// Whether collisions are handled at all.
    pub collisions: bool,
    /// Whether proximity repulsion runs before CCD (turning it off leaves everything to CCD
    /// impulses and impact zones; for testing the fail-safes).
    pub proximity: bool,
    /// Fraction of a pair's thickness that CCD guarantees (proximity aims at the full thickness).
    pub ccd_ratio: f64,
    /// CCD impulse passes before impact zones.
    pub max_impulse_iterations: usize,
    /// Impact-zone passes before the fail-safe stops the cloth for the step.
    pub max_zone_iterations: usize,
    /// Which cloth-cloth pairs become contact springs in the next step's implicit solve
    /// ([`crate::sim::contact`]): `false` (default) = pairs that start within twice their
    /// thickness or received a proximity impulse; `true` = also every pair that could come
    /// within its thickness during the step. The second gives many more springs on fast fine
    /// cloth (189k in one step of a 20k-vertex shirt), the first changed the Cha & Ko loop's
    /// trajectories so that some of its validated cases stopped resolving, so the loop uses
    /// `true` ([`crate::methods::cha_ko::ResolveParams`]).
    pub contacts_within_reach: bool,
    /// Preconditioner of CG for meshes of at least 200 vertices (smaller ones use block-Jacobi).
    pub preconditioner: CgPreconditioner,
    /// How free rigid impact zones move (see [`ZoneMotion`]).
    pub zone_motion: ZoneMotion,
    /// The time integrator of the cloth dynamics (before collision handling).
    pub integrator: Integrator,
    /// Local/global iterations per step of [`Integrator::Projective`].
    pub projective_iterations: usize,
    /// Spectral-radius estimate `rho` of the Chebyshev acceleration of the local/global
    /// iterations (Wang 2015); 0 turns it off. Applied only to steps whose global steps are
    /// direct solves: the factor is current (no rest edit since) and the contact terms, if any,
    /// are few enough for a low-rank correction ([`crate::sim::low_rank`]). Default 0.9: on the
    /// t-shirt benchmark 10 accelerated iterations reach Baraff & Witkin's stretch (5-6%), 10
    /// plain ones 12%, and 0.97 overshoots (BENCHMARKS.md, "Projective dynamics").
    pub projective_chebyshev: f64,
    /// Window `m` of the Anderson acceleration of the local/global iterations (Peng et al.
    /// 2018, [`crate::sim::anderson`], with their energy safeguard); 0 turns it off. It replaces
    /// Chebyshev on the steps whose global steps are direct solves.
    pub projective_anderson: usize,
    /// Cap of the CG iterations of one projective global step under contact terms (ours; CG
    /// stops earlier at a relative residual of 1e-6). Default 10. With 1 a global step is one
    /// factor-preconditioned steepest-descent step (one factor solve: CG skips the solve that
    /// would only test convergence at the cap), which still never increases the step energy;
    /// in the Cha & Ko loop that is 10 instead of ~35 solves per step (BENCHMARKS.md, branch
    /// loop9). Plain simulation keeps 10 (cap 1 let the 20k-vertex shirt's energy grow
    /// ~1000x); the Cha & Ko loop sets its own
    /// ([`crate::methods::cha_ko::ResolveParams::projective_cg_cap`], 1 by default;
    /// BENCHMARKS.md, branch loop10).
    pub projective_cg_iterations: usize,
    /// Thickness cap of cloth-cloth pairs that are neighbours on the cloth, as a fraction of the
    /// shortest edge at their nodes ([`crate::sim::near`], ours): keeps a thickness larger than
    /// a fine mesh's edges from pushing the cloth apart in its own plane. Default 0.25; 0 turns
    /// it off (the Cha & Ko loop turns it off: its m-CCH thicknesses are the paper's, already
    /// tied to the edge length).
    pub near_pair_fraction: f64,
}

/// How the implicit step before collision handling is solved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// One Newton step of implicit Euler with the Baraff & Witkin 1998 forces, solved by
    /// filtered PCG (the default).
    #[default]
    BaraffWitkin,
    /// Projective dynamics (Bouaziz et al. 2014): implicit Euler as a minimisation by a fixed
    /// number of local/global iterations with a pre-factored constant matrix
    /// ([`crate::sim::projective`]).
    Projective,
}

/// Which preconditioner CG uses (see [`crate::sim::pcg`] and [`crate::sim::amg`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CgPreconditioner {
    /// Smoothed-aggregation multigrid V-cycle, its hierarchy reused across steps while it
    /// works ([`crate::sim::amg`]). Fewer iterations, but on the benchmarks of BENCHMARKS.md
    /// ("Simulation") more time per step than [`CgPreconditioner::TwoLevel`], so not the
    /// default.
    Multigrid,
    /// Block-Jacobi plus an additive 64-aggregate coarse grid; the default.
    TwoLevel,
}

impl Default for SimParams {
    fn default() -> Self {
        SimParams {
            dt: 0.02,
            density: 0.15,
            stretch_stiffness: 1000.0,
            shear_stiffness: 100.0,
            bend_stiffness: 5e-6,
            damping_mass: 0.02,
            damping_stiffness: 1e-3,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            friction: 0.2,
            cg_tolerance: 1e-3,
            cg_max_iterations: 200,
            collisions: true,
            proximity: true,
            ccd_ratio: 0.5,
            max_impulse_iterations: 12,
            max_zone_iterations: 100,
            contacts_within_reach: false,
            preconditioner: CgPreconditioner::TwoLevel,
            zone_motion: ZoneMotion::default(),
            integrator: Integrator::BaraffWitkin,
            projective_iterations: 10,
            projective_chebyshev: 0.9,
            projective_anderson: 0,
            projective_cg_iterations: PD_CG_CAP,
            near_pair_fraction: NEAR_PAIR_FRACTION,
        }
    }
}

impl SimParams {
    /// Checks ranges; an [`Error::Parameter`] names the first bad one.
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(Error::Parameter(format!(
                    "{name} must be positive and finite, got {v}"
                )))
            }
        };
        let nonneg = |name: &str, v: f64| {
            if v >= 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(Error::Parameter(format!(
                    "{name} must be >= 0 and finite, got {v}"
                )))
            }
        };
        pos("dt", self.dt)?;
        pos("density", self.density)?;
        nonneg("stretch stiffness", self.stretch_stiffness)?;
        nonneg("shear stiffness", self.shear_stiffness)?;
        nonneg("bend stiffness", self.bend_stiffness)?;
        nonneg("mass damping", self.damping_mass)?;
        nonneg("stiffness damping", self.damping_stiffness)?;
        nonneg("friction", self.friction)?;
        pos("cg tolerance", self.cg_tolerance)?;
        nonneg("near pair fraction", self.near_pair_fraction)?;
        if !(self.ccd_ratio > 0.0 && self.ccd_ratio <= 1.0) {
            return Err(Error::Parameter(format!(
                "ccd ratio must be in (0, 1], got {}",
                self.ccd_ratio
            )));
        }
        if !(0.0..1.0).contains(&self.projective_chebyshev) {
            return Err(Error::Parameter(format!(
                "projective chebyshev rho must be in [0, 1), got {}",
                self.projective_chebyshev
            )));
        }
        if self.projective_cg_iterations == 0 {
            return Err(Error::Parameter(
                "projective CG iterations must be at least 1".into(),
            ));
        }
        if self.projective_iterations == 0 {
            return Err(Error::Parameter(
                "projective iterations must be at least 1".into(),
            ));
        }
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return Err(Error::Parameter("gravity must be finite".into()));
        }
        Ok(())
    }
}

/// The dynamic state of a [`Simulator`] at one moment ([`Simulator::snapshot`],
/// [`Simulator::restore`]).
#[derive(Clone, Debug)]
pub struct SimSnapshot {
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    pin_targets: Vec<Option<Vec3>>,
    obstacles: Obstacles,
    broad: BroadPhase,
    contacts: ContactFinder,
    resting: Vec<Pair>,
    contact_impulse: Vec<f64>,
    amg_built: Option<(usize, u64)>,
    amg_last: usize,
    dv_prev: Vec<Vec3>,
    steps: u64,
    time: f64,
}

impl SimSnapshot {
    /// The cloth's positions at the snapshot.
    pub fn positions(&self) -> &[Vec3] {
        &self.x
    }
}

/// A cloth simulator over one garment (world vertices = nodes) plus obstacles.
pub struct Simulator {
    params: SimParams,
    /// Shared with the step's [`NearCapped`] policy.
    triangles: Arc<Vec<[u32; 3]>>,
    uv_triangles: Vec<[u32; 3]>,
    /// Shared with the step's [`NearCapped`] policy.
    topology: Arc<Topology>,
    uv: Vec<Vec2>,
    rest: RestShape,
    /// What a uv edit touches ([`Simulator::set_rest_uv`] updates only that).
    rest_index: RestIndex,
    mass: Vec<f64>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    pinned: Vec<bool>,
    /// Where a pinned vertex moves during the next step (`None`: it stays).
    pin_targets: Vec<Option<Vec3>>,
    obstacles: Obstacles,
    pattern: BsrPattern,
    /// Slot of block `(tri[i], tri[j])` for each triangle, row-major `3 * i + j`.
    tri_slots: Vec<[u32; 9]>,
    /// Per triangle, the vertex across each edge (see `collision::Scene::hinge`).
    hinge: Vec<[u32; 3]>,
    /// Bending Hessian per slot (a multiple of the identity), rebuilt with the rest shape.
    bend_base: Vec<f64>,
    broad: BroadPhase,
    contacts: ContactFinder,
    /// Cloth-cloth pairs in resting contact at the end of the previous step.
    resting: Vec<Pair>,
    /// Normal impulse of each vertex's obstacle contact in the previous step (friction bound).
    contact_impulse: Vec<f64>,
    /// Sum of the masses.
    total_mass: f64,
    /// Coarse level of the two-level CG preconditioner (`None` for small meshes).
    aggregation: Option<Aggregation>,
    /// Multigrid hierarchy (built on first use, for meshes with an aggregation).
    amg: Amg,
    /// Iterations of the first solve after the last build, and the step of that build.
    amg_built: Option<(usize, u64)>,
    /// Iterations of the last multigrid solve.
    amg_last: usize,
    /// Velocity change of the previous step: the initial guess of CG.
    dv_prev: Vec<Vec3>,
    /// Projective-dynamics state (built on the first projective step).
    pd: Option<PdState>,
    /// The last step's velocities as the implicit solve left them, before the collision
    /// handling (empty before the first step or with collisions off).
    solved_v: Vec<Vec3>,
    /// Per vertex, a factor (>= 1) on its mass in the collision handling only (empty: 1 for
    /// all); see [`Simulator::set_collision_mass_factors`].
    collision_mass: Vec<f64>,
    steps: u64,
    time: f64,
}

impl Simulator {
    /// A simulator for `garment` at its current positions, at rest, nothing pinned.
    pub fn new(garment: &Garment, params: SimParams) -> Result<Simulator> {
        params.validate()?;
        let mesh = &garment.mesh;
        let uv = garment.uv();
        let topology = garment.topology.clone();
        let rest =
            RestShape::new(&mesh.triangles, &uv.triangles, &uv.coords, &topology).map_err(|e| {
                match e {
                    Error::Input { place, message } => {
                        Error::input(format!("{} {}", mesh.place(), place), message)
                    }
                    other => other,
                }
            })?;
        let n = mesh.positions.len();
        let mut mass = vec![0.0; n];
        for (t, r) in mesh.triangles.iter().zip(&rest.triangles) {
            for &v in t {
                mass[v as usize] += params.density * r.area / 3.0;
            }
        }
        if let Some(v) = mass.iter().position(|&m| m <= 0.0) {
            return Err(Error::input(
                mesh.place(),
                format!("vertex {} belongs to no triangle", v + 1),
            ));
        }
        let mut pairs = Vec::new();
        for t in &mesh.triangles {
            pairs.extend([(t[0], t[1]), (t[1], t[2]), (t[0], t[2])]);
        }
        for s in &rest.bend {
            let w = s.vertices;
            pairs.push((w[2], w[3]));
        }
        let pattern = BsrPattern::from_pairs(n, pairs);
        let tri_slots = mesh
            .triangles
            .iter()
            .map(|t| {
                let mut s = [0u32; 9];
                for i in 0..3 {
                    for j in 0..3 {
                        s[3 * i + j] = pattern.slot(t[i], t[j]).expect("in pattern") as u32;
                    }
                }
                s
            })
            .collect();
        let hinge = (0..mesh.triangles.len() as u32)
            .map(|t| {
                let e = topology.triangle_edges[t as usize];
                e.map(|e| {
                    let o = topology.other_triangle(e, t);
                    if o == crate::mesh::topology::NONE {
                        return u32::MAX;
                    }
                    let ev = topology.edges[e as usize];
                    *mesh.triangles[o as usize]
                        .iter()
                        .find(|&&v| v != ev[0] && v != ev[1])
                        .expect("a triangle has a third vertex")
                })
            })
            .collect();
        let total_mass = mass.iter().sum();
        let rest_index = RestIndex::new(
            &mesh.triangles,
            &uv.triangles,
            uv.coords.len(),
            &topology,
            &rest,
        );
        let mut sim = Simulator {
            rest_index,
            hinge,
            params,
            triangles: Arc::new(mesh.triangles.clone()),
            uv_triangles: uv.triangles.clone(),
            topology: Arc::new(topology),
            uv: uv.coords.clone(),
            rest,
            mass,
            x: mesh.positions.clone(),
            v: vec![Vec3::zeros(); n],
            pinned: vec![false; n],
            pin_targets: vec![None; n],
            obstacles: Obstacles::default(),
            bend_base: Vec::new(),
            pattern,
            tri_slots,
            broad: BroadPhase::default(),
            contacts: ContactFinder::default(),
            total_mass,
            aggregation: (n >= COARSE_MIN_VERTICES).then(|| {
                Aggregation::from_graph(
                    n,
                    |i| garment.topology.vertex_neighbors.row(i),
                    n.div_ceil(COARSE_AGGREGATES).max(COARSE_MIN_SIZE),
                )
            }),
            amg: Amg::new(AmgSettings::default()),
            amg_built: None,
            amg_last: 0,
            resting: Vec::new(),
            contact_impulse: vec![0.0; n],
            dv_prev: vec![Vec3::zeros(); n],
            pd: None,
            solved_v: Vec::new(),
            collision_mass: Vec::new(),
            steps: 0,
            time: 0.0,
        };
        sim.rebuild_bend_base();
        Ok(sim)
    }

    fn rebuild_bend_base(&mut self) {
        let mut base = vec![0.0; self.pattern.nnz()];
        let kb = self.params.bend_stiffness;
        for s in &self.rest.bend {
            bend_terms(&self.pattern, s, kb, |k, v| base[k] += v);
        }
        self.bend_base = base;
    }

    /// Replaces the rest shape by new uv coordinates (one per uv index of the garment, metres),
    /// meant to be called every step (Cha & Ko 2022, Sec. 5.1). Only the rest data of the
    /// triangles whose uv changed and of the bending stencils at their edges is recomputed, and
    /// only the matrix entries they touch, each summed as a full rebuild sums it (the same
    /// bits); when more than an eighth of the triangles change, everything is rebuilt in
    /// O(triangles + edges). Masses stay those of the original rest shape. With projective
    /// dynamics the next step factors the new matrix (if it differs from the factored one).
    /// On error (a degenerate uv triangle, wrong count) nothing changes.
    pub fn set_rest_uv(&mut self, uv: &[Vec2]) -> Result<()> {
        if uv.len() != self.uv.len() {
            return Err(Error::Parameter(format!(
                "set_rest_uv: {} uv coordinates given, the garment has {}",
                uv.len(),
                self.uv.len()
            )));
        }
        let edit = self.rest_index.edit(
            &self.triangles,
            &self.uv_triangles,
            &self.topology,
            &self.uv,
            uv,
            self.triangles.len() / 8,
        )?;
        match edit {
            Some(edit) => {
                self.uv.copy_from_slice(uv);
                self.rest.apply(&edit);
                self.update_bend_base(&edit);
                if let Some(pd) = &mut self.pd {
                    pd.system.update_rest(&edit);
                    pd.rest_changed = true;
                }
            }
            None => {
                let rest = RestShape::new(&self.triangles, &self.uv_triangles, uv, &self.topology)?;
                self.uv.copy_from_slice(uv);
                self.rest = rest;
                self.rebuild_bend_base();
                if let Some(pd) = &mut self.pd {
                    pd.system.set_rest(&self.rest);
                    pd.rest_changed = true;
                }
            }
        }
        Ok(())
    }

    /// [`Simulator::rebuild_bend_base`] for the slots of the stencils `edit` changed (already
    /// applied to `self.rest`), summed over the same stencils in the same order.
    fn update_bend_base(&mut self, edit: &RestEdit) {
        let kb = self.params.bend_stiffness;
        let mut slots = Vec::new();
        for (_, b) in &edit.stencils {
            bend_terms(&self.pattern, b, kb, |k, _| slots.push(k));
        }
        slots.sort_unstable();
        slots.dedup();
        let (pattern, bend) = (&self.pattern, &self.rest.bend);
        resum_slots(&mut self.bend_base, &slots, |add| {
            for &s in &edit.near_stencils {
                bend_terms(pattern, &bend[s as usize], kb, &mut *add);
            }
        });
    }

    /// The current rest uv.
    pub fn rest_uv(&self) -> &[Vec2] {
        &self.uv
    }

    /// Parameters.
    pub fn params(&self) -> &SimParams {
        &self.params
    }

    /// Changes parameters that do not affect the system structure (everything except the
    /// density, which fixed the masses). The bending stiffness takes effect immediately.
    pub fn set_params(&mut self, params: SimParams) -> Result<()> {
        params.validate()?;
        let rebuild = params.bend_stiffness != self.params.bend_stiffness;
        self.params = params;
        if rebuild {
            self.rebuild_bend_base();
        }
        Ok(())
    }

    /// The state a step changes (positions, velocities, resting contacts, obstacle motion,
    /// CG warm start, step count and time), to undo a step with [`Simulator::restore`]. Caches
    /// that only speed a step up (the projective factor, the multigrid hierarchy) are not part of
    /// it; the rest shape is not either (set it again if it changed).
    pub fn snapshot(&self) -> SimSnapshot {
        SimSnapshot {
            x: self.x.clone(),
            v: self.v.clone(),
            pin_targets: self.pin_targets.clone(),
            obstacles: self.obstacles.clone(),
            broad: self.broad.clone(),
            contacts: self.contacts.clone(),
            resting: self.resting.clone(),
            contact_impulse: self.contact_impulse.clone(),
            amg_built: self.amg_built,
            amg_last: self.amg_last,
            dv_prev: self.dv_prev.clone(),
            steps: self.steps,
            time: self.time,
        }
    }

    /// Returns to a state taken with [`Simulator::snapshot`] of this simulator: the steps since
    /// are undone (a trial step, e.g. Cha & Ko's loop predicting the colouring after a step).
    pub fn restore(&mut self, s: &SimSnapshot) -> Result<()> {
        if s.x.len() != self.x.len() {
            return Err(Error::Parameter(format!(
                "snapshot of {} vertices restored into a simulator of {}",
                s.x.len(),
                self.x.len()
            )));
        }
        self.x.clone_from(&s.x);
        self.v.clone_from(&s.v);
        self.pin_targets.clone_from(&s.pin_targets);
        self.obstacles.clone_from(&s.obstacles);
        self.broad.clone_from(&s.broad);
        self.contacts.clone_from(&s.contacts);
        self.resting.clone_from(&s.resting);
        self.contact_impulse.clone_from(&s.contact_impulse);
        self.amg_built = s.amg_built;
        self.amg_last = s.amg_last;
        self.dv_prev.clone_from(&s.dv_prev);
        self.steps = s.steps;
        self.time = s.time;
        Ok(())
    }

    /// World positions of the cloth (one per world vertex).
    pub fn positions(&self) -> &[Vec3] {
        &self.x
    }

    /// Velocities of the cloth.
    pub fn velocities(&self) -> &[Vec3] {
        &self.v
    }

    /// The last step's velocities as its implicit solve left them, before the collision
    /// handling changed them (empty before the first step, or when collisions are off): the
    /// solve's end positions are `x_before + h v`. For diagnostics (how much of a step's motion
    /// the collision handling removed, e.g. in the Cha & Ko loop).
    pub fn solved_velocities(&self) -> &[Vec3] {
        &self.solved_v
    }

    /// Lumped vertex masses (kg).
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// Moves the cloth (e.g. a user edit); the caller is responsible for not creating
    /// intersections.
    pub fn set_positions(&mut self, x: &[Vec3]) -> Result<()> {
        check_vectors("positions", x, self.x.len())?;
        self.x.copy_from_slice(x);
        Ok(())
    }

    /// Sets the velocities.
    pub fn set_velocities(&mut self, v: &[Vec3]) -> Result<()> {
        check_vectors("velocities", v, self.v.len())?;
        self.v.copy_from_slice(v);
        Ok(())
    }

    /// Pins (`true`) or frees vertex `v`: a pinned vertex keeps its position.
    pub fn set_pinned(&mut self, v: u32, pinned: bool) -> Result<()> {
        let n = self.x.len();
        let p = self
            .pinned
            .get_mut(v as usize)
            .ok_or_else(|| Error::Parameter(format!("pin: vertex {} out of range (0..{n})", v)))?;
        *p = pinned;
        if pinned {
            self.v[v as usize] = Vec3::zeros();
        } else {
            self.pin_targets[v as usize] = None;
        }
        Ok(())
    }

    /// Makes vertices heavier in the collision handling only (ours, for Cha & Ko's loop): vertex
    /// `i`'s inverse mass in the proximity impulses, CCD impulses and impact zones of the next
    /// steps is divided by `factors[i]`, so a pair's impulse moves its other side more and a
    /// zone's rigid motion follows the heavy vertices; the implicit solve keeps the true
    /// masses. Every factor must be finite and at least 1; an empty vector restores the true
    /// masses. The guarantee is unchanged: impulses and zones stop the same pairs whatever the
    /// masses.
    pub fn set_collision_mass_factors(&mut self, factors: Vec<f64>) -> Result<()> {
        if !factors.is_empty() && factors.len() != self.x.len() {
            return Err(Error::Parameter(format!(
                "{} collision mass factors for {} vertices",
                factors.len(),
                self.x.len()
            )));
        }
        if let Some(f) = factors.iter().find(|f| !(f.is_finite() && **f >= 1.0)) {
            return Err(Error::Parameter(format!(
                "collision mass factor {f} (must be finite and >= 1)"
            )));
        }
        self.collision_mass = if factors.iter().all(|&f| f == 1.0) {
            Vec::new()
        } else {
            factors
        };
        Ok(())
    }

    /// Moves pinned vertex `v` linearly to `target` during the next step (animated pins, user
    /// manipulation). The target is kept until reached (a stalled step does not reach it).
    pub fn set_pin_target(&mut self, v: u32, target: Vec3) -> Result<()> {
        if !self.pinned.get(v as usize).copied().unwrap_or(false) {
            return Err(Error::Parameter(format!(
                "pin target: vertex {v} is not pinned"
            )));
        }
        check_vectors("pin target", &[target], 1)?;
        self.pin_targets[v as usize] = Some(target);
        Ok(())
    }

    /// Which vertices are pinned.
    pub fn pinned(&self) -> &[bool] {
        &self.pinned
    }

    /// Adds an obstacle at its given positions; returns its index.
    pub fn add_obstacle(&mut self, obstacle: Obstacle) -> Result<usize> {
        self.obstacles.add(obstacle)
    }

    /// Sets where obstacle `id` will be at the end of the next step (it moves linearly).
    pub fn set_obstacle_next_positions(&mut self, id: usize, positions: &[Vec3]) -> Result<()> {
        self.obstacles.set_next_positions(id, positions)
    }

    /// The obstacles (start positions = where they are now).
    pub fn obstacles(&self) -> &Obstacles {
        &self.obstacles
    }

    /// Triangles of the cloth.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Edges of the cloth, the numbering the contact policy uses.
    pub fn topology(&self) -> &Topology {
        &self.topology
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Number of nonzero 3x3 blocks of the system matrix.
    pub fn matrix_blocks(&self) -> usize {
        self.pattern.nnz()
    }

    /// Stretch and shear energy of each triangle at positions `x` (one per cloth vertex)
    /// against the current rest shape, in triangle order: Baraff & Witkin's conditions
    /// ([`super::forces::stretch`]), whose sum is [`super::report::Energy::stretch`]. Cha & Ko's
    /// loop uses it to find which uv edit a diverging step came from
    /// ([`crate::methods::cha_ko::divergence`]), so non-finite positions are accepted: the
    /// triangles at them get non-finite energies (a blown-up step must be measurable, not an
    /// error). A wrong number of positions is an error.
    pub fn stretch_energies(&self, x: &[Vec3]) -> Result<Vec<f64>> {
        check_len("positions", x, self.x.len())?;
        Ok(self.triangle_energies(x))
    }

    /// [`Simulator::stretch_energies`] of positions known to fit.
    fn triangle_energies(&self, x: &[Vec3]) -> Vec<f64> {
        let p = &self.params;
        self.triangles
            .par_iter()
            .zip(&self.rest.triangles)
            .with_min_len(256)
            .map(|(t, r)| {
                stretch_energy(
                    r,
                    t.map(|k| &x[k as usize]),
                    p.stretch_stiffness,
                    p.shear_stiffness,
                )
            })
            .collect()
    }

    /// Kinetic energy of the current velocities.
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.mass)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum()
    }

    /// Largest relative edge stretch `|e| / |e_rest| - 1` over all triangle edges (rest lengths
    /// from each triangle's uv).
    pub fn max_stretch(&self) -> f64 {
        self.stretch_of(&self.x)
    }

    fn stretch_of(&self, x: &[Vec3]) -> f64 {
        self.triangles
            .par_iter()
            .zip(&self.uv_triangles)
            .map(|(t, u)| {
                (0..3)
                    .map(|k| {
                        let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
                        let (ua, ub) = (u[k] as usize, u[(k + 1) % 3] as usize);
                        (x[a] - x[b]).norm() / (self.uv[ua] - self.uv[ub]).norm() - 1.0
                    })
                    .fold(f64::MIN, f64::max)
            })
            .reduce(|| f64::MIN, f64::max)
    }

    /// Assembles `K = -df/dx` into `k`, returns the forces and the elastic energies.
    fn assemble(&self, k: &mut BsrMatrix) -> (Vec<Vec3>, f64, f64) {
        let p = &self.params;
        let terms: Vec<StretchTerms> = self
            .triangles
            .par_iter()
            .zip(&self.rest.triangles)
            .with_min_len(256)
            .map(|(t, r)| {
                stretch_terms(
                    r,
                    [
                        &self.x[t[0] as usize],
                        &self.x[t[1] as usize],
                        &self.x[t[2] as usize],
                    ],
                    p.stretch_stiffness,
                    p.shear_stiffness,
                )
            })
            .collect();
        k.values
            .par_iter_mut()
            .zip(&self.bend_base)
            .with_min_len(1024)
            .for_each(|(b, &s)| *b = Matrix3::identity() * s);
        let mut f: Vec<Vec3> = self.mass.iter().map(|&m| p.gravity * m).collect();
        let mut e_stretch = 0.0;
        for ((t, slots), term) in self.triangles.iter().zip(&self.tri_slots).zip(&terms) {
            e_stretch += term.energy;
            for c in 0..3 {
                f[t[c] as usize] -= term.gradient[c];
            }
            for (b, &(i, j)) in BLOCKS.iter().enumerate() {
                k.values[slots[3 * i + j] as usize] += term.hessian[b];
                if i != j {
                    k.values[slots[3 * j + i] as usize] += term.hessian[b].transpose();
                }
            }
        }
        let kb = p.bend_stiffness;
        let mut e_bend = 0.0;
        for s in &self.rest.bend {
            let q = s.curvature(&self.x);
            e_bend += 0.5 * kb * q.norm_squared();
            for i in 0..4 {
                f[s.vertices[i] as usize] -= q * (kb * s.weights[i]);
            }
        }
        (f, e_stretch, e_bend)
    }

    /// Coulomb friction at an obstacle contact as tangential damping (Baraff & Witkin 1998,
    /// Sec. 5.3): the tangent-plane projector `I - n n^T` and the damping coefficient `g`,
    /// bounded by the previous step's normal impulse over the predicted sliding speed and by
    /// [`FRICTION_CAP`] times the vertex mass; `None` without friction or without a previous
    /// impulse. Both integrators add it to their systems (in velocities or in positions).
    fn friction_damping(&self, c: &ObstacleContact, v_pred: &Vec3) -> Option<(Matrix3<f64>, f64)> {
        let i = c.vertex as usize;
        let lam = self.contact_impulse[i];
        if !(lam > 0.0 && c.friction > 0.0) {
            return None;
        }
        let rel = v_pred - c.obstacle_velocity;
        let vt = rel - c.normal * c.normal.dot(&rel);
        let g = (c.friction * lam / vt.norm().max(1e-9)).min(FRICTION_CAP * self.mass[i]);
        Some((Matrix3::identity() - c.normal * c.normal.transpose(), g))
    }

    /// The implicit solve of Baraff & Witkin (module docs): new velocities.
    fn solve_baraff_witkin(&mut self, policy: &dyn ContactPolicy, inv_mass: &[f64]) -> Solved {
        let p = self.params.clone();
        let h = p.dt;
        let n = self.x.len();
        let mut k = BsrMatrix::zeros(&self.pattern);
        let (f, e_stretch, e_bend) = self.assemble(&mut k);
        let energy = Energy {
            kinetic: self.kinetic_energy(),
            stretch: e_stretch,
            bend: e_bend,
            gravity: -(0..n)
                .map(|i| self.mass[i] * p.gravity.dot(&self.x[i]))
                .sum::<f64>(),
        };
        let mut kv = vec![Vec3::zeros(); n];
        k.mul(&self.pattern, &self.v, &mut kv);
        let c_k = h * p.damping_stiffness + h * h;
        let c_m = 1.0 + h * p.damping_mass;
        let b: Vec<Vec3> = (0..n)
            .map(|i| {
                (f[i] - self.v[i] * (p.damping_mass * self.mass[i])) * h
                    - kv[i] * (h * (p.damping_stiffness + h))
            })
            .collect();
        k.values
            .par_iter_mut()
            .with_min_len(1024)
            .for_each(|blk| *blk *= c_k);
        for i in 0..n {
            k.values[self.pattern.diag[i] as usize] += Matrix3::identity() * (c_m * self.mass[i]);
        }
        let filter: Vec<Filter> = self
            .pinned
            .iter()
            .map(|&pin| if pin { Filter::Fixed } else { Filter::Free })
            .collect();
        // Pinned vertices: prescribed velocity (towards their target, else zero).
        let z: Vec<Vec3> = (0..n)
            .map(|i| {
                if self.pinned[i] {
                    let vp = self.pin_targets[i].map_or(Vec3::zeros(), |t| (t - self.x[i]) / h);
                    vp - self.v[i]
                } else {
                    Vec3::zeros()
                }
            })
            .collect();
        let v_pred: Vec<Vec3> = (0..n).map(|i| self.v[i] + self.dv_prev[i]).collect();
        let (mut contacts, mut springs) = self.gather_contacts(policy, &v_pred, inv_mass);
        let t1 = Instant::now();
        let mut dv = self.dv_prev.clone();
        let settings = PcgSettings {
            tolerance: p.cg_tolerance,
            absolute: p.cg_tolerance * p.gravity.norm() * h * self.total_mass.sqrt(),
            max_iterations: p.cg_max_iterations,
        };
        let mut cg = PcgResult::default();
        let mut impulse = vec![0.0; contacts.len()];
        let mut coarse = None;
        for round in 0..=MAX_RELEASE_ROUNDS {
            // The system of this round: base matrix plus contact springs and friction.
            let mut a = k.clone();
            let mut rhs = b.clone();
            for s in &springs {
                let nn = s.normal * s.normal.transpose();
                a.add_pair(&self.pattern, s.nodes, s.weights, nn * s.stiffness_h2);
                let push = s.stiffness_h2 / h * (s.thickness - s.end_gap(&self.v, h));
                for kk in 0..4 {
                    rhs[s.nodes[kk] as usize] += s.normal * (push * s.weights[kk]);
                }
            }
            a.finish_pairs(&self.pattern);
            let mut fl = filter.clone();
            let mut zz = z.clone();
            for c in &contacts {
                let i = c.vertex as usize;
                fl[i] = Filter::Normal(c.normal);
                zz[i] = c.normal * (c.normal_velocity - c.normal.dot(&self.v[i]));
                // Coulomb friction as tangential damping bounded by the normal impulse of the
                // previous step (Baraff & Witkin 1998, Sec. 5.3 treat friction after the solve;
                // inside it, it decelerates the cloth around the contact consistently).
                if let Some((t, g)) = self.friction_damping(c, &v_pred[i]) {
                    a.values[self.pattern.diag[i] as usize] += t * g;
                    rhs[i] -= t * ((self.v[i] - c.obstacle_velocity) * g);
                }
            }
            let multigrid =
                p.preconditioner == CgPreconditioner::Multigrid && self.aggregation.is_some();
            if round == 0 && multigrid {
                let stale = match self.amg_built {
                    None => true,
                    Some((first, at)) => {
                        self.amg_last > AMG_REBUILD_FACTOR * first + AMG_REBUILD_SLACK
                            || self.steps >= at + AMG_MAX_AGE
                    }
                };
                if stale || !self.amg.is_built_for(&self.pattern) {
                    self.amg_built = None;
                    if !self.amg.build(&self.pattern, &a, &fl, &self.x) {
                        self.amg = Amg::new(AmgSettings::default());
                    }
                }
            } else if round == 0 {
                coarse = self
                    .aggregation
                    .as_ref()
                    .and_then(|g| CoarseLevel::new(g, &self.pattern, &a, &fl));
            }
            let mg = if multigrid {
                self.amg.preconditioner(&self.pattern, &a, &fl)
            } else {
                None
            };
            let preconditioner = match &mg {
                Some(m) => pcg::Preconditioner::Amg(m),
                None => pcg::Preconditioner::BlockJacobi(coarse.as_ref()),
            };
            let mut r = pcg::solve(
                &self.pattern,
                &a,
                &rhs,
                &fl,
                &zz,
                &mut dv,
                settings,
                preconditioner,
            );
            if mg.is_some() {
                if round == 0 {
                    self.amg_last = r.iterations;
                    if self.amg_built.is_none() {
                        self.amg_built = Some((r.iterations, self.steps));
                    }
                }
                if !r.relative_residual.is_finite() {
                    // The reused hierarchy stopped being positive definite for this matrix:
                    // finish with block-Jacobi and rebuild next step.
                    let more = pcg::solve(
                        &self.pattern,
                        &a,
                        &rhs,
                        &fl,
                        &zz,
                        &mut dv,
                        settings,
                        pcg::Preconditioner::BlockJacobi(None),
                    );
                    r.iterations += more.iterations;
                    r.relative_residual = more.relative_residual;
                    r.converged = more.converged;
                    self.amg_built = None;
                }
            }
            // Momentum and angular momentum: CG leaves its error mostly in the rigid motions
            // (see `pcg::correct_rigid_motions`).
            pcg::correct_rigid_motions(&self.pattern, &a, &rhs, &fl, &self.x, &mut dv);
            cg.iterations += r.iterations;
            cg.relative_residual = r.relative_residual;
            cg.converged = r.converged;
            if contacts.is_empty() && springs.is_empty() {
                break;
            }
            // Release contacts that pull (Baraff & Witkin's rule) and solve again.
            let mut res = vec![Vec3::zeros(); n];
            a.mul(&self.pattern, &dv, &mut res);
            let last = round == MAX_RELEASE_ROUNDS;
            let mut keep_c = Vec::with_capacity(contacts.len());
            impulse.clear();
            for c in &contacts {
                let i = c.vertex as usize;
                let lam = c.normal.dot(&(res[i] - rhs[i]));
                if lam >= 0.0 || last {
                    keep_c.push(*c);
                    impulse.push(lam.max(0.0));
                }
            }
            let v_new: Vec<Vec3> = (0..n).map(|i| self.v[i] + dv[i]).collect();
            let keep_s: Vec<contact::ClothContact> = springs
                .iter()
                .filter(|s| last || s.end_gap(&v_new, h) <= s.thickness)
                .copied()
                .collect();
            let released = keep_c.len() < contacts.len() || keep_s.len() < springs.len();
            contacts = keep_c;
            springs = keep_s;
            if !released {
                break;
            }
        }
        let (obstacle_contacts, contact_springs) = (contacts.len(), springs.len());
        self.contact_impulse.iter_mut().for_each(|l| *l = 0.0);
        for (c, &lam) in contacts.iter().zip(&impulse) {
            self.contact_impulse[c.vertex as usize] = lam;
        }
        let mut v: Vec<Vec3> = (0..n).map(|i| self.v[i] + dv[i]).collect();
        if v.iter().any(|x| !x.iter().all(|c| c.is_finite())) {
            // A failed solve must not poison the state: keep the old velocities.
            v.copy_from_slice(&self.v);
            dv.iter_mut().for_each(|d| *d = Vec3::zeros());
        }
        if v.iter().any(|x| !x.iter().all(|c| c.is_finite())) {
            // A failed solve must not poison the state: keep the old velocities.
            v.copy_from_slice(&self.v);
            dv.iter_mut().for_each(|d| *d = Vec3::zeros());
        }
        self.dv_prev = dv;
        Solved {
            v,
            cg,
            energy,
            obstacle_contacts,
            contact_springs,
            projective: None,
            assembled: t1,
        }
    }

    /// The implicit solve by projective dynamics ([`crate::sim::projective`]): the contacts of
    /// [`Simulator::gather_contacts`] enter the global system (obstacle contacts as filter
    /// constraints on the normal position, cloth-cloth springs and friction as quadratic terms);
    /// new velocities `(x_pd - x_n) / h`.
    fn solve_projective(&mut self, policy: &dyn ContactPolicy, inv_mass: &[f64]) -> Solved {
        let p = self.params.clone();
        let h = p.dt;
        let n = self.x.len();
        let elastic = Elastic {
            stretch: p.stretch_stiffness,
            shear: p.shear_stiffness,
            bend: p.bend_stiffness,
        };
        let mut pd = self.pd.take().unwrap_or_else(|| PdState {
            system: Projective::new(n, &self.triangles, &self.rest, elastic),
            factor: None,
            key: None,
            rest_changed: false,
            factor_exact: false,
            factored_values: Vec::new(),
        });
        if pd.system.elastic() != elastic {
            pd.system.set_elastic(elastic);
        }
        let c_m = 1.0 + h * p.damping_mass;
        let inertia: Vec<f64> = self.mass.iter().map(|m| c_m * m / (h * h)).collect();
        // Stiffness damping is left out: the constant elastic matrix does not vanish on
        // rotations, so `beta/(2h) |x - x_n|_L^2` damps rigid swinging (a hanging sheet crept
        // down for seconds). Mass damping and implicit Euler dissipate (docs/projective.md).
        let damping = 0.0;
        let values = pd.system.system_values(&inertia, damping);
        let key = FactorKey {
            h,
            c_m,
            damping,
            elastic,
            pinned: self.pinned.clone(),
        };
        // A rest edit that changed the matrix: factor the new one. (Keeping the old factor as
        // CG's preconditioner until a global step needed more than three CG iterations cost
        // more: in the Cha & Ko loop, whose rest shape changes every step, 42.5 CG iterations
        // per step against 25 with the current factor; BENCHMARKS.md, branch loop6.)
        if pd.rest_changed {
            // A rest edit that leaves the matrix as it was (e.g. a uniform scaling of a
            // triangle: area x |Dm^-1|^2 is invariant) keeps the factor exact.
            pd.factor_exact = pd.factored_values.len() == values.len()
                && pd
                    .factored_values
                    .iter()
                    .zip(&values)
                    .all(|(a, b)| (a - b).abs() <= 1e-12 * a.abs().max(b.abs()));
            pd.rest_changed = false;
        }
        let degraded = !pd.factor_exact;
        let mut result = ProjectiveResult::default();
        let refactor = pd.factor.is_none() || pd.key.as_ref() != Some(&key) || degraded;
        // The factorisation is sequential: it runs beside the rest of the set-up (energies,
        // inertial target, contact search), which does not depend on it. The same arithmetic
        // as one after the other.
        let pinned = &key.pinned;
        let factor_pd = |pd: &mut PdState| -> Option<f64> {
            if !refactor {
                return None;
            }
            let tf = Instant::now();
            let pattern = pd.system.pattern();
            let mut f = match pd.factor.take() {
                Some(f) => Some(f),
                None => ScalarCholesky::new(pattern),
            };
            if let Some(fac) = &mut f {
                if !fac.factor(pattern, &values, pinned) {
                    f = None;
                }
            }
            pd.factor = f;
            pd.factor_exact = pd.factor.is_some();
            pd.factored_values.clone_from(&values);
            Some(tf.elapsed().as_secs_f64() * 1e3)
        };
        let (factored, (energy, y, v_pred, (contacts, springs))) = rayon::join(
            || factor_pd(&mut pd),
            || self.prepare_projective(policy, inv_mass, c_m),
        );
        let mut contacts = contacts;
        let mut springs = springs;
        if let Some(ms) = factored {
            pd.key = Some(key);
            result.refactored = true;
            result.factor_ms = ms;
        }
        let t1 = Instant::now();
        let settings = PcgSettings {
            // Relative to the residual at the current iterate, without the Baraff & Witkin
            // path's absolute floor: with it (and with 1e-3) the factor-preconditioned CG
            // stopped after one iteration and the 20k-vertex t-shirt, under ~36k contact springs,
            // blew up at step 14 (stretch energy 1e7 J); solved to 1e-6 (2-4 iterations per
            // global step) it stayed bounded (BENCHMARKS.md, branch sim7).
            tolerance: p.cg_tolerance.min(PD_CG_TOLERANCE),
            absolute: 0.0,
            // Inexact global steps keep the energy decreasing (CG from the current iterate
            // only lowers the quadratic), and the next iteration solves again.
            max_iterations: p.cg_max_iterations.min(p.projective_cg_iterations),
        };
        // Start at the inertial target `y` (Bouaziz et al. 2014, Alg. 1). Starting at the
        // extrapolated prediction `x + h (v + dv_prev)` instead injected energy whenever the
        // iterations had not converged (a hanging sheet swung higher and higher).
        let mut x = y.clone();
        let mut cg = PcgResult {
            converged: true,
            ..Default::default()
        };
        // Constraint forces `A x - rhs` of the last global step that computed them.
        let mut force = vec![Vec3::zeros(); n];
        let mut releases = 0;
        let h2 = h * h;
        let mut work = projective::Workspace::default();
        // Chebyshev's iterate before the last (`prev`) and the last (`cur`); reused buffers.
        let (mut prev, mut cur) = (Vec::new(), Vec::new());
        // The iterations run inside the pool (one hand-over to a worker thread per step instead
        // of one per parallel loop: under load a woken worker is often descheduled).
        // The last release round's low-rank correction (its columns are reused).
        let mut prev_lr: Option<low_rank::LowRank> = None;
        rayon::scope(|_| {
            'rounds: loop {
                // The global system of this round: base matrix plus contact springs and friction,
                // assembled only for CG global steps (a direct solve uses the factored matrix).
                // The contact terms of this round's global system: cloth-cloth springs
                // `k (w (x) n)(w (x) n)^T` and friction `k (I - n n^T)` at obstacle contacts, whose
                // normal motion is prescribed by the filter.
                let mut extra = vec![Vec3::zeros(); n];
                let mut filter: Vec<Filter> = self
                    .pinned
                    .iter()
                    .map(|&q| if q { Filter::Fixed } else { Filter::Free })
                    .collect();
                let mut targets: Vec<Vec3> = (0..n)
                    .map(|i| match (self.pinned[i], self.pin_targets[i]) {
                        (true, Some(t)) => t,
                        _ => self.x[i],
                    })
                    .collect();
                let mut spring_k = Vec::with_capacity(springs.len());
                for s in &springs {
                    let k = s.stiffness_h2 / h2;
                    let c = s.thickness - s.distance
                        + s.normal.dot(&(0..4).fold(Vec3::zeros(), |acc, j| {
                            acc + self.x[s.nodes[j] as usize] * s.weights[j]
                        }));
                    for j in 0..4 {
                        extra[s.nodes[j] as usize] += s.normal * (k * c * s.weights[j]);
                    }
                    spring_k.push(k);
                }
                let mut friction = Vec::new();
                for c in &contacts {
                    let i = c.vertex as usize;
                    filter[i] = Filter::Normal(c.normal);
                    targets[i] = self.x[i] + c.normal * (h * c.normal_velocity);
                    // Coulomb friction as tangential damping bounded by the previous step's normal
                    // impulse, as in the Baraff & Witkin solve (there in velocities, here in
                    // positions: the same quadratic divided by h^2).
                    let k = self
                        .friction_damping(c, &v_pred[i])
                        .map_or(0.0, |(_, g)| g / h2);
                    if k > 0.0 {
                        let t = Matrix3::identity() - c.normal * c.normal.transpose();
                        extra[i] += t * (k * (self.x[i] + c.obstacle_velocity * h));
                    }
                    friction.push(k);
                }
                let terms = !(springs.is_empty() && contacts.is_empty());
                // A few contact terms with the exact factor: a low-rank correction of the factor
                // keeps the global step direct; more (or a stale factor, or a correction that is
                // not positive definite): CG on the assembled matrix.
                let lr = (pd.factor_exact
                    && terms
                    && springs.len() + contacts.len() <= low_rank::MAX_GROUPS)
                    .then(|| {
                        let f = pd.factor.as_ref()?;
                        let (groups, lr_terms) =
                            low_rank_terms(&springs, &spring_k, &contacts, &friction);
                        // A release round keeps most groups: their columns are taken over.
                        low_rank::LowRank::reusing(
                            f,
                            &self.pinned,
                            groups,
                            lr_terms,
                            true,
                            prev_lr.as_ref(),
                        )
                    })
                    .flatten();
                // Otherwise the terms next to the factored matrix, for CG's products.
                let ct = (terms && lr.is_none()).then(|| projective::ContactTerms {
                    springs: springs
                        .iter()
                        .zip(&spring_k)
                        .map(|(s, &k)| projective::SpringTerm {
                            nodes: s.nodes,
                            weights: s.weights,
                            normal: s.normal,
                            k,
                        })
                        .collect(),
                    friction: contacts
                        .iter()
                        .zip(&friction)
                        .filter(|(_, &k)| k > 0.0)
                        .map(|(c, &k)| (c.vertex, c.normal, k))
                        .collect(),
                });
                for i in 0..n {
                    x[i] = match filter[i] {
                        Filter::Free => x[i],
                        Filter::Fixed => targets[i],
                        Filter::Normal(nn) => x[i] + nn * nn.dot(&(targets[i] - x[i])),
                    };
                }
                let problem = StepProblem {
                    x0: &self.x,
                    y: &y,
                    inertia: &inertia,
                    damping,
                    contacts: ct.as_ref(),
                    low_rank: lr.as_ref(),
                    values: &values,
                    exact: pd.factor_exact
                        && springs.is_empty()
                        && filter.iter().all(|f| !matches!(f, Filter::Normal(_))),
                    rhs_extra: &extra,
                    filter: &filter,
                    targets: &targets,
                };
                let rhs_const = pd.system.constant_rhs(&problem);
                let Some(factor) = pd.factor.as_ref() else {
                    break 'rounds;
                };
                // Chebyshev semi-iterative acceleration (Wang 2015): the iterate before the last
                // and the current weight; restarted with every new system.
                let mut have_prev = false;
                let mut omega = 1.0;
                // Anderson acceleration (Peng et al. 2018) instead, when asked: its history, the
                // energy of the last accepted iterate, whether `x` is an extrapolation.
                let mut anderson = Anderson::new(p.projective_anderson);
                let mut accepted = f64::INFINITY;
                let mut extrapolated = false;
                // The step energy at `x` given its membrane energy (the local step's): inertia,
                // membrane, bending and the contact penalties with their linear part (up to a
                // constant, the same within a round).
                let energy_at = |x: &[Vec3], membrane: f64| -> f64 {
                    let mut e = membrane + pd.system.bend_energy(x);
                    for i in 0..n {
                        e += 0.5 * inertia[i] * (x[i] - y[i]).norm_squared() - extra[i].dot(&x[i]);
                    }
                    e + lr.as_ref().map_or(0.0, |lr| lr.penalty_energy(x))
                };
                loop {
                    let tl = Instant::now();
                    // Only for direct global steps (the exact factor, no contact terms or a few as
                    // a low-rank correction): there the global step is one fixed linear map, as the
                    // acceleration assumes (with CG global steps under many contact terms it
                    // diverged on the 20k-vertex t-shirt: stretch 543 vs 15 without).
                    let direct = problem.exact || problem.low_rank.is_some();
                    let accelerate = p.projective_anderson > 0 && direct;
                    let chebyshev = !accelerate && p.projective_chebyshev > 0.0 && direct;
                    // Chebyshev's copy of the iterate and its extrapolation inside the global
                    // step's substitution (same bits) when that is the plain direct step.
                    let fused = chebyshev && Projective::fuses_extrapolation(&problem);
                    if chebyshev && !fused {
                        cur.clone_from(&x);
                    }
                    if accelerate {
                        // Peng et al.'s safeguard: an extrapolation that raised the energy is
                        // replaced by the plain iterate, and the history restarts.
                        let membrane = pd.system.project_energy(&x, &mut work.targets);
                        let mut e = energy_at(&x, membrane);
                        if extrapolated && e > accepted {
                            x.copy_from_slice(anderson.plain());
                            anderson.reset();
                            e = energy_at(&x, pd.system.project_energy(&x, &mut work.targets));
                            result.rejected += 1;
                        }
                        accepted = e;
                        anderson.begin(&x);
                    } else {
                        pd.system.project(&x, &mut work.targets);
                    }
                    let tg = Instant::now();
                    let last = result.iterations + 1 >= p.projective_iterations;
                    let check = !last
                        && releases < MAX_RELEASE_ROUNDS
                        && (!contacts.is_empty() || !springs.is_empty());
                    // x = omega (x_hat - x_prev) + x_prev; the constrained components agree in
                    // both, so the constraints stay satisfied.
                    if chebyshev && have_prev {
                        let rho2 = p.projective_chebyshev * p.projective_chebyshev;
                        omega = if omega == 1.0 {
                            2.0 / (2.0 - rho2)
                        } else {
                            4.0 / (4.0 - rho2 * omega)
                        };
                    }
                    let r = if fused {
                        cur.resize(n, Vec3::zeros());
                        pd.system.global_step_extrapolated(
                            &problem,
                            &rhs_const,
                            factor,
                            &mut x,
                            &work,
                            have_prev.then_some((omega, &prev[..])),
                            &mut cur,
                        )
                    } else {
                        let r = pd.system.global_step(
                            &problem,
                            &rhs_const,
                            factor,
                            settings,
                            &mut x,
                            // The constraint forces are read only at obstacle contacts (release
                            // rule, friction bound of the next step): without any, no residual
                            // product (the springs' release looks at the velocities).
                            ((check || last) && !contacts.is_empty()).then_some(&mut force),
                            &mut work,
                        );
                        if chebyshev && have_prev {
                            for i in 0..n {
                                x[i] = (x[i] - prev[i]) * omega + prev[i];
                            }
                        }
                        r
                    };
                    if accelerate {
                        let last = result.iterations + 1 >= p.projective_iterations;
                        extrapolated = anderson.finish(&mut x, !last);
                    }
                    std::mem::swap(&mut prev, &mut cur);
                    have_prev = chebyshev;
                    result.local_ms += (tg - tl).as_secs_f64() * 1e3;
                    result.global_ms += tg.elapsed().as_secs_f64() * 1e3;
                    result.iterations += 1;
                    cg.iterations += r.iterations;
                    cg.relative_residual = r.relative_residual;
                    cg.converged &= r.converged;
                    if result.iterations >= p.projective_iterations {
                        break 'rounds;
                    }
                    if check {
                        // Release obstacle contacts that pull and springs that end apart
                        // (Baraff & Witkin's rule), then continue with the new system.
                        let keep_c: Vec<ObstacleContact> = contacts
                            .iter()
                            .filter(|c| c.normal.dot(&force[c.vertex as usize]) >= 0.0)
                            .copied()
                            .collect();
                        let v_new: Vec<Vec3> = (0..n).map(|i| (x[i] - self.x[i]) / h).collect();
                        let keep_s: Vec<contact::ClothContact> = springs
                            .iter()
                            .filter(|s| s.end_gap(&v_new, h) <= s.thickness)
                            .copied()
                            .collect();
                        let released =
                            keep_c.len() < contacts.len() || keep_s.len() < springs.len();
                        contacts = keep_c;
                        springs = keep_s;
                        if released {
                            releases += 1;
                            prev_lr = lr;
                            continue 'rounds;
                        }
                    }
                }
            }
        });
        result.cg_iterations = cg.iterations;
        result.relative_residual = cg.relative_residual;
        // Normal impulses of the kept contacts (friction bound of the next step): the
        // constraint force of the last global step times h.
        self.contact_impulse.iter_mut().for_each(|l| *l = 0.0);
        for c in &contacts {
            let i = c.vertex as usize;
            self.contact_impulse[i] = (h * c.normal.dot(&force[i])).max(0.0);
        }
        let (obstacle_contacts, contact_springs) = (contacts.len(), springs.len());
        let mut v: Vec<Vec3> = (0..n).map(|i| (x[i] - self.x[i]) / h).collect();
        if pd.factor.is_none() || v.iter().any(|x| !x.iter().all(|c| c.is_finite())) {
            // A failed factorisation or solve must not poison the state: keep the velocities.
            v.copy_from_slice(&self.v);
        }
        self.dv_prev = (0..n).map(|i| v[i] - self.v[i]).collect();
        self.pd = Some(pd);
        Solved {
            v,
            cg,
            energy,
            obstacle_contacts,
            contact_springs,
            projective: Some(result),
            assembled: t1,
        }
    }

    /// The set-up of a projective step besides the factorisation ([`Simulator::solve_projective`]
    /// runs the two side by side): the energies at the start, the inertial target `y`, the
    /// predicted velocities and the contacts.
    #[allow(clippy::type_complexity)]
    fn prepare_projective(
        &mut self,
        policy: &dyn ContactPolicy,
        inv_mass: &[f64],
        c_m: f64,
    ) -> (
        Energy,
        Vec<Vec3>,
        Vec<Vec3>,
        (Vec<ObstacleContact>, Vec<contact::ClothContact>),
    ) {
        let p = &self.params;
        let h = p.dt;
        let n = self.x.len();
        let energy = Energy {
            kinetic: self.kinetic_energy(),
            // Summed in triangle order: rayon's parallel sum depends on the thread count.
            stretch: self.triangle_energies(&self.x).iter().sum(),
            bend: self
                .rest
                .bend
                .par_iter()
                .with_min_len(256)
                .map(|s| s.energy(&self.x, p.bend_stiffness))
                // In stencil order, as the stretch energy.
                .collect::<Vec<f64>>()
                .iter()
                .sum(),
            gravity: -(0..n)
                .map(|i| self.mass[i] * p.gravity.dot(&self.x[i]))
                .sum::<f64>(),
        };
        let y: Vec<Vec3> = (0..n)
            .map(|i| self.x[i] + (self.v[i] * h + p.gravity * (h * h)) / c_m)
            .collect();
        let v_pred: Vec<Vec3> = (0..n).map(|i| self.v[i] + self.dv_prev[i]).collect();
        let contacts = self.gather_contacts(policy, &v_pred, inv_mass);
        (energy, y, v_pred, contacts)
    }

    /// The contacts of the implicit solve (see `contact`): obstacle contacts as constraints,
    /// resting cloth-cloth pairs as implicit one-sided springs; predicted velocities `v_pred`.
    fn gather_contacts(
        &mut self,
        policy: &dyn ContactPolicy,
        v_pred: &[Vec3],
        inv_mass: &[f64],
    ) -> (Vec<ObstacleContact>, Vec<contact::ClothContact>) {
        let p = &self.params;
        let h = p.dt;
        if p.collisions {
            let free: Vec<bool> = self.pinned.iter().map(|&q| !q).collect();
            let contacts = self
                .contacts
                .find(&self.x, v_pred, &free, &self.obstacles, h, policy);
            // In parallel, in the resting pairs' order (rayon's collect keeps it).
            let pairs: Vec<([u32; 4], bool, f64)> = self
                .resting
                .par_iter()
                .with_min_len(256)
                .filter_map(|pr| {
                    let (nodes, vt, c) = match pr.kind {
                        PairKind::VertexTriangle => {
                            let t = self.triangles[pr.b as usize];
                            (
                                [pr.a, t[0], t[1], t[2]],
                                true,
                                policy.vertex_triangle(pr.a, pr.b),
                            )
                        }
                        PairKind::EdgeEdge => {
                            let (e, f) = (
                                self.topology.edges[pr.a as usize],
                                self.topology.edges[pr.b as usize],
                            );
                            (
                                [e[0], e[1], f[0], f[1]],
                                false,
                                policy.edge_edge(pr.a, pr.b),
                            )
                        }
                        _ => return None,
                    };
                    match c {
                        Contact::Thickness(e) if e > 0.0 && e.is_finite() => Some((nodes, vt, e)),
                        _ => None,
                    }
                })
                .collect();
            let springs = contact::cloth_contacts(&self.x, v_pred, inv_mass, &pairs, h);
            (contacts, springs)
        } else {
            (Vec::new(), Vec::new())
        }
    }

    /// Advances one step of `params.dt` with the contact `policy` (cloth-cloth pairs; obstacle
    /// pairs default to the obstacle's thickness).
    ///
    /// The step runs inside rayon's pool ([`crate::pool::in_pool`]): one hand-over to a worker
    /// thread per step instead of one per parallel loop; the same results.
    pub fn step(&mut self, policy: &dyn ContactPolicy) -> StepReport {
        crate::pool::in_pool(|| self.step_in_pool(policy))
    }

    /// [`Simulator::step`]'s body.
    fn step_in_pool(&mut self, policy: &dyn ContactPolicy) -> StepReport {
        let t0 = Instant::now();
        let p = self.params.clone();
        // Neighbour pairs' thickness capped at the start positions ([`super::near`]).
        let (triangles, topology) = (self.triangles.clone(), self.topology.clone());
        let capped = (p.near_pair_fraction > 0.0)
            .then(|| NearCapped::new(policy, &topology, &triangles, &self.x, p.near_pair_fraction))
            .filter(NearCapped::binds);
        self.step_with(p, capped.as_ref().map_or(policy, |c| c as _), t0)
    }

    /// [`Simulator::step_in_pool`] with the policy in force (`p`: a copy of the parameters).
    fn step_with(&mut self, p: SimParams, policy: &dyn ContactPolicy, t0: Instant) -> StepReport {
        let h = p.dt;
        let n = self.x.len();
        let inv_mass: Vec<f64> = (0..n)
            .map(|i| {
                if self.pinned[i] {
                    0.0
                } else {
                    1.0 / self.mass[i]
                }
            })
            .collect();
        let solved = match p.integrator {
            Integrator::BaraffWitkin => self.solve_baraff_witkin(policy, &inv_mass),
            Integrator::Projective => self.solve_projective(policy, &inv_mass),
        };
        let Solved {
            mut v,
            cg,
            energy,
            obstacle_contacts,
            contact_springs,
            projective,
            assembled: t1,
        } = solved;
        let t2 = Instant::now();
        // The solve's velocities, to report how far the collision handling moved the cloth.
        let solved = p.collisions.then(|| v.clone());
        let mut collisions = if p.collisions {
            let heavy: Vec<f64>;
            let inv_mass: &[f64] = if self.collision_mass.is_empty() {
                &inv_mass
            } else {
                heavy = inv_mass
                    .iter()
                    .zip(&self.collision_mass)
                    .map(|(m, f)| m / f)
                    .collect();
                &heavy
            };
            let scene = Scene {
                x0: &self.x,
                h,
                triangles: &self.triangles,
                edges: &self.topology.edges,
                hinge: &self.hinge,
                obstacles: &self.obstacles,
                inv_mass,
                friction: p.friction,
                ccd_ratio: p.ccd_ratio,
            };
            collision::handle(
                &scene,
                &mut v,
                policy,
                CollisionSettings {
                    max_impulse_iterations: p.max_impulse_iterations,
                    max_zone_iterations: p.max_zone_iterations,
                    proximity: p.proximity,
                    contacts_within_reach: p.contacts_within_reach,
                    rebuild: self.steps % collision::broad::REBUILD_EVERY == 0,
                    zone_motion: p.zone_motion,
                },
                &mut self.broad,
            )
        } else {
            Default::default()
        };
        self.resting = std::mem::take(&mut collisions.resting);
        let collision_shift = solved.as_ref().map_or_else(CollisionShift::default, |s| {
            CollisionShift::between(s, &v, h)
        });
        self.solved_v = solved.unwrap_or_default();
        let t3 = Instant::now();
        for i in 0..n {
            self.x[i] += v[i] * h;
            if let Some(t) = self.pin_targets[i] {
                if (self.x[i] - t).norm() <= 1e-12 * (1.0 + t.norm()) {
                    self.x[i] = t;
                    self.pin_targets[i] = None;
                }
            }
        }
        self.v = v;
        self.obstacles.advance();
        let report = StepReport {
            step: self.steps,
            time: self.time + h,
            cg,
            projective,
            collisions,
            collision_shift,
            energy,
            max_stretch: self.max_stretch(),
            obstacle_contacts,
            contact_springs,
            timing: StepTiming {
                assemble: (t1 - t0).as_secs_f64() * 1e3,
                solve: (t2 - t1).as_secs_f64() * 1e3,
                collisions: (t3 - t2).as_secs_f64() * 1e3,
                total: t0.elapsed().as_secs_f64() * 1e3,
            },
        };
        self.steps += 1;
        self.time += h;
        report
    }
}

/// What the implicit solve of a step hands to the collision handling and the report.
struct Solved {
    v: Vec<Vec3>,
    cg: PcgResult,
    energy: Energy,
    obstacle_contacts: usize,
    contact_springs: usize,
    projective: Option<ProjectiveResult>,
    /// When the system was assembled (end of the "assemble" phase).
    assembled: Instant,
}

/// The contact terms of a projective global step as rank-one terms ([`low_rank`]): per spring
/// one group (its four weighted nodes) with the normal penalty, per obstacle contact one group
/// (its vertex) with the normal constraint and, with friction `k > 0`, two tangential penalties.
fn low_rank_terms(
    springs: &[contact::ClothContact],
    spring_k: &[f64],
    contacts: &[ObstacleContact],
    friction: &[f64],
) -> (Vec<low_rank::Group>, Vec<low_rank::Term>) {
    let mut groups = Vec::with_capacity(springs.len() + contacts.len());
    let mut terms = Vec::new();
    for (s, &k) in springs.iter().zip(spring_k) {
        terms.push(low_rank::Term {
            group: groups.len() as u32,
            dir: s.normal,
            inv_k: 1.0 / k,
        });
        groups.push(low_rank::Group {
            nodes: s.nodes,
            weights: s.weights,
        });
    }
    for (c, &k) in contacts.iter().zip(friction) {
        let group = groups.len() as u32;
        groups.push(low_rank::Group {
            nodes: [c.vertex; 4],
            weights: [1.0, 0.0, 0.0, 0.0],
        });
        terms.push(low_rank::Term {
            group,
            dir: c.normal,
            inv_k: 0.0,
        });
        if k > 0.0 {
            // k (I - n n^T) = k (t1 t1^T + t2 t2^T).
            let axis = if c.normal.x.abs() < 0.9 {
                Vec3::x()
            } else {
                Vec3::y()
            };
            let t1 = c.normal.cross(&axis).normalize();
            let t2 = c.normal.cross(&t1);
            for dir in [t1, t2] {
                terms.push(low_rank::Term {
                    group,
                    dir,
                    inv_k: 1.0 / k,
                });
            }
        }
    }
    (groups, terms)
}

/// Default [`SimParams::near_pair_fraction`]: a neighbour pair's thickness is at most a
/// quarter of the shortest edge at its nodes (a flat cloth's neighbour pairs are at least
/// about half an edge apart; BENCHMARKS.md, "Every target after session 26").
pub const NEAR_PAIR_FRACTION: f64 = 0.25;

/// Default cap of the CG iterations of one projective global step
/// ([`SimParams::projective_cg_iterations`]).
const PD_CG_CAP: usize = 10;
/// Relative CG tolerance of a projective global step with contact terms.
const PD_CG_TOLERANCE: f64 = 1e-6;

/// What the factor of the projective global matrix was computed for.
#[derive(Clone, Debug, PartialEq)]
struct FactorKey {
    h: f64,
    c_m: f64,
    damping: f64,
    elastic: Elastic,
    pinned: Vec<bool>,
}

/// Projective-dynamics state kept across steps.
struct PdState {
    system: Projective,
    factor: Option<ScalarCholesky>,
    key: Option<FactorKey>,
    /// Whether the rest shape changed since the last step.
    rest_changed: bool,
    /// Whether the factor is of the current base matrix.
    factor_exact: bool,
    /// The scalar matrix the factor is of.
    factored_values: Vec<f64>,
}

/// `x` has one entry per cloth vertex (`n`).
fn check_len(what: &str, x: &[Vec3], n: usize) -> Result<()> {
    if x.len() != n {
        return Err(Error::Parameter(format!(
            "{what}: {} given, the cloth has {n} vertices",
            x.len()
        )));
    }
    Ok(())
}

fn check_vectors(what: &str, x: &[Vec3], n: usize) -> Result<()> {
    check_len(what, x, n)?;
    if let Some(i) = x.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(Error::Parameter(format!("{what}: entry {i} is not finite")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::UniformThickness;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Debug strings tell every two different floats apart (also `0.0` and `-0.0`).
    fn bits<T: std::fmt::Debug>(x: &T) -> String {
        format!("{x:?}")
    }

    /// `set_rest_uv`'s partial update (a few uv coordinates moved) against the rest shape,
    /// bending base and projective matrix computed from scratch for the same uv: equal bit for
    /// bit, over several edits in a row, one of them large enough for the full rebuild; a
    /// degenerate edit is an error and changes nothing.
    #[test]
    fn partial_rest_updates_equal_a_rebuild_from_scratch() {
        let g = Garment::new(crate::scenes::exploded::exploded(3, 14).meshes[0].clone()).unwrap();
        let params = SimParams {
            integrator: Integrator::Projective,
            gravity: Vec3::zeros(),
            ..SimParams::default()
        };
        let mut sim = Simulator::new(&g, params.clone()).unwrap();
        sim.step(&UniformThickness(1e-3));
        let n = sim.x.len();
        let inertia: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
        let mut uv = g.uv().coords.clone();
        let nt = g.mesh.triangles.len();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for round in 0..8 {
            // Round 5 moves every coordinate (a full rebuild), the others one to four.
            let moves = if round == 5 { uv.len() } else { 1 + round % 4 };
            for _ in 0..moves {
                let k = rng.random_range(0..uv.len());
                uv[k] += Vec2::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5) * 1e-3;
            }
            let edit = sim
                .rest_index
                .edit(
                    &sim.triangles,
                    &sim.uv_triangles,
                    &sim.topology,
                    &sim.uv,
                    &uv,
                    nt / 8,
                )
                .unwrap();
            assert_eq!(
                edit.is_none(),
                round == 5,
                "partial unless everything moved"
            );
            if let Some(e) = &edit {
                assert!(!e.triangles.is_empty() && e.triangles.len() <= 4 * 8);
            }
            sim.set_rest_uv(&uv).unwrap();
            let full =
                RestShape::new(&sim.triangles, &sim.uv_triangles, &uv, &sim.topology).unwrap();
            assert_eq!(bits(&sim.rest.triangles), bits(&full.triangles));
            assert_eq!(bits(&sim.rest.bend), bits(&full.bend));
            let mut fresh = Simulator::new(&g, params.clone()).unwrap();
            fresh.rest = full.clone();
            fresh.rebuild_bend_base();
            assert_eq!(bits(&sim.bend_base), bits(&fresh.bend_base));
            let elastic = sim.pd.as_ref().unwrap().system.elastic();
            let pd = Projective::new(n, &sim.triangles, &full, elastic);
            assert_eq!(
                bits(&sim.pd.as_ref().unwrap().system.system_values(&inertia, 0.0)),
                bits(&pd.system_values(&inertia, 0.0))
            );
            sim.step(&UniformThickness(1e-3));
        }
        // A degenerate uv triangle: an error, nothing changed.
        let before = (
            bits(&sim.uv),
            bits(&sim.rest.triangles),
            bits(&sim.bend_base),
        );
        let mut bad = uv.clone();
        let t = sim.uv_triangles[0];
        bad[t[1] as usize] = bad[t[0] as usize];
        assert!(sim.set_rest_uv(&bad).is_err());
        assert_eq!(
            before,
            (
                bits(&sim.uv),
                bits(&sim.rest.triangles),
                bits(&sim.bend_base)
            )
        );
    }
}
