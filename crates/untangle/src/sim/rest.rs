//! The rest shape of the cloth, from the uv layer (uv units = metres): per triangle the stretch
//! rest data, per interior edge the bending stencil. Rebuilt in O(triangles + edges) whenever the
//! uv changes (Cha & Ko 2022, Sec. 5.1, edit the uv every step).

use rayon::prelude::*;

use super::forces::bend::BendStencil;
use super::forces::stretch::TriangleRest;
use super::sparse::BsrPattern;
use crate::error::{Error, Result};
use crate::geom::Vec2;
use crate::mesh::topology::{Csr, NONE};
use crate::mesh::Topology;

/// Rest data derived from a uv layout.
#[derive(Clone, Debug)]
pub struct RestShape {
    /// Per triangle.
    pub triangles: Vec<TriangleRest>,
    /// Per interior edge (edges with two triangles), in edge order.
    pub bend: Vec<BendStencil>,
}

impl RestShape {
    /// Builds the rest shape of `triangles` (world) with uv corners `uv_triangles` into `uv`.
    pub fn new(
        triangles: &[[u32; 3]],
        uv_triangles: &[[u32; 3]],
        uv: &[Vec2],
        topology: &Topology,
    ) -> Result<RestShape> {
        let rest: Vec<Result<TriangleRest>> = uv_triangles
            .par_iter()
            .map(|t| TriangleRest::new(&uv[t[0] as usize], &uv[t[1] as usize], &uv[t[2] as usize]))
            .collect();
        let mut tris = Vec::with_capacity(rest.len());
        for (i, r) in rest.into_iter().enumerate() {
            tris.push(r.map_err(|e| Error::input(format!("triangle {}", i + 1), e.to_string()))?);
        }
        let bend = (0..topology.edges.len())
            .into_par_iter()
            .filter_map(|e| bend_stencil(triangles, uv_triangles, uv, topology, e))
            .collect();
        Ok(RestShape {
            triangles: tris,
            bend,
        })
    }
}

/// The bending stencil of edge `e` (Sec. 5.1's rest shape from the uv of the two triangles at
/// the edge); `None` for a boundary edge or an edge whose two triangles share all three
/// vertices. Which edges have a stencil depends on the topology only, not on the uv.
pub fn bend_stencil(
    triangles: &[[u32; 3]],
    uv_triangles: &[[u32; 3]],
    uv: &[Vec2],
    topology: &Topology,
    e: usize,
) -> Option<BendStencil> {
    let ev = topology.edges[e];
    let ts = topology.edge_triangles[e];
    if ts[1] == NONE {
        return None;
    }
    let corner = |t: u32, v: u32| -> usize {
        triangles[t as usize]
            .iter()
            .position(|&x| x == v)
            .expect("edge vertex in its triangle")
    };
    let side = |t: u32| {
        let (ka, kb) = (corner(t, ev[0]), corner(t, ev[1]));
        let kc = 3 - ka - kb;
        let ut = uv_triangles[t as usize];
        (
            triangles[t as usize][kc],
            [ka, kb, kc].map(|k| uv[ut[k] as usize]),
        )
    };
    let (c0, u0) = side(ts[0]);
    let (c1, u1) = side(ts[1]);
    if c0 == c1 {
        return None;
    }
    Some(BendStencil::new([ev[0], ev[1], c0, c1], u0, u1))
}

/// The bending stencil's terms of the scalar matrix, `kb w_i w_j` for its 16 node pairs in
/// row-major order (the quadratic bending of [`BendStencil`]): `add(slot, value)` with the slot
/// of each pair in `pattern`. The full builds and the partial updates of a rest edit both sum
/// these, in the same order, so they give the same bits.
pub fn bend_terms(pattern: &BsrPattern, s: &BendStencil, kb: f64, mut add: impl FnMut(usize, f64)) {
    for i in 0..4 {
        for j in 0..4 {
            let slot = pattern
                .slot(s.vertices[i], s.vertices[j])
                .expect("bending pairs are in the pattern");
            add(slot, kb * s.weights[i] * s.weights[j]);
        }
    }
}

/// Re-sums the entries `slots` (sorted, distinct) of `values` from scratch: each is zeroed,
/// then every term that `terms` passes to its callback for one of these slots is added, in the
/// order given (terms for other slots are ignored). With the terms of a [`RestEdit`]'s
/// `near_triangles` / `near_stencils` in ascending order, the result is that of a full rebuild.
pub fn resum_slots(
    values: &mut [f64],
    slots: &[usize],
    terms: impl FnOnce(&mut dyn FnMut(usize, f64)),
) {
    for &k in slots {
        values[k] = 0.0;
    }
    terms(&mut |k, v| {
        if slots.binary_search(&k).is_ok() {
            values[k] += v;
        }
    });
}

