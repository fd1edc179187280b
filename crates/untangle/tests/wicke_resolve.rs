//! Wicke et al. 2006, Sec. 5 (`methods::wicke`): correspondences, boundary distances, forces and
//! the whole loop, each against an independent check.

mod common;

use proptest::prelude::*;
use untangle::analysis::{analyze, AnalysisMesh, Region};
use untangle::geom::Vec3;
use untangle::mesh::{Garment, Mesh};
use untangle::methods::wicke::correspondence::{path_samples, uv_point, UvLocator};
use untangle::methods::wicke::forces::{boundary_distance, ForceContext};
use untangle::methods::wicke::{ForceParams, WickeOutcome, WickeParams, WickeResolver};

fn scene_garment(name: &str) -> Garment {
    let s = untangle::scenes::by_name(name, None, 1).unwrap();
    Garment::new(AnalysisMesh::merge_cloth(&s.meshes).unwrap()).unwrap()
}

/// The exploded handkerchief of `seed` at the paper's size (14 x 14 cells) as a garment.
fn exploded_garment(seed: u64) -> Garment {
    let s = untangle::scenes::exploded::exploded(seed, 14);
    Garment::new(s.meshes[0].clone()).unwrap()
}

fn world(am: &AnalysisMesh, pos: &[Vec3], t: u32, b: &[f64; 3]) -> Vec3 {
    let c = am.triangles[t as usize];
    (0..3).fold(Vec3::zeros(), |s, k| s + pos[c[k] as usize] * b[k])
}

/// A path sample is one world point seen from two triangles: both barycentric readings give the
/// same point, and it lies on the segment's line (checked against the crossing geometry of the
/// analysis through an independent route: both triangles' planes contain it).
#[test]
fn samples_are_the_same_world_point_in_both_triangles() {
    for name in ["closed", "ll", "bbii", "bibi", "eight", "cross"] {
        let g = scene_garment(name);
        let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
        let a = analyze(&am, &pos).unwrap();
        assert!(!a.paths.is_empty(), "{name}");
        for p in &a.paths {
            for s in path_samples(&am, &pos, &a, p) {
                let x = world(&am, &pos, s.here_triangle, &s.here);
                let y = world(&am, &pos, s.there_triangle, &s.there);
                assert!((x - y).norm() < 1e-9, "{name}: {x:?} vs {y:?}");
                for t in [s.here_triangle, s.there_triangle] {
                    let c = am.triangles[t as usize].map(|v| pos[v as usize]);
                    let n = (c[1] - c[0]).cross(&(c[2] - c[0]));
                    assert!(n.normalize().dot(&(x - c[0])).abs() < 1e-9, "{name}");
                }
                assert!(s.length > 0.0);
            }
        }
    }
}

/// Point location: the located triangle and coordinates give back the query point when it is
/// inside the panel, else a point of the panel no farther than any triangle corner.
#[test]
fn uv_locator_finds_the_containing_triangle() {
    let g = scene_garment("closed");
    let loc = UvLocator::new(&g);
    let uv = g.mesh.uv.as_ref().unwrap();
    for (t, tri) in uv.triangles.iter().enumerate() {
        let c =
            (uv.coords[tri[0] as usize] + uv.coords[tri[1] as usize] + uv.coords[tri[2] as usize])
                / 3.0;
        let panel = g.panel_of_triangle[t];
        let (found, b) = loc.locate(&c, panel).unwrap();
        assert_eq!(g.panel_of_triangle[found as usize], panel);
        assert!((uv_point(&g, found, &b) - c).norm() < 1e-12);
    }
    // Far outside: the nearest point of the panel.
    let far = uv.coords.iter().fold(uv.coords[0], |m, c| m.sup(c)) * 3.0
        + untangle::geom::Vec2::new(1.0, 1.0);
    let (t, b) = loc.locate(&far, 0).unwrap();
    let q = uv_point(&g, t, &b);
    for (k, c) in uv.coords.iter().enumerate() {
        if g.panel_of_uv[k] == 0 {
            assert!((q - far).norm() <= (c - far).norm() + 1e-12);
        }
    }
}

