//! End-to-end tests of the `untangle` binary: exit codes, messages, files.

mod common;

use common::{stderr, stdout, untangle};

const CLEAN: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";

#[test]
fn check_exit_codes_summary_and_json() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("clean.obj"), CLEAN).unwrap();
    let o = untangle(&["check", "clean.obj"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("no intersections"));

    let o = untangle(&["scene", "cross", "-o", "cross.obj"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = untangle(
        &[
            "check",
            "cross.obj",
            "--json",
            "r.json",
            "--colored-obj",
            "c.obj",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stdout(&o).contains("1 CROSS"), "{}", stdout(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.path().join("r.json")).unwrap()).unwrap();
    for key in [
        "triangles",
        "vertices",
        "intersecting_triangle_pairs",
        "intersecting_triangles",
        "paths",
        "red_vertices",
        "red_triangles",
        "timing_ms",
    ] {
        assert!(r.get(key).is_some(), "report has {key}");
    }
    assert!(r["timing_ms"]["total"].is_number());
    let paths = r["paths"].as_array().unwrap();
    assert_eq!(paths.len(), 2);
    for p in paths {
        for key in ["kind", "loop_vertices", "corresponds_to", "segments"] {
            assert!(p.get(key).is_some(), "path has {key}");
        }
    }
    let tris = r["intersecting_triangles"].as_array().unwrap();
    assert!(
        tris.windows(2).all(|w| w[0].as_u64() < w[1].as_u64()),
        "sorted"
    );
    assert_eq!(r["intersecting_triangle_pairs"].as_u64(), Some(23));
    let colored = std::fs::read_to_string(d.path().join("c.obj")).unwrap();
    assert!(
        colored
            .lines()
            .any(|l| l.starts_with("v ") && l.split_whitespace().count() == 7),
        "vertex colours"
    );
    assert!(colored.contains("vt "), "uv kept");

    // Quiet: nothing on stdout, same exit code.
    let o = untangle(&["--quiet", "check", "cross.obj"], d.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(stdout(&o).is_empty());
}

/// The summary names panels and seam vertices in the singular when there is one: a square of
/// two triangles in one uv panel whose corner 1 has two uv copies (one seam vertex), and a
/// second copy of the square as its own panel (two panels, two seam vertices).
#[test]
fn summary_counts_panels_and_seam_vertices() {
    let d = tempfile::tempdir().unwrap();
    let one = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
               vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt -1 0\n\
               f 1/1 2/2 3/3\nf 1/5 3/3 4/4\n";
    // Two panels: the same square's second triangle in a uv island of its own.
    let two = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
               vt 0 0\nvt 1 0\nvt 1 1\nvt 5 5\nvt 6 6\nvt 5 6\n\
               f 1/1 2/2 3/3\nf 1/4 3/5 4/6\n";
    for (name, obj, summary) in [
        ("one", one, "one: 1 panel, 1 seam vertex\n"),
        ("two", two, "two: 2 panels, 2 seam vertices\n"),
    ] {
        let file = format!("{name}.obj");
        std::fs::write(d.path().join(&file), obj).unwrap();
        let o = untangle(&["check", &file], d.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(stdout(&o).contains(summary), "{}", stdout(&o));
    }
}

#[test]
fn report_does_not_depend_on_threads() {
    let d = tempfile::tempdir().unwrap();
    untangle(
        &["scene", "exploded", "--seed", "7", "-o", "e.obj"],
        d.path(),
    );
    let mut reports = Vec::new();
    for t in ["1", "2"] {
        let json = format!("r{t}.json");
        let o = untangle(
            &["--threads", t, "check", "e.obj", "--json", &json],
            d.path(),
        );
        assert_eq!(o.status.code(), Some(1));
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.path().join(&json)).unwrap()).unwrap();
        v.as_object_mut().unwrap().remove("timing_ms");
        reports.push(v);
    }
    assert_eq!(reports[0], reports[1]);
}

#[test]
fn bad_input_gives_one_line_and_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str, &str)] = &[
        (
            "nan.obj",
            "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "nan.obj:1: non-finite number",
        ),
        (
            "range.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            "range.obj:4: vertex index 9 out of range",
        ),
        (
            "zero.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            "zero.obj:4: vertex index 0",
        ),
        (
            "degenerate.obj",
            "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n",
            "degenerate.obj:4: degenerate face",
        ),
        (
            "nonmanifold.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n",
            "non-manifold edge",
        ),
        (
            "duplicate.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nf 3 2 4\n",
            "duplicate.obj:7: duplicate face: the same three vertices as the face at duplicate.obj:6",
        ),
        ("nofaces.obj", "v 0 0 0\n", "nofaces.obj: no faces"),
        ("empty.obj", "", "empty.obj: no faces"),
        (
            "mixeduv.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2 4 3\n",
            "mixed uv",
        ),
    ];
    for (name, text, want) in cases {
        std::fs::write(d.path().join(name), text).unwrap();
        let o = untangle(&["check", name, "--json", "out.json"], d.path());
        assert_eq!(o.status.code(), Some(2), "{name}");
        let e = stderr(&o);
        assert!(e.contains(want), "{name}: got '{e}'");
        assert_eq!(e.trim_end().lines().count(), 1, "{name}: one line: '{e}'");
        assert!(
            !d.path().join("out.json").exists(),
            "{name}: no partial output"
        );
    }
    let o = untangle(&["check", "missing.obj"], d.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing.obj"));
    // The OS reason once, not repeated by the error chain.
    let text = stderr(&o);
    assert_eq!(text.lines().count(), 1, "{text}");
    assert!(text.matches("(os error").count() <= 1, "{text}");
    std::fs::create_dir(d.path().join("adir")).unwrap();
    let o = untangle(&["check", "adir"], d.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("adir"));
    let o = untangle(&["check"], d.path());
    assert_eq!(o.status.code(), Some(2), "usage error");
}

#[test]
fn outputs_never_overwrite_inputs() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("in.obj"), CLEAN).unwrap();
    for flag in ["--json", "--colored-obj"] {
        let o = untangle(&["check", "in.obj", flag, "in.obj"], d.path());
        assert_eq!(o.status.code(), Some(2), "{flag}");
        assert!(stderr(&o).contains("refusing to overwrite"));
        assert_eq!(
            std::fs::read_to_string(d.path().join("in.obj")).unwrap(),
            CLEAN
        );
    }
    // Output into a folder that does not exist: clear error, nothing written.
    let o = untangle(&["check", "in.obj", "--json", "nowhere/r.json"], d.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nowhere/r.json"));
}

