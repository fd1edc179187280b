//! Tests of [`super::ccd`]: hand-made degenerate cases, exactly constructed contacts and
//! sampled-distance oracles on random trajectories.

use super::*;

fn v(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, y, z)
}

/// Unit right triangle in the plane z = 0.
fn tri() -> [Vec3; 3] {
    [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]
}

fn vt(p0: Vec3, p1: Vec3, t0: [Vec3; 3], t1: [Vec3; 3], h: f64) -> Option<f64> {
    vertex_triangle_ccd(&[p0, t0[0], t0[1], t0[2]], &[p1, t1[0], t1[1], t1[2]], h)
}

fn ee(a0: [Vec3; 2], b0: [Vec3; 2], a1: [Vec3; 2], b1: [Vec3; 2], h: f64) -> Option<f64> {
    edge_edge_ccd(
        &[a0[0], a0[1], b0[0], b0[1]],
        &[a1[0], a1[1], b1[0], b1[1]],
        h,
    )
}

/// A conservative answer close to the expected one (within the default tolerance).
fn near(got: Option<f64>, want: f64) {
    near_within(got, want, 1e-5);
}

/// A conservative answer at most `band` earlier than the expected one.
fn near_within(got: Option<f64>, want: f64, band: f64) {
    let t = got.unwrap_or_else(|| panic!("expected a hit at {want}"));
    assert!(t <= want && t >= want - band, "toi {t}, expected {want}");
}

#[test]
fn vertex_through_face() {
    let t = tri();
    near(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, -1.0), t, t, 0.0), 0.5);
    // Passing beside the triangle.
    assert_eq!(vt(v(0.8, 0.8, 1.0), v(0.8, 0.8, -1.0), t, t, 0.0), None);
    // Face moving onto a static vertex.
    let up = t.map(|p| p + v(0.0, 0.0, 1.0));
    near(vt(v(0.1, 0.1, 0.25), v(0.1, 0.1, 0.25), t, up, 0.0), 0.25);
}

#[test]
fn vertex_on_face_at_start_and_end() {
    let t = tri();
    near(vt(v(0.2, 0.2, 0.0), v(0.2, 0.2, 1.0), t, t, 0.0), 0.0);
    near(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.0), t, t, 0.0), 1.0);
    // On an edge and on a corner at t = 1.
    near(vt(v(0.5, 0.0, 1.0), v(0.5, 0.0, 0.0), t, t, 0.0), 1.0);
    near(vt(v(1.0, 0.0, 1.0), v(1.0, 0.0, 0.0), t, t, 0.0), 1.0);
    // Stopping just short of the face.
    assert_eq!(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 1e-3), t, t, 0.0), None);
}

#[test]
fn vertex_sliding_in_face_plane() {
    let t = tri();
    // Entering the triangle from outside, in its plane: first contact on edge x = 0 at 0.5.
    near(vt(v(-1.0, 0.3, 0.0), v(1.0, 0.3, 0.0), t, t, 0.0), 0.5);
    // Sliding in the plane but beside the triangle.
    assert_eq!(vt(v(-1.0, 2.0, 0.0), v(2.0, 2.0, 0.0), t, t, 0.0), None);
    // Sliding inside the triangle all the time.
    near(vt(v(0.1, 0.1, 0.0), v(0.3, 0.1, 0.0), t, t, 0.0), 0.0);
}

#[test]
fn zero_motion() {
    let t = tri();
    near(vt(v(0.2, 0.2, 0.0), v(0.2, 0.2, 0.0), t, t, 0.0), 0.0);
    assert_eq!(vt(v(0.2, 0.2, 0.5), v(0.2, 0.2, 0.5), t, t, 0.0), None);
    let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let b = [v(0.5, -1.0, 0.5), v(0.5, 1.0, 0.5)];
    assert_eq!(ee(a, b, a, b, 0.0), None);
    near(ee(a, b, a, b, 0.5), 0.0);
}