/// Random sheets with holes cut out: Dijkstra distances to the boundary against an independent
/// Bellman-Ford relaxation over the same rest edge lengths.
fn grid_with_holes(n: usize, holes: &[(usize, usize)], jitter: &[f64]) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let k = j * (n + 1) + i;
            positions.push(Vec3::new(
                i as f64 + 0.3 * jitter[k % jitter.len()],
                j as f64 + 0.3 * jitter[(k * 7 + 3) % jitter.len()],
                0.0,
            ));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            if holes.contains(&(i, j)) {
                continue;
            }
            let v = |a: usize, b: usize| (b * (n + 1) + a) as u32;
            triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    Mesh {
        name: "grid".into(),
        positions,
        triangles,
        ..Default::default()
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn boundary_distance_matches_bellman_ford(
        n in 3usize..9,
        holes in prop::collection::vec((1usize..8, 1usize..8), 0..3),
        jitter in prop::collection::vec(-1.0f64..1.0, 7..20),
    ) {
        let holes: Vec<(usize, usize)> = holes.into_iter().filter(|&(i, j)| i + 1 < n && j + 1 < n).collect();
        let m = grid_with_holes(n, &holes, &jitter);
        let Ok(g) = Garment::new(m) else { return Ok(()); };
        let d = boundary_distance(&g);
        let uv = g.mesh.uv.as_ref().unwrap();
        // Oracle: relax every triangle edge (uv length) until nothing changes.
        let nv = g.mesh.positions.len();
        let mut o = vec![f64::INFINITY; nv];
        for e in 0..g.topology.num_edges() {
            if g.topology.is_boundary_edge(e as u32) {
                for &v in &g.topology.edges[e] {
                    o[v as usize] = 0.0;
                }
            }
        }
        loop {
            let mut changed = false;
            for (t, tri) in g.mesh.triangles.iter().enumerate() {
                for k in 0..3 {
                    let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
                    let ut = uv.triangles[t];
                    let l = (uv.coords[ut[k] as usize] - uv.coords[ut[(k + 1) % 3] as usize]).norm();
                    for (x, y) in [(a, b), (b, a)] {
                        if o[x] + l < o[y] - 1e-12 {
                            o[y] = o[x] + l;
                            changed = true;
                        }
                    }
                }
            }
            if !changed {
                break;
            }
        }
        // Vertices off every triangle keep infinity in both.
        for v in 0..nv {
            if o[v].is_finite() || d[v].is_finite() {
                prop_assert!((d[v] - o[v]).abs() < 1e-9, "vertex {v}: {} vs {}", d[v], o[v]);
            }
        }
    }
}

/// The forces of the CLOSED case: the free set is inside regions plus intersecting corners,
/// and every inside vertex of both sheets is pushed toward
/// the other sheet (its target lies on a triangle of the other sheet, and the force points
/// across the sheet it penetrates); with symmetric forces the total force is zero.
#[test]
fn closed_case_forces_pull_each_inside_vertex_to_the_other_sheet() {
    let g = scene_garment("closed");
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let ctx = ForceContext::new(&g, &am);
    let mass = vec![1.0; pos.len()];
    let (acc, free, rep) = ctx.accelerations(&a, &pos, &mass, &ForceParams::default());
    assert!(rep.inside_points > 0 && rep.unhandled_paths == 0, "{rep:?}");
    let mut inside = Vec::new();
    for r in &a.regions {
        if let Region::Inside(vs) = r {
            inside.extend(vs.iter().copied());
        }
    }
    assert!(!inside.is_empty());
    for &v in &inside {
        assert!(acc[v as usize].norm() > 0.0, "vertex {v} has no force");
    }
    // The free set is exactly Sec. 5.2's: inside vertices and the corners of intersecting
    // triangles (whatever the forces did).
    let mut want = vec![false; pos.len()];
    for &v in &inside {
        want[v as usize] = true;
    }
    for t in a.intersecting_triangles() {
        for v in am.triangles[t as usize] {
            want[v as usize] = true;
        }
    }
    assert_eq!(free, want);
    assert_eq!(rep.free_vertices, want.iter().filter(|&&f| f).count());
    // The dent of sheet B pokes up through sheet A (z ~ 0) and A's inside region is pushed
    // down, B's up: check the sign of z against each vertex's own sheet.
    let n_a = g.mesh.positions.len() / 2;
    for &v in &inside {
        let z = acc[v as usize].z;
        if (v as usize) < n_a {
            assert!(
                z < 0.0 || acc[v as usize].norm() < 1e-9,
                "A vertex {v}: {z}"
            );
        } else {
            assert!(
                z > 0.0 || acc[v as usize].norm() < 1e-9,
                "B vertex {v}: {z}"
            );
        }
    }
    let total = acc.iter().fold(Vec3::zeros(), |s, a| s + a);
    assert!(total.norm() < 1e-9 * acc.iter().map(|a| a.norm()).sum::<f64>().max(1.0));
}

