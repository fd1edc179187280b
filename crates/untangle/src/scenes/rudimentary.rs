//! The six rudimentary tanglements of Cha & Ko 2022, Fig. 13 (Sec. 9.1), plus a BLI case.
//!
//! CLOSED, BB/II and BI/BI come from two handkerchiefs pushed through each other by smooth
//! deformations. LL, EIGHT and CROSS need a *loop vertex* (two triangles sharing a vertex that
//! intersect), which is a configuration at the scale of one vertex fan; they are built from small
//! cores with a flat rest layout (the uv) and a folded world shape, then refined by midpoint
//! subdivision, which keeps the world surface and therefore the kind:
//!
//! - CROSS: a boundary vertex whose open fan has two wedges crossing through it (two BLI paths
//!   sharing the loop vertex, split into a BB/II pair).
//! - EIGHT: the same fan with a pocket closing the far side, so the curve returns to the vertex.
//! - LL: a flap hinged at an edge folds into a pyramid on the other side of the hinge; the curve
//!   runs from one hinge vertex to the other.
//! - BLI: one wedge of a boundary vertex's fan folded through another.

use super::{handkerchief, Scene};
use crate::geom::{Vec2, Vec3};
use crate::mesh::subdivide::subdivide_n;
use crate::mesh::{Group, Mesh, UvLayer};

/// A core piece: uv layout, world positions, triangles.
fn core(name: &str, uv: &[[f64; 2]], world: &[[f64; 3]], tris: &[[u32; 3]], levels: usize) -> Mesh {
    let m = Mesh {
        name: name.into(),
        positions: world.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect(),
        triangles: tris.to_vec(),
        uv: Some(UvLayer {
            coords: uv.iter().map(|p| Vec2::new(p[0], p[1])).collect(),
            triangles: tris.to_vec(),
        }),
        groups: vec![Group {
            name: name.into(),
            first: 0,
            count: tris.len() as u32,
            is_object: true,
        }],
        source: None,
    };
    subdivide_n(&m, levels)
}

/// Half-disc fan layout around a boundary vertex at the origin: ring point `k` of `n` at angle
/// `pi * k / (n - 1)`.
fn half_disc(n: usize) -> Vec<[f64; 2]> {
    let mut v = vec![[0.0, 0.0]];
    for k in 0..n {
        let a = std::f64::consts::PI * k as f64 / (n - 1) as f64;
        v.push([a.cos(), a.sin()]);
    }
    v
}

/// World positions of the crossing fan: wedge P (triangles 0, 1) in the plane y = 0, a middle
/// triangle lifting off, and wedge Q (triangles 3, 4) dipping through P.
const CROSS_WORLD: [[f64; 3]; 7] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.6428, 0.0, 0.7660],
    [-0.1736, 0.0, 0.9848],
    [-0.45, 0.3, 0.779],
    [0.55, -0.5, 0.55],
    [0.9, 0.4, 0.1],
];

/// CROSS: see the module documentation.
pub fn cross(levels: usize) -> Scene {
    let tris = [[0u32, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5], [0, 5, 6]];
    let m = core("cross", &half_disc(6), &CROSS_WORLD, &tris, levels);
    Scene {
        name: "cross".into(),
        meshes: vec![m],
        expected: vec![("CROSS", 1)],
    }
}

/// EIGHT: the crossing fan with a pocket triangle joining the two dipping edges.
pub fn eight(levels: usize) -> Scene {
    let mut uv = half_disc(6);
    // The dipping ring vertex moves inside the layout triangle (origin, ring 3, ring 5), so the
    // pocket triangle closes the fan's far side in the rest shape too.
    uv[5] = [-0.445, 0.323];
    let tris = [
        [0u32, 1, 2],
        [0, 2, 3],
        [0, 3, 4],
        [0, 4, 5],
        [0, 5, 6],
        [5, 4, 6],
    ];
    let m = core("eight", &uv, &CROSS_WORLD, &tris, levels);
    Scene {
        name: "eight".into(),
        meshes: vec![m],
        expected: vec![("EIGHT", 1)],
    }
}

