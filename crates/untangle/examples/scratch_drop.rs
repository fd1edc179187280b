use untangle::geom::Vec3;
use untangle::mesh::{Garment, Mesh};
use untangle::scenes::handkerchief;
use untangle::sim::{Obstacle, SimParams, Simulator, UniformThickness};

fn floor(y: f64, half: f64) -> Mesh {
    Mesh::new(
        "floor",
        vec![
            Vec3::new(-half, y, -half),
            Vec3::new(half, y, -half),
            Vec3::new(half, y, half),
            Vec3::new(-half, y, half),
        ],
        vec![[0, 2, 1], [0, 3, 2]],
    )
    .unwrap()
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let n: usize = a.get(1).map(|s| s.parse().unwrap()).unwrap_or(48);
    let steps: usize = a.get(2).map(|s| s.parse().unwrap()).unwrap_or(100);
    let mode = a.get(3).cloned().unwrap_or_default();
    let cloth = handkerchief("sheet", n, n, 0.5, 0.5, |p| {
        Vec3::new(p.x, p.y + 0.27, 0.02 * (6.0 * p.y).sin() + 0.01 * p.x)
    });
    let g = Garment::new(cloth.clone()).unwrap();
    let mut params = SimParams::default();
    if mode.contains("nofric") {
        params.friction = 0.0;
    }
    if mode.contains("tight") {
        params.cg_tolerance = 1e-7;
        params.cg_max_iterations = 20000;
    }
    if mode.contains("nocoll") {
        params.collisions = false;
    }
    if mode.contains("noprox") {
        params.proximity = false;
    }
    let mut sim = Simulator::new(&g, params).unwrap();
    let fl = floor(0.0, 2.0);
    let fr = if mode.contains("nofric") { 0.0 } else { 0.3 };
    sim.add_obstacle(Obstacle::from_mesh(&fl, 2e-3, fr).unwrap())
        .unwrap();
    let pol = UniformThickness(2e-3);
    for k in 0..steps {
        let r = sim.step(&pol);
        let c = &r.collisions;
        let miny = sim.positions().iter().map(|p| p.y).fold(f64::MAX, f64::min);
        println!(
            "{k:4} stretch {:8.4} cg {:3} {:.1e} cand {:6} prox {:5} it {:2} imp {:4} zit {:3} zones {:3}/{:5} stall {} ke {:.3e} miny {:.4} t {:.1} asm {:.1} cg {:.1} br {:.1} px {:.1} ccd {:.1} z {:.1}",
            r.max_stretch, r.cg.iterations, r.cg.relative_residual, c.candidates, c.proximity_impulses, c.iterations, c.impulses,
            c.zone_iterations, c.impact_zones, c.zone_vertices, c.stalled as u8, r.energy.kinetic, miny, r.timing.total, r.timing.assemble, r.timing.solve, c.timing.broad, c.timing.proximity, c.timing.impulses, c.timing.zones
        );
    }
}
