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

use crate::analysis::{Analysis, AnalysisMesh, Coloring, ObjectKind, PathKind};
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
    /// Edges a red edge may pass whatever their colour (ours: the edges at the open BLI loops
    /// of [`open_bli_loops`]; `None`: none). A pair of an open edge and a red edge is red-red;
    /// every other pair keeps its colour.
    pub open_edges: Option<&'a [bool]>,
    /// Vertices that pass red cloth, and the cloth they pass (ours: `(subjects, partners)`,
    /// per vertex: the subjects of the running BLI sector operations and the corners of the
    /// triangles their paths cross, [`super::sectors::transparency`]; `None`: none). A pair of
    /// a subject (or an edge or triangle at one) and a red primitive at a partner is red-red;
    /// every other pair keeps its colour.
    pub transparent: Option<(&'a [bool], &'a [bool])>,
}

/// The interior loop vertices of the BLI paths of `a` that lie in their loop vertex's fan
/// (ours), sorted: where m-CCH may open the loop ([`edges_at`], [`MchPolicy::open_edges`]).
///
/// A BLI path (Wicke et al. 2006, Sec. 4.1) runs from the cloth's boundary, where a boundary
/// edge pierces a triangle `T`, to a loop vertex `v`, a corner of `T`. When `v` lies on the
/// boundary, half of the path separates the cloth and the inside region pulls out like any
/// other. When `v` is interior, nothing separates, and the path can only vanish by shrinking
/// into `v`: its piercing point must reach the corner `v` of `T`. m-CCH keeps a red edge
/// `epsilon_RG` away from the green edges of `T` (Sec. 5.2, Fig. 7b), so the point can come no
/// nearer to `v` than that band, and every pull or shrink toward `v` saturates (dress4 sagged
/// 120 steps ended with one such pair, BENCHMARKS.md). Opening `v`'s edges lets the piercing
/// (red) edge pass them; every other pair keeps its colour.
///
/// Only for the last stretch: a loop vertex is listed when every triangle its path crosses has
/// it as a corner (the piercing point is in `v`'s fan). A longer path is still being pulled out
/// by its region, and opening its loop vertex then only lets red edges through cloth that is
/// not about to untangle there (the tangled pants, sagged 25 steps, took 242 steps instead of
/// 168 when every interior BLI loop was opened; BENCHMARKS.md, session 34).
pub fn open_bli_loops(mesh: &AnalysisMesh, a: &Analysis) -> Vec<u32> {
    let topo = &mesh.topology;
    let mut loops = Vec::new();
    for p in &a.paths {
        if p.kind != PathKind::BoundaryLoopInside
            || mesh.objects[p.object as usize].kind != ObjectKind::Cloth
        {
            continue;
        }
        for &v in p.loop_vertices() {
            // Interior, and every piece in a triangle at `v`.
            let at_v = |&piece: &u32| mesh.triangles[a.piece_triangle(piece) as usize].contains(&v);
            if !topo.boundary_vertex[v as usize] && p.pieces().iter().all(at_v) {
                loops.push(v);
            }
        }
    }
    loops.sort_unstable();
    loops.dedup();
    loops
}

