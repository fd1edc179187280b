//! What the uv-space update did: one [`UvUpdateReport`] per step, a [`FinesseRecord`] per
//! operation (pull or shrink, from initiation to restoration), and the analogue of the paper's
//! Table 1 ([`FinesseStats`]: steps per finesse off-seam and on-seam).

use super::fallback::Fallback;
use super::seams::SeamKind;
use super::state::OpKind;

/// Why an operation stopped being advanced (Alg. 2: it is then revoked level by level).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EndReason {
    /// The finesse completed: the pulled vertex turned green, or the shrunk triangle's red edge
    /// turned green (Sec. 5.3).
    Finished,
    /// The colouring changed under it otherwise (the pulled vertex is no longer out-most red,
    /// its target turned red, the triangle is no longer red* with the same red edge).
    Superseded,
    /// It saturated and was held [`super::Params::hold_steps`] steps without finishing: given
    /// up so that another target (or the red* triangle across the red edge) can be tried.
    Abandoned,
    /// A simulator step diverged and most of its energy growth was in the triangles at its
    /// subjects: given up and restored to the original uv at once (ours,
    /// [`super::divergence`]).
    Diverged,
}

/// The life of one operation: the unit the paper's Table 1 counts.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FinesseRecord {
    /// Index in the log.
    pub id: u32,
    /// Pull or shrink.
    pub kind: OpKind,
    /// Subject world vertices.
    pub subjects: Vec<u32>,
    /// Target world vertex.
    pub target: u32,
    /// The red* triangle of a shrink.
    pub triangle: Option<u32>,
    /// Off-seam or on-seam (A: across panels, B: within a panel).
    pub seam: SeamKind,
    /// Copies moved toward a virtual target (seams).
    pub virtual_copies: u32,
    /// Copies left in place because their ring could not be developed.
    pub unsupported_copies: u32,
    /// The fallback used, if the regular inversion test failed.
    pub fallback: Option<Fallback>,
    /// Step at which it was initiated.
    pub start_step: u64,
    /// First step at which it was no longer warranted by the colouring.
    pub end_step: Option<u64>,
    /// Why it ended.
    pub end: Option<EndReason>,
    /// Step at which its last level was revoked (subjects back at their original uv).
    pub restored_step: Option<u64>,
    /// Deepest level reached.
    pub max_level: u32,
    /// Step at which it reached its level cap (edge shortening hindered, Sec. 5.5).
    pub saturated_step: Option<u64>,
}

impl FinesseRecord {
    /// Steps from initiation to completion, for finished finesses.
    pub fn steps(&self) -> Option<u64> {
        match (self.end, self.end_step) {
            (Some(EndReason::Finished), Some(e)) => Some(e - self.start_step),
            _ => None,
        }
    }
}

/// Why something could not proceed.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StallReason {
    /// No target (pull) or no shrink passes the inversion test, and no fallback either
    /// (Sec. 6.1); the subject is left alone this step.
    NoTitPassableFan,
    /// An operation reached its level cap without finishing its finesse (Sec. 5.5: the edge
    /// shortening is hindered). It is held at that level.
    Saturated,
    /// Triangles intersect but the colouring offers nothing to operate on (no out-most red
    /// vertex, no red* triangle) and nothing is in progress: outside the method (e.g. BLI).
    NothingToOperateOn,
    /// A saturated operation was held too long and is given up (see [`EndReason::Abandoned`]).
    Abandoned,
    /// An operation was given up and restored at once because a simulator step diverged at its
    /// subjects (see [`EndReason::Diverged`]).
    Diverged,
}

/// A place where the method could not proceed.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Stall {
    /// Why.
    pub reason: StallReason,
    /// The subject vertex (pulls) or first subject (shrinks).
    pub vertex: Option<u32>,
    /// The triangle (shrinks, or an intersecting triangle).
    pub triangle: Option<u32>,
    /// World position of the vertex (or triangle centroid) at the analysed step.
    pub position: Option<[f64; 3]>,
    /// Panel of the vertex or triangle.
    pub panel: Option<u32>,
}

/// A use of a fallback.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FallbackUse {
    /// The operation started with it.
    pub op: u32,
    /// Its first subject.
    pub vertex: u32,
    /// Which fallback.
    pub fallback: Fallback,
}