#[test]
fn demo_writes_its_files() {
    let d = tempfile::tempdir().unwrap();
    let o = untangle(&["demo", "--out", "demo"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for f in ["report.json", "colored.obj", "input.obj"] {
        assert!(d.path().join("demo").join(f).is_file(), "{f}");
    }
}

/// `check --winding-regions` on `untangle scene tubes`: two long open tubes (radius 1, axes
/// at x = -0.85 and x = +0.85) overlapping side by side in one object (each wall between the
/// intersection lines lies inside the other tube). Wicke's rules give their paths no region;
/// with the flag the report gives them the walls inside the other tube, coloured red, and only
/// vertices that are inside the other tube.
#[test]
fn check_winding_regions_report_the_walls_inside_the_other_tube() {
    let d = tempfile::tempdir().unwrap();
    let off = 0.85;
    let o = untangle(&["scene", "tubes", "-o", "tubes.obj"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report = |extra: &[&str]| {
        let mut args = vec![
            "check",
            "tubes.obj",
            "--json",
            "r.json",
            "--colored-obj",
            "c.obj",
        ];
        args.extend_from_slice(extra);
        let o = untangle(&args, d.path());
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let text = std::fs::read_to_string(d.path().join("r.json")).unwrap();
        let json = serde_json::from_str::<serde_json::Value>(&text).unwrap();
        // Red vertices of the coloured OBJ ("v x y z 0.85 0.1 0.1"; orange marks the
        // intersecting triangles, the curves' vertices have no colour).
        let red: Vec<[f64; 3]> = std::fs::read_to_string(d.path().join("c.obj"))
            .unwrap()
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                l.split(' ')
                    .map(|x| x.parse().unwrap())
                    .collect::<Vec<f64>>()
            })
            .filter(|v| v.len() == 6 && v[3] > 0.8 && v[4] < 0.2)
            .map(|v| [v[0], v[1], v[2]])
            .collect();
        (json, red)
    };
    let (plain, plain_red) = report(&[]);
    let (with, red) = report(&["--winding-regions"]);
    let regions = |r: &serde_json::Value| -> u64 {
        r["paths"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|p| p["inside_vertices"].as_u64())
            .sum()
    };
    assert_eq!(regions(&plain), 0, "Wicke's rules give no region");
    let flagged = |r: &serde_json::Value| {
        r["paths"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| p["winding_region"].as_bool().unwrap())
            .count()
    };
    assert_eq!(flagged(&plain), 0);
    assert!(flagged(&with) > 0);
    assert!(plain_red.is_empty());
    assert!(regions(&with) > 50, "{}", regions(&with));
    assert!(red.len() > 50, "{}", red.len());
    assert_eq!(with["red_vertices"].as_u64(), Some(red.len() as u64));
    for p in red {
        // On its own tube (distance 1 from its axis) and strictly inside the other one.
        let inside = |c: f64| (p[0] - c).hypot(p[1]) < 0.999;
        assert!(
            inside(off) || inside(-off),
            "{p:?} is outside the other tube"
        );
    }
}