fn resolve(g: &Garment, max_steps: usize) -> (WickeOutcome, usize) {
    let (am, pos0) = AnalysisMesh::single(&g.mesh).unwrap();
    assert!(!analyze(&am, &pos0).unwrap().is_clean());
    let mut p = WickeParams::default();
    p.sim.gravity = Vec3::zeros();
    p.max_steps = max_steps;
    let mut r = WickeResolver::new(g, &am, p).unwrap();
    let o = r.run(|_| {}).unwrap();
    if o == WickeOutcome::Resolved {
        // Independent analysis of the final positions.
        assert!(analyze(&am, r.simulator().positions()).unwrap().is_clean());
        assert!(r.simulator().max_stretch() < 0.5);
    }
    (o, r.history().len())
}

/// All six rudimentary cases of Cha & Ko Fig. 13 resolve (Wicke's method covers every path
/// type with an inside region, and BI/BI through the boundary field).
#[test]
fn rudimentary_cases_resolve() {
    for name in ["closed", "eight", "ll", "cross", "bibi", "bbii"] {
        let (o, steps) = resolve(&scene_garment(name), 200);
        assert_eq!(o, WickeOutcome::Resolved, "{name} after {steps} steps");
    }
}

/// A BI/BI pair has no inside region: no inside point gets a target, and its forces come from
/// the boundary field of Sec. 5.3 alone, on both paths.
#[test]
fn bibi_needs_the_boundary_forces() {
    let g = scene_garment("bibi");
    let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let ctx = ForceContext::new(&g, &am);
    let (acc, _, rep) = ctx.accelerations(&a, &pos, &vec![1.0; pos.len()], &ForceParams::default());
    assert_eq!(rep.inside_points, 0);
    assert_eq!(rep.bi_paths, 2, "{rep:?}");
    assert!(acc.iter().any(|a| a.norm() > 0.0));
}

/// The exploded handkerchief is beyond it (Cha & Ko's motivation): the loop reports a stall or
/// the step limit instead of looping silently, and the pair count drops well below the input's.
#[test]
fn exploded_handkerchief_stops_with_a_reason() {
    let g = exploded_garment(1);
    let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
    let mut p = WickeParams::default();
    p.sim.gravity = Vec3::zeros();
    p.max_steps = 60;
    p.stuck_steps = 30;
    let mut r = WickeResolver::new(&g, &am, p).unwrap();
    let o = r.run(|_| {}).unwrap();
    let h = r.history();
    let first = h[0].intersecting_pairs;
    let best = h.iter().map(|s| s.intersecting_pairs).min().unwrap();
    assert!(best * 4 < first, "{first} -> {best}");
    // Not resolved, and the reason given is what happened: 30 steps without a new low before
    // the limit (the stall), or the limit itself.
    let last_low = h.iter().position(|s| s.intersecting_pairs == best).unwrap();
    match o {
        WickeOutcome::Stuck => assert_eq!(h.len() - 1 - last_low, 30, "{}", h.len()),
        WickeOutcome::StepLimit => assert_eq!(h.len(), 60),
        WickeOutcome::Resolved => panic!("the exploded handkerchief resolved: {h:?}"),
    }
}

mod combined {
    use super::*;
    use untangle::methods::cha_ko::{ResolveParams, Resolver};
    use untangle::methods::combined::{CombinedOutcome, CombinedParams, CombinedResolver, Stage};

