//! Every query of the public CCD benchmark sample (Wang et al. 2021), whose exact ground truth was
//! computed with rational arithmetic by its authors: the CCD must have no false negative. False
//! positives are allowed and printed per scene.

use std::path::PathBuf;
use untangle::geom::ccd::{edge_edge_impact, vertex_triangle_impact, CcdOptions};
use untangle::geom::ccd_queries::read_queries;

fn shared_dir() -> PathBuf {
    std::env::var_os("UNTANGLE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")))
}

#[test]
fn no_false_negatives_on_benchmark_queries() {
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
    let options = CcdOptions::default();
    let mut total = 0;
    let mut false_negatives = Vec::new();
    for scene in &scenes {
        for kind in ["vertex-face", "edge-edge"] {
            let dir = scene.join(kind);
            let Ok(entries) = std::fs::read_dir(&dir) else {
                continue;
            };
            let mut files: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
            files.sort();
            let (mut n, mut positives, mut fp, mut unresolved) = (0, 0, 0, 0);
            for file in files
                .iter()
                .filter(|f| f.extension().is_some_and(|e| e == "csv"))
            {
                for (i, q) in read_queries(file).unwrap().iter().enumerate() {
                    let hit = if kind == "vertex-face" {
                        vertex_triangle_impact(&q.x0, &q.x1, 0.0, &options)
                    } else {
                        edge_edge_impact(&q.x0, &q.x1, 0.0, &options)
                    };
                    n += 1;
                    positives += q.truth as usize;
                    match (q.truth, hit) {
                        (true, None) => {
                            false_negatives.push(format!("{} query {i}", file.display()))
                        }
                        (false, Some(_)) => fp += 1,
                        _ => {}
                    }
                    if let Some(h) = hit {
                        assert!((0.0..=1.0).contains(&h.toi), "toi {} out of range", h.toi);
                        unresolved += !h.resolved as usize;
                    }
                }
            }
            total += n;
            eprintln!(
                "{:<30} {:<12} queries {:>5}  positives {:>5}  false positives {:>4}  unresolved {:>3}",
                scene.file_name().unwrap().to_string_lossy(),
                kind,
                n,
                positives,
                fp,
                unresolved
            );
        }
    }
    eprintln!("{total} queries, {} false negatives", false_negatives.len());
    assert!(total > 0, "no queries found under {}", root.display());
    assert!(
        false_negatives.is_empty(),
        "false negatives: {false_negatives:#?}"
    );
}
