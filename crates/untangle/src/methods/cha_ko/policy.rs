//! The m-CCH contact decision (Cha & Ko 2022, Sec. 5.2 and 5.3.1) as a pure function of the
//! colouring.
//!
//! Continuous collision handling looks at *elementary pairs*: a vertex against a triangle and an
//! edge against an edge. Each primitive has the colour of Sec. 3 (a vertex is red when it lies in
//! an inside region, an edge when an end is red or it penetrates a triangle, a triangle when a
//! corner is red or it intersects another triangle), so a pair is red-red, red-green or
//! green-green:
//!
//! - red-red pairs are skipped: they may cross (this is how red turns green);
//! - red-green pairs are kept apart by the larger `epsilon_RG` (default 0.1 x average edge
//!   length), which is what makes a finesse finish (Sec. 5.3, Eq. 1 and 2);
//! - green-green pairs use the ordinary `epsilon` (`epsilon_CCD`, 1e-6 in the paper).
//!
//! Pairs with an obstacle (body) primitive are not part of the method: the body is never
//! coloured, and such pairs always use the ordinary `epsilon`.

use crate::analysis::{AnalysisMesh, Coloring, ObjectKind};
use crate::sim::{Contact, ContactPolicy};

/// Colour class of an elementary pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum PairColour {
    /// Both primitives red.
    RedRed,
    /// One red, one green.
    RedGreen,
    /// Both green (or an obstacle is involved).
    GreenGreen,
}

/// Colour class of a pair of primitives with the given redness.
#[inline]
pub fn pair_colour(a_red: bool, b_red: bool) -> PairColour {
    match (a_red, b_red) {
        (true, true) => PairColour::RedRed,
        (false, false) => PairColour::GreenGreen,
        _ => PairColour::RedGreen,
    }
}

/// The m-CCH rule for a colour class: red-red may cross, red-green keeps `eps_rg`, green-green
/// keeps `eps`.
#[inline]
pub fn rule(colour: PairColour, eps: f64, eps_rg: f64) -> Contact {
    match colour {
        PairColour::RedRed => Contact::Skip,
        PairColour::RedGreen => Contact::Thickness(eps_rg),
        PairColour::GreenGreen => Contact::Thickness(eps),
    }
}

/// The m-CCH contact policy of one step: the colouring of the analysed state plus the two
/// thicknesses. It implements the simulator's [`ContactPolicy`] (cloth vertices, triangles and
/// edges numbered as in the garment, which must be the first object of the analysis mesh;
/// obstacle pairs keep the obstacle's thickness) and answers colour queries for any primitive
/// of the [`AnalysisMesh`].
#[derive(Clone, Debug)]
pub struct MchPolicy<'a> {
    mesh: &'a AnalysisMesh,
    coloring: &'a Coloring,
    /// Ordinary thickness (green-green pairs).
    pub eps: f64,
    /// Red-green thickness.
    pub eps_rg: f64,
    /// Treat an edge with exactly one red end as green in edge-edge pairs (experiment, see
    /// [`super::Params::mixed_edges_green`]).
    pub mixed_edges_green: bool,
}

impl<'a> MchPolicy<'a> {
    /// A policy from a colouring of `mesh`.
    pub fn new(mesh: &'a AnalysisMesh, coloring: &'a Coloring, eps: f64, eps_rg: f64) -> Self {
        MchPolicy {
            mesh,
            coloring,
            eps,
            eps_rg,
            mixed_edges_green: false,
        }
    }

    /// Whether edge `e` (analysis-mesh topology index) counts as red in edge-edge pairs.
    #[inline]
    fn edge_red(&self, e: u32) -> bool {
        let c = self.coloring;
        if !c.red_edge[e as usize] {
            return false;
        }
        if self.mixed_edges_green {
            let [a, b] = self.mesh.topology.edges[e as usize];
            return c.red_vertex[a as usize] == c.red_vertex[b as usize];
        }
        true
    }

    fn vertex_is_cloth(&self, v: u32) -> bool {
        self.mesh
            .objects
            .iter()
            .find(|o| o.vertices.contains(&v))
            .is_some_and(|o| o.kind == ObjectKind::Cloth)
    }

    /// Colour class of vertex `v` against triangle `t` (analysis-mesh numbering; a pair with an
    /// obstacle primitive is green-green).
    pub fn vertex_triangle_colour(&self, v: u32, t: u32) -> PairColour {
        if !self.vertex_is_cloth(v) || self.mesh.kind_of_triangle(t) != ObjectKind::Cloth {
            return PairColour::GreenGreen;
        }
        pair_colour(
            self.coloring.red_vertex[v as usize],
            self.coloring.red_triangle[t as usize],
        )
    }

    /// Colour class of edge `e0` against edge `e1` (analysis-mesh topology edge indices).
    pub fn edge_edge_colour(&self, e0: u32, e1: u32) -> PairColour {
        let topo = &self.mesh.topology;
        let cloth = |e: u32| self.vertex_is_cloth(topo.edges[e as usize][0]);
        if !cloth(e0) || !cloth(e1) {
            return PairColour::GreenGreen;
        }
        pair_colour(self.edge_red(e0), self.edge_red(e1))
    }

    /// Rule for the edge `(a0, a1)` against the edge `(b0, b1)`, given by their vertices. An
    /// unknown edge (not in the mesh) is treated as green.
    pub fn edge_edge_by_vertices(&self, a: [u32; 2], b: [u32; 2]) -> Contact {
        let topo = &self.mesh.topology;
        let red = |e: [u32; 2]| {
            topo.edge_between(e[0], e[1])
                .is_some_and(|i| self.edge_red(i))
        };
        let cloth = |e: [u32; 2]| self.vertex_is_cloth(e[0]);
        let colour = if cloth(a) && cloth(b) {
            pair_colour(red(a), red(b))
        } else {
            PairColour::GreenGreen
        };
        rule(colour, self.eps, self.eps_rg)
    }
}

impl ContactPolicy for MchPolicy<'_> {
    fn max_thickness(&self) -> f64 {
        self.eps.max(self.eps_rg)
    }

    /// Cloth vertex against cloth triangle (garment numbering = analysis numbering).
    #[inline]
    fn vertex_triangle(&self, vertex: u32, triangle: u32) -> Contact {
        rule(
            pair_colour(
                self.coloring.red_vertex[vertex as usize],
                self.coloring.red_triangle[triangle as usize],
            ),
            self.eps,
            self.eps_rg,
        )
    }

    /// Cloth edge against cloth edge (garment topology edge indices).
    #[inline]
    fn edge_edge(&self, edge_a: u32, edge_b: u32) -> Contact {
        rule(
            pair_colour(self.edge_red(edge_a), self.edge_red(edge_b)),
            self.eps,
            self.eps_rg,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_by_colour() {
        assert_eq!(pair_colour(true, true), PairColour::RedRed);
        assert_eq!(pair_colour(true, false), PairColour::RedGreen);
        assert_eq!(pair_colour(false, true), PairColour::RedGreen);
        assert_eq!(pair_colour(false, false), PairColour::GreenGreen);
        assert_eq!(rule(PairColour::RedRed, 1e-6, 0.1), Contact::Skip);
        assert_eq!(
            rule(PairColour::RedGreen, 1e-6, 0.1),
            Contact::Thickness(0.1)
        );
        assert_eq!(
            rule(PairColour::GreenGreen, 1e-6, 0.1),
            Contact::Thickness(1e-6)
        );
    }
}
