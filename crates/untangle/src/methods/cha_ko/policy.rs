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

/// How an edge with one red and one green end (a *mixed* edge; red by Sec. 3) takes part in
/// edge-edge pairs of m-CCH. An experiment about the theorem's first part (Sec. 7, footnote 7):
/// the red-vertex count increased only after such an edge crossed another red edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum MixedEdges {
    /// The paper: a mixed edge is red (it crosses any red edge).
    Red,
    /// A mixed edge counts as green: it never crosses another edge.
    Green,
    /// Two mixed edges do not cross each other (red-green thickness); a mixed edge crosses
    /// other red edges.
    NotWithMixed,
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
    /// How edges with one red and one green end take part in edge-edge pairs.
    pub mixed_edges: MixedEdges,
    /// Thin red-green pairs at the subjects (ours, off by default: `None`): with
    /// `Some((subject, t))`, a red-green pair whose red primitive has a vertex flagged in
    /// `subject` (the running operations' subjects) keeps `t` instead of `eps_rg` (use
    /// `eps <= t <= eps_rg`), so the subject's own red-green pairs hold a pull back less.
    pub thin_rg: Option<(&'a [bool], f64)>,
}

impl<'a> MchPolicy<'a> {
    /// A policy from a colouring of `mesh`.
    pub fn new(mesh: &'a AnalysisMesh, coloring: &'a Coloring, eps: f64, eps_rg: f64) -> Self {
        MchPolicy {
            mesh,
            coloring,
            eps,
            eps_rg,
            mixed_edges: MixedEdges::Red,
            thin_rg: None,
        }
    }

    /// The thickness of a red-green pair whose red primitive has the vertices `red_side`.
    #[inline]
    fn red_green_thickness(&self, red_side: &[u32]) -> f64 {
        match self.thin_rg {
            Some((subject, t))
                if red_side
                    .iter()
                    .any(|&v| subject.get(v as usize).copied().unwrap_or(false)) =>
            {
                t
            }
            _ => self.eps_rg,
        }
    }

    /// Whether edge `e` (analysis-mesh topology index) has one red and one green end.
    #[inline]
    fn mixed(&self, e: u32) -> bool {
        let [a, b] = self.mesh.topology.edges[e as usize];
        self.coloring.red_vertex[a as usize] != self.coloring.red_vertex[b as usize]
    }

    /// Colour class of the edge pair `(e0, e1)` under [`MchPolicy::mixed_edges`].
    #[inline]
    fn edge_pair(&self, e0: u32, e1: u32) -> PairColour {
        let (r0, r1) = self.edge_reds(e0, e1);
        pair_colour(r0, r1)
    }

    /// Whether each edge of the pair `(e0, e1)` counts as red under
    /// [`MchPolicy::mixed_edges`].
    #[inline]
    fn edge_reds(&self, e0: u32, e1: u32) -> (bool, bool) {
        let c = self.coloring;
        let (r0, r1) = (c.red_edge[e0 as usize], c.red_edge[e1 as usize]);
        let (r0, r1) = match self.mixed_edges {
            MixedEdges::Red => (r0, r1),
            MixedEdges::Green => (r0 && !self.mixed(e0), r1 && !self.mixed(e1)),
            MixedEdges::NotWithMixed => {
                if self.mixed(e0) && self.mixed(e1) {
                    (false, r1)
                } else {
                    (r0, r1)
                }
            }
        };
        (r0, r1)
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
        self.edge_pair(e0, e1)
    }

