//! Obstacles: static or animated triangle meshes (a body) the cloth collides with. An obstacle
//! moves linearly within a step from its current positions to the positions set for the end of
//! the step ([`Obstacles::set_next_positions`]); it has infinite mass, a thickness and a friction
//! coefficient.

use crate::error::{Error, Result};
use crate::geom::Vec3;
use crate::mesh::{Mesh, Topology};

/// One obstacle as the caller describes it.
#[derive(Clone, Debug)]
pub struct Obstacle {
    /// Name for messages.
    pub name: String,
    /// Positions now.
    pub positions: Vec<Vec3>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Distance the cloth keeps from it (metres).
    pub thickness: f64,
    /// Coulomb friction coefficient against the cloth.
    pub friction: f64,
}

impl Obstacle {
    /// An obstacle from a validated mesh.
    pub fn from_mesh(mesh: &Mesh, thickness: f64, friction: f64) -> Result<Obstacle> {
        mesh.validate()?;
        let ok = |x: f64| x >= 0.0 && x.is_finite();
        if !ok(thickness) || !ok(friction) {
            return Err(Error::Parameter(format!(
                "obstacle '{}': thickness and friction must be finite and >= 0",
                mesh.name
            )));
        }
        Ok(Obstacle {
            name: mesh.name.clone(),
            positions: mesh.positions.clone(),
            triangles: mesh.triangles.clone(),
            thickness,
            friction,
        })
    }
}

/// All obstacles concatenated: one vertex, triangle and edge numbering, with the positions at
/// the start and at the end of the coming step.
#[derive(Clone, Debug, Default)]
pub struct Obstacles {
    /// Start-of-step positions.
    pub start: Vec<Vec3>,
    /// End-of-step positions.
    pub end: Vec<Vec3>,
    /// Triangles (concatenated numbering).
    pub triangles: Vec<[u32; 3]>,
    /// Unique edges, sorted vertex pairs.
    pub edges: Vec<[u32; 2]>,
    /// Obstacle index of each vertex.
    pub object_of_vertex: Vec<u32>,
    /// Vertex range of each obstacle.
    pub ranges: Vec<std::ops::Range<u32>>,
    /// Thickness of each obstacle.
    pub thickness: Vec<f64>,
    /// Friction of each obstacle.
    pub friction: Vec<f64>,
    /// Names.
    pub names: Vec<String>,
}

impl Obstacles {
    /// Adds an obstacle; returns its index.
    pub fn add(&mut self, o: Obstacle) -> Result<usize> {
        let v0 = self.start.len() as u32;
        let topo = Topology::from_triangles(&o.triangles, o.positions.len(), |t| {
            format!("obstacle '{}', triangle {}", o.name, t)
        })?;
        self.start.extend_from_slice(&o.positions);
        self.end.extend_from_slice(&o.positions);
        self.triangles
            .extend(o.triangles.iter().map(|t| t.map(|v| v + v0)));
        self.edges
            .extend(topo.edges.iter().map(|e| e.map(|v| v + v0)));
        let id = self.ranges.len() as u32;
        self.object_of_vertex
            .extend(std::iter::repeat_n(id, o.positions.len()));
        self.ranges.push(v0..self.start.len() as u32);
        self.thickness.push(o.thickness);
        self.friction.push(o.friction);
        self.names.push(o.name);
        Ok(id as usize)
    }

    /// Number of obstacles.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Sets where obstacle `id` will be at the end of the next step (same vertex count).
    pub fn set_next_positions(&mut self, id: usize, positions: &[Vec3]) -> Result<()> {
        let r = self
            .ranges
            .get(id)
            .ok_or_else(|| Error::Parameter(format!("no obstacle {id}")))?
            .clone();
        if positions.len() != r.len() {
            return Err(Error::input(
                format!("obstacle '{}'", self.names[id]),
                format!(
                    "new positions have {} vertices, the obstacle has {}",
                    positions.len(),
                    r.len()
                ),
            ));
        }
        if let Some(i) = positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(Error::input(
                format!("obstacle '{}'", self.names[id]),
                format!("vertex {} has a non-finite coordinate", i + 1),
            ));
        }
        self.end[r.start as usize..r.end as usize].copy_from_slice(positions);
        Ok(())
    }

    /// Ends a step: the end positions become the start positions.
    pub fn advance(&mut self) {
        self.start.copy_from_slice(&self.end);
    }

    /// Thickness of the obstacle owning vertex `v`.
    #[inline]
    pub fn thickness_of_vertex(&self, v: u32) -> f64 {
        self.thickness[self.object_of_vertex[v as usize] as usize]
    }

    /// Friction of the obstacle owning vertex `v`.
    #[inline]
    pub fn friction_of_vertex(&self, v: u32) -> f64 {
        self.friction[self.object_of_vertex[v as usize] as usize]
    }

    /// Largest thickness of all obstacles.
    pub fn max_thickness(&self) -> f64 {
        self.thickness.iter().copied().fold(0.0, f64::max)
    }
}

