//! Diagnostic: runs the Cha & Ko loop on a named scene and, at the listed steps, prints the
//! red* triangles, their red edges, the crossings they take part in and the operations.
//! `CHAKO_SLIT=0` runs the loop without slit ridges (`ResolveParams::slit_ridges`, on by
//! default; the printed colouring is the plain analysis' either way). `CHAKO_LOOP_ANALYSIS=1`
//! prints the analysis with the loop's settings instead (BLI and winding regions coloured, as
//! the loop sees them); `SCENE_SIZE=K` builds the scene at size / refinement level `K`.
//!
//! `cargo run --release -p untangle --example cha_ko_inspect -- cross 20,60,100 [seed]`
use untangle::analysis::{analyze, analyze_with, AnalysisMesh};
use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::methods::cha_ko::{ResolveParams, Resolver};

fn main() {
    let which = std::env::args().nth(1).unwrap_or("cross".into());
    let at: Vec<usize> = std::env::args()
        .nth(2)
        .unwrap_or("20".into())
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();
    let seed: u64 = std::env::args()
        .nth(3)
        .map_or(1, |s| s.parse().expect("a seed"));
    let scene = untangle::scenes::by_name(
        &which,
        std::env::var("SCENE_SIZE").ok().map(|s| s.parse().unwrap()),
        seed,
    )
    .unwrap();
    let g = Garment::new(AnalysisMesh::merge_cloth(&scene.meshes).unwrap()).unwrap();
    let mut p = ResolveParams::default();
    p.sim.gravity = Vec3::zeros();
    if let Ok(v) = std::env::var("CHAKO_SLIT") {
        p.slit_ridges = v != "0";
    }
    let aparams = p.analysis;
    let loop_analysis = std::env::var("CHAKO_LOOP_ANALYSIS").is_ok_and(|v| v != "0");
    let mut r = Resolver::new(&g, p).unwrap();
    let (am, _) = AnalysisMesh::single(&g.mesh).unwrap();
    let topo = &g.topology;
    let last = *at.iter().max().unwrap();
    for i in 0..=last {
        if at.contains(&i) {
            let pos = r.simulator().positions().to_vec();
            let a = if loop_analysis {
                analyze_with(&am, &pos, &aparams).unwrap()
            } else {
                analyze(&am, &pos).unwrap()
            };
            let c = &a.coloring;
            println!(
                "=== step {i}: pairs {} red v {} outmost {:?} red* {:?}",
                a.segments.len(),
                c.num_red_vertices(),
                c.outmost_red,
                c.red_star
            );
            for (path, region) in a.paths.iter().zip(&a.regions) {
                let region = match region {
                    untangle::analysis::Region::Inside(vs) => format!("inside {vs:?}"),
                    other => format!("{other:?}"),
                };
                println!(
                    "path {:?} loops {:?} cut edges {} region {region}",
                    path.kind,
                    path.loop_vertices(),
                    path.cut_edges().len()
                );
            }
            for cr in &a.crossings {
                let e = topo.edges[cr.edge as usize];
                let t = g.mesh.triangles[cr.triangle as usize];
                println!(
                    "  crossing edge {}{:?} [{}{}] through tri {}{:?} [{}{}{}]",
                    cr.edge,
                    e,
                    c.red_vertex[e[0] as usize] as u8,
                    c.red_vertex[e[1] as usize] as u8,
                    cr.triangle,
                    t,
                    c.red_vertex[t[0] as usize] as u8,
                    c.red_vertex[t[1] as usize] as u8,
                    c.red_vertex[t[2] as usize] as u8,
                );
            }
            for op in r.chako().operations() {
                println!(
                    "  op {:?} subj {:?} target {} tri {} level {}",
                    op.kind, op.subjects, op.target, op.triangle, op.level
                );
                let mut vs = op.subjects.clone();
                vs.push(op.target);
                for &s in &op.subjects {
                    let w = (pos[s as usize] - pos[op.target as usize]).norm();
                    let cu = r.chako().current_uv();
                    let ou = r.chako().original_uv();
                    let rest = (cu[s as usize] - cu[op.target as usize]).norm();
                    let orig = (ou[s as usize] - ou[op.target as usize]).norm();
                    println!(
                        "    {s}-{}: world {w:.4} rest {rest:.4} orig {orig:.4}",
                        op.target
                    );
                }
            }
            println!("  eps_rg {:.4}", r.chako().eps_rg());
        }
        let (st, sr) = r.step().unwrap();
        if at.contains(&i) {
            println!(
                "  step: pulls +{} ~{} shrinks +{} ~{} rev {} | springs {} prox {} imp {} zones {} stalled {}",
                st.uv.pulls_started,
                st.uv.pulls_continued,
                st.uv.shrinks_started,
                st.uv.shrinks_continued,
                st.uv.revoked_levels,
                sr.contact_springs,
                sr.collisions.proximity_impulses,
                sr.collisions.impulses,
                sr.collisions.impact_zones,
                sr.collisions.stalled
            );
        }
    }
}
