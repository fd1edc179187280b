//! Shared by the benchmark examples: where the shared data folder is, and loading an ARCSim
//! garment from it (research licence: the data stays in `../shared`, never copied here).

#![allow(dead_code)] // each example uses part of this

use std::path::PathBuf;
use untangle::mesh::{obj, Mesh};

/// The shared data folder: `$UNTANGLE_SHARED`, else `../shared` beside the repository.
pub fn shared_dir() -> PathBuf {
    std::env::var_os("UNTANGLE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")))
}

/// `data/arcsim/meshes/NAME.obj` from the shared folder, or `None` after printing a
/// "skipping" note when it is absent or unreadable.
pub fn arcsim_mesh(name: &str) -> Option<Mesh> {
    let path = shared_dir().join(format!("data/arcsim/meshes/{name}.obj"));
    match obj::read_obj(&path) {
        Ok(m) => Some(m),
        Err(e) => {
            eprintln!("skipping: {e}");
            None
        }
    }
}

/// Positional argument `i` of the process (1-based) as a number, `default` when absent.
pub fn arg(i: usize, default: usize) -> usize {
    std::env::args()
        .nth(i)
        .map(|s| s.parse().expect("a number"))
        .unwrap_or(default)
}

/// The integrator picked by the environment: `UNTANGLE_INTEGRATOR=projective` (or `pd`) selects
/// projective dynamics, anything else (or unset) Baraff & Witkin; `UNTANGLE_PD_ITERATIONS` sets
/// the local/global iterations per step (default: the library's), `UNTANGLE_PD_CHEBYSHEV` the
/// Chebyshev spectral radius (0 = off), `UNTANGLE_PD_ANDERSON` the Anderson window (0 = off),
/// `UNTANGLE_PD_CG_CAP` the CG iterations per global step under contact terms (default: the
/// library's).
pub fn integrator_params(mut p: untangle::sim::SimParams) -> untangle::sim::SimParams {
    use untangle::sim::Integrator;
    if let Ok(s) = std::env::var("UNTANGLE_INTEGRATOR") {
        p.integrator = match s.as_str() {
            "projective" | "pd" => Integrator::Projective,
            _ => Integrator::BaraffWitkin,
        };
    }
    if let Some(k) = std::env::var("UNTANGLE_PD_CG_CAP")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        p.projective_cg_iterations = k;
    }
    if let Some(k) = std::env::var("UNTANGLE_PD_ITERATIONS")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        p.projective_iterations = k;
    }
    if let Some(r) = std::env::var("UNTANGLE_PD_CHEBYSHEV")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        p.projective_chebyshev = r;
    }
    if let Some(m) = std::env::var("UNTANGLE_PD_ANDERSON")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        p.projective_anderson = m;
    }
    p
}

