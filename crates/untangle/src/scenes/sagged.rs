//! Garments tangled by simulation without self-collision, the way Cha & Ko 2022 describe
//! tanglements arising in practice (Sec. 1: a step that starts with self-collisions unresolved):
//! the garment, its top vertices pinned, sags under gravity for a few steps with the collision
//! handling switched off, so its folds pass through each other. BLIs are allowed.

use crate::error::Result;
use crate::geom::Vec3;
use crate::mesh::{Garment, Mesh};
use crate::sim::{SimParams, Simulator, UniformThickness};

/// Gravity used for the ARCSim garments (z up).
pub const GRAVITY_Z: Vec3 = Vec3::new(0.0, 0.0, -9.81);

/// The highest `fraction` of the vertices of `mesh` along `up` (at least one), highest first
/// (ties by index).
pub fn top_vertices(mesh: &Mesh, up: &Vec3, fraction: f64) -> Vec<u32> {
    let mut by_height: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    by_height.sort_by(|&a, &b| {
        let (ha, hb) = (
            mesh.positions[a as usize].dot(up),
            mesh.positions[b as usize].dot(up),
        );
        hb.total_cmp(&ha).then(a.cmp(&b))
    });
    let k = ((mesh.positions.len() as f64 * fraction).ceil() as usize)
        .clamp(1, mesh.positions.len().max(1));
    by_height.truncate(k);
    by_height
}

/// `garment` after `steps` simulator steps with `gravity`, the vertices `pins` held, and
/// collision handling off: a copy of its mesh at the sagged positions.
pub fn sagged(garment: &Garment, gravity: Vec3, pins: &[u32], steps: usize) -> Result<Mesh> {
    let mut sim = Simulator::new(
        garment,
        SimParams {
            gravity,
            collisions: false,
            ..SimParams::default()
        },
    )?;
    for &v in pins {
        sim.set_pinned(v, true)?;
    }
    for _ in 0..steps {
        sim.step(&UniformThickness(0.0));
    }
    let mut m = garment.mesh.clone();
    m.positions = sim.positions().to_vec();
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_vertices_pins_and_sagging() {
        // A tilted sheet at its rest shape (isometric to the uv).
        let (c, sn) = (0.5f64.sqrt(), 0.5f64.sqrt());
        let m =
            crate::scenes::handkerchief("s", 6, 6, 0.3, 0.3, |p| Vec3::new(p.x, c * p.y, sn * p.y));
        let top = top_vertices(&m, &Vec3::z(), 0.1);
        assert_eq!(top.len(), (49.0f64 * 0.1).ceil() as usize);
        let zmax = m.positions.iter().map(|p| p.z).fold(f64::MIN, f64::max);
        // Highest first; every pinned vertex is at least as high as every other.
        let lowest_pinned = m.positions[*top.last().unwrap() as usize].z;
        assert_eq!(m.positions[top[0] as usize].z, zmax);
        for (i, p) in m.positions.iter().enumerate() {
            if !top.contains(&(i as u32)) {
                assert!(p.z <= lowest_pinned);
            }
        }
        let g = Garment::new(m.clone()).unwrap();
        assert_eq!(
            sagged(&g, GRAVITY_Z, &top, 0).unwrap().positions,
            m.positions
        );
        let s = sagged(&g, GRAVITY_Z, &top, 10).unwrap();
        let (mut before, mut after) = (0.0, 0.0);
        for (i, (a, b)) in s.positions.iter().zip(&m.positions).enumerate() {
            if top.contains(&(i as u32)) {
                assert_eq!(a, b);
            } else {
                after += a.z;
                before += b.z;
            }
        }
        assert!(
            after < before - 1e-3,
            "the free part did not fall: {after} vs {before}"
        );
    }
}
