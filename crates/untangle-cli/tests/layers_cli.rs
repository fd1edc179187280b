//! `untangle layers`: outputs, JSON report, exit codes and bad-input errors.

use std::process::Command;
use untangle::geom::Vec3;
use untangle::implicit::shapes::sphere_mesh;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_untangle"))
}

fn write(dir: &std::path::Path, name: &str, r: f64) -> std::path::PathBuf {
    let p = dir.join(name);
    let m = sphere_mesh(name.trim_end_matches(".obj"), &Vec3::zeros(), r, 16);
    untangle::mesh::obj::write_obj(&p, &m, None, "").unwrap();
    p
}

#[test]
fn inverted_spheres_are_untangled_with_a_report() {
    run_inverted_spheres(&[]);
}

#[test]
fn the_self_intersection_guard_flag_keeps_the_result_clean() {
    let r = run_inverted_spheres(&["--no-new-self-intersections"]);
    assert_eq!(r["verification"]["self_intersections"], 0);
}

fn run_inverted_spheres(extra: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let inner = write(dir.path(), "inner.obj", 0.5);
    let outer = write(dir.path(), "outer.obj", 0.46);
    let out = dir.path().join("out");
    let json = dir.path().join("r.json");
    let o = bin()
        .args(["--quiet", "layers"])
        .arg(&inner)
        .arg(&outer)
        .args(["--thickness", "0.01", "--samples", "200", "-o"])
        .arg(&out)
        .arg("--json")
        .arg(&json)
        .args(extra)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(r["verification"]["between_layers"], 0);
    let sep = &r["layers"][1]["separation"];
    assert!(sep["count"].as_u64().unwrap() > 100);
    assert!(sep["relative_error"].as_f64().unwrap() < 0.05, "{sep}");
    let m = untangle::mesh::obj::read_obj(&out.join("outer.obj")).unwrap();
    let mean = m.positions.iter().map(|p| p.norm()).sum::<f64>() / m.positions.len() as f64;
    assert!((mean - (0.5 + 0.46 + 0.01) / 2.0).abs() < 3e-3, "{mean}");
    r
}

#[test]
fn bad_input_is_one_error_line_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let a = write(dir.path(), "a.obj", 0.5);
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap();
    let out = dir.path().join("o");
    let cases: Vec<Vec<std::ffi::OsString>> = vec![
        vec![bad.clone().into(), "-o".into(), out.clone().into()],
        vec![
            dir.path().join("missing.obj").into(),
            "-o".into(),
            out.clone().into(),
        ],
        vec![
            a.clone().into(),
            "--weight".into(),
            "1,2".into(),
            "-o".into(),
            out.clone().into(),
        ],
        vec![
            a.clone().into(),
            "--weight=-1".into(),
            "-o".into(),
            out.clone().into(),
        ],
        vec![
            a.clone().into(),
            "--thickness".into(),
            "nan".into(),
            "-o".into(),
            out.clone().into(),
        ],
        // Output onto the input itself.
        vec![a.clone().into(), "-o".into(), dir.path().into()],
    ];
    for args in cases {
        let o = bin().arg("layers").args(&args).output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.starts_with("error: "), "{err}");
    }
}
