//! Broad phase of the collision handling: bounding volume hierarchies over the swept boxes of
//! cloth triangles and edges and of obstacle triangles and edges (start and end of the step,
//! inflated by the largest thickness), refitted on every pass and rebuilt every few steps;
//! candidate pairs in a deterministic order for any thread count. The full traversals of
//! [`BroadPhase::candidates`] start from where the last one stopped ([`crate::broad::Front`]).

use std::sync::{Mutex, MutexGuard};

use rayon::prelude::*;

use super::{Pair, PairKind, Scene};
use crate::broad::{Bvh, Front};
use crate::geom::{Aabb, Vec3};

/// Steps between full rebuilds of the hierarchies (refit in between).
pub const REBUILD_EVERY: u64 = 16;

/// Most primitives per leaf of the hierarchies (the candidate order does not depend on it).
pub const LEAF_SIZE: usize = 8;

fn build(boxes: &[Aabb]) -> Bvh {
    Bvh::build_with_leaf_size(boxes, LEAF_SIZE)
}

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
    /// Per cloth triangle / edge, whether a vertex changed in the last
    /// [`BroadPhase::update_changed`] (buffers kept across calls, filled in parallel).
    tri_changed: Vec<bool>,
    edge_changed: Vec<bool>,
    /// Where the last traversals of [`BroadPhase::candidates`] stopped.
    fronts: Fronts,
}

/// The traversal fronts of [`BroadPhase::candidates`] (vertex-triangle and edge-edge), behind
/// locks so that the candidates can be asked through a shared reference.
#[derive(Debug, Default)]
struct Fronts {
    vertex_triangle: Mutex<Front>,
    edge_edge: Mutex<Front>,
}

impl Clone for Fronts {
    fn clone(&self) -> Self {
        Fronts {
            vertex_triangle: Mutex::new(lock(&self.vertex_triangle).clone()),
            edge_edge: Mutex::new(lock(&self.edge_edge).clone()),
        }
    }
}

/// The front behind `m` (a front is only ever replaced whole, so one left by a panic is still
/// a valid front or an empty one).
fn lock(m: &Mutex<Front>) -> MutexGuard<'_, Front> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

fn swept<const N: usize>(scene: &Scene, v: &[Vec3], nodes: [u32; N], margin: f64) -> Aabb {
    let mut b = Aabb::EMPTY;
    for n in nodes {
        b.grow(&scene.position(v, n, 0.0));
        b.grow(&scene.position(v, n, 1.0));
    }
    b.inflated(margin)
}

/// The union of the (uninflated) swept boxes `vert` of cloth vertices `nodes`.
#[inline]
fn union_of(vert: &[Aabb], nodes: &[u32]) -> Aabb {
    nodes
        .iter()
        .fold(Aabb::EMPTY, |b, &k| b.union(&vert[k as usize]))
}

