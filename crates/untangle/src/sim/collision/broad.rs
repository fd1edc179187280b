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
    /// Cloth vertices' swept boxes (for the triangles of changed vertices).
    vert: Bvh,
    obs_tri: Bvh,
    obs_edge: Bvh,
    /// Obstacle vertices' swept boxes (for the cloth triangles of changed vertices).
    obs_vert: Bvh,
    /// Swept boxes of the last update (inflated as in the hierarchies).
    tri_boxes: Vec<Aabb>,
    edge_boxes: Vec<Aabb>,
    vert_boxes: Vec<Aabb>,
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
        let vert: Vec<Aabb> = (0..scene.x0.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .map(|p| swept(scene, v, [p], 0.0))
            .collect();
        let obs = scene.obstacles;
        let fresh = !self.built || rebuild || self.obstacle_count != obs.triangles.len();
        let (obs_tri, obs_edge, obs_vert): (Vec<Aabb>, Vec<Aabb>, Vec<Aabb>) = if obs.is_empty() {
            (Vec::new(), Vec::new(), Vec::new())
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
                (0..obs.start.len() as u32)
                    .into_par_iter()
                    .with_min_len(1024)
                    .map(|q| swept(scene, v, [q | OBSTACLE], 0.0))
                    .collect(),
            )
        };
        if fresh {
            self.tri = Bvh::build(&tri);
            self.edge = Bvh::build(&edge);
            self.vert = Bvh::build(&vert);
            self.obs_tri = Bvh::build(&obs_tri);
            self.obs_edge = Bvh::build(&obs_edge);
            self.obs_vert = Bvh::build(&obs_vert);
            self.built = true;
            self.obstacle_count = obs.triangles.len();
        } else {
            self.tri.refit(&tri);
            self.edge.refit(&edge);
            self.vert.refit(&vert);
            self.obs_tri.refit(&obs_tri);
            self.obs_edge.refit(&obs_edge);
            self.obs_vert.refit(&obs_vert);
        }
        self.tri_boxes = tri;
        self.edge_boxes = edge;
        self.vert_boxes = vert;
    }

    /// [`BroadPhase::update`] between the passes of one step, when only the velocities of the
    /// cloth vertices with `changed[i]` differ from the last update: only their primitives' boxes
    /// are recomputed, then the cloth hierarchies are refitted (obstacle motion does not depend
    /// on `v`).
    pub fn update_changed(&mut self, scene: &Scene, v: &[Vec3], margin: f64, changed: &[bool]) {
        let count = changed.iter().filter(|&&c| c).count();
        if !self.built || self.vert_boxes.len() != scene.x0.len() || 4 * count > changed.len() {
            self.update(scene, v, margin, false);
            return;
        }
        let touched = |nodes: &[u32]| nodes.iter().any(|&k| changed[k as usize]);
        for (t, b) in scene.triangles.iter().zip(self.tri_boxes.iter_mut()) {
            if touched(t) {
                *b = swept(scene, v, *t, margin);
            }
        }
        for (e, b) in scene.edges.iter().zip(self.edge_boxes.iter_mut()) {
            if touched(e) {
                *b = swept(scene, v, *e, 0.5 * margin);
            }
        }
        for (p, b) in self.vert_boxes.iter_mut().enumerate() {
            if changed[p] {
                *b = swept(scene, v, [p as u32], 0.0);
            }
        }
        self.tri.refit(&self.tri_boxes);
        self.edge.refit(&self.edge_boxes);
        self.vert.refit(&self.vert_boxes);
    }

    /// The candidate pairs of [`BroadPhase::candidates`] that have at least one cloth vertex
    /// with `changed[i]` (after [`BroadPhase::update`] with the same `v`), sorted and without
    /// duplicates. A pair without a changed vertex has the same swept boxes as in the previous
    /// pass, so between passes only these can become candidates; the queries start from the
    /// changed primitives instead of traversing everything, which makes the later CCD passes
    /// of a step cost in proportion to what the impulses touched.
    pub fn candidates_of_changed(
        &self,
        scene: &Scene,
        v: &[Vec3],
        margin: f64,
        changed: &[bool],
    ) -> Vec<Pair> {
        let n = scene.x0.len();
        let obs = scene.obstacles;
        let touched = |nodes: &[u32]| nodes.iter().any(|&k| changed[k as usize]);
        let verts: Vec<u32> = (0..n as u32).filter(|&p| changed[p as usize]).collect();
        let tris: Vec<u32> = (0..scene.triangles.len() as u32)
            .filter(|&t| touched(&scene.triangles[t as usize]))
            .collect();
        let edges: Vec<u32> = (0..scene.edges.len() as u32)
            .filter(|&e| touched(&scene.edges[e as usize]))
            .collect();
        let mut out: Vec<Pair> = verts
            .par_iter()
            .with_min_len(64)
            .flat_map_iter(|&p| {
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
                if !obs.is_empty() {
                    self.obs_tri.query(&b.inflated(margin), |t| {
                        local.push(Pair {
                            kind: PairKind::VertexObstacle,
                            a: p,
                            b: t,
                        });
                    });
                }
                local
            })
            .collect();
        out.par_extend(tris.par_iter().with_min_len(64).flat_map_iter(|&t| {
            let tri = scene.triangles[t as usize];
            let b = self.tri_boxes[t as usize];
            let mut local = Vec::new();
            self.vert.query(&b, |p| {
                if !tri.contains(&p) {
                    local.push(Pair {
                        kind: PairKind::VertexTriangle,
                        a: p,
                        b: t,
                    });
                }
            });
            if !obs.is_empty() {
                self.obs_vert.query(&b, |q| {
                    local.push(Pair {
                        kind: PairKind::ObstacleVertex,
                        a: q,
                        b: t,
                    });
                });
            }
            local
        }));
        let all_edges = scene.edges;
        out.par_extend(edges.par_iter().with_min_len(64).flat_map_iter(|&i| {
            let e = all_edges[i as usize];
            let b = self.edge_boxes[i as usize];
            let mut local = Vec::new();
            self.edge.query(&b, |j| {
                let f = all_edges[j as usize];
                if e[0] != f[0] && e[0] != f[1] && e[1] != f[0] && e[1] != f[1] {
                    local.push(Pair {
                        kind: PairKind::EdgeEdge,
                        a: i.min(j),
                        b: i.max(j),
                    });
                }
            });
            if !obs.is_empty() {
                self.obs_edge.query(&b, |j| {
                    local.push(Pair {
                        kind: PairKind::EdgeObstacleEdge,
                        a: i,
                        b: j,
                    });
                });
            }
            local
        }));
        out.par_sort_unstable();
        out.dedup();
        out
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
