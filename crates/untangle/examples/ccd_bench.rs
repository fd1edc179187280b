//! Throughput and accuracy of the CCD, single-threaded.
//!
//! ```text
//! cargo run --release -p untangle --example ccd_bench [-- --json] [--min-seconds S] [--write-synthetic FILE]
//! ```
//!
//! Groups:
//! - every query of the CCD benchmark sample of Wang et al. 2021
//!   (`shared/data/ccd-sample-queries`, skipped with a note when absent), thickness 0, exact
//!   ground truth;
//! - `synthetic-*`: seeded queries with a thickness, as a cloth simulator issues them:
//!   `planted` = a contact within the thickness is planted at a random time (truth 1, exact by
//!   construction), `resting` = a vertex or an edge slides parallel to the other primitive at a
//!   distance of `thickness (1 + e)`, `e` in `[2e-3, 0.1]`, so they never come within the
//!   thickness (truth 0; cloth at rest on cloth).
//!
//! Prints one line per group (queries, positives, false positives, false negatives, queries per
//! second) and a total; `--json` prints the same as one JSON object, and `--write-synthetic`
//! writes the synthetic queries (one per line: 24 coordinates of `x0` then `x1`, thickness,
//! truth; shortest round-trip decimals) so that `bench/ccd_ipctk.py` runs ipctk on them too.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;
use std::time::Instant;
use untangle::geom::ccd::{
    edge_edge_ccd, edge_edge_impact, vertex_triangle_ccd, vertex_triangle_impact, CcdOptions,
};
use untangle::geom::ccd_queries::read_queries;
use untangle::geom::Vec3;

fn shared_dir() -> PathBuf {
    std::env::var_os("UNTANGLE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")))
}

/// One query: positions at 0 and 1, thickness, ground truth.
type Query = ([Vec3; 4], [Vec3; 4], f64, bool);

struct Group {
    scene: String,
    kind: &'static str,
    queries: Vec<Query>,
}

fn run(kind: &str, q: &Query) -> Option<f64> {
    if kind == "vertex-face" {
        vertex_triangle_ccd(&q.0, &q.1, q.2)
    } else {
        edge_edge_ccd(&q.0, &q.1, q.2)
    }
}

/// Boxes the search examined (a machine-independent work measure).
fn boxes(kind: &str, q: &Query) -> u32 {
    let o = CcdOptions::default();
    let hit = if kind == "vertex-face" {
        vertex_triangle_impact(&q.0, &q.1, q.2, &o)
    } else {
        edge_edge_impact(&q.0, &q.1, q.2, &o)
    };
    hit.map_or(0, |h| h.boxes)
}

fn benchmark_groups() -> Vec<Group> {
    let root = shared_dir().join("data/ccd-sample-queries");
    if !root.is_dir() {
        eprintln!(
            "skipping: CCD benchmark queries not found at {}",
            root.display()
        );
        return Vec::new();
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
                let qs = read_queries(f).unwrap_or_else(|e| panic!("{e}"));
                queries.extend(qs.into_iter().map(|q| (q.x0, q.x1, 0.0, q.truth)));
            }
            groups.push(Group {
                scene: scene.file_name().unwrap().to_string_lossy().into_owned(),
                kind,
                queries,
            });
        }
    }
    groups
}

/// A dyadic coordinate `k / 16`, `|k| <= 32` (exact arithmetic in the constructions below).
fn dy(r: &mut ChaCha8Rng) -> f64 {
    r.random_range(-32i32..=32) as f64 / 16.0
}

fn dy_vec(r: &mut ChaCha8Rng) -> Vec3 {
    Vec3::new(dy(r), dy(r), dy(r))
}

