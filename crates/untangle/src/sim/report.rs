//! What one simulation step did: solver effort, collision handling (iterations, impact zones,
//! administrative quits — never silent), energies and timings. Serialises to JSON.

use super::collision::CollisionReport;
use super::pcg::PcgResult;
use super::projective::ProjectiveResult;

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