/// The Cha & Ko loop's settings from the environment: [`integrator_params`] for its simulator,
/// and `UNTANGLE_PD_CG_CAP` as the loop's own CG cap per projective global step
/// (`ResolveParams::projective_cg_cap`).
///
/// `UNTANGLE_INTEGRATOR=adaptive` selects the adaptive integrator
/// (`ResolveParams::adaptive`: projective dynamics, Baraff & Witkin after a stall), with
/// `UNTANGLE_ADAPTIVE_STALL` stalled steps before the switch and `UNTANGLE_ADAPTIVE_BW` steps of
/// Baraff & Witkin then (0: for the rest of the run); `pd` / `bw` (or any other value) turn it
/// off; unset keeps `p`'s choice. `CHAKO_DT` sets the loop's time step, `CHAKO_EPS` the
/// green-green thickness (`Params::eps`); [`sim_knobs`] the simulator's material and solver.
pub fn loop_params(p: &mut untangle::methods::cha_ko::ResolveParams) {
    let env = std::env::var("UNTANGLE_INTEGRATOR").ok();
    if env.as_deref() == Some("adaptive") {
        let mut a = p.adaptive.unwrap_or_default();
        let num = |k: &str| std::env::var(k).ok().and_then(|s| s.parse::<usize>().ok());
        if let Some(k) = num("UNTANGLE_ADAPTIVE_STALL") {
            a.stall_steps = k;
        }
        if let Some(k) = num("UNTANGLE_ADAPTIVE_BW") {
            a.bw_steps = if k == 0 { usize::MAX } else { k };
        }
        if let Some(k) = num("UNTANGLE_ADAPTIVE_RESTART") {
            a.restart_stall = k != 0;
        }
        p.adaptive = Some(a);
    } else {
        if env.is_some() {
            p.adaptive = None;
        }
        p.sim = integrator_params(p.sim.clone());
    }
    if let Some(k) = std::env::var("UNTANGLE_PD_CG_CAP")
        .ok()
        .and_then(|s| s.parse::<usize>().ok())
    {
        p.projective_cg_cap = Some(k);
    }
    sim_knobs(&mut p.sim);
    // CHAKO_DT: the loop's time step (`Params::dt`, Cha & Ko's 0.02 s by default).
    if let Some(dt) = std::env::var("CHAKO_DT")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
    {
        p.cha_ko.dt = dt;
    }
    if let Some(e) = std::env::var("CHAKO_EPS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
    {
        p.cha_ko.eps = e;
    }
    // CHAKO_HEAVY: the running operations' subjects' mass factor in the collision handling
    // (`ResolveParams::heavy_subjects`, 1 = off); CHAKO_HEAVY_FANS=1 makes their fans heavy too.
    if let Some(f) = std::env::var("CHAKO_HEAVY")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
    {
        p.heavy_subjects = f;
    }
    // CHAKO_SUBJECT_RG: the subjects' red-green thickness as a fraction of epsilon_RG
    // (`ResolveParams::subject_rg_scale`, 1 = off).
    if let Some(f) = std::env::var("CHAKO_SUBJECT_RG")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
    {
        p.subject_rg_scale = f;
    }
    if std::env::var("CHAKO_HEAVY_FANS").is_ok_and(|s| s == "1") {
        p.heavy_scope = untangle::methods::cha_ko::subjects::HeavyScope::SubjectsAndFans;
    }
    // CHAKO_DIVERGENCE: the divergence guard's energy ratio (`DivergenceGuard::ratio`; 0 turns
    // the guard off).
    if let Some(r) = std::env::var("CHAKO_DIVERGENCE")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
    {
        p.divergence = (r > 0.0).then(|| untangle::methods::cha_ko::DivergenceGuard {
            ratio: r,
            ..p.divergence.unwrap_or_default()
        });
    }
    // CHAKO_UV_UPDATE=0: m-CCH alone, no pulls or shrinks (`ResolveParams::uv_update`).
    if std::env::var("CHAKO_UV_UPDATE").is_ok_and(|s| s == "0") {
        p.uv_update = false;
    }
}

/// The loop simulator's material and solver settings from the environment (each unset
/// variable keeps `p`'s value): `CHAKO_SIM_STIFF` multiplies the stretch and shear stiffness,
/// `CHAKO_SIM_DENSITY` sets the area density (kg/m^2), `CHAKO_SIM_DAMP_MASS` /
/// `CHAKO_SIM_DAMP_STIFF` the mass- / stiffness-proportional damping, `CHAKO_SIM_CG_TOL` /
/// `CHAKO_SIM_CG_MAX` CG's tolerance and iteration cap, `CHAKO_SIM_IMPULSES` the CCD impulse
/// passes before impact zones, `CHAKO_SIM_FRICTION` the cloth-cloth friction,
/// `CHAKO_SIM_REACH` (0 / 1) `contacts_within_reach`, `CHAKO_SIM_CCD_RATIO` the fraction of a
/// pair's thickness CCD guarantees.
pub fn sim_knobs(p: &mut untangle::sim::SimParams) {
    let env = |k: &str| {
        std::env::var(k)
            .ok()
            .map(|s| s.parse::<f64>().unwrap_or_else(|_| panic!("{k}: a number")))
    };
    if let Some(v) = env("CHAKO_SIM_STIFF") {
        p.stretch_stiffness *= v;
        p.shear_stiffness *= v;
    }
    if let Some(v) = env("CHAKO_SIM_DENSITY") {
        p.density = v;
    }
    if let Some(v) = env("CHAKO_SIM_DAMP_MASS") {
        p.damping_mass = v;
    }
    if let Some(v) = env("CHAKO_SIM_DAMP_STIFF") {
        p.damping_stiffness = v;
    }
    if let Some(v) = env("CHAKO_SIM_CG_TOL") {
        p.cg_tolerance = v;
    }
    if let Some(v) = env("CHAKO_SIM_CG_MAX") {
        p.cg_max_iterations = v as usize;
    }
    if let Some(v) = env("CHAKO_SIM_IMPULSES") {
        p.max_impulse_iterations = v as usize;
    }
    if let Some(v) = env("CHAKO_SIM_FRICTION") {
        p.friction = v;
    }
    if let Some(v) = env("CHAKO_SIM_REACH") {
        p.contacts_within_reach = v != 0.0;
    }
    if let Some(v) = env("CHAKO_SIM_CCD_RATIO") {
        p.ccd_ratio = v;
    }
}

/// What [`run_tracking`] saw of the simulator besides the loop's summary.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tracked {
    /// Largest relative edge stretch (`|e| / |e_rest| - 1`) at the end of any step.
    pub max_stretch: f64,
    /// The same at the end of the last step.
    pub final_stretch: f64,
    /// Elastic (stretch + bend) and kinetic energy at the start of the last step, J.
    pub final_elastic: f64,
    /// See `final_elastic`.
    pub final_kinetic: f64,
    /// Mean over the steps of the step's mean collision shift (`StepReport::collision_shift`:
    /// how far the collision handling moved a vertex from the solve's end position), metres.
    pub mean_shift: f64,
}

