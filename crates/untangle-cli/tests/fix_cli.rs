//! `untangle fix` exit codes, report, frames, body and bad input; `untangle check --png`;
//! `untangle demo` files. The oracle for "clean" is always a separate `untangle check` run on the
//! written file.

mod common;

use common::{json, stderr, stdout, untangle};
use std::path::Path;

/// A small exploded handkerchief the loop resolves in a few dozen steps.
fn tangled(dir: &Path) {
    let o = untangle(
        &[
            "scene", "exploded", "--size", "10", "--seed", "2", "-o", "ex.obj",
        ],
        dir,
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[test]
fn exit_0_report_per_step_and_coloured_frames() {
    let d = tempfile::tempdir().unwrap();
    tangled(d.path());
    let o = untangle(&["check", "ex.obj", "--json", "in.json"], d.path());
    assert_eq!(o.status.code(), Some(1));
    let input = json(&d.path().join("in.json"));
    let o = untangle(
        &[
            "fix",
            "ex.obj",
            "-o",
            "out.obj",
            "--method",
            "cha-ko",
            "--json",
            "r.json",
            "--frames",
            "frames",
            "--frame-every",
            "5",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("resolved after") && out.contains("free of intersections"));
    assert!(out.lines().count() < 20, "short summary:\n{out}");
    // The oracle: an independent check of the written file.
    let c = untangle(&["check", "out.obj"], d.path());
    assert_eq!(c.status.code(), Some(0), "{}", stdout(&c));
    let r = json(&d.path().join("r.json"));
    assert_eq!(r["outcome"], "resolved");
    assert_eq!(r["output_intersection_free"], true);
    assert_eq!(r["final_analysis"]["intersecting_triangle_pairs"], 0);
    let steps = r["steps"].as_array().unwrap();
    let n = r["summary"]["steps"].as_u64().unwrap() as usize;
    assert_eq!(steps.len(), n);
    // Step 0 saw the input: the same counts `check` reports.
    assert_eq!(steps[0]["red_vertices"], input["red_vertices"]);
    assert_eq!(steps[0]["red_triangles"], input["red_triangles"]);
    assert_eq!(
        steps[0]["intersecting_pairs"],
        input["intersecting_triangle_pairs"]
    );
    for (k, s) in steps.iter().enumerate() {
        assert_eq!(s["step"], k as u64);
        for f in ["pulls", "shrinks", "revokes", "red_triangles", "ms"] {
            assert!(s[f].is_number(), "step {k}: {f}");
        }
    }
    let total = |f: &str| steps.iter().map(|s| s[f].as_u64().unwrap()).sum::<u64>();
    assert!(total("pulls") + total("shrinks") > 0);
    // Every level applied is revoked by the end (the rest shape is restored).
    assert_eq!(total("pulls") + total("shrinks"), total("revokes"));
    // Frames: 0 = the input, coloured; the last = the output.
    let f0 = std::fs::read_to_string(d.path().join("frames/frame_0000.obj")).unwrap();
    let v0: Vec<&str> = f0.lines().filter(|l| l.starts_with("v ")).collect();
    // 11 x 11 cloth vertices with colours, then the curves' points without.
    assert!(v0.len() > 121);
    assert!(v0[..121].iter().all(|l| l.split_whitespace().count() == 7));
    assert!(f0.contains("curve_"), "intersection curves");
    let last = d.path().join(format!("frames/frame_{n:04}.obj"));
    assert!(last.is_file(), "{}", last.display());
    assert!(d.path().join("frames/frame_0005.obj").is_file());
    assert!(!d.path().join("frames/frame_0001.obj").exists());
    let c = untangle(&["check", last.to_str().unwrap()], d.path());
    assert_eq!(c.status.code(), Some(0));
    // Quiet: nothing on stdout. Without `--method` the default (cha-ko) runs.
    let o = untangle(&["fix", "ex.obj", "-o", "q.obj", "-q"], d.path());
    assert_eq!(o.status.code(), Some(0));
    assert!(o.stdout.is_empty() && o.stderr.is_empty());
    assert_eq!(
        std::fs::read(d.path().join("q.obj")).unwrap(),
        std::fs::read(d.path().join("out.obj")).unwrap(),
        "deterministic"
    );
}

#[test]
fn exit_1_when_steps_run_out_says_where_and_what_is_left() {
    let d = tempfile::tempdir().unwrap();
    tangled(d.path());
    let o = untangle(
        &[
            "fix",
            "ex.obj",
            "-o",
            "out.obj",
            "--method",
            "cha-ko",
            "--max-steps",
            "2",
            "--json",
            "r.json",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stdout(&o).contains("step limit reached"));
    assert!(stdout(&o).contains("left:"));
    let c = untangle(&["check", "out.obj", "--json", "c.json"], d.path());
    assert_eq!(c.status.code(), Some(1), "the oracle agrees");
    let r = json(&d.path().join("r.json"));
    assert_eq!(r["outcome"], "step_limit");
    assert_eq!(r["output_intersection_free"], false);
    assert_eq!(r["steps"].as_array().unwrap().len(), 2);
    let fa = &r["final_analysis"];
    let c = json(&d.path().join("c.json"));
    assert_eq!(
        fa["intersecting_triangle_pairs"],
        c["intersecting_triangle_pairs"]
    );
    let paths = fa["paths"].as_array().unwrap();
    assert!(!paths.is_empty());
    for p in paths {
        assert!(p["kind"].is_string());
        assert_eq!(p["location"].as_array().unwrap().len(), 3);
    }
}

fn quad(z: f64, half: f64, cx: f64) -> String {
    format!(
        "v {} {} {z}\nv {} {} {z}\nv {} {} {z}\nv {} {} {z}\nf 1 2 3\nf 1 3 4\n",
        cx - half,
        -half,
        cx + half,
        -half,
        cx + half,
        half,
        cx - half,
        half
    )
}

#[test]
fn body_file_and_dir_and_pins() {
    let d = tempfile::tempdir().unwrap();
    tangled(d.path());
    // A floor below the explosion ball: the cloth untangles above it, the output (cloth and
    // body analysed together) is clean.
    std::fs::write(d.path().join("floor.obj"), quad(-0.6, 2.0, 0.0)).unwrap();
    let o = untangle(
        &[
            "fix",
            "ex.obj",
            "-o",
            "out.obj",
            "--method",
            "cha-ko",
            "--body",
            "floor.obj",
            "--json",
            "r.json",
            "--pin",
            "corners",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let r = json(&d.path().join("r.json"));
    assert_eq!(r["pinned"], 4);
    assert_eq!(r["body"]["frames"], 1);
    assert_eq!(r["final_analysis"]["objects"].as_array().unwrap().len(), 2);
    let c = untangle(&["check", "out.obj", "--body", "floor.obj"], d.path());
    assert_eq!(c.status.code(), Some(0), "the oracle agrees");
    // Pinned corners stay where they were.
    let corners = |f: &str| {
        let t = std::fs::read_to_string(d.path().join(f)).unwrap();
        t.lines()
            .filter(|l| l.starts_with("v "))
            .filter(|l| {
                let v: Vec<f64> = l
                    .split_whitespace()
                    .skip(1)
                    .map(|x| x.parse().unwrap())
                    .collect();
                v[0].abs() == 0.5 && v[1].abs() == 0.5
            })
            .count()
    };
    assert_eq!(corners("ex.obj"), 4);
    assert_eq!(corners("out.obj"), 4);
    // A clean sheet pierced by a small wall: nothing for Cha & Ko to do (the cloth alone is
    // clean), but the output intersects the body, so the exit code is 1.
    std::fs::write(d.path().join("sheet.obj"), quad(0.0, 0.5, 0.0)).unwrap();
    std::fs::write(
        d.path().join("wall.obj"),
        "v 0.2 -0.05 -0.05\nv 0.2 0.05 -0.05\nv 0.2 0.05 0.05\nv 0.2 -0.05 0.05\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let o = untangle(
        &[
            "fix",
            "sheet.obj",
            "-o",
            "w.obj",
            "--method",
            "cha-ko",
            "--body",
            "wall.obj",
            "--json",
            "w.json",
            "--max-steps",
            "3",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let r = json(&d.path().join("w.json"));
    assert_eq!(r["output_intersection_free"], false);
    // The user is told why: the input already penetrates the body.
    assert!(r["input_body_intersecting_pairs"].as_u64().unwrap() > 0);
    assert!(
        stdout(&o).contains("already intersects the body"),
        "{}",
        stdout(&o)
    );
    let c = untangle(&["check", "w.obj", "--body", "wall.obj"], d.path());
    assert_eq!(c.status.code(), Some(1), "the oracle agrees");
    // The same wall placed away from the sheet with `--body-scale`/`--body-offset` (shared
    // with `simulate`): nothing intersects, exit 0; the oracle, given the wall moved the same
    // way, agrees.
    let o = untangle(
        &[
            "fix",
            "sheet.obj",
            "-o",
            "p.obj",
            "--method",
            "cha-ko",
            "--body",
            "wall.obj",
            "--body-scale",
            "2",
            "--body-offset",
            "-0.4,0,-1",
            "--max-steps",
            "3",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let moved: String = std::fs::read_to_string(d.path().join("wall.obj"))
        .unwrap()
        .lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(v) => {
                let c: Vec<f64> = v.split_whitespace().map(|x| x.parse().unwrap()).collect();
                format!(
                    "v {} {} {}\n",
                    2.0 * c[0] - 0.4,
                    2.0 * c[1],
                    2.0 * c[2] - 1.0
                )
            }
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(d.path().join("wall_moved.obj"), moved).unwrap();
    let c = untangle(&["check", "p.obj", "--body", "wall_moved.obj"], d.path());
    assert_eq!(c.status.code(), Some(0), "the oracle agrees");
    let o = untangle(
        &[
            "fix",
            "sheet.obj",
            "-o",
            "q.obj",
            "--method",
            "cha-ko",
            "--body",
            "wall.obj",
            "--body-scale",
            "0",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!d.path().join("q.obj").exists());
    // A body directory of two frames far below a clean sheet: clean, exit 0.
    std::fs::create_dir(d.path().join("body")).unwrap();
    std::fs::write(d.path().join("body/f0.obj"), quad(-1.0, 2.0, 0.0)).unwrap();
    std::fs::write(d.path().join("body/f1.obj"), quad(-0.9, 2.0, 0.0)).unwrap();
    let o = untangle(
        &[
            "fix",
            "sheet.obj",
            "-o",
            "s.obj",
            "--method",
            "cha-ko",
            "--body",
            "body",
            "--json",
            "s.json",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = json(&d.path().join("s.json"));
    assert_eq!(r["body"]["frames"], 2);
    assert_eq!(r["outcome"], "resolved");
}

#[test]
fn bad_input_is_one_line_exit_2_and_no_output() {
    let d = tempfile::tempdir().unwrap();
    tangled(d.path());
    std::fs::write(
        d.path().join("nan.obj"),
        "v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        d.path().join("idx.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
    )
    .unwrap();
    let mut cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["fix", "missing.obj", "-o", "o.obj", "--method", "cha-ko"],
            "missing.obj",
        ),
        (
            vec!["fix", "nan.obj", "-o", "o.obj", "--method", "cha-ko"],
            "nan.obj:2",
        ),
        (
            vec!["fix", "idx.obj", "-o", "o.obj", "--method", "cha-ko"],
            "idx.obj:4",
        ),
        (
            vec!["fix", "ex.obj", "-o", "o.obj", "--method", "buffet"],
            "buffet",
        ),
        (
            vec!["fix", "ex.obj", "-o", "ex.obj", "--method", "cha-ko"],
            "ex.obj: refusing to overwrite an input",
        ),
        (
            vec![
                "fix", "ex.obj", "-o", "o.obj", "--method", "cha-ko", "--json", "ex.obj",
            ],
            "refusing to overwrite an input",
        ),
        (
            vec![
                "fix", "ex.obj", "-o", "o.obj", "--method", "cha-ko", "--pin", "0",
            ],
            "out of range",
        ),
        (
            vec![
                "fix",
                "ex.obj",
                "-o",
                "o.obj",
                "--method",
                "cha-ko",
                "--body",
                "nobody.obj",
            ],
            "nobody.obj",
        ),
        (
            vec![
                "fix", "ex.obj", "-o", "o.obj", "--method", "cha-ko", "--gamma", "1.5",
            ],
            "gamma",
        ),
        (
            vec![
                "fix",
                "ex.obj",
                "-o",
                "o.obj",
                "--method",
                "cha-ko",
                "--revoke-levels",
                "0",
            ],
            "revoke_levels_per_step",
        ),
        (
            vec![
                "fix",
                "ex.obj",
                "-o",
                "o.obj",
                "--method",
                "cha-ko",
                "--divergence-ratio",
                "-3",
            ],
            "divergence ratio",
        ),
    ];
    std::fs::create_dir(d.path().join("fr")).unwrap();
    std::fs::copy(d.path().join("ex.obj"), d.path().join("fr/frame_0000.obj")).unwrap();
    cases.push((
        vec![
            "fix",
            "fr/frame_0000.obj",
            "-o",
            "o.obj",
            "--method",
            "cha-ko",
            "--frames",
            "fr",
        ],
        "refusing to overwrite an input",
    ));
    let before = std::fs::read(d.path().join("ex.obj")).unwrap();
    for (args, what) in cases {
        let o = untangle(&args, d.path());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(
            e.starts_with("error: ") && e.lines().count() == 1 && e.contains(what),
            "{args:?}: {e}"
        );
        assert!(!d.path().join("o.obj").exists(), "{args:?}: no output");
    }
    assert_eq!(std::fs::read(d.path().join("ex.obj")).unwrap(), before);
}

#[test]
fn check_png_is_a_picture_of_the_right_size() {
    let d = tempfile::tempdir().unwrap();
    tangled(d.path());
    let o = untangle(&["check", "ex.obj", "--png", "ex.png", "-q"], d.path());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let img = image::open(d.path().join("ex.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (720, 600));
    // Red (tanglement) and dark blue (curves) pixels are in the picture.
    let reddish = img
        .pixels()
        .filter(|p| p[0] > 120 && p[1] < 40 && p[2] < 40)
        .count();
    let curve = img.pixels().filter(|p| p.0 == [20, 20, 160]).count();
    assert!(reddish > 50 && curve > 50, "{reddish} {curve}");
    let o = untangle(&["check", "ex.obj", "--png", "ex.obj"], d.path());
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn demo_untangles_and_writes_pictures() {
    let d = tempfile::tempdir().unwrap();
    let o = untangle(&["demo", "--out", "demo"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("free of intersections"));
    let p = d.path().join("demo");
    let c = untangle(&["check", "demo/input.obj"], d.path());
    assert_eq!(c.status.code(), Some(1), "the demo input is tangled");
    let c = untangle(&["check", "demo/untangled.obj"], d.path());
    assert_eq!(c.status.code(), Some(0), "the demo output is clean");
    let r = json(&p.join("report.json"));
    assert_eq!(r["outcome"], "resolved");
    assert!(std::fs::read_to_string(p.join("colored.obj"))
        .unwrap()
        .contains("curve_"));
    for (f, w, h) in [
        ("red_vertices.png", 800, 480),
        ("before.png", 720, 600),
        ("after.png", 720, 600),
    ] {
        let img = image::open(p.join(f)).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (w, h), "{f}");
        let first = img.get_pixel(0, 0);
        assert!(img.pixels().filter(|q| q != &first).count() > 2000, "{f}");
    }
    // The chart's curve colour is present; the after picture has no red.
    let chart = image::open(p.join("red_vertices.png")).unwrap().to_rgb8();
    assert!(chart.pixels().filter(|q| q.0 == [200, 20, 20]).count() > 100);
    let after = image::open(p.join("after.png")).unwrap().to_rgb8();
    let before = image::open(p.join("before.png")).unwrap().to_rgb8();
    let red = |i: &image::RgbImage| {
        i.pixels()
            .filter(|q| q[0] > 120 && q[1] < 40 && q[2] < 40)
            .count()
    };
    assert!(red(&before) > 100 && red(&after) == 0);
}

/// `--revoke-levels K` undoes K levels (scalings by `1/gamma`) of an operation per step: on
/// the LL scene the subjects get back to their original uv sooner, so the loop resolves in
/// fewer steps, and the report shows at most K levels revoked per operation and step.
#[test]
fn revoke_levels_speed_up_the_restoration() {
    let d = tempfile::tempdir().unwrap();
    let o = untangle(&["scene", "ll", "-o", "ll.obj"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let mut steps = Vec::new();
    for k in ["1", "3"] {
        let json_name = format!("r{k}.json");
        let o = untangle(
            &[
                "fix",
                "ll.obj",
                "-o",
                &format!("o{k}.obj"),
                "--gravity",
                "0",
                "--revoke-levels",
                k,
                "--json",
                &json_name,
                "--quiet",
            ],
            d.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let c = untangle(&["check", &format!("o{k}.obj")], d.path());
        assert_eq!(c.status.code(), Some(0), "{}", stdout(&c));
        let r = json(&d.path().join(&json_name));
        assert_eq!(
            r["params"]["revoke_levels_per_step"],
            k.parse::<u64>().unwrap()
        );
        steps.push(r["summary"]["steps"].as_u64().unwrap());
    }
    assert!(
        steps[1] < steps[0],
        "steps with 1 and 3 levels per step: {steps:?}"
    );
}

/// `--integrator`: the JSON report names each step's integrator, the adaptive one switches to
/// Baraff & Witkin when projective dynamics stalls (and says so on stdout), and the exit code
/// agrees with an independent `check` of the written file either way.
#[test]
fn integrator_choice_is_reported_per_step() {
    let d = tempfile::tempdir().unwrap();
    tangled(d.path());
    for (arg, stall) in [("projective", "8"), ("adaptive", "3")] {
        let out = format!("out-{arg}.obj");
        let rep = format!("r-{arg}.json");
        let o = untangle(
            &[
                "fix",
                "ex.obj",
                "-o",
                &out,
                "--integrator",
                arg,
                "--adaptive-stall",
                stall,
                "--max-steps",
                "60",
                "--json",
                &rep,
            ],
            d.path(),
        );
        let code = o.status.code();
        assert!(matches!(code, Some(0) | Some(1)), "{}", stderr(&o));
        let c = untangle(&["check", &out], d.path());
        assert_eq!(c.status.code(), code, "the oracle agrees ({arg})");
        let r = json(&d.path().join(&rep));
        let steps = r["steps"].as_array().unwrap();
        let ints: Vec<&str> = steps
            .iter()
            .map(|s| s["integrator"].as_str().unwrap())
            .collect();
        assert_eq!(
            ints[0], "projective",
            "{arg}: starts with projective dynamics"
        );
        assert!(stdout(&o).contains("integrator: projective dynamics"));
        let switches: Vec<usize> = (0..steps.len())
            .filter(|&k| !steps[k]["integrator_switch"].is_null())
            .collect();
        if arg == "projective" {
            assert!(ints.iter().all(|&i| i == "projective"));
            assert!(switches.is_empty());
        } else {
            // Each switch is where the integrator changes, and only there.
            for k in 1..steps.len() {
                assert_eq!(switches.contains(&k), ints[k] != ints[k - 1], "step {k}");
            }
            // With a 3-step stall this scene stalls under projective dynamics (step 19).
            let k = *switches.first().expect("the adaptive integrator switched");
            assert_eq!(steps[k]["integrator_switch"], "stalled");
            assert_eq!(ints[k], "baraff_witkin");
            assert!(stdout(&o).contains(&format!("Stalled at step {k}")));
        }
    }
    // The default runs Baraff & Witkin throughout and prints no integrator line.
    let o = untangle(
        &[
            "fix",
            "ex.obj",
            "-o",
            "bw.obj",
            "--max-steps",
            "3",
            "--json",
            "bw.json",
        ],
        d.path(),
    );
    assert!(matches!(o.status.code(), Some(0) | Some(1)));
    assert!(!stdout(&o).contains("integrator:"));
    let r = json(&d.path().join("bw.json"));
    for s in r["steps"].as_array().unwrap() {
        assert_eq!(s["integrator"], "baraff_witkin");
    }
}

/// `--no-open-bli-loops`: the unrefined `bli-interior` core (one triangle pair meeting at an
/// interior loop vertex, the kind of pair dress4 sagged 120 steps ended with) resolves with the
/// default open BLI loops and ends stuck without them (exit 1, the BLI reported); the report
/// carries the setting and the steps that opened a loop, and `check` agrees with the exit
/// code.
#[test]
fn open_bli_loops_resolve_the_one_pair_bli() {
    let d = tempfile::tempdir().unwrap();
    let o = untangle(
        &["scene", "bli-interior", "--size", "0", "-o", "bli.obj"],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // A running BLI sector opens its loop vertex too, so both are turned off.
    for (flag, code) in [(None, 0), (Some("--no-open-bli-loops"), 1)] {
        let mut args = vec!["fix", "bli.obj", "-o", "out.obj", "--json", "r.json"];
        args.extend(flag);
        args.extend(flag.map(|_| "--no-bli-sectors"));
        let o = untangle(&args, d.path());
        assert_eq!(o.status.code(), Some(code), "{flag:?}: {}", stdout(&o));
        let r = json(&d.path().join("r.json"));
        assert_eq!(r["params"]["open_bli_loops"], flag.is_none(), "{flag:?}");
        let opened = r["steps"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s["open_bli_loops"].as_u64().unwrap() > 0)
            .count();
        assert_eq!(
            opened > 0,
            flag.is_none(),
            "{flag:?}: {opened} steps opened"
        );
        let c = untangle(&["check", "out.obj"], d.path());
        assert_eq!(c.status.code(), Some(code), "{flag:?}: {}", stdout(&c));
        if code == 1 {
            assert!(stdout(&o).contains("BLI"), "{}", stdout(&o));
        }
    }
}

#[test]
fn bli_sectors_resolve_the_refined_interior_bli() {
    let d = tempfile::tempdir().unwrap();
    let o = untangle(
        &["scene", "bli-interior", "--size", "3", "-o", "bli.obj"],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for (flag, code) in [(None, 0), (Some("--no-bli-sectors"), 1)] {
        let mut args = vec!["fix", "bli.obj", "-o", "out.obj", "--json", "r.json"];
        args.extend(flag);
        let o = untangle(&args, d.path());
        assert_eq!(o.status.code(), Some(code), "{flag:?}: {}", stdout(&o));
        let r = json(&d.path().join("r.json"));
        assert_eq!(r["params"]["bli_sectors"], flag.is_none(), "{flag:?}");
        let steps = r["steps"].as_array().unwrap();
        let started: u64 = steps
            .iter()
            .map(|s| s["sectors_started"].as_u64().unwrap())
            .sum();
        assert_eq!(started > 0, flag.is_none(), "{flag:?}: {started} started");
        // `sectors` counts the levels added (started + continued): a started sector counts in
        // its step, and without sectors nothing does.
        for s in steps {
            let n = s["sectors"].as_u64().unwrap();
            assert!(n >= s["sectors_started"].as_u64().unwrap(), "{flag:?}: {s}");
            assert!(flag.is_none() || n == 0, "{flag:?}: {s}");
        }
        let c = untangle(&["check", "out.obj"], d.path());
        assert_eq!(c.status.code(), Some(code), "{flag:?}: {}", stdout(&c));
    }
}
