//! Physics sanity of the implicit integrator: free fall against the closed-form implicit Euler
//! recurrence, a hanging sheet that settles with its stretch within a few percent and its total
//! energy dissipated (with both integrators), and bad input rejected with errors.

use untangle::geom::{Vec2, Vec3};
use untangle::mesh::Garment;
use untangle::scenes::handkerchief;
use untangle::sim::{Integrator, SimParams, Simulator, UniformThickness};

#[test]
fn free_fall_follows_the_implicit_euler_recurrence() {
    let cloth = handkerchief("s", 6, 6, 0.3, 0.3, |p| {
        Vec3::new(p.x, 1.0 + 0.1 * p.y, p.y)
    });
    let g = Garment::new(cloth).unwrap();
    let params = SimParams {
        damping_mass: 0.0,
        cg_tolerance: 1e-10,
        cg_max_iterations: 1000,
        ..SimParams::default()
    };
    let h = params.dt;
    let grav = params.gravity;
    let mut sim = Simulator::new(&g, params).unwrap();
    let m: f64 = sim.masses().iter().sum();
    let com = |s: &Simulator| {
        s.positions()
            .iter()
            .zip(s.masses())
            .fold(Vec3::zeros(), |a, (p, &w)| a + p * w)
            / m
    };
    let c0 = com(&sim);
    let steps = 50;
    for _ in 0..steps {
        sim.step(&UniformThickness(1e-3));
    }
    // Internal forces cancel in the sum: v_k = k h g, x_n = x_0 + h^2 g n (n + 1) / 2.
    let n = steps as f64;
    let expect = c0 + grav * (h * h * n * (n + 1.0) / 2.0);
    let got = com(&sim);
    assert!(
        (got - expect).norm() < 1e-6 * (1.0 + expect.norm()),
        "{got} vs {expect}"
    );
    // The sheet is rigid in free fall: no stretch develops.
    assert!(sim.max_stretch().abs() < 1e-6);
}

#[test]
fn hanging_sheet_settles_with_small_stretch() {
    hanging_sheet_settles(SimParams::default());
}

/// The same with projective dynamics (`untangle::sim::projective`).
#[test]
fn hanging_sheet_settles_with_small_stretch_projective() {
    hanging_sheet_settles(SimParams {
        integrator: Integrator::Projective,
        ..SimParams::default()
    });
}

/// The same with projective dynamics accelerated by Anderson (`untangle::sim::anderson`,
/// window 5) instead of Chebyshev.
#[test]
fn hanging_sheet_settles_with_small_stretch_projective_anderson() {
    hanging_sheet_settles(SimParams {
        integrator: Integrator::Projective,
        projective_anderson: 5,
        ..SimParams::default()
    });
}

