//! Inside regions of partitioning paths (Wicke et al. 2006, Sec. 4.2): the edges a CLOSED, LL or
//! BB path passes across (an odd number of times) are cut, its loop vertices are removed, and a
//! flood fill run in lock-step from both sides of one cut edge finds the smaller side (by vertex
//! count, as Cha & Ko count it) in time proportional to that side. A path that does not split its
//! mesh (a BB path joining two different boundary loops of a sleeve, say) gets no region.

use super::input::AnalysisMesh;
use super::paths::{Path, PathKind};
use super::segments::Segment;
use crate::geom::Vec3;
use std::ops::Range;

/// Scratch buffers reused across paths (stamps avoid clearing).
pub struct RegionFinder<'a> {
    mesh: &'a AnalysisMesh,
    edge_stamp: Vec<u32>,
    vertex_stamp: Vec<u32>,
    vertex_side: Vec<u8>,
    stamp: u32,
    /// Region of interest for BLI paths: vertices stamped with `roi_stamp` are inside it.
    roi: Vec<u32>,
    roi_stamp: u32,
    dist: Vec<f64>,
    /// The two flood queues (kept for their capacity).
    queues: [Vec<u32>; 2],
    /// Winding numbers computed so far ([`RegionFinder::winding_region`]; NaN: not yet; empty
    /// until first needed). Positions are fixed for a finder's life, so they stay valid.
    winding: Vec<f64>,
    /// Each object's reference winding number (median of a vertex sample), once computed.
    reference: Vec<Option<f64>>,
    /// Each object's fast-winding-number hierarchy, once built.
    trees: Vec<Option<super::winding::Tree>>,
}

/// Outcome for one path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Region {
    /// Not a partitioning path, or no vertex on either side to start from.
    None,
    /// The path does not separate its mesh.
    NotSeparating,
    /// The smaller side's vertices, sorted.
    Inside(Vec<u32>),
}

impl<'a> RegionFinder<'a> {
    /// Scratch space for `mesh`.
    pub fn new(mesh: &'a AnalysisMesh) -> Self {
        RegionFinder {
            mesh,
            edge_stamp: vec![0; mesh.topology.num_edges()],
            vertex_stamp: vec![0; mesh.num_vertices()],
            vertex_side: vec![0; mesh.num_vertices()],
            stamp: 0,
            roi: vec![0; mesh.num_vertices()],
            roi_stamp: 0,
            dist: vec![f64::INFINITY; mesh.num_vertices()],
            queues: [Vec::new(), Vec::new()],
            winding: Vec::new(),
            reference: vec![None; mesh.objects.len()],
            trees: (0..mesh.objects.len()).map(|_| None).collect(),
        }
    }

    /// The inside region of a BLI path by Wicke's cone heuristic (Sec. 4.2): the cloth around a
    /// BLI path forms a cone with the loop vertex at its apex; restricted to a geodesic disc
    /// around the loop vertex just large enough to contain the nearer end of the path, the path
    /// splits the disc and the smaller side is inside. Distances are Dijkstra distances along
    /// world-space edges.
    pub fn bli_cone(&mut self, path: &Path, segments: &[Segment], pos: &[Vec3]) -> Region {
        if path.kind != PathKind::BoundaryLoopInside || path.cut_edges().is_empty() {
            return Region::None;
        }
        let Some(&apex) = path.loop_vertices().first() else {
            return Region::None;
        };
        let topo = &self.mesh.topology;
        // Each end of the path lies in the triangle of the path's first or last piece. The disc
        // reaches the nearer end: its radius is the distance of that triangle's nearest corner,
        // so the path leaves the disc through its end triangle and splits the disc (a larger
        // disc would let the two sides join around the end).
        let end_triangle = |piece: u32| {
            let seg = &segments[(piece / 2) as usize];
            self.mesh.triangles[seg.triangles[(piece % 2) as usize] as usize]
        };
        let ends = [
            end_triangle(path.pieces()[0]),
            end_triangle(*path.pieces().last().expect("non-empty")),
        ];
        self.roi_stamp += 1;
        let rs = self.roi_stamp;
        let mut heap = std::collections::BinaryHeap::new();
        let mut settled: Vec<u32> = Vec::new();
        self.dist[apex as usize] = 0.0;
        let mut touched = vec![apex];
        heap.push(std::cmp::Reverse((OrdF(0.0), apex)));
        let mut radius = f64::INFINITY;
        while let Some(std::cmp::Reverse((OrdF(d), v))) = heap.pop() {
            if d > self.dist[v as usize] || self.roi[v as usize] == rs {
                continue;
            }
            if d > radius {
                break;
            }
            self.roi[v as usize] = rs;
            settled.push(v);
            if v != apex && ends.iter().any(|tri| tri.contains(&v)) {
                radius = radius.min(d);
            }
            for &w in topo.vertex_neighbors.row(v as usize) {
                let nd = d + (pos[w as usize] - pos[v as usize]).norm();
                if nd < self.dist[w as usize] {
                    if self.dist[w as usize].is_infinite() {
                        touched.push(w);
                    }
                    self.dist[w as usize] = nd;
                    heap.push(std::cmp::Reverse((OrdF(nd), w)));
                }
            }
        }
        for &v in &touched {
            self.dist[v as usize] = f64::INFINITY;
        }
        self.flood(path, Some(rs))
    }

