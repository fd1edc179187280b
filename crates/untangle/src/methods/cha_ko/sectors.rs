//! BLI sectors (ours, beyond Cha & Ko 2022): shrinking the boundary strand of a BLI path with
//! an interior loop vertex into that vertex.
//!
//! A BLI path (Wicke et al. 2006, Sec. 4.1: from a loop vertex to a boundary edge) whose loop
//! vertex `v` is interior separates nothing: it runs `I -> v -> B` through the parameter space,
//! its *pierced strand* from the point where a boundary edge pierces the cloth to `v`, its
//! *boundary strand* from `v` out to that boundary edge. Such a path can only vanish by
//! shrinking into `v` (or by its piercing edge sliding off the pierced cloth's own boundary).
//! Cha & Ko's operations do not aim at `v`: the cone region Wicke's heuristic gives the path is
//! pulled across its rim, and the pulls move `v` and the strand around (the `bli-interior`
//! scene from level 1 on stays stuck; docs/cha-ko.md, "BLI").
//!
//! The *sector* of such a path is the triangles of its boundary strand (from `v` out to the
//! pierced boundary edge, in the panel of its triangle at `v`) and their edge neighbours in
//! that panel; its *subjects* are their corners other than `v`. A sector operation
//! ([`super::state::OpKind::Sector`]) moves every uv copy those triangles use for a subject
//! toward `v`'s uv, `gamma` per level like a pull or shrink (Sec. 5.1.1): the cloth around the
//! strand contracts into `v` in the rest shape, the world follows, and the boundary edge is
//! carried to `v`. Two m-CCH exceptions hold while the operation runs (the loop,
//! [`super::Resolver`]): its subjects pass red primitives
//! ([`super::policy::MchPolicy::transparent`]: the `epsilon_RG` band would hold the
//! contracting cloth at arm's length from the red cloth it has to slide through), and the edges
//! at `v` are open to red edges as for an open loop ([`super::policy::open_bli_loops`]), so the
//! path can vanish at `v`. The operation is scheduled before everything else, continues while a
//! BLI path keeps its loop vertex at `v`, and is held, abandoned and revoked like any other
//! ([`super::schedule`]). Triangles whose three corners move are scaled about `v`, so they keep
//! their orientation; the others are checked by the triangle inversion test before it starts.
//!
//! Measured (BENCHMARKS.md, session 35): the `bli-interior` scene resolves at refinement levels
//! 0 and 3 (16 and 168 steps; without sectors 77 steps and stuck), not at 1, 2 and 4, and
//! dress4 sagged 60 steps resolves through Cha & Ko's loop alone (one dress4 run in seven is
//! lost: sag 10 as `cha_ko_garments` runs it).

use super::state::{MovedCopy, Op};
use super::subjects::subject_flags;
use crate::analysis::{Analysis, AnalysisMesh, EndKind, ObjectKind, PathKind};
use crate::geom::Vec2;
use crate::mesh::Garment;

/// The sector of one interior BLI loop vertex (see the module text).
#[derive(Clone, Debug, PartialEq)]
pub struct Sector {
    /// The interior loop vertex the strand shrinks into (the operation's target).
    pub vertex: u32,
    /// Corners of [`Sector::triangles`] other than `vertex`, ascending.
    pub subjects: Vec<u32>,
    /// The boundary strand's triangles, from `vertex` out to the boundary end, then their edge
    /// neighbours in the same panel.
    pub triangles: Vec<u32>,
    /// Corners of every triangle the path crosses (both strands) and of their edge neighbours,
    /// ascending: the red cloth the subjects may pass while the operation runs.
    pub partners: Vec<u32>,
}

