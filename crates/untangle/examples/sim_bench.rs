//! Simulation benchmark: one step of a garment with collision handling in ordinary motion.
//!
//! `cargo run --release -p untangle --example sim_bench [-- LEVELS...]`
//! `cargo run --release -p untangle --example sim_bench -- sheet [CELLS...]`
//! `cargo run --release -p untangle --example sim_bench -- tangled [LEVEL PATCHES STEPS]`
//!
//! The ARCSim t-shirt (../shared/data/arcsim/meshes/tshirt.obj, or $UNTANGLE_SHARED) refined by
//! 1-to-4 midpoint subdivision (levels 2 and 3 give about 5k and 20k vertices), pinned at the
//! shoulders (z up), swinging under gravity with self-collisions (front and back layers). The
//! shirt's 3D shape is its rest shape (ARCSim's sewing pattern is unsewn: seam triangles start
//! stretched up to 36x, which would make the first steps a violent sewing rather than ordinary
//! motion). After 10 warm-up steps, 30 steps are timed; the per-phase mean is printed, with the
//! process CPU time per step. `sheet`: a generated 1 m sheet (no shared data needed) of
//! `CELLS x CELLS` cells (35, 70, 141: about 1.3k, 5k, 20k vertices) pinned at two corners,
//! falling and folding onto itself. `tangled`: see [`tangled`]. `SIM_BENCH_THICKNESS` (metres)
//! replaces the 2 mm cloth-cloth thickness of the timed runs.

mod common;

use untangle::geom::Vec3;
use untangle::mesh::{subdivide::subdivide, Garment, Mesh};
use untangle::sim::{SimParams, Simulator, UniformThickness};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("tangled") {
        let arg = |i: usize, d: usize| {
            args.get(i)
                .map(|s| s.parse().expect("a number"))
                .unwrap_or(d)
        };
        let Some(base) = common::arcsim_mesh("tshirt") else {
            return;
        };
        let arcsim_uv = args.iter().any(|a| a == "--arcsim-uv");
        tangled(&base, arg(1, 2), arg(2, 3), arg(3, 10), arcsim_uv);
        return;
    }
    if args.first().map(String::as_str) == Some("sheet") {
        let sizes: Vec<usize> = args[1..]
            .iter()
            .map(|s| s.parse().expect("cells per side"))
            .collect();
        let sizes = if sizes.is_empty() {
            vec![35, 70, 141]
        } else {
            sizes
        };
        header("cells");
        for n in sizes {
            // A 1 m square sheet, horizontal, pinned at two adjacent corners: it falls, swings
            // and folds onto itself.
            let m = untangle::scenes::handkerchief("sheet", n, n, 1.0, 1.0, |uv| {
                Vec3::new(uv.x, uv.y, 0.0)
            });
            let g = Garment::new(m.clone()).expect("valid sheet");
            let mut sim = Simulator::new(&g, params()).expect("simulator");
            let corner = |x: f64, y: f64| {
                (0..m.positions.len())
                    .min_by(|&a, &b| {
                        let d = |i: usize| (m.positions[i] - Vec3::new(x, y, 0.0)).norm();
                        d(a).total_cmp(&d(b))
                    })
                    .expect("vertices")
            };
            for i in [corner(-0.5, 0.5), corner(0.5, 0.5)] {
                sim.set_pinned(i as u32, true).unwrap();
            }
            timed(n, m.positions.len(), &mut sim);
        }
        return;
    }
    let levels: Vec<usize> = args
        .iter()
        .map(|s| s.parse().expect("subdivision levels"))
        .collect();
    let levels = if levels.is_empty() {
        vec![0, 1, 2, 3]
    } else {
        levels
    };
    let Some(base) = common::arcsim_mesh("tshirt") else {
        return;
    };
    header("level");
    for level in levels {
        let mut m = base.clone();
        for _ in 0..level {
            m = subdivide(&m);
        }
        // ARCSim's shirt is unsewn (seam triangles stretched up to 36x); its 3D shape is the rest.
        m.uv = Some(untangle::sim::rest::isometric_uv(
            &m.positions,
            &m.triangles,
        ));
        let g = Garment::new(m.clone()).expect("valid garment");
        let mut sim = Simulator::new(&g, params()).expect("simulator");
        let top = common::pin_top(&mut sim, &m);
        sim.set_velocities(&common::sideways_push(&m, top)).unwrap();
        timed(level, m.positions.len(), &mut sim);
    }
}

