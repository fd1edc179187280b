//! Connectivity of a triangle mesh over its world vertices: edges, the triangles beside each
//! edge, one-rings and boundaries. Seams are interior here (the two panels' triangles share the
//! world edge), so the garment is analysed as the sewn surface.

use super::Mesh;
use crate::error::{Error, Result};

/// Marker for "no triangle" (the missing side of a boundary edge).
pub const NONE: u32 = u32::MAX;

/// Compressed sparse rows: `items[offsets[i]..offsets[i + 1]]` belong to `i`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Csr {
    /// Row starts, one more than the number of rows.
    pub offsets: Vec<u32>,
    /// Concatenated rows.
    pub items: Vec<u32>,
}

impl Csr {
    /// The items of row `i`.
    #[inline]
    pub fn row(&self, i: usize) -> &[u32] {
        &self.items[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Builds rows from `(row, item)` pairs; items keep their order of appearance within a row.
    pub fn from_pairs(rows: usize, pairs: impl Iterator<Item = (u32, u32)> + Clone) -> Csr {
        let mut offsets = vec![0u32; rows + 1];
        for (r, _) in pairs.clone() {
            offsets[r as usize + 1] += 1;
        }
        for i in 0..rows {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut items = vec![0u32; offsets[rows] as usize];
        for (r, it) in pairs {
            items[fill[r as usize] as usize] = it;
            fill[r as usize] += 1;
        }
        Csr { offsets, items }
    }
}

/// Edges, edge-triangle incidence and one-rings of a manifold triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Topology {
    /// Number of world vertices.
    pub num_vertices: usize,
    /// Edges as `(low, high)` vertex pairs, sorted.
    pub edges: Vec<[u32; 2]>,
    /// The one or two triangles beside each edge; the second is [`NONE`] on a boundary edge.
    pub edge_triangles: Vec<[u32; 2]>,
    /// For each triangle, the edge from corner `k` to corner `k + 1`.
    pub triangle_edges: Vec<[u32; 3]>,
    /// Triangles around each vertex.
    pub vertex_triangles: Csr,
    /// Vertices adjacent to each vertex (sorted).
    pub vertex_neighbors: Csr,
    /// The edge to each neighbour, parallel to `vertex_neighbors`.
    pub vertex_edges: Csr,
    /// Whether a vertex lies on a boundary edge.
    pub boundary_vertex: Vec<bool>,
}

impl Topology {
    /// Builds the topology; fails on an edge shared by more than two triangles (non-manifold),
    /// naming the triangles' places.
    pub fn new(mesh: &Mesh) -> Result<Topology> {
        Self::from_triangles(&mesh.triangles, mesh.positions.len(), |t| {
            mesh.triangle_place(t)
        })
    }

    /// Builds the topology of bare triangles over `num_vertices` vertices; `place` names a
    /// triangle in error messages. Indices must be in range.
    pub fn from_triangles(
        triangles: &[[u32; 3]],
        num_vertices: usize,
        place: impl Fn(usize) -> String,
    ) -> Result<Topology> {
        let mut half: Vec<(u64, u32)> = Vec::with_capacity(triangles.len() * 3);
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                half.push((((lo as u64) << 32) | hi as u64, (t as u32) * 3 + k as u32));
            }
        }
        // By edge, then half-edge: the half-edges are pushed in increasing order, so a stable
        // sort by `(low, high)` (two counting sorts, linear) gives the order of sorting the
        // whole tuples.
        crate::radix::sort_by_bucket_then_key(
            &mut half,
            (num_vertices, num_vertices),
            |h| (h.0 >> 32) as u32,
            |h| h.0 as u32,
        );
        let mut edges = Vec::with_capacity(half.len() / 2 + 8);
        let mut edge_triangles = Vec::with_capacity(half.len() / 2 + 8);
        let mut triangle_edges = vec![[0u32; 3]; triangles.len()];
        let mut i = 0;
        while i < half.len() {
            let key = half[i].0;
            let mut j = i;
            while j < half.len() && half[j].0 == key {
                j += 1;
            }
            let (lo, hi) = ((key >> 32) as u32, key as u32);
            if let Some((first, second)) = duplicate(&half[i..j], triangles) {
                return Err(Error::input(
                    place(second),
                    format!(
                        "duplicate face: the same three vertices as the face at {}",
                        place(first)
                    ),
                ));
            }
            if j - i > 2 {
                let lines: Vec<String> = half[i..j]
                    .iter()
                    .map(|h| place((h.1 / 3) as usize))
                    .collect();
                return Err(Error::input(
                    place((half[i].1 / 3) as usize),
                    format!(
                        "non-manifold edge between vertices {} and {}: shared by {} faces ({})",
                        lo + 1,
                        hi + 1,
                        j - i,
                        lines.join(", ")
                    ),
                ));
            }
            let e = edges.len() as u32;
            edges.push([lo, hi]);
            let t0 = half[i].1 / 3;
            let t1 = if j - i == 2 { half[i + 1].1 / 3 } else { NONE };
            edge_triangles.push([t0, t1]);
            for h in &half[i..j] {
                triangle_edges[(h.1 / 3) as usize][(h.1 % 3) as usize] = e;
            }
            i = j;
        }
        let vertex_triangles = Csr::from_pairs(
            num_vertices,
            triangles
                .iter()
                .enumerate()
                .flat_map(|(t, tri)| tri.iter().map(move |&v| (v, t as u32))),
        );
        // (vertex, neighbour, edge) sorted, so every one-ring row is sorted by neighbour.
        let mut incid: Vec<(u32, u32, u32)> = Vec::with_capacity(edges.len() * 2);
        for (i, e) in edges.iter().enumerate() {
            incid.push((e[0], e[1], i as u32));
            incid.push((e[1], e[0], i as u32));
        }
        // Every (vertex, neighbour) pair appears once (edges are unique): sorting by it alone
        // (stable counting sorts) gives the order of sorting the whole triples.
        crate::radix::sort_by_bucket_then_key(
            &mut incid,
            (num_vertices, num_vertices),
            |x| x.0,
            |x| x.1,
        );
        let vertex_neighbors = Csr::from_pairs(num_vertices, incid.iter().map(|x| (x.0, x.1)));
        let vertex_edges = Csr::from_pairs(num_vertices, incid.iter().map(|x| (x.0, x.2)));
        let mut boundary_vertex = vec![false; num_vertices];
        for (e, et) in edges.iter().zip(&edge_triangles) {
            if et[1] == NONE {
                boundary_vertex[e[0] as usize] = true;
                boundary_vertex[e[1] as usize] = true;
            }
        }
        Ok(Topology {
            num_vertices,
            edges,
            edge_triangles,
            triangle_edges,
            vertex_triangles,
            vertex_neighbors,
            vertex_edges,
            boundary_vertex,
        })
    }