/// Sectors of every BLI path of the garment (object 0 of `mesh`, a cloth) with an interior loop
/// vertex, one per loop vertex (the first path's, in path order), ascending by vertex. A strand
/// that leaves the panel of its triangle at `v` is cut at the panel border.
pub fn sectors(mesh: &AnalysisMesh, a: &Analysis, g: &Garment) -> Vec<Sector> {
    let topo = &mesh.topology;
    let nt = g.mesh.triangles.len() as u32;
    let mut out: Vec<Sector> = Vec::new();
    for p in &a.paths {
        if p.kind != PathKind::BoundaryLoopInside
            || p.object != 0
            || mesh.objects[0].kind != ObjectKind::Cloth
        {
            continue;
        }
        let Some(ends) = p.ends else { continue };
        let pieces = p.pieces();
        // The boundary strand, from the B end inward.
        let from_b: Vec<u32> = match ends {
            [_, EndKind::Boundary] => pieces.iter().rev().copied().collect(),
            [EndKind::Boundary, _] => pieces.to_vec(),
            _ => continue,
        };
        for &v in p.loop_vertices() {
            if topo.boundary_vertex[v as usize] || out.iter().any(|s| s.vertex == v) {
                continue;
            }
            let mut strand = Vec::new();
            let mut reached = false;
            for &piece in &from_b {
                let t = a.piece_triangle(piece);
                if t >= nt {
                    break;
                }
                if strand.last() != Some(&t) {
                    strand.push(t);
                }
                if g.mesh.triangles[t as usize].contains(&v) {
                    reached = true;
                    break;
                }
            }
            if !reached {
                continue;
            }
            strand.reverse();
            // Keep the panel of the triangle at `v`.
            let panel = g.panel_of_triangle[strand[0] as usize];
            let cut = strand
                .iter()
                .position(|&t| g.panel_of_triangle[t as usize] != panel)
                .unwrap_or(strand.len());
            strand.truncate(cut);
            // The strand's triangles and their edge neighbours in the same panel.
            let mut tris = strand.clone();
            for &t in &strand {
                for &e in &g.topology.triangle_edges[t as usize] {
                    let [t0, t1] = g.topology.edge_triangles[e as usize];
                    let n = if t0 == t { t1 } else { t0 };
                    if n != crate::mesh::topology::NONE
                        && n < nt
                        && g.panel_of_triangle[n as usize] == panel
                        && !tris.contains(&n)
                    {
                        tris.push(n);
                    }
                }
            }
            let mut subjects: Vec<u32> = tris
                .iter()
                .flat_map(|&t| g.mesh.triangles[t as usize])
                .filter(|&w| w != v)
                .collect();
            subjects.sort_unstable();
            subjects.dedup();
            if subjects.is_empty() {
                continue;
            }
            let mut partners: Vec<u32> = pieces
                .iter()
                .map(|&piece| a.piece_triangle(piece))
                .filter(|&t| t < nt)
                .flat_map(|t| {
                    g.topology.triangle_edges[t as usize]
                        .iter()
                        .flat_map(|&e| g.topology.edge_triangles[e as usize])
                        .chain([t])
                })
                .filter(|&t| t != crate::mesh::topology::NONE && t < nt)
                .flat_map(|t| g.mesh.triangles[t as usize])
                .collect();
            partners.sort_unstable();
            partners.dedup();
            out.push(Sector {
                vertex: v,
                subjects,
                triangles: tris,
                partners,
            });
        }
    }
    out.sort_by_key(|s| s.vertex);
    out
}

/// The moved uv copies of a sector operation: every uv copy the sector's triangles use for a
/// subject, anchored at `v`'s uv copy in the strand's first triangle (`orig` = original uv).
pub fn sector_copies(g: &Garment, orig: &[Vec2], s: &Sector) -> Vec<MovedCopy> {
    let uv = g.uv();
    let first = s.triangles[0] as usize;
    let Some(kv) = g.mesh.triangles[first].iter().position(|&w| w == s.vertex) else {
        return Vec::new();
    };
    let anchor = orig[uv.triangles[first][kv] as usize];
    let mut copies: Vec<u32> = s
        .triangles
        .iter()
        .flat_map(|&t| {
            let w = g.mesh.triangles[t as usize];
            let u = uv.triangles[t as usize];
            (0..3)
                .filter(move |&k| s.subjects.binary_search(&w[k]).is_ok())
                .map(move |k| u[k])
        })
        .collect();
    copies.sort_unstable();
    copies.dedup();
    copies
        .into_iter()
        .map(|c| MovedCopy { uv: c, anchor })
        .collect()
}