impl BroadPhase {
    /// Refits (or, every [`REBUILD_EVERY`] steps and when `rebuild`, rebuilds) the hierarchies to
    /// the motion `v` of this pass; `margin` is the largest thickness in use.
    pub fn update(&mut self, scene: &Scene, v: &[Vec3], margin: f64, rebuild: bool) {
        // A primitive's swept box is the union of its vertices' (min and max are exact, so
        // the same box as [`swept`] over its nodes), inflated.
        let vert: Vec<Aabb> = (0..scene.x0.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .map(|p| swept(scene, v, [p], 0.0))
            .collect();
        let (tri, edge): (Vec<Aabb>, Vec<Aabb>) = rayon::join(
            || {
                scene
                    .triangles
                    .par_iter()
                    .with_min_len(1024)
                    .map(|t| union_of(&vert, t).inflated(margin))
                    .collect()
            },
            || {
                scene
                    .edges
                    .par_iter()
                    .with_min_len(1024)
                    .map(|e| union_of(&vert, e).inflated(0.5 * margin))
                    .collect()
            },
        );
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
        // The cloth hierarchies side by side (each also splits its own work).
        if fresh {
            (self.tri, (self.edge, self.vert)) = rayon::join(
                || build(&tri),
                || rayon::join(|| build(&edge), || build(&vert)),
            );
            // Vertex keys: the traversals drop corner and shared-vertex pairs at the leaves.
            let verts: Vec<[u32; 1]> = (0..scene.x0.len() as u32).map(|p| [p]).collect();
            let (t, e, vk) = (&mut self.tri, &mut self.edge, &mut self.vert);
            rayon::join(
                || t.set_keys(scene.triangles),
                || rayon::join(|| e.set_keys(scene.edges), || vk.set_keys(&verts)),
            );
            self.obs_tri = build(&obs_tri);
            self.obs_edge = build(&obs_edge);
            self.obs_vert = build(&obs_vert);
            self.built = true;
            self.obstacle_count = obs.triangles.len();
        } else {
            let (t, e, v) = (&mut self.tri, &mut self.edge, &mut self.vert);
            rayon::join(
                || t.refit(&tri),
                || rayon::join(|| e.refit(&edge), || v.refit(&vert)),
            );
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
    /// are recomputed, then only the cloth hierarchies' nodes above them are refitted
    /// ([`Bvh::refit_changed`]; obstacle motion does not depend on `v`).
    pub fn update_changed(&mut self, scene: &Scene, v: &[Vec3], margin: f64, changed: &[bool]) {
        let count = changed.iter().filter(|&&c| c).count();
        if !self.built || self.vert_boxes.len() != scene.x0.len() || 4 * count > changed.len() {
            self.update(scene, v, margin, false);
            return;
        }
        if count == 0 {
            // The boxes of the last update are those of `v` already.
            return;
        }
        let touched = |nodes: &[u32]| nodes.iter().any(|&k| changed[k as usize]);
        self.vert_boxes
            .par_iter_mut()
            .with_min_len(4096)
            .enumerate()
            .for_each(|(p, b)| {
                if changed[p] {
                    *b = swept(scene, v, [p as u32], 0.0);
                }
            });
        // Which triangles and edges have a changed vertex, in the loops that recompute their
        // boxes (into buffers kept across calls).
        self.tri_changed.resize(scene.triangles.len(), false);
        self.edge_changed.resize(scene.edges.len(), false);
        let vert = &self.vert_boxes;
        self.tri_boxes
            .par_iter_mut()
            .with_min_len(4096)
            .zip(self.tri_changed.par_iter_mut())
            .zip(scene.triangles.par_iter())
            .for_each(|((b, c), t)| {
                *c = touched(t);
                if *c {
                    *b = union_of(vert, t).inflated(margin);
                }
            });
        self.edge_boxes
            .par_iter_mut()
            .with_min_len(4096)
            .zip(self.edge_changed.par_iter_mut())
            .zip(scene.edges.par_iter())
            .for_each(|((b, c), e)| {
                *c = touched(e);
                if *c {
                    *b = union_of(vert, e).inflated(0.5 * margin);
                }
            });
        let (tri_changed, edge_changed) = (&self.tri_changed, &self.edge_changed);
        // Only the nodes above changed primitives (the same boxes as a full refit).
        let (t, e, vb) = (&mut self.tri, &mut self.edge, &mut self.vert);
        let (tb, eb, vbb) = (&self.tri_boxes, &self.edge_boxes, &self.vert_boxes);
        rayon::join(
            || t.refit_changed(tb, tri_changed),
            || {
                rayon::join(
                    || e.refit_changed(eb, edge_changed),
                    || vb.refit_changed(vbb, changed),
                )
            },
        );
    }

    /// The candidate pairs of [`BroadPhase::candidates`] that have at least one cloth vertex
    /// with `changed[i]` (after [`BroadPhase::update`] with the same `v`), sorted and without
    /// duplicates. A pair without a changed vertex has the same swept boxes as in the previous
    /// pass, so between passes only these can become candidates; the queries start from the
    /// changed primitives instead of traversing everything, which makes the later CCD passes
    /// of a step cost in proportion to what the impulses touched. Each pair is reported by one
    /// query only (a vertex-triangle pair by its vertex if changed, else by its triangle; an
    /// edge pair by its lower edge if both are touched), so the cloth pairs need no
    /// deduplication and are ordered by two counting sorts per kind.
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
        let edge_touched: Vec<bool> = scene.edges.iter().map(|e| touched(e)).collect();
        let edges: Vec<u32> = (0..scene.edges.len() as u32)
            .filter(|&e| edge_touched[e as usize])
            .collect();
        let (nt, ne) = (scene.triangles.len(), scene.edges.len());
        // Cloth vertex-triangle pairs `(vertex, triangle)`: from the changed vertices, then
        // from the touched triangles with an unchanged vertex.
        let mut vt: Vec<(u32, u32)> = verts
            .par_iter()
            .with_min_len(64)
            .flat_map_iter(|&p| {
                let b = self.vert_boxes[p as usize];
                let mut local = Vec::new();
                self.tri.query(&b, |t| {
                    if !scene.triangles[t as usize].contains(&p) {
                        local.push((p, t));
                    }
                });
                local
            })
            .collect();
        vt.par_extend(tris.par_iter().with_min_len(64).flat_map_iter(|&t| {
            let tri = scene.triangles[t as usize];
            let b = self.tri_boxes[t as usize];
            let mut local = Vec::new();
            self.vert.query(&b, |p| {
                if !changed[p as usize] && !tri.contains(&p) {
                    local.push((p, t));
                }
            });
            local
        }));
        // Cloth edge pairs `(lower, higher)`, each from one of its touched edges.
        let all_edges = scene.edges;
        let mut ee: Vec<(u32, u32)> = edges
            .par_iter()
            .with_min_len(64)
            .flat_map_iter(|&i| {
                let e = all_edges[i as usize];
                let b = self.edge_boxes[i as usize];
                let mut local = Vec::new();
                self.edge.query(&b, |j| {
                    let f = all_edges[j as usize];
                    if (i < j || !edge_touched[j as usize])
                        && e[0] != f[0]
                        && e[0] != f[1]
                        && e[1] != f[0]
                        && e[1] != f[1]
                    {
                        local.push((i.min(j), i.max(j)));
                    }
                });
                local
            })
            .collect();
        let ((), ()) = rayon::join(
            || crate::radix::sort_by_bucket_then_key(&mut vt, (n, nt), |x| x.0, |x| x.1),
            || crate::radix::sort_by_bucket_then_key(&mut ee, (ne, ne), |x| x.0, |x| x.1),
        );
        // Kinds in the order of `Pair`'s: vertex-triangle, edge-edge, then the obstacle kinds.
        let mut out: Vec<Pair> = Vec::with_capacity(vt.len() + ee.len());
        out.extend(vt.into_iter().map(|(a, b)| Pair {
            kind: PairKind::VertexTriangle,
            a,
            b,
        }));
        out.extend(ee.into_iter().map(|(a, b)| Pair {
            kind: PairKind::EdgeEdge,
            a,
            b,
        }));
        if obs.is_empty() {
            return out;
        }
        let mut more: Vec<Pair> = verts
            .par_iter()
            .with_min_len(64)
            .flat_map_iter(|&p| {
                let b = swept(scene, v, [p], 0.0);
                let mut local = Vec::new();
                self.obs_tri.query(&b.inflated(margin), |t| {
                    local.push(Pair {
                        kind: PairKind::VertexObstacle,
                        a: p,
                        b: t,
                    });
                });
                local
            })
            .collect();
        more.par_extend(tris.par_iter().with_min_len(64).flat_map_iter(|&t| {
            let b = self.tri_boxes[t as usize];
            let mut local = Vec::new();
            self.obs_vert.query(&b, |q| {
                local.push(Pair {
                    kind: PairKind::ObstacleVertex,
                    a: q,
                    b: t,
                });
            });
            local
        }));
        more.par_extend(edges.par_iter().with_min_len(64).flat_map_iter(|&i| {
            let b = self.edge_boxes[i as usize];
            let mut local = Vec::new();
            self.obs_edge.query(&b, |j| {
                local.push(Pair {
                    kind: PairKind::EdgeObstacleEdge,
                    a: i,
                    b: j,
                });
            });
            local
        }));
        more.par_sort_unstable();
        more.dedup();
        out.extend(more);
        out
    }

    /// All candidate pairs whose swept boxes overlap (after [`BroadPhase::update`] with the same
    /// `v`): cloth vertex-triangle (vertex not a corner), cloth edge-edge (no common vertex), and
    /// cloth-obstacle pairs. The order is canonical (it does not depend on the hierarchies, which
    /// are free to change): vertex pairs first (cloth-triangle and obstacle pairs ordered by
    /// vertex, kind, triangle), then the edge-edge pairs by (edge, edge), the obstacle-vertex
    /// pairs by (obstacle vertex, triangle) and the cloth-obstacle edge pairs by (edge, edge).
    pub fn candidates(&self, scene: &Scene, v: &[Vec3], margin: f64) -> Vec<Pair> {
        let n = scene.x0.len();
        let obs = scene.obstacles;
        // Vertex-triangle pairs from one dual traversal of the vertex and triangle hierarchies
        // (the same box tests as a query per vertex, far fewer node visits), cloth-vertex
        // obstacle pairs from a query per vertex; then ordered by vertex, kind, triangle, as a
        // per-vertex enumeration with sorted results gives them. Key: vertex (bits 33..),
        // obstacle flag (bit 32), triangle (bits 0..32).
        let vertex_pairs = || -> Vec<Pair> {
            let mut front = lock(&self.fronts.vertex_triangle);
            // Corners are dropped by the hierarchies' vertex keys.
            let mut keys: Vec<u64> =
                self.vert
                    .cross_pairs_tracked(&self.tri, &mut front, |p, t, o: &mut Vec<u64>| {
                        o.push(((p as u64) << 33) | t as u64);
                    });
            drop(front);
            if !obs.is_empty() {
                keys.par_extend(
                    (0..n as u32)
                        .into_par_iter()
                        .with_min_len(256)
                        .flat_map_iter(|p| {
                            let bo = self.vert_boxes[p as usize].inflated(margin);
                            let mut local = Vec::new();
                            self.obs_tri.query(&bo, |t| {
                                local.push(((p as u64) << 33) | (1 << 32) | t as u64);
                            });
                            local
                        }),
                );
            }
            // By vertex, then by (kind, triangle) ranked cloth triangles first, then obstacle
            // triangles: the order of the keys, by two counting sorts.
            let (nt, no) = (scene.triangles.len(), obs.triangles.len());
            crate::radix::sort_by_bucket_then_key(
                &mut keys,
                (n, nt + no),
                |&k| (k >> 33) as u32,
                |&k| k as u32 + ((k >> 32) & 1) as u32 * nt as u32,
            );
            keys.iter()
                .map(|&k| Pair {
                    kind: if k & (1 << 32) == 0 {
                        PairKind::VertexTriangle
                    } else {
                        PairKind::VertexObstacle
                    },
                    a: (k >> 33) as u32,
                    b: k as u32,
                })
                .collect()
        };
        // Edge-edge pairs sorted by (edge, edge): the order reaches the decisions (proximity's
        // Gauss-Seidel sweeps, the resting contacts), so it must not depend on the tree.
        let ne = scene.edges.len();
        let edge_pairs = || -> Vec<(u32, u32)> {
            let mut front = lock(&self.fronts.edge_edge);
            // Pairs with a common vertex are dropped by the hierarchy's vertex keys.
            let mut ee: Vec<(u32, u32)> =
                self.edge
                    .self_pairs_tracked(&mut front, |i, j, o: &mut Vec<(u32, u32)>| {
                        o.push((i.min(j), i.max(j)));
                    });
            drop(front);
            crate::radix::sort_by_bucket_then_key(&mut ee, (ne, ne), |p| p.0, |p| p.1);
            ee
        };
        // The two kinds side by side (their sequential sorts overlap the other's traversal).
        let (mut out, ee) = rayon::join(vertex_pairs, edge_pairs);
        out.reserve(ee.len());
        out.extend(ee.into_iter().map(|(a, b)| Pair {
            kind: PairKind::EdgeEdge,
            a,
            b,
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
            let mut eo: Vec<(u32, u32)> = self
                .edge
                .cross_pairs(&self.obs_edge, |i, j, o: &mut Vec<(u32, u32)>| {
                    o.push((i, j))
                });
            let no = obs.edges.len();
            crate::radix::sort_by_bucket_then_key(&mut eo, (ne, no), |p| p.0, |p| p.1);
            out.extend(eo.into_iter().map(|(a, b)| Pair {
                kind: PairKind::EdgeObstacleEdge,
                a,
                b,
            }));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec2;
    use crate::mesh::Topology;
    use crate::sim::collision::obstacle_free_scene_for_tests as scene_of;
    use crate::sim::collision::{impulses, OBSTACLE};
    use crate::sim::obstacle::{Obstacle, Obstacles};
    use crate::sim::policy::UniformThickness;
    use proptest::prelude::*;

    /// Brute-force oracle: every cloth vertex-triangle pair (vertex not a corner) whose swept
    /// boxes overlap, every edge pair without a common vertex whose boxes overlap, and the
    /// cloth-obstacle pairs likewise, with the boxes of [`BroadPhase::update`].
    fn all_pairs(scene: &Scene, v: &[Vec3], margin: f64) -> Vec<Pair> {
        let tb: Vec<Aabb> = scene
            .triangles
            .iter()
            .map(|t| swept(scene, v, *t, margin))
            .collect();
        let eb: Vec<Aabb> = scene
            .edges
            .iter()
            .map(|e| swept(scene, v, *e, 0.5 * margin))
            .collect();
        let obs = scene.obstacles;
        let ot: Vec<Aabb> = obs
            .triangles
            .iter()
            .map(|t| swept(scene, v, t.map(|k| k | OBSTACLE), 0.0))
            .collect();
        let oe: Vec<Aabb> = obs
            .edges
            .iter()
            .map(|e| swept(scene, v, e.map(|k| k | OBSTACLE), 0.5 * margin))
            .collect();
        let mut out = Vec::new();
        for p in 0..scene.x0.len() as u32 {
            let b = swept(scene, v, [p], 0.0);
            for (t, tri) in scene.triangles.iter().enumerate() {
                if !tri.contains(&p) && b.overlaps(&tb[t]) {
                    out.push(Pair {
                        kind: PairKind::VertexTriangle,
                        a: p,
                        b: t as u32,
                    });
                }
            }
            for (t, bt) in ot.iter().enumerate() {
                if b.inflated(margin).overlaps(bt) {
                    out.push(Pair {
                        kind: PairKind::VertexObstacle,
                        a: p,
                        b: t as u32,
                    });
                }
            }
        }
        for i in 0..scene.edges.len() {
            let e = scene.edges[i];
            for j in i + 1..scene.edges.len() {
                let f = scene.edges[j];
                let shared = e.iter().any(|k| f.contains(k));
                if !shared && eb[i].overlaps(&eb[j]) {
                    out.push(Pair {
                        kind: PairKind::EdgeEdge,
                        a: i as u32,
                        b: j as u32,
                    });
                }
            }
            for (j, bj) in oe.iter().enumerate() {
                if eb[i].overlaps(bj) {
                    out.push(Pair {
                        kind: PairKind::EdgeObstacleEdge,
                        a: i as u32,
                        b: j as u32,
                    });
                }
            }
        }
        for q in 0..obs.start.len() as u32 {
            let b = swept(scene, v, [q | OBSTACLE], 0.0);
            for (t, bt) in tb.iter().enumerate() {
                if b.overlaps(bt) {
                    out.push(Pair {
                        kind: PairKind::ObstacleVertex,
                        a: q,
                        b: t as u32,
                    });
                }
            }
        }
        out.sort_unstable();
        out
    }

    /// The order [`BroadPhase::candidates`] promises: vertex pairs by (vertex, kind, triangle),
    /// then edge-edge, obstacle-vertex and cloth-obstacle edge pairs, each by (first, second).
    fn canonical(mut pairs: Vec<Pair>) -> Vec<Pair> {
        pairs.sort_unstable_by_key(|p| match p.kind {
            PairKind::VertexTriangle | PairKind::VertexObstacle => (0, p.a, p.kind, p.b),
            PairKind::EdgeEdge => (1, p.a, p.kind, p.b),
            PairKind::ObstacleVertex => (2, p.a, p.kind, p.b),
            PairKind::EdgeObstacleEdge => (3, p.a, p.kind, p.b),
        });
        pairs
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// [`BroadPhase::candidates`] against the brute-force oracle on crumpled sheets (with
        /// and without a floor obstacle) under random velocities: the same set, no duplicate,
        /// in the canonical order (independent of the tree and of the traversal fronts left by
        /// an earlier call); and every pair that
        /// CCD over *all* pairs finds colliding is among the candidates (superset of the true
        /// pairs).
        #[test]
        fn candidates_are_the_brute_force_overlaps(
            seed in any::<u64>(),
            nx in 3usize..10,
            speed in 0.01f64..2.0,
            floor in any::<bool>(),
            rebuild_then_refit in any::<bool>(),
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let amp = rng.random_range(0.0..0.05);
            let sheet = crate::scenes::handkerchief("s", nx, nx + 1, 0.1, 0.1, |uv: Vec2| {
                Vec3::new(uv.x, amp * (60.0 * uv.x).sin() * (45.0 * uv.y).cos(), uv.y)
            });
            let topo = Topology::new(&sheet).unwrap();
            let n = sheet.positions.len();
            let mut obstacles = Obstacles::default();
            if floor {
                let f = crate::scenes::handkerchief("f", 4, 4, 0.15, 0.15, |uv: Vec2| {
                    Vec3::new(uv.x, -0.01 + 0.1 * uv.y, uv.y)
                });
                obstacles.add(Obstacle::from_mesh(&f, 2e-3, 0.1).unwrap()).unwrap();
            }
            let (hinge, inv_mass) = (vec![[u32::MAX; 3]; sheet.triangles.len()], vec![1.0; n]);
            let scene =
                scene_of(&sheet.positions, &sheet.triangles, &topo.edges, &hinge, &obstacles, &inv_mass);
            let rv = |rng: &mut rand_chacha::ChaCha8Rng| {
                Vec3::new(
                    rng.random_range(-speed..speed),
                    rng.random_range(-speed..speed),
                    rng.random_range(-speed..speed),
                )
            };
            let mut v: Vec<Vec3> = (0..n).map(|_| rv(&mut rng)).collect();
            let policy = UniformThickness(3e-3);
            let margin = 3e-3 * 1.0001;
            let mut broad = BroadPhase::default();
            broad.update(&scene, &v, margin, true);
            if rebuild_then_refit {
                // A first traversal leaves its fronts, which the one after the refit starts from.
                let _ = broad.candidates(&scene, &v, margin);
                v = (0..n).map(|_| rv(&mut rng)).collect();
                broad.update(&scene, &v, margin, false);
            }
            let got = broad.candidates(&scene, &v, margin);
            let mut sorted = got.clone();
            sorted.sort_unstable();
            let len = sorted.len();
            sorted.dedup();
            prop_assert_eq!(len, sorted.len(), "duplicates");
            let want = all_pairs(&scene, &v, margin);
            prop_assert_eq!(&sorted, &want);
            // The exact sequence is the canonical order of the brute-force set, whatever tree
            // (built from these boxes, or from other ones and refitted) produced it.
            prop_assert_eq!(&got, &canonical(want));
            // Superset of the true pairs: CCD over every primitive pair.
            let mut every = Vec::new();
            for p in 0..n as u32 {
                for t in 0..sheet.triangles.len() as u32 {
                    if !sheet.triangles[t as usize].contains(&p) {
                        every.push(Pair { kind: PairKind::VertexTriangle, a: p, b: t });
                    }
                }
            }
            for a in 0..topo.edges.len() as u32 {
                for b in a + 1..topo.edges.len() as u32 {
                    let (e, f) = (topo.edges[a as usize], topo.edges[b as usize]);
                    if !e.iter().any(|k| f.contains(k)) {
                        every.push(Pair { kind: PairKind::EdgeEdge, a, b });
                    }
                }
            }
            let hits = impulses::detect(&scene, &v, &every, &policy, &|_: &[u32; 4]| false);
            for c in &hits {
                prop_assert!(sorted.binary_search(&c.pair).is_ok(), "{:?} collides but is no candidate", c.pair);
            }
        }
    }
}
