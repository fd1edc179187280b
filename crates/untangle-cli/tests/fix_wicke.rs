//! `untangle fix --method wicke` end to end: a tangled scene in, an intersection-free OBJ and a
//! JSON report out (exit 0); a tangle beyond the method ends with exit 1 and says what is left;
//! bad settings give one error line and exit code 2.

use std::process::Command;

fn untangle() -> Command {
    Command::new(env!("CARGO_BIN_EXE_untangle"))
}

#[test]
fn fixes_a_bbii_case_and_reports_every_step() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("bbii.obj");
    let out = dir.path().join("fixed.obj");
    let json = dir.path().join("rep.json");
    assert!(untangle()
        .args(["scene", "bbii", "-o"])
        .arg(&input)
        .status()
        .unwrap()
        .success());
    let o = untangle()
        .args(["fix", "--method", "wicke"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.starts_with("wicke: resolved after "), "{stdout}");
    let check = untangle().arg("check").arg(&out).output().unwrap();
    assert_eq!(check.status.code(), Some(0), "the output is clean");
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rep["method"], "wicke");
    assert_eq!(rep["outcome"], "Resolved");
    assert_eq!(rep["output_intersection_free"], true);
    let steps = rep["steps"].as_array().unwrap();
    assert!(steps.len() >= 2);
    assert!(steps[0]["intersecting_pairs"].as_u64().unwrap() > 0);
    assert!(steps[0]["inside_points"].as_u64().unwrap() > 0);
    // Each entry is a simulator step (pairs at its start); the clean state after the last one
    // is the output.
    assert_eq!(rep["steps_run"].as_u64().unwrap() as usize, steps.len());
    assert_eq!(rep["output_intersecting_pairs"], 0);
}

#[test]
fn exit_1_with_what_is_left_and_exit_2_on_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ex.obj");
    assert!(untangle()
        .args(["scene", "exploded", "--seed", "1", "-o"])
        .arg(&input)
        .status()
        .unwrap()
        .success());
    let out = dir.path().join("out.obj");
    let o = untangle()
        .args(["fix", "--method", "wicke", "--max-steps", "5"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("step limit reached") && stdout.contains("tanglements left"),
        "{stdout}"
    );
    assert!(out.exists(), "the partial result is written");
    for bad in [
        ["--wicke-stiffness", "-1"],
        ["--wicke-max-acceleration", "nan"],
    ] {
        let x = dir.path().join("x.obj");
        let o = untangle()
            .args(["fix", "--method", "wicke"])
            .arg(&input)
            .arg("-o")
            .arg(&x)
            .args(bad)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.starts_with("error: ") && err.lines().count() == 1,
            "{err}"
        );
        assert!(!x.exists());
    }
}

#[test]
fn combined_fixes_an_exploded_handkerchief_in_stages() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ex.obj");
    let out = dir.path().join("fixed.obj");
    let json = dir.path().join("rep.json");
    assert!(untangle()
        .args(["scene", "exploded", "--seed", "4", "-o"])
        .arg(&input)
        .status()
        .unwrap()
        .success());
    let o = untangle()
        .args(["fix", "--method", "combined"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("stages: Wicke pre-pass "), "{stdout}");
    let check = untangle().arg("check").arg(&out).output().unwrap();
    assert_eq!(check.status.code(), Some(0), "the output is clean");
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rep["method"], "combined");
    let st = &rep["stage_steps"];
    let n = st["prepass"].as_u64().unwrap()
        + st["cha_ko"].as_u64().unwrap()
        + st["finish"].as_u64().unwrap();
    assert_eq!(n as usize, rep["steps"].as_array().unwrap().len());
    assert_eq!(rep["steps"][0]["stage"], "prepass");
    assert!(rep["steps"]
        .as_array()
        .unwrap()
        .iter()
        .any(|s| s["stage"] == "cha_ko" && s["red_vertices"].is_u64()));
}