    /// Whether edge `e` is a boundary edge (one triangle beside it).
    #[inline]
    pub fn is_boundary_edge(&self, e: u32) -> bool {
        self.edge_triangles[e as usize][1] == NONE
    }

    /// The triangle across edge `e` from triangle `t` ([`NONE`] on a boundary).
    #[inline]
    pub fn other_triangle(&self, e: u32, t: u32) -> u32 {
        let et = self.edge_triangles[e as usize];
        if et[0] == t {
            et[1]
        } else {
            et[0]
        }
    }

    /// The edge index joining `a` and `b`, if any.
    pub fn edge_between(&self, a: u32, b: u32) -> Option<u32> {
        let key = if a < b { [a, b] } else { [b, a] };
        self.edges.binary_search(&key).ok().map(|e| e as u32)
    }

    /// Number of edges.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// Per vertex, the shortest distance along edges to a boundary vertex, edge `e` from `v` to
    /// `w` being `len(v, w, e)` long (multi-source Dijkstra; ties settle the lower vertex first, so
    /// the sums are the same on every run). Infinite where no boundary is reachable (a closed
    /// surface). Used for the HRBF interior constraints (world lengths) and Wicke's BI/BI
    /// boundary field (rest lengths).
    pub fn distances_to_boundary(&self, len: impl Fn(u32, u32, u32) -> f64) -> Vec<f64> {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        let mut dist = vec![f64::INFINITY; self.boundary_vertex.len()];
        let mut heap = BinaryHeap::new();
        for (v, _) in self.boundary_vertex.iter().enumerate().filter(|(_, &b)| b) {
            dist[v] = 0.0;
            heap.push(Reverse((0u64, v as u32)));
        }
        // Non-negative distances order as their bit patterns.
        while let Some(Reverse((d, v))) = heap.pop() {
            let d = f64::from_bits(d);
            if d > dist[v as usize] {
                continue;
            }
            let edges = self.vertex_edges.row(v as usize);
            for (&u, &e) in self.vertex_neighbors.row(v as usize).iter().zip(edges) {
                let nd = d + len(v, u, e);
                if nd < dist[u as usize] {
                    dist[u as usize] = nd;
                    heap.push(Reverse((nd.to_bits(), u)));
                }
            }
        }
        dist
    }
}

