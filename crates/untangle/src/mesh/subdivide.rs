//! Midpoint (1-to-4) subdivision of a mesh together with its uv layer, to refine the coarse
//! garments of the data sets. Every edge gets a midpoint in world space and every uv edge one in
//! uv space, so a seam edge (one world edge, one uv edge per panel) gets one world midpoint with
//! one uv copy per panel: seams stay seams.

use super::{Group, Mesh, Source, Topology, UvLayer};
use crate::error::Result;

/// The mesh with every triangle `(a, b, c)` split into `(a, ab, ca)`, `(ab, b, bc)`,
/// `(ca, bc, c)` and `(ab, bc, ca)` (midpoints of the edges; new vertices after the old ones, in
/// edge order). Triangle `t` becomes triangles `4t .. 4t + 4`, so groups and source lines carry
/// over.
pub fn midpoint(mesh: &Mesh) -> Result<Mesh> {
    mesh.validate()?;
    let topo = Topology::new(mesh)?;
    let n = mesh.positions.len() as u32;
    let mut positions = mesh.positions.clone();
    positions.extend(
        topo.edges
            .iter()
            .map(|e| (mesh.positions[e[0] as usize] + mesh.positions[e[1] as usize]) * 0.5),
    );
    let split = |t: [u32; 3], m: [u32; 3]| {
        // m[k] is the midpoint of the edge from corner k to corner k + 1.
        [
            [t[0], m[0], m[2]],
            [m[0], t[1], m[1]],
            [m[2], m[1], t[2]],
            [m[0], m[1], m[2]],
        ]
    };
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .zip(&topo.triangle_edges)
        .flat_map(|(&t, e)| split(t, e.map(|e| n + e)))
        .collect();
    let uv = mesh.uv.as_ref().map(|uv| {
        let m = uv.coords.len() as u32;
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let mut edges: Vec<(u32, u32)> = uv
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| key(t[k], t[(k + 1) % 3])))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let mut coords = uv.coords.clone();
        coords.extend(
            edges
                .iter()
                .map(|&(a, b)| (uv.coords[a as usize] + uv.coords[b as usize]) * 0.5),
        );
        let id = |a: u32, b: u32| m + edges.binary_search(&key(a, b)).expect("listed") as u32;
        let triangles = uv
            .triangles
            .iter()
            .flat_map(|&t| split(t, [id(t[0], t[1]), id(t[1], t[2]), id(t[2], t[0])]))
            .collect();
        UvLayer { coords, triangles }
    });
    Ok(Mesh {
        name: mesh.name.clone(),
        positions,
        triangles,
        uv,
        groups: mesh
            .groups
            .iter()
            .map(|g| Group {
                name: g.name.clone(),
                first: 4 * g.first,
                count: 4 * g.count,
            })
            .collect(),
        source: mesh.source.as_ref().map(|s| Source {
            file: s.file.clone(),
            triangle_lines: s.triangle_lines.iter().flat_map(|&l| [l; 4]).collect(),
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{cross2, triangle_area};
    use crate::mesh::obj::parse_obj;
    use crate::mesh::Garment;

    #[test]
    fn two_sewn_squares_stay_sewn() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0.1\nv 2 1 0.1\n\
                    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 0\nvt 6 0\nvt 6 1\nvt 5 1\n\
                    f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 2/5 5/6 6/7\nf 2/5 6/7 3/8\n";
        let m = parse_obj(text, "s.obj", "s").unwrap();
        let g0 = Garment::new(m.clone()).unwrap();
        let s = midpoint(&m).unwrap();
        let g = Garment::new(s.clone()).unwrap();
        assert_eq!(s.positions.len(), 6 + g0.topology.num_edges());
        assert_eq!(s.triangles.len(), 16);
        assert_eq!(g.num_panels, 2);
        // The seam edge (2, 3) gained one seam vertex: 2 + 1 + the two ends.
        assert_eq!(g.num_seam_vertices(), 3);
        let area = |m: &Mesh| -> f64 {
            m.triangles
                .iter()
                .map(|t| {
                    triangle_area(
                        &m.positions[t[0] as usize],
                        &m.positions[t[1] as usize],
                        &m.positions[t[2] as usize],
                    )
                })
                .sum()
        };
        assert!((area(&s) - area(&m)).abs() < 1e-12);
        let uv = s.uv.as_ref().unwrap();
        let puv = m.uv.as_ref().unwrap();
        for (t, ut) in uv.triangles.iter().enumerate() {
            let a = cross2(
                &uv.coords[ut[0] as usize],
                &uv.coords[ut[1] as usize],
                &uv.coords[ut[2] as usize],
            );
            let p = puv.triangles[t / 4];
            let pa = cross2(
                &puv.coords[p[0] as usize],
                &puv.coords[p[1] as usize],
                &puv.coords[p[2] as usize],
            );
            assert!(
                (a - pa / 4.0).abs() < 1e-12,
                "each child has a quarter of its parent's uv area"
            );
        }
        assert_eq!(s.source.as_ref().unwrap().triangle_lines.len(), 16);
        // Twice: 4^2 triangles per original one.
        assert_eq!(midpoint(&s).unwrap().triangles.len(), 64);
    }
}
