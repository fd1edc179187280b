//! `untangle fix --method cha-ko` end to end: a tangled scene in, an intersection-free OBJ and a
//! JSON report out; bad input gives one error line and exit code 2.

use std::process::Command;

fn untangle() -> Command {
    Command::new(env!("CARGO_BIN_EXE_untangle"))
}

#[test]
fn fixes_an_exploded_handkerchief() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ex.obj");
    let out = dir.path().join("fixed.obj");
    let json = dir.path().join("rep.json");
    let s = untangle()
        .args(["scene", "exploded", "--size", "10", "--seed", "2", "-o"])
        .arg(&input)
        .status()
        .unwrap();
    assert!(s.success());
    let check = untangle().arg("check").arg(&input).output().unwrap();
    assert_eq!(check.status.code(), Some(1), "the input intersects");
    let o = untangle()
        .args(["fix", "--method", "cha-ko", "-q"])
        .arg(&input)
        .arg("--out")
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
    let check = untangle().arg("check").arg(&out).output().unwrap();
    assert_eq!(check.status.code(), Some(0), "the output is clean");
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rep["summary"]["outcome"], "resolved");
    assert!(!rep["operations"].as_array().unwrap().is_empty());
    // Never over an input; bad parameters are one line, exit code 2.
    let o = untangle()
        .arg("fix")
        .arg(&input)
        .arg("--out")
        .arg(&input)
        .args(["--method", "cha-ko"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let o = untangle()
        .arg("fix")
        .arg(&input)
        .arg("--out")
        .arg(dir.path().join("x.obj"))
        .args(["--method", "cha-ko", "--gamma", "1.5"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.starts_with("error: ") && err.contains("gamma") && err.lines().count() == 1,
        "{err}"
    );
}
