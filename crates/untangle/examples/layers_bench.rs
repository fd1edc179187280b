//! Benchmark of the layered untangling (Buffet et al. 2019, Tables 1 and 2 analogues):
//! field precomputation per garment, projection time against the number of vertices
//! (subdivision levels) and against the number of layers.
//!
//! `cargo run -p untangle --release --example layers_bench [LEVELS] [SHARED]`
use std::path::PathBuf;
use std::time::Instant;
use untangle::implicit::*;

fn main() {
    let max_level: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let shared = std::env::args()
        .nth(2)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")));
    let all = untangle::scenes::outfit::GARMENTS;
    println!("threads: {}", rayon::current_num_threads());
    println!("| layers (incl. body) | subdiv | vertices | fields (s) | max field per garment (s) | projection (s) | passes | between | with body |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for level in 1..=max_level {
        for k in 1..=all.len() {
            if level < max_level && k < all.len() {
                continue;
            }
            let (body, garments) =
                untangle::scenes::outfit::arcsim_outfit(&shared, &all[..k], level).expect("data");
            let inputs: Vec<GarmentInput> = garments
                .iter()
                .map(|m| GarmentInput {
                    mesh: m,
                    thickness: 0.01,
                    weight: 1.0,
                })
                .collect();
            let t = Instant::now();
            let out = untangle_layers(Some(&body), &inputs, &Params::default(), &|_| {}).unwrap();
            let total = t.elapsed().as_secs_f64();
            let fields: f64 =
                out.body_field_ms / 1e3 + out.reports.iter().map(|r| r.field_ms).sum::<f64>() / 1e3;
            let maxf = out.reports.iter().map(|r| r.field_ms).fold(0.0, f64::max) / 1e3;
            let proj: f64 = out.reports.iter().map(|r| r.projection_ms).sum::<f64>() / 1e3;
            let nv: usize = garments.iter().map(|m| m.positions.len()).sum();
            let refs: Vec<&untangle::mesh::Mesh> = garments.iter().collect();
            let v = verify(Some(&body), &refs, &out.positions).unwrap();
            let passes: Vec<usize> = out.reports.iter().map(|r| r.iterations).collect();
            println!("| {} | {level} | {nv} | {fields:.2} | {maxf:.2} | {proj:.2} | {passes:?} | {} | {} |", k + 1, v.between_layers, v.with_body);
            let _ = total;
        }
    }
}
