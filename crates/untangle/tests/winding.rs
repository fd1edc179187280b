//! Generalized winding numbers (`analysis::winding`) against independent oracles, and the
//! winding regions of the analysis (`RegionFinder::winding_region`) against the geometry of a
//! scene whose inside is known exactly.

mod common;

use common::*;
use rand::{Rng, SeedableRng};
use untangle::analysis::winding::{at_vertex, solid_angle, Tree};
use untangle::analysis::{analyze_with, AnalysisMesh, ObjectKind, Options, Region};
use untangle::geom::Vec3;
use untangle::implicit::shapes::sphere_mesh;
use untangle::mesh::Mesh;

/// The solid angle of a triangle by L'Huilier's theorem (the spherical excess of the corners'
/// projections on the unit sphere around `p`), signed by the orientation: an independent oracle
/// for `solid_angle` (which uses Van Oosterom and Strackee's formula).
fn lhuilier(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    let (a, b, c) = (
        (a - p).normalize(),
        (b - p).normalize(),
        (c - p).normalize(),
    );
    let side = |u: &Vec3, v: &Vec3| u.dot(v).clamp(-1.0, 1.0).acos();
    let (x, y, z) = (side(&b, &c), side(&c, &a), side(&a, &b));
    let s = (x + y + z) / 2.0;
    let t = (s / 2.0).tan() * ((s - x) / 2.0).tan() * ((s - y) / 2.0).tan() * ((s - z) / 2.0).tan();
    let excess = 4.0 * t.max(0.0).sqrt().atan();
    excess * a.dot(&b.cross(&c)).signum()
}

/// A point with coordinates uniform in `[-h, h)`.
fn random_point(rng: &mut impl Rng, h: f64) -> Vec3 {
    Vec3::new(
        rng.random_range(-h..h),
        rng.random_range(-h..h),
        rng.random_range(-h..h),
    )
}

#[test]
fn solid_angles_match_lhuilier_on_random_triangles() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for _ in 0..2000 {
        let mut r = || random_point(&mut rng, 1.0);
        let (p, a, b, c) = (r(), r(), r(), r());
        let got = solid_angle(&p, &a, &b, &c);
        let want = lhuilier(&p, &a, &b, &c);
        assert!((got - want).abs() < 1e-7, "{got} vs {want}");
        // Reversing the orientation flips the sign.
        assert!((solid_angle(&p, &a, &c, &b) + got).abs() < 1e-12);
    }
    // A corner sees nothing.
    let (a, b, c) = (Vec3::zeros(), Vec3::x(), Vec3::y());
    assert_eq!(solid_angle(&a, &a, &b, &c), 0.0);
}

#[test]
fn closed_sphere_has_winding_one_inside_zero_outside_and_a_half_on_it() {
    let m = sphere_mesh("s", &Vec3::zeros(), 1.0, 24);
    let n = m.positions.len() as u32;
    let tris = m.triangles.clone();
    let total = 0..tris.len() as u32;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    // Extra points appended after the sphere's vertices (no triangle refers to them).
    let mut pos = m.positions.clone();
    let mut expected = Vec::new();
    for _ in 0..200 {
        let d = random_point(&mut rng, 1.0);
        let r = rng.random_range(0.0..2.0);
        if d.norm() < 1e-3 || (0.95..1.05).contains(&r) {
            continue;
        }
        pos.push(d.normalize() * r);
        expected.push(if r < 1.0 { 1.0 } else { 0.0 });
    }
    for (k, e) in expected.iter().enumerate() {
        let w = at_vertex(n + k as u32, &pos, &tris, total.clone());
        assert!((w - e).abs() < 1e-9, "point {k}: {w}, expected {e}");
    }
    for v in 0..n {
        let w = at_vertex(v, &pos, &tris, total.clone());
        assert!((w - 0.5).abs() < 0.05, "vertex {v}: {w}");
    }
    // The opposite orientation negates every value.
    let flipped: Vec<[u32; 3]> = tris.iter().map(|t| [t[0], t[2], t[1]]).collect();
    for v in (0..n).step_by(37) {
        let (w, f) = (
            at_vertex(v, &pos, &tris, total.clone()),
            at_vertex(v, &pos, &flipped, total.clone()),
        );
        assert!((w + f).abs() < 1e-12);
    }
}

/// The hierarchy's batch evaluation (what the analysis calls) gives the same bits with one and
/// two threads.
#[test]
fn winding_numbers_do_not_depend_on_the_threads() {
    let m = sphere_mesh("s", &Vec3::zeros(), 1.0, 16);
    let vs: Vec<u32> = (0..m.positions.len() as u32).collect();
    let tree = Tree::new(&m.positions, &m.triangles, 0..m.triangles.len() as u32);
    let one = with_threads(1, || tree.at_vertices(&vs, &m.positions, &m.triangles));
    let two = with_threads(2, || tree.at_vertices(&vs, &m.positions, &m.triangles));
    assert_eq!(
        one.iter().map(|w| w.to_bits()).collect::<Vec<_>>(),
        two.iter().map(|w| w.to_bits()).collect::<Vec<_>>()
    );
}

/// Two long open tubes (`scenes::garment::overlapping_tubes`: radius 1, length 8, axes along z
/// at x = -d and x = +d, d < 1) in one mesh: each tube's wall between the two intersection lines
/// lies inside the other tube. Neither line separates a tube (no Wicke region); the winding
/// regions must be exactly the vertices inside the other tube, away from the open ends (where an
/// open tube's winding number fades).
fn overlapping_tubes(d: f64) -> (Mesh, f64) {
    let scene = untangle::scenes::garment::overlapping_tubes(48, d);
    (scene.meshes[0].clone(), 8.0)
}