    /// Rule for the edge `(a0, a1)` against the edge `(b0, b1)`, given by their vertices. An
    /// unknown edge (not in the mesh) is treated as green.
    pub fn edge_edge_by_vertices(&self, a: [u32; 2], b: [u32; 2]) -> Contact {
        let topo = &self.mesh.topology;
        let cloth = |e: [u32; 2]| self.vertex_is_cloth(e[0]);
        let colour = match (topo.edge_between(a[0], a[1]), topo.edge_between(b[0], b[1])) {
            (Some(i), Some(j)) if cloth(a) && cloth(b) => self.edge_pair(i, j),
            _ => PairColour::GreenGreen,
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
        let (rv, rt) = (
            self.coloring.red_vertex[vertex as usize],
            self.coloring.red_triangle[triangle as usize],
        );
        let colour = pair_colour(rv, rt);
        if colour == PairColour::RedGreen && self.thin_rg.is_some() {
            let t = if rv {
                self.red_green_thickness(&[vertex])
            } else {
                self.red_green_thickness(&self.mesh.triangles[triangle as usize])
            };
            return Contact::Thickness(t);
        }
        rule(colour, self.eps, self.eps_rg)
    }

    /// Cloth edge against cloth edge (garment topology edge indices).
    #[inline]
    fn edge_edge(&self, edge_a: u32, edge_b: u32) -> Contact {
        let (ra, rb) = self.edge_reds(edge_a, edge_b);
        let colour = pair_colour(ra, rb);
        if colour == PairColour::RedGreen && self.thin_rg.is_some() {
            let red = if ra { edge_a } else { edge_b };
            let t = self.red_green_thickness(&self.mesh.topology.edges[red as usize]);
            return Contact::Thickness(t);
        }
        rule(colour, self.eps, self.eps_rg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{AnalysisMesh, Coloring};

    /// Thin red-green pairs at subjects, against a brute-force oracle over every vertex-triangle
    /// and edge-edge pair of a 5 x 5 vertex grid with red vertices 6 (a subject) and 18 (not
    /// one).
    #[test]
    fn thin_red_green_pairs_only_where_the_red_side_has_a_subject() {
        use crate::analysis::ObjectKind;
        let m = crate::scenes::handkerchief("grid", 4, 4, 1.0, 1.0, |p| {
            crate::geom::Vec3::new(p.x, p.y, 0.0)
        });
        let (am, _) = AnalysisMesh::new(&[(&m, ObjectKind::Cloth)]).unwrap();
        let red_vertex: Vec<bool> = (0..25).map(|v| v == 6 || v == 18).collect();
        let edges = am.topology.edges.clone();
        let red_edge: Vec<bool> = edges
            .iter()
            .map(|e| red_vertex[e[0] as usize] || red_vertex[e[1] as usize])
            .collect();
        let red_triangle: Vec<bool> = am
            .triangles
            .iter()
            .map(|t| t.iter().any(|&v| red_vertex[v as usize]))
            .collect();
        let coloring = Coloring {
            red_vertex: red_vertex.clone(),
            red_edge: red_edge.clone(),
            red_triangle: red_triangle.clone(),
            ..Coloring::default()
        };
        let subject: Vec<bool> = (0..25).map(|v| v == 6 || v == 24).collect();
        let (eps, eps_rg, thin) = (1e-6, 0.1, 0.03);
        let mut p = MchPolicy::new(&am, &coloring, eps, eps_rg);
        let plain = p.clone();
        p.thin_rg = Some((&subject, thin));
        let has_subject = |vs: &[u32]| vs.iter().any(|&v| subject[v as usize]);
        let expect = |a_red: bool, b_red: bool, red_side_has_subject: bool| match (a_red, b_red) {
            (true, true) => Contact::Skip,
            (false, false) => Contact::Thickness(eps),
            _ if red_side_has_subject => Contact::Thickness(thin),
            _ => Contact::Thickness(eps_rg),
        };
        let (mut thin_pairs, mut rg_pairs) = (0, 0);
        for v in 0..25u32 {
            for (t, tri) in am.triangles.iter().enumerate() {
                let (a, b) = (red_vertex[v as usize], red_triangle[t]);
                let red_side = if a {
                    has_subject(&[v])
                } else {
                    has_subject(tri)
                };
                let want = expect(a, b, red_side);
                assert_eq!(p.vertex_triangle(v, t as u32), want, "v {v} t {t}");
                assert_eq!(plain.vertex_triangle(v, t as u32), expect(a, b, false));
                thin_pairs += (want == Contact::Thickness(thin)) as usize;
                rg_pairs += (want == Contact::Thickness(eps_rg)) as usize;
            }
        }
        for (i, e) in edges.iter().enumerate() {
            for (j, f) in edges.iter().enumerate() {
                let (a, b) = (red_edge[i], red_edge[j]);
                let red_side = if a { has_subject(e) } else { has_subject(f) };
                let want = expect(a, b, red_side);
                assert_eq!(p.edge_edge(i as u32, j as u32), want, "e {i} f {j}");
                assert_eq!(plain.edge_edge(i as u32, j as u32), expect(a, b, false));
            }
        }
        // Both kinds occur: the subject's pairs thin, the other red vertex's at eps_RG
        // (vertex 24 is a green subject: its pairs are never thin).
        assert!(thin_pairs > 0 && rg_pairs > 0, "{thin_pairs} {rg_pairs}");
    }

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
