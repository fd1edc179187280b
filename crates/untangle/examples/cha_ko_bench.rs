//! Cost of one Cha & Ko step (analysis + colouring, uv-space update, simulator step with m-CCH)
//! on a garment of about the paper's size (Sec. 9.3: 4,183 vertices at 1.56 fps).
//!
//! The ARCSim t-shirt refined twice (4,950 vertices) is tangled by exploding `patches` two-ring
//! patches (as in `cha_ko_seams`) and run for `steps` steps of the loop without gravity; the mean
//! milliseconds of each part are printed, with steps per second.
//!
//! `CHA_KO_BENCH_VERBOSE=1` also prints each step's simulator report (JSON) to stderr.
//!
//! ARCSim's t-shirt is an *unsewn* pattern: its seam edges are stretched up to 36x in world space
//! against the uv rest shape, so the first steps of the loop also sew the shirt together at
//! metres per second. With `sew_steps > 0` the shirt is first sewn (untimed) by that many plain
//! simulator steps (conventional collision handling, no gravity, not tangled), and only then
//! exploded and untangled: the loop then measures untangling a dressed garment, as in the paper's
//! Sec. 9.3, rather than sewing. The default (0) is the unsewn start.
//!
//! ```text
//! cargo run --release -p untangle --example cha_ko_bench -- [subdivisions] [patches] [steps] [sew_steps]
//! ```

mod common;

use untangle::geom::Vec3;
use untangle::mesh::{subdivide, Garment};
use untangle::methods::cha_ko::{ResolveParams, Resolver};

fn main() {
    use common::arg;
    let (subdivisions, patches, steps) = (arg(1, 2), arg(2, 3), arg(3, 30));
    let sew_steps = arg(4, 0);
    let Some(mut mesh) = common::arcsim_mesh("tshirt") else {
        return;
    };
    mesh = subdivide::subdivide_n(&mesh, subdivisions);
    if sew_steps > 0 {
        mesh = sew_cached(mesh, sew_steps);
    }
    let g0 = Garment::new(mesh.clone()).expect("garment");
    untangle::scenes::exploded::explode_patches(&mut mesh, &g0.topology, patches, 7);
    let g = Garment::new(mesh).expect("garment");
    let mut p = ResolveParams::default();
    p.sim.gravity = Vec3::zeros();
    p.max_steps = steps;
    // UNTANGLE_INTEGRATOR=projective: projective dynamics (see `common`).
    common::loop_params(&mut p);
    let mut r = Resolver::new(&g, p).expect("resolver");
    let t = std::time::Instant::now();
    // The loop of `Resolver::run`, driven here so that CHA_KO_BENCH_VERBOSE=1 can print each
    // step's simulator report (JSON: collision passes, impact zones, per-phase milliseconds).
    let verbose = std::env::var("CHA_KO_BENCH_VERBOSE").is_ok();
    let mut phases = Phases::default();
    let mut run = || loop {
        if let Some(o) = r.stop_reason() {
            break o;
        }
        let (x, sr) = r.step().expect("step");
        eprintln!(
            "step {}: {} pairs, analysis {:.2} ms, uv {:.3} ms, rest {:.3} ms, sim {:.1} ms",
            x.step, x.intersecting_pairs, x.ms_analysis, x.ms_uv, x.ms_rest, x.ms_sim
        );
        if verbose {
            eprintln!("{}", sr.to_json());
        }
        phases.add(&sr);
    };
    // CHA_KO_BENCH_SCOPE=1: the loop inside one `rayon::scope`, so that with one worker thread
    // everything runs on one stack and callgrind's inclusive costs are per phase.
    let outcome = if std::env::var("CHA_KO_BENCH_SCOPE").is_ok() {
        rayon::scope(|_| run())
    } else {
        run()
    };
    let s = r.summary(outcome);
    let wall = t.elapsed().as_secs_f64();
    let h = r.history();
    let n = h.len() as f64;
    let mean =
        |f: &dyn Fn(&untangle::methods::cha_ko::LoopStep) -> f64| h.iter().map(f).sum::<f64>() / n;
    println!(
        "t-shirt x{subdivisions}: {} vertices, {} triangles; {} exploded patches; {} steps, {:?}",
        g.mesh.positions.len(),
        g.mesh.triangles.len(),
        patches,
        s.steps,
        s.outcome
    );
    println!(
        "intersecting pairs {} -> {}, red vertices {} -> {}",
        s.initial_pairs, s.final_pairs, s.initial_red_vertices, s.final_red_vertices
    );
    println!(
        "mean ms per step: analysis {:.2}, uv update {:.3}, rest-shape update {:.3}, simulation {:.1}; total {:.1} ms = {:.2} steps/s (wall {:.1} s)",
        mean(&|x| x.ms_analysis),
        mean(&|x| x.ms_uv),
        mean(&|x| x.ms_rest),
        mean(&|x| x.ms_sim),
        1e3 * wall / n,
        n / wall,
        wall
    );
    println!(
        "largest uv update {:.3} ms",
        h.iter().map(|x| x.ms_uv).fold(0.0, f64::max)
    );
    phases.print(n);
}

