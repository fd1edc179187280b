//! Garments: a mesh whose uv layer is guaranteed, split into sewing panels (connected components
//! of the uv layer), with seam vertices (world vertices that have several uv copies).

use super::{Mesh, Topology, UvLayer};
use crate::error::Result;
use crate::geom::{Vec2, Vec3};
use crate::mesh::topology::Csr;

/// Where a garment's uv layer came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UvSource {
    /// The input file's `vt` coordinates.
    File,
    /// No `vt` in the input: the mesh was projected onto its best-fitting plane (one panel
    /// parameterised by its own shape).
    PlanarProjection,
}

/// A validated garment: world mesh, topology, uv layer, panels and seams.
#[derive(Clone, Debug)]
pub struct Garment {
    /// The mesh; its `uv` is always `Some`.
    pub mesh: Mesh,
    /// World-mesh connectivity (seams are interior edges here).
    pub topology: Topology,
    /// Origin of the uv layer.
    pub uv_source: UvSource,
    /// Panel of each uv coordinate.
    pub panel_of_uv: Vec<u32>,
    /// Panel of each triangle.
    pub panel_of_triangle: Vec<u32>,
    /// Number of panels.
    pub num_panels: usize,
    /// For each world vertex, its distinct uv indices (sorted); several on a seam.
    pub uv_copies: Csr,
}

impl Garment {
    /// Validates `mesh` and derives panels and seams; a mesh without uv gets one planar panel.
    pub fn new(mut mesh: Mesh) -> Result<Garment> {
        mesh.validate()?;
        let topology = Topology::new(&mesh)?;
        let uv_source = if mesh.uv.is_some() {
            UvSource::File
        } else {
            mesh.uv = Some(planar_uv(&mesh.positions, &mesh.triangles));
            UvSource::PlanarProjection
        };
        let uv = mesh.uv.as_ref().expect("set above");
        let (panel_of_uv, num_panels) = components(uv);
        let panel_of_triangle = uv
            .triangles
            .iter()
            .map(|t| panel_of_uv[t[0] as usize])
            .collect();
        let mut pairs: Vec<(u32, u32)> = mesh
            .triangles
            .iter()
            .zip(&uv.triangles)
            .flat_map(|(t, u)| (0..3).map(move |k| (t[k], u[k])))
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        let uv_copies = Csr::from_pairs(mesh.positions.len(), pairs.iter().copied());
        Ok(Garment {
            mesh,
            topology,
            uv_source,
            panel_of_uv,
            panel_of_triangle,
            num_panels,
            uv_copies,
        })
    }

    /// The uv layer.
    pub fn uv(&self) -> &UvLayer {
        self.mesh.uv.as_ref().expect("a garment always has uv")
    }

    /// Number of seam vertices (world vertices with more than one uv copy).
    pub fn num_seam_vertices(&self) -> usize {
        (0..self.mesh.positions.len())
            .filter(|&v| self.uv_copies.row(v).len() > 1)
            .count()
    }

    /// Whether world vertex `v` lies on a seam.
    pub fn is_seam_vertex(&self, v: u32) -> bool {
        self.uv_copies.row(v as usize).len() > 1
    }
}

/// Connected components of the uv layer (uv indices joined by triangles), numbered in order of
/// first appearance.
fn components(uv: &UvLayer) -> (Vec<u32>, usize) {
    let n = uv.coords.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for t in &uv.triangles {
        for k in 1..3 {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut count = 0u32;
    let mut out = vec![u32::MAX; n];
    for t in &uv.triangles {
        for &i in t {
            let r = find(&mut parent, i) as usize;
            if label[r] == u32::MAX {
                label[r] = count;
                count += 1;
            }
            out[i as usize] = label[r];
        }
    }
    (out, count as usize)
}

/// Projects the mesh onto its best-fitting plane (principal axes), oriented so that the
/// majority of triangles are counter-clockwise in uv. One uv per world vertex.
pub fn planar_uv(positions: &[Vec3], triangles: &[[u32; 3]]) -> UvLayer {
    let n = positions.len().max(1) as f64;
    let c: Vec3 = positions.iter().sum::<Vec3>() / n;
    let mut cov = nalgebra::Matrix3::<f64>::zeros();
    for p in positions {
        let d = p - c;
        cov += d * d.transpose();
    }
    let eig = nalgebra::SymmetricEigen::new(cov);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let e1: Vec3 = eig.eigenvectors.column(idx[0]).into();
    let mut e2: Vec3 = eig.eigenvectors.column(idx[1]).into();
    let project = |e2: &Vec3| -> Vec<Vec2> {
        positions
            .iter()
            .map(|p| Vec2::new((p - c).dot(&e1), (p - c).dot(e2)))
            .collect()
    };
    let mut coords = project(&e2);
    let signed: f64 = triangles
        .iter()
        .map(|t| {
            crate::geom::cross2(
                &coords[t[0] as usize],
                &coords[t[1] as usize],
                &coords[t[2] as usize],
            )
            .signum()
        })
        .sum();
    if signed < 0.0 {
        e2 = -e2;
        coords = project(&e2);
    }
    UvLayer {
        coords,
        triangles: triangles.to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::obj::parse_obj;

    #[test]
    fn panels_and_seams_of_two_sewn_squares() {
        // Two unit squares sewn along x = 1; the seam vertices 2 and 5 have two uvs each.
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0.1\nv 2 1 0.1\n\
                    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 0\nvt 6 0\nvt 6 1\nvt 5 1\n\
                    f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 2/5 5/6 6/7\nf 2/5 6/7 3/8\n";
        let g = Garment::new(parse_obj(text, "s.obj", "s").unwrap()).unwrap();
        assert_eq!(g.num_panels, 2);
        assert_eq!(g.panel_of_triangle, vec![0, 0, 1, 1]);
        assert_eq!(g.num_seam_vertices(), 2);
        assert!(g.is_seam_vertex(1) && g.is_seam_vertex(2) && !g.is_seam_vertex(0));
        assert_eq!(g.uv_source, UvSource::File);
        // Seams are interior in the world mesh.
        let e = g.topology.edge_between(1, 2).unwrap();
        assert!(!g.topology.is_boundary_edge(e));
    }

    #[test]
    fn missing_uv_is_one_planar_panel() {
        let text = "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nf 1 2 3\nf 1 3 4\n";
        let g = Garment::new(parse_obj(text, "s.obj", "s").unwrap()).unwrap();
        assert_eq!(g.uv_source, UvSource::PlanarProjection);
        assert_eq!(g.num_panels, 1);
        let uv = g.uv();
        for t in &uv.triangles {
            let a = crate::geom::cross2(
                &uv.coords[t[0] as usize],
                &uv.coords[t[1] as usize],
                &uv.coords[t[2] as usize],
            );
            assert!(
                (a - 1.0).abs() < 1e-12,
                "isometric and counter-clockwise: {a}"
            );
        }
    }
}
