//! Benchmark of the generalized winding numbers behind the analysis's winding regions
//! (`analysis::winding`): the cluster hierarchy's build time, its evaluation time per vertex,
//! the direct sum's, and the largest difference between the two over every vertex; then how many
//! vertices have a winding number in each bin of 0.1 (the contrast the regions rely on: about
//! 1/2 on a garment's surface, about 1.5 where its cloth lies inside another of its tubes).
//!
//! ```text
//! cargo run --release -p untangle --example winding_bench -- [MESH.obj] [runs]
//! ```
//!
//! Without a mesh it uses `untangle scene tubes` (`scenes::garment::overlapping_tubes(32, 0.85)`).
//! Times are the median over `runs` (default 9) on the calling thread's rayon pool.

use std::time::Instant;
use untangle::analysis::winding::{at_vertex, Tree};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mesh = match std::env::args().nth(1) {
        Some(p) => untangle::mesh::obj::read_obj(std::path::Path::new(&p)).expect("a mesh"),
        None => untangle::scenes::garment::overlapping_tubes(32, 0.85).meshes[0].clone(),
    };
    let runs: usize = std::env::args()
        .nth(2)
        .map(|s| s.parse().expect("a number"))
        .unwrap_or(9);
    let (pos, tris) = (&mesh.positions, &mesh.triangles);
    let range = 0..tris.len() as u32;
    let all: Vec<u32> = (0..pos.len() as u32).collect();
    let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
    let mut build = Vec::new();
    let mut eval = Vec::new();
    let mut tree_values = Vec::new();
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        let tree = Tree::new(pos, tris, range.clone());
        build.push(ms(t));
        let t = Instant::now();
        tree_values = tree.at_vertices(&all, pos, tris);
        eval.push(ms(t));
    }
    let t = Instant::now();
    let direct: Vec<f64> = all
        .iter()
        .map(|&v| at_vertex(v, pos, tris, range.clone()))
        .collect();
    let direct_ms = ms(t);
    let worst = tree_values
        .iter()
        .zip(&direct)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let n = all.len() as f64;
    println!(
        "{}: {} vertices, {} triangles; tree build {:.3} ms, {:.2} us per vertex (all vertices, {} thread(s)); direct sum {:.1} us per vertex (one thread); largest difference {:.4}",
        mesh.name,
        pos.len(),
        tris.len(),
        median(build),
        median(eval) * 1e3 / n,
        rayon::current_num_threads(),
        direct_ms * 1e3 / n,
        worst
    );
    let mut bins = std::collections::BTreeMap::<i64, usize>::new();
    for w in &tree_values {
        *bins.entry((w * 10.0).floor() as i64).or_default() += 1;
    }
    let line: Vec<String> = bins
        .iter()
        .map(|(b, n)| {
            format!(
                "[{:.1}, {:.1}): {n}",
                *b as f64 / 10.0,
                (*b + 1) as f64 / 10.0
            )
        })
        .collect();
    println!("winding numbers: {}", line.join(", "));
}
