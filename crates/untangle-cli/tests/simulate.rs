//! End-to-end tests of `untangle simulate`: outputs, JSON per step, frames, exit codes.

mod common;

use common::untangle;

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

/// `--integrator projective`: the report carries the local/global iterations of every step;
/// the pinned corners stay and the cloth falls, without intersections.
#[test]
fn simulate_with_projective_dynamics() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("g.obj"), grid_obj()).unwrap();
    let args = [
        "simulate",
        "g.obj",
        "-o",
        "out.obj",
        "--steps",
        "8",
        "--pin",
        "1,7",
        "--json",
        "r.json",
        "--integrator",
        "projective",
        "--pd-iterations",
        "6",
        "--quiet",
    ];
    let out = untangle(&args, dir.path());
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r.json")).unwrap()).unwrap();
    let reports = json["reports"].as_array().unwrap();
    assert_eq!(reports.len(), 8);
    for r in reports {
        assert_eq!(r["projective"]["iterations"].as_u64(), Some(6));
    }
    assert_eq!(json["end_intersecting_pairs"], 0);
    let text = std::fs::read_to_string(dir.path().join("out.obj")).unwrap();
    let ys: Vec<f64> = text
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| l.split_whitespace().nth(2).unwrap().parse().unwrap())
        .collect();
    assert_eq!((ys[0], ys[6]), (1.0, 1.0));
    assert!(ys[48] < 0.99);
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
        vec!["simulate", "g.obj", "-o", "o.obj", "--dt", "-1"],
        vec!["simulate", "g.obj", "-o", "g.obj"],
        vec!["simulate", "g.obj", "-o", "o.obj", "--body", "nothing.obj"],
        vec![
            "simulate",
            "g.obj",
            "-o",
            "o.obj",
            "--integrator",
            "projective",
            "--pd-iterations",
            "0",
        ],
    ] {
        let out = untangle(&args, dir.path());
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("error: "), "{err}");
        if args.contains(&"-1") {
            // A negative number is a value, judged by the parameter check, not a flag.
            assert!(err.contains("dt must be positive"), "{err}");
        }
    }
    assert!(!dir.path().join("o.obj").exists());
}

/// A closed box `[x0, x1] x [y0, y1] x [z0, z1]` with `k` subdivisions per side of its top face
/// (so frames can differ in their meshes), as OBJ text.
fn box_obj(lo: [f64; 3], hi: [f64; 3], k: usize) -> String {
    let mut s = String::new();
    let mut vid = 0;
    let mut v = |s: &mut String, p: [f64; 3]| {
        *s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        vid += 1;
        vid
    };
    // Top face as a (k+1)^2 grid, the rest as a fan of the 4 bottom corners.
    let mut top = Vec::new();
    for j in 0..=k {
        for i in 0..=k {
            let x = lo[0] + (hi[0] - lo[0]) * i as f64 / k as f64;
            let z = lo[2] + (hi[2] - lo[2]) * j as f64 / k as f64;
            top.push(v(&mut s, [x, hi[1], z]));
        }
    }
    let b: Vec<usize> = [
        [lo[0], lo[2]],
        [hi[0], lo[2]],
        [hi[0], hi[2]],
        [lo[0], hi[2]],
    ]
    .iter()
    .map(|c| v(&mut s, [c[0], lo[1], c[1]]))
    .collect();
    let t = |i: usize, j: usize| top[j * (k + 1) + i];
    for j in 0..k {
        for i in 0..k {
            s += &format!("f {} {} {}\n", t(i, j), t(i, j + 1), t(i + 1, j + 1));
            s += &format!("f {} {} {}\n", t(i, j), t(i + 1, j + 1), t(i + 1, j));
        }
    }
    s += &format!(
        "f {} {} {}\nf {} {} {}\n",
        b[0], b[1], b[2], b[0], b[2], b[3]
    );
    // Sides: each side joins the top boundary (in order) to its two bottom corners.
    let sides: [(Vec<usize>, usize, usize); 4] = [
        ((0..=k).map(|i| t(i, 0)).collect(), b[0], b[1]),
        ((0..=k).map(|j| t(k, j)).collect(), b[1], b[2]),
        ((0..=k).rev().map(|i| t(i, k)).collect(), b[2], b[3]),
        ((0..=k).rev().map(|j| t(0, j)).collect(), b[3], b[0]),
    ];
    for (edge, c0, c1) in sides {
        for w in edge.windows(2) {
            s += &format!("f {} {} {}\n", w[1], w[0], c0);
        }
        s += &format!("f {} {} {}\n", edge[k], c0, c1);
    }
    s
}

/// `--body DIR` with frames meshed differently (a box under the cloth, rising, remeshed in every
/// frame): the frames are tracked onto frame 0's mesh, the run says so and ends clean.
#[test]
fn body_frames_with_different_meshes_are_tracked() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("g.obj"), grid_obj()).unwrap();
    let frames = dir.path().join("body");
    std::fs::create_dir(&frames).unwrap();
    for (f, k) in [(0, 2), (1, 3), (2, 5)] {
        let y = 0.8 + 0.02 * f as f64;
        std::fs::write(
            frames.join(format!("f{f}.obj")),
            box_obj([0.05, 0.5, 0.05], [0.25, y, 0.25], k),
        )
        .unwrap();
    }
    let out = untangle(
        &[
            "simulate", "g.obj", "-o", "out.obj", "--steps", "20", "--body", "body",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("do not share one mesh"), "{stdout}");
    assert!(stdout.contains("intersection-free"), "{stdout}");
}
