//! World-space intersection curves, for display: each tanglement's curve as a polyline through
//! the crossing points (and loop vertices) of its first path, in path order.

use super::segments::End;
use super::{Analysis, AnalysisMesh};
use crate::geom::tri_tri::edge_triangle_point;
use crate::geom::Vec3;

/// World position of a segment end (crossing points in floating point).
pub fn end_point(mesh: &AnalysisMesh, pos: &[Vec3], a: &Analysis, end: End) -> Vec3 {
    match end {
        End::LoopVertex(v) => pos[v as usize],
        End::Crossing(c) => {
            let cr = a.crossings[c as usize];
            let [i, j] = mesh.topology.edges[cr.edge as usize];
            let t = mesh.triangles[cr.triangle as usize];
            let (p, q) = (&pos[i as usize], &pos[j as usize]);
            let (s, _) = edge_triangle_point(
                p,
                q,
                &pos[t[0] as usize],
                &pos[t[1] as usize],
                &pos[t[2] as usize],
            );
            p + (q - p) * s
        }
    }
}

/// One polyline per tanglement (its first path's pieces in order; closed curves repeat their
/// first point at the end).
pub fn tanglement_curves(mesh: &AnalysisMesh, pos: &[Vec3], a: &Analysis) -> Vec<Vec<Vec3>> {
    a.tanglements
        .iter()
        .map(|t| {
            let path = &a.paths[t.paths[0] as usize];
            let mut pts: Vec<Vec3> = Vec::with_capacity(path.pieces().len() + 1);
            let mut last_end: Option<End> = None;
            for (k, &piece) in path.pieces().iter().enumerate() {
                let seg = &a.segments[(piece / 2) as usize];
                // Orient the segment so that it starts where the previous piece ended.
                let (e0, e1) = match last_end {
                    Some(prev) if seg.ends[1] == prev => (seg.ends[1], seg.ends[0]),
                    Some(_) => (seg.ends[0], seg.ends[1]),
                    None => {
                        // First piece: start at the end not shared with the next piece.
                        let next = path
                            .pieces()
                            .get(k + 1)
                            .map(|&n| a.segments[(n / 2) as usize].ends);
                        match next {
                            Some(n) if n.contains(&seg.ends[0]) => (seg.ends[1], seg.ends[0]),
                            _ => (seg.ends[0], seg.ends[1]),
                        }
                    }
                };
                if k == 0 {
                    pts.push(end_point(mesh, pos, a, e0));
                }
                pts.push(end_point(mesh, pos, a, e1));
                last_end = Some(e1);
            }
            if path.closed {
                if let Some(&first) = pts.first() {
                    pts.push(first);
                }
            }
            pts
        })
        .collect()
}
