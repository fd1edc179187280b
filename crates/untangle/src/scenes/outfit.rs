//! A layered outfit from the ARCSim meshes (research licence, read from the shared data folder,
//! never copied): a body and garments placed and scaled so that they overlap deeply, for the
//! layered untangling (Buffet et al. 2019) tests and benchmark.
//!
//! Placement (garments are in metres, z up; see `shared/data/README.md`): the T-shirt is the
//! reference (hem at z = 0, torso centred near the z axis). The pants are lifted by 12 cm so
//! their waist goes up inside the T-shirt's hem; the dress is moved onto the torso axis with its
//! top at z = 0.25 (it covers the hips, the pants and the T-shirt's hem); the jacket is shrunk by
//! 8 % about its centroid so that it cuts through the T-shirt. The body (`guy_mannequin`, a
//! closed-ish blob in decimetres) is scaled to 0.4 m across (x) and centred on the torso, so it
//! pokes through the T-shirt and the jacket.

use crate::error::Result;
use crate::geom::{Aabb, Vec3};
use crate::mesh::obj::read_obj;
use crate::mesh::subdivide::subdivide;
use crate::mesh::Mesh;
use std::path::Path;

/// Garments known to [`arcsim_outfit`].
pub const GARMENTS: &[&str] = &["pants3", "tshirt", "dress3", "jacket"];

/// Where the torso is (the T-shirt's axis), in metres.
pub const TORSO: Vec3 = Vec3::new(0.005, 0.007, 0.16);

fn centroid(m: &Mesh) -> Vec3 {
    m.positions.iter().sum::<Vec3>() / m.positions.len().max(1) as f64
}

/// Places a garment of [`GARMENTS`] (unknown names are left where they are).
pub fn place_garment(mut m: Mesh, name: &str) -> Mesh {
    let c = centroid(&m);
    let map: Box<dyn Fn(&Vec3) -> Vec3> = match name {
        "pants3" => Box::new(|p| p + Vec3::new(0.0, 0.0, 0.12)),
        "dress3" => {
            let top = Aabb::from_points(&m.positions).max.z;
            let shift = Vec3::new(TORSO.x - c.x, TORSO.y - c.y, 0.25 - top);
            Box::new(move |p| p + shift)
        }
        "jacket" => Box::new(move |p| c + (p - c) * 0.92),
        _ => Box::new(|p| *p),
    };
    for p in &mut m.positions {
        *p = map(p);
    }
    m
}

/// Scales a body to `width` metres across x, centred at `centre`.
pub fn place_body(mut m: Mesh, width: f64, centre: &Vec3) -> Mesh {
    let b = Aabb::from_points(&m.positions);
    let s = width / b.extent().x.max(1e-12);
    let c = centroid(&m);
    for p in &mut m.positions {
        *p = centre + (*p - c) * s;
    }
    m
}

/// The body and the named garments (innermost first), each subdivided `subdivisions` times.
pub fn arcsim_outfit(
    shared: &Path,
    garments: &[&str],
    subdivisions: usize,
) -> Result<(Mesh, Vec<Mesh>)> {
    let dir = shared.join("data/arcsim/meshes");
    let body = place_body(
        read_obj(&dir.join("guy_mannequin/body0000.obj"))?,
        0.4,
        &TORSO,
    );
    let mut out = Vec::new();
    for name in garments {
        let mut m = place_garment(read_obj(&dir.join(format!("{name}.obj")))?, name);
        for _ in 0..subdivisions {
            m = subdivide(&m);
        }
        out.push(m);
    }
    Ok((body, out))
}