/// Carries the vertices of `first` through a sequence of body frames that do not share its mesh
/// (each frame re-meshed, as exported by many tools), so that the motion can be interpolated on
/// one topology: frame 0 is `first` itself; for every later frame, each vertex moves from where it
/// was in the previous frame to its closest point on that frame's surface (nearest triangle,
/// ties to the lower index). Returns one position list per frame, all with `first`'s vertex
/// count.
///
/// This is meaningful when consecutive frames are close compared with the body's features (the
/// projection tracks the surface; tangential motion is lost, and a vertex may jump to another
/// limb if the frames are far apart). Errors: a frame without triangles or with non-finite
/// positions.
pub fn track_frames(first: &Mesh, frames: &[Mesh]) -> Result<Vec<Vec<Vec3>>> {
    use rayon::prelude::*;
    let mut out = vec![first.positions.clone()];
    for f in frames {
        if f.triangles.is_empty() {
            return Err(Error::input(
                format!("body frame '{}'", f.name),
                "has no triangles to project onto",
            ));
        }
        if f.positions.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(Error::input(
                format!("body frame '{}'", f.name),
                "has a non-finite coordinate",
            ));
        }
        let boxes: Vec<crate::geom::Aabb> = f
            .triangles
            .iter()
            .map(|t| crate::geom::Aabb::from_points(&t.map(|k| f.positions[k as usize])))
            .collect();
        let bvh = crate::broad::Bvh::build(&boxes);
        let edge = f
            .triangles
            .iter()
            .map(|t| (f.positions[t[0] as usize] - f.positions[t[1] as usize]).norm())
            .sum::<f64>()
            / f.triangles.len() as f64;
        let root = bvh.root_aabb();
        let diag = (root.max - root.min).norm();
        let prev = out.last().expect("frame 0 is there");
        let next: Vec<Vec3> = prev
            .par_iter()
            .map(|p| {
                let nearest = |r: f64| {
                    let q = crate::geom::Aabb::from_points(&[*p]).inflated(r);
                    let mut best: Option<(f64, u32, Vec3)> = None;
                    bvh.query(&q, |t| {
                        let c = f.triangles[t as usize].map(|k| f.positions[k as usize]);
                        let (d2, w) = crate::geom::distance::point_triangle(p, &c[0], &c[1], &c[2]);
                        let better = match best {
                            None => true,
                            Some((bd, bt, _)) => d2 < bd || (d2 == bd && t < bt),
                        };
                        if better {
                            best = Some((d2, t, c[0] * w[0] + c[1] * w[1] + c[2] * w[2]));
                        }
                    });
                    best
                };
                // Grow a box until it holds a triangle, then search the box of that distance
                // (which holds every closer triangle).
                let mut r = edge.max(1e-12 * (1.0 + diag));
                let found = loop {
                    if let Some(b) = nearest(r) {
                        break b;
                    }
                    r *= 2.0;
                };
                nearest(found.0.sqrt() * (1.0 + 1e-12) + 1e-300).map_or(found.2, |b| b.2)
            })
            .collect();
        out.push(next);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UV sphere of radius `r` around `c` with `m` rings and `2m` segments.
    fn sphere(c: Vec3, r: f64, m: usize) -> Mesh {
        let mut pos = vec![c + Vec3::new(0.0, 0.0, r), c - Vec3::new(0.0, 0.0, r)];
        let s = 2 * m;
        for i in 1..m {
            let th = std::f64::consts::PI * i as f64 / m as f64;
            for j in 0..s {
                let ph = 2.0 * std::f64::consts::PI * j as f64 / s as f64;
                pos.push(c + Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * r);
            }
        }
        let ring = |i: usize, j: usize| (2 + (i - 1) * s + j % s) as u32;
        let mut tris = Vec::new();
        for j in 0..s {
            tris.push([0, ring(1, j), ring(1, j + 1)]);
            tris.push([1, ring(m - 1, j + 1), ring(m - 1, j)]);
        }
        for i in 1..m - 1 {
            for j in 0..s {
                tris.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
                tris.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
            }
        }
        Mesh::new("sphere", pos, tris).unwrap()
    }

    /// Frames of a sphere moving and growing, each meshed at another resolution: the tracked
    /// vertices of frame 0 lie on every frame's surface (oracle: brute-force distance to all of
    /// its triangles is zero) and follow the motion (close to the analytic sphere).
    #[test]
    fn tracked_vertices_lie_on_each_frame_and_follow_the_motion() {
        let first = sphere(Vec3::zeros(), 1.0, 8);
        let frames: Vec<Mesh> = (1..5)
            .map(|k| {
                let c = Vec3::new(0.1 * k as f64, 0.02 * k as f64, 0.0);
                sphere(c, 1.0 + 0.03 * k as f64, 8 + 3 * k)
            })
            .collect();
        let tracked = track_frames(&first, &frames).unwrap();
        assert_eq!(tracked.len(), 5);
        for (k, (pos, f)) in tracked[1..].iter().zip(&frames).enumerate() {
            assert_eq!(pos.len(), first.positions.len());
            let c = Vec3::new(0.1 * (k + 1) as f64, 0.02 * (k + 1) as f64, 0.0);
            let r = 1.0 + 0.03 * (k + 1) as f64;
            for p in pos {
                let d = f
                    .triangles
                    .iter()
                    .map(|t| {
                        let q = t.map(|i| f.positions[i as usize]);
                        crate::geom::distance::point_triangle(p, &q[0], &q[1], &q[2]).0
                    })
                    .fold(f64::MAX, f64::min);
                assert!(
                    d.sqrt() < 1e-9,
                    "frame {}: off the surface by {}",
                    k + 1,
                    d.sqrt()
                );
                // A coarse sphere mesh lies within 8% inside the analytic one.
                let rho = (p - c).norm();
                assert!(
                    rho <= r * (1.0 + 1e-9) && rho > 0.92 * r,
                    "frame {}: {rho} vs {r}",
                    k + 1
                );
            }
        }
        let bad = Mesh {
            triangles: Vec::new(),
            ..first.clone()
        };
        assert!(track_frames(&first, &[bad]).is_err());
    }
}