/// Positions at 0 and 1 passing through `xs` at time `ts` along displacements `d` (exact).
fn through(xs: [Vec3; 4], d: [Vec3; 4], ts: f64) -> ([Vec3; 4], [Vec3; 4]) {
    (
        [0, 1, 2, 3].map(|i| xs[i] - d[i] * ts),
        [0, 1, 2, 3].map(|i| xs[i] + d[i] * (1.0 - ts)),
    )
}

/// Planted contacts within the thickness (truth 1).
fn planted(kind: &str, n: usize, seed: u64) -> Vec<Query> {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let offset = dy_vec(&mut r) * 0.0625;
            let thickness = offset.norm() * (1.0 + 1e-12) + 1e-3;
            let ts = r.random_range(0..=32) as f64 / 32.0;
            let d = [
                dy_vec(&mut r),
                dy_vec(&mut r),
                dy_vec(&mut r),
                dy_vec(&mut r),
            ];
            let xs = if kind == "vertex-face" {
                let t = [dy_vec(&mut r), dy_vec(&mut r), dy_vec(&mut r)];
                let i = r.random_range(0..=8);
                let j = r.random_range(0..=8 - i);
                let (u, v) = (i as f64 / 8.0, j as f64 / 8.0);
                [
                    t[0] * (1.0 - u - v) + t[1] * u + t[2] * v + offset,
                    t[0],
                    t[1],
                    t[2],
                ]
            } else {
                let x = dy_vec(&mut r);
                let (fa, fb) = (dy_vec(&mut r), dy_vec(&mut r));
                let (s, w) = (
                    r.random_range(0..=8) as f64 / 8.0,
                    r.random_range(0..=8) as f64 / 8.0,
                );
                let y = x + offset;
                [
                    x - fa * s,
                    x + fa * (1.0 - s),
                    y - fb * w,
                    y + fb * (1.0 - w),
                ]
            };
            let (x0, x1) = through(xs, d, ts);
            (x0, x1, thickness, true)
        })
        .collect()
}

/// Sliding at a distance `thickness (1 + e)` over the plane `z = 0`, then rotated (truth 0).
fn resting(kind: &str, n: usize, seed: u64) -> Vec<Query> {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    let flat = |r: &mut ChaCha8Rng| Vec3::new(dy(r), dy(r), 0.0);
    (0..n)
        .map(|_| {
            let thickness = 10f64.powf(r.random_range(-3.0..-1.0));
            let e = 10f64.powf(r.random_range(-2.7..-1.0));
            let h = Vec3::new(0.0, 0.0, thickness * (1.0 + e));
            let drift = flat(&mut r) * 0.25;
            let (x0, x1) = if kind == "vertex-face" {
                // A triangle around the origin and a vertex above it, sliding in parallel.
                let t = [flat(&mut r), flat(&mut r), flat(&mut r)];
                let p = (t[0] + t[1] + t[2]) / 3.0 + h;
                let x0 = [p, t[0], t[1], t[2]];
                let moved = [
                    p + flat(&mut r) * 0.25 + drift,
                    t[0] + drift,
                    t[1] + drift,
                    t[2] + drift,
                ];
                (x0, moved)
            } else {
                let a = [flat(&mut r), flat(&mut r)];
                let b = [flat(&mut r) + h, flat(&mut r) + h];
                let x0 = [a[0], a[1], b[0], b[1]];
                let sb = flat(&mut r) * 0.25;
                (
                    x0,
                    [
                        a[0] + drift,
                        a[1] + drift,
                        b[0] + drift + sb,
                        b[1] + drift + sb,
                    ],
                )
            };
            // A random rotation keeps the separation (up to rounding, far below e thickness).
            let axis =
                Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), 1.0).normalize();
            let rot = nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Unit::new_normalize(axis),
                r.random_range(0.0..std::f64::consts::TAU),
            );
            (x0.map(|p| rot * p), x1.map(|p| rot * p), thickness, false)
        })
        .collect()
}

