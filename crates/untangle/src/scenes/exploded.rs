//! The exploded handkerchief of Cha & Ko 2022, Sec. 9.2: a 14 x 14-cell handkerchief (392
//! triangles; the paper's had 388) centred at the origin whose vertices in the central area
//! (`|x|, |y| <= 0.3` of a unit side: 81 of 225) are thrown to random spherical coordinates
//! `(r, phi, psi)` drawn from `[0, r0] x [0, 2 pi] x [-pi, pi]`. The rest, including the boundary
//! ring, keeps its place, so no BLI occurs; a draw that still produces a BLI (or any path ending
//! on the boundary) is redrawn from the same seeded stream, so every seed gives a scene within the
//! theorem's range.

//!
//! [`explode_patches`] applies the same kind of explosion to small patches of any garment (the
//! tangled garments of Sec. 9.3 and the seam measurements of Sec. 8 / Table 1).

use super::{handkerchief, Scene};
use crate::analysis::{analyze, AnalysisMesh};
use crate::geom::Vec3;
use crate::mesh::{Mesh, Topology};
use rand::{Rng, SeedableRng};

/// Default ball radius, relative to the handkerchief side 1.
pub const R0: f64 = 0.25;
/// Half-width of the central area whose vertices are thrown.
pub const CENTRAL: f64 = 0.3001;

/// Where and how far the vertices of the handkerchief are thrown (Cha & Ko 2022, Sec. 9.2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Explosion {
    /// Ball radius `r0`, relative to the handkerchief side 1.
    pub r0: f64,
    /// Half-width of the central square (or radius of the central disc) whose vertices are thrown.
    pub central: f64,
    /// A central disc instead of a square.
    pub disc: bool,
}

impl Default for Explosion {
    fn default() -> Self {
        Explosion {
            r0: R0,
            central: CENTRAL,
            disc: false,
        }
    }
}

/// The exploded handkerchief for `seed`, with `n x n` cells (`n = 14` in the paper's setting).
pub fn exploded(seed: u64, n: usize) -> Scene {
    exploded_with(seed, n, Explosion::default())
}

