//! What one simulation step did: solver effort, collision handling (iterations, impact zones,
//! administrative quits — never silent), energies and timings. Serialises to JSON.

use super::collision::CollisionReport;
use super::pcg::PcgResult;
use super::projective::ProjectiveResult;
use crate::geom::Vec3;

/// Energies of the state at the start of the step (joules).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Energy {
    /// Kinetic energy.
    pub kinetic: f64,
    /// Stretch and shear energy.
    pub stretch: f64,
    /// Bending energy.
    pub bend: f64,
    /// Gravitational potential energy, relative to the origin.
    pub gravity: f64,
}

/// Wall-clock milliseconds per phase of the step.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StepTiming {
    /// Forces, Jacobians and system assembly.
    pub assemble: f64,
    /// Conjugate gradients.
    pub solve: f64,
    /// Collision handling.
    pub collisions: f64,
    /// Everything.
    pub total: f64,
}

/// How far the collision handling moved the cloth from the implicit solve's end-of-step
/// positions: `h |v_after - v_solved|` per vertex (metres), its largest value and its mean over
/// all vertices. Zero when nothing was in contact. A diagnostic of how much of the solve's
/// motion the proximity impulses, CCD and impact zones undid: in the Cha & Ko loop with
/// projective dynamics it is several times that with Baraff & Witkin (docs/cha-ko.md, "Loop").
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CollisionShift {
    /// Largest shift of a vertex.
    pub max: f64,
    /// Mean shift over the vertices.
    pub mean: f64,
}

impl CollisionShift {
    /// The shift from the solve's velocities `solved` to the collision handling's `after`,
    /// over a step of `h` seconds (vertices in index order, so the sums do not depend on the
    /// thread count).
    pub fn between(solved: &[Vec3], after: &[Vec3], h: f64) -> Self {
        let (mut max, mut sum) = (0.0f64, 0.0);
        for (a, b) in solved.iter().zip(after) {
            let d = (b - a).norm() * h;
            max = max.max(d);
            sum += d;
        }
        CollisionShift {
            max,
            mean: if solved.is_empty() {
                0.0
            } else {
                sum / solved.len() as f64
            },
        }
    }
}

/// The report of one step.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct StepReport {
    /// Index of the step (0 for the first).
    pub step: u64,
    /// Simulated time at the end of the step (seconds).
    pub time: f64,
    /// The linear solve (for projective dynamics: CG iterations summed over the global steps).
    pub cg: PcgResult,
    /// The local/global iterations of projective dynamics (`None` with Baraff & Witkin).
    pub projective: Option<ProjectiveResult>,
    /// Cloth vertices held by an obstacle inside the solve (after releases).
    pub obstacle_contacts: usize,
    /// Cloth-cloth contact springs inside the solve (after releases).
    pub contact_springs: usize,
    /// The collision handling.
    pub collisions: CollisionReport,
    /// How far the collision handling moved the cloth from the solve's end positions. Not in
    /// the JSON (the step reports' JSON is what the decision hashes of BENCHMARKS.md compare).
    #[serde(skip)]
    pub collision_shift: CollisionShift,
    /// Energies at the start of the step.
    pub energy: Energy,
    /// Largest relative edge stretch at the end of the step (`|e| / |e_rest| - 1`).
    pub max_stretch: f64,
    /// Timings.
    pub timing: StepTiming,
}

impl StepReport {
    /// Whether the step ended with an administrative quit (collisions left unresolved).
    pub fn administrative_quit(&self) -> bool {
        self.collisions.administrative_quit
    }

    /// One-line JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("plain data serialises")
    }
}