/// Per vertex, whether it is a subject of one of `ops`, and whether it is a partner of one of
/// `sectors` whose loop vertex is the target of one of `ops` (`None` when `ops` is empty): the
/// vertex flags of [`super::policy::MchPolicy::transparent`] while those operations run.
pub fn transparency<'a>(
    ops: impl Iterator<Item = &'a Op>,
    sectors: &[Sector],
    num_vertices: usize,
) -> Option<(Vec<bool>, Vec<bool>)> {
    let ops: Vec<&Op> = ops.collect();
    if ops.is_empty() {
        return None;
    }
    let subjects = subject_flags(ops.iter().copied(), num_vertices);
    let mut partners = vec![false; num_vertices];
    for s in sectors
        .iter()
        .filter(|s| ops.iter().any(|op| op.target == s.vertex))
    {
        for &v in &s.partners {
            partners[v as usize] = true;
        }
    }
    Some((subjects, partners))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::analyze;
    use crate::scenes::rudimentary::{bli, bli_interior};

    fn sectors_of(scene: &crate::scenes::Scene) -> (Garment, Vec<Sector>) {
        let mesh = AnalysisMesh::merge_cloth(&scene.meshes).unwrap();
        let g = Garment::new(mesh).unwrap();
        let (am, pos) = AnalysisMesh::single(&g.mesh).unwrap();
        let a = analyze(&am, &pos).unwrap();
        let s = sectors(&am, &a, &g);
        (g, s)
    }

    #[test]
    fn the_unrefined_interior_bli_shrinks_the_dipping_wedge_and_its_neighbours() {
        // Core fan of `bli_interior`: P = (0,1,2), (0,2,3) in the plane y = 0; Q = (0,4,5)
        // dips through P, its boundary edge 4-5 piercing it; (0,3,4), (0,5,6), (0,6,1) close
        // the disc. The boundary strand is Q alone; with its edge neighbours (0,3,4) and
        // (0,5,6), minus the loop vertex 0, the subjects are 3, 4, 5 and 6.
        let (g, s) = sectors_of(&bli_interior(0));
        assert_eq!(s.len(), 1, "{s:?}");
        assert_eq!(s[0].vertex, 0);
        assert_eq!(s[0].subjects, vec![3, 4, 5, 6]);
        assert_eq!(g.mesh.triangles[s[0].triangles[0] as usize], [0, 4, 5]);
        let mut tris: Vec<[u32; 3]> = s[0]
            .triangles
            .iter()
            .map(|&t| g.mesh.triangles[t as usize])
            .collect();
        tris.sort();
        assert_eq!(tris, vec![[0, 3, 4], [0, 4, 5], [0, 5, 6]]);
        // One copy per subject (one panel, no seams), each moving toward vertex 0's uv (the
        // origin of the layout).
        let orig = &g.uv().coords;
        let copies = sector_copies(&g, orig, &s[0]);
        let mut moved: Vec<u32> = copies.iter().map(|c| c.uv).collect();
        moved.sort_unstable();
        assert_eq!(moved, vec![3, 4, 5, 6], "{copies:?}");
        for c in copies {
            assert!(c.anchor.norm() < 1e-15, "{c:?}");
        }
    }

    #[test]
    fn refined_sectors_reach_from_the_loop_vertex_to_the_pierced_boundary() {
        for level in 1..=2 {
            let (g, s) = sectors_of(&bli_interior(level));
            assert_eq!(s.len(), 1, "level {level}: {s:?}");
            let topo = &g.topology;
            let v = s[0].vertex;
            assert!(!topo.boundary_vertex[v as usize]);
            // The first triangle has the loop vertex as a corner, and some subject lies on
            // the boundary (the pierced boundary edge's ends are subjects).
            assert!(g.mesh.triangles[s[0].triangles[0] as usize].contains(&v));
            assert!(s[0]
                .subjects
                .iter()
                .any(|&w| topo.boundary_vertex[w as usize]));
            assert!(!s[0].subjects.contains(&v));
        }
    }

    #[test]
    fn bli_on_the_boundary_has_no_sector() {
        // `bli`'s loop vertex is a boundary vertex: its path separates, the region pulls out.
        let (_, s) = sectors_of(&bli(0));
        assert!(s.is_empty(), "{s:?}");
        let (_, s) = sectors_of(&bli(1));
        assert!(s.is_empty(), "{s:?}");
    }

    #[test]
    fn transparency_marks_the_running_subjects_and_their_sectors_partners() {
        use super::super::state::{Op, OpKind};
        let op = |target: u32, subjects: Vec<u32>| Op {
            id: 0,
            kind: OpKind::Sector,
            subjects,
            target,
            triangle: crate::mesh::topology::NONE,
            copies: Vec::new(),
            level: 1,
            level_cap: 15,
        };
        let sector = |vertex: u32, partners: Vec<u32>| Sector {
            vertex,
            subjects: Vec::new(),
            triangles: Vec::new(),
            partners,
        };
        let sectors = [sector(0, vec![0, 2]), sector(5, vec![5, 6])];
        assert_eq!(transparency(std::iter::empty(), &sectors, 7), None);
        let ops = [op(0, vec![1, 3]), op(9, vec![4])];
        let (s, p) = transparency(ops.iter(), &sectors, 7).unwrap();
        assert_eq!(s, vec![false, true, false, true, true, false, false]);
        // Only the sector of a running operation's target lends its partners.
        assert_eq!(p, vec![true, false, true, false, false, false, false]);
    }
}
