//! Midpoint 1-to-4 subdivision, keeping the uv layer (seams stay seams) and the groups.

use super::{Group, Mesh, UvLayer};
use std::collections::HashMap;

/// Splits every triangle into four at its edge midpoints. World and uv midpoints are shared by
/// the triangles beside an edge; each triangle's four children are consecutive, so groups keep
/// their triangles (counts times four).
pub fn subdivide(mesh: &Mesh) -> Mesh {
    fn split<T: Copy>(
        tris: &[[u32; 3]],
        points: &mut Vec<T>,
        mid: impl Fn(&T, &T) -> T,
    ) -> Vec<[u32; 3]> {
        let mut edge_mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut out = Vec::with_capacity(tris.len() * 4);
        for t in tris {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[k] = *edge_mid.entry(key).or_insert_with(|| {
                    let p = mid(&points[a as usize], &points[b as usize]);
                    points.push(p);
                    (points.len() - 1) as u32
                });
            }
            out.push([t[0], m[0], m[2]]);
            out.push([m[0], t[1], m[1]]);
            out.push([m[2], m[1], t[2]]);
            out.push([m[0], m[1], m[2]]);
        }
        out
    }
    let mut positions = mesh.positions.clone();
    let triangles = split(&mesh.triangles, &mut positions, |a, b| (a + b) * 0.5);
    let uv = mesh.uv.as_ref().map(|uv| {
        let mut coords = uv.coords.clone();
        let triangles = split(&uv.triangles, &mut coords, |a, b| (a + b) * 0.5);
        UvLayer { coords, triangles }
    });
    Mesh {
        name: mesh.name.clone(),
        positions,
        triangles,
        uv,
        groups: mesh
            .groups
            .iter()
            .map(|g| Group {
                name: g.name.clone(),
                first: g.first * 4,
                count: g.count * 4,
            })
            .collect(),
        source: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::obj::parse_obj;

    #[test]
    fn counts_area_and_seams_are_kept() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0.1\nv 2 1 0.1\n\
                    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 0\nvt 6 0\nvt 6 1\nvt 5 1\n\
                    f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 2/5 5/6 6/7\nf 2/5 6/7 3/8\n";
        let m = parse_obj(text, "s.obj", "s").unwrap();
        let s = subdivide(&m);
        s.validate().unwrap();
        // V' = V + E, F' = 4F; the uv layer likewise over its own edges.
        let topo = crate::mesh::Topology::new(&m).unwrap();
        assert_eq!(s.positions.len(), m.positions.len() + topo.edges.len());
        assert_eq!(s.triangles.len(), 16);
        let area = |m: &Mesh| -> f64 {
            m.triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| m.positions[v as usize]);
                    crate::geom::triangle_area(&a, &b, &c)
                })
                .sum()
        };
        assert!((area(&m) - area(&s)).abs() < 1e-12);
        let g = crate::mesh::Garment::new(s).unwrap();
        assert_eq!(g.num_panels, 2);
        assert_eq!(
            g.num_seam_vertices(),
            3,
            "the seam edge got a midpoint with two uvs"
        );
    }
}
