//! Cha & Ko 2022 on garments: the ARCSim `tshirt`, `dress3` and `pants3` (research licence, read
//! from the shared data folder), refined by midpoint subdivision to at least `min_vertices`
//! vertices, tangled the way the paper describes onset and user-made tanglements arising: the
//! simulator runs `tangle_steps` steps with self-collision switched off (gravity along -z, the
//! top 3 % of the vertices pinned, so the garment sags and folds through itself; BLIs allowed),
//! then the loop of Fig. 1b (`Resolver`: analysis, uv-space update, simulator step with m-CCH)
//! runs with the same pins and gravity until resolved, stuck or `max_steps`. Prints one row per
//! garment: vertices, intersecting pairs after tangling, outcome, steps, first clean step, final
//! pairs, mean ms per step (analysis / uv / simulation), wall time, the largest relative edge
//! stretch (over the run / at the end) and the final elastic and kinetic energies.
//! `UNTANGLE_INTEGRATOR` and `UNTANGLE_PD_CG_CAP` as in `common::loop_params`.
//!
//! ```text
//! cargo run --release -p untangle --example cha_ko_garments -- [min_vertices] [tangle_steps] [max_steps]
//! ```

mod common;

use std::time::Instant;
use untangle::analysis::{analyze, AnalysisMesh, PathKind};
use untangle::geom::Vec3;
use untangle::mesh::{subdivide, Garment};
use untangle::methods::cha_ko::{ResolveParams, Resolver};