/// Which rest data a uv edit touches (built once per mesh), so that an edit of a few uv
/// coordinates (Cha & Ko 2022, Sec. 5.1: a few operations per step) recomputes only the rest
/// data of the triangles using them and of the bending stencils at their edges.
#[derive(Clone, Debug)]
pub struct RestIndex {
    /// Triangles using each uv coordinate.
    uv_triangles: Csr,
    /// Index into [`RestShape::bend`] of each edge's stencil ([`NONE`] if it has none).
    stencil_of_edge: Vec<u32>,
    /// Stencils with each world vertex, ascending.
    vertex_stencils: Csr,
    /// Triangles with each world vertex, ascending.
    vertex_triangles: Csr,
}

/// The rest data an edit changed: triangles and bending stencils (ascending indices into
/// [`RestShape::triangles`] and [`RestShape::bend`]) with their new values, and every triangle
/// and stencil with a vertex of a changed one (ascending): the ones whose contributions to a
/// matrix entry of a changed one have to be summed again.
#[derive(Clone, Debug, Default)]
pub struct RestEdit {
    /// Changed triangles and their new rest data.
    pub triangles: Vec<(u32, TriangleRest)>,
    /// Changed stencils and their new values.
    pub stencils: Vec<(u32, BendStencil)>,
    /// Triangles with a vertex of a changed triangle or stencil.
    pub near_triangles: Vec<u32>,
    /// Stencils with a vertex of a changed triangle or stencil.
    pub near_stencils: Vec<u32>,
}

impl RestIndex {
    /// The index of a mesh (`triangles`, uv corners `uv_triangles` into `uv_count` coordinates)
    /// whose rest shape is `rest`.
    pub fn new(
        triangles: &[[u32; 3]],
        uv_triangles: &[[u32; 3]],
        uv_count: usize,
        topology: &Topology,
        rest: &RestShape,
    ) -> RestIndex {
        let uv_tris = Csr::from_pairs(
            uv_count,
            uv_triangles
                .iter()
                .enumerate()
                .flat_map(|(t, u)| u.iter().map(move |&k| (k, t as u32))),
        );
        let mut stencil_of_edge = vec![NONE; topology.edges.len()];
        let mut k = 0;
        for (e, s) in stencil_of_edge.iter_mut().enumerate() {
            if let Some(b) = rest.bend.get(k) {
                let ev = topology.edges[e];
                if b.vertices[0] == ev[0] && b.vertices[1] == ev[1] {
                    *s = k as u32;
                    k += 1;
                }
            }
        }
        debug_assert_eq!(
            k,
            rest.bend.len(),
            "one stencil per interior edge, in edge order"
        );
        let n = topology.num_vertices;
        let vertex_stencils = Csr::from_pairs(
            n,
            rest.bend
                .iter()
                .enumerate()
                .flat_map(|(s, b)| b.vertices.iter().map(move |&v| (v, s as u32))),
        );
        let vertex_triangles = Csr::from_pairs(
            n,
            triangles
                .iter()
                .enumerate()
                .flat_map(|(t, tri)| tri.iter().map(move |&v| (v, t as u32))),
        );
        RestIndex {
            uv_triangles: uv_tris,
            stencil_of_edge,
            vertex_stencils,
            vertex_triangles,
        }
    }