/// Per edge of `mesh`'s topology, whether an end is in `vertices` (`None` when `vertices` is
/// empty): the open edges of [`MchPolicy::open_edges`] for the loops of [`open_bli_loops`].
pub fn edges_at(mesh: &AnalysisMesh, vertices: &[u32]) -> Option<Vec<bool>> {
    if vertices.is_empty() {
        return None;
    }
    let topo = &mesh.topology;
    let mut open = vec![false; topo.num_edges()];
    for &v in vertices {
        for &e in topo.vertex_edges.row(v as usize) {
            open[e as usize] = true;
        }
    }
    Some(open)
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
            open_edges: None,
            transparent: None,
        }
    }

    /// Whether the primitive with vertices `a` may pass the red primitive with vertices `b`
    /// under [`MchPolicy::transparent`] (`a` has a subject, `b` a partner).
    #[inline]
    fn passes(&self, a: &[u32], b: &[u32]) -> bool {
        let flag = |m: &[bool], vs: &[u32]| {
            vs.iter()
                .any(|&v| m.get(v as usize).copied().unwrap_or(false))
        };
        self.transparent
            .is_some_and(|(s, p)| flag(s, a) && flag(p, b))
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
        if let Some(open) = self.open_edges {
            if (r0 && open[e1 as usize]) || (r1 && open[e0 as usize]) {
                return (true, true);
            }
        }
        if self.transparent.is_some() {
            let (a, b) = (
                &self.mesh.topology.edges[e0 as usize],
                &self.mesh.topology.edges[e1 as usize],
            );
            if (r1 && self.passes(a, b)) || (r0 && self.passes(b, a)) {
                return (true, true);
            }
        }
        (r0, r1)
    }

    /// Whether vertex `v` and triangle `t` count as red: their colours, except that a pair of
    /// a [`MchPolicy::transparent`] subject (or a triangle at one) and a red primitive at a
    /// partner is red-red.
    #[inline]
    fn vt_reds(&self, v: u32, t: u32) -> (bool, bool) {
        let (rv, rt) = (
            self.coloring.red_vertex[v as usize],
            self.coloring.red_triangle[t as usize],
        );
        let tri = &self.mesh.triangles[t as usize];
        if self.transparent.is_some()
            && ((rt && self.passes(&[v], tri)) || (rv && self.passes(tri, &[v])))
        {
            return (true, true);
        }
        (rv, rt)
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
        let (rv, rt) = self.vt_reds(v, t);
        pair_colour(rv, rt)
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
        let (rv, rt) = self.vt_reds(vertex, triangle);
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

    /// A flat 5 x 5 vertex grid and the colouring of Sec. 3 with the vertices `red` red and
    /// no crossings (an edge or triangle is red when a vertex of it is).
    fn grid_coloring(red: &[u32]) -> (AnalysisMesh, Coloring) {
        use crate::analysis::ObjectKind;
        let m = crate::scenes::handkerchief("grid", 4, 4, 1.0, 1.0, |p| {
            crate::geom::Vec3::new(p.x, p.y, 0.0)
        });
        let (am, _) = AnalysisMesh::new(&[(&m, ObjectKind::Cloth)]).unwrap();
        let red_vertex: Vec<bool> = (0..25).map(|v| red.contains(&v)).collect();
        let red_edge = am
            .topology
            .edges
            .iter()
            .map(|e| red_vertex[e[0] as usize] || red_vertex[e[1] as usize])
            .collect();
        let red_triangle = am
            .triangles
            .iter()
            .map(|t| t.iter().any(|&v| red_vertex[v as usize]))
            .collect();
        let coloring = Coloring {
            red_vertex,
            red_edge,
            red_triangle,
            ..Coloring::default()
        };
        (am, coloring)
    }

    /// Thin red-green pairs at subjects, against a brute-force oracle over every vertex-triangle
    /// and edge-edge pair of a 5 x 5 vertex grid with red vertices 6 (a subject) and 18 (not
    /// one).
    #[test]
    fn thin_red_green_pairs_only_where_the_red_side_has_a_subject() {
        let (am, coloring) = grid_coloring(&[6, 18]);
        let (red_vertex, red_edge, red_triangle) = (
            &coloring.red_vertex,
            &coloring.red_edge,
            &coloring.red_triangle,
        );
        let edges = am.topology.edges.clone();
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

    /// [`open_bli_loops`] and [`edges_at`] on the constructed BLI with an interior loop vertex
    /// (core vertex 0, `tests/analysis.rs`) at four refinement levels. Oracle: the loop opens
    /// exactly when every intersecting triangle of the scene (it has one path) has vertex 0 as
    /// a corner, which holds for the unrefined core only; the open edges are those with an end
    /// at vertex 0, read edge by edge. BLI with a boundary loop vertex and CLOSED open nothing.
    #[test]
    fn open_bli_loops_are_interior_bli_loop_vertices_with_their_path_in_the_fan() {
        use crate::analysis::analyze;
        use crate::scenes::rudimentary;
        let mut opened = Vec::new();
        for lv in 0..4 {
            let s = rudimentary::bli_interior(lv);
            let (am, pos) = AnalysisMesh::single(&s.meshes[0]).unwrap();
            let a = analyze(&am, &pos).unwrap();
            assert_eq!(a.paths.len(), 1, "level {lv}");
            assert_eq!(a.paths[0].kind, PathKind::BoundaryLoopInside, "level {lv}");
            assert!(!am.topology.boundary_vertex[0]);
            let in_fan = a
                .intersecting_triangles()
                .iter()
                .all(|&t| am.triangles[t as usize].contains(&0));
            let loops = open_bli_loops(&am, &a);
            let got = edges_at(&am, &loops);
            if !in_fan {
                assert!(loops.is_empty() && got.is_none(), "level {lv}: {loops:?}");
                continue;
            }
            assert_eq!(loops, vec![0], "level {lv}");
            let want: Vec<bool> = am.topology.edges.iter().map(|e| e.contains(&0)).collect();
            assert_eq!(got, Some(want), "level {lv}");
            opened.push(lv);
        }
        assert_eq!(opened, vec![0], "the unrefined core's path lies in the fan");
        for name in ["bli", "closed"] {
            let s = crate::scenes::by_name(name, None, 1).unwrap();
            let m = AnalysisMesh::merge_cloth(&s.meshes).unwrap();
            let (am, pos) = AnalysisMesh::single(&m).unwrap();
            let a = analyze(&am, &pos).unwrap();
            assert!(!a.is_clean(), "{name}");
            assert!(open_bli_loops(&am, &a).is_empty(), "{name}");
        }
    }

    /// With open edges, a pair of a red edge and an open edge crosses (red-red); every other
    /// edge-edge pair and every vertex-triangle pair keeps its colour. Oracle: the colour table
    /// over all pairs of a 5 x 5 grid with red vertex 6 and the edges at vertex 12 open (vertex
    /// 12 is a neighbour of 6, so one open edge is red itself).
    #[test]
    fn a_red_edge_passes_open_edges_and_nothing_else_changes() {
        let (am, coloring) = grid_coloring(&[6]);
        let red_edge = &coloring.red_edge;
        let edges = am.topology.edges.clone();
        let open: Vec<bool> = edges.iter().map(|e| e.contains(&12)).collect();
        assert!((0..edges.len()).any(|e| open[e] && red_edge[e]));
        assert!((0..edges.len()).any(|e| open[e] && !red_edge[e]));
        let (eps, eps_rg) = (1e-6, 0.1);
        let plain = MchPolicy::new(&am, &coloring, eps, eps_rg);
        let mut p = plain.clone();
        p.open_edges = Some(&open);
        let mut opened = 0;
        for i in 0..edges.len() {
            for j in 0..edges.len() {
                let crosses = (red_edge[i] && open[j]) || (red_edge[j] && open[i]);
                let colour = if crosses {
                    PairColour::RedRed
                } else {
                    pair_colour(red_edge[i], red_edge[j])
                };
                let want = rule(colour, eps, eps_rg);
                let (i, j) = (i as u32, j as u32);
                assert_eq!(p.edge_edge(i, j), want, "e {i} f {j}");
                assert_eq!(
                    p.edge_edge_by_vertices(edges[i as usize], edges[j as usize]),
                    want
                );
                opened += (want != plain.edge_edge(i, j)) as usize;
            }
        }
        // Some red-green pairs (a red edge against a green open one) now cross.
        assert!(opened > 0);
        for v in 0..25u32 {
            for t in 0..am.triangles.len() as u32 {
                assert_eq!(p.vertex_triangle(v, t), plain.vertex_triangle(v, t));
            }
        }
    }

    #[test]
    fn transparent_subjects_pass_red_partners_and_nothing_else_changes() {
        // Vertex 6 red (its edges and triangles too); vertex 18, far from it, a subject; the
        // only partner is 7, so of the red triangles at 6 those at 7 too are passed, the rest
        // not.
        let (am, coloring) = grid_coloring(&[6]);
        let (eps, eps_rg) = (1e-6, 0.1);
        let plain = MchPolicy::new(&am, &coloring, eps, eps_rg);
        let subjects: Vec<bool> = (0..25).map(|v| v == 18).collect();
        let partners: Vec<bool> = (0..25).map(|v| v == 7).collect();
        let mut p = plain.clone();
        p.transparent = Some((&subjects, &partners));
        let sub = |vs: &[u32]| vs.contains(&18);
        let par = |vs: &[u32]| vs.contains(&7);
        let (c, edges, tris) = (&coloring, &am.topology.edges, &am.triangles);
        let (mut passed, mut kept) = (0, 0);
        for v in 0..25u32 {
            for t in 0..tris.len() as u32 {
                let (rv, rt) = (c.red_vertex[v as usize], c.red_triangle[t as usize]);
                let tri = &tris[t as usize];
                let crosses = (rt && sub(&[v]) && par(tri)) || (rv && sub(tri) && par(&[v]));
                let colour = if crosses {
                    PairColour::RedRed
                } else {
                    pair_colour(rv, rt)
                };
                assert_eq!(
                    p.vertex_triangle(v, t),
                    rule(colour, eps, eps_rg),
                    "v {v} t {t}"
                );
                assert_eq!(p.vertex_triangle_colour(v, t), colour);
                passed += (p.vertex_triangle(v, t) != plain.vertex_triangle(v, t)) as usize;
                kept += (v == 18 && rt && !par(tri)) as usize;
            }
        }
        for i in 0..edges.len() {
            for j in 0..edges.len() {
                let (ri, rj) = (c.red_edge[i], c.red_edge[j]);
                let crosses = (rj && sub(&edges[i]) && par(&edges[j]))
                    || (ri && sub(&edges[j]) && par(&edges[i]));
                let colour = if crosses {
                    PairColour::RedRed
                } else {
                    pair_colour(ri, rj)
                };
                let (a, b) = (i as u32, j as u32);
                assert_eq!(p.edge_edge(a, b), rule(colour, eps, eps_rg), "e {i} f {j}");
                assert_eq!(
                    p.edge_edge_by_vertices(edges[i], edges[j]),
                    rule(colour, eps, eps_rg)
                );
                passed += (p.edge_edge(a, b) != plain.edge_edge(a, b)) as usize;
            }
        }
        // Vertex 18 against the red triangles at 6 and 7, and edges at 18 against red edges at
        // 7, now cross (red-green before); red triangles at 6 only keep the red-green band.
        assert!(passed > 0);
        assert!(kept > 0);
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
