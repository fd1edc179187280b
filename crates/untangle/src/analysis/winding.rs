//! Generalized winding numbers of points with respect to a triangle set (Jacobson, Kavan and
//! Sorkine-Hornung 2013, Eq. 3 with the triangle solid angle of Van Oosterom and Strackee 1983):
//! `w(p) = sum_t Omega_t(p) / (4 pi)`. For a closed, outward-oriented surface `w` is 1 inside and
//! 0 outside, and jumps by 1 across every sheet; for open garments (tubes open at hems, waist
//! and cuffs) it is close to those values away from the openings. Evaluated at a vertex of the
//! surface itself (its own triangles skipped, they subtend no solid angle from a corner), a
//! vertex on a smooth part of the surface gets about 1/2, and a vertex whose cloth has passed
//! into another tube of the same garment about 1/2 + 1: that is the geometric criterion the
//! regions of a garment's long BLIs need (see [`super::regions::RegionFinder::winding_region`]).
//!
//! [`at_vertex`] sums every triangle (the oracle); [`Tree`] evaluates the same number in
//! logarithmic time by the first-order far-field expansion of Barill, Dickson, Schmidt, Levin and
//! Jacobson 2018 ("Fast winding numbers for soups and clouds", Sec. 3): a cluster of triangles
//! seen from farther than `beta` times its radius acts as one dipole, its area-weighted normal
//! at its area-weighted centre (here beyond 4 radii). Every value is one sequential traversal in a fixed order, so it
//! does not depend on how many threads evaluate a batch of points.

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

/// A cluster hierarchy over a range of triangles for fast winding numbers (Barill et al. 2018,
/// Sec. 3, first order): each node keeps the sum of its triangles' area vectors (`n`, half the
/// cross product of two edges), their area-weighted centre and the radius of a ball around that
/// centre holding every corner (exact at the leaves, bounded by the children's balls above).
pub struct Tree {
    nodes: Vec<Node>,
    /// Triangle indices (into the full triangle list), leaves' ranges refer to it.
    order: Vec<u32>,
}

struct Node {
    n: Vec3,
    centre: Vec3,
    radius: f64,
    /// Sum of the triangles' areas (the centre's weight).
    area: f64,
    /// Children (internal node) or `order` range (leaf, `leaf = true`).
    a: u32,
    b: u32,
    leaf: bool,
}

/// Largest number of triangles in a leaf.
const LEAF: usize = 8;
/// Far-field acceptance: a cluster farther than `BETA` radii is one dipole. Barill et al. use 2
/// with a second-order expansion; with the first order alone 2 was too coarse on the surface of
/// two overlapping tubes, and 4 leaves a largest difference below 0.01 from the direct sum there
/// and on the tangled pants (`examples/winding_bench.rs`).
const BETA: f64 = 4.0;

impl Tree {
    /// The hierarchy over `tris[range]` at positions `pos`: the triangles sorted along the Morton
    /// curve of their centroids (radix sort; ties in input order) and split where the highest
    /// Morton bit changes (Karras 2012, as [`crate::broad::bvh`]), so the tree is fixed by the
    /// input and built in linear time.
    pub fn new(pos: &[Vec3], tris: &[[u32; 3]], range: Range<u32>) -> Tree {
        let tris_here = &tris[range.start as usize..range.end as usize];
        let cents: Vec<Vec3> = tris_here
            .iter()
            .map(|t| (pos[t[0] as usize] + pos[t[1] as usize] + pos[t[2] as usize]) / 3.0)
            .collect();
        let mut tree = Tree {
            nodes: Vec::with_capacity(2 * cents.len() / LEAF + 1),
            order: Vec::new(),
        };
        if cents.is_empty() {
            return tree;
        }
        let (codes, order) = crate::broad::bvh::morton_sorted(&cents);
        tree.order = order.into_iter().map(|t| t + range.start).collect();
        tree.build(&codes, 0, &cents, range.start, pos, tris);
        tree
    }

