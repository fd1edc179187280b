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