    /// The inside region of a BLI path whose loop vertex lies on the boundary (ours): the half
    /// of the path from the loop vertex to its `B` end then runs from boundary to boundary and
    /// separates the mesh like a BB path, so the smaller side is a true inside region, with no
    /// disc to cut it off (the other half ends inside and only slits the surface). The flood is
    /// seeded from the cut edges in turn until one separates (a seed on the slit does not), at
    /// most `MAX_SEEDS` of them spread over the cut; [`Region::NotSeparating`] when none does or
    /// the loop vertex is interior.
    pub fn bli_boundary_partition(&mut self, path: &Path) -> Region {
        const MAX_SEEDS: usize = 8;
        let topo = &self.mesh.topology;
        if path.kind != PathKind::BoundaryLoopInside
            || path.cut_edges().is_empty()
            || !path
                .loop_vertices()
                .iter()
                .all(|&v| topo.boundary_vertex[v as usize])
        {
            return Region::NotSeparating;
        }
        let n = path.cut_edges().len();
        let stride = n.div_ceil(MAX_SEEDS).max(1);
        for k in (0..n).step_by(stride) {
            let st = self.stamp_cut(path);
            let [a, b] = topo.edges[path.cut_edges()[k] as usize];
            if self.removed(a, st) || self.removed(b, st) {
                continue;
            }
            let region = self.flood_from([a, b], st, None);
            if let Region::Inside(_) = region {
                return region;
            }
        }
        Region::NotSeparating
    }

