//! The exploded handkerchief of Cha & Ko 2022, Sec. 9.2: a flat handkerchief centred at the
//! origin whose central vertices are re-positioned at random spherical coordinates
//! `(r, phi, theta)`, `r` uniform in `[0, r0]`. Only the central area is exploded, "to avoid the
//! BLI cases occurring"; the rest stays flat.

use super::sheet::handkerchief;
use crate::geom::Vec3;
use crate::mesh::Mesh;
use rand::{Rng, SeedableRng};

/// A `n x n`-cell unit handkerchief in the plane `z = 0` (uv = rest shape) whose vertices
/// within distance `central` of the centre (in the rest shape) are moved to random points of
/// the ball of radius `r0` (uniform in `r`, `phi` and `cos(theta)`), deterministically for
/// `seed`.
pub fn exploded_handkerchief(n: usize, r0: f64, central: f64, seed: u64) -> Mesh {
    let mut m = handkerchief("exploded", n, n, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let uv = m.uv.as_ref().expect("handkerchief has uv").coords.clone();
    for (p, q) in m.positions.iter_mut().zip(&uv) {
        if q.norm() < central {
            let r = rng.random_range(0.0..r0);
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let c: f64 = rng.random_range(-1.0..1.0);
            let s = (1.0 - c * c).sqrt();
            *p = Vec3::new(r * s * phi.cos(), r * s * phi.sin(), r * c);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_centre_moves_and_it_is_deterministic() {
        let a = exploded_handkerchief(10, 0.2, 0.25, 7);
        let b = exploded_handkerchief(10, 0.2, 0.25, 7);
        assert_eq!(a.positions, b.positions);
        let uv = &a.uv.as_ref().unwrap().coords;
        let mut moved = 0;
        for (p, q) in a.positions.iter().zip(uv) {
            if q.norm() < 0.25 {
                assert!(p.norm() <= 0.2);
                moved += 1;
            } else {
                assert_eq!(*p, Vec3::new(q.x, q.y, 0.0));
            }
        }
        assert!(moved > 10);
        a.validate().unwrap();
    }
}