/// A sheet pinned along one edge hangs down and settles with small stretch and dissipated
/// energy, with the integrator and material of `params`.
fn hanging_sheet_settles(params: SimParams) {
    let (nx, ny) = (10, 10);
    let cloth = handkerchief("s", nx, ny, 0.4, 0.4, |p| Vec3::new(p.x, 1.0, p.y));
    let g = Garment::new(cloth).unwrap();
    let mut sim = Simulator::new(&g, params).unwrap();
    // Pin the whole edge at uv y = -0.2 (z = -0.2).
    let top: Vec<u32> = (0..=nx as u32).collect();
    for &v in &top {
        sim.set_pinned(v, true).unwrap();
    }
    let policy = UniformThickness(1e-3);
    let mut total = Vec::new();
    let mut last = None;
    for _ in 0..400 {
        let r = sim.step(&policy);
        let e = r.energy;
        total.push(e.kinetic + e.stretch + e.bend + e.gravity);
        last = Some(r);
    }
    let r = last.unwrap();
    // Settled: (almost) no kinetic energy left.
    assert!(r.energy.kinetic < 1e-5, "kinetic {}", r.energy.kinetic);
    // Implicit Euler with damping dissipates: the total energy ends well below the start and
    // never rises more than 1% above it (the nonlinear stretch makes it not strictly monotone).
    // The centre of mass drops 0.2 m: 0.024 kg x 9.81 x 0.2 = 0.047 J released.
    assert!(total[total.len() - 1] < total[0] - 0.03);
    for (k, &e) in total.iter().enumerate() {
        assert!(
            e <= total[0] + 0.01 * total[0].abs(),
            "step {k}: {e} above the start {}",
            total[0]
        );
    }
    // Stretch within a few percent, everywhere.
    assert!(r.max_stretch < 0.03, "max stretch {}", r.max_stretch);
    // Hangs straight down below the pinned edge: free vertices lie below it, the far edge at
    // about one sheet length.
    let pos = sim.positions();
    let bottom = ((ny * (nx + 1))..=(ny * (nx + 1) + nx)).map(|i| pos[i].y);
    for y in bottom {
        assert!((y - (1.0 - 0.4)).abs() < 0.02, "bottom edge at {y}");
    }
    for &v in &top {
        assert_eq!(pos[v as usize], Vec3::new(pos[v as usize].x, 1.0, -0.2));
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let cloth = handkerchief("s", 3, 3, 0.3, 0.3, |p| Vec3::new(p.x, 0.0, p.y));
    let g = Garment::new(cloth.clone()).unwrap();
    for bad in [
        SimParams {
            dt: 0.0,
            ..SimParams::default()
        },
        SimParams {
            density: f64::NAN,
            ..SimParams::default()
        },
        SimParams {
            ccd_ratio: 1.5,
            ..SimParams::default()
        },
        SimParams {
            stretch_stiffness: -1.0,
            ..SimParams::default()
        },
    ] {
        assert!(Simulator::new(&g, bad).is_err());
    }
    let mut sim = Simulator::new(&g, SimParams::default()).unwrap();
    assert!(sim.set_pinned(1000, true).is_err());
    assert!(sim.set_pin_target(0, Vec3::zeros()).is_err(), "not pinned");
    assert!(sim.set_positions(&[Vec3::zeros()]).is_err());
    let mut nan = sim.positions().to_vec();
    nan[0].x = f64::NAN;
    assert!(sim.set_positions(&nan).is_err());
    assert!(sim.set_obstacle_next_positions(0, &[]).is_err());
    assert!(sim.set_rest_uv(&[Vec2::zeros(); 3]).is_err());
    // A garment whose uv triangle is degenerate is refused with its place.
    let mut m = cloth;
    let uv = m.uv.as_mut().unwrap();
    let t = uv.triangles[0];
    uv.coords[t[1] as usize] = uv.coords[t[0] as usize];
    let g = Garment::new(m).unwrap();
    let e = Simulator::new(&g, SimParams::default())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("triangle 1"), "{e}");
}

#[test]
fn a_free_tangled_cloth_keeps_its_momentum() {
    // Regression: with gravity off and nothing pinned, the internal forces (stretch, bending,
    // the implicit cloth-cloth contact springs) and the collision impulses all cancel in the sum,
    // so the total momentum of a cloth starting at rest must stay zero. The exploded
    // handkerchief is tangled and far from its rest shape (large internal forces), and the
    // contact policy is Cha & Ko's m-CCH from its colouring (red-red pairs may cross). With the
    // default CG tolerance the solve used to leave its error in the rigid translations and the
    // sheet drifted away (metres within a few seconds).
    use untangle::analysis::{analyze, AnalysisMesh};
    use untangle::methods::cha_ko::{ChaKo, Params};
    let g = Garment::new(untangle::scenes::exploded::exploded(2, 10).meshes[0].clone()).unwrap();
    let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
    let params = SimParams {
        gravity: Vec3::zeros(),
        ..SimParams::default()
    };
    let mut sim = Simulator::new(&g, params).unwrap();
    let ck = ChaKo::new(&g, Params::default()).unwrap();
    let mut scale = 0.0f64;
    for step in 0..25 {
        let a = analyze(&am, sim.positions()).unwrap();
        let policy = ck.contact_policy(&am, &a);
        let rep = sim.step(&policy);
        let (p, s) = sim
            .velocities()
            .iter()
            .zip(sim.masses())
            .fold((Vec3::zeros(), 0.0), |(p, s), (v, &m)| {
                (p + v * m, s + v.norm() * m)
            });
        scale = scale.max(s);
        assert!(
            p.norm() <= 1e-9 * scale,
            "step {step}: momentum {p} (sum m|v| {s}, springs {}, proximity {})",
            rep.contact_springs,
            rep.collisions.proximity_impulses
        );
    }
    // The cloth did move (the check is not vacuous).
    assert!(scale > 1e-3, "{scale}");
}