    /// The inside region of a path by the generalized winding number (ours), for the paths the
    /// rules above leave without one on a garment: long BLIs whose loop vertex is interior (a
    /// leg's inner wall passed into the other leg: neither the boundary partition nor the cone
    /// applies), BI paths (a hem passed through the other leg's wall) and cuts that do not
    /// separate. On a consistently oriented garment, a vertex whose cloth lies inside another
    /// tube of the same object has a winding number ([`super::winding`]) about 1 away from the
    /// object's typical on-surface value (the median over a fixed sample of its vertices, about
    /// 1/2); the path's cut edges then have one such endpoint and one typical one. The region is
    /// the flood from the atypical endpoints of (up to 16, spread) cut edges through vertices at
    /// least 1/2 away from the typical value, never across the path's cut edges or through its
    /// loop vertices.
    ///
    /// [`Region::None`] when the path runs between two objects (one garment legitimately lies
    /// inside another), when its object is a topological disc (a sheet, like the handkerchief:
    /// it encloses nothing) or its typical value is below 1/4 in magnitude (open sheets,
    /// inconsistent orientation), when fewer than half of the sampled cut edges show the
    /// contrast (at least 0.6 away against at most 0.4), or when the flood reaches half of the
    /// object's vertices (no inside).
    pub fn winding_region(&mut self, path: &Path, segments: &[Segment], pos: &[Vec3]) -> Region {
        const SAMPLED_CUT_EDGES: usize = 16;
        const REFERENCE_SAMPLE: usize = 64;
        let Some(&first) = path.pieces().first() else {
            return Region::None;
        };
        let seg = &segments[(first / 2) as usize];
        let of = |t: u32| self.mesh.object_of_triangle[t as usize];
        if path.cut_edges().is_empty() || of(seg.triangles[0]) != of(seg.triangles[1]) {
            return Region::None;
        }
        let object = &self.mesh.objects[path.object as usize];
        let (verts, tris) = (object.vertices.clone(), object.triangles.clone());
        if self.winding.is_empty() {
            self.winding = vec![f64::NAN; self.mesh.num_vertices()];
        }
        let reference = match self.reference[path.object as usize] {
            Some(r) => r,
            None => {
                let r = if self.is_disc(&verts, &tris) {
                    0.0
                } else {
                    let n = (verts.end - verts.start) as usize;
                    let stride = n.div_ceil(REFERENCE_SAMPLE).max(1);
                    let sample: Vec<u32> = (verts.start..verts.end).step_by(stride).collect();
                    let mut w = self.windings(&sample, pos, path.object);
                    w.sort_by(f64::total_cmp);
                    w[w.len() / 2]
                };
                self.reference[path.object as usize] = Some(r);
                r
            }
        };
        if reference.abs() < 0.25 {
            return Region::None;
        }
        let st = self.stamp_cut(path);
        let topo = &self.mesh.topology;
        let cut = path.cut_edges();
        let stride = cut.len().div_ceil(SAMPLED_CUT_EDGES).max(1);
        let ends: Vec<[u32; 2]> = cut
            .iter()
            .step_by(stride)
            .map(|&e| topo.edges[e as usize])
            .filter(|&[a, b]| !self.removed(a, st) && !self.removed(b, st))
            .collect();
        let flat: Vec<u32> = ends.iter().flatten().copied().collect();
        let w = self.windings(&flat, pos, path.object);
        let off = |x: f64| (x - reference).abs();
        let seeds: Vec<u32> = ends
            .iter()
            .zip(w.chunks(2))
            .filter_map(|(&[a, b], w)| {
                let (da, db) = (off(w[0]), off(w[1]));
                match (da >= 0.6 && db <= 0.4, db >= 0.6 && da <= 0.4) {
                    (true, _) => Some(a),
                    (_, true) => Some(b),
                    _ => None,
                }
            })
            .collect();
        if seeds.is_empty() || 2 * seeds.len() < ends.len() {
            return Region::None;
        }
        let limit = (verts.end - verts.start) as usize / 2;
        let mut region = Vec::new();
        let mut layer = Vec::new();
        for &s in &seeds {
            if self.vertex_stamp[s as usize] != st {
                self.vertex_stamp[s as usize] = st;
                self.vertex_side[s as usize] = 0;
                layer.push(s);
            }
        }
        while !layer.is_empty() {
            region.extend_from_slice(&layer);
            if region.len() > limit {
                return Region::None;
            }
            let mut next = Vec::new();
            for &v in &layer {
                let nbrs = topo.vertex_neighbors.row(v as usize);
                let edges = topo.vertex_edges.row(v as usize);
                for (&u, &e) in nbrs.iter().zip(edges) {
                    if self.edge_stamp[e as usize] == st || self.vertex_stamp[u as usize] == st {
                        continue;
                    }
                    self.vertex_stamp[u as usize] = st;
                    self.vertex_side[u as usize] = 1;
                    next.push(u);
                }
            }
            let w = self.windings(&next, pos, path.object);
            layer = next
                .into_iter()
                .zip(w)
                .filter(|&(_, w)| off(w) > 0.5)
                .map(|(u, _)| u)
                .collect();
            for &u in &layer {
                self.vertex_side[u as usize] = 0;
            }
        }
        Region::Inside(sorted(&region))
    }

    /// Whether the object with these vertices and triangles is a topological disc (Euler
    /// characteristic `V - E + F = 1`).
    fn is_disc(&self, verts: &Range<u32>, tris: &Range<u32>) -> bool {
        let topo = &self.mesh.topology;
        let edges = topo.edges.iter().filter(|e| verts.contains(&e[0])).count() as i64;
        let (v, f) = (
            (verts.end - verts.start) as i64,
            (tris.end - tris.start) as i64,
        );
        v - edges + f == 1
    }

    /// Winding numbers of `vertices` with respect to the triangles of `object`, memoised (by
    /// the object's [`super::winding::Tree`], built at the first call).
    fn windings(&mut self, vertices: &[u32], pos: &[Vec3], object: u32) -> Vec<f64> {
        let todo: Vec<u32> = vertices
            .iter()
            .copied()
            .filter(|&v| self.winding[v as usize].is_nan())
            .collect();
        let tris = &self.mesh.triangles;
        let tree = self.trees[object as usize].get_or_insert_with(|| {
            let range = self.mesh.objects[object as usize].triangles.clone();
            super::winding::Tree::new(pos, tris, range)
        });
        let w = tree.at_vertices(&todo, pos, tris);
        for (v, w) in todo.into_iter().zip(w) {
            self.winding[v as usize] = w;
        }
        vertices.iter().map(|&v| self.winding[v as usize]).collect()
    }

    /// The inside region of `path` (smaller side of its cut).
    pub fn inside(&mut self, path: &Path) -> Region {
        if !path.kind.is_partitioning() {
            return Region::None;
        }
        self.flood(path, None)
    }

