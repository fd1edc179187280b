//! `untangle fix`'s divergence guard as a user sees it: forced with a ratio no step stays under,
//! every step is reported as diverged, the operations charged with its energy growth are given
//! up (the report's per-step `divergence` and the operations' `end`), and the summary says so;
//! with the default ratio the same run has none of it.

mod common;
use common::{json, stdout, untangle};

/// Writes scene `scene` into `d` and runs `fix` on it with `method`, `steps` and the guard's
/// `ratio`: its stdout and JSON report (exit 0 or 1, never an error).
fn fix(
    d: &std::path::Path,
    scene: &str,
    method: &str,
    steps: &str,
    ratio: &str,
) -> (String, serde_json::Value) {
    let o = untangle(&["scene", scene, "-o", "scene.obj"], d);
    assert!(o.status.success());
    let o = untangle(
        &[
            "fix",
            "scene.obj",
            "-o",
            "out.obj",
            "--method",
            method,
            "--max-steps",
            steps,
            "--divergence-ratio",
            ratio,
            "--json",
            "r.json",
        ],
        d,
    );
    assert!(matches!(o.status.code(), Some(0 | 1)), "{ratio}: no error");
    (stdout(&o), json(&d.join("r.json")))
}

#[test]
fn a_forced_divergence_is_reported_and_its_operations_given_up() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fix = |ratio: &str| fix(d, "eight", "cha-ko", "3", ratio);
    let (out, r) = fix("1e-300");
    let steps = r["step_details"].as_array().unwrap();
    assert_eq!(steps.len(), 3);
    let (mut given_up, mut kept) = (0, 0);
    for s in steps {
        let div = &s["divergence"];
        // Every try diverges, so every step ends keeping a diverged try; before that, the
        // operations holding a quarter of the growth are given up.
        assert!(div["diverged"].as_u64().unwrap() >= 1, "{div}");
        assert_eq!(div["kept_diverged"], true, "{div}");
        kept += 1;
        given_up += div["given_up"].as_array().unwrap().len();
    }
    assert!(given_up > 0);
    let ops = r["operations"].as_array().unwrap();
    let diverged = ops.iter().filter(|op| op["end"] == "diverged").count();
    assert_eq!(diverged, given_up, "each operation given up once");
    let kept = if kept > 0 {
        format!(", {kept} kept diverged")
    } else {
        String::new()
    };
    let ops = if given_up == 1 {
        "operation"
    } else {
        "operations"
    };
    assert!(
        out.contains(&format!(
            "divergence guard: the simulation diverged in 3 steps (first at step 0); {given_up} {ops} given up and the steps run again{kept}"
        )),
        "{out}"
    );
    let (out, r) = fix("10");
    assert!(!out.contains("divergence guard"), "{out}");
    for s in r["step_details"].as_array().unwrap() {
        assert_eq!(s["divergence"]["diverged"].as_u64(), Some(0));
        assert!(s["divergence"]["growth"].as_f64().unwrap() < 10.0);
    }
}

/// The combined method's Cha & Ko stage has the same guard: its steps in the report carry the
/// `divergence` record, and the summary line counts them with their index in the whole run.
#[test]
fn the_combined_methods_cha_ko_stage_reports_the_guard() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (out, r) = fix(d, "bli", "combined", "8", "1e-300");
    let steps = r["steps"].as_array().unwrap();
    let cha_ko: Vec<(usize, &serde_json::Value)> = steps
        .iter()
        .enumerate()
        .filter(|(_, s)| s["stage"] == "cha_ko")
        .collect();
    assert!(!cha_ko.is_empty(), "the Cha & Ko stage ran");
    // Every try diverges, so every Cha & Ko step does; the Wicke steps have no such record.
    for (_, s) in &cha_ko {
        assert!(s["divergence"]["diverged"].as_u64().unwrap() >= 1, "{s}");
    }
    assert!(steps
        .iter()
        .filter(|s| s["stage"] != "cha_ko")
        .all(|s| s.get("divergence").is_none()));
    let n = cha_ko.len();
    let line = format!(
        "divergence guard: the simulation diverged in {n} step{} (first at step {});",
        if n == 1 { "" } else { "s" },
        cha_ko[0].0
    );
    assert!(out.contains(&line), "{out}\nwant {line}");
}