#[test]
fn thickness_exactly_reached() {
    let t = tri();
    // The vertex stops at distance exactly 0.25 = thickness at t = 1, approaching at speed 0.75.
    // With the default thickness tolerance (1e-3) the answer may be earlier by the time it takes
    // to cover 0.25e-3, i.e. 3.3e-4.
    near_within(
        vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.25), t, t, 0.25),
        1.0,
        3.4e-4,
    );
    assert_eq!(vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.25), t, t, 0.2), None);
    // Reaches 0.5 at t = 0.5 (from 1 down to 0, speed 1).
    near_within(
        vt(v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.0), t, t, 0.5),
        0.5,
        5.1e-4,
    );
    let exact = CcdOptions {
        thickness_tolerance: 0.0,
        ..CcdOptions::default()
    };
    let x0 = [v(0.2, 0.2, 1.0), t[0], t[1], t[2]];
    let x1 = [v(0.2, 0.2, 0.25), t[0], t[1], t[2]];
    let toi = vertex_triangle_impact(&x0, &x1, 0.25, &exact).map(|i| i.toi);
    near(toi, 1.0);
    // Passing beside the corner: the closest approach to corner (1,0,0) is exactly 0.5, a
    // tangential contact. The distance is within thickness (1 + 1e-3) of the corner from
    // t = 0.5 - sqrt(0.5005^2 - 0.25) / 2 ~ 0.4888 on, so the answer may be that early.
    let toi = vt(v(1.5, -1.0, 0.0), v(1.5, 1.0, 0.0), t, t, 0.5).unwrap();
    assert!((0.4888..=0.5).contains(&toi), "{toi}");
    let x0 = [v(1.5, -1.0, 0.0), t[0], t[1], t[2]];
    let x1 = [v(1.5, 1.0, 0.0), t[0], t[1], t[2]];
    let toi = vertex_triangle_impact(&x0, &x1, 0.5, &exact).unwrap().toi;
    assert!((0.499..=0.5).contains(&toi), "{toi}");
    assert_eq!(vt(v(1.5, -1.0, 0.0), v(1.5, 1.0, 0.0), t, t, 0.49), None);
    // Beside a corner diagonally: the Euclidean (not max-norm) distance decides.
    let p = v(1.0 + 0.3, -0.3, 0.3); // distance 0.3 sqrt(3) ~ 0.52 from (1, 0, 0)
    assert_eq!(vt(p, p, t, t, 0.5), None);
    near(vt(p, p, t, t, 0.53), 0.0);
    // Edge-edge: crossing edges separated by exactly the thickness.
    let a = [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let b = [v(0.0, -1.0, 0.75), v(0.0, 1.0, 0.75)];
    near(ee(a, b, a, b, 0.75), 0.0);
    assert_eq!(ee(a, b, a, b, 0.74), None);
}

#[test]
fn toi_exactly_zero_and_one() {
    let a = [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let b0 = [v(0.0, -1.0, 0.0), v(0.0, 1.0, 0.0)];
    let b1 = [v(0.0, -1.0, 1.0), v(0.0, 1.0, 1.0)];
    near(ee(a, b0, a, b1, 0.0), 0.0);
    near(ee(a, b1, a, b0, 0.0), 1.0);
    assert_eq!(ee(a, b1, a, b1, 0.0), None);
}

#[test]
fn parallel_edges() {
    // Coplanar parallel edges approaching each other sideways: touch at t = 0.5.
    let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let b0 = [v(0.5, 1.0, 0.0), v(1.5, 1.0, 0.0)];
    let b1 = [v(0.5, -1.0, 0.0), v(1.5, -1.0, 0.0)];
    near(ee(a, b0, a, b1, 0.0), 0.5);
    // Same but without overlap along the edge direction.
    let c0 = [v(1.5, 1.0, 0.0), v(2.5, 1.0, 0.0)];
    let c1 = [v(1.5, -1.0, 0.0), v(2.5, -1.0, 0.0)];
    assert_eq!(ee(a, c0, a, c1, 0.0), None);
    // Collinear, overlapping and sliding along each other.
    let d0 = [v(0.5, 0.0, 0.0), v(1.5, 0.0, 0.0)];
    let d1 = [v(2.5, 0.0, 0.0), v(3.5, 0.0, 0.0)];
    near(ee(a, d0, a, d1, 0.0), 0.0);
    // Collinear, sliding towards each other: endpoints meet at t = 0.5.
    let e0 = [v(2.0, 0.0, 0.0), v(3.0, 0.0, 0.0)];
    let e1 = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    near(ee(a, e0, a, e1, 0.0), 0.5);
    // Parallel at a fixed offset 1e-3 out of plane, sliding: never touch.
    let f0 = [v(0.5, 0.0, 1e-3), v(1.5, 0.0, 1e-3)];
    let f1 = [v(-0.5, 0.0, 1e-3), v(0.5, 0.0, 1e-3)];
    assert_eq!(ee(a, f0, a, f1, 0.0), None);
    near(ee(a, f0, a, f1, 1e-3), 0.0);
}

#[test]
fn edges_touch_at_endpoint() {
    let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    // Endpoint of b reaches endpoint of a at t = 1.
    let b0 = [v(1.0, 0.0, 1.0), v(1.0, 1.0, 1.0)];
    let b1 = [v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0)];
    near(ee(a, b0, a, b1, 0.0), 1.0);
    // Shifted by a hair: never touch.
    let s = v(1e-9, 0.0, 0.0);
    assert_eq!(ee(a, b0.map(|p| p + s), a, b1.map(|p| p + s), 0.0), None);
    // Shared endpoint from the start.
    let c = [v(1.0, 0.0, 0.0), v(2.0, 1.0, 0.0)];
    near(ee(a, c, a, c, 0.0), 0.0);
}