    /// Intersecting pairs per step of Cha & Ko's own loop on `g` (gravity off): the oracle of
    /// the stages that must be exactly that loop.
    fn chako_alone_pairs(g: &Garment) -> Vec<usize> {
        let mut cp = ResolveParams::default();
        cp.sim.gravity = Vec3::zeros();
        cp.max_steps = 600;
        let mut plain = Resolver::new(g, cp).unwrap();
        plain.run(|_| {}).unwrap();
        plain
            .history()
            .iter()
            .map(|s| s.intersecting_pairs)
            .collect()
    }

    fn params(patience: usize) -> CombinedParams {
        let mut p = CombinedParams {
            prepass_patience: patience,
            max_steps: 600,
            ..Default::default()
        };
        p.wicke.sim.gravity = Vec3::zeros();
        p.cha_ko.sim.gravity = Vec3::zeros();
        p
    }

    /// The exploded handkerchief: the pre-pass runs until the pair count misses a new low, Cha
    /// & Ko finishes from the pre-pass's best state, and an independent analysis finds the
    /// result clean. Oracle for the hand-over: with no pre-pass the combined loop is Cha & Ko's
    /// loop step for step (same pair counts).
    #[test]
    fn exploded_handkerchief_resolves_in_stages() {
        let g = exploded_garment(4);
        let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
        let mut r = CombinedResolver::new(&g, params(1)).unwrap();
        let o = r.run(|_| {}).unwrap();
        assert_eq!(o, CombinedOutcome::Resolved);
        assert!(analyze(&am, r.positions()).unwrap().is_clean());
        let n = r.stage_steps();
        assert!(n[0] >= 2 && n[1] > 0, "{n:?}");
        let h = r.history();
        // Stages in order (one round here); the pre-pass stops at the first step that is not a
        // new low.
        assert!(h
            .windows(2)
            .all(|w| w[0].stage() as u8 <= w[1].stage() as u8));
        let pre: Vec<usize> = h
            .iter()
            .filter(|s| s.stage() == Stage::Prepass)
            .map(|s| s.intersecting_pairs())
            .collect();
        assert!(
            pre[..pre.len() - 1].windows(2).all(|w| w[1] < w[0]),
            "{pre:?}"
        );
        assert!(pre[pre.len() - 1] >= *pre[..pre.len() - 1].iter().min().unwrap());
        // Cha & Ko starts from the best pre-pass state.
        let first_chako = h.iter().find(|s| s.stage() == Stage::ChaKo).unwrap();
        assert_eq!(first_chako.intersecting_pairs(), *pre.iter().min().unwrap());

        // No pre-pass: Cha & Ko's own loop, step for step.
        let mut c = CombinedResolver::new(&g, params(0)).unwrap();
        c.run(|_| {}).unwrap();
        let a: Vec<usize> = c.history().iter().map(|s| s.intersecting_pairs()).collect();
        assert_eq!(a, chako_alone_pairs(&g));
    }

    /// A pre-pass that does not halve the pairs is discarded: Cha & Ko then starts from the
    /// input, and its steps are exactly Cha & Ko's own loop's (oracle), after the pre-pass's.
    #[test]
    fn a_weak_prepass_is_discarded() {
        let g = exploded_garment(4);
        let mut p = params(1);
        p.prepass_keep_below = 0.0;
        let mut r = CombinedResolver::new(&g, p).unwrap();
        r.run(|_| {}).unwrap();
        let a: Vec<usize> = r
            .history()
            .iter()
            .filter(|s| s.stage() == Stage::ChaKo)
            .map(|s| s.intersecting_pairs())
            .collect();
        let b = chako_alone_pairs(&g);
        assert!(r.stage_steps()[0] > 0);
        assert_eq!(a, b);
    }

