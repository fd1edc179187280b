//! Benchmark of the global intersection analysis (issue: full analysis of the 31k-triangle
//! folded sheet; growth with size; exploded handkerchief; garments).
//!
//! `cargo run --release -p untangle --example analysis_bench [-- --runs N] [-- --only NAME]`
//! Prints the median and minimum wall time of each phase over N runs.

use std::time::Instant;
use untangle::analysis::{analyze, AnalysisMesh, ObjectKind};
use untangle::mesh::Mesh;
use untangle::scenes;

fn bench(name: &str, meshes: &[Mesh], runs: usize) {
    let parts: Vec<_> = meshes.iter().map(|m| (m, ObjectKind::Cloth)).collect();
    let (am, pos) = AnalysisMesh::new(&parts).expect("valid scene");
    let mut totals = Vec::new();
    let mut phases = Vec::new();
    let mut last = None;
    for _ in 0..runs {
        let t = Instant::now();
        let a = analyze(&am, &pos).expect("consistent");
        totals.push(t.elapsed().as_secs_f64() * 1e3);
        phases.push(a.timing);
        last = Some(a);
    }
    let a = last.expect("at least one run");
    let mut sorted = totals.clone();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let med = sorted[sorted.len() / 2];
    let best = sorted[0];
    let bi = totals.iter().position(|&t| t == best).unwrap_or(0);
    let p = phases[bi];
    let closed = a.tanglements.iter().filter(|t| t.kind == "CLOSED").count();
    println!(
        "{name:<26} tris {:>7} pairs {:>6} paths {:>5} closed {:>4} | median {:>8.2} ms  min {:>8.2} ms  (broad {:.2}, crossings {:.2}, paths {:.2}, regions {:.2})",
        am.triangles.len(),
        a.segments.len(),
        a.paths.len(),
        closed,
        med,
        best,
        p.broad_phase,
        p.crossings,
        p.paths,
        p.regions
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs = args
        .iter()
        .position(|a| a == "--runs")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(21);
    let only = args
        .iter()
        .position(|a| a == "--only")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let want = |n: &str| {
        only.as_deref()
            .map(|o| n.starts_with(o) || o.starts_with(n))
            .unwrap_or(true)
    };
    println!("threads: {}", rayon::current_num_threads());
    if want("folded") {
        for (n, dents) in [
            (125, 4),
            (125, 15),
            (60, 4),
            (90, 4),
            (177, 4),
            (224, 4),
            (250, 15),
            (22, 4),
            (30, 4),
            (40, 4),
            (64, 4),
        ] {
            let name = format!("folded n={n} dents={dents}");
            if let Some(o) = &only {
                if o.len() > "folded".len() && !name.starts_with(o.as_str()) {
                    continue;
                }
            }
            let s = scenes::folded::folded(n, dents);
            bench(&name, &s.meshes, runs);
        }
    }
    if want("skirt") {
        for n in [56, 112, 160, 224] {
            let s = scenes::garment::skirt(n, 5);
            bench(&format!("skirt n={n} (2 panels)"), &s.meshes, runs.min(11));
        }
    }
    if want("exploded") {
        // The paper's size (14 x 14 cells) for seeds 0-2, then larger balls (seed 0): the number
        // of crossing pairs grows with the square of the triangles thrown into the ball.
        let cases = [(14, 0), (14, 1), (14, 2), (20, 0), (28, 0), (40, 0)];
        for (n, seed) in cases {
            let name = if n == 14 {
                format!("exploded seed={seed}")
            } else {
                format!("exploded n={n} seed={seed}")
            };
            if let Some(o) = &only {
                if o.len() > "exploded".len() && !name.starts_with(o.as_str()) {
                    continue;
                }
            }
            let s = scenes::exploded::exploded(seed, n);
            bench(&name, &s.meshes, runs);
        }
    }
    if want("garment") {
        let dir = std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data/arcsim/meshes"
        ));
        if let Ok(m) = untangle::mesh::obj::read_obj(&dir.join("tshirt.obj")) {
            for lv in [2, 3, 4] {
                let s = untangle::mesh::subdivide::subdivide_n(&m, lv);
                bench(&format!("tshirt subdivided x{lv}"), &[s], runs.min(7));
            }
        } else {
            println!("garment: skipped (no ../shared data)");
        }
    }
}