/// `SIM_BENCH_MULTIGRID=1` measures the multigrid CG preconditioner instead of the default.
/// `UNTANGLE_INTEGRATOR=projective` measures projective dynamics (see `common`).
fn params() -> SimParams {
    common::integrator_params(SimParams {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        preconditioner: if std::env::var("SIM_BENCH_MULTIGRID").is_ok() {
            untangle::sim::CgPreconditioner::Multigrid
        } else {
            untangle::sim::CgPreconditioner::TwoLevel
        },
        ..SimParams::default()
    })
}

fn header(first: &str) {
    println!("threads: {}", rayon::current_num_threads());
    println!(
        "{:>6} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>6} {:>9} {:>7}",
        first,
        "verts",
        "step ms",
        "assem",
        "cg",
        "broad",
        "prox",
        "ccd",
        "zones",
        "cg it",
        "cands",
        "cpu ms"
    );
}

/// Process CPU time (user + system) in milliseconds: less sensitive to other processes on a
/// shared machine than wall-clock time.
fn cpu_ms() -> f64 {
    let t = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = t.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|s| s.parse::<f64>().ok()).unwrap_or(0.0);
    // Fields 14 and 15 (utime, stime) are at 11 and 12 after the command name; 100 ticks/s.
    (ticks(11) + ticks(12)) * 10.0
}

