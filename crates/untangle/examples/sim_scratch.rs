use untangle::geom::Vec3;
use untangle::mesh::{Garment, Mesh};
use untangle::scenes::handkerchief;
use untangle::sim::{Obstacle, SimParams, Simulator, UniformThickness};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(14);
    let steps: usize = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(250);
    let cloth = handkerchief("sheet", n, n, 0.5, 0.5, |p| {
        Vec3::new(p.x, p.y + 0.27, 0.02 * (6.0 * p.y).sin() + 0.01 * p.x)
    });
    let g = Garment::new(cloth).unwrap();
    let g = &g;
    let mut sim = Simulator::new(
        g,
        SimParams {
            collisions: std::env::var("NOCOL").is_err(),
            proximity: std::env::var("NOPROX").is_err(),
            friction: std::env::var("MU")
                .map(|s| s.parse().unwrap())
                .unwrap_or(0.2),
            cg_max_iterations: std::env::var("CGMAX")
                .map(|s| s.parse().unwrap())
                .unwrap_or(200),
            ..SimParams::default()
        },
    )
    .unwrap();
    let half = 2.0;
    let fl = Mesh::new(
        "floor",
        vec![
            Vec3::new(-half, 0.0, -half),
            Vec3::new(half, 0.0, -half),
            Vec3::new(half, 0.0, half),
            Vec3::new(-half, 0.0, half),
        ],
        vec![[0, 2, 1], [0, 3, 2]],
    )
    .unwrap();
    sim.add_obstacle(Obstacle::from_mesh(&fl, 2e-3, 0.3).unwrap())
        .unwrap();
    let pol = UniformThickness(2e-3);
    for s in 0..steps {
        let r = sim.step(&pol);
        worst(&sim, g);
        let c = &r.collisions;
        println!("{s} t {:.1}ms (asm {:.1} cg {:.1} col {:.1}) cg {} | cand {} prox {} it {} first {} imp {} zit {} zones {} zv {} stall {} quit {} | ke {:.5} str {:.3}", r.timing.total, r.timing.assemble, r.timing.solve, r.timing.collisions, r.cg.iterations, c.candidates, c.proximity_impulses, c.iterations, c.first_pass_collisions, c.impulses, c.zone_iterations, c.impact_zones, c.zone_vertices, c.stalled, c.administrative_quit, r.energy.kinetic, r.max_stretch);
    }
}
#[allow(dead_code)]
fn worst(sim: &Simulator, g: &Garment) {
    let uv = &g.uv().coords;
    let mut best = (0.0, 0, 0);
    for t in sim.triangles() {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let s = (sim.positions()[a] - sim.positions()[b]).norm() / (uv[a] - uv[b]).norm() - 1.0;
            if s > best.0 {
                best = (s, a, b);
            }
        }
    }
    let (s, a, b) = best;
    eprintln!(
        "worst {s} edge {a}-{b} xa {:?} xb {:?} va {:?} vb {:?}",
        sim.positions()[a].as_slice(),
        sim.positions()[b].as_slice(),
        sim.velocities()[a].as_slice(),
        sim.velocities()[b].as_slice()
    );
}