/// What one call of the uv-space update (Alg. 2) did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct UvUpdateReport {
    /// Step number (0 for the first call).
    pub step: u64,
    /// Red* triangles in the colouring.
    pub red_star_triangles: usize,
    /// Out-most red vertices in the colouring.
    pub outmost_red_vertices: usize,
    /// Shrinks initiated (Alg. 2, line 5).
    pub shrinks_started: usize,
    /// Shrinks continued by one more level.
    pub shrinks_continued: usize,
    /// Pulls initiated (line 9).
    pub pulls_started: usize,
    /// Pulls continued by one more level.
    pub pulls_continued: usize,
    /// BLI sector operations initiated (ours, [`super::sectors`]).
    pub sectors_started: usize,
    /// BLI sector operations continued by one more level.
    pub sectors_continued: usize,
    /// Levels revoked (lines 10-13).
    pub revoked_levels: usize,
    /// Operations fully revoked (subjects back at their original uv).
    pub restored: usize,
    /// Operations still warranted but not advanced this step (blocked or at their cap).
    pub paused: usize,
    /// Candidates skipped because their fan was not at its original uv (lines 3, 7; the
    /// scheduling cases 1-3).
    pub blocked_fan: usize,
    /// Candidates skipped because a subject is held by another operation.
    pub blocked_subject: usize,
    /// Candidates (red* triangles, pull targets) skipped because they were recently abandoned.
    pub blocked_tabu: usize,
    /// Red* triangles not shrunk because their target vertex (the corner opposite the red edge)
    /// is a loop vertex of an intersection path: the intersection starts at the target, so
    /// shrinking toward it can never finish (see [`super::schedule`]).
    pub blocked_loop_target: usize,
    /// Out-most red vertices whose loop-vertex neighbours were left out as pull targets
    /// because another green neighbour was available (ours, see [`super::schedule`]).
    pub pull_loop_targets_skipped: usize,
    /// Shrinks toward a loop vertex started as a last resort (ours, see [`super::schedule`]).
    pub loop_target_last_resort: usize,
    /// Operations abandoned this step: held saturated too long, or given up by the
    /// divergence guard ([`super::divergence`]).
    pub abandoned: usize,
    /// Candidate targets / shrinks that failed the inversion test.
    pub tit_rejected: usize,
    /// Sec. 6.1: some candidates were tested, none passed the regular test, and nothing else
    /// moved this step (the paper's method would halt here).
    pub no_tit_passable_fan: bool,
    /// Fallbacks used this step.
    pub fallbacks: Vec<FallbackUse>,
    /// New stalls this step.
    pub stalls: Vec<Stall>,
    /// Operations in progress after the step.
    pub active_ops: usize,
    /// Of those, held at their level cap.
    pub saturated_ops: usize,
    /// Whether any uv coordinate changed.
    pub uv_changed: bool,
}

/// One row of the Table 1 analogue.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FinesseRow {
    /// Off-seam / on-seam kind.
    pub seam: SeamKind,
    /// Finished finesses of this kind (#).
    pub count: usize,
    /// Share of all finished finesses, in percent (%).
    pub percent: f64,
    /// Mean steps from initiation to completion (t).
    pub mean_steps: f64,
    /// Operations of this kind that did not finish (superseded or still running).
    pub unfinished: usize,
}

/// The analogue of Cha & Ko's Table 1 over a finesse log.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FinesseStats {
    /// Rows for off-seam, on-seam A and on-seam B.
    pub rows: Vec<FinesseRow>,
    /// Mean steps over all on-seam finesses minus the off-seam mean (paper: at most 1.76).
    pub on_minus_off: Option<f64>,
}

impl FinesseStats {
    /// Statistics of `log`.
    pub fn of(log: &[FinesseRecord]) -> FinesseStats {
        let total = log.iter().filter(|r| r.steps().is_some()).count();
        let kinds = [SeamKind::OffSeam, SeamKind::OnSeamA, SeamKind::OnSeamB];
        let mean = |f: &dyn Fn(&FinesseRecord) -> bool| {
            let v: Vec<u64> = log
                .iter()
                .filter(|r| f(r))
                .filter_map(|r| r.steps())
                .collect();
            (!v.is_empty()).then(|| v.iter().sum::<u64>() as f64 / v.len() as f64)
        };
        let rows = kinds
            .iter()
            .map(|&k| {
                let count = log
                    .iter()
                    .filter(|r| r.seam == k && r.steps().is_some())
                    .count();
                FinesseRow {
                    seam: k,
                    count,
                    percent: if total > 0 {
                        100.0 * count as f64 / total as f64
                    } else {
                        0.0
                    },
                    mean_steps: mean(&|r| r.seam == k).unwrap_or(0.0),
                    unfinished: log
                        .iter()
                        .filter(|r| r.seam == k && r.steps().is_none())
                        .count(),
                }
            })
            .collect();
        let off = mean(&|r| r.seam == SeamKind::OffSeam);
        let on = mean(&|r| r.seam != SeamKind::OffSeam);
        FinesseStats {
            rows,
            on_minus_off: on.zip(off).map(|(a, b)| a - b),
        }
    }
}
