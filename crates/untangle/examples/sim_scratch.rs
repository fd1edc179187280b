use untangle::geom::Vec3;
use untangle::mesh::Garment;
use untangle::scenes::handkerchief;
use untangle::sim::{SimParams, Simulator, UniformThickness};

fn main() {
    let n: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(20);
    let m = handkerchief("sheet", n, n, 1.0, 1.0, |p| Vec3::new(p.x, 0.5, p.y));
    let g = Garment::new(m).unwrap();
    let mut sim = Simulator::new(&g, SimParams::default()).unwrap();
    sim.set_pinned(0, true).unwrap();
    sim.set_pinned(n as u32, true).unwrap();
    let pol = UniformThickness(2e-3);
    let steps: usize = std::env::args().nth(2).map(|s| s.parse().unwrap()).unwrap_or(200);
    for s in 0..steps {
        let r = sim.step(&pol);
        if s % 10 == 0 {
            println!("{s} asm {:.2} solve {:.2} coll {:.2} | cg {} res {:.1e} ke {:.4} es {:.4} eb {:.6} stretch {:.4} col {:?} t {:.2}ms {:?}", r.timing.assemble, r.timing.solve, r.timing.collisions, r.cg.iterations, r.cg.relative_residual, r.energy.kinetic, r.energy.stretch, r.energy.bend, r.max_stretch, (r.collisions.candidates, r.collisions.proximity_impulses, r.collisions.iterations, r.collisions.impact_zones, r.collisions.stalled), r.timing.total, r.collisions.timing);
        }
    }
}
