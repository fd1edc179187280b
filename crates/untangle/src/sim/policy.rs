//! The per-pair contact policy: for every candidate pair of primitives the collision handling
//! asks whether to handle it and with which thickness. This is where Cha & Ko 2022 (Sec. 5.2)
//! turn CCH into m-CCH: red-red elementary pairs may cross (`Skip`), red-green pairs use a larger
//! `epsilon_RG`, green-green pairs the ordinary `epsilon_CCD`.
//!
//! Identifiers: cloth vertices and triangles are the garment's world vertex and triangle
//! indices; cloth edges are indices into [`crate::mesh::Topology::edges`] of the garment
//! (sorted vertex pairs). Obstacle primitives are numbered within the concatenation of all
//! obstacles, in the order they were added.
//!
//! The policy is called for every candidate pair in every collision pass, from several threads:
//! keep it a few array look-ups.

/// What to do with one pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Contact {
    /// Ignore the pair: it may pass through (m-CCH red-red pairs).
    Skip,
    /// Keep the pair at least this far apart (metres); used by proximity repulsion and CCD.
    Thickness(f64),
}

/// A cloth-obstacle pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObstaclePair {
    /// A cloth vertex and an obstacle triangle.
    ClothVertex {
        /// Cloth world vertex.
        vertex: u32,
        /// Obstacle triangle.
        triangle: u32,
    },
    /// An obstacle vertex and a cloth triangle.
    ObstacleVertex {
        /// Obstacle vertex.
        vertex: u32,
        /// Cloth triangle.
        triangle: u32,
    },
    /// A cloth edge and an obstacle edge.
    EdgeEdge {
        /// Cloth edge.
        cloth_edge: u32,
        /// Obstacle edge.
        obstacle_edge: u32,
    },
}

/// Decides, per pair of primitives, whether and how the collision handling treats it.
pub trait ContactPolicy: Sync {
    /// An upper bound of every thickness this policy returns (broad-phase box inflation).
    fn max_thickness(&self) -> f64;
    /// A cloth vertex and a cloth triangle (the vertex is not a corner of it).
    fn vertex_triangle(&self, vertex: u32, triangle: u32) -> Contact;
    /// Two cloth edges without a common vertex.
    fn edge_edge(&self, edge_a: u32, edge_b: u32) -> Contact;
    /// A cloth-obstacle pair; `obstacle_thickness` is the obstacle's own. Default: handle it
    /// with that thickness.
    fn obstacle(&self, pair: ObstaclePair, obstacle_thickness: f64) -> Contact {
        let _ = pair;
        Contact::Thickness(obstacle_thickness)
    }

    /// `Some(c)` when [`Self::vertex_triangle`] and [`Self::edge_edge`] return `c` for every
    /// pair, so that a pass over many candidates may ask once instead of once per pair (the
    /// same decisions). Default: `None` (ask per pair).
    fn uniform_cloth(&self) -> Option<Contact> {
        None
    }
}

/// Conventional CCH: one thickness for every cloth-cloth pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UniformThickness(pub f64);

impl ContactPolicy for UniformThickness {
    fn max_thickness(&self) -> f64 {
        self.0
    }
    fn vertex_triangle(&self, _: u32, _: u32) -> Contact {
        Contact::Thickness(self.0)
    }
    fn edge_edge(&self, _: u32, _: u32) -> Contact {
        Contact::Thickness(self.0)
    }
    fn uniform_cloth(&self) -> Option<Contact> {
        Some(Contact::Thickness(self.0))
    }
}

/// Cha & Ko's m-CCH (Sec. 5.2, 5.3.1) from a red/green colouring: red-red pairs skip,
/// red-green pairs use `epsilon_rg`, green-green pairs `epsilon`. A vertex-triangle pair is red
/// on a side when the vertex (resp. the triangle) is red; an edge-edge pair when the edge is.
#[derive(Clone, Debug, PartialEq)]
pub struct RedGreen {
    /// Red flag per cloth vertex.
    pub red_vertex: Vec<bool>,
    /// Red flag per cloth edge.
    pub red_edge: Vec<bool>,
    /// Red flag per cloth triangle.
    pub red_triangle: Vec<bool>,
    /// Thickness of green-green pairs (`epsilon_CCD`).
    pub epsilon: f64,
    /// Thickness of red-green pairs (`epsilon_RG`, the paper uses 0.1 x mean edge length).
    pub epsilon_rg: f64,
}

impl RedGreen {
    #[inline]
    fn decide(&self, a: bool, b: bool) -> Contact {
        match (a, b) {
            (true, true) => Contact::Skip,
            (false, false) => Contact::Thickness(self.epsilon),
            _ => Contact::Thickness(self.epsilon_rg),
        }
    }
}

impl ContactPolicy for RedGreen {
    fn max_thickness(&self) -> f64 {
        self.epsilon.max(self.epsilon_rg)
    }
    fn vertex_triangle(&self, vertex: u32, triangle: u32) -> Contact {
        self.decide(
            self.red_vertex
                .get(vertex as usize)
                .copied()
                .unwrap_or(false),
            self.red_triangle
                .get(triangle as usize)
                .copied()
                .unwrap_or(false),
        )
    }
    fn edge_edge(&self, a: u32, b: u32) -> Contact {
        self.decide(
            self.red_edge.get(a as usize).copied().unwrap_or(false),
            self.red_edge.get(b as usize).copied().unwrap_or(false),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn red_green_table() {
        let p = RedGreen {
            red_vertex: vec![true, false],
            red_edge: vec![true, false],
            red_triangle: vec![true, false],
            epsilon: 1e-3,
            epsilon_rg: 5e-3,
        };
        assert_eq!(p.vertex_triangle(0, 0), Contact::Skip);
        assert_eq!(p.vertex_triangle(0, 1), Contact::Thickness(5e-3));
        assert_eq!(p.vertex_triangle(1, 0), Contact::Thickness(5e-3));
        assert_eq!(p.vertex_triangle(1, 1), Contact::Thickness(1e-3));
        assert_eq!(p.edge_edge(0, 0), Contact::Skip);
        assert_eq!(p.edge_edge(1, 0), Contact::Thickness(5e-3));
        assert_eq!(p.edge_edge(1, 1), Contact::Thickness(1e-3));
        assert_eq!(p.max_thickness(), 5e-3);
        let o = ObstaclePair::ClothVertex {
            vertex: 0,
            triangle: 0,
        };
        assert_eq!(p.obstacle(o, 2e-3), Contact::Thickness(2e-3));
        // Not uniform: asked pair by pair.
        assert_eq!(p.uniform_cloth(), None);
    }

    /// [`UniformThickness`] declares the answer it gives every cloth pair.
    #[test]
    fn uniform_thickness_is_uniform() {
        let p = UniformThickness(2e-3);
        let c = p.uniform_cloth();
        assert_eq!(c, Some(Contact::Thickness(2e-3)));
        for (a, b) in [(0, 1), (7, 3), (u32::MAX, 0)] {
            assert_eq!(Some(p.vertex_triangle(a, b)), c);
            assert_eq!(Some(p.edge_edge(a, b)), c);
        }
    }
}