    /// Exploded seed 73: one round (Cha & Ko, then the finish) ends with tanglements left; the
    /// second round (Cha & Ko again, from the input: the first started from the pre-pass's
    /// state) resolves it.
    #[test]
    fn a_second_round_resolves_what_the_first_left() {
        let g = exploded_garment(73);
        let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
        let mut one = params(1);
        one.rounds = 1;
        let mut r1 = CombinedResolver::new(&g, one).unwrap();
        assert_eq!(r1.run(|_| {}).unwrap(), CombinedOutcome::Unresolved);
        assert!(!analyze(&am, r1.positions()).unwrap().is_clean());
        let mut r2 = CombinedResolver::new(&g, params(1)).unwrap();
        assert_eq!(r2.run(|_| {}).unwrap(), CombinedOutcome::Resolved);
        assert!(analyze(&am, r2.positions()).unwrap().is_clean());
        // The first round is the same run; Cha & Ko comes back after the finish, from the
        // input (the first round started from the pre-pass's state): its first step sees the
        // input's pairs, and from there it is Cha & Ko's own run.
        let n1 = r1.history().len();
        assert!(r1.history().iter().zip(&r2.history()[..n1]).all(
            |(a, b)| a.stage() == b.stage() && a.intersecting_pairs() == b.intersecting_pairs()
        ));
        assert_eq!(r2.history()[n1].stage(), Stage::ChaKo);
        let first_chako = r1
            .history()
            .iter()
            .find(|s| s.stage() == Stage::ChaKo)
            .unwrap();
        assert!(first_chako.intersecting_pairs() < r1.history()[0].intersecting_pairs());
        assert_eq!(
            r2.history()[n1].intersecting_pairs(),
            r1.history()[0].intersecting_pairs()
        );
        let tail: Vec<usize> = r2.history()[n1..]
            .iter()
            .map(|s| s.intersecting_pairs())
            .collect();
        assert_eq!(tail, chako_alone_pairs(&g));
    }

    /// The finishing stage gives up after `finish_stuck_steps` steps without a new lowest
    /// pair count, above its starting count (oracle: the stage's own pair counts), and a
    /// second round that follows a
    /// first started from the input begins at the run's fewest-pair state after the first step
    /// (oracle: the step records' counts and an independent analysis of where the finish
    /// stopped). Cha & Ko is made to stop early (stuck after 3 steps without progress) so that
    /// both stages run on a small scene.
    #[test]
    fn the_finish_gives_up_and_the_second_round_starts_from_the_fewest_pairs() {
        let g = exploded_garment(4);
        let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
        let mut p = params(1);
        p.prepass_keep_below = 0.0;
        p.cha_ko.stuck_steps = 3;
        p.finish_stuck_steps = 4;
        p.max_steps = 200;
        let mut r = CombinedResolver::new(&g, p).unwrap();
        let mut after = Vec::new(); // positions after each step
        while r.step().unwrap().is_some() {
            after.push(r.positions().to_vec());
        }
        let h = r.history();
        let stages: Vec<Stage> = h.iter().map(|s| s.stage()).collect();
        let first_finish = stages.iter().position(|&s| s == Stage::Finish).unwrap();
        let second = first_finish
            + stages[first_finish..]
                .iter()
                .position(|&s| s == Stage::ChaKo)
                .unwrap();
        // The finish: at most `finish_stuck_steps` steps after its last new low.
        let fin: Vec<usize> = h[first_finish..second]
            .iter()
            .map(|s| s.intersecting_pairs())
            .collect();
        let last_low = (0..fin.len())
            .filter(|&i| fin[..i].iter().all(|&x| fin[i] < x))
            .max()
            .unwrap();
        assert_eq!(fin.len() - 1 - last_low, 4, "{fin:?}");
        assert!(fin[fin.len() - 1] > fin[0], "{fin:?}");
        // The second round's first step sees the fewest-pair state after step 1, or where the
        // finish stopped if that has fewer.
        let end_pairs = analyze(&am, &after[second - 1]).unwrap().segments.len();
        let fewest = h[1..second]
            .iter()
            .map(|s| s.intersecting_pairs())
            .min()
            .unwrap();
        assert!(
            fewest < end_pairs,
            "{fewest} {end_pairs}: the rule is not exercised"
        );
        assert_eq!(h[second].intersecting_pairs(), fewest);
    }

