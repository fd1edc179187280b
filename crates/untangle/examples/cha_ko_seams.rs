//! The analogue of Cha & Ko 2022, Table 1: how many steps a finesse (a pull or shrink from
//! initiation to completion) takes off the seams and on them, on a real garment.
//!
//! The ARCSim t-shirt (6 panels) is refined by midpoint subdivision and tangled by "exploding"
//! patches around chosen centres (half of them seam vertices, half not), as in the paper's
//! exploded handkerchief (Sec. 9.2): every vertex within two rings of the centre is moved to a
//! random point of the ball of radius `r0` (the mean edge length) around the centre. Centres
//! are kept at least six rings away from the garment's boundary, so that no BLI path (outside
//! the method) arises, as the paper did. Each scene is then untangled by the Cha & Ko loop
//! without gravity, and every operation's seam kind and duration is collected.
//!
//! ```text
//! cargo run --release -p untangle --example cha_ko_seams -- [subdivisions] [scenes] [max_steps]
//! ```
//! Data: `$UNTANGLE_SHARED/data/arcsim/meshes/tshirt.obj` (default `../shared`).

mod common;

use rand::{Rng, SeedableRng};
use untangle::analysis::{analyze, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::{subdivide, Garment};
use untangle::methods::cha_ko::{FinesseRecord, FinesseStats, Outcome, ResolveParams, Resolver};

fn main() {
    use common::arg;
    let (subdivisions, scenes, max_steps) = (arg(1, 1), arg(2, 8), arg(3, 300));
    let Some(mut mesh) = common::arcsim_mesh("tshirt") else {
        return;
    };
    mesh = subdivide::subdivide_n(&mesh, subdivisions);
    let g0 = Garment::new(mesh.clone()).expect("garment");
    let avg = untangle::scenes::exploded::mean_edge_length(&mesh.positions, &g0.topology);
    println!(
        "t-shirt x{subdivisions}: {} vertices, {} triangles, {} panels, {} seam vertices, mean edge {:.4} m",
        mesh.positions.len(),
        mesh.triangles.len(),
        g0.num_panels,
        g0.num_seam_vertices(),
        avg
    );
    let rings = |c: u32, k: usize| -> Vec<u32> {
        let mut seen = vec![c];
        let mut frontier = vec![c];
        for _ in 0..k {
            let mut next = Vec::new();
            for &v in &frontier {
                for &w in g0.topology.vertex_neighbors.row(v as usize) {
                    if !seen.contains(&w) {
                        seen.push(w);
                        next.push(w);
                    }
                }
            }
            frontier = next;
        }
        seen
    };
    let inner = |v: u32| {
        rings(v, 6)
            .iter()
            .all(|&w| !g0.topology.boundary_vertex[w as usize])
    };
    let seam: Vec<u32> = (0..mesh.positions.len() as u32)
        .filter(|&v| g0.is_seam_vertex(v) && inner(v))
        .collect();
    let off: Vec<u32> = (0..mesh.positions.len() as u32)
        .filter(|&v| rings(v, 3).iter().all(|&w| !g0.is_seam_vertex(w)) && inner(v))
        .collect();
    println!(
        "centre candidates: {} on seams, {} off seams",
        seam.len(),
        off.len()
    );
    let mut log: Vec<FinesseRecord> = Vec::new();
    let mut resolved = 0;
    for k in 0..scenes {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(k as u64);
        let on_seam = k % 2 == 0;
        let pool = if on_seam { &seam } else { &off };
        if pool.is_empty() {
            eprintln!(
                "scene {k}: no interior {} vertex to explode around",
                if on_seam { "seam" } else { "off-seam" }
            );
            continue;
        }
        let c = pool[rng.random_range(0..pool.len())];
        let centre = mesh.positions[c as usize];
        let r0 = avg;
        let mut m = mesh.clone();
        for v in rings(c, 2) {
            let p = &mut m.positions[v as usize];
            {
                let r = rng.random_range(0.0..r0);
                let phi = rng.random_range(0.0..std::f64::consts::TAU);
                let z: f64 = rng.random_range(-1.0..1.0);
                let s = (1.0 - z * z).sqrt();
                *p = centre + Vec3::new(r * s * phi.cos(), r * s * phi.sin(), r * z);
            }
        }
        let g = Garment::new(m.clone()).expect("garment");
        let (am, pos) = AnalysisMesh::single(&g.mesh).expect("mesh");
        let a = analyze(&am, &pos).expect("analysis");
        let mut p = ResolveParams::default();
        p.sim.gravity = Vec3::zeros();
        p.max_steps = max_steps;
        let mut r = Resolver::new(&g, p).expect("resolver");
        let t = std::time::Instant::now();
        let verbose = std::env::var("VERBOSE").is_ok();
        let s = r
            .run(|st| {
                if verbose {
                    eprintln!(
                        "  {} pairs {} red {} ops {} sat {} {:.0}/{:.1}/{:.0} ms",
                        st.step,
                        st.intersecting_pairs,
                        st.red_vertices,
                        st.uv.active_ops,
                        st.uv.saturated_ops,
                        st.ms_analysis,
                        st.ms_uv,
                        st.ms_sim
                    )
                }
            })
            .expect("run");
        let secs = t.elapsed().as_secs_f64();
        if s.outcome == Outcome::Resolved {
            resolved += 1;
        }
        let kinds: Vec<String> = a
            .tanglements
            .iter()
            .fold(
                std::collections::BTreeMap::<&str, usize>::new(),
                |mut m, t| {
                    *m.entry(t.kind).or_default() += 1;
                    m
                },
            )
            .into_iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        println!(
            "scene {k} ({} centre {c}): {} pairs [{}], {:?} after {} steps (clean at {:?}), {} ops, {:.1} s",
            if on_seam { "seam" } else { "off-seam" },
            s.initial_pairs,
            kinds.join(", "),
            s.outcome,
            s.steps,
            s.clean_at,
            r.chako().finesse_log().len(),
            secs
        );
        log.extend(r.chako().finesse_log().iter().cloned());
        print_table(&log, resolved, k + 1);
    }
}

fn print_table(log: &[FinesseRecord], resolved: usize, scenes: usize) {
    let stats = FinesseStats::of(log);
    println!("resolved {resolved}/{scenes}");
    println!(
        "{:<10} {:>6} {:>7} {:>7} {:>11}",
        "type", "#", "%", "t", "unfinished"
    );
    for row in &stats.rows {
        println!(
            "{:<10} {:>6} {:>7.2} {:>7.2} {:>11}",
            format!("{:?}", row.seam),
            row.count,
            row.percent,
            row.mean_steps,
            row.unfinished
        );
    }
    println!(
        "on-seam minus off-seam mean steps: {:?} (paper: at most 1.76)",
        stats.on_minus_off
    );
}
