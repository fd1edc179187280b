//! Garments: a mesh whose uv layer is guaranteed, split into sewing panels (connected components
//! of the uv layer), with seam vertices (world vertices that have several uv copies).

use super::{Mesh, Topology, UvLayer};
use crate::error::{Error, Result};
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
    /// No `vt` in the input, and the projection degenerated or inverted a triangle (a sheet
    /// folded onto itself): the mesh was unfolded triangle by triangle with its own edge lengths
    /// ([`unfolded_uv`]).
    Unfolded,
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
            let planar = planar_uv(&mesh.positions, &mesh.triangles);
            let unfolded = (!faithful(&planar, &mesh.positions))
                .then(|| unfolded_uv(&mesh.positions, &mesh.triangles, &topology))
                .filter(|u| faithful(u, &mesh.positions));
            match unfolded {
                Some(u) => {
                    mesh.uv = Some(u);
                    UvSource::Unfolded
                }
                None => {
                    mesh.uv = Some(planar);
                    UvSource::PlanarProjection
                }
            }
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

    /// The same garment with world positions `positions` (a simulator's state, say). Topology,
    /// uv layer, panels and seams do not depend on the positions, so nothing is derived again;
    /// unlike [`Garment::new`], a world triangle may be degenerate (a simulated cloth can crush
    /// one; the rest shape is the uv). Errors on a wrong vertex count or a non-finite coordinate.
    pub fn with_positions(&self, positions: &[Vec3]) -> Result<Garment> {
        let place = self.mesh.place();
        if positions.len() != self.mesh.positions.len() {
            return Err(Error::input(
                place,
                format!(
                    "{} positions for {} vertices",
                    positions.len(),
                    self.mesh.positions.len()
                ),
            ));
        }
        if let Some(i) = positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(Error::input(
                place,
                format!("vertex {} has a non-finite coordinate", i + 1),
            ));
        }
        let mut g = self.clone();
        g.mesh.positions = positions.to_vec();
        Ok(g)
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

/// Whether every uv triangle of a derived layer (one uv per world vertex) is counter-clockwise
/// with at least 1 % of its world area: a usable rest shape.
fn faithful(uv: &UvLayer, positions: &[Vec3]) -> bool {
    uv.triangles.iter().all(|t| {
        let [a, b, c] = t.map(|v| v as usize);
        let world = (positions[b] - positions[a])
            .cross(&(positions[c] - positions[a]))
            .norm();
        crate::geom::cross2(&uv.coords[a], &uv.coords[b], &uv.coords[c]) >= 0.01 * world
    })
}