/// 10 warm-up steps, then `SIM_BENCH_STEPS` (30) timed steps; prints the per-phase means.
fn timed(label: usize, verts: usize, sim: &mut Simulator) {
    // `SIM_BENCH_THICKNESS` (metres) overrides the 2 mm cloth thickness.
    let thickness = std::env::var("SIM_BENCH_THICKNESS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2e-3);
    let policy = UniformThickness(thickness);
    let verbose = std::env::var("SIM_BENCH_VERBOSE").is_ok();
    for _ in 0..10 {
        let r = sim.step(&policy);
        if verbose {
            eprintln!("{}", r.to_json());
        }
    }
    let n: usize = std::env::var("SIM_BENCH_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(30);
    let mut acc = [0.0f64; 7];
    let mut cg = 0usize;
    let mut cands = 0usize;
    let mut quits = 0;
    let (mut pd_it, mut max_stretch, mut energy) = (0usize, 0.0f64, 0.0);
    let (mut pd_local, mut pd_global) = (0.0, 0.0);
    let cpu0 = cpu_ms();
    for _ in 0..n {
        let r = sim.step(&policy);
        if verbose {
            eprintln!("{}", r.to_json());
        }
        let c = &r.collisions.timing;
        for (a, x) in acc.iter_mut().zip([
            r.timing.total,
            r.timing.assemble,
            r.timing.solve,
            c.broad,
            c.proximity,
            c.impulses,
            c.zones,
        ]) {
            *a += x / n as f64;
        }
        cg += r.cg.iterations;
        pd_it += r.projective.map_or(0, |p| p.iterations);
        pd_local += r.projective.map_or(0.0, |p| p.local_ms) / n as f64;
        pd_global += r.projective.map_or(0.0, |p| p.global_ms) / n as f64;
        max_stretch = max_stretch.max(r.max_stretch);
        energy = r.energy.stretch + r.energy.bend;
        cands += r.collisions.candidates;
        quits += r.administrative_quit() as usize;
    }
    let cpu = (cpu_ms() - cpu0) / n as f64;
    println!(
        "{:>6} {:>7} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>6.1} {:>9} {:>7.1}{}",
        label,
        verts,
        acc[0],
        acc[1],
        acc[2],
        acc[3],
        acc[4],
        acc[5],
        acc[6],
        cg as f64 / n as f64,
        cands / n,
        cpu,
        if quits > 0 {
            format!("  ({quits} administrative quits)")
        } else {
            String::new()
        }
    );
    println!(
        "        integrator {:?}: {:.1} local/global iterations per step (local {:.2} ms, global \
         {:.2} ms), max stretch {:.4}, elastic energy at the last step {:.4e} J",
        sim.params().integrator,
        pd_it as f64 / n as f64,
        pd_local,
        pd_global,
        max_stretch,
        energy
    );
}

/// `tangled LEVEL PATCHES STEPS [--arcsim-uv]`: the Cha & Ko setting (issue 4). The t-shirt
/// refined `LEVEL` times (its clean 3D shape is the rest shape; with `--arcsim-uv` ARCSim's
/// unsewn pattern is, as in `cha_ko_bench`, so the whole shirt also sews itself together), `PATCHES` two-ring patches exploded into balls of one mean edge length (seed 7, as in
/// `cha_ko_bench`), no gravity; every step the intersection analysis colours the state (not
/// timed) and the step runs with the m-CCH policy `RedGreen` (red-red pairs skipped, red-green
/// pairs at epsilon_RG = 0.1 x mean edge length, green-green at 1e-6 m).
fn tangled(base: &Mesh, level: usize, patches: usize, steps: usize, arcsim_uv: bool) {
    use untangle::analysis::{analyze, AnalysisMesh, ObjectKind};
    use untangle::sim::RedGreen;
    let mut mesh = base.clone();
    for _ in 0..level {
        mesh = subdivide(&mesh);
    }
    if !arcsim_uv {
        // The clean shirt is the rest shape (ARCSim's pattern is unsewn, see the module doc).
        mesh.uv = Some(untangle::sim::rest::isometric_uv(
            &mesh.positions,
            &mesh.triangles,
        ));
    }
    let g0 = Garment::new(mesh.clone()).expect("garment");
    let avg = untangle::scenes::exploded::explode_patches(&mut mesh, &g0.topology, patches, 7);
    let g = Garment::new(mesh.clone()).expect("garment");
    let params = SimParams {
        gravity: Vec3::zeros(),
        // As the Cha & Ko loop runs it (`ResolveParams::default`); SIM_BENCH_CLOSE_CONTACTS=1
        // measures the default contact set instead.
        contacts_within_reach: std::env::var("SIM_BENCH_CLOSE_CONTACTS").is_err(),
        ..SimParams::default()
    };
    let params = common::integrator_params(params);
    let mut sim = Simulator::new(&g, params).expect("simulator");
    let (am, _) = AnalysisMesh::new(&[(&mesh, ObjectKind::Cloth)]).expect("analysis mesh");
    let verbose = std::env::var("SIM_BENCH_VERBOSE").is_ok();
    println!(
        "tangled t-shirt x{level}: {} vertices, {patches} exploded patches, eps_rg {:.2e} m",
        mesh.positions.len(),
        0.1 * avg
    );
    println!(
        "{:>5} {:>6} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>6} {:>5} {:>6} {:>5}",
        "step",
        "pairs",
        "red v",
        "step ms",
        "cg",
        "broad",
        "prox",
        "ccd",
        "zones",
        "cg it",
        "ccd i",
        "zone v",
        "quit"
    );
    let (mut total, mut cpu) = (0.0, 0.0);
    for s in 0..steps {
        let a = analyze(&am, sim.positions()).expect("analysis");
        let policy = RedGreen {
            red_vertex: a.coloring.red_vertex.clone(),
            red_edge: a.coloring.red_edge.clone(),
            red_triangle: a.coloring.red_triangle.clone(),
            epsilon: 1e-6,
            epsilon_rg: 0.1 * avg,
        };
        let c0 = cpu_ms();
        let r = sim.step(&policy);
        cpu += cpu_ms() - c0;
        if verbose {
            eprintln!("{}", r.to_json());
        }
        total += r.timing.total;
        let c = &r.collisions;
        println!(
            "{:>5} {:>6} {:>6} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>6} {:>5} {:>6} {:>5}",
            s,
            a.crossings.len(),
            a.coloring.num_red_vertices(),
            r.timing.total,
            r.timing.solve,
            c.timing.broad,
            c.timing.proximity,
            c.timing.impulses,
            c.timing.zones,
            r.cg.iterations,
            c.iterations,
            c.zone_vertices,
            r.administrative_quit()
        );
    }
    println!(
        "mean simulator step with m-CCH: {:.2} ms wall, {:.1} ms CPU ({} threads)",
        total / steps as f64,
        cpu / steps as f64,
        rayon::current_num_threads()
    );
}