/// [`exploded`] with the explosion's parameters given.
pub fn exploded_with(seed: u64, n: usize, explosion: Explosion) -> Scene {
    let n = n.max(4);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let base = handkerchief("handkerchief", n, n, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
    let c = explosion.central;
    let kept: Vec<bool> = base
        .uv
        .as_ref()
        .expect("handkerchief has uv")
        .coords
        .iter()
        .map(|p| {
            if explosion.disc {
                p.x * p.x + p.y * p.y > c * c
            } else {
                p.x.abs() > c || p.y.abs() > c
            }
        })
        .collect();
    for _attempt in 0..1000 {
        let mut m = base.clone();
        for (p, &b) in m.positions.iter_mut().zip(&kept) {
            if b {
                continue;
            }
            let r: f64 = rng.random_range(0.0..explosion.r0);
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

/// Mean world-space length of the edges of `topology` at `positions`.
pub fn mean_edge_length(positions: &[Vec3], topology: &Topology) -> f64 {
    topology
        .edges
        .iter()
        .map(|e| (positions[e[0] as usize] - positions[e[1] as usize]).norm())
        .sum::<f64>()
        / topology.num_edges().max(1) as f64
}

/// Tangles a garment locally, in the manner of Cha & Ko Sec. 9.2 applied to patches: `patches`
/// times, an interior vertex is drawn (seeded), and every vertex within two rings of it is thrown
/// to a uniformly random direction at a uniform distance in `[0, r)` from the centre's current
/// position, `r` being the mesh's mean edge length (returned). Patches may overlap; boundary
/// vertices can move when they lie in a patch. Same `seed`, same result.
pub fn explode_patches(mesh: &mut Mesh, topology: &Topology, patches: usize, seed: u64) -> f64 {
    let r0 = mean_edge_length(&mesh.positions, topology);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let interior: Vec<u32> = (0..mesh.positions.len() as u32)
        .filter(|&v| !topology.boundary_vertex[v as usize])
        .collect();
    if interior.is_empty() {
        return r0;
    }
    for _ in 0..patches {
        let c = interior[rng.random_range(0..interior.len())];
        let centre = mesh.positions[c as usize];
        let mut ring = vec![c];
        for _ in 0..2 {
            let next: Vec<u32> = ring
                .iter()
                .flat_map(|&v| topology.vertex_neighbors.row(v as usize).iter().copied())
                .collect();
            ring.extend(next);
            ring.sort_unstable();
            ring.dedup();
        }
        for v in ring {
            let r = rng.random_range(0.0..r0);
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let z: f64 = rng.random_range(-1.0..1.0);
            let s = (1.0 - z * z).sqrt();
            mesh.positions[v as usize] =
                centre + Vec3::new(r * s * phi.cos(), r * s * phi.sin(), r * z);
        }
    }
    r0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sheet() -> (Mesh, Topology) {
        let m = handkerchief("sheet", 12, 12, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
        let t = Topology::new(&m).unwrap();
        (m, t)
    }

    /// Graph distance (in edges) from `c`, by breadth-first search: the oracle for "two rings".
    fn hops(t: &Topology, c: u32) -> Vec<usize> {
        let mut d = vec![usize::MAX; t.vertex_neighbors.rows()];
        d[c as usize] = 0;
        let mut queue = std::collections::VecDeque::from([c]);
        while let Some(v) = queue.pop_front() {
            for &w in t.vertex_neighbors.row(v as usize) {
                if d[w as usize] == usize::MAX {
                    d[w as usize] = d[v as usize] + 1;
                    queue.push_back(w);
                }
            }
        }
        d
    }

    #[test]
    fn mean_edge_length_of_a_unit_grid() {
        // 12 x 12 cells of side 1/12 with one diagonal each: 2 * 12 * 13 axis edges of length
        // h and 144 diagonals of length h * sqrt(2).
        let (m, t) = sheet();
        let h = 1.0 / 12.0;
        let want = (2.0 * 12.0 * 13.0 * h + 144.0 * h * 2f64.sqrt()) / (2.0 * 12.0 * 13.0 + 144.0);
        assert!((mean_edge_length(&m.positions, &t) - want).abs() < 1e-12);
    }

    #[test]
    fn one_patch_moves_exactly_two_rings_within_the_radius_and_tangles() {
        let (m0, t) = sheet();
        for seed in 0..8 {
            let mut m = m0.clone();
            let r0 = explode_patches(&mut m, &t, 1, seed);
            let moved: Vec<u32> = (0..m.positions.len() as u32)
                .filter(|&v| m.positions[v as usize] != m0.positions[v as usize])
                .collect();
            // Some interior vertex is the centre: its two-ring is exactly the moved set (every
            // thrown vertex lands elsewhere almost surely), and every moved vertex lies within
            // r0 of the centre's original position.
            let is_centre = |c: u32| {
                let d = hops(&t, c);
                let ring: Vec<u32> = (0..d.len() as u32)
                    .filter(|&v| d[v as usize] <= 2)
                    .collect();
                !t.boundary_vertex[c as usize]
                    && ring == moved
                    && moved
                        .iter()
                        .all(|&v| (m.positions[v as usize] - m0.positions[c as usize]).norm() < r0)
            };
            assert!(moved.len() >= 7, "seed {seed}: {} moved", moved.len());
            assert!(
                moved.iter().any(|&c| is_centre(c)),
                "seed {seed}: no centre"
            );
            // Deterministic, and the explosion tangles the sheet.
            let mut again = m0.clone();
            explode_patches(&mut again, &t, 1, seed);
            assert_eq!(again.positions, m.positions);
            let (am, pos) = AnalysisMesh::single(&m).unwrap();
            assert!(!analyze(&am, &pos).unwrap().is_clean(), "seed {seed}");
        }
    }

    /// The thrown set is exactly the central square or disc (the oracle: the flat sheet's own
    /// coordinates), every thrown vertex lands within `r0` of the centre, the default is the
    /// square of `CENTRAL` and `R0`, and no path reaches the boundary.
    #[test]
    fn the_explosion_throws_exactly_the_central_area_into_the_ball() {
        let flat = handkerchief("flat", 14, 14, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
        for (e, want) in [
            (Explosion::default(), 81),
            (
                Explosion {
                    r0: 0.1,
                    central: 0.33,
                    disc: true,
                },
                69,
            ),
        ] {
            for seed in 0..3 {
                let s = exploded_with(seed, 14, e);
                let m = &s.meshes[0];
                let mut thrown = 0;
                for (p, q) in m.positions.iter().zip(&flat.positions) {
                    let inside = if e.disc {
                        q.x * q.x + q.y * q.y <= e.central * e.central
                    } else {
                        q.x.abs() <= e.central && q.y.abs() <= e.central
                    };
                    if inside {
                        thrown += 1;
                        assert!(p.norm() < e.r0, "{e:?} seed {seed}: {p:?}");
                    } else {
                        assert_eq!(p, q);
                    }
                }
                assert_eq!(thrown, want, "{e:?}");
                let (am, pos) = AnalysisMesh::single(m).unwrap();
                let a = analyze(&am, &pos).unwrap();
                assert!(!a.is_clean() && a.paths.iter().all(|p| p.closed));
            }
        }
        assert_eq!(
            exploded(5, 14).meshes[0].positions,
            exploded_with(5, 14, Explosion::default()).meshes[0].positions
        );
    }
}