#[test]
fn degenerate_primitives() {
    // A triangle collapsed to a segment and an edge collapsed to a point.
    let flat = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0)];
    near(
        vt(v(0.5, 0.0, 1.0), v(0.5, 0.0, -1.0), flat, flat, 0.0),
        0.5,
    );
    let pt = [v(0.0, 0.0, 1.0), v(0.0, 0.0, 1.0)];
    let seg = [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let pt1 = [v(0.0, 0.0, -1.0), v(0.0, 0.0, -1.0)];
    near(ee(pt, seg, pt1, seg, 0.0), 0.5);
}

#[test]
fn invalid_input_is_conservative() {
    let t = tri();
    let p = v(5.0, 5.0, 5.0);
    assert_eq!(vt(v(f64::NAN, 0.0, 0.0), p, t, t, 0.0), Some(0.0));
    assert_eq!(vt(p, v(f64::INFINITY, 0.0, 0.0), t, t, 0.0), Some(0.0));
    assert_eq!(vt(p, p, t, t, f64::NAN), Some(0.0));
    assert_eq!(vt(p, p, t, t, -1.0), None); // negative thickness acts as zero
                                            // Huge but finite coordinates are still handled exactly.
    let s = 1e250;
    let big = t.map(|q| q * s);
    near(
        vt(v(0.2, 0.2, 1.0) * s, v(0.2, 0.2, -1.0) * s, big, big, 0.0),
        0.5,
    );
}

#[test]
fn budget_exhaustion_is_conservative() {
    // Parallel edges meeting all along their overlap at t = 0.5: with a budget of a few boxes
    // the search must stop early, unresolved, with an answer no later than 0.5.
    let a = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let x0 = [a[0], a[1], v(0.5, 1.0, 0.0), v(1.5, 1.0, 0.0)];
    let x1 = [a[0], a[1], v(0.5, -1.0, 0.0), v(1.5, -1.0, 0.0)];
    let full = edge_edge_impact(&x0, &x1, 0.0, &CcdOptions::default()).unwrap();
    assert!(
        full.resolved && full.toi <= 0.5 && full.toi > 0.49,
        "{full:?}"
    );
    for max_boxes in 1..full.boxes {
        let o = CcdOptions {
            max_boxes,
            ..CcdOptions::default()
        };
        let cut = edge_edge_impact(&x0, &x1, 0.0, &o).unwrap();
        assert!(
            !cut.resolved && cut.toi <= full.toi && cut.boxes == max_boxes,
            "{cut:?}"
        );
    }
}

#[test]
fn batch_matches_single() {
    let t = tri();
    let q: Vec<([Vec3; 4], [Vec3; 4])> = (0..600)
        .map(|i| {
            let x = i as f64 / 300.0 - 0.5;
            (
                [v(x, 0.2, 1.0), t[0], t[1], t[2]],
                [v(x, 0.2, -1.0), t[0], t[1], t[2]],
            )
        })
        .collect();
    let got = vertex_triangle_ccd_batch(&q, 0.0);
    for (i, (a, b)) in q.iter().enumerate() {
        assert_eq!(got[i], vertex_triangle_ccd(a, b, 0.0));
    }
    assert!(got.iter().any(|g| g.is_some()) && got.iter().any(|g| g.is_none()));
    let e: Vec<([Vec3; 4], [Vec3; 4])> = q
        .iter()
        .map(|(a, b)| {
            (
                [a[0], a[0] + v(0.0, 1.0, 0.0), a[1], a[2]],
                [b[0], b[0] + v(0.0, 1.0, 0.0), b[1], b[2]],
            )
        })
        .collect();
    let got = edge_edge_ccd_batch(&e, 0.0);
    for (i, (a, b)) in e.iter().enumerate() {
        assert_eq!(got[i], edge_edge_ccd(a, b, 0.0));
    }
}

