//! Simulation benchmark: one step of a garment with collision handling in ordinary motion.
//!
//! `cargo run --release -p untangle --example sim_bench [-- LEVELS...]`
//!
//! The ARCSim t-shirt (../shared/data/arcsim/meshes/tshirt.obj, or $UNTANGLE_SHARED) refined by
//! 1-to-4 midpoint subdivision (levels 2 and 3 give about 5k and 20k vertices), pinned at the
//! shoulders (z up), swinging under gravity with self-collisions (front and back layers). After
//! 10 warm-up steps, 30 steps are timed; the per-phase mean is printed.

use std::path::PathBuf;
use untangle::geom::Vec3;
use untangle::mesh::{obj, subdivide::subdivide, Garment};
use untangle::sim::{SimParams, Simulator, UniformThickness};

fn shared() -> PathBuf {
    std::env::var("UNTANGLE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|_| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")))
}

fn main() {
    let levels: Vec<usize> = std::env::args()
        .skip(1)
        .map(|s| s.parse().expect("subdivision levels"))
        .collect();
    let levels = if levels.is_empty() {
        vec![0, 1, 2, 3]
    } else {
        levels
    };
    let path = shared().join("data/arcsim/meshes/tshirt.obj");
    let Ok(base) = obj::read_obj(&path) else {
        eprintln!("skipping: {} not found", path.display());
        return;
    };
    println!("threads: {}", rayon::current_num_threads());
    println!(
        "{:>6} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>6} {:>9}",
        "level",
        "verts",
        "step ms",
        "assem",
        "cg",
        "broad",
        "prox",
        "ccd",
        "zones",
        "cg it",
        "cands"
    );
    for level in levels {
        let mut m = base.clone();
        for _ in 0..level {
            m = subdivide(&m);
        }
        let g = Garment::new(m.clone()).expect("valid garment");
        let params = SimParams {
            gravity: Vec3::new(0.0, 0.0, -9.81),
            ..SimParams::default()
        };
        let mut sim = Simulator::new(&g, params).expect("simulator");
        let top = m.positions.iter().map(|p| p.z).fold(f64::MIN, f64::max);
        for (i, p) in m.positions.iter().enumerate() {
            if p.z >= top - 0.01 {
                sim.set_pinned(i as u32, true).unwrap();
            }
        }
        // A sideways push so that it swings.
        let v: Vec<Vec3> = m
            .positions
            .iter()
            .map(|p| Vec3::new(0.3 * (top - p.z), 0.0, 0.0))
            .collect();
        sim.set_velocities(&v).unwrap();
        let policy = UniformThickness(2e-3);
        for _ in 0..10 {
            sim.step(&policy);
        }
        let n = 30;
        let mut acc = [0.0f64; 7];
        let mut cg = 0usize;
        let mut cands = 0usize;
        let mut quits = 0;
        for _ in 0..n {
            let r = sim.step(&policy);
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
            cands += r.collisions.candidates;
            quits += r.administrative_quit() as usize;
        }
        println!(
            "{:>6} {:>7} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>6.1} {:>9}{}",
            level,
            m.positions.len(),
            acc[0],
            acc[1],
            acc[2],
            acc[3],
            acc[4],
            acc[5],
            acc[6],
            cg as f64 / n as f64,
            cands / n,
            if quits > 0 {
                format!("  ({quits} administrative quits)")
            } else {
                String::new()
            }
        );
    }
}