fn main() {
    use common::arg;
    let (min_vertices, tangle_steps, max_steps) = (arg(1, 2000), arg(2, 25), arg(3, 600));
    println!("| garment | vertices | triangles | pairs after tangling | BLI paths | outcome | steps | clean at | final pairs | ms/step (analysis / uv / sim) | wall s | max stretch (run / final) | final elastic / kinetic J | BW steps / switches | diverged steps / ops given up / largest step energy growth |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    // CHAKO_ONLY=<name>: one garment; CHAKO_STALLS=1: print the last stalls of a run;
    // CHAKO_KINDS=1: the path kinds (and their inside-region sizes) before and after;
    // CHAKO_WRITE=<dir>: the tangled garment as <dir>/<name>_tangled.obj.
    let only = std::env::var("CHAKO_ONLY").ok();
    // CHAKO_GARMENTS=a,b,...: other ARCSim meshes (e.g. dress4,jacket,sleeve).
    let list = std::env::var("CHAKO_GARMENTS").unwrap_or_else(|_| "tshirt,dress3,pants3".into());
    for name in list.split(',') {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let Some(mut mesh) = common::arcsim_mesh(name) else {
            return;
        };
        while mesh.positions.len() < min_vertices {
            mesh = subdivide::subdivide(&mesh);
        }
        let g = Garment::new(mesh.clone()).expect("garment");
        let gravity = untangle::scenes::sagged::GRAVITY_Z;
        let pins = untangle::scenes::sagged::top_vertices(&mesh, &Vec3::z(), 0.03);
        let tangled =
            untangle::scenes::sagged::sagged(&g, gravity, &pins, tangle_steps).expect("sagging");
        let (am, _) = AnalysisMesh::single(&tangled).expect("analysis mesh");
        let a0 = analyze(&am, &tangled.positions).expect("analysis");
        let bli = a0
            .paths
            .iter()
            .filter(|p| p.kind == PathKind::BoundaryLoopInside)
            .count();
        if let Ok(dir) = std::env::var("CHAKO_WRITE") {
            let path = std::path::Path::new(&dir).join(format!("{name}_tangled.obj"));
            untangle::mesh::obj::write_obj(&path, &tangled, None, "sagged, self-collision off")
                .expect("write");
        }
        let tg = Garment::new(tangled).expect("garment");
        let mut p = ResolveParams::default();
        p.sim.gravity = gravity;
        p.max_steps = max_steps;
        // UNTANGLE_INTEGRATOR=pd, UNTANGLE_PD_CG_CAP (see `common`).
        common::loop_params(&mut p);
        // Ablations: CHAKO_REVOKE, CHAKO_LAST_RESORT=0, CHAKO_AVOID_LOOP_PULL=1,
        // CHAKO_AVOID_LOOP_PULL_START=1, CHAKO_ZONE_SOFT
        // (the simulator's soft impact-zone levels; 0 = rigid zones), CHAKO_SLIT=0|1 (slit ridges, on by default),
        // CHAKO_SLIT_STALL.
        let env = |k: &str| std::env::var(k).ok().map(|s| s.parse::<f64>().expect(k));
        common::trial_params(&mut p.cha_ko);
        // CHAKO_REVOKE_CLEAN, CHAKO_REVOKE_FINISHED, CHAKO_HOLD_PROGRESS, CHAKO_PULL_ORDER.
        common::schedule_params(&mut p.cha_ko);
        if let Some(v) = env("CHAKO_REVOKE") {
            p.cha_ko.revoke_levels_per_step = v as u32;
        }
        if let Some(v) = env("CHAKO_SLIT") {
            p.slit_ridges = v != 0.0;
        }
        if let Some(v) = env("CHAKO_SLIT_STALL") {
            p.slit_stall = v as usize;
        }
        if let Some(v) = env("CHAKO_LAST_RESORT") {
            p.cha_ko.loop_target_last_resort = v != 0.0;
        }
        if let Some(v) = env("CHAKO_AVOID_LOOP_PULL_START") {
            p.cha_ko.avoid_loop_pull_targets_at_start = v != 0.0;
        }
        if let Some(v) = env("CHAKO_ZONE_SOFT") {
            p.sim.zone_motion.soft_levels = v as u32;
        }
        if let Some(v) = env("CHAKO_AVOID_LOOP_PULL") {
            p.cha_ko.avoid_loop_pull_targets = v != 0.0;
        }
        let t = Instant::now();
        let mut r = Resolver::new(&tg, p).expect("resolver");
        for &v in &pins {
            r.simulator_mut().set_pinned(v, true).expect("pin");
        }
        // CHAKO_TRACE=1: one line per step on stderr.
        let trace = std::env::var("CHAKO_TRACE").is_ok();
        let (s, tracked) = common::run_tracking(&mut r, |st, sr| {
            if trace {
                eprintln!(
                    "{name} step {} pairs {} red {} {:?} {:?} ms sim {:.1} stretch {:.3}",
                    st.step,
                    st.intersecting_pairs,
                    st.red_vertices,
                    st.integrator,
                    st.integrator_switch,
                    st.ms_sim,
                    sr.max_stretch
                );
            }
        });
        let wall = t.elapsed().as_secs_f64();
        let diverged = r
            .history()
            .iter()
            .filter(|s| s.divergence.diverged > 0)
            .count();
        let given_up: usize = r
            .history()
            .iter()
            .map(|s| s.divergence.given_up.len())
            .sum();
        let growth = r
            .history()
            .iter()
            .map(|s| s.divergence.growth)
            .fold(0.0, f64::max);
        println!(
            "| {name} | {} | {} | {} | {bli} | {:?} | {} | {} | {} | {:.1} / {:.2} / {:.1} | {:.1} | {:.3} / {:.3} | {:.3e} / {:.3e} | {} | {diverged} / {given_up} / {growth:.2}x |",
            mesh.positions.len(),
            mesh.triangles.len(),
            a0.segments.len(),
            s.outcome,
            s.steps,
            s.clean_at.map_or("-".into(), |c| c.to_string()),
            s.final_pairs,
            s.mean_ms[0],
            s.mean_ms[1],
            s.mean_ms[2],
            wall,
            tracked.max_stretch,
            tracked.final_stretch,
            tracked.final_elastic,
            tracked.final_kinetic,
            common::integrator_use(&r)
        );
        if std::env::var("CHAKO_KINDS").is_ok() {
            let a1 = analyze(&am, r.simulator().positions()).expect("analysis");
            for (when, a) in [("after tangling", &a0), ("at the end", &a1)] {
                let mut kinds = std::collections::BTreeMap::<String, (usize, usize)>::new();
                for (p, reg) in a.paths.iter().zip(&a.regions) {
                    let e = kinds.entry(format!("{:?}", p.kind)).or_default();
                    e.0 += 1;
                    if let untangle::analysis::Region::Inside(vs) = reg {
                        e.1 += vs.len();
                    }
                }
                println!(
                    "  {when}: {} pairs, {} red vertices; paths (count, inside vertices) {kinds:?}",
                    a.segments.len(),
                    a.coloring.num_red_vertices()
                );
            }
        }
        if std::env::var("CHAKO_STALLS").is_ok() {
            let h = r.history();
            for st in h.iter().rev().take(5).rev() {
                println!(
                    "  step {}: pairs {} red {} ops {} pulls +{} ~{} shrinks +{} ~{} blocked fan/subject/tabu {}/{}/{} loop-skipped {} stalls {:?}",
                    st.step, st.intersecting_pairs, st.red_vertices, st.uv.active_ops,
                    st.uv.pulls_started, st.uv.pulls_continued, st.uv.shrinks_started,
                    st.uv.shrinks_continued, st.uv.blocked_fan, st.uv.blocked_subject,
                    st.uv.blocked_tabu, st.uv.pull_loop_targets_skipped, st.uv.stalls
                );
            }
            let x = r.simulator().positions().to_vec();
            let (am2, _) = AnalysisMesh::single(&tg.mesh).expect("analysis mesh");
            let a = untangle::analysis::analyze_with(
                &am2,
                &x,
                &untangle::analysis::Options {
                    bli_regions_red: true,
                    winding_regions: true,
                },
            )
            .expect("analysis");
            let c = &a.coloring;
            let mut loops: Vec<u32> = a
                .paths
                .iter()
                .flat_map(|p| p.loop_vertices().iter().copied())
                .collect();
            loops.sort_unstable();
            println!(
                "  final: red {:?} outmost {:?} red* {:?} loop vertices {:?}",
                (0..c.red_vertex.len())
                    .filter(|&i| c.red_vertex[i])
                    .collect::<Vec<_>>(),
                c.outmost_red,
                c.red_star,
                loops
            );
            for op in r.chako().operations() {
                println!(
                    "  op {:?} subjects {:?} target {} (red {}, loop {}) triangle {} level {} / {}",
                    op.kind,
                    op.subjects,
                    op.target,
                    c.red_vertex[op.target as usize],
                    loops.binary_search(&op.target).is_ok(),
                    op.triangle,
                    op.level,
                    op.level_cap
                );
            }
        }
    }
}
