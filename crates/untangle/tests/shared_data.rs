//! Tests on third-party data in `../shared/data` (skipped with a note when it is absent).

mod common;

use common::*;
use untangle::geom::Vec3;
use untangle::mesh::{obj::read_obj, subdivide::subdivide_n, Garment};

/// The seven path-type cases of Untangling26 (Apache-2.0): file name, kind, exact pair count
/// (from the data set's README).
const UNITS: [(&str, &str, usize); 7] = [
    ("unit_BBII.obj", "BBII", 1),
    ("unit_BIBI.obj", "BIBI", 1),
    ("unit_BLI.obj", "BLI", 1),
    ("unit_Closed.obj", "CLOSED", 3),
    ("unit_Cross.obj", "CROSS", 2),
    ("unit_Eight.obj", "EIGHT", 3),
    ("unit_LL.obj", "LL", 2),
];

#[test]
fn untangling26_units_have_their_kind_and_pair_count() {
    let Some(shared) = shared() else { return };
    for (file, kind, pairs) in UNITS {
        let m = read_obj(&shared.join("data/untangling26-units").join(file)).unwrap();
        let (_, _, a) = analyse_checked(&[m]);
        assert_eq!(kinds(&a), vec![(kind.to_string(), 1)], "{file}");
        assert_eq!(a.segments.len(), pairs, "{file}");
    }
}

/// As the upstream project runs them: subdivided three times (1-to-4 midpoint), rotated by
/// (-30, 0, -30) degrees and scaled by 0.2. Subdivision puts many vertices exactly on other
/// triangles' planes, so this exercises the tie rule; the world surface is unchanged, so the
/// kind must be too.
#[test]
fn untangling26_units_keep_their_kind_when_subdivided_rotated_and_scaled() {
    let Some(shared) = shared() else { return };
    let (ax, az) = (-30f64.to_radians(), -30f64.to_radians());
    let rx = nalgebra::Rotation3::from_axis_angle(&Vec3::x_axis(), ax);
    let rz = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), az);
    for (file, kind, _) in UNITS {
        let m = read_obj(&shared.join("data/untangling26-units").join(file)).unwrap();
        let mut s = subdivide_n(&m, 3);
        for p in &mut s.positions {
            *p = (rz * rx * *p) * 0.2;
        }
        let (_, _, a) = analyse_checked(&[s]);
        assert_eq!(kinds(&a), vec![(kind.to_string(), 1)], "{file} subdivided");
    }
}

#[test]
fn tshirt_has_six_panels_and_ninety_seam_vertices() {
    let Some(shared) = shared() else { return };
    let m = read_obj(&shared.join("data/arcsim/meshes/tshirt.obj")).unwrap();
    let g = Garment::new(m).unwrap();
    assert_eq!(g.mesh.positions.len(), 330);
    assert_eq!(g.num_panels, 6);
    assert_eq!(g.num_seam_vertices(), 90);
    let expected = [
        ("dress3.obj", 12, 126),
        ("pants3.obj", 4, 59),
        ("jacket.obj", 6, 34),
        ("dress4.obj", 5, 22),
    ];
    for (f, panels, seams) in expected {
        let g =
            Garment::new(read_obj(&shared.join("data/arcsim/meshes").join(f)).unwrap()).unwrap();
        assert_eq!(
            (g.num_panels, g.num_seam_vertices()),
            (panels, seams),
            "{f}"
        );
    }
}

#[test]
fn arcsim_meshes_read_and_analyse() {
    let Some(shared) = shared() else { return };
    let dir = shared.join("data/arcsim/meshes");
    let mut n = 0;
    for f in [
        "tshirt.obj",
        "dress3.obj",
        "pants3.obj",
        "jacket.obj",
        "dress4.obj",
        "sleeve.obj",
        "square.obj",
        "flag.obj",
        "female-objs/body0000.obj",
    ] {
        let m = read_obj(&dir.join(f)).unwrap();
        let (am, pos, a) = analyse_checked(&[m]);
        assert_eq!(a.segments.len(), brute_pairs(&am, &pos).len(), "{f}");
        n += 1;
    }
    assert_eq!(n, 9);
}

/// The Untangling26 CROSS unit resolves with slit ridges (`methods::cha_ko::slit`, on by
/// default) instead of the regionless fallback: its slit's ridge is pulled back across it.
#[test]
fn untangling26_cross_resolves_with_slit_ridges() {
    use untangle::analysis::{analyze, AnalysisMesh};
    use untangle::methods::cha_ko::{Outcome, ResolveParams, Resolver};
    let Some(shared) = shared() else { return };
    let m = read_obj(&shared.join("data/untangling26-units/unit_Cross.obj")).unwrap();
    let g = Garment::new(m).unwrap();
    let p = ResolveParams {
        max_steps: 400,
        ..Default::default()
    };
    let mut r = Resolver::new(&g, p).unwrap();
    let s = r.run(|_| {}).unwrap();
    assert_eq!(s.outcome, Outcome::Resolved, "{s:?}");
    assert!(r.history().iter().any(|h| h.slit_red > 0));
    let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
    assert!(analyze(&am, r.simulator().positions()).unwrap().is_clean());
    assert_eq!(r.chako().current_uv(), r.chako().original_uv());
}

