//! Which triangle reports the crossings of each edge.
//!
//! A crossing (Wicke et al. 2006, Sec. 4) is an edge `e` through a triangle `t`; the crossing
//! search tests triangle pairs, and edge `e` belongs to the one or two triangles beside it, so the
//! pair of either of them with `t` decides the crossing. Only one of them, the edge's *reporter*,
//! records it, so every crossing is found exactly once. Any choice of reporters gives the same
//! crossings; this one makes as many triangles as possible *silent* (reporting no edge at all), so
//! that the pairs of two silent triangles, which can record nothing, are skipped before any
//! geometry is read.
//!
//! Silent triangles must be pairwise non-adjacent (an edge between two silent triangles would have
//! no reporter) and have no boundary edge (its only triangle reports it): a maximal independent
//! set of the interior triangles in the triangle adjacency graph, chosen greedily in index order.
//! On a grid split into two triangles per cell that set is one triangle of (almost) every cell,
//! so about a quarter of all triangle pairs are pairs of silent triangles.

use crate::mesh::topology::{Topology, NONE};

/// The reporter of every edge and which triangles report none.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Reporters {
    /// The triangle reporting each edge's crossings: one of the edge's triangles, the
    /// lower-indexed one when neither is silent.
    pub of_edge: Vec<u32>,
    /// Whether a triangle reports no edge.
    pub silent: Vec<bool>,
}

impl Reporters {
    /// Reporters for `topo` (see the module docs). Linear in the number of triangles.
    pub fn new(topo: &Topology) -> Self {
        let et = &topo.edge_triangles;
        let nt = topo.triangle_edges.len();
        let mut silent = vec![false; nt];
        for t in 0..nt {
            let mut ok = true;
            for &e in &topo.triangle_edges[t] {
                let [a, b] = et[e as usize];
                // A boundary edge, or a silent neighbour.
                let other = if a == t as u32 { b } else { a };
                if other == NONE || silent[other as usize] {
                    ok = false;
                    break;
                }
            }
            silent[t] = ok;
        }
        let of_edge = et
            .iter()
            .map(|&[a, b]| {
                if b == NONE {
                    a
                } else if silent[a as usize] {
                    b
                } else if silent[b as usize] {
                    a
                } else {
                    a.min(b)
                }
            })
            .collect();
        Reporters { of_edge, silent }
    }

    /// Whether triangle `t` reports edge `e`'s crossings.
    #[inline]
    pub fn reports(&self, e: u32, t: u32) -> bool {
        self.of_edge[e as usize] == t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use proptest::prelude::*;

    /// Every edge is reported by exactly one of its own triangles, never by a silent one; silent
    /// triangles are interior and pairwise non-adjacent, and the set is maximal.
    fn check(topo: &Topology) -> Result<(), TestCaseError> {
        let r = Reporters::new(topo);
        prop_assert_eq!(r.of_edge.len(), topo.edge_triangles.len());
        for (e, &[a, b]) in topo.edge_triangles.iter().enumerate() {
            let t = r.of_edge[e];
            prop_assert!(t == a || (b != NONE && t == b));
            prop_assert!(!r.silent[t as usize]);
            prop_assert!(r.reports(e as u32, t));
        }
        // A silent triangle reports none of its edges (so its pairs with another silent
        // triangle have nothing to record), and the set is maximal: every interior triangle
        // that is not silent has a silent neighbour.
        for (t, edges) in topo.triangle_edges.iter().enumerate() {
            let t = t as u32;
            let neighbours: Vec<u32> = edges.iter().map(|&e| topo.other_triangle(e, t)).collect();
            if r.silent[t as usize] {
                prop_assert!(edges.iter().all(|&e| !r.reports(e, t)));
                prop_assert!(neighbours
                    .iter()
                    .all(|&n| n != NONE && !r.silent[n as usize]));
            } else if neighbours.iter().all(|&n| n != NONE) {
                prop_assert!(neighbours.iter().any(|&n| r.silent[n as usize]));
            }
        }
        Ok(())
    }

    proptest! {
        /// Reporters of a sheet with a random subset of its triangles (holes, several
        /// components, boundary everywhere).
        #[test]
        fn every_edge_has_one_reporting_triangle(
            n in 2usize..10,
            keep in proptest::collection::vec(proptest::bool::weighted(0.85), 200),
        ) {
            let sheet = crate::scenes::sheet::handkerchief("s", n, n, 1.0, 1.0, |p| {
                Vec3::new(p.x, p.y, 0.0)
            });
            let triangles: Vec<[u32; 3]> = sheet
                .triangles
                .iter()
                .enumerate()
                .filter(|(i, _)| keep[i % keep.len()])
                .map(|(_, t)| *t)
                .collect();
            let topo = Topology::from_triangles(&triangles, sheet.positions.len(), |t| {
                format!("{t}")
            })
            .expect("manifold");
            check(&topo)?;
        }
    }

    /// On a closed surface (no boundary) about half of the triangles are silent.
    #[test]
    fn closed_surface_has_many_silent_triangles() {
        let m = crate::implicit::shapes::sphere_mesh("s", &Vec3::zeros(), 1.0, 8);
        let topo = Topology::new(&m).expect("manifold");
        check(&topo).expect("valid reporters");
        let r = Reporters::new(&topo);
        let silent = r.silent.iter().filter(|&&s| s).count();
        assert!(
            silent * 3 >= r.silent.len(),
            "{silent} of {}",
            r.silent.len()
        );
    }
}