fn synthetic_groups() -> Vec<Group> {
    let mut groups = Vec::new();
    for (i, kind) in ["vertex-face", "edge-edge"].into_iter().enumerate() {
        groups.push(Group {
            scene: "synthetic-planted".into(),
            kind,
            queries: planted(kind, 1000, 11 + i as u64),
        });
        groups.push(Group {
            scene: "synthetic-resting".into(),
            kind,
            queries: resting(kind, 1000, 21 + i as u64),
        });
    }
    groups
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let json = args.iter().any(|a| a == "--json");
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
    };
    let min_seconds: f64 =
        arg("--min-seconds").map_or(1.0, |s| s.parse().expect("--min-seconds takes a number"));
    let mut groups = benchmark_groups();
    let synthetic = synthetic_groups();
    if let Some(path) = arg("--write-synthetic") {
        let mut out = String::new();
        for g in &synthetic {
            out.push_str(&format!("# {} {} {}\n", g.scene, g.kind, g.queries.len()));
            for (x0, x1, h, truth) in &g.queries {
                let c: Vec<String> = x0
                    .iter()
                    .chain(x1)
                    .flat_map(|p| [p.x, p.y, p.z])
                    .map(|c| format!("{c:?}"))
                    .collect();
                out.push_str(&format!("{} {h:?} {}\n", c.join(" "), *truth as u8));
            }
        }
        std::fs::write(path, out).expect("cannot write the synthetic queries");
    }
    groups.extend(synthetic);
    let mut rows = Vec::new();
    let (mut tn, mut tfp, mut tfn, mut tsec) = (0usize, 0usize, 0usize, 0.0f64);
    let mut tboxes = 0.0;
    for g in &groups {
        let results: Vec<Option<f64>> = g.queries.iter().map(|q| run(g.kind, q)).collect();
        let fp = g
            .queries
            .iter()
            .zip(&results)
            .filter(|(q, r)| !q.3 && r.is_some())
            .count();
        let fneg = g
            .queries
            .iter()
            .zip(&results)
            .filter(|(q, r)| q.3 && r.is_none())
            .count();
        let positives = g.queries.iter().filter(|q| q.3).count();
        let mean_boxes = g
            .queries
            .iter()
            .map(|q| boxes(g.kind, q) as f64)
            .sum::<f64>()
            / g.queries.len() as f64;
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
        rows.push((
            g.scene.clone(),
            g.kind,
            n,
            positives,
            fp,
            fneg,
            secs,
            mean_boxes,
        ));
        tboxes += mean_boxes * n as f64;
    }
    if json {
        let groups: Vec<serde_json::Value> = rows
            .iter()
            .map(|(scene, kind, n, pos, fp, fneg, secs, mb)| {
                serde_json::json!({"scene": scene, "kind": kind, "queries": n, "positives": pos,
                    "false_positives": fp, "false_negatives": fneg, "seconds": secs, "mean_boxes": mb})
            })
            .collect();
        let out = serde_json::json!({"groups": groups, "queries": tn, "false_positives": tfp,
            "false_negatives": tfn, "seconds": tsec, "queries_per_second": tn as f64 / tsec, "mean_boxes": tboxes / tn as f64});
        println!("{out}");
    } else {
        println!(
            "{:<30} {:<12} {:>6} {:>6} {:>5} {:>5} {:>12} {:>10}",
            "scene", "kind", "n", "pos", "FP", "FN", "queries/s", "boxes/q"
        );
        for (scene, kind, n, pos, fp, fneg, secs, mb) in &rows {
            println!(
                "{scene:<30} {kind:<12} {n:>6} {pos:>6} {fp:>5} {fneg:>5} {:>12.0} {mb:>10.1}",
                *n as f64 / secs
            );
        }
        println!(
            "{:<30} {:<12} {tn:>6} {:>6} {tfp:>5} {tfn:>5} {:>12.0} {:>10.1}",
            "total",
            "",
            "",
            tn as f64 / tsec,
            tboxes / tn as f64
        );
    }
}