/// Among the faces beside one edge (half-edges `3 t + k`, in increasing order), the first two
/// with the same three vertices in any order (a duplicated face), as `(earlier, later)`.
fn duplicate(beside: &[(u64, u32)], triangles: &[[u32; 3]]) -> Option<(usize, usize)> {
    let sorted = |t: u32| {
        let mut v = triangles[t as usize];
        v.sort_unstable();
        v
    };
    for (a, ha) in beside.iter().enumerate() {
        for hb in &beside[a + 1..] {
            let (ta, tb) = (ha.1 / 3, hb.1 / 3);
            if ta != tb && sorted(ta) == sorted(tb) {
                return Some((ta as usize, tb as usize));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_of_two_triangles() {
        let tris = [[0u32, 1, 2], [0, 2, 3]];
        let t = Topology::from_triangles(&tris, 4, |i| format!("t{i}")).unwrap();
        assert_eq!(t.edges.len(), 5);
        let diag = t.edge_between(0, 2).unwrap();
        assert!(!t.is_boundary_edge(diag));
        assert_eq!(t.other_triangle(diag, 0), 1);
        assert_eq!(
            t.edges
                .iter()
                .enumerate()
                .filter(|(e, _)| t.is_boundary_edge(*e as u32))
                .count(),
            4
        );
        assert_eq!(t.vertex_neighbors.row(0), &[1, 2, 3]);
        for v in 0..4 {
            for (n, e) in t.vertex_neighbors.row(v).iter().zip(t.vertex_edges.row(v)) {
                assert_eq!(t.edge_between(v as u32, *n), Some(*e));
            }
        }
        assert_eq!(t.vertex_triangles.row(2), &[0, 1]);
        assert!(t.boundary_vertex.iter().all(|&b| b));
        // Edge k of a triangle joins corners k and k + 1.
        for (ti, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                let e = t.edges[t.triangle_edges[ti][k] as usize];
                let (a, b) = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
                assert_eq!(e, [a, b]);
            }
        }
    }

    /// The topology by maps and comparison sorts (the oracle of the counting sorts).
    fn brute_force(tris: &[[u32; 3]], nv: usize) -> Topology {
        use std::collections::BTreeMap;
        let mut by_edge: BTreeMap<[u32; 2], Vec<u32>> = BTreeMap::new();
        for (t, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let h = (t * 3 + k) as u32;
                by_edge.entry([a.min(b), a.max(b)]).or_default().push(h);
            }
        }
        let mut topo = Topology {
            num_vertices: nv,
            triangle_edges: vec![[0; 3]; tris.len()],
            boundary_vertex: vec![false; nv],
            ..Topology::default()
        };
        let mut rings: Vec<Vec<(u32, u32)>> = vec![Vec::new(); nv];
        for (e, (key, hs)) in by_edge.iter().enumerate() {
            topo.edges.push(*key);
            let second = hs.get(1).map_or(NONE, |h| h / 3);
            topo.edge_triangles.push([hs[0] / 3, second]);
            for h in hs {
                topo.triangle_edges[(h / 3) as usize][(h % 3) as usize] = e as u32;
            }
            if second == NONE {
                topo.boundary_vertex[key[0] as usize] = true;
                topo.boundary_vertex[key[1] as usize] = true;
            }
            rings[key[0] as usize].push((key[1], e as u32));
            rings[key[1] as usize].push((key[0], e as u32));
        }
        let csr = |rows: Vec<Vec<u32>>| {
            let mut c = Csr {
                offsets: vec![0],
                items: Vec::new(),
            };
            for r in rows {
                c.items.extend(r);
                c.offsets.push(c.items.len() as u32);
            }
            c
        };
        let mut around: Vec<Vec<u32>> = vec![Vec::new(); nv];
        for (t, tri) in tris.iter().enumerate() {
            for &v in tri {
                around[v as usize].push(t as u32);
            }
        }
        topo.vertex_triangles = csr(around);
        for r in &mut rings {
            r.sort();
        }
        topo.vertex_neighbors = csr(rings
            .iter()
            .map(|r| r.iter().map(|x| x.0).collect())
            .collect());
        topo.vertex_edges = csr(rings
            .iter()
            .map(|r| r.iter().map(|x| x.1).collect())
            .collect());
        topo
    }

    proptest::proptest! {
        /// A grid with shuffled vertex numbers and triangle order (plus unused vertices): the
        /// same topology as the brute force.
        #[test]
        fn matches_the_brute_force(w in 1usize..14, h in 1usize..14, extra in 0usize..5, seed in 0u64..1000) {
            use rand::seq::SliceRandom;
            use rand::SeedableRng;
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let nv = (w + 1) * (h + 1) + extra;
            let mut perm: Vec<u32> = (0..nv as u32).collect();
            perm.shuffle(&mut rng);
            let id = |i: usize, j: usize| perm[i * (h + 1) + j];
            let mut tris = Vec::new();
            for i in 0..w {
                for j in 0..h {
                    tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                    tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
                }
            }
            tris.shuffle(&mut rng);
            let t = Topology::from_triangles(&tris, nv, |i| i.to_string()).unwrap();
            proptest::prop_assert_eq!(t, brute_force(&tris, nv));
        }
    }

    #[test]
    fn non_manifold_edge_is_an_error() {
        let tris = [[0u32, 1, 2], [0, 1, 3], [1, 0, 4]];
        let err = Topology::from_triangles(&tris, 5, |i| format!("f.obj:{}", i + 10)).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("non-manifold edge between vertices 1 and 2"),
            "{msg}"
        );
        assert!(
            msg.contains("f.obj:10") && msg.contains("f.obj:12"),
            "{msg}"
        );
    }

    #[test]
    fn duplicate_face_is_an_error() {
        // The same face twice, in either winding, beside a valid one.
        for dup in [[2u32, 1, 3], [1, 2, 3], [3, 1, 2]] {
            let tris = [[0u32, 1, 2], [1, 3, 2], dup];
            let err =
                Topology::from_triangles(&tris, 4, |i| format!("f.obj:{}", i + 10)).unwrap_err();
            let msg = err.to_string();
            assert!(msg.contains("duplicate face"), "{msg}");
            assert!(
                msg.starts_with("f.obj:12") && msg.contains("f.obj:11"),
                "{msg}"
            );
        }
        // Two faces sharing an edge but not the third vertex are fine.
        assert!(Topology::from_triangles(&[[0, 1, 2], [1, 0, 3]], 4, |i| i.to_string()).is_ok());
    }
}
