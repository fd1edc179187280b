//! Generalized winding numbers of points with respect to a triangle set (Jacobson, Kavan and
//! Sorkine-Hornung 2013, Eq. 3 with the triangle solid angle of Van Oosterom and Strackee 1983):
//! `w(p) = sum_t Omega_t(p) / (4 pi)`. For a closed, outward-oriented surface `w` is 1 inside and
//! 0 outside, and jumps by 1 across every sheet; for open garments (tubes open at hems, waist
//! and cuffs) it is close to those values away from the openings. Evaluated at a vertex of the
//! surface itself (its own triangles skipped, they subtend no solid angle from a corner), a
//! vertex on a smooth part of the surface gets about 1/2, and a vertex whose cloth has passed
//! into another tube of the same garment about 1/2 + 1: that is the geometric criterion the
//! long BLI regions of a garment need (see [`super::regions::RegionFinder::bli_winding`]).
//!
//! Each value is one sequential sum in triangle order, so it does not depend on how many threads
//! evaluate a batch of points.

use crate::geom::Vec3;
use rayon::prelude::*;
use std::ops::Range;

/// The solid angle (steradians, signed by the orientation `a, b, c`) that triangle `abc`
/// subtends at `p` (Van Oosterom and Strackee 1983). Zero when `p` is a corner.
pub fn solid_angle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    let (a, b, c) = (a - p, b - p, c - p);
    let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
    let det = a.dot(&b.cross(&c));
    let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
    if det == 0.0 && den <= 0.0 {
        // In the triangle's plane: on the triangle (a corner or an edge) or outside it; the
        // limit from either side averages to zero.
        return 0.0;
    }
    2.0 * det.atan2(den)
}

/// The generalized winding number of vertex `v` at `pos[v]` with respect to the triangles
/// `tris[range]`, skipping the triangles that have `v` as a corner.
pub fn at_vertex(v: u32, pos: &[Vec3], tris: &[[u32; 3]], range: Range<u32>) -> f64 {
    let p = pos[v as usize];
    let mut sum = 0.0;
    for t in &tris[range.start as usize..range.end as usize] {
        if t.contains(&v) {
            continue;
        }
        sum += solid_angle(
            &p,
            &pos[t[0] as usize],
            &pos[t[1] as usize],
            &pos[t[2] as usize],
        );
    }
    sum / (4.0 * std::f64::consts::PI)
}

/// [`at_vertex`] for each of `vertices` (in parallel; the values do not depend on the threads).
pub fn at_vertices(
    vertices: &[u32],
    pos: &[Vec3],
    tris: &[[u32; 3]],
    range: Range<u32>,
) -> Vec<f64> {
    vertices
        .par_iter()
        .map(|&v| at_vertex(v, pos, tris, range.clone()))
        .collect()
}