    /// Builds the node over `order[lo..lo + codes.len()]`; returns its index. A leaf sums its
    /// triangles; an internal node sums its children, with the radius bounded by their balls.
    fn build(
        &mut self,
        codes: &[u64],
        lo: usize,
        cents: &[Vec3],
        first: u32,
        pos: &[Vec3],
        tris: &[[u32; 3]],
    ) -> u32 {
        let hi = lo + codes.len();
        let id = self.nodes.len() as u32;
        self.nodes.push(Node {
            n: Vec3::zeros(),
            centre: Vec3::zeros(),
            radius: 0.0,
            area: 0.0,
            a: lo as u32,
            b: hi as u32,
            leaf: true,
        });
        if hi - lo <= LEAF {
            let (mut n, mut weighted, mut area) = (Vec3::zeros(), Vec3::zeros(), 0.0);
            for &t in &self.order[lo..hi] {
                let [a, b, c] = tris[t as usize].map(|v| pos[v as usize]);
                let an = 0.5 * (b - a).cross(&(c - a));
                n += an;
                let w = an.norm();
                weighted += w * cents[(t - first) as usize];
                area += w;
            }
            let centre = if area > 0.0 {
                weighted / area
            } else {
                cents[(self.order[lo] - first) as usize]
            };
            let radius = self.order[lo..hi]
                .iter()
                .flat_map(|&t| tris[t as usize])
                .map(|v| (pos[v as usize] - centre).norm())
                .fold(0.0, f64::max);
            let node = &mut self.nodes[id as usize];
            (node.n, node.centre, node.radius, node.area) = (n, centre, radius, area);
            return id;
        }
        let m = crate::broad::bvh::split_point(codes);
        let a = self.build(&codes[..m], lo, cents, first, pos, tris);
        let b = self.build(&codes[m..], lo + m, cents, first, pos, tris);
        let (na, nb) = (&self.nodes[a as usize], &self.nodes[b as usize]);
        let area = na.area + nb.area;
        let centre = if area > 0.0 {
            (na.area * na.centre + nb.area * nb.centre) / area
        } else {
            na.centre
        };
        let radius =
            ((na.centre - centre).norm() + na.radius).max((nb.centre - centre).norm() + nb.radius);
        let n = na.n + nb.n;
        let node = &mut self.nodes[id as usize];
        (node.n, node.centre, node.radius, node.area) = (n, centre, radius, area);
        (node.a, node.b, node.leaf) = (a, b, false);
        id
    }

    /// The winding number of vertex `v` at `pos[v]` (as [`at_vertex`], up to the far-field
    /// error: at most a few hundredths), skipping the triangles with `v` as a corner.
    pub fn at_vertex(&self, v: u32, pos: &[Vec3], tris: &[[u32; 3]]) -> f64 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let p = pos[v as usize];
        let mut sum = 0.0;
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            let d = node.centre - p;
            let dist = d.norm();
            if dist > BETA * node.radius {
                sum += d.dot(&node.n) / (dist * dist * dist);
            } else if node.leaf {
                for &t in &self.order[node.a as usize..node.b as usize] {
                    let tri = tris[t as usize];
                    if tri.contains(&v) {
                        continue;
                    }
                    let [a, b, c] = tri.map(|u| pos[u as usize]);
                    sum += solid_angle(&p, &a, &b, &c);
                }
            } else {
                stack.push(node.b);
                stack.push(node.a);
            }
        }
        sum / (4.0 * std::f64::consts::PI)
    }

    /// [`Tree::at_vertex`] for each of `vertices`, in parallel (values independent of threads).
    pub fn at_vertices(&self, vertices: &[u32], pos: &[Vec3], tris: &[[u32; 3]]) -> Vec<f64> {
        vertices
            .par_iter()
            .map(|&v| self.at_vertex(v, pos, tris))
            .collect()
    }
}
