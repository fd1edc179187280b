//! How far Cha & Ko's uv edits and the world move a garment's edges from their original
//! length, step by step, with the loop run as `untangle fix` runs it by default (gravity off,
//! no pins): BENCHMARKS.md, session 31 (dress4).
//!
//! Every `EVERY` steps it prints, for the edges inside the input's largest inside region (the
//! region the loop pulls first) and for all edges: the largest ratio of edited rest (uv) to
//! original length, the largest ratio of world to original length, world over edited rest
//! (median / largest); for all edges, those over twice their original length, the longest
//! world / original ratio and the shortest edited rest / original; the simulator step's
//! stretch energy (at its start) and CCD candidates; and the analysis's crossings split into
//! those within the region (edge and triangle), touching it, and elsewhere (also for the input). Then, for each further OBJ (the same
//! garment, e.g. `fix`'s outputs), its edges over twice their original length and the longest
//! edge over its original length.
//!
//! ```text
//! cargo run --release -p untangle --example cha_ko_rest_growth -- IN.obj STEPS EVERY [OUT.obj ...]
//! ```

use untangle::analysis::{analyze, AnalysisMesh, Region};
use untangle::geom::{Vec2, Vec3};
use untangle::mesh::{obj, Garment, Mesh};
use untangle::methods::cha_ko::{ResolveParams, Resolver};

/// Per edge of each triangle: (world vertices, uv indices).
fn edges(m: &Mesh) -> Vec<([u32; 2], [usize; 2])> {
    let uv = m.uv.as_ref().expect("a garment with uv");
    m.triangles
        .iter()
        .zip(&uv.triangles)
        .flat_map(|(t, u)| {
            (0..3).map(move |k| {
                (
                    [t[k], t[(k + 1) % 3]],
                    [u[k] as usize, u[(k + 1) % 3] as usize],
                )
            })
        })
        .collect()
}

/// Crossings of `x` within the region (edge and triangle), touching it, and elsewhere.
fn crossings_by_region(am: &AnalysisMesh, x: &[Vec3], region: &[bool]) -> [usize; 3] {
    let an = analyze(am, x).expect("analysis");
    let mut n = [0; 3];
    for c in &an.crossings {
        let e = am.topology.edges[c.edge as usize];
        let t = am.triangles[c.triangle as usize];
        let inside = |v: &u32| region[*v as usize];
        if e.iter().all(inside) && t.iter().all(inside) {
            n[0] += 1;
        } else if e.iter().any(inside) || t.iter().any(inside) {
            n[1] += 1;
        } else {
            n[2] += 1;
        }
    }
    n
}

/// Edges over twice their original length, and the largest world / original ratio.
fn world_growth(edges: &[([u32; 2], [usize; 2])], uv0: &[Vec2], x: &[Vec3]) -> (usize, f64) {
    let r: Vec<f64> = edges
        .iter()
        .map(|(w, u)| (x[w[0] as usize] - x[w[1] as usize]).norm() / (uv0[u[0]] - uv0[u[1]]).norm())
        .collect();
    (
        r.iter().filter(|&&v| v > 2.0).count(),
        r.iter().copied().fold(0.0, f64::max),
    )
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    if a.len() < 4 {
        eprintln!("usage: cha_ko_rest_growth IN.obj STEPS EVERY [OUT.obj ...]");
        std::process::exit(2);
    }
    let mesh = obj::read_obj(std::path::Path::new(&a[1])).expect("a mesh");
    let steps: usize = a[2].parse().expect("STEPS");
    let every: usize = a[3].parse::<usize>().expect("EVERY").max(1);
    let g = Garment::new(mesh.clone()).expect("a garment");
    let mesh = g.mesh.clone();
    let uv0 = mesh.uv.as_ref().expect("uv").coords.clone();
    let es = edges(&mesh);
    let (am, pos) = AnalysisMesh::single(&mesh).expect("analysis mesh");
    let a0 = analyze(&am, &pos).expect("analysis");
    let mut region = vec![false; pos.len()];
    if let Some(vs) = a0
        .regions
        .iter()
        .filter_map(|r| match r {
            Region::Inside(vs) => Some(vs),
            _ => None,
        })
        .max_by_key(|vs| vs.len())
    {
        for &v in vs {
            region[v as usize] = true;
        }
        println!("largest inside region: {} vertices", vs.len());
    }
    let (twice, longest) = world_growth(&es, &uv0, &pos);
    let [w, t, e] = crossings_by_region(&am, &pos, &region);
    println!(
        "input: {twice} edges over 2x, longest {longest:.2}x; crossings within / touching / elsewhere {w} / {t} / {e}"
    );
    let mut p = ResolveParams::default();
    p.sim.gravity = Vec3::zeros();
    let mut r = Resolver::new(&g, p).expect("resolver");
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    for k in 1..=steps {
        let (_, sr) = r.step().expect("step");
        if k % every != 0 && k != steps {
            continue;
        }
        let x = r.simulator().positions();
        let uv = r.simulator().rest_uv();
        let (mut edited, mut world, mut over) = (0.0f64, 0.0f64, Vec::new());
        for (w, u) in es
            .iter()
            .filter(|(w, _)| w.iter().all(|&v| region[v as usize]))
        {
            let o = (uv0[u[0]] - uv0[u[1]]).norm();
            let e = (uv[u[0]] - uv[u[1]]).norm();
            let l = (x[w[0] as usize] - x[w[1] as usize]).norm();
            edited = edited.max(e / o);
            world = world.max(l / o);
            over.push(l / e);
        }
        let over_max = over.iter().copied().fold(0.0, f64::max);
        let (twice, longest) = world_growth(&es, &uv0, x);
        // The longest edge (world / original): its edited rest / original.
        let growth = |(w, u): &([u32; 2], [usize; 2])| {
            (x[w[0] as usize] - x[w[1] as usize]).norm() / (uv0[u[0]] - uv0[u[1]]).norm()
        };
        let longest_edge = es
            .iter()
            .max_by(|a, b| growth(a).total_cmp(&growth(b)))
            .expect("edges");
        let longest_rest = (uv[longest_edge.1[0]] - uv[longest_edge.1[1]]).norm()
            / (uv0[longest_edge.1[0]] - uv0[longest_edge.1[1]]).norm();
        let shortest = es
            .iter()
            .map(|(_, u)| (uv[u[0]] - uv[u[1]]).norm() / (uv0[u[0]] - uv0[u[1]]).norm())
            .fold(f64::INFINITY, f64::min);
        let [within, touching, elsewhere] = crossings_by_region(&am, x, &region);
        println!(
            "after {k} steps: region edges: edited rest / original {edited:.2}, world / original {world:.2}, world / edited rest {:.2} / {over_max:.2}; all edges: {twice} over 2x, longest {longest:.2}x (its edited rest / original {longest_rest:.3}), shortest edited rest / original {shortest:.3}; step {} (0-based) began at stretch energy {:.3e} J, {} CCD candidates; crossings within / touching / elsewhere {within} / {touching} / {elsewhere}",
            median(over),
            k - 1,
            sr.energy.stretch,
            sr.collisions.candidates,
        );
    }
    for f in &a[4..] {
        let m = obj::read_obj(std::path::Path::new(f)).expect("an OBJ");
        let (twice, longest) = world_growth(&es, &uv0, &m.positions[..mesh.positions.len()]);
        println!("{f}: {twice} edges over 2x their original length, longest {longest:.2}x");
    }
}
