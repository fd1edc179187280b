//! A layered outfit from the ARCSim meshes (research licence, read from the shared data folder,
//! never copied): a body and garments placed and scaled so that they overlap deeply, for the
//! layered untangling (Buffet et al. 2019) tests and benchmark.
//!
//! Placement (garments are in metres, z up; see `shared/data/README.md`): the T-shirt is the
//! reference (hem at z = −0.24, shoulders at z ≈ 0.33, torso 0.49 m wide and 0.30 m deep,
//! centred near the z axis). The body (`guy_mannequin`, a closed blob in decimetres) is scaled
//! to a torso of 0.40 × 0.31 × 0.58 m ([`BODY_SIZE`]) from below the T-shirt's hem to its
//! shoulder line, so it pokes through the T-shirt at the shoulders and front and back. The
//! pants are lifted by 12 cm so their waist goes up inside the T-shirt's hem. The dress is
//! scaled by 1.4 about its bodice (it was made for a smaller body) and centred on the torso
//! with its top at z = 0.28: its bodice is narrower but deeper than the T-shirt, so the two
//! cross each other all around, and its skirt covers the pants' hips. The jacket is shrunk by
//! 8 % about its centroid so that it cuts through the T-shirt and the dress. Garments overlap by
//! up to about 6 cm, several times the 1 cm cloth thickness of the tests.

use crate::error::Result;
use crate::geom::{Aabb, Vec3};
use crate::mesh::obj::read_obj;
use crate::mesh::subdivide::subdivide;
use crate::mesh::Mesh;
use std::path::Path;

/// Garments known to [`arcsim_outfit`].
pub const GARMENTS: &[&str] = &["pants3", "dress3", "tshirt", "jacket"];

/// Where the torso is (the T-shirt's axis), in metres.
pub const TORSO: Vec3 = Vec3::new(0.005, 0.007, 0.02);

/// Extent of the body along x, y, z, in metres.
pub const BODY_SIZE: Vec3 = Vec3::new(0.40, 0.31, 0.58);

fn centroid(m: &Mesh) -> Vec3 {
    m.positions.iter().sum::<Vec3>() / m.positions.len().max(1) as f64
}

/// Places a garment of [`GARMENTS`] (unknown names are left where they are).
pub fn place_garment(mut m: Mesh, name: &str) -> Mesh {
    let c = centroid(&m);
    let bb = Aabb::from_points(&m.positions);
    let map: Box<dyn Fn(&Vec3) -> Vec3> = match name {
        "pants3" => Box::new(|p| p + Vec3::new(0.0, 0.0, 0.12)),
        "dress3" => {
            // The bodice: vertices in the top 35 % of the height.
            let cut = bb.max.z - 0.35 * bb.extent().z;
            let top: Vec<&Vec3> = m.positions.iter().filter(|p| p.z >= cut).collect();
            let tc = top.iter().copied().sum::<Vec3>() / top.len().max(1) as f64;
            let anchor = Vec3::new(tc.x, tc.y, bb.max.z);
            let target = Vec3::new(TORSO.x, TORSO.y, 0.30);
            Box::new(move |p| target + (p - anchor) * 1.25)
        }
        "jacket" => Box::new(move |p| c + (p - c) * 0.92),
        _ => Box::new(|p| *p),
    };
    for p in &mut m.positions {
        *p = map(p);
    }
    m
}

/// Scales a body (each axis separately) to `size` metres across, centred (box centre) at
/// `centre`.
pub fn place_body(mut m: Mesh, size: &Vec3, centre: &Vec3) -> Mesh {
    let b = Aabb::from_points(&m.positions);
    let e = b.extent();
    let s = Vec3::new(
        size.x / e.x.max(1e-12),
        size.y / e.y.max(1e-12),
        size.z / e.z.max(1e-12),
    );
    let c = (b.min + b.max) * 0.5;
    for p in &mut m.positions {
        *p = centre + (*p - c).component_mul(&s);
    }
    m
}

/// The body and the named garments (innermost first), each subdivided `subdivisions` times. A
/// name `NAME*S` is garment `NAME` scaled by `S` about its centroid after placement.
pub fn arcsim_outfit(
    shared: &Path,
    garments: &[&str],
    subdivisions: usize,
) -> Result<(Mesh, Vec<Mesh>)> {
    let dir = shared.join("data/arcsim/meshes");
    let body = place_body(
        read_obj(&dir.join("guy_mannequin/body0000.obj"))?,
        &BODY_SIZE,
        &TORSO,
    );
    let mut out = Vec::new();
    for name in garments {
        // `NAME*S`: the garment placed as usual, then scaled by `S` about its centroid (more
        // layers from the same meshes, as the stacked copies of Fig. 9).
        let (base, scale) = match name.split_once('*') {
            Some((b, s)) => (b, s.parse::<f64>().unwrap_or(1.0)),
            None => (*name, 1.0),
        };
        let mut m = place_garment(read_obj(&dir.join(format!("{base}.obj")))?, base);
        if scale != 1.0 {
            let c = centroid(&m);
            for p in &mut m.positions {
                *p = c + (*p - c) * scale;
            }
            m.name = name.to_string();
        }
        for _ in 0..subdivisions {
            m = subdivide(&m);
        }
        out.push(m);
    }
    Ok((body, out))
}