    /// Lock-step flood fill from both sides of a cut edge, optionally within a region of interest.
    fn flood(&mut self, path: &Path, roi: Option<u32>) -> Region {
        if path.cut_edges().is_empty() {
            return Region::None;
        }
        let topo = &self.mesh.topology;
        let st = self.stamp_cut(path);
        let seed = path.cut_edges().iter().find_map(|&e| {
            let [a, b] = topo.edges[e as usize];
            (!self.removed(a, st) && !self.removed(b, st)).then_some([a, b])
        });
        let Some(seed) = seed else {
            return Region::None;
        };
        self.flood_from(seed, st, roi)
    }

    /// A new stamp with the path's cut edges and its loop vertices (removed: side 2) marked.
    fn stamp_cut(&mut self, path: &Path) -> u32 {
        self.stamp += 1;
        let st = self.stamp;
        for &e in path.cut_edges() {
            self.edge_stamp[e as usize] = st;
        }
        for &v in path.loop_vertices() {
            self.vertex_stamp[v as usize] = st;
            self.vertex_side[v as usize] = 2;
        }
        st
    }

    /// Whether `v` is removed (a loop vertex of the cut stamped `st`).
    fn removed(&self, v: u32, st: u32) -> bool {
        self.vertex_stamp[v as usize] == st && self.vertex_side[v as usize] == 2
    }

    /// The lock-step flood from the two ends of a cut edge under stamp `st`.
    fn flood_from(&mut self, seed: [u32; 2], st: u32, roi: Option<u32>) -> Region {
        let mut queues = std::mem::take(&mut self.queues);
        for (q, s) in queues.iter_mut().zip(seed) {
            q.clear();
            q.push(s);
        }
        let region = self.lock_step(&mut queues, st, roi);
        self.queues = queues;
        region
    }

    /// The lock-step flood of [`RegionFinder::flood`] from the seeds in `queues`.
    fn lock_step(&mut self, queues: &mut [Vec<u32>; 2], st: u32, roi: Option<u32>) -> Region {
        let in_roi = |roi_arr: &[u32], v: u32| roi.is_none_or(|r| roi_arr[v as usize] == r);
        let topo = &self.mesh.topology;
        let seed = [queues[0][0], queues[1][0]];
        let mut heads = [0usize; 2];
        for s in 0..2 {
            self.vertex_stamp[seed[s] as usize] = st;
            self.vertex_side[seed[s] as usize] = s as u8;
        }
        let mut done = [false; 2];
        loop {
            for s in 0..2 {
                if done[s] {
                    continue;
                }
                if heads[s] == queues[s].len() {
                    done[s] = true;
                    continue;
                }
                let v = queues[s][heads[s]];
                heads[s] += 1;
                let nbrs = topo.vertex_neighbors.row(v as usize);
                let edges = topo.vertex_edges.row(v as usize);
                for (&w, &e) in nbrs.iter().zip(edges) {
                    if self.edge_stamp[e as usize] == st || !in_roi(&self.roi, w) {
                        continue;
                    }
                    if self.vertex_stamp[w as usize] == st {
                        let side = self.vertex_side[w as usize];
                        if side as usize != s && side != 2 {
                            return Region::NotSeparating;
                        }
                        continue;
                    }
                    self.vertex_stamp[w as usize] = st;
                    self.vertex_side[w as usize] = s as u8;
                    queues[s].push(w);
                }
            }
            // A side is complete once its queue is exhausted; it is the inside if the other side
            // has already found at least as many vertices (ties: the side without the lowest
            // vertex index, a fixed rule).
            let complete = |s: usize| heads[s] == queues[s].len();
            for s in 0..2 {
                if complete(s) {
                    let o = 1 - s;
                    let (ns, no) = (queues[s].len(), queues[o].len());
                    if ns < no {
                        return Region::Inside(sorted(&queues[s]));
                    }
                    if complete(o) {
                        if ns == no {
                            let ms = queues[s].iter().min();
                            let mo = queues[o].iter().min();
                            let pick = if ms > mo { s } else { o };
                            return Region::Inside(sorted(&queues[pick]));
                        }
                        return Region::Inside(sorted(&queues[o]));
                    }
                }
            }
        }
    }
}

/// A total order on finite distances for the Dijkstra heap.
#[derive(Clone, Copy, PartialEq)]
struct OrdF(f64);
impl Eq for OrdF {}
impl Ord for OrdF {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0)
    }
}
impl PartialOrd for OrdF {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

fn sorted(v: &[u32]) -> Vec<u32> {
    let mut v = v.to_vec();
    v.sort_unstable();
    v
}
