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
