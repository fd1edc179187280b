//! End-to-end tests of `untangle simulate`: outputs, JSON per step, frames, exit codes.

use std::path::Path;
use std::process::{Command, Output};

fn untangle(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_untangle"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run untangle")
}

/// A flat 6x6 grid in the x-z plane, with uv, as OBJ text.
fn grid_obj() -> String {
    let n = 6;
    let mut s = String::new();
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f64 * 0.05, j as f64 * 0.05);
            s += &format!("v {u} 1 {v}\nvt {u} {v}\n");
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i + 1;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            s += &format!("f {a}/{a} {b}/{b} {c}/{c}\nf {a}/{a} {c}/{c} {d}/{d}\n");
        }
    }
    s
}

#[test]
fn simulate_writes_result_json_and_frames() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("g.obj"), grid_obj()).unwrap();
    let out = untangle(
        &[
            "simulate",
            "g.obj",
            "-o",
            "out.obj",
            "--steps",
            "12",
            "--pin",
            "1,7",
            "--frames",
            "frames",
            "--frame-every",
            "5",
            "--json",
            "r.json",
            "--quiet",
        ],
        dir.path(),
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stdout.is_empty(), "quiet prints nothing");
    let text = std::fs::read_to_string(dir.path().join("out.obj")).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 49);
    assert_eq!(text.lines().filter(|l| l.starts_with("vt ")).count(), 49);
    // Pinned vertices 1 and 7 stay; the rest falls.
    let ys: Vec<f64> = text
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| l.split_whitespace().nth(2).unwrap().parse().unwrap())
        .collect();
    assert_eq!(ys[0], 1.0);
    assert_eq!(ys[6], 1.0);
    assert!(ys[48] < 0.99);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r.json")).unwrap()).unwrap();
    let reports = json["reports"].as_array().unwrap();
    assert_eq!(reports.len(), 12);
    for r in reports {
        assert!(r["time"].as_f64().unwrap() > 0.0);
        assert!(r["cg"]["iterations"].as_u64().is_some());
        assert!(r["collisions"]["iterations"].as_u64().is_some());
        assert!(r["collisions"]["impact_zones"].as_u64().is_some());
        assert_eq!(r["collisions"]["administrative_quit"], false);
    }
    assert_eq!(json["end_intersecting_pairs"], 0);
    let frames: Vec<_> = std::fs::read_dir(dir.path().join("frames"))
        .unwrap()
        .collect();
    assert_eq!(frames.len(), 3, "steps 5, 10 and the last");
}

#[test]
fn bad_input_exits_2_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("g.obj"), grid_obj()).unwrap();
    for args in [
        vec!["simulate", "missing.obj", "-o", "o.obj"],
        vec!["simulate", "g.obj", "-o", "o.obj", "--pin", "0"],
        vec!["simulate", "g.obj", "-o", "o.obj", "--pin", "box:1,2"],
        vec!["simulate", "g.obj", "-o", "o.obj", "--dt", "0"],
        vec!["simulate", "g.obj", "-o", "g.obj"],
        vec!["simulate", "g.obj", "-o", "o.obj", "--body", "nothing.obj"],
    ] {
        let out = untangle(&args, dir.path());
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("error: "), "{err}");
    }
    assert!(!dir.path().join("o.obj").exists());
}
