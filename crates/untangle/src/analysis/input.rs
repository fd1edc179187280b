//! What the analysis looks at: one or more cloth meshes and optional obstacles, concatenated
//! into one triangle set with per-object ranges, so self-intersections, intersections between
//! garments and intersections with a body are found in one pass and reported separately.

use crate::error::Result;
use crate::geom::Vec3;
use crate::mesh::{Mesh, Topology};
use std::ops::Range;

/// What an object is for the analysis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ObjectKind {
    /// Cloth: self-intersections and intersections with other objects are analysed.
    Cloth,
    /// An obstacle (body): only its intersections with cloth are analysed.
    Obstacle,
}

/// One object of the analysed scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// Name used in reports.
    pub name: String,
    /// Cloth or obstacle.
    pub kind: ObjectKind,
    /// Its vertices in the concatenated numbering.
    pub vertices: Range<u32>,
    /// Its triangles in the concatenated numbering.
    pub triangles: Range<u32>,
}

/// Concatenated triangles and topology of all objects (positions are passed separately, since
/// they change every simulation step while the connectivity does not).
#[derive(Clone, Debug)]
pub struct AnalysisMesh {
    /// All triangles, vertex indices in the concatenated numbering.
    pub triangles: Vec<[u32; 3]>,
    /// Connectivity of the concatenation (objects are disjoint components).
    pub topology: Topology,
    /// The objects, in input order.
    pub objects: Vec<Object>,
    /// Object of each triangle.
    pub object_of_triangle: Vec<u32>,
    /// The triangle reporting each edge's crossings, and the triangles reporting none.
    pub reporters: super::Reporters,
}

impl AnalysisMesh {
    /// Concatenates validated meshes; returns the analysis mesh and the concatenated positions.
    pub fn new(parts: &[(&Mesh, ObjectKind)]) -> Result<(AnalysisMesh, Vec<Vec3>)> {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        let mut objects = Vec::new();
        let mut object_of_triangle = Vec::new();
        for (i, (m, kind)) in parts.iter().enumerate() {
            m.validate()?;
            let v0 = positions.len() as u32;
            let t0 = triangles.len() as u32;
            positions.extend_from_slice(&m.positions);
            triangles.extend(m.triangles.iter().map(|t| t.map(|v| v + v0)));
            object_of_triangle.extend(std::iter::repeat_n(i as u32, m.triangles.len()));
            objects.push(Object {
                name: m.name.clone(),
                kind: *kind,
                vertices: v0..positions.len() as u32,
                triangles: t0..triangles.len() as u32,
            });
        }
        let topology = Topology::from_triangles(&triangles, positions.len(), |t| {
            let o = object_of_triangle[t] as usize;
            parts[o]
                .0
                .triangle_place(t - objects[o].triangles.start as usize)
        })?;
        let reporters = super::Reporters::new(&topology);
        Ok((
            AnalysisMesh {
                triangles,
                reporters,
                topology,
                objects,
                object_of_triangle,
            },
            positions,
        ))
    }

    /// A single cloth mesh.
    pub fn single(mesh: &Mesh) -> Result<(AnalysisMesh, Vec<Vec3>)> {
        Self::new(&[(mesh, ObjectKind::Cloth)])
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.topology.num_vertices
    }

    /// Kind of the object owning triangle `t`.
    #[inline]
    pub fn kind_of_triangle(&self, t: u32) -> ObjectKind {
        self.objects[self.object_of_triangle[t as usize] as usize].kind
    }

    /// Cloth pieces as one mesh, each piece a group (and its uv layer its panels when every
    /// piece has uv): the input of a garment made of several files or scene pieces.
    pub fn merge_cloth(meshes: &[Mesh]) -> Result<Mesh> {
        let parts: Vec<_> = meshes.iter().map(|m| (m, ObjectKind::Cloth)).collect();
        let (am, pos) = AnalysisMesh::new(&parts)?;
        Ok(am.merged(&pos, &meshes.iter().collect::<Vec<_>>()))
    }

    /// All objects as one mesh (for writing): concatenated positions `pos`, uv layers of the
    /// parts kept where every part has one, one group per object.
    pub fn merged(&self, pos: &[Vec3], parts: &[&Mesh]) -> Mesh {
        let uv = if parts.iter().all(|m| m.uv.is_some()) {
            let mut layer = crate::mesh::UvLayer::default();
            for m in parts {
                let uv = m.uv.as_ref().expect("checked");
                let base = layer.coords.len() as u32;
                layer.coords.extend_from_slice(&uv.coords);
                layer
                    .triangles
                    .extend(uv.triangles.iter().map(|t| t.map(|i| i + base)));
            }
            Some(layer)
        } else {
            None
        };
        Mesh {
            name: self
                .objects
                .iter()
                .map(|o| o.name.as_str())
                .collect::<Vec<_>>()
                .join("+"),
            positions: pos.to_vec(),
            triangles: self.triangles.clone(),
            uv,
            groups: self
                .objects
                .iter()
                .map(|o| crate::mesh::Group {
                    name: o.name.clone(),
                    first: o.triangles.start,
                    count: o.triangles.end - o.triangles.start,
                    is_object: true,
                })
                .collect(),
            source: None,
        }
    }

    /// Object owning vertex `v`.
    pub fn object_of_vertex(&self, v: u32) -> u32 {
        self.objects
            .iter()
            .position(|o| o.vertices.contains(&v))
            .unwrap_or(0) as u32
    }
}
