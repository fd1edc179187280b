//! Broad phase of the collision handling: bounding volume hierarchies over the swept boxes of
//! cloth triangles and edges and of obstacle triangles and edges (start and end of the step,
//! inflated by the largest thickness), refitted on every pass and rebuilt every few steps;
//! candidate pairs in a deterministic order for any thread count.

use rayon::prelude::*;

use super::{Pair, PairKind, Scene};
use crate::broad::Bvh;
use crate::geom::{Aabb, Vec3};

/// Steps between full rebuilds of the hierarchies (refit in between).
pub const REBUILD_EVERY: u64 = 16;

/// The hierarchies, kept across steps.
#[derive(Clone, Debug, Default)]
pub struct BroadPhase {
    tri: Bvh,
    edge: Bvh,
    obs_tri: Bvh,
    obs_edge: Bvh,
    built: bool,
    obstacle_count: usize,
}

fn swept<const N: usize>(scene: &Scene, v: &[Vec3], nodes: [u32; N], margin: f64) -> Aabb {
    let mut b = Aabb::EMPTY;
    for n in nodes {
        b.grow(&scene.position(v, n, 0.0));
        b.grow(&scene.position(v, n, 1.0));
    }
    b.inflated(margin)
}

impl BroadPhase {
    /// Refits (or, every [`REBUILD_EVERY`] steps and when `rebuild`, rebuilds) the hierarchies to
    /// the motion `v` of this pass; `margin` is the largest thickness in use.
    pub fn update(&mut self, scene: &Scene, v: &[Vec3], margin: f64, rebuild: bool) {
        let tri: Vec<Aabb> = scene
            .triangles
            .par_iter()
            .map(|t| swept(scene, v, *t, margin))
            .collect();
        let edge: Vec<Aabb> = scene
            .edges
            .par_iter()
            .map(|e| swept(scene, v, *e, 0.5 * margin))
            .collect();
        let obs = scene.obstacles;
        let fresh = !self.built || rebuild || self.obstacle_count != obs.triangles.len();
        let (obs_tri, obs_edge): (Vec<Aabb>, Vec<Aabb>) = if obs.is_empty() {
            (Vec::new(), Vec::new())
        } else {
            use super::OBSTACLE;
            (
                obs.triangles
                    .par_iter()
                    .map(|t| swept(scene, v, t.map(|k| k | OBSTACLE), 0.0))
                    .collect(),
                obs.edges
                    .par_iter()
                    .map(|e| swept(scene, v, e.map(|k| k | OBSTACLE), 0.5 * margin))
                    .collect(),
            )
        };
        if fresh {
            self.tri = Bvh::build(&tri);
            self.edge = Bvh::build(&edge);
            self.obs_tri = Bvh::build(&obs_tri);
            self.obs_edge = Bvh::build(&obs_edge);
            self.built = true;
            self.obstacle_count = obs.triangles.len();
        } else {
            self.tri.refit(&tri);
            self.edge.refit(&edge);
            self.obs_tri.refit(&obs_tri);
            self.obs_edge.refit(&obs_edge);
        }
    }

    /// All candidate pairs whose swept boxes overlap (after [`BroadPhase::update`] with the same
    /// `v`): cloth vertex-triangle (vertex not a corner), cloth edge-edge (no common vertex), and
    /// cloth-obstacle pairs. Sorted by kind, then by the enumeration order.
    pub fn candidates(&self, scene: &Scene, v: &[Vec3], margin: f64) -> Vec<Pair> {
        let n = scene.x0.len();
        let obs = scene.obstacles;
        let mut out: Vec<Pair> = (0..n as u32)
            .into_par_iter()
            .with_min_len(256)
            .flat_map_iter(|p| {
                let b = swept(scene, v, [p], 0.0);
                let mut local = Vec::new();
                self.tri.query(&b, |t| {
                    if !scene.triangles[t as usize].contains(&p) {
                        local.push(Pair {
                            kind: PairKind::VertexTriangle,
                            a: p,
                            b: t,
                        });
                    }
                });
                let bo = b.inflated(margin);
                self.obs_tri.query(&bo, |t| {
                    local.push(Pair {
                        kind: PairKind::VertexObstacle,
                        a: p,
                        b: t,
                    });
                });
                local.sort_unstable();
                local
            })
            .collect();
        let edges = scene.edges;
        out.extend(self.edge.self_pairs(|i, j, o: &mut Vec<Pair>| {
            let (e, f) = (edges[i as usize], edges[j as usize]);
            if e[0] != f[0] && e[0] != f[1] && e[1] != f[0] && e[1] != f[1] {
                o.push(Pair {
                    kind: PairKind::EdgeEdge,
                    a: i.min(j),
                    b: i.max(j),
                });
            }
        }));
        if !obs.is_empty() {
            let root = self.tri.root_aabb();
            out.extend(
                (0..obs.start.len() as u32)
                    .into_par_iter()
                    .with_min_len(256)
                    .flat_map_iter(|q| {
                        let b = swept(scene, v, [q | super::OBSTACLE], 0.0);
                        let mut local = Vec::new();
                        if b.overlaps(&root) {
                            self.tri.query(&b, |t| {
                                local.push(Pair {
                                    kind: PairKind::ObstacleVertex,
                                    a: q,
                                    b: t,
                                })
                            });
                        }
                        local.sort_unstable();
                        local
                    })
                    .collect::<Vec<_>>(),
            );
            out.extend(
                self.edge
                    .cross_pairs(&self.obs_edge, |i, j, o: &mut Vec<Pair>| {
                        o.push(Pair {
                            kind: PairKind::EdgeObstacleEdge,
                            a: i,
                            b: j,
                        })
                    }),
            );
        }
        out
    }
}