// ---------------------------------------------------------------------------------------------
// Property tests.
//
// Oracle 1 (exact construction): a contact is planted at a dyadic time t* between dyadic
// positions, with dyadic barycentric / edge parameters, so that every coordinate of the query and
// of the positions at t* is exactly representable. The primitives then provably touch (or come
// within a planted offset) at t*, without computing anything with the code under test: the CCD
// must answer `Some(t)` with `t <= t*`.
//
// Oracle 2 (sampled distance): on random trajectories, the distance between the primitives is
// evaluated at 2001 times with the closest-point kernels of `distance.rs` (themselves checked
// against brute-force minimisation). A sample closer than the thickness is a contact the CCD must
// report no later than that sample; when the CCD reports a resolved contact, the distance at the
// reported time must be within the tolerance bound of the module docs.
// ---------------------------------------------------------------------------------------------

use super::super::distance::{point_triangle, segment_segment};
use proptest::prelude::*;

/// A dyadic coordinate `k / 8` with `|k| <= 16`.
fn dy() -> impl Strategy<Value = f64> {
    (-16i32..=16).prop_map(|k| k as f64 / 8.0)
}

fn dy_vec() -> impl Strategy<Value = Vec3> {
    (dy(), dy(), dy()).prop_map(|(x, y, z)| v(x, y, z))
}

/// Moves the configuration `xs` (positions at `t*`) back and forth along displacements `d`:
/// positions at 0 and 1 such that linear interpolation passes through `xs` at `t*` exactly.
fn trajectory(xs: [Vec3; 4], d: [Vec3; 4], ts: f64) -> ([Vec3; 4], [Vec3; 4]) {
    let x0 = [0, 1, 2, 3].map(|i| xs[i] - d[i] * ts);
    let x1 = [0, 1, 2, 3].map(|i| xs[i] + d[i] * (1.0 - ts));
    for i in 0..4 {
        // The construction is exact: re-interpolating gives back xs bit for bit.
        assert_eq!(x0[i] + (x1[i] - x0[i]) * ts, xs[i]);
    }
    (x0, x1)
}

fn position_at(x0: &[Vec3; 4], x1: &[Vec3; 4], t: f64) -> [Vec3; 4] {
    [0, 1, 2, 3].map(|i| x0[i] + (x1[i] - x0[i]) * t)
}

fn vt_distance(x: &[Vec3; 4]) -> f64 {
    point_triangle(&x[0], &x[1], &x[2], &x[3]).0.sqrt()
}

fn ee_distance(x: &[Vec3; 4]) -> f64 {
    segment_segment(&x[0], &x[1], &x[2], &x[3]).0.sqrt()
}

/// Checks a CCD answer against densely sampled distances (oracle 2).
fn check_sampled(
    x0: &[Vec3; 4],
    x1: &[Vec3; 4],
    thickness: f64,
    hit: Option<Impact>,
    distance: fn(&[Vec3; 4]) -> f64,
) -> Result<(), TestCaseError> {
    let n = 2000;
    let scale = (0..4)
        .flat_map(|i| (0..4).flat_map(move |j| [(x0[i] - x0[j]).amax(), (x1[i] - x1[j]).amax()]))
        .fold(0.0, f64::max);
    let slack = 1e-12 * (1.0 + scale);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let d = distance(&position_at(x0, x1, t));
        if d <= thickness - slack {
            let Some(h) = hit else {
                return Err(TestCaseError::fail(format!(
                    "missed contact: distance {d} at t = {t}"
                )));
            };
            prop_assert!(
                h.toi <= t,
                "toi {} later than sampled contact at {t} (distance {d})",
                h.toi
            );
            break;
        }
    }
    if let Some(h) = hit {
        prop_assert!((0.0..=1.0).contains(&h.toi) && h.toi <= h.toi_upper);
        if h.resolved {
            // At the reported time the primitives are within sqrt(3) (thickness + tol); the
            // tolerance scale used by the search is at most `scale` (largest corner magnitude).
            let d = distance(&position_at(x0, x1, h.toi));
            let o = CcdOptions::default();
            let bound = 3f64.sqrt()
                * (thickness * (1.0 + o.thickness_tolerance) + o.tolerance * scale)
                + slack;
            prop_assert!(d <= bound, "distance {d} at toi {} exceeds {bound}", h.toi);
        }
    }
    Ok(())
}

/// Random coordinates mixing a small integer grid (degenerate configurations) and reals.
fn coord() -> impl Strategy<Value = f64> {
    prop_oneof![(-2i32..=2).prop_map(|k| k as f64 * 0.5), -1.0..1.0f64]
}

fn point() -> impl Strategy<Value = Vec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| v(x, y, z))
}