/// The Cha & Ko loop on the third-party units (no `vt`: the BIBI unit's best-fitting plane
/// squashes a triangle to a sliver, so it is unfolded with its own edge lengths): every unit
/// ends intersection-free by an independent analysis with its uv restored; CROSS with the
/// regionless-tanglement fallback (`methods::cha_ko::regionless`, off by default; stuck
/// without it, see docs/cha-ko.md).
#[test]
fn untangling26_units_resolve() {
    use untangle::analysis::{analyze, AnalysisMesh};
    use untangle::methods::cha_ko::{Outcome, ResolveParams, Resolver};
    let Some(shared) = shared() else { return };
    for (file, _, _) in UNITS {
        let m = read_obj(&shared.join("data/untangling26-units").join(file)).unwrap();
        let g = Garment::new(m).unwrap();
        let p = ResolveParams {
            max_steps: 400,
            regionless_after: if file == "unit_Cross.obj" { 30 } else { 0 },
            ..Default::default()
        };
        let mut r = Resolver::new(&g, p).unwrap();
        let s = r.run(|_| {}).unwrap();
        assert_eq!(s.outcome, Outcome::Resolved, "{file}: {s:?}");
        let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
        assert!(
            analyze(&am, r.simulator().positions()).unwrap().is_clean(),
            "{file}"
        );
        assert_eq!(r.chako().current_uv(), r.chako().original_uv(), "{file}");
    }
}

/// The ARCSim pants (refined to >= 2,000 vertices) sagged 25 steps with self-collision off:
/// one leg's inner wall passes into the other leg along two long BLI paths whose loop vertices
/// are interior, so neither Wicke's boundary partition nor his cone gives them a region, and
/// without one the loop ends stuck (docs/cha-ko.md, "BLI"). The generalized winding number
/// (`RegionFinder::winding_region`, on in the loop) finds the wall inside the other leg: both
/// paths get a region, every vertex of it is about 1 away from the garment's typical winding
/// number, and the loop resolves the pants with its uv restored.
#[test]
fn pants_with_a_leg_inside_the_other_resolve_with_winding_regions() {
    use untangle::analysis::{analyze_with, winding, AnalysisMesh, Options, PathKind, Region};
    use untangle::methods::cha_ko::{Outcome, ResolveParams, Resolver};
    use untangle::scenes::sagged;
    let Some(shared) = shared() else { return };
    let mut mesh = read_obj(&shared.join("data/arcsim/meshes/pants3.obj")).unwrap();
    while mesh.positions.len() < 2000 {
        mesh = untangle::mesh::subdivide::subdivide(&mesh);
    }
    let g = Garment::new(mesh.clone()).unwrap();
    let pins = sagged::top_vertices(&mesh, &Vec3::z(), 0.03);
    let tangled = sagged::sagged(&g, sagged::GRAVITY_Z, &pins, 25).unwrap();
    let (am, pos) = AnalysisMesh::single(&tangled).unwrap();
    let opts = |winding_regions| Options {
        bli_regions_red: true,
        winding_regions,
    };
    let without = analyze_with(&am, &pos, &opts(false)).unwrap();
    let with = analyze_with(&am, &pos, &opts(true)).unwrap();
    let bli: Vec<usize> = (0..with.paths.len())
        .filter(|&i| with.paths[i].kind == PathKind::BoundaryLoopInside)
        .collect();
    assert_eq!(bli.len(), 2, "the two BLIs along the inner legs");
    let range = 0..am.triangles.len() as u32;
    let typical = {
        let mut w: Vec<f64> = (0..pos.len() as u32)
            .step_by(97)
            .map(|v| winding::at_vertex(v, &pos, &am.triangles, range.clone()))
            .collect();
        w.sort_by(f64::total_cmp);
        w[w.len() / 2]
    };
    assert!(without.winding_region_paths.is_empty());
    for &i in &bli {
        assert!(with.winding_region_paths.contains(&(i as u32)));
        assert!(!matches!(without.regions[i], Region::Inside(_)));
        let Region::Inside(vs) = &with.regions[i] else {
            panic!("BLI {i} has no winding region");
        };
        assert!(vs.len() > 100, "{}", vs.len());
        for &v in vs {
            let w = winding::at_vertex(v, &pos, &am.triangles, range.clone());
            assert!(
                (w - typical).abs() > 0.5,
                "vertex {v}: {w} against {typical}"
            );
        }
    }
    let tg = Garment::new(tangled).unwrap();
    let mut p = ResolveParams::default();
    p.sim.gravity = sagged::GRAVITY_Z;
    p.max_steps = 400;
    let mut r = Resolver::new(&tg, p).unwrap();
    for &v in &pins {
        r.simulator_mut().set_pinned(v, true).unwrap();
    }
    let s = r.run(|_| {}).unwrap();
    assert_eq!(s.outcome, Outcome::Resolved, "{s:?}");
    assert!(r.history()[0].winding_paths >= 2);
    assert!(
        analyze_with(&am, r.simulator().positions(), &Options::default())
            .unwrap()
            .is_clean()
    );
    assert_eq!(r.chako().current_uv(), r.chako().original_uv());
}
