//! Thickness caps for pairs of primitives that are neighbours on the cloth (ours; the papers'
//! thickness `epsilon` assumes it is well below the edge length).
//!
//! A vertex and a triangle of its two-ring (a corner of the triangle is joined to the vertex by
//! an edge), or two edges joined by an edge, are a few millimetres apart *in the flat cloth*
//! when the mesh is fine. With a thickness larger than that (the 2 mm of
//! [`crate::sim::UniformThickness`] on a 20k-vertex shirt, whose shortest edges are 1.4 mm),
//! proximity repulsion and the contact springs push such pairs apart *in the plane* every step
//! and fight the stretch forces: the cloth inflates and the step count of impulses and impact
//! zones explodes (BENCHMARKS.md, "Every target after session 26"). [`NearCapped`] wraps a
//! [`ContactPolicy`] and lowers the thickness of such neighbour pairs to `fraction` times the
//! shortest edge at their nodes (at the start of the step). The pairs are still handled, with
//! that thickness, so a fold that brings a vertex through a neighbouring triangle is still
//! stopped (CCD keeps every pair apart at any positive thickness); pairs that are not
//! neighbours keep the policy's thickness.

use super::policy::{Contact, ContactPolicy, ObstaclePair};
use crate::geom::Vec3;
use crate::mesh::Topology;

/// Per vertex, `fraction` times the length of its shortest edge at positions `x`.
pub fn vertex_caps(x: &[Vec3], edges: &[[u32; 2]], fraction: f64) -> Vec<f64> {
    let mut cap = vec![f64::INFINITY; x.len()];
    for e in edges {
        let l = fraction * (x[e[0] as usize] - x[e[1] as usize]).norm();
        for v in e {
            let c = &mut cap[*v as usize];
            if l < *c {
                *c = l;
            }
        }
    }
    cap
}

/// A [`ContactPolicy`] whose cloth-cloth thickness is capped for neighbour pairs (module
/// docs). The cap never goes below a thousandth of the policy's own thickness, so that a
/// degenerate (zero-length) edge does not turn its neighbours' contacts into zero-thickness
/// ones.
pub struct NearCapped<'a> {
    inner: &'a dyn ContactPolicy,
    topology: &'a Topology,
    triangles: &'a [[u32; 3]],
    cap: Vec<f64>,
    /// The smallest cap: a thickness at most this is never capped.
    floor: f64,
}

impl<'a> NearCapped<'a> {
    /// `inner` with neighbour pairs capped at `fraction` times the shortest edge at their
    /// nodes, at positions `x` (the start of the step).
    pub fn new(
        inner: &'a dyn ContactPolicy,
        topology: &'a Topology,
        triangles: &'a [[u32; 3]],
        x: &[Vec3],
        fraction: f64,
    ) -> NearCapped<'a> {
        let cap = vertex_caps(x, &topology.edges, fraction);
        let floor = cap.iter().copied().fold(f64::INFINITY, f64::min);
        NearCapped {
            inner,
            topology,
            triangles,
            cap,
            floor,
        }
    }

    /// Whether some pair's thickness can be capped (else the wrapper answers as `inner`).
    pub fn binds(&self) -> bool {
        self.floor < self.inner.max_thickness()
    }

    /// Whether an edge joins `a` and `b`.
    #[inline]
    fn adjacent(&self, a: u32, b: u32) -> bool {
        self.topology.vertex_neighbors.row(a as usize).contains(&b)
    }

    #[inline]
    fn capped(&self, c: Contact, nodes: [u32; 4], near: impl Fn() -> bool) -> Contact {
        let Contact::Thickness(t) = c else {
            return c;
        };
        // (A NaN thickness is never capped: it compares false.)
        if t.partial_cmp(&self.floor) != Some(std::cmp::Ordering::Greater) {
            return c;
        }
        let m = nodes
            .iter()
            .map(|&n| self.cap[n as usize])
            .fold(f64::INFINITY, f64::min);
        if t > m && near() {
            Contact::Thickness(m.max(1e-3 * t))
        } else {
            c
        }
    }
}

