//! Analytic shapes with known answers: sphere and cylinder meshes, and their exact signed
//! distance fields as layers (used by the tests and the benchmark to check the operators and the
//! projection independently of the HRBF approximation).

use super::field::{FieldSample, LayerField};
use crate::geom::Vec3;
use crate::mesh::Mesh;

/// A UV sphere with `n` rings (and `2n` segments), counter-clockwise seen from outside.
pub fn sphere_mesh(name: &str, centre: &Vec3, radius: f64, n: usize) -> Mesh {
    let n = n.max(3);
    let seg = 2 * n;
    let mut pos = vec![centre + Vec3::new(0.0, 0.0, radius)];
    for r in 1..n {
        let th = std::f64::consts::PI * r as f64 / n as f64;
        for s in 0..seg {
            let ph = 2.0 * std::f64::consts::PI * s as f64 / seg as f64;
            pos.push(
                centre + radius * Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()),
            );
        }
    }
    pos.push(centre - Vec3::new(0.0, 0.0, radius));
    let south = (pos.len() - 1) as u32;
    let ring = |r: usize, s: usize| (1 + (r - 1) * seg + s % seg) as u32;
    let mut tris = Vec::new();
    for s in 0..seg {
        tris.push([0, ring(1, s), ring(1, s + 1)]);
        tris.push([south, ring(n - 1, s + 1), ring(n - 1, s)]);
    }
    for r in 1..n - 1 {
        for s in 0..seg {
            tris.push([ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)]);
            tris.push([ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)]);
        }
    }
    Mesh::new(name, pos, tris).expect("a valid sphere")
}

/// A cylinder of `radius` around the z axis, `z ∈ [-h/2, h/2]`, with `seg` segments and
/// `rings` rows of quads; open at both ends unless `closed` (then capped by fans).
pub fn cylinder_mesh(
    name: &str,
    radius: f64,
    h: f64,
    seg: usize,
    rings: usize,
    closed: bool,
) -> Mesh {
    let (seg, rings) = (seg.max(3), rings.max(1));
    let mut pos = Vec::new();
    for r in 0..=rings {
        let z = -h / 2.0 + h * r as f64 / rings as f64;
        for s in 0..seg {
            let ph = 2.0 * std::f64::consts::PI * s as f64 / seg as f64;
            pos.push(Vec3::new(radius * ph.cos(), radius * ph.sin(), z));
        }
    }
    let id = |r: usize, s: usize| (r * seg + s % seg) as u32;
    let mut tris = Vec::new();
    for r in 0..rings {
        for s in 0..seg {
            tris.push([id(r, s), id(r, s + 1), id(r + 1, s + 1)]);
            tris.push([id(r, s), id(r + 1, s + 1), id(r + 1, s)]);
        }
    }
    if closed {
        let bottom = pos.len() as u32;
        pos.push(Vec3::new(0.0, 0.0, -h / 2.0));
        let top = pos.len() as u32;
        pos.push(Vec3::new(0.0, 0.0, h / 2.0));
        for s in 0..seg {
            tris.push([bottom, id(0, s + 1), id(0, s)]);
            tris.push([top, id(rings, s), id(rings, s + 1)]);
        }
    }
    Mesh::new(name, pos, tris).expect("a valid cylinder")
}

/// Exact signed distance to a sphere (negative inside), influential everywhere.
#[derive(Clone, Copy, Debug)]
pub struct SphereField {
    /// Centre.
    pub centre: Vec3,
    /// Radius.
    pub radius: f64,
}

impl SphereField {
    /// Spheres of the given radii about the origin: the analytic nested layers (exact
    /// separations) of the layer tests.
    pub fn concentric(radii: &[f64]) -> Vec<SphereField> {
        radii
            .iter()
            .map(|&radius| SphereField {
                centre: Vec3::zeros(),
                radius,
            })
            .collect()
    }
}

impl LayerField for SphereField {
    fn sample(&self, p: &Vec3) -> Option<FieldSample> {
        let v = p - self.centre;
        let r = v.norm();
        let g = if r > 0.0 { v / r } else { Vec3::z() };
        Some(FieldSample {
            value: r - self.radius,
            gradient: g,
            fade: 0.0,
            fade_gradient: Vec3::zeros(),
        })
    }
}

/// Exact signed distance to an infinite cylinder around the z axis, influential for
/// `|z| < half_height` (the co-variant field of an open tube).
#[derive(Clone, Copy, Debug)]
pub struct CylinderField {
    /// Radius.
    pub radius: f64,
    /// Half of the height of the influence region.
    pub half_height: f64,
}

impl LayerField for CylinderField {
    fn sample(&self, p: &Vec3) -> Option<FieldSample> {
        let v = Vec3::new(p.x, p.y, 0.0);
        let r = v.norm();
        let g = if r > 0.0 { v / r } else { Vec3::x() };
        Some(FieldSample {
            value: r - self.radius,
            gradient: g,
            fade: if p.z.abs() < self.half_height {
                0.0
            } else {
                1.0
            },
            fade_gradient: Vec3::zeros(),
        })
    }
}

/// A linear field `scale · (n · p − offset)` (a plane whose field has gradient norm `scale`, so
/// not a distance field unless `scale = 1`), influential everywhere: the exact local model of
/// two layers meeting at an angle, used to check the thickness rule (Sec. 6.2).
#[derive(Clone, Copy, Debug)]
pub struct PlaneField {
    /// Unit normal.
    pub normal: Vec3,
    /// Signed distance of the plane from the origin along `normal`.
    pub offset: f64,
    /// Gradient norm.
    pub scale: f64,
}

impl LayerField for PlaneField {
    fn sample(&self, p: &Vec3) -> Option<FieldSample> {
        Some(FieldSample {
            value: self.scale * (self.normal.dot(p) - self.offset),
            gradient: self.normal * self.scale,
            fade: 0.0,
            fade_gradient: Vec3::zeros(),
        })
    }
}