/// Sums over the loop's simulator steps of the per-phase timings and counts of their reports.
#[derive(Default)]
struct Phases {
    assemble: f64,
    solve: f64,
    collisions: f64,
    local: f64,
    global: f64,
    factor: f64,
    refactors: usize,
    pd_iterations: usize,
    cg_iterations: usize,
    springs: usize,
    broad: f64,
    proximity: f64,
    impulses: f64,
    zones: f64,
    candidates: usize,
    proximity_impulses: usize,
    ccd_passes: usize,
    zone_passes: usize,
}

impl Phases {
    fn add(&mut self, r: &untangle::sim::StepReport) {
        self.assemble += r.timing.assemble;
        self.solve += r.timing.solve;
        self.collisions += r.timing.collisions;
        if let Some(p) = &r.projective {
            self.local += p.local_ms;
            self.global += p.global_ms;
            self.factor += p.factor_ms;
            self.refactors += p.refactored as usize;
            self.pd_iterations += p.iterations;
        }
        self.cg_iterations += r.cg.iterations;
        self.springs += r.contact_springs;
        let c = &r.collisions;
        self.broad += c.timing.broad;
        self.proximity += c.timing.proximity;
        self.impulses += c.timing.impulses;
        self.zones += c.timing.zones;
        self.candidates += c.candidates;
        self.proximity_impulses += c.proximity_impulses;
        self.ccd_passes += c.iterations;
        self.zone_passes += c.zone_iterations;
    }

    /// Means per loop step (`n` steps).
    fn print(&self, n: f64) {
        let c = |k: usize| k as f64 / n;
        println!(
            "simulation per step: assemble {:.1}, solve {:.1} (local {:.1}, global {:.1}, factor {:.1} ms in {} refactors; {:.1} local/global iterations, {:.1} CG iterations, {:.0} contact springs), collisions {:.1} ms",
            self.assemble / n,
            self.solve / n,
            self.local / n,
            self.global / n,
            self.factor / n,
            self.refactors,
            c(self.pd_iterations),
            c(self.cg_iterations),
            c(self.springs),
            self.collisions / n,
        );
        println!(
            "collisions per step: broad {:.1}, proximity {:.1}, CCD impulses {:.1}, impact zones {:.1} ms; {:.0} candidates, {:.0} proximity impulses, {:.1} CCD passes, {:.1} zone passes",
            self.broad / n,
            self.proximity / n,
            self.impulses / n,
            self.zones / n,
            c(self.candidates),
            c(self.proximity_impulses),
            c(self.ccd_passes),
            c(self.zone_passes),
        );
    }
}

/// [`sew`], or the positions it gave before, read bit-exactly from the file named by
/// `CHA_KO_BENCH_SEWN` (written there when missing; for profiling the loop alone).
fn sew_cached(mut mesh: untangle::mesh::Mesh, steps: usize) -> untangle::mesh::Mesh {
    let Ok(path) = std::env::var("CHA_KO_BENCH_SEWN") else {
        return sew(mesh, steps);
    };
    if let Ok(bytes) = std::fs::read(&path) {
        let c: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        if c.len() == 3 * mesh.positions.len() {
            for (p, q) in mesh.positions.iter_mut().zip(c.chunks_exact(3)) {
                *p = Vec3::new(q[0], q[1], q[2]);
            }
            return mesh;
        }
    }
    let mesh = sew(mesh, steps);
    let bytes: Vec<u8> = mesh
        .positions
        .iter()
        .flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes()).collect::<Vec<u8>>())
        .collect();
    std::fs::write(&path, bytes).expect("write the sewn positions");
    mesh
}

/// Sews ARCSim's unsewn pattern: `steps` plain simulator steps (no gravity, conventional
/// collision handling), printing the largest world/rest edge ratio before and after.
fn sew(mesh: untangle::mesh::Mesh, steps: usize) -> untangle::mesh::Mesh {
    use untangle::sim::{SimParams, Simulator, UniformThickness};
    let g = Garment::new(mesh).expect("garment");
    // Always Baraff-Witkin: projective dynamics does not pull the 36x-stretched seams together
    // (the largest stretch grew to 72x in 60 steps); UNTANGLE_INTEGRATOR picks the loop's only.
    // Without the neighbour-pair thickness cap (`sim::near`, session 26), so that the sewn shirt
    // stays the benchmark scene of the earlier sessions (with the cap, the sewing ends at a
    // largest stretch of 1.80 instead of 3.96, a different scene: BENCHMARKS.md, session 26).
    let p = SimParams {
        gravity: Vec3::zeros(),
        near_pair_fraction: 0.0,
        ..SimParams::default()
    };
    // As `sim_bench`'s ordinary motion: 2 mm cloth-cloth thickness.
    let thickness = 2e-3;
    let mut sim = Simulator::new(&g, p).expect("simulator");
    // Largest edge length over its rest length (`max_stretch` is that ratio minus one).
    let before = sim.max_stretch() + 1.0;
    let t = std::time::Instant::now();
    for _ in 0..steps {
        sim.step(&UniformThickness(thickness));
    }
    eprintln!(
        "sewn in {steps} steps ({:.1} s): largest edge stretch {before:.2} -> {:.3}",
        t.elapsed().as_secs_f64(),
        sim.max_stretch() + 1.0
    );
    let mut m = g.mesh.clone();
    m.positions = sim.positions().to_vec();
    m
}