    /// A moving obstacle (a quad far below, sinking 1 cm per step): every stage's simulator has
    /// it where the last step left it, and once it has moved Cha & Ko starts from the state the
    /// pre-pass stopped in (its own first analysis sees that state's pairs), not from the best.
    #[test]
    fn a_moving_obstacle_follows_every_stage() {
        let g = exploded_garment(4);
        let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
        let quad = |k: usize| {
            let z = -1.0 - 0.01 * k as f64;
            vec![
                Vec3::new(-2.0, -2.0, z),
                Vec3::new(2.0, -2.0, z),
                Vec3::new(2.0, 2.0, z),
                Vec3::new(-2.0, 2.0, z),
            ]
        };
        let o = untangle::sim::Obstacle {
            name: "floor".into(),
            positions: quad(0),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            thickness: 1e-3,
            friction: 0.0,
        };
        let mut r = CombinedResolver::new(&g, params(1)).unwrap();
        r.add_obstacle(o).unwrap();
        assert!(r.set_obstacle_next_positions(1, &quad(1)).is_err());
        let mut after = Vec::new(); // (stage, pairs at its start, positions after the step)
        loop {
            r.set_obstacle_next_positions(0, &quad(after.len() + 1))
                .unwrap();
            let Some(step) = r.step().unwrap() else { break };
            let k = after.len() + 1;
            if let Some(sim) = r.simulator() {
                assert_eq!(sim.obstacles().start, quad(k), "step {k}");
            }
            after.push((
                step.stage(),
                step.intersecting_pairs(),
                r.positions().to_vec(),
            ));
        }
        assert_eq!(r.stop_reason(), Some(CombinedOutcome::Resolved));
        assert!(analyze(&am, r.positions()).unwrap().is_clean());
        let first_chako = after.iter().position(|a| a.0 == Stage::ChaKo).unwrap();
        let last_pre = &after[first_chako - 1];
        assert_eq!(last_pre.0, Stage::Prepass);
        let stopped_pairs = analyze(&am, &last_pre.2).unwrap().segments.len();
        assert_eq!(after[first_chako].1, stopped_pairs);
        // The best pre-pass state (a step's start) had fewer pairs: reverting would differ.
        let best = after[..first_chako].iter().map(|a| a.1).min().unwrap();
        assert!(best < stopped_pairs, "{best} {stopped_pairs}");
    }

    /// A case the pre-pass resolves alone never reaches Cha & Ko.
    #[test]
    fn closed_case_ends_in_the_prepass() {
        let g = scene_garment("closed");
        let mut r = CombinedResolver::new(&g, params(1)).unwrap();
        assert_eq!(r.run(|_| {}).unwrap(), CombinedOutcome::Resolved);
        let n = r.stage_steps();
        assert!(n[0] > 0 && n[1] == 0 && n[2] == 0, "{n:?}");
        assert!(r.simulator().is_none());
    }

    /// The step budget covers all stages.
    #[test]
    fn the_budget_is_shared() {
        let g = exploded_garment(2);
        let mut p = params(1);
        p.max_steps = 12;
        let mut r = CombinedResolver::new(&g, p).unwrap();
        let o = r.run(|_| {}).unwrap();
        assert_eq!(o, CombinedOutcome::StepLimit);
        assert_eq!(r.history().len(), 12);
    }
}

/// Deterministic: the same positions, bit for bit, after a pre-pass and some Cha & Ko steps of
/// the combined loop with one worker thread and with two.
#[test]
fn same_result_for_one_and_two_threads() {
    use untangle::methods::combined::{CombinedParams, CombinedResolver};
    let g = exploded_garment(3);
    let run = |threads: usize| {
        common::with_threads(threads, || {
            let mut p = CombinedParams {
                max_steps: 20,
                ..Default::default()
            };
            p.wicke.sim.gravity = Vec3::zeros();
            p.cha_ko.sim.gravity = Vec3::zeros();
            let mut r = CombinedResolver::new(&g, p).unwrap();
            r.run(|_| {}).unwrap();
            (r.stage_steps(), r.positions().to_vec())
        })
    };
    let (a, b) = (run(1), run(2));
    assert!(a.0[0] > 0 && a.0[1] > 0, "{:?}", a.0);
    assert_eq!(a.0, b.0);
    assert!(a.1.iter().zip(&b.1).all(|(x, y)| x == y));
}