impl ContactPolicy for NearCapped<'_> {
    fn max_thickness(&self) -> f64 {
        self.inner.max_thickness()
    }

    fn vertex_triangle(&self, vertex: u32, triangle: u32) -> Contact {
        let t = self.triangles[triangle as usize];
        self.capped(
            self.inner.vertex_triangle(vertex, triangle),
            [vertex, t[0], t[1], t[2]],
            || t.iter().any(|&c| self.adjacent(vertex, c)),
        )
    }

    fn edge_edge(&self, edge_a: u32, edge_b: u32) -> Contact {
        let edges = &self.topology.edges;
        let (e, f) = (edges[edge_a as usize], edges[edge_b as usize]);
        self.capped(
            self.inner.edge_edge(edge_a, edge_b),
            [e[0], e[1], f[0], f[1]],
            || e.iter().any(|&a| f.iter().any(|&b| self.adjacent(a, b))),
        )
    }

    fn obstacle(&self, pair: ObstaclePair, obstacle_thickness: f64) -> Contact {
        self.inner.obstacle(pair, obstacle_thickness)
    }

    fn uniform_cloth(&self) -> Option<Contact> {
        match self.inner.uniform_cloth() {
            Some(Contact::Thickness(t)) if t > self.floor => None,
            u => u,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::UniformThickness;
    use proptest::prelude::*;

    /// A flat `n x n` grid of squares of side `s`, each split into two triangles.
    fn grid(n: usize, s: f64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
        let mut x = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                x.push(Vec3::new(j as f64 * s, i as f64 * s, 0.0));
            }
        }
        let mut t = Vec::new();
        for i in 0..n {
            for j in 0..n {
                t.push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
            }
        }
        (x, t)
    }

    fn topology(n: usize, t: &[[u32; 3]]) -> Option<Topology> {
        Topology::from_triangles(t, n, |i| format!("triangle {i}")).ok()
    }

    /// Oracle: whether the triangles have an edge from `a` to `b` (scanning every triangle).
    fn joined(t: &[[u32; 3]], a: u32, b: u32) -> bool {
        a != b && t.iter().any(|t| t.contains(&a) && t.contains(&b))
    }

    #[test]
    fn caps_neighbour_pairs_only() {
        // 1 cm squares, 2 mm thickness, fraction 0.1: neighbour pairs get 1 mm, others 2 mm.
        let (x, t) = grid(4, 0.01);
        let topo = topology(x.len(), &t).unwrap();
        let policy = UniformThickness(2e-3);
        let p = NearCapped::new(&policy, &topo, &t, &x, 0.1);
        assert!(p.binds());
        assert_eq!(p.uniform_cloth(), None);
        let (mut near_pairs, mut far_pairs) = (0, 0);
        for v in 0..x.len() as u32 {
            for (ti, tri) in t.iter().enumerate() {
                if tri.contains(&v) {
                    continue;
                }
                let near = tri.iter().any(|&c| joined(&t, v, c));
                let want = if near { 1e-3 } else { 2e-3 };
                *(if near {
                    &mut near_pairs
                } else {
                    &mut far_pairs
                }) += 1;
                match p.vertex_triangle(v, ti as u32) {
                    Contact::Thickness(got) => assert!((got - want).abs() < 1e-12, "{v} {ti}"),
                    Contact::Skip => panic!("skipped"),
                }
            }
        }
        assert!(near_pairs > 0 && far_pairs > 0);
        // A thickness below every cap is never capped, and the uniform answer stays.
        let thin = UniformThickness(5e-4);
        let q = NearCapped::new(&thin, &topo, &t, &x, 0.1);
        assert!(!q.binds());
        assert_eq!(q.uniform_cloth(), Some(Contact::Thickness(5e-4)));
    }

    #[test]
    fn degenerate_edge_keeps_a_positive_thickness() {
        let (mut x, t) = grid(2, 0.01);
        x[4] = x[0]; // the centre vertex onto a corner: edge 0-4 has length 0
        let topo = topology(x.len(), &t).unwrap();
        let policy = UniformThickness(2e-3);
        let p = NearCapped::new(&policy, &topo, &t, &x, 0.25);
        let mut floored = 0;
        for v in 0..x.len() as u32 {
            for (ti, tri) in t.iter().enumerate() {
                if !tri.contains(&v) {
                    let Contact::Thickness(got) = p.vertex_triangle(v, ti as u32) else {
                        panic!("skipped")
                    };
                    assert!((2e-6..=2e-3).contains(&got));
                    floored += usize::from(got == 2e-6);
                }
            }
        }
        assert!(floored > 0);
    }

    proptest! {
        /// On random triangle soups: vertex-triangle and edge-edge pairs are capped exactly
        /// when a node of one is joined by an edge to a node of the other and the thickness
        /// exceeds `fraction` times the shortest edge at the four nodes, to that length.
        #[test]
        fn pairs_match_the_definition(
            tris in prop::collection::vec(prop::array::uniform3(0u32..10), 1..10),
            coords in prop::collection::vec(prop::array::uniform3(-1.0f64..1.0), 10),
            thickness in 0.0f64..1.0,
        ) {
            let x: Vec<Vec3> = coords.iter().map(|c| Vec3::new(c[0], c[1], c[2])).collect();
            let mut t: Vec<[u32; 3]> = tris
                .into_iter()
                .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
                .collect();
            t.sort_unstable_by_key(|t| { let mut s = *t; s.sort_unstable(); s });
            t.dedup_by_key(|t| { let mut s = *t; s.sort_unstable(); s });
            let topo = topology(x.len(), &t);
            prop_assume!(topo.is_some());
            let topo = topo.unwrap();
            let policy = UniformThickness(thickness);
            let p = NearCapped::new(&policy, &topo, &t, &x, 0.25);
            // The oracle's caps: every triangle's edges scanned.
            let cap = |v: u32| {
                t.iter()
                    .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
                    .filter(|f| f.contains(&v))
                    .map(|f| 0.25 * (x[f[0] as usize] - x[f[1] as usize]).norm())
                    .fold(f64::INFINITY, f64::min)
            };
            let want = |nodes: [u32; 4], near: bool| {
                let m = nodes.map(cap).into_iter().fold(f64::INFINITY, f64::min);
                Contact::Thickness(if near && thickness > m { m.max(1e-3 * thickness) } else { thickness })
            };
            let e = &topo.edges;
            for (i, f) in e.iter().enumerate() {
                for (j, g) in e.iter().enumerate() {
                    if f.iter().any(|v| g.contains(v)) {
                        continue;
                    }
                    let near = f.iter().any(|&a| g.iter().any(|&b| joined(&t, a, b)));
                    prop_assert_eq!(p.edge_edge(i as u32, j as u32), want([f[0], f[1], g[0], g[1]], near));
                }
            }
            for v in 0..x.len() as u32 {
                if cap(v).is_infinite() {
                    continue;
                }
                for (k, tri) in t.iter().enumerate() {
                    if tri.contains(&v) {
                        continue;
                    }
                    let near = tri.iter().any(|&c| joined(&t, v, c));
                    prop_assert_eq!(p.vertex_triangle(v, k as u32), want([v, tri[0], tri[1], tri[2]], near));
                }
            }
        }
    }
}
