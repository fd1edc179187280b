use untangle::geom::Vec3;
use untangle::mesh::{obj, subdivide::subdivide, Garment};
use untangle::sim::{SimParams, Simulator, UniformThickness};
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let level: usize = a[1].parse().unwrap();
    let steps: usize = a[2].parse().unwrap();
    let mode = a.get(3).cloned().unwrap_or_default();
    let mut m = obj::read_obj(std::path::Path::new(
        "/work/shared/data/arcsim/meshes/tshirt.obj",
    ))
    .unwrap();
    for _ in 0..level {
        m = subdivide(&m);
    }
    if !mode.contains("uv") {
        m.uv = Some(untangle::sim::rest::isometric_uv(
            &m.positions,
            &m.triangles,
        ));
    }
    let g = Garment::new(m.clone()).unwrap();
    let mut params = SimParams {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        ..SimParams::default()
    };
    if mode.contains("nocoll") {
        params.collisions = false;
    }
    if let Some(t) = std::env::var("TOL").ok().and_then(|s| s.parse().ok()) {
        params.cg_tolerance = t;
    }
    if mode.contains("tight") {
        params.cg_tolerance = 1e-8;
        params.cg_max_iterations = 20000;
    }
    let mut sim = Simulator::new(&g, params).unwrap();
    println!("initial stretch {}", sim.max_stretch());
    let top = m.positions.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    for (i, p) in m.positions.iter().enumerate() {
        if p.z >= top - 0.01 {
            sim.set_pinned(i as u32, true).unwrap();
        }
    }
    if !mode.contains("still") {
        let v: Vec<Vec3> = m
            .positions
            .iter()
            .map(|p| Vec3::new(0.3 * (top - p.z), 0.0, 0.0))
            .collect();
        sim.set_velocities(&v).unwrap();
    }
    let pol = UniformThickness(2e-3);
    for k in 0..steps {
        let r = sim.step(&pol);
        let c = &r.collisions;
        println!("{k} cg {} {:.1e} str {:.4} cand {} prox {} it {} imp {} zones {} {} ke {:.2e} ms {:.0}", r.cg.iterations, r.cg.relative_residual, r.max_stretch, c.candidates, c.proximity_impulses, c.iterations, c.impulses, c.zone_iterations, c.zone_vertices, r.energy.kinetic, r.timing.total);
    }
}