fn quad() -> impl Strategy<Value = [Vec3; 4]> {
    [point(), point(), point(), point()]
}

fn thickness() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), Just(0.0), 0.0..0.3f64, Just(0.125)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Oracle 1, vertex-triangle: exact contact (thickness 0) or planted offset `o` with
    /// thickness >= |o| at t* = k/16.
    #[test]
    fn planted_vertex_triangle_contact(
        tri in [dy_vec(), dy_vec(), dy_vec()],
        (i, j) in (0i32..=8).prop_flat_map(|i| (Just(i), 0..=8 - i)),
        d in [dy_vec(), dy_vec(), dy_vec(), dy_vec()],
        k in 0i32..=16,
        offset in prop_oneof![Just(v(0.0, 0.0, 0.0)), dy_vec().prop_map(|o| o * 0.125), Just(v(0.0, 0.0, 0.25))],
    ) {
        let (u, w) = (i as f64 / 8.0, j as f64 / 8.0);
        let q = tri[0] * (1.0 - u - w) + tri[1] * u + tri[2] * w; // exact: dyadic with few bits
        let p = q + offset;
        // |offset| rounded up (an axis-aligned offset gives exactly the thickness).
        let h = offset.norm() * (1.0 + f64::powi(2.0, -50));
        let h = if offset.x == 0.0 && offset.y == 0.0 { offset.z.abs() } else { h };
        let ts = k as f64 / 16.0;
        let (x0, x1) = trajectory([p, tri[0], tri[1], tri[2]], d, ts);
        let hit = vertex_triangle_impact(&x0, &x1, h, &CcdOptions::default());
        prop_assert!(hit.is_some_and(|h| h.toi <= ts), "missed planted contact at {ts}: {hit:?}");
        check_sampled(&x0, &x1, h, hit, vt_distance)?;
    }

    /// Oracle 1, edge-edge: the edges cross (or pass at the planted offset) at t* = k/16.
    #[test]
    fn planted_edge_edge_contact(
        x in dy_vec(),
        (fa, fb) in (dy_vec(), dy_vec()),
        (sa, sb) in (0i32..=8, 0i32..=8),
        d in [dy_vec(), dy_vec(), dy_vec(), dy_vec()],
        k in 0i32..=16,
        offset in prop_oneof![Just(v(0.0, 0.0, 0.0)), dy_vec().prop_map(|o| o * 0.125), Just(v(0.5, 0.0, 0.0))],
    ) {
        let (s, w) = (sa as f64 / 8.0, sb as f64 / 8.0);
        let y = x + offset;
        let xs = [x - fa * s, x + fa * (1.0 - s), y - fb * w, y + fb * (1.0 - w)];
        let h = offset.norm() * (1.0 + f64::powi(2.0, -50));
        let h = if offset.y == 0.0 && offset.z == 0.0 { offset.x.abs() } else { h };
        let ts = k as f64 / 16.0;
        let (x0, x1) = trajectory(xs, d, ts);
        let hit = edge_edge_impact(&x0, &x1, h, &CcdOptions::default());
        prop_assert!(hit.is_some_and(|h| h.toi <= ts), "missed planted contact at {ts}: {hit:?}");
        check_sampled(&x0, &x1, h, hit, ee_distance)?;
    }

    /// Oracle 2 on random trajectories, vertex-triangle.
    #[test]
    fn random_vertex_triangle_vs_sampling(x0 in quad(), x1 in quad(), h in thickness()) {
        let hit = vertex_triangle_impact(&x0, &x1, h, &CcdOptions::default());
        check_sampled(&x0, &x1, h, hit, vt_distance)?;
    }

    /// Oracle 2 on random trajectories, edge-edge.
    #[test]
    fn random_edge_edge_vs_sampling(x0 in quad(), x1 in quad(), h in thickness()) {
        let hit = edge_edge_impact(&x0, &x1, h, &CcdOptions::default());
        check_sampled(&x0, &x1, h, hit, ee_distance)?;
    }

    /// Scaling every coordinate and the thickness by a power of two is exact, and the search only
    /// compares and averages, so the answer must not change at all.
    #[test]
    fn invariant_under_power_of_two_scaling(x0 in quad(), x1 in quad(), h in thickness(), e in -30i32..30) {
        let s = f64::powi(2.0, e);
        let a = vertex_triangle_impact(&x0, &x1, h, &CcdOptions::default()).map(|i| i.toi);
        let b = vertex_triangle_impact(&x0.map(|p| p * s), &x1.map(|p| p * s), h * s, &CcdOptions::default()).map(|i| i.toi);
        prop_assert_eq!(a, b);
    }
}
