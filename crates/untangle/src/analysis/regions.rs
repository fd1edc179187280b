//! Inside regions of partitioning paths (Wicke et al. 2006, Sec. 4.2): the edges a CLOSED, LL or
//! BB path passes across (an odd number of times) are cut, its loop vertices are removed, and a
//! flood fill run in lock-step from both sides of one cut edge finds the smaller side (by vertex
//! count, as Cha & Ko count it) in time proportional to that side. A path that does not split its
//! mesh (a BB path joining two different boundary loops of a sleeve, say) gets no region.

use super::input::AnalysisMesh;
use super::paths::Path;

/// Scratch buffers reused across paths (stamps avoid clearing).
pub struct RegionFinder<'a> {
    mesh: &'a AnalysisMesh,
    edge_stamp: Vec<u32>,
    vertex_stamp: Vec<u32>,
    vertex_side: Vec<u8>,
    stamp: u32,
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
        }
    }

    /// The inside region of `path` (smaller side of its cut).
    pub fn inside(&mut self, path: &Path) -> Region {
        if !path.kind.is_partitioning() || path.cut_edges.is_empty() {
            return Region::None;
        }
        let topo = &self.mesh.topology;
        self.stamp += 1;
        let st = self.stamp;
        for &e in &path.cut_edges {
            self.edge_stamp[e as usize] = st;
        }
        // Removed vertices (loop vertices on the path) are stamped with side 2.
        for &v in &path.loop_vertices {
            self.vertex_stamp[v as usize] = st;
            self.vertex_side[v as usize] = 2;
        }
        let seed = path.cut_edges.iter().find_map(|&e| {
            let [a, b] = topo.edges[e as usize];
            let free = |v: u32| {
                !(self.vertex_stamp[v as usize] == st && self.vertex_side[v as usize] == 2)
            };
            (free(a) && free(b)).then_some([a, b])
        });
        let Some(seed) = seed else {
            return Region::None;
        };
        let mut queues: [Vec<u32>; 2] = [vec![seed[0]], vec![seed[1]]];
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
                    if self.edge_stamp[e as usize] == st {
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

fn sorted(v: &[u32]) -> Vec<u32> {
    let mut v = v.to_vec();
    v.sort_unstable();
    v
}
