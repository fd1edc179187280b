//! Throughput and accuracy of the CCD on every query of the CCD benchmark sample of Wang et al.
//! 2021 (`shared/data/ccd-sample-queries`), single-threaded, thickness 0.
//!
//! ```text
//! cargo run --release -p untangle --example ccd_bench [-- --json] [--min-seconds S]
//! ```
//!
//! Prints one line per scene and kind (queries, positives, false positives, false negatives,
//! queries per second) and a total; `--json` prints the same as one JSON object (used by
//! `bench/ccd_ipctk.py`).

use std::path::PathBuf;
use std::time::Instant;
use untangle::geom::ccd::{edge_edge_ccd, vertex_triangle_ccd};
use untangle::geom::ccd_queries::{read_queries, CcdQuery};

fn shared_dir() -> PathBuf {
    std::env::var_os("UNTANGLE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")))
}

struct Group {
    scene: String,
    kind: &'static str,
    queries: Vec<CcdQuery>,
}

fn run(kind: &str, q: &CcdQuery) -> Option<f64> {
    if kind == "vertex-face" {
        vertex_triangle_ccd(&q.x0, &q.x1, 0.0)
    } else {
        edge_edge_ccd(&q.x0, &q.x1, 0.0)
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let json = args.iter().any(|a| a == "--json");
    let min_seconds: f64 = args
        .iter()
        .position(|a| a == "--min-seconds")
        .and_then(|i| args.get(i + 1))
        .map(|s| s.parse().expect("--min-seconds takes a number"))
        .unwrap_or(1.0);
    let root = shared_dir().join("data/ccd-sample-queries");
    if !root.is_dir() {
        eprintln!(
            "skipping: CCD benchmark queries not found at {}",
            root.display()
        );
        return;
    }
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    scenes.sort();
    let mut groups = Vec::new();
    for scene in &scenes {
        for kind in ["vertex-face", "edge-edge"] {
            let Ok(entries) = std::fs::read_dir(scene.join(kind)) else {
                continue;
            };
            let mut files: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
            files.sort();
            let mut queries = Vec::new();
            for f in files
                .iter()
                .filter(|f| f.extension().is_some_and(|e| e == "csv"))
            {
                queries.extend(read_queries(f).unwrap_or_else(|e| panic!("{e}")));
            }
            groups.push(Group {
                scene: scene.file_name().unwrap().to_string_lossy().into_owned(),
                kind,
                queries,
            });
        }
    }
    let mut rows = Vec::new();
    let (mut tn, mut tfp, mut tfn, mut tsec) = (0usize, 0usize, 0usize, 0.0f64);
    for g in &groups {
        let results: Vec<Option<f64>> = g.queries.iter().map(|q| run(g.kind, q)).collect();
        let fp = g
            .queries
            .iter()
            .zip(&results)
            .filter(|(q, r)| !q.truth && r.is_some())
            .count();
        let fneg = g
            .queries
            .iter()
            .zip(&results)
            .filter(|(q, r)| q.truth && r.is_none())
            .count();
        let positives = g.queries.iter().filter(|q| q.truth).count();
        // Time whole passes over the group until `min_seconds / groups` have elapsed.
        let budget = min_seconds / groups.len() as f64;
        let start = Instant::now();
        let mut passes = 0usize;
        let mut sink = 0usize;
        while passes == 0 || start.elapsed().as_secs_f64() < budget {
            for q in &g.queries {
                sink +=
                    std::hint::black_box(run(g.kind, std::hint::black_box(q))).is_some() as usize;
            }
            passes += 1;
        }
        let secs = start.elapsed().as_secs_f64() / passes as f64;
        std::hint::black_box(sink);
        let n = g.queries.len();
        tn += n;
        tfp += fp;
        tfn += fneg;
        tsec += secs;
        rows.push((g.scene.clone(), g.kind, n, positives, fp, fneg, secs));
    }
    if json {
        let groups: Vec<serde_json::Value> = rows
            .iter()
            .map(|(scene, kind, n, pos, fp, fneg, secs)| {
                serde_json::json!({"scene": scene, "kind": kind, "queries": n, "positives": pos,
                    "false_positives": fp, "false_negatives": fneg, "seconds": secs})
            })
            .collect();
        let out = serde_json::json!({"groups": groups, "queries": tn, "false_positives": tfp,
            "false_negatives": tfn, "seconds": tsec, "queries_per_second": tn as f64 / tsec});
        println!("{out}");
    } else {
        println!(
            "{:<30} {:<12} {:>6} {:>6} {:>5} {:>5} {:>12}",
            "scene", "kind", "n", "pos", "FP", "FN", "queries/s"
        );
        for (scene, kind, n, pos, fp, fneg, secs) in &rows {
            println!(
                "{scene:<30} {kind:<12} {n:>6} {pos:>6} {fp:>5} {fneg:>5} {:>12.0}",
                *n as f64 / secs
            );
        }
        println!(
            "{:<30} {:<12} {tn:>6} {:>6} {tfp:>5} {tfn:>5} {:>12.0}",
            "total",
            "",
            "",
            tn as f64 / tsec
        );
    }
}
