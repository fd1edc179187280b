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

/// What collision handling does with a pair.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum ContactRule {
    /// Ignore the pair: it may cross.
    Skip,
    /// Keep the primitives at least this far apart.
    Thickness(f64),
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

/// The m-CCH rule for a colour class.
#[inline]
pub fn rule(colour: PairColour, eps: f64, eps_rg: f64) -> ContactRule {
    match colour {
        PairColour::RedRed => ContactRule::Skip,
        PairColour::RedGreen => ContactRule::Thickness(eps_rg),
        PairColour::GreenGreen => ContactRule::Thickness(eps),
    }
}

/// The per-pair contact policy of one step: the colouring of the analysed state plus the two
/// thicknesses. Indices are those of the [`AnalysisMesh`] the colouring came from (vertices,
/// triangles, and edges of its topology).
#[derive(Clone, Debug)]
pub struct ContactPolicy<'a> {
    mesh: &'a AnalysisMesh,
    coloring: &'a Coloring,
    /// Ordinary thickness (green-green and obstacle pairs).
    pub eps: f64,
    /// Red-green thickness.
    pub eps_rg: f64,
}

impl<'a> ContactPolicy<'a> {
    /// A policy from a colouring of `mesh`.
    pub fn new(mesh: &'a AnalysisMesh, coloring: &'a Coloring, eps: f64, eps_rg: f64) -> Self {
        ContactPolicy {
            mesh,
            coloring,
            eps,
            eps_rg,
        }
    }

    fn vertex_is_cloth(&self, v: u32) -> bool {
        self.mesh
            .objects
            .iter()
            .find(|o| o.vertices.contains(&v))
            .is_some_and(|o| o.kind == ObjectKind::Cloth)
    }

    /// Colour class of vertex `v` against triangle `t`.
    pub fn vertex_triangle_colour(&self, v: u32, t: u32) -> PairColour {
        if !self.vertex_is_cloth(v) || self.mesh.kind_of_triangle(t) != ObjectKind::Cloth {
            return PairColour::GreenGreen;
        }
        pair_colour(
            self.coloring.red_vertex[v as usize],
            self.coloring.red_triangle[t as usize],
        )
    }

    /// Colour class of edge `e0` against edge `e1` (topology edge indices).
    pub fn edge_edge_colour(&self, e0: u32, e1: u32) -> PairColour {
        let topo = &self.mesh.topology;
        let cloth = |e: u32| self.vertex_is_cloth(topo.edges[e as usize][0]);
        if !cloth(e0) || !cloth(e1) {
            return PairColour::GreenGreen;
        }
        pair_colour(
            self.coloring.red_edge[e0 as usize],
            self.coloring.red_edge[e1 as usize],
        )
    }

    /// Rule for vertex `v` against triangle `t`.
    pub fn vertex_triangle(&self, v: u32, t: u32) -> ContactRule {
        rule(self.vertex_triangle_colour(v, t), self.eps, self.eps_rg)
    }

    /// Rule for edge `e0` against edge `e1` (topology edge indices).
    pub fn edge_edge(&self, e0: u32, e1: u32) -> ContactRule {
        rule(self.edge_edge_colour(e0, e1), self.eps, self.eps_rg)
    }

    /// Rule for the edge `(a0, a1)` against the edge `(b0, b1)`, given by their vertices. An
    /// unknown edge (not in the mesh) is treated as green.
    pub fn edge_edge_by_vertices(&self, a: [u32; 2], b: [u32; 2]) -> ContactRule {
        let topo = &self.mesh.topology;
        let red = |e: [u32; 2]| {
            topo.edge_between(e[0], e[1])
                .is_some_and(|i| self.coloring.red_edge[i as usize])
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_by_colour() {
        assert_eq!(pair_colour(true, true), PairColour::RedRed);
        assert_eq!(pair_colour(true, false), PairColour::RedGreen);
        assert_eq!(pair_colour(false, true), PairColour::RedGreen);
        assert_eq!(pair_colour(false, false), PairColour::GreenGreen);
        assert_eq!(rule(PairColour::RedRed, 1e-6, 0.1), ContactRule::Skip);
        assert_eq!(
            rule(PairColour::RedGreen, 1e-6, 0.1),
            ContactRule::Thickness(0.1)
        );
        assert_eq!(
            rule(PairColour::GreenGreen, 1e-6, 0.1),
            ContactRule::Thickness(1e-6)
        );
    }
}