    /// The rest data that changes when the uv goes from `old` to `new` (bitwise comparison),
    /// or `None` when more than `max_triangles` triangles change (a full rebuild is then
    /// cheaper). An error, as [`RestShape::new`]'s, if a changed triangle is degenerate.
    #[allow(clippy::too_many_arguments)]
    pub fn edit(
        &self,
        triangles: &[[u32; 3]],
        uv_triangles: &[[u32; 3]],
        topology: &Topology,
        old: &[Vec2],
        new: &[Vec2],
        max_triangles: usize,
    ) -> Result<Option<RestEdit>> {
        let same =
            |a: &Vec2, b: &Vec2| a.x.to_bits() == b.x.to_bits() && a.y.to_bits() == b.y.to_bits();
        let mut tris: Vec<u32> = Vec::new();
        for (k, (a, b)) in old.iter().zip(new).enumerate() {
            if !same(a, b) {
                tris.extend_from_slice(self.uv_triangles.row(k));
                if tris.len() > 3 * max_triangles {
                    return Ok(None);
                }
            }
        }
        tris.sort_unstable();
        tris.dedup();
        if tris.len() > max_triangles {
            return Ok(None);
        }
        let mut edit = RestEdit::default();
        for &t in &tris {
            let u = uv_triangles[t as usize];
            let r = TriangleRest::new(
                &new[u[0] as usize],
                &new[u[1] as usize],
                &new[u[2] as usize],
            )
            .map_err(|e| Error::input(format!("triangle {}", t + 1), e.to_string()))?;
            edit.triangles.push((t, r));
        }
        let mut stencils: Vec<(u32, usize)> = tris
            .iter()
            .flat_map(|&t| topology.triangle_edges[t as usize])
            .filter_map(|e| {
                let s = self.stencil_of_edge[e as usize];
                (s != NONE).then_some((s, e as usize))
            })
            .collect();
        stencils.sort_unstable();
        stencils.dedup();
        for (s, e) in stencils {
            let b = bend_stencil(triangles, uv_triangles, new, topology, e)
                .expect("an edge with a stencil keeps it");
            edit.stencils.push((s, b));
        }
        let mut verts: Vec<u32> = edit
            .triangles
            .iter()
            .flat_map(|&(t, _)| triangles[t as usize])
            .chain(edit.stencils.iter().flat_map(|(_, b)| b.vertices))
            .collect();
        verts.sort_unstable();
        verts.dedup();
        for &v in &verts {
            edit.near_triangles
                .extend_from_slice(self.vertex_triangles.row(v as usize));
            edit.near_stencils
                .extend_from_slice(self.vertex_stencils.row(v as usize));
        }
        edit.near_triangles.sort_unstable();
        edit.near_triangles.dedup();
        edit.near_stencils.sort_unstable();
        edit.near_stencils.dedup();
        Ok(Some(edit))
    }
}

impl RestShape {
    /// Applies the changes of `edit` ([`RestIndex::edit`]).
    pub fn apply(&mut self, edit: &RestEdit) {
        for (t, r) in &edit.triangles {
            self.triangles[*t as usize] = *r;
        }
        for (s, b) in &edit.stencils {
            self.bend[*s as usize] = *b;
        }
    }
}

/// A uv layer in which every triangle is its own copy of its world shape, laid flat (corner 0 at
/// the origin, edge 0-1 along +u): the garment's current shape becomes its rest shape (zero
/// stretch, and bending towards flat). For garments whose sewing pattern does not match their
/// 3D shape, such as ARCSim's unsewn garments whose seam triangles are stretched up to 36 times,
/// and for meshes without uv.
pub fn isometric_uv(
    positions: &[crate::geom::Vec3],
    triangles: &[[u32; 3]],
) -> crate::mesh::UvLayer {
    let mut coords = Vec::with_capacity(3 * triangles.len());
    let mut uv_triangles = Vec::with_capacity(triangles.len());
    for t in triangles {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let e = b - a;
        let f = c - a;
        let l = e.norm();
        let (u2, v2) = if l > 0.0 {
            let x = e / l;
            let fx = f.dot(&x);
            (fx, (f - x * fx).norm())
        } else {
            (0.0, f.norm())
        };
        let k = coords.len() as u32;
        coords.extend([Vec2::new(0.0, 0.0), Vec2::new(l, 0.0), Vec2::new(u2, v2)]);
        uv_triangles.push([k, k + 1, k + 2]);
    }
    crate::mesh::UvLayer {
        coords,
        triangles: uv_triangles,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use proptest::prelude::*;

    proptest! {
        /// Every uv triangle has the world triangle's edge lengths and a positive orientation.
        #[test]
        fn isometric_uv_keeps_edge_lengths(p in prop::collection::vec(-1.0f64..1.0, 12)) {
            let pos: Vec<Vec3> = p.chunks(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
            let tris = [[0u32, 1, 2], [0, 2, 3], [1, 3, 2]];
            let uv = isometric_uv(&pos, &tris);
            for (t, u) in tris.iter().zip(&uv.triangles) {
                for k in 0..3 {
                    let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
                    let (ua, ub) = (u[k] as usize, u[(k + 1) % 3] as usize);
                    let d3 = (pos[a] - pos[b]).norm();
                    let d2 = (uv.coords[ua] - uv.coords[ub]).norm();
                    prop_assert!((d3 - d2).abs() <= 1e-12 * (1.0 + d3));
                }
                prop_assert!(crate::geom::cross2(&uv.coords[u[0] as usize], &uv.coords[u[1] as usize], &uv.coords[u[2] as usize]) >= 0.0);
            }
        }
    }
}