/// LL: flap `(a, c, b)` hinged at edge `ab` folds into the pyramid over `(a, b, e)` with apex `d`.
pub fn loop_loop(levels: usize) -> Scene {
    // 0 = a, 1 = b, 2 = c (flap apex), 3 = d (pyramid apex), 4 = e.
    let uv = [[0.0, 0.0], [1.0, 0.0], [0.5, -0.8], [0.5, 0.4], [0.5, 1.0]];
    let world = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.5, 0.3, 0.95],
        [0.5, 0.1, 0.6],
        [0.5, 1.0, 0.0],
    ];
    let tris = [[0u32, 2, 1], [0, 1, 3], [3, 1, 4], [0, 3, 4]];
    let m = core("ll", &uv, &world, &tris, levels);
    Scene {
        name: "ll".into(),
        meshes: vec![m],
        expected: vec![("LL", 1)],
    }
}

/// BLI: the crossing fan with only the first dipping triangle.
pub fn bli(levels: usize) -> Scene {
    let m = core("bli", &half_disc(5), &CROSS_WORLD[..6], &BLI_FAN, levels);
    Scene {
        name: "bli".into(),
        meshes: vec![m],
        expected: vec![("BLI", 1)],
    }
}

/// The fan of [`bli`]: four triangles around core vertex 0.
const BLI_FAN: [[u32; 3]; 4] = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]];

/// BLI with an interior loop vertex: the fan of [`bli`] (same layout and world positions)
/// closed into a full disc by two more triangles on the far side of its diameter (core vertex
/// 6, away from both wedges). The same tanglement, but no half of the path separates anything:
/// the inside region comes from Wicke's cone heuristic.
pub fn bli_interior(levels: usize) -> Scene {
    let mut uv = half_disc(5);
    uv.push([0.0, -1.0]);
    let mut world = CROSS_WORLD[..6].to_vec();
    world.push([0.6, -0.8, -0.2]);
    let mut tris = BLI_FAN.to_vec();
    tris.extend([[0, 5, 6], [0, 6, 1]]);
    let m = core("bli_interior", &uv, &world, &tris, levels);
    Scene {
        name: "bli-interior".into(),
        meshes: vec![m],
        expected: vec![("BLI", 1)],
    }
}

/// BB/II: handkerchief B lies above A and its right edge is bent down through A, so the curve
/// runs across B from boundary to boundary (BB) and inside A (II).
pub fn bb_ii(n: usize) -> Scene {
    let a = handkerchief("A", n, n, 1.4, 1.4, |p| Vec3::new(p.x, p.y, 0.0113 * p.y));
    let b = handkerchief("B", n, n, 1.0, 1.0, |p| {
        let bend = if p.x > 0.1731 {
            (p.x - 0.1731) * 0.9
        } else {
            0.0
        };
        Vec3::new(
            p.x - 0.0123,
            p.y + 0.0071,
            0.0612 - bend * bend * 3.0 - bend * 0.2,
        )
    });
    Scene {
        name: "bbii".into(),
        meshes: vec![a, b],
        expected: vec![("BBII", 1)],
    }
}

/// BI/BI: two handkerchiefs overlapping at a corner, crossing at an angle, so each has one end
/// of the curve on its boundary and one inside.
pub fn bi_bi(n: usize) -> Scene {
    let a = handkerchief("A", n, n, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0117 * p.x));
    let b = handkerchief("B", n, n, 1.0, 1.0, |p| {
        Vec3::new(
            p.x + 0.6123,
            p.y + 0.0137,
            0.35 * (p.y - 0.0213) + 0.0071 * p.x,
        )
    });
    Scene {
        name: "bibi".into(),
        meshes: vec![a, b],
        expected: vec![("BIBI", 1)],
    }
}
