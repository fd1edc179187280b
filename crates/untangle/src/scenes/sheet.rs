//! The handkerchief: a square grid of triangles with its flat rest shape as uv.

use crate::geom::{Vec2, Vec3};
use crate::mesh::{Group, Mesh, UvLayer};

/// A `nx x ny`-cell sheet of size `w x h` centred at the origin, each cell split into two
/// triangles along alternating diagonals; uv = rest position; world position = `place(uv)`.
pub fn handkerchief(
    name: &str,
    nx: usize,
    ny: usize,
    w: f64,
    h: f64,
    place: impl Fn(Vec2) -> Vec3,
) -> Mesh {
    let (nx, ny) = (nx.max(1), ny.max(1));
    let mut uv = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            uv.push(Vec2::new(
                -0.5 * w + w * i as f64 / nx as f64,
                -0.5 * h + h * j as f64 / ny as f64,
            ));
        }
    }
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            } else {
                triangles.push([a, b, d]);
                triangles.push([b, c, d]);
            }
        }
    }
    let positions = uv.iter().map(|p| place(*p)).collect();
    Mesh {
        name: name.into(),
        positions,
        uv: Some(UvLayer {
            coords: uv,
            triangles: triangles.clone(),
        }),
        groups: vec![Group {
            name: name.into(),
            first: 0,
            count: triangles.len() as u32,
            is_object: true,
        }],
        triangles,
        source: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_counts_and_orientation() {
        let m = handkerchief("h", 4, 3, 2.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0));
        assert_eq!(m.positions.len(), 20);
        assert_eq!(m.triangles.len(), 24);
        m.validate().unwrap();
        let uv = m.uv.as_ref().unwrap();
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
