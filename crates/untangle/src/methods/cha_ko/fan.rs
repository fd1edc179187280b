//! Fans (Cha & Ko 2022, Sec. 5.1.2).
//!
//! - `fan(x)`: the vertices adjacent to `x`, excluding `x` (footnote 3).
//! - `fan(E(xi, xj))`: the vertices adjacent to either end, excluding both ends — Fig. 9a says it
//!   "consists of all the contour vertices".
//!
//! Fans are taken over the sewn (world) mesh, so on a seam `fan(x)` is the union of the fans of
//! all of `x`'s uv copies (Sec. 8, Fig. 12: both `fan(x0)` and `fan(x5)` matter). The triangles
//! of a fan are those that have a subject as a corner; they are the triangles the subject fan
//! re-meshing changes and the ones the inversion test looks at.
//!
//! Reading of Alg. 2, lines 3 and 7 ("fan in its original uv-position"): every *contour* vertex
//! is at its original uv. The subjects themselves may be displaced — by this very operation,
//! which then continues its finesse across steps.

use crate::mesh::Topology;

/// `fan(x)`: the neighbours of `x`, sorted.
pub fn vertex_fan(topo: &Topology, x: u32) -> &[u32] {
    topo.vertex_neighbors.row(x as usize)
}

/// `fan(E(j, k))`: neighbours of `j` or `k`, without `j` and `k`, sorted and distinct.
pub fn edge_fan(topo: &Topology, j: u32, k: u32) -> Vec<u32> {
    let mut f: Vec<u32> = vertex_fan(topo, j)
        .iter()
        .chain(vertex_fan(topo, k))
        .copied()
        .filter(|&v| v != j && v != k)
        .collect();
    f.sort_unstable();
    f.dedup();
    f
}

/// The triangles with at least one of `subjects` as a corner, sorted and distinct.
pub fn fan_triangles(topo: &Topology, subjects: &[u32]) -> Vec<u32> {
    let mut t: Vec<u32> = subjects
        .iter()
        .flat_map(|&v| topo.vertex_triangles.row(v as usize).iter().copied())
        .collect();
    t.sort_unstable();
    t.dedup();
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fans_of_a_strip() {
        // 0-1-2 / 3-4-5 strip, triangles (0,1,4),(0,4,3),(1,2,5),(1,5,4).
        let tris = [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]];
        let topo = Topology::from_triangles(&tris, 6, |t| t.to_string()).unwrap();
        assert_eq!(vertex_fan(&topo, 4), &[0, 1, 3, 5]);
        assert_eq!(edge_fan(&topo, 1, 4), vec![0, 2, 3, 5]);
        assert_eq!(fan_triangles(&topo, &[1, 4]), vec![0, 1, 2, 3]);
        assert_eq!(fan_triangles(&topo, &[2]), vec![2]);
    }
}