/// `Resolver::run` written out (same steps and stopping), also keeping the stretch and the
/// energies of the simulator's step reports.
pub fn run_tracking(
    r: &mut untangle::methods::cha_ko::Resolver,
    mut on_step: impl FnMut(&untangle::methods::cha_ko::LoopStep, &untangle::sim::StepReport),
) -> (untangle::methods::cha_ko::ResolveSummary, Tracked) {
    let mut t = Tracked::default();
    let outcome = loop {
        if let Some(o) = r.stop_reason() {
            break o;
        }
        let (rec, sr) = r.step().expect("loop step");
        t.max_stretch = t.max_stretch.max(sr.max_stretch);
        t.final_stretch = sr.max_stretch;
        t.final_elastic = sr.energy.stretch + sr.energy.bend;
        t.final_kinetic = sr.energy.kinetic;
        t.mean_shift += sr.collision_shift.mean;
        on_step(&rec, &sr);
    };
    let steps = r.history().len();
    if steps > 0 {
        t.mean_shift /= steps as f64;
    }
    (r.summary(outcome), t)
}

/// The trial step of the Cha & Ko loop from the environment (`methods::cha_ko::trial`):
/// `CHAKO_TRIAL` (retries, 0 = off), `CHAKO_TRIAL_TRIGGER` (0: any newly red vertex, 1: the
/// count went up), `CHAKO_TRIAL_SCOPE` (0: crossings at the newly red vertices' edges and
/// triangles, 1: edges only), `CHAKO_TRIAL_RELEASE` (a pair blocked this many steps in a row may
/// cross; 0 = never), `CHAKO_TRIAL_BLOCK` (0: blocked pairs green-green, 1: red-green). Unset
/// variables keep `p`'s values.
pub fn trial_params(p: &mut untangle::methods::cha_ko::Params) {
    use untangle::methods::cha_ko::{TrialBlock, TrialScope, TrialTrigger};
    let env = |k: &str| {
        std::env::var(k)
            .ok()
            .map(|s| s.parse::<u32>().unwrap_or_else(|_| panic!("{k}: a number")))
    };
    if let Some(v) = env("CHAKO_TRIAL") {
        p.trial_retries = v;
    }
    if let Some(v) = env("CHAKO_TRIAL_TRIGGER") {
        p.trial_trigger = [TrialTrigger::AnyNewlyRed, TrialTrigger::CountIncrease][v as usize];
    }
    if let Some(v) = env("CHAKO_TRIAL_SCOPE") {
        p.trial_scope = [TrialScope::EdgesAndTriangles, TrialScope::Edges][v as usize];
    }
    if let Some(v) = env("CHAKO_TRIAL_RELEASE") {
        p.trial_release_after = v;
    }
    if let Some(v) = env("CHAKO_TRIAL_BLOCK") {
        p.trial_block = [TrialBlock::GreenGreen, TrialBlock::RedGreen][v as usize];
    }
}

