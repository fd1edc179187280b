//! The exploded handkerchief of Cha & Ko 2022, Sec. 9.2: a 14 x 14-cell handkerchief (392
//! triangles; the paper's had 388) centred at the origin whose vertices in the central area
//! (`|x|, |y| <= 0.3` of a unit side: 81 of 225) are thrown to random spherical coordinates
//! `(r, phi, psi)` drawn from `[0, r0] x [0, 2 pi] x [-pi, pi]`. The rest, including the boundary
//! ring, keeps its place, so no BLI occurs; a draw that still produces a BLI (or any path ending
//! on the boundary) is redrawn from the same seeded stream, so every seed gives a scene within the
//! theorem's range.

use super::{handkerchief, Scene};
use crate::analysis::{analyze, AnalysisMesh};
use crate::geom::Vec3;
use rand::{Rng, SeedableRng};

/// Default ball radius, relative to the handkerchief side 1.
pub const R0: f64 = 0.25;
/// Half-width of the central area whose vertices are thrown.
pub const CENTRAL: f64 = 0.3001;

/// The exploded handkerchief for `seed`, with `n x n` cells (`n = 14` in the paper's setting).
pub fn exploded(seed: u64, n: usize) -> Scene {
    let n = n.max(4);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let base = handkerchief("handkerchief", n, n, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
    let kept: Vec<bool> = base
        .uv
        .as_ref()
        .expect("handkerchief has uv")
        .coords
        .iter()
        .map(|p| p.x.abs() > CENTRAL || p.y.abs() > CENTRAL)
        .collect();
    for _attempt in 0..1000 {
        let mut m = base.clone();
        for (p, &b) in m.positions.iter_mut().zip(&kept) {
            if b {
                continue;
            }
            let r: f64 = rng.random_range(0.0..R0);
            let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let psi: f64 = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
            *p = Vec3::new(
                r * psi.cos() * phi.cos(),
                r * psi.cos() * phi.sin(),
                r * psi.sin(),
            );
        }
        let Ok((am, pos)) = AnalysisMesh::single(&m) else {
            continue; // a (measure-zero) degenerate triangle: draw again
        };
        let Ok(a) = analyze(&am, &pos) else { continue };
        if a.paths.iter().all(|p| p.closed) {
            return Scene {
                name: format!("exploded-{seed}"),
                meshes: vec![m],
                expected: vec![],
            };
        }
    }
    unreachable!("1000 draws without a BLI-free explosion")
}
