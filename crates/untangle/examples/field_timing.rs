use untangle::geom::Vec3;
use untangle::implicit::{layers::build_field, shapes::sphere_mesh, FieldParams};
fn main() {
    let m = sphere_mesh("s", &Vec3::zeros(), 0.5, 32);
    for samples in [300, 500, 700, 900] {
        let p = FieldParams {
            samples,
            max_nodes: 300_000,
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let f = build_field(&m, &Vec3::zeros(), false, &p).unwrap();
        println!(
            "{samples} -> {} samples {:?} total {:.0} ms nodes {}",
            f.num_samples,
            f.timing_ms,
            t.elapsed().as_secs_f64() * 1e3,
            f.f.num_nodes()
        );
    }
}
