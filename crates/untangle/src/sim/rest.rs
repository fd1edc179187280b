//! The rest shape of the cloth, from the uv layer (uv units = metres): per triangle the stretch
//! rest data, per interior edge the bending stencil. Rebuilt in O(triangles + edges) whenever the
//! uv changes (Cha & Ko 2022, Sec. 5.1, edit the uv every step).

use rayon::prelude::*;

use super::forces::bend::BendStencil;
use super::forces::stretch::TriangleRest;
use crate::error::{Error, Result};
use crate::geom::Vec2;
use crate::mesh::topology::NONE;
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
        let corner = |t: u32, v: u32| -> usize {
            triangles[t as usize]
                .iter()
                .position(|&x| x == v)
                .expect("edge vertex in its triangle")
        };
        let bend = topology
            .edges
            .par_iter()
            .zip(&topology.edge_triangles)
            .filter_map(|(e, ts)| {
                if ts[1] == NONE {
                    return None;
                }
                let side = |t: u32| {
                    let (ka, kb) = (corner(t, e[0]), corner(t, e[1]));
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
                Some(BendStencil::new([e[0], e[1], c0, c1], u0, u1))
            })
            .collect();
        Ok(RestShape {
            triangles: tris,
            bend,
        })
    }
}
