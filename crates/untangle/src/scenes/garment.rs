//! A garment-like scene with seams: a skirt of two panels (front and back) sewn along two side
//! seams, with vertical folds, flattened so the panels lie close, and round dents on the front
//! pushed through the back. Each dent makes one CLOSED tanglement. World vertices on the seams are
//! shared by both panels and have one uv copy per panel, like garments from pattern tools.

use super::Scene;
use crate::geom::{Vec2, Vec3};
use crate::mesh::{Group, Mesh, UvLayer};

/// The skirt with `n` cells around each panel and `n / 2` up, `dents` dents on the front
/// (`2 n^2` triangles in all; `n = 224` gives 100,352).
pub fn skirt(n: usize, dents: usize) -> Scene {
    let (nt, nz) = (n.max(8), (n / 2).max(4));
    let height = 0.8;
    let around = 2 * nt; // world vertex columns around the tube (seams at 0 and nt)
    let id = |i: usize, j: usize| (j * around + (i % around)) as u32;
    let dent_at: Vec<(f64, f64)> = (0..dents)
        .map(|k| {
            let t = (k as f64 + 0.5) / dents as f64;
            (0.25 + 0.5 * t, 0.3 + 0.4 * ((k * 7 % 5) as f64 / 4.0))
        })
        .collect();
    let sigma = 0.35 / (dents.max(1) as f64).sqrt() * 0.25;
    let mut positions = Vec::with_capacity(around * (nz + 1));
    for j in 0..=nz {
        let z = height * j as f64 / nz as f64;
        let flare = 0.25 + 0.1 * (z / height);
        for i in 0..around {
            let th = std::f64::consts::TAU * i as f64 / around as f64;
            let fold = 1.0 + 0.04 * (12.0 * th).sin();
            let x = flare * fold * th.cos();
            let mut y = 0.06 * fold * th.sin();
            if i > 0 && i < nt {
                // Front panel: dents pushed through the back.
                let u = i as f64 / nt as f64;
                let v = z / height;
                for &(cu, cv) in &dent_at {
                    let d2 = ((u - cu) * 2.0).powi(2) + (v - cv).powi(2);
                    y -= 0.2 * (-d2 / (sigma * sigma)).exp();
                }
            }
            positions.push(Vec3::new(x + 0.0013 * z, y, z));
        }
    }
    let mut triangles = Vec::new();
    let mut uv_tris = Vec::new();
    let mut coords: Vec<Vec2> = Vec::new();
    let mut groups = Vec::new();
    for panel in 0..2 {
        let base = coords.len() as u32;
        let i0 = panel * nt;
        let width = 0.9; // flat pattern width of a panel (m)
        for j in 0..=nz {
            for k in 0..=nt {
                coords.push(Vec2::new(
                    panel as f64 * 1.2 + width * k as f64 / nt as f64,
                    height * j as f64 / nz as f64,
                ));
            }
        }
        let uid = |k: usize, j: usize| base + (j * (nt + 1) + k) as u32;
        let first = triangles.len() as u32;
        for j in 0..nz {
            for k in 0..nt {
                let (a, b, c, d) = (
                    id(i0 + k, j),
                    id(i0 + k + 1, j),
                    id(i0 + k + 1, j + 1),
                    id(i0 + k, j + 1),
                );
                let (ua, ub, uc, ud) = (uid(k, j), uid(k + 1, j), uid(k + 1, j + 1), uid(k, j + 1));
                if (k + j) % 2 == 0 {
                    triangles.extend([[a, b, c], [a, c, d]]);
                    uv_tris.extend([[ua, ub, uc], [ua, uc, ud]]);
                } else {
                    triangles.extend([[a, b, d], [b, c, d]]);
                    uv_tris.extend([[ua, ub, ud], [ub, uc, ud]]);
                }
            }
        }
        groups.push(Group {
            name: if panel == 0 {
                "front".into()
            } else {
                "back".into()
            },
            first,
            count: triangles.len() as u32 - first,
            is_object: false,
        });
    }
    let mesh = Mesh {
        name: "skirt".into(),
        positions,
        triangles,
        uv: Some(UvLayer {
            coords,
            triangles: uv_tris,
        }),
        groups,
        source: None,
    };
    Scene {
        name: format!("skirt-{n}-{dents}"),
        meshes: vec![mesh],
        expected: vec![("CLOSED", dents)],
    }
}

/// Two long open tubes (radius 1, length 8, `n` segments around and `2 n` rings along, axes
/// along z at `x = -offset` and `x = +offset`, `offset < 1`) in one mesh: each tube's wall
/// between the two intersection lines lies inside the other tube, like a leg passed into the
/// other leg. The analysis finds two BIBI tanglements (four BI paths, each from an open end to
/// where the other tube's rim pierces the wall); no path separates a tube, so Wicke's rules
/// give no inside region;
/// the known answer is geometric: the cloth inside the other tube, which the analysis's winding
/// regions ([`crate::analysis::regions::RegionFinder::winding_region`]) must find.
pub fn overlapping_tubes(n: usize, offset: f64) -> Scene {
    let n = n.max(8);
    let tube = crate::implicit::shapes::cylinder_mesh("tube", 1.0, 8.0, n, 2 * n, false);
    let count = tube.positions.len() as u32;
    let shift = Vec3::new(offset, 0.0, 0.0);
    let mut pos: Vec<Vec3> = tube.positions.iter().map(|p| p - shift).collect();
    pos.extend(tube.positions.iter().map(|p| p + shift));
    let mut tris = tube.triangles.clone();
    tris.extend(tube.triangles.iter().map(|t| t.map(|v| v + count)));
    Scene {
        name: "tubes".into(),
        meshes: vec![Mesh::new("tubes", pos, tris).expect("two valid tubes")],
        expected: vec![("BIBI", 2)],
    }
}