/// The multigrid preconditioner (`CgPreconditioner::Multigrid`) against the two-level one on a
/// generated sheet pinned at two corners, falling and swinging: fewer CG iterations in total,
/// and the same motion (both solve the same systems to the same tolerance; oracle: the other
/// run).
#[test]
fn multigrid_needs_fewer_cg_iterations_on_a_sheet() {
    use untangle::sim::CgPreconditioner;
    let run = |pre: CgPreconditioner| {
        let cloth = handkerchief("s", 24, 24, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
        let g = Garment::new(cloth.clone()).unwrap();
        let params = SimParams {
            gravity: Vec3::new(0.0, 0.0, -9.81),
            preconditioner: pre,
            ..SimParams::default()
        };
        let mut sim = Simulator::new(&g, params).unwrap();
        for i in [0, 24] {
            sim.set_pinned(i, true).unwrap();
        }
        let mut iterations = 0;
        for _ in 0..20 {
            let r = sim.step(&UniformThickness(2e-3));
            assert!(r.cg.converged, "{pre:?}: {:?}", r.cg);
            iterations += r.cg.iterations;
        }
        (iterations, sim.positions().to_vec())
    };
    let (it_mg, x_mg) = run(CgPreconditioner::Multigrid);
    let (it_two, x_two) = run(CgPreconditioner::TwoLevel);
    assert!(it_mg < it_two, "multigrid {it_mg}, two-level {it_two}");
    let diff = x_mg
        .iter()
        .zip(&x_two)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(diff < 0.01, "largest difference {diff} m");
}

/// Regression (exploded-handkerchief seeds that stretched to edges of 10^40 m): a tangled cloth
/// whose rest shape is shrunk far below its world shape (as Cha & Ko's deep pulls shrink rest
/// edges to 0.003 against world edges of 0.5), gravity off, nothing pinned, m-CCH contacts from
/// its colouring, with the simulator settings of the Cha & Ko loop. The stretch forces are huge
/// and the collision handling forms impact zones over most of the cloth. The cloth must contract
/// (mean edge length down, stretch energy down) and its kinetic energy stay bounded; it used to
/// inflate: CG's error in the rotations gave the rigid zones a spurious spin, whose linearised
/// rotation grows every distance in a zone by `sqrt(1 + (h |omega|)^2)` per step.
#[test]
fn a_tangled_cloth_with_a_shrunk_rest_shape_contracts() {
    use untangle::analysis::{analyze, AnalysisMesh};
    use untangle::methods::cha_ko::{ChaKo, Params, ResolveParams};
    let g = Garment::new(untangle::scenes::exploded::exploded(2, 10).meshes[0].clone()).unwrap();
    let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
    let mut params = ResolveParams::default().sim;
    params.gravity = Vec3::zeros();
    let mut sim = Simulator::new(&g, params).unwrap();
    // Rest shape: every uv coordinate scaled by 0.05 about the centre.
    let uv = g.uv().coords.clone();
    let c = uv.iter().sum::<Vec2>() / uv.len() as f64;
    let shrunk: Vec<Vec2> = uv.iter().map(|p| c + (p - c) * 0.05).collect();
    sim.set_rest_uv(&shrunk).unwrap();
    let ck = ChaKo::new(&g, Params::default()).unwrap();
    let mean_edge = |x: &[Vec3]| {
        let e = &g.topology.edges;
        e.iter()
            .map(|e| (x[e[0] as usize] - x[e[1] as usize]).norm())
            .sum::<f64>()
            / e.len() as f64
    };
    let l0 = mean_edge(sim.positions());
    let mut first = None;
    let mut last = None;
    let mut zone_steps = 0;
    let mut ke_max = 0.0f64;
    for _ in 0..60 {
        let a = analyze(&am, sim.positions()).unwrap();
        let r = sim.step(&ck.contact_policy(&am, &a));
        first.get_or_insert(r.energy);
        last = Some(r.energy);
        ke_max = ke_max.max(r.energy.kinetic);
        zone_steps += (r.collisions.impact_zones > 0) as usize;
    }
    let l1 = mean_edge(sim.positions());
    let (first, last) = (first.unwrap(), last.unwrap());
    eprintln!(
        "mean edge {l0:.4} -> {l1:.4}, stretch energy {:.3e} -> {:.3e}, max kinetic {ke_max:.3e}, {zone_steps} zone steps",
        first.stretch, last.stretch
    );
    assert!(zone_steps > 0, "impact zones must be exercised");
    assert!(l1 < 0.9 * l0, "mean edge {l0} -> {l1}");
    assert!(last.stretch < first.stretch, "{first:?} -> {last:?}");
    assert!(ke_max < first.stretch, "kinetic {ke_max} vs {first:?}");
}

/// A sheet whose edges are shorter than its thickness (1.6 mm cells, 2 mm thickness: every
/// vertex has non-adjacent triangles of its own two-ring 1.6 mm away) hangs as if it had no
/// thickness because neighbour pairs' thickness is capped (`untangle::sim::near`); without the
/// cap, proximity repulsion and contact springs push the flat sheet apart in its own plane.
/// (The rule covers two rings: with cells below about 0.7 x the thickness, the three-ring's
/// pairs are within it too and the sheet inflates again.) Projective dynamics' 10 iterations
/// leave this stiff fine sheet stretched even without thickness, so the oracle is the same
/// run with a negligible thickness.
#[test]
fn a_sheet_finer_than_its_thickness_hangs_as_without_thickness() {
    let run = |near_pair_fraction: f64, integrator: Integrator, thickness: f64| {
        let n = 15;
        let cloth = handkerchief("s", n, n, 0.024, 0.024, |p| Vec3::new(p.x, 1.0, p.y));
        let g = Garment::new(cloth).unwrap();
        let params = SimParams {
            near_pair_fraction,
            integrator,
            ..SimParams::default()
        };
        let mut sim = Simulator::new(&g, params).unwrap();
        for v in 0..=n as u32 {
            sim.set_pinned(v, true).unwrap();
        }
        let mut worst: f64 = 0.0;
        for _ in 0..40 {
            let r = sim.step(&UniformThickness(thickness));
            worst = worst.max(r.max_stretch);
        }
        worst
    };
    let fraction = SimParams::default().near_pair_fraction;
    for integrator in [Integrator::BaraffWitkin, Integrator::Projective] {
        let thin = run(fraction, integrator, 1e-6);
        let capped = run(fraction, integrator, 2e-3);
        let uncapped = run(0.0, integrator, 2e-3);
        eprintln!(
            "{integrator:?}: max stretch without thickness {thin:.4}, capped {capped:.4}, \
             uncapped {uncapped:.4}"
        );
        assert!(
            capped <= 1.3 * thin + 0.005,
            "{integrator:?}: capped {capped} vs {thin} without thickness"
        );
        assert!(
            uncapped > 5.0 * capped,
            "{integrator:?}: uncapped {uncapped}"
        );
    }
}

/// `stretch_energies` and `kinetic_energy` give the energies the next step reports at its start
/// (Baraff & Witkin's assembly sums them its own way), for the current positions and for
/// positions passed in; wrong-length positions are an error, non-finite ones give non-finite
/// energies at their triangles.
#[test]
fn per_triangle_stretch_energies_sum_to_the_reported_energy() {
    let cloth = handkerchief("s", 6, 6, 0.4, 0.4, |p| Vec3::new(p.x, 1.0, p.y));
    let g = Garment::new(cloth).unwrap();
    let mut sim = Simulator::new(&g, SimParams::default()).unwrap();
    sim.set_pinned(0, true).unwrap();
    let policy = UniformThickness(1e-3);
    for _ in 0..5 {
        sim.step(&policy);
    }
    let x = sim.positions().to_vec();
    let per: Vec<f64> = sim.stretch_energies(&x).unwrap();
    assert_eq!(per.len(), g.mesh.triangles.len());
    assert!(per.iter().all(|&e| e >= 0.0));
    let (sum, kinetic) = (per.iter().sum::<f64>(), sim.kinetic_energy());
    assert!(sum > 0.0 && kinetic > 0.0);
    let r = sim.step(&policy);
    assert!(
        (sum - r.energy.stretch).abs() <= 1e-12 * sum,
        "{sum} vs {}",
        r.energy.stretch
    );
    assert!((kinetic - r.energy.kinetic).abs() <= 1e-12 * kinetic);
    // Other positions: the flat input is at rest (zero stretch), a uniform 10 % stretch in the
    // sheet's plane costs 0.5 k (0.1^2 + 0.1^2) per unit rest area, plus the shear of none.
    let flat = sim.stretch_energies(&g.mesh.positions).unwrap();
    assert!(flat.iter().all(|&e| e < 1e-20), "{flat:?}");
    let centre = Vec3::new(0.0, 1.0, 0.0);
    let big: Vec<Vec3> = g
        .mesh
        .positions
        .iter()
        .map(|p| centre + (p - centre) * 1.1)
        .collect();
    let e: f64 = sim.stretch_energies(&big).unwrap().iter().sum();
    let k = SimParams::default().stretch_stiffness;
    assert!((e - 0.5 * k * 0.02 * 0.16).abs() < 1e-9 * e, "{e}");
    assert!(sim.stretch_energies(&x[1..]).is_err());
    // A non-finite position (a blown-up step) is measured, not refused: exactly the triangles
    // at it get non-finite energies.
    let mut bad = x.clone();
    bad[3].y = f64::NAN;
    let e = sim.stretch_energies(&bad).unwrap();
    for (t, (&eb, &ex)) in g.mesh.triangles.iter().zip(e.iter().zip(&per)) {
        if t.contains(&3) {
            assert!(!eb.is_finite());
        } else {
            assert_eq!(eb, ex);
        }
    }
}
