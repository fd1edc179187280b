//! 1-to-4 midpoint subdivision (refining the coarse arcsim garments to realistic sizes).
//!
//! Every edge gets a midpoint, every triangle becomes four with the same orientation. The uv
//! layer is subdivided on its own edges (a seam edge gets one world midpoint and one uv midpoint
//! per panel), so panels and seams survive. Groups are scaled to the new triangle ranges. The
//! surface is unchanged geometrically (new vertices lie on the old triangles).

use super::{Group, Mesh, UvLayer};
use crate::geom::Vec2;
use std::collections::HashMap;

fn midpoints<T: Copy>(
    tris: &[[u32; 3]],
    base: &mut Vec<T>,
    mid: impl Fn(&T, &T) -> T,
) -> Vec<[u32; 3]> {
    let mut index: HashMap<(u32, u32), u32> = HashMap::with_capacity(tris.len() * 2);
    let mut out = Vec::with_capacity(tris.len());
    for t in tris {
        let mut m = [0u32; 3];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            m[k] = *index.entry(key).or_insert_with(|| {
                let p = mid(&base[a as usize], &base[b as usize]);
                base.push(p);
                (base.len() - 1) as u32
            });
        }
        out.push(m);
    }
    out
}

fn split(t: &[u32; 3], m: &[u32; 3]) -> [[u32; 3]; 4] {
    // m[k] is the midpoint of edge (t[k], t[k+1]).
    [
        [t[0], m[0], m[2]],
        [m[0], t[1], m[1]],
        [m[2], m[1], t[2]],
        [m[0], m[1], m[2]],
    ]
}

/// One level of 1-to-4 midpoint subdivision.
pub fn subdivide(mesh: &Mesh) -> Mesh {
    let mut positions = mesh.positions.clone();
    let mids = midpoints(&mesh.triangles, &mut positions, |a, b| (a + b) * 0.5);
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .zip(&mids)
        .flat_map(|(t, m)| split(t, m))
        .collect();
    let uv = mesh.uv.as_ref().map(|uv| {
        let mut coords = uv.coords.clone();
        let umids = midpoints(&uv.triangles, &mut coords, |a: &Vec2, b: &Vec2| {
            (a + b) * 0.5
        });
        UvLayer {
            coords,
            triangles: uv
                .triangles
                .iter()
                .zip(&umids)
                .flat_map(|(t, m)| split(t, m))
                .collect(),
        }
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
                is_object: g.is_object,
            })
            .collect(),
        source: None,
    }
}

/// Subdivides `levels` times.
pub fn subdivide_n(mesh: &Mesh, levels: usize) -> Mesh {
    let mut m = mesh.clone();
    for _ in 0..levels {
        m = subdivide(&m);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{obj::parse_obj, Garment};

    #[test]
    fn counts_area_panels_and_seams() {
        // Two sewn panels (see garment tests): subdivision keeps 2 panels and the seam.
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0.1\nv 2 1 0.1\n\
                    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 0\nvt 6 0\nvt 6 1\nvt 5 1\n\
                    f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 2/5 5/6 6/7\nf 2/5 6/7 3/8\n";
        let m = parse_obj(text, "s.obj", "s").unwrap();
        let s = subdivide_n(&m, 2);
        s.validate().unwrap();
        // V' = V + E per level: 6 -> 6 + 9 = 15 -> 15 + 30 = 45.
        assert_eq!(s.positions.len(), 45);
        assert_eq!(s.triangles.len(), 64);
        let area = |m: &Mesh| -> f64 {
            m.triangles
                .iter()
                .map(|t| {
                    crate::geom::triangle_area(
                        &m.positions[t[0] as usize],
                        &m.positions[t[1] as usize],
                        &m.positions[t[2] as usize],
                    )
                })
                .sum()
        };
        assert!((area(&s) - area(&m)).abs() < 1e-12);
        let g0 = Garment::new(m).unwrap();
        let g = Garment::new(s).unwrap();
        assert_eq!(g.num_panels, 2);
        // The seam had 2 vertices and 1 edge; two levels put 3 more on it.
        assert_eq!(g0.num_seam_vertices(), 2);
        assert_eq!(g.num_seam_vertices(), 5);
        // Orientation kept in uv.
        let uv = g.uv();
        for t in &uv.triangles {
            let a = crate::geom::cross2(
                &uv.coords[t[0] as usize],
                &uv.coords[t[1] as usize],
                &uv.coords[t[2] as usize],
            );
            assert!(a > 0.0);
        }
    }
}
