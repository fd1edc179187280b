//! `untangle fix --method wicke` and `--method combined` end to end: a tangled scene in, an
//! intersection-free OBJ and a JSON report out (exit 0); a tangle beyond the method ends with
//! exit 1 and says what is left; bad settings give one error line and exit code 2.

mod common;

use common::{json, stderr, stdout, untangle};
use std::path::Path;

/// Writes scene `args` as `dir/name.obj` and runs `fix --method METHOD` on it with `extra`
/// arguments, output `fixed.obj` and report `rep.json` in `dir`.
fn fix(dir: &Path, scene: &[&str], method: &str, extra: &[&str]) -> std::process::Output {
    let mut a = vec!["scene"];
    a.extend_from_slice(scene);
    a.extend_from_slice(&["-o", "in.obj"]);
    assert!(untangle(&a, dir).status.success());
    let mut f = vec![
        "fix",
        "in.obj",
        "-o",
        "fixed.obj",
        "--json",
        "rep.json",
        "--method",
        method,
    ];
    f.extend_from_slice(extra);
    untangle(&f, dir)
}

/// A run `o` of [`fix`] in `dir` that exited 0: `untangle check` finds its output clean, and
/// its report names `method`. Returns the report.
fn clean_run_report(dir: &Path, o: &std::process::Output, method: &str) -> serde_json::Value {
    assert_eq!(o.status.code(), Some(0), "{}", stderr(o));
    let check = untangle(&["check", "fixed.obj"], dir);
    assert_eq!(check.status.code(), Some(0), "the output is clean");
    let rep = json(&dir.join("rep.json"));
    assert_eq!(rep["method"], method);
    rep
}

/// An animated body in `dir/name`: a 4 x 4 m horizontal quad at height `zs[i]` in frame `i`.
fn quad_frames(dir: &Path, name: &str, zs: &[f64]) {
    std::fs::create_dir(dir.join(name)).unwrap();
    for (i, z) in zs.iter().enumerate() {
        let text = format!("v -2 -2 {z}\nv 2 -2 {z}\nv 2 2 {z}\nv -2 2 {z}\nf 1 2 3\nf 1 3 4\n");
        std::fs::write(dir.join(format!("{name}/{i:02}.obj")), text).unwrap();
    }
}

#[test]
fn wicke_fixes_a_bbii_case_and_reports_every_step() {
    let dir = tempfile::tempdir().unwrap();
    let o = fix(dir.path(), &["bbii"], "wicke", &[]);
    let rep = clean_run_report(dir.path(), &o, "wicke");
    assert!(
        stdout(&o).starts_with("wicke: resolved after "),
        "{}",
        stdout(&o)
    );
    assert_eq!(rep["outcome"], "Resolved");
    assert_eq!(rep["output_intersection_free"], true);
    let steps = rep["steps"].as_array().unwrap();
    assert!(steps.len() >= 2);
    assert!(steps[0]["intersecting_pairs"].as_u64().unwrap() > 0);
    assert!(steps[0]["inside_points"].as_u64().unwrap() > 0);
    assert!(steps.iter().all(|s| s["stage"] == "wicke"));
    // Each entry is a simulator step (pairs at its start); the clean state after the last one
    // is the output.
    assert_eq!(rep["steps_run"].as_u64().unwrap() as usize, steps.len());
    assert_eq!(rep["output_intersecting_pairs"], 0);
}

#[test]
fn wicke_exit_1_with_what_is_left_and_exit_2_on_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let o = fix(
        dir.path(),
        &["exploded", "--seed", "1"],
        "wicke",
        &["--max-steps", "5"],
    );
    assert_eq!(o.status.code(), Some(1));
    let out = stdout(&o);
    assert!(
        out.contains("step limit reached") && out.contains("tanglements left"),
        "{out}"
    );
    assert!(
        dir.path().join("fixed.obj").exists(),
        "the partial result is written"
    );
    for bad in [
        ["--wicke-stiffness", "-1"],
        ["--wicke-max-acceleration", "nan"],
    ] {
        let mut f = vec!["fix", "in.obj", "-o", "x.obj", "--method", "wicke"];
        f.extend_from_slice(&bad);
        let o = untangle(&f, dir.path());
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
        let err = stderr(&o);
        assert!(
            err.starts_with("error: ") && err.lines().count() == 1,
            "{err}"
        );
        assert!(!dir.path().join("x.obj").exists());
    }
}

