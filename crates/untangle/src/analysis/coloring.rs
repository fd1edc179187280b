//! The red/green colouring of Cha & Ko 2022 (Sec. 3).
//!
//! - Red vertices: vertices in the smaller region of a partitioning path (union over paths).
//! - Red triangles: a red vertex, or the triangle intersects another triangle.
//! - Red edges: a red vertex, or the edge penetrates a triangle.
//! - Out-most red vertices: red vertices adjacent to a green vertex.
//! - Red* triangles: three green vertices, two green edges and one red edge.

use super::crossings::Crossing;
use super::input::AnalysisMesh;
use super::segments::Segment;

/// Colour of every vertex, edge and triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coloring {
    /// Red vertices.
    pub red_vertex: Vec<bool>,
    /// Red edges (topology edge order).
    pub red_edge: Vec<bool>,
    /// Red triangles.
    pub red_triangle: Vec<bool>,
    /// Out-most red vertices, sorted.
    pub outmost_red: Vec<u32>,
    /// Red* triangles, sorted.
    pub red_star: Vec<u32>,
}

impl Coloring {
    /// Number of red vertices.
    pub fn num_red_vertices(&self) -> usize {
        self.red_vertex.iter().filter(|&&r| r).count()
    }
    /// Number of red triangles.
    pub fn num_red_triangles(&self) -> usize {
        self.red_triangle.iter().filter(|&&r| r).count()
    }
    /// Number of red edges.
    pub fn num_red_edges(&self) -> usize {
        self.red_edge.iter().filter(|&&r| r).count()
    }
}

/// Per-vertex display colours: red for red vertices, orange for green vertices of intersecting
/// triangles, green for clean cloth, grey for obstacles.
pub fn vertex_colors(
    mesh: &AnalysisMesh,
    coloring: &Coloring,
    segments: &[Segment],
) -> Vec<[f32; 3]> {
    let mut touched = vec![false; mesh.num_vertices()];
    for s in segments {
        for t in s.triangles {
            for v in mesh.triangles[t as usize] {
                touched[v as usize] = true;
            }
        }
    }
    let mut out = vec![[0.2, 0.65, 0.25]; mesh.num_vertices()];
    for o in &mesh.objects {
        for v in o.vertices.clone() {
            out[v as usize] = if o.kind == super::ObjectKind::Obstacle {
                [0.6, 0.6, 0.6]
            } else if coloring.red_vertex[v as usize] {
                [0.85, 0.1, 0.1]
            } else if touched[v as usize] {
                [1.0, 0.6, 0.0]
            } else {
                [0.2, 0.65, 0.25]
            };
        }
    }
    out
}

/// Colours the mesh from the red vertices, crossings and segments.
pub fn color(
    mesh: &AnalysisMesh,
    red_vertex: Vec<bool>,
    crossings: &[Crossing],
    segments: &[Segment],
) -> Coloring {
    let topo = &mesh.topology;
    let mut red_edge: Vec<bool> = topo
        .edges
        .iter()
        .map(|e| red_vertex[e[0] as usize] || red_vertex[e[1] as usize])
        .collect();
    for c in crossings {
        red_edge[c.edge as usize] = true;
    }
    let mut red_triangle: Vec<bool> = mesh
        .triangles
        .iter()
        .map(|t| t.iter().any(|&v| red_vertex[v as usize]))
        .collect();
    for s in segments {
        red_triangle[s.triangles[0] as usize] = true;
        red_triangle[s.triangles[1] as usize] = true;
    }
    let outmost_red = (0..topo.num_vertices as u32)
        .filter(|&v| {
            red_vertex[v as usize]
                && topo
                    .vertex_neighbors
                    .row(v as usize)
                    .iter()
                    .any(|&w| !red_vertex[w as usize])
        })
        .collect();
    let red_star = (0..mesh.triangles.len() as u32)
        .filter(|&t| {
            let tri = mesh.triangles[t as usize];
            tri.iter().all(|&v| !red_vertex[v as usize])
                && topo.triangle_edges[t as usize]
                    .iter()
                    .filter(|&&e| red_edge[e as usize])
                    .count()
                    == 1
        })
        .collect();
    Coloring {
        red_vertex,
        red_edge,
        red_triangle,
        outmost_red,
        red_star,
    }
}
