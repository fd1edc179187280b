//! Cha & Ko 2022, *Tanglement Resolution in Clothing Simulation With Explicit Convergence*:
//! the uv-space mesh update and the m-CCH contact policy, as a library a simulator calls from its
//! own loop (Fig. 1b):
//!
//! ```text
//! let mut ck = ChaKo::new(&garment, Params::default())?;
//! let (am, _) = AnalysisMesh::single(&garment.mesh)?;     // or with a body as obstacle after it
//! loop {
//!     let a = analyze(&am, &positions)?;                    // intersection analysis + colouring (Sec. 3)
//!     let report = ck.update_uv(&am, &a, &positions)?;      // Alg. 2 (Sec. 5.1, 6, 8)
//!     sim.set_rest_uv(ck.current_uv());                     // the rest shape changed
//!     sim.step(&ck.contact_policy(&am, &a));                // m-CCH (Sec. 5.2, 5.3)
//! }
//! ```
//!
//! Modules, one concept each: [`params`] (gamma, dt, epsilons), [`state`] (original and current
//! uv, operations in progress, exact revoke), [`fan`] (fans and their triangles), [`tit`] (the
//! exact triangle inversion test), [`operations`] (pull, shrink, target choice), [`schedule`]
//! (Algorithm 2), [`seams`] (coordinated pulls across panels, our design of the missing
//! Appendix A/B), [`fallback`] (when no fan passes the test, Sec. 6.1, our design of the missing
//! Appendix C), [`policy`] (m-CCH), [`regionless`] (a fallback colouring for tanglements
//! without a usable region, ours), [`report`] (per-step reports and the Table 1 analogue),
//! [`resolve`] (the whole loop of Fig. 1b with the simulator), [`trial`] (the trial step: a
//! step rolled back and retried when a green vertex turned red, ours), [`divergence`] (a
//! diverging simulator step undone and the uv edits it came from given up, ours).

pub mod adaptive;
pub mod divergence;
pub mod fallback;
pub mod fan;
pub mod operations;
pub mod params;
pub mod policy;
pub mod regionless;
pub mod report;
pub mod resolve;
pub mod schedule;
pub mod seams;
pub mod sectors;
pub mod slit;
pub mod state;
pub mod subjects;
pub mod tit;
pub mod trial;

pub use adaptive::{AdaptiveIntegrator, IntegratorSchedule, IntegratorSwitch};
pub use divergence::{DivergenceGuard, DivergenceReport};
pub use fallback::Fallback;
pub use params::{Params, PullOrder};
pub use policy::{MchPolicy, MixedEdges, PairColour};
pub use report::{EndReason, FinesseRecord, FinesseStats, Stall, StallReason, UvUpdateReport};
pub use resolve::{LoopStep, Outcome, ResolveParams, ResolveSummary, Resolver};
pub use seams::SeamKind;
pub use state::{MovedCopy, Op, OpKind};
pub use trial::{TrialBlock, TrialReport, TrialScope, TrialTrigger};

use crate::analysis::{Analysis, AnalysisMesh, Coloring, ObjectKind};
use crate::error::{Error, Result};
use crate::geom::{Vec2, Vec3};
use crate::mesh::{Garment, UvLayer};
use operations::UvMesh;
use state::UvState;

/// The Cha & Ko uv-space updater of one garment: original and current uv, operations in
/// progress, the finesse log.
#[derive(Clone, Debug)]
pub struct ChaKo {
    params: Params,
    mesh: UvMesh,
    state: UvState,
    log: Vec<FinesseRecord>,
    step: u64,
    avg_edge: f64,
    eps_rg: f64,
    moved: Vec<u64>,
    tabu: std::collections::BTreeMap<schedule::TabuKey, u64>,
    /// Saturated operations under [`Params::hold_progress_steps`]: the shortest world distance
    /// from subject to target seen while held, and the step it was seen.
    closing: std::collections::BTreeMap<u32, (f64, u64)>,
    /// Loop vertices of the step's intersection paths (sorted): a red* triangle is not shrunk
    /// toward one (see [`schedule`]).
    loop_vertices: Vec<u32>,
    /// Edges that penetrate a triangle in the step's analysis (empty when unknown, as with a
    /// bare colouring): pulls start across them (see [`Params::pull_across_cut_edges`]).
    cut_edge: Vec<bool>,
    /// Red vertices of the previous step's colouring (for [`Params::persistent_green`]).
    prev_red: Option<Vec<bool>>,
    /// Shrinks toward a loop vertex started as a last resort (see [`schedule`]).
    last_resort_ops: std::collections::BTreeSet<u32>,
    /// Sectors of the last [`ChaKo::update_uv`]'s BLI paths with an interior loop vertex
    /// ([`sectors`]; empty when [`Params::bli_sectors`] is off; the other updates, which see
    /// no paths, keep them).
    sectors: Vec<sectors::Sector>,
}