#[test]
fn combined_fixes_an_exploded_handkerchief_in_stages() {
    let dir = tempfile::tempdir().unwrap();
    let o = fix(dir.path(), &["exploded", "--seed", "4"], "combined", &[]);
    let rep = clean_run_report(dir.path(), &o, "combined");
    assert!(
        stdout(&o).contains("stages: Wicke pre-pass "),
        "{}",
        stdout(&o)
    );
    let st = &rep["stage_steps"];
    let n: u64 = ["prepass", "cha_ko", "finish"]
        .iter()
        .map(|k| st[k].as_u64().unwrap())
        .sum();
    let steps = rep["steps"].as_array().unwrap();
    assert_eq!(n as usize, steps.len());
    assert_eq!(steps[0]["stage"], "prepass");
    assert!(steps
        .iter()
        .any(|s| s["stage"] == "cha_ko" && s["red_vertices"].is_u64()));
    // The stages' settings are in the report.
    let p = &rep["params"];
    assert_eq!(p["finish_stuck_steps"], 30);
    assert_eq!(p["rounds"], 2);
    assert_eq!(p["prepass_keep_below"], 0.5);
}

#[test]
fn combined_follows_an_animated_body_and_takes_a_static_one() {
    let dir = tempfile::tempdir().unwrap();
    quad_frames(dir.path(), "body", &[-1.0, -1.1]);
    // An animated body far below: every stage follows it, and the report says so.
    let o = fix(dir.path(), &["closed"], "combined", &["--body", "body"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = json(&dir.path().join("rep.json"));
    assert_eq!(r["body"]["frames"], 2, "{r}");
    assert!(r["steps"]
        .as_array()
        .unwrap()
        .iter()
        .all(|s| s["stage"].is_string()));
    // A body file that is not there: one error line, exit 2, no output.
    std::fs::remove_file(dir.path().join("fixed.obj")).unwrap();
    let o = fix(
        dir.path(),
        &["closed"],
        "combined",
        &["--body", "nobody.obj"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
    assert!(!dir.path().join("fixed.obj").exists());
    // A static body far below: the combined loop runs with it and resolves.
    let o = fix(
        dir.path(),
        &["closed"],
        "combined",
        &["--body", "body/00.obj"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// A body that rises through the cloth's place and beyond, over 30 steps: every method stops
/// clean after a few steps, then the rest of the animation is played with full collision
/// handling, so the output rests on the body's last frame (z = 0.4 plus its 2 mm thickness)
/// instead of where the cloth was when the method stopped (z in [-0.2, 0.08]).
#[test]
fn every_method_plays_an_animated_body_to_its_last_frame() {
    let dir = tempfile::tempdir().unwrap();
    quad_frames(dir.path(), "lift", &[-0.5, 0.4]);
    for method in ["cha-ko", "wicke", "combined"] {
        let frames = format!("frames-{method}");
        let o = fix(
            dir.path(),
            &["closed"],
            method,
            &[
                "--body",
                "lift",
                "--body-frame-steps",
                "30",
                "--frames",
                &frames,
                "--frame-every",
                "7",
            ],
        );
        assert_eq!(o.status.code(), Some(0), "{method}: {}", stderr(&o));
        assert!(stdout(&o).contains("to play the rest of the body animation"));
        let r = json(&dir.path().join("rep.json"));
        let steps = r["steps"].as_array().unwrap().len();
        assert!(steps > 0 && steps < 30, "{method}: {steps}");
        assert_eq!(r["body_tail_steps"], 30 - steps, "{method}");
        assert_eq!(r["output_intersection_free"], true);
        let out = untangle::mesh::obj::read_obj(&dir.path().join("fixed.obj")).unwrap();
        let zs: Vec<f64> = out.positions.iter().map(|p| p.z).collect();
        let (lo, hi) = zs
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &z| (a.min(z), b.max(z)));
        assert!(lo > 0.4 && hi < 0.45, "{method}: z in [{lo}, {hi}]");
        // Frames: every 7th step of the run and of the body's tail, and the last one.
        let mut names: Vec<String> = std::fs::read_dir(dir.path().join(&frames))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(
            names.last().unwrap(),
            "frame_0030.obj",
            "{method}: {names:?}"
        );
        assert!(names.contains(&"frame_0028.obj".to_string()), "{names:?}");
    }
}
