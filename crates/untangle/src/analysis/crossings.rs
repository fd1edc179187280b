//! Crossings: every edge `e` that passes through a triangle `t` not incident to it (Wicke et al.
//! 2006, Sec. 4, "intersections between cloth primitives"). Found once each, in parallel, with
//! the symbolically perturbed predicates, and returned sorted so the result is identical for any
//! thread count.

use super::input::{AnalysisMesh, ObjectKind};
use crate::broad::Bvh;
use crate::geom::tri_tri::{edge_crosses_triangle, edge_may_cross_plane};
use crate::geom::{Aabb, Vec3};

/// Edge `edge` passes through triangle `triangle`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Crossing {
    /// Edge index in the analysis mesh's topology.
    pub edge: u32,
    /// Triangle index.
    pub triangle: u32,
}

/// Box of every triangle.
pub fn triangle_boxes(mesh: &AnalysisMesh, pos: &[Vec3]) -> Vec<Aabb> {
    mesh.triangles
        .iter()
        .map(|t| Aabb::from_points(t.iter().map(|&v| &pos[v as usize])))
        .collect()
}

/// All crossings, sorted by `(edge, triangle)`. Obstacle-obstacle pairs are skipped.
pub fn find_crossings(mesh: &AnalysisMesh, pos: &[Vec3], bvh: &Bvh) -> Vec<Crossing> {
    let topo = &mesh.topology;
    let tris = &mesh.triangles;
    let has_obstacles = mesh.objects.iter().any(|o| o.kind == ObjectKind::Obstacle);
    let mut out = bvh.self_pairs(|a, b, out: &mut Vec<Crossing>| {
        let (ta, tb) = (tris[a as usize], tris[b as usize]);
        let shared = ta.iter().filter(|v| tb.contains(v)).count();
        if shared >= 2 {
            return;
        }
        if has_obstacles
            && mesh.kind_of_triangle(a) == ObjectKind::Obstacle
            && mesh.kind_of_triangle(b) == ObjectKind::Obstacle
        {
            return;
        }
        test_edges(a, b, ta, tb, mesh, pos, out);
        test_edges(b, a, tb, ta, mesh, pos, out);
    });
    let _ = topo;
    out.sort_unstable();
    out
}

/// Tests the edges of triangle `a` owned by `a` (the lower-indexed triangle beside the edge)
/// against triangle `b`, so that every crossing is computed exactly once.
#[inline]
fn test_edges(
    a: u32,
    b: u32,
    ta: [u32; 3],
    tb: [u32; 3],
    mesh: &AnalysisMesh,
    pos: &[Vec3],
    out: &mut Vec<Crossing>,
) {
    let topo = &mesh.topology;
    let edges = topo.triangle_edges[a as usize];
    let (pa, pb, pc) = (
        &pos[tb[0] as usize],
        &pos[tb[1] as usize],
        &pos[tb[2] as usize],
    );
    for k in 0..3 {
        let e = edges[k];
        if topo.edge_triangles[e as usize][0] != a {
            continue;
        }
        let (i, j) = (ta[k], ta[(k + 1) % 3]);
        if tb.contains(&i) || tb.contains(&j) {
            continue;
        }
        let (p, q) = (&pos[i as usize], &pos[j as usize]);
        if !edge_may_cross_plane(p, q, pa, pb, pc) {
            continue;
        }
        if edge_crosses_triangle(p, q, pa, pb, pc, [i, j, tb[0], tb[1], tb[2]]) {
            out.push(Crossing {
                edge: e,
                triangle: b,
            });
        }
    }
}
