use untangle::analysis::{analyze, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{ResolveParams, Resolver};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(10);
    let seed: u64 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(3);
    let upto: usize = std::env::args()
        .nth(3)
        .map(|s| s.parse().unwrap())
        .unwrap_or(20);
    let g = Garment::new(untangle::scenes::exploded::exploded(seed, n).meshes[0].clone()).unwrap();
    let mut p = ResolveParams::default();
    p.sim.gravity = Vec3::zeros();
    let mut r = Resolver::new(&g, p).unwrap();
    for i in 0..upto {
        let (st, sr) = r.step().unwrap();
        let m = r
            .simulator()
            .positions()
            .iter()
            .map(|p| p.norm())
            .fold(0.0, f64::max);
        println!(
            "step {i} pairs {} max|x| {m:.3e} cg {} res {:.1e} stretch {:.2} zones {} stalled {}",
            st.intersecting_pairs,
            sr.cg.iterations,
            sr.cg.relative_residual,
            sr.max_stretch,
            sr.collisions.impact_zones,
            sr.collisions.stalled
        );
    }
    let pos = r.simulator().positions().to_vec();
    let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
    let a = analyze(&am, &pos).unwrap();
    let topo = &g.topology;
    println!("red* {:?}", a.coloring.red_star);
    for t in &a.tanglements {
        println!("tanglement {:?}", t);
    }
    for path in &a.paths {
        println!(
            "path {:?} loops {:?} cut {:?}",
            path.kind,
            path.loop_vertices,
            path.cut_edges.len()
        );
    }
    for c in &a.crossings {
        let e = topo.edges[c.edge as usize];
        println!(
            "crossing edge {:?} (red {}) through tri {} {:?}",
            e,
            a.coloring.red_edge[c.edge as usize],
            c.triangle,
            g.mesh.triangles[c.triangle as usize]
        );
    }
    for op in r.chako().operations() {
        println!(
            "op {:?} subj {:?} target {} tri {} level {}",
            op.kind, op.subjects, op.target, op.triangle, op.level
        );
        if op.triangle == u32::MAX {
            continue;
        }
        let tri = g.mesh.triangles[op.triangle as usize];
        for k in 0..3 {
            let (a_, b_) = (tri[k], tri[(k + 1) % 3]);
            let w = (pos[a_ as usize] - pos[b_ as usize]).norm();
            let rest =
                (r.chako().current_uv()[a_ as usize] - r.chako().current_uv()[b_ as usize]).norm();
            let orig = (r.chako().original_uv()[a_ as usize]
                - r.chako().original_uv()[b_ as usize])
                .norm();
            println!("  edge {a_}-{b_}: world {w:.5} rest {rest:.5} orig {orig:.5}");
        }
    }
    println!("eps_rg {}", r.chako().eps_rg());
}