impl ChaKo {
    /// An updater for `garment` with `params` (checked). The garment's uv is the original rest
    /// shape.
    pub fn new(garment: &Garment, params: Params) -> Result<ChaKo> {
        params.validate()?;
        let orig = garment.uv().coords.clone();
        let avg_edge = average_uv_edge_length(garment);
        let eps_rg = params.eps_rg.unwrap_or(params.eps_rg_factor * avg_edge);
        let n = garment.mesh.positions.len();
        Ok(ChaKo {
            mesh: UvMesh::new(garment.clone(), params.min_scale()),
            state: UvState::new(orig, n, params.gamma),
            log: Vec::new(),
            step: 0,
            avg_edge,
            eps_rg,
            moved: vec![0; n],
            tabu: Default::default(),
            closing: Default::default(),
            loop_vertices: Vec::new(),
            cut_edge: Vec::new(),
            prev_red: None,
            last_resort_ops: Default::default(),
            sectors: Vec::new(),
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The garment (with its original uv).
    pub fn garment(&self) -> &Garment {
        &self.mesh.garment
    }

    /// Number of updates run so far.
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// The original uv coordinates (parallel to the garment's uv layer).
    pub fn original_uv(&self) -> &[Vec2] {
        &self.state.orig
    }

    /// The current uv coordinates: the rest shape the simulator should use now.
    pub fn current_uv(&self) -> &[Vec2] {
        &self.state.cur
    }

    /// The current uv as a layer (coordinates and the garment's uv triangles), for writing.
    pub fn current_uv_layer(&self) -> UvLayer {
        UvLayer {
            coords: self.state.cur.clone(),
            triangles: self.mesh.garment.uv().triangles.clone(),
        }
    }

    /// Average original uv edge length (the paper's `avg(l)`).
    pub fn average_edge_length(&self) -> f64 {
        self.avg_edge
    }

    /// The red-green thickness `epsilon_RG` in use.
    pub fn eps_rg(&self) -> f64 {
        self.eps_rg
    }

    /// Operations in progress, by id.
    pub fn operations(&self) -> impl Iterator<Item = &Op> {
        self.state.ops.values()
    }

    /// The sectors of the last [`ChaKo::update_uv`] ([`sectors`]).
    pub fn sectors(&self) -> &[sectors::Sector] {
        &self.sectors
    }

    /// The BLI sector operations in progress that have not ended ([`sectors`]).
    pub fn running_sectors(&self) -> impl Iterator<Item = &Op> {
        self.state
            .ops
            .values()
            .filter(|op| op.kind == OpKind::Sector && self.log[op.id as usize].end.is_none())
    }

    /// Whether every uv coordinate is back at its original value (no operation in progress).
    pub fn is_restored(&self) -> bool {
        self.state.ops.is_empty()
    }

    /// Every operation so far.
    pub fn finesse_log(&self) -> &[FinesseRecord] {
        &self.log
    }

    /// The Table 1 analogue over the log.
    pub fn finesse_stats(&self) -> FinesseStats {
        FinesseStats::of(&self.log)
    }

    /// uv triangles that are inverted or degenerate now but were not in the input (always empty
    /// unless something is wrong; exact orientation tests).
    pub fn inverted_uv_triangles(&self) -> Vec<u32> {
        let uv = self.mesh.garment.uv();
        let o = |p: &Vec2| robust::Coord { x: p.x, y: p.y };
        (0..uv.triangles.len() as u32)
            .filter(|t| self.mesh.skip.binary_search(t).is_err())
            .filter(|&t| {
                let [a, b, c] = uv.triangles[t as usize].map(|i| &self.state.cur[i as usize]);
                self.mesh.sign[t as usize] * robust::orient2d(o(a), o(b), o(c)) <= 0.0
            })
            .collect()
    }

    /// One uv-space mesh update (Alg. 2) from the analysis of the garment's current positions.
    /// `am` must have the garment as its first object (vertex and triangle numbers equal to the
    /// garment's; obstacles may follow); `positions` are the analysed positions (used to name
    /// the location of stalls).
    pub fn update_uv(
        &mut self,
        am: &AnalysisMesh,
        analysis: &Analysis,
        positions: &[Vec3],
    ) -> Result<UvUpdateReport> {
        self.check_analysis_mesh(am)?;
        let lv: Vec<u32> = analysis
            .paths
            .iter()
            .flat_map(|p| p.loop_vertices().iter().copied())
            .collect();
        let cut: Vec<u32> = analysis.crossings.iter().map(|c| c.edge).collect();
        self.sectors = if self.params.bli_sectors {
            sectors::sectors(am, analysis, &self.mesh.garment)
        } else {
            Vec::new()
        };
        self.update_uv_with_paths(&analysis.coloring, &lv, Some(&cut), Some(positions))
    }

    /// One update from a colouring and the loop vertices of its intersection paths (Wicke et
    /// al.'s loop vertices; any order, duplicates allowed), as [`ChaKo::update_uv`] takes them
    /// from an analysis: pulls avoid loop-vertex targets and red* triangles are not shrunk
    /// toward one except as a last resort (see [`schedule`]).
    pub fn update_uv_with_loops(
        &mut self,
        coloring: &Coloring,
        loop_vertices: &[u32],
        positions: Option<&[Vec3]>,
    ) -> Result<UvUpdateReport> {
        self.update_uv_with_paths(coloring, loop_vertices, None, positions)
    }

    /// One update from a colouring, the loop vertices of its intersection paths and, when
    /// known, its *cut edges* (edges that penetrate a triangle, i.e. the edges of
    /// [`crate::analysis::Crossing`]s, any order, duplicates and edges beyond the garment's
    /// allowed), as [`ChaKo::update_uv`] takes them from an analysis: besides the loop-vertex
    /// rules, a pull then starts only across a cut edge or toward a loop vertex
    /// ([`Params::pull_across_cut_edges`]). `None` leaves that rule off.
    pub fn update_uv_with_paths(
        &mut self,
        coloring: &Coloring,
        loop_vertices: &[u32],
        cut_edges: Option<&[u32]>,
        positions: Option<&[Vec3]>,
    ) -> Result<UvUpdateReport> {
        let mut lv = loop_vertices.to_vec();
        lv.sort_unstable();
        lv.dedup();
        self.loop_vertices = lv;
        if let Some(cut) = cut_edges {
            let ne = self.mesh.garment.topology.num_edges();
            self.cut_edge.resize(ne, false); // empty between updates: all false, capacity kept
            for &e in cut {
                if (e as usize) < ne {
                    self.cut_edge[e as usize] = true;
                }
            }
        }
        let r = self.update_uv_with_coloring(coloring, positions);
        self.loop_vertices.clear();
        self.cut_edge.clear();
        r
    }

    /// One update from a colouring over the garment's own vertices, edges (its topology's order)
    /// and triangles (a colouring of a larger analysis mesh whose first object is the garment is
    /// accepted too).
    /// A bare colouring carries no intersection paths, so no loop vertex is known: red*
    /// triangles are shrunk toward any target (see [`schedule`]); [`ChaKo::update_uv`] knows them.
    pub fn update_uv_with_coloring(
        &mut self,
        coloring: &Coloring,
        positions: Option<&[Vec3]>,
    ) -> Result<UvUpdateReport> {
        let g = &self.mesh.garment;
        let (nv, ne, nt) = (
            g.mesh.positions.len(),
            g.topology.num_edges(),
            g.mesh.triangles.len(),
        );
        if coloring.red_vertex.len() < nv
            || coloring.red_edge.len() < ne
            || coloring.red_triangle.len() < nt
        {
            return Err(Error::Parameter(format!(
                "colouring covers {} vertices, {} edges, {} triangles; the garment has {nv}, {ne}, {nt}",
                coloring.red_vertex.len(),
                coloring.red_edge.len(),
                coloring.red_triangle.len()
            )));
        }
        if let Some(p) = positions {
            if p.len() < nv {
                return Err(Error::Parameter(format!(
                    "{} positions given for a garment of {nv} vertices",
                    p.len()
                )));
            }
        }
        let report = self.run_schedule(coloring, positions);
        self.step += 1;
        Ok(report)
    }

    /// Gives up the operations `ids` at once (ours, [`divergence`]): each ends as
    /// [`EndReason::Diverged`] (if it had not ended), is revoked to its original uv in full, and
    /// its subject-target pair (or red* triangle) is barred for `2 hold_steps` steps like an
    /// abandoned one. Ids of operations not in progress are skipped. Returns a stall per
    /// operation given up, located at its subject in `positions` when given.
    pub fn give_up(&mut self, ids: &[u32], positions: Option<&[Vec3]>) -> Vec<Stall> {
        let step = self.step.saturating_sub(1);
        let bar = step + 2 * u64::from(self.params.hold_steps.max(1));
        let mut stalls = Vec::new();
        for &id in ids {
            let Some(op) = self.state.ops.get(&id) else {
                continue;
            };
            let rec = &mut self.log[id as usize];
            if rec.end.is_none() {
                rec.end = Some(EndReason::Diverged);
                rec.end_step = Some(step);
            }
            self.tabu.insert(schedule::TabuKey::of(op), bar);
            let t = (op.triangle != crate::mesh::topology::NONE).then_some(op.triangle);
            stalls.push(schedule::stall(
                &self.mesh,
                StallReason::Diverged,
                Some(op.subjects[0]),
                t,
                positions,
            ));
            self.state.revoke(id, u32::MAX);
            self.log[id as usize].restored_step = Some(step);
        }
        stalls
    }

    /// The m-CCH contact policy for the step analysed in `analysis` (of `am`); it implements
    /// [`crate::sim::ContactPolicy`].
    pub fn contact_policy<'a>(
        &self,
        am: &'a AnalysisMesh,
        analysis: &'a Analysis,
    ) -> MchPolicy<'a> {
        let mut p = MchPolicy::new(am, &analysis.coloring, self.params.eps, self.eps_rg);
        p.mixed_edges = self.params.mixed_edges;
        p
    }

    /// Applies [`Params::persistent_green`] to a fresh analysis of `am`: vertices green at the
    /// previous call stay green, and edges, triangles, out-most red vertices and red* triangles
    /// are recoloured from the result (Sec. 3). Remembers the red vertices for the next call.
    pub fn persist_coloring(&mut self, am: &AnalysisMesh, analysis: &mut Analysis) {
        if !self.params.persistent_green {
            return;
        }
        if let Some(prev) = &self.prev_red {
            if prev.len() == analysis.coloring.red_vertex.len() {
                let red: Vec<bool> = analysis
                    .coloring
                    .red_vertex
                    .iter()
                    .zip(prev)
                    .map(|(&a, &b)| a && b)
                    .collect();
                if red != analysis.coloring.red_vertex {
                    analysis.coloring = crate::analysis::coloring::color(
                        am,
                        red,
                        &analysis.crossings,
                        &analysis.segments,
                    );
                }
            }
        }
        self.prev_red = Some(analysis.coloring.red_vertex.clone());
    }

    fn check_analysis_mesh(&self, am: &AnalysisMesh) -> Result<()> {
        let g = &self.mesh.garment;
        let ok = am.objects.first().is_some_and(|o| {
            o.kind == ObjectKind::Cloth
                && o.vertices == (0..g.mesh.positions.len() as u32)
                && o.triangles == (0..g.mesh.triangles.len() as u32)
        }) && am.triangles[..g.mesh.triangles.len()] == g.mesh.triangles[..]
            && am.topology.edges.get(..g.topology.num_edges()) == Some(&g.topology.edges[..]);
        if ok {
            Ok(())
        } else {
            Err(Error::Parameter(
                "the analysis mesh must have the garment as its first object".into(),
            ))
        }
    }
}

/// Average length of the distinct uv edges.
fn average_uv_edge_length(g: &Garment) -> f64 {
    let uv = g.uv();
    let mut edges: Vec<(u32, u32)> = uv
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let sum: f64 = edges
        .iter()
        .map(|&(a, b)| (uv.coords[a as usize] - uv.coords[b as usize]).norm())
        .sum();
    sum / edges.len().max(1) as f64
}