/// Unfolds the mesh into the plane triangle by triangle (breadth-first over shared edges, from
/// the first triangle of each connected piece), placing each new vertex with the triangle's own
/// edge length and corner angle, counter-clockwise. Exact (an isometry) where the mesh is
/// developable without closing a loop around an interior vertex, e.g. a strip or a sheet folded
/// onto itself; a vertex reached again keeps its first place. One uv per world vertex.
pub fn unfolded_uv(positions: &[Vec3], triangles: &[[u32; 3]], topo: &Topology) -> UvLayer {
    let mut coords = vec![Vec2::new(f64::NAN, f64::NAN); positions.len()];
    let mut done = vec![false; triangles.len()];
    // Largest x placed so far: a new piece starts right of it (pieces are separate panels).
    let mut right = f64::NEG_INFINITY;
    let placed = |coords: &[Vec2], v: u32| !coords[v as usize].x.is_nan();
    fn place(coords: &mut [Vec2], right: &mut f64, v: u32, p: Vec2) {
        *right = right.max(p.x);
        coords[v as usize] = p;
    }
    // Third corner of (a, b, c), counter-clockwise, from the world triangle's shape.
    let third = |coords: &[Vec2], a: u32, b: u32, c: u32| -> Vec2 {
        let (pa, pb, pc) = (
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        );
        let (ab, ac) = (pb - pa, pc - pa);
        let angle = ab.cross(&ac).norm().atan2(ab.dot(&ac));
        let (ua, ub) = (coords[a as usize], coords[b as usize]);
        let d = ub - ua;
        let u = if d.norm() > 0.0 {
            d / d.norm()
        } else {
            Vec2::new(1.0, 0.0)
        };
        let perp = Vec2::new(-u.y, u.x);
        ua + (u * angle.cos() + perp * angle.sin()) * ac.norm()
    };
    let mut origin = 0.0;
    for seed in 0..triangles.len() {
        if done[seed] {
            continue;
        }
        let [a, b, c] = triangles[seed];
        // The seed's first edge along +x: each unplaced end takes the next slot.
        for v in [a, b] {
            if !placed(&coords, v) {
                place(&mut coords, &mut right, v, Vec2::new(origin, 0.0));
                origin += (positions[b as usize] - positions[a as usize]).norm();
            }
        }
        if !placed(&coords, c) {
            let p = third(&coords, a, b, c);
            place(&mut coords, &mut right, c, p);
        }
        done[seed] = true;
        let mut queue = std::collections::VecDeque::from([seed]);
        while let Some(t) = queue.pop_front() {
            for &e in &topo.triangle_edges[t] {
                for &n in &topo.edge_triangles[e as usize] {
                    if n == crate::mesh::topology::NONE || done[n as usize] {
                        continue;
                    }
                    done[n as usize] = true;
                    let tri = triangles[n as usize];
                    for k in 0..3 {
                        let (p, q, r) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                        if placed(&coords, p) && placed(&coords, q) && !placed(&coords, r) {
                            let at = third(&coords, p, q, r);
                            place(&mut coords, &mut right, r, at);
                        }
                    }
                    queue.push_back(n as usize);
                }
            }
        }
        origin = right.max(origin) + 1.0;
    }
    for p in coords.iter_mut().filter(|p| p.x.is_nan()) {
        *p = Vec2::zeros(); // an isolated vertex (no triangle)
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

    /// Two unit squares sewn along x = 1; the seam vertices 2 and 5 have two uvs each.
    fn two_sewn_squares() -> Garment {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0.1\nv 2 1 0.1\n\
                    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 0\nvt 6 0\nvt 6 1\nvt 5 1\n\
                    f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 2/5 5/6 6/7\nf 2/5 6/7 3/8\n";
        Garment::new(parse_obj(text, "s.obj", "s").unwrap()).unwrap()
    }

    /// `with_positions` equals `Garment::new` of the moved mesh (everything derived from
    /// connectivity and uv), and refuses a wrong count or a non-finite coordinate.
    #[test]
    fn with_positions_is_new_at_those_positions() {
        let g = two_sewn_squares();
        let moved: Vec<Vec3> = g
            .mesh
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vec3::new(0.1 * i as f64, -0.2, 0.3 * (i % 2) as f64))
            .collect();
        let mut m = g.mesh.clone();
        m.positions = moved.clone();
        let want = Garment::new(m).unwrap();
        let got = g.with_positions(&moved).unwrap();
        assert_eq!(got.mesh.positions, want.mesh.positions);
        assert_eq!(got.mesh.uv, want.mesh.uv);
        assert_eq!(got.topology.edges, want.topology.edges);
        assert_eq!(got.panel_of_uv, want.panel_of_uv);
        assert_eq!(got.panel_of_triangle, want.panel_of_triangle);
        assert_eq!(got.num_panels, want.num_panels);
        assert_eq!(got.uv_source, want.uv_source);
        assert_eq!(
            (0..6)
                .map(|v| got.uv_copies.row(v).to_vec())
                .collect::<Vec<_>>(),
            (0..6)
                .map(|v| want.uv_copies.row(v).to_vec())
                .collect::<Vec<_>>()
        );
        // A crushed world triangle (two corners on one point) is fine here, unlike in `new`.
        let mut flat = moved.clone();
        flat[3] = flat[0];
        assert!(g.with_positions(&flat).is_ok());
        let mut m = g.mesh.clone();
        m.positions = flat;
        assert!(Garment::new(m).is_err());
        let mut bad = moved.clone();
        bad[4].y = f64::NAN;
        let e = g.with_positions(&bad).unwrap_err().to_string();
        assert!(e.contains("vertex 5 has a non-finite coordinate"), "{e}");
        assert!(g.with_positions(&moved[..5]).is_err());
    }

    #[test]
    fn panels_and_seams_of_two_sewn_squares() {
        let g = two_sewn_squares();
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
    fn a_folded_sheet_without_uv_is_unfolded_isometrically() {
        // A strip of four squares folded in a Z (the first and last square fold back over the
        // middle ones, like the third-party BIBI unit): its best-fitting plane squashes some
        // triangles to slivers, the unfolding keeps every world edge length.
        let mut text = String::new();
        let xs = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.2, 1.0), (0.2, 0.0)];
        for (x, z) in xs {
            text += &format!("v {x} 0 {z}\nv {x} 1 {z}\n");
        }
        for i in 0..4 {
            let (a, b, c, d) = (2 * i + 1, 2 * i + 3, 2 * i + 4, 2 * i + 2);
            text += &format!("f {a} {b} {c}\nf {a} {c} {d}\n");
        }
        let m = parse_obj(&text, "z.obj", "z").unwrap();
        assert!(!faithful(
            &planar_uv(&m.positions, &m.triangles),
            &m.positions
        ));
        let g = Garment::new(m).unwrap();
        assert_eq!(g.uv_source, UvSource::Unfolded);
        assert_eq!(g.num_panels, 1);
        let uv = g.uv();
        for t in &g.mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
                let world = (g.mesh.positions[a] - g.mesh.positions[b]).norm();
                let flat = (uv.coords[a] - uv.coords[b]).norm();
                assert!(
                    (world - flat).abs() < 1e-12,
                    "edge {a}-{b}: {world} vs {flat}"
                );
            }
        }
        assert!(faithful(uv, &g.mesh.positions));
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