#[test]
fn winding_regions_of_overlapping_tubes_are_the_walls_inside_the_other_tube() {
    for d in [0.8, 0.9] {
        let (m, h) = overlapping_tubes(d);
        let n = m.positions.len() / 2;
        let (am, pos) = AnalysisMesh::single(&m).unwrap();
        let with = Options {
            winding_regions: true,
            ..Default::default()
        };
        let a = analyze_with(&am, &pos, &with).unwrap();
        let plain = analyze_with(&am, &pos, &Options::default()).unwrap();
        assert_eq!(
            kinds(&a),
            vec![("BIBI".to_string(), 2)],
            "the scene's known kinds"
        );
        // Without the option no path has a region; with it, the regions are winding regions.
        assert!(plain
            .regions
            .iter()
            .all(|r| !matches!(r, Region::Inside(_))));
        assert!(plain.winding_region_paths.is_empty());
        let with_region: Vec<u32> = (0..a.regions.len() as u32)
            .filter(|&i| matches!(a.regions[i as usize], Region::Inside(_)))
            .collect();
        assert_eq!(a.winding_region_paths, with_region);
        let mut inside: Vec<u32> = a
            .regions
            .iter()
            .filter_map(|r| match r {
                Region::Inside(vs) => Some(vs.clone()),
                _ => None,
            })
            .flatten()
            .collect();
        inside.sort_unstable();
        inside.dedup();
        assert!(!inside.is_empty(), "d = {d}: no winding region");
        // The oracle: strictly inside the other tube's cylinder.
        let in_other = |v: usize| {
            let p = pos[v];
            let cx = if v < n { d } else { -d };
            ((p.x - cx).powi(2) + p.y.powi(2)).sqrt() < 1.0
        };
        let middle = |v: usize| pos[v].z.abs() < h / 2.0 - 1.5;
        for &v in &inside {
            assert!(
                in_other(v as usize),
                "d = {d}: vertex {v} is outside the other tube"
            );
        }
        for v in (0..pos.len()).filter(|&v| middle(v) && in_other(v)) {
            assert!(
                inside.binary_search(&(v as u32)).is_ok(),
                "d = {d}: vertex {v} inside the other tube is not in a region"
            );
        }
        // Every vertex in a region is red.
        assert!(inside.iter().all(|&v| a.coloring.red_vertex[v as usize]));
    }
}

#[test]
fn sheets_get_no_winding_region() {
    use untangle::scenes::{exploded, rudimentary};
    let with = Options {
        bli_regions_red: true,
        winding_regions: true,
    };
    let without = Options {
        bli_regions_red: true,
        winding_regions: false,
    };
    let mut scenes: Vec<_> = (1..=4).map(|s| exploded::exploded(s, 14)).collect();
    for levels in [2, 3] {
        scenes.push(rudimentary::bli_interior(levels));
        scenes.push(rudimentary::cross(levels));
        scenes.push(rudimentary::loop_loop(levels));
    }
    scenes.push(untangle::scenes::closed(12));
    for sc in &scenes {
        let parts: Vec<_> = sc.meshes.iter().map(|m| (m, ObjectKind::Cloth)).collect();
        let (am, pos) = AnalysisMesh::new(&parts).unwrap();
        let a = analyze_with(&am, &pos, &with).unwrap();
        let b = analyze_with(&am, &pos, &without).unwrap();
        assert!(!a.paths.is_empty(), "{}", sc.name);
        assert_eq!(a.regions, b.regions, "{}", sc.name);
        assert_eq!(a.coloring.red_vertex, b.coloring.red_vertex, "{}", sc.name);
    }
}

/// The fast hierarchy (Barill et al. 2018, first order, beta = 4) against the triangle-by-
/// triangle sum: on the overlapping tubes' vertices (on the surface, inside the other tube, near
/// the open ends), a sphere with points inside and out, and a random soup, within 0.04 (well
/// inside the regions' thresholds of 0.4-0.6; `winding_bench` prints the measured largest
/// difference).
#[test]
fn tree_matches_the_direct_sum() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (tubes, _) = overlapping_tubes(0.85);
    let mut sphere = sphere_mesh("s", &Vec3::zeros(), 1.0, 20);
    for _ in 0..100 {
        sphere.positions.push(random_point(&mut rng, 2.0));
    }
    let mut soup_pos = Vec::new();
    let mut soup_tris = Vec::new();
    for k in 0..600u32 {
        let c = random_point(&mut rng, 1.0);
        for _ in 0..3 {
            soup_pos.push(c + 0.1 * random_point(&mut rng, 1.0));
        }
        soup_tris.push([3 * k, 3 * k + 1, 3 * k + 2]);
    }
    let cases = [
        (tubes.positions.clone(), tubes.triangles.clone()),
        (sphere.positions.clone(), sphere.triangles.clone()),
        (soup_pos, soup_tris),
    ];
    for (pos, tris) in &cases {
        let range = 0..tris.len() as u32;
        let tree = Tree::new(pos, tris, range.clone());
        let mut worst: f64 = 0.0;
        for v in 0..pos.len() as u32 {
            let direct = at_vertex(v, pos, tris, range.clone());
            worst = worst.max((tree.at_vertex(v, pos, tris) - direct).abs());
        }
        assert!(worst < 0.04, "largest difference {worst}");
    }
}