/// The swinging-shirt start of `sim_bench` and `pd_accuracy`: pins the vertices within 1 cm of
/// the mesh's top (largest z) and returns that top.
pub fn pin_top(sim: &mut untangle::sim::Simulator, m: &Mesh) -> f64 {
    let top = m.positions.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    for (i, p) in m.positions.iter().enumerate() {
        if p.z >= top - 0.01 {
            sim.set_pinned(i as u32, true).unwrap();
        }
    }
    top
}

/// A sideways push growing with the distance below `top` (so that a top-pinned shirt swings).
pub fn sideways_push(m: &Mesh, top: f64) -> Vec<untangle::geom::Vec3> {
    m.positions
        .iter()
        .map(|p| untangle::geom::Vec3::new(0.3 * (top - p.z), 0.0, 0.0))
        .collect()
}

/// Steps the loop ran with Baraff & Witkin, and the integrator switches of the adaptive
/// integrator (`ResolveParams::adaptive`), as "BW / switches".
pub fn integrator_use(r: &untangle::methods::cha_ko::Resolver) -> String {
    let h = r.history();
    let bw = h
        .iter()
        .filter(|s| s.integrator == untangle::sim::Integrator::BaraffWitkin)
        .count();
    let switches = h.iter().filter(|s| s.integrator_switch.is_some()).count();
    format!("{bw} / {switches}")
}

/// Scheduling options of the Cha & Ko loop from the environment (`methods::cha_ko::Params`,
/// all ours): `CHAKO_REVOKE_CLEAN` (levels revoked per step once nothing intersects,
/// `revoke_levels_when_clean`: default 0, one per step as elsewhere; 200: at once; the
/// others are off by default), `CHAKO_REVOKE_FINISHED` (levels per step for
/// finished finesses, `revoke_levels_finished`), `CHAKO_HOLD_PROGRESS` (abandon a saturated
/// operation that stopped closing in for this many steps, `hold_progress_steps`),
/// `CHAKO_PULL_ORDER` (0: by index, 1: fewest out-most red neighbours first). Unset variables
/// keep `p`'s values.
pub fn schedule_params(p: &mut untangle::methods::cha_ko::Params) {
    use untangle::methods::cha_ko::PullOrder;
    let env = |k: &str| {
        std::env::var(k)
            .ok()
            .map(|s| s.parse::<u32>().unwrap_or_else(|_| panic!("{k}: a number")))
    };
    if let Some(v) = env("CHAKO_REVOKE_CLEAN") {
        p.revoke_levels_when_clean = v;
    }
    if let Some(v) = env("CHAKO_REVOKE_FINISHED") {
        p.revoke_levels_finished = v;
    }
    if let Some(v) = env("CHAKO_HOLD_PROGRESS") {
        p.hold_progress_steps = v;
    }
    if let Some(v) = env("CHAKO_PULL_ORDER") {
        p.pull_order = [PullOrder::Index, PullOrder::FewestOutmostNeighbours][v as usize];
    }
}

/// The exploded handkerchief of `seed` with the explosion's knobs from the environment:
/// `EXPLODE_R0` (ball radius, default `R0`), `EXPLODE_CENTRAL` (half-width or radius of the
/// thrown area, default `CENTRAL`), `EXPLODE_DISC=1` (a central disc instead of a square).
#[allow(dead_code)]
pub fn exploded_scene(seed: u64, cells: usize) -> untangle::scenes::Scene {
    use untangle::scenes::exploded::{exploded_with, Explosion};
    let env = |k: &str| std::env::var(k).ok().map(|s| s.parse::<f64>().expect(k));
    let d = Explosion::default();
    let e = Explosion {
        r0: env("EXPLODE_R0").unwrap_or(d.r0),
        central: env("EXPLODE_CENTRAL").unwrap_or(d.central),
        disc: env("EXPLODE_DISC").is_some_and(|v| v != 0.0),
    };
    exploded_with(seed, cells, e)
}
