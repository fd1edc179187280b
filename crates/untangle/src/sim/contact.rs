//! Cloth-obstacle contact as constraints of the implicit solve (Baraff & Witkin 1998, Sec. 5.3:
//! "the cloth/solid contact constraint" enforced by the filter of the modified PCG).
//!
//! Why: the collision handling after the solve changes velocities vertex by vertex. A vertex the
//! floor stops while its neighbours keep falling is displaced by up to `h |v|` relative to them in
//! one step — with 1 cm edges and a cloth landing at 0.6 m/s that is a 100% strain, and a sheet
//! landing edge-on even drives the next row of vertices through the stopped one, in the sheet's
//! own plane, where the self-collision response then pushes sideways. With the contact inside the
//! solve, the stiff cloth around a stopped vertex decelerates with it in the same step.
//!
//! Per step: every free cloth vertex that, moving with its predicted velocity (the current one
//! plus the previous step's change), would come within the obstacle thickness of an obstacle
//! triangle gets its normal velocity prescribed (the filter's `Normal` constraint): it lands
//! exactly at the thickness, or, already inside it, moves out at [`PUSH_OUT`] of the overlap per
//! step, relative to the obstacle's motion at the closest point. After the solve, the constraint
//! impulse `A dv - b` of each contact is checked; contacts that pull the cloth towards the
//! obstacle are released and the system solved again (Baraff & Witkin's release rule). The
//! normal impulse bounds Coulomb friction, applied to the tangential relative velocity.

use rayon::prelude::*;

use super::obstacle::Obstacles;
use super::policy::{Contact, ContactPolicy, ObstaclePair};
use crate::broad::Bvh;
use crate::geom::{Aabb, Vec3};

/// Fraction of an overlap (thickness minus distance) removed per step.
pub const PUSH_OUT: f64 = 0.25;

/// One vertex held by an obstacle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObstacleContact {
    /// Cloth vertex.
    pub vertex: u32,
    /// Unit normal from the obstacle towards the vertex (closest point at the step start).
    pub normal: Vec3,
    /// Velocity of the obstacle at the closest point over the step.
    pub obstacle_velocity: Vec3,
    /// Prescribed normal velocity of the vertex (`normal . v`).
    pub normal_velocity: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
}

/// A hierarchy over the obstacle triangles' swept boxes, kept across steps.
#[derive(Clone, Debug, Default)]
pub struct ContactFinder {
    bvh: Bvh,
    count: usize,
    steps: u64,
}

impl ContactFinder {
    /// The contacts of this step: for every vertex with `free[i]`, the obstacle triangle closest
    /// at the start among those the vertex, moving along `v_pred` for `h`, comes within the
    /// thickness of (the policy decides the thickness, or skips the pair).
    #[allow(clippy::too_many_arguments)]
    pub fn find(
        &mut self,
        x: &[Vec3],
        v_pred: &[Vec3],
        free: &[bool],
        obstacles: &Obstacles,
        h: f64,
        policy: &dyn ContactPolicy,
    ) -> Vec<ObstacleContact> {
        if obstacles.triangles.is_empty() {
            return Vec::new();
        }
        let boxes: Vec<Aabb> = obstacles
            .triangles
            .par_iter()
            .map(|t| {
                let mut b = Aabb::EMPTY;
                for &k in t {
                    b.grow(&obstacles.start[k as usize]);
                    b.grow(&obstacles.end[k as usize]);
                }
                b
            })
            .collect();
        if self.count != boxes.len() || self.steps % 16 == 0 {
            self.bvh = Bvh::build(&boxes);
            self.count = boxes.len();
        } else {
            self.bvh.refit(&boxes);
        }
        self.steps += 1;
        let reach = obstacles.max_thickness() * 1.0001 + 1e-12;
        (0..x.len())
            .into_par_iter()
            .with_min_len(256)
            .filter_map(|i| {
                if !free[i] {
                    return None;
                }
                let (p, vp) = (x[i], v_pred[i]);
                let mut q = Aabb::EMPTY;
                q.grow(&p);
                q.grow(&(p + vp * h));
                let q = q.inflated(reach);
                let mut best: Option<(f64, ObstacleContact)> = None;
                self.bvh.query(&q, |t| {
                    let tri = obstacles.triangles[t as usize];
                    let eps = match policy.obstacle(
                        ObstaclePair::ClothVertex {
                            vertex: i as u32,
                            triangle: t,
                        },
                        obstacles.thickness_of_vertex(tri[0]),
                    ) {
                        Contact::Thickness(e) if e.is_finite() && e > 0.0 => e,
                        _ => return,
                    };
                    let s = tri.map(|k| obstacles.start[k as usize]);
                    let (d2, w) = crate::geom::distance::point_triangle(&p, &s[0], &s[1], &s[2]);
                    let d0 = d2.max(0.0).sqrt();
                    let c = s[0] * w[0] + s[1] * w[1] + s[2] * w[2];
                    let n = if d0 > 1e-12 * (1.0 + p.amax()) {
                        (p - c) / d0
                    } else {
                        let f = (s[1] - s[0]).cross(&(s[2] - s[0]));
                        let l = f.norm();
                        if l == 0.0 {
                            return;
                        }
                        f / l
                    };
                    let vo = tri.iter().zip(w).fold(Vec3::zeros(), |a, (&k, wk)| {
                        let k = k as usize;
                        a + (obstacles.end[k] - obstacles.start[k]) * (wk / h)
                    });
                    let rel = n.dot(&(vp - vo));
                    if d0 >= eps && d0 + h * rel >= eps {
                        return;
                    }
                    // The nearest triangle decides (on a flat obstacle that is the one below the
                    // vertex, whose normal is the surface normal).
                    if best.as_ref().is_some_and(|(bd, _)| *bd <= d0) {
                        return;
                    }
                    let target = if d0 >= eps {
                        -(d0 - eps) / h
                    } else {
                        PUSH_OUT * (eps - d0) / h
                    };
                    best = Some((
                        d0,
                        ObstacleContact {
                            vertex: i as u32,
                            normal: n,
                            obstacle_velocity: vo,
                            normal_velocity: n.dot(&vo) + target,
                            friction: obstacles.friction_of_vertex(tri[0]),
                        },
                    ));
                });
                best.map(|(_, c)| c)
            })
            .collect()
    }
}

/// Stiffness of the implicit cloth-cloth repulsion relative to the pair's effective mass over
/// `h^2`: a pair that would end the step `g` inside its thickness is pushed back by
/// `g * C / (1 + C)` within the solve; proximity impulses and CCD handle the rest.
pub const PENALTY: f64 = 20.0;

/// A cloth-cloth pair in resting contact, handled inside the implicit solve as a stiff
/// one-sided spring on the closest-point distance (linearised at the step start).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClothContact {
    /// Nodes: vertex and triangle corners, or the two edges' end points.
    pub nodes: [u32; 4],
    /// Closest-point weights (relative vector `sum w_k x_k`).
    pub weights: [f64; 4],
    /// Unit normal from the second primitive to the first.
    pub normal: Vec3,
    /// Distance at the step start.
    pub distance: f64,
    /// Thickness.
    pub thickness: f64,
    /// Spring stiffness times `h^2` (kg).
    pub stiffness_h2: f64,
}

impl ClothContact {
    /// Normal gap at the end of the step for velocities `v` (linearised).
    pub fn end_gap(&self, v: &[Vec3], h: f64) -> f64 {
        let rel = (0..4).fold(Vec3::zeros(), |a, k| {
            a + v[self.nodes[k] as usize] * self.weights[k]
        });
        self.distance + h * self.normal.dot(&rel)
    }
}

/// The resting pairs (from the previous step's proximity pass) that, moving with `v_pred`,
/// would end this step inside their thickness. Nodes of `pairs` are given by `nodes_of`.
#[allow(clippy::too_many_arguments)]
pub fn cloth_contacts(
    x: &[Vec3],
    v_pred: &[Vec3],
    inv_mass: &[f64],
    pairs: &[([u32; 4], bool, f64)],
    h: f64,
) -> Vec<ClothContact> {
    pairs
        .par_iter()
        .with_min_len(256)
        .filter_map(|&(nodes, vt, eps)| {
            let p = nodes.map(|k| x[k as usize]);
            let g = super::collision::closest(&p, vt);
            let im: f64 = (0..4)
                .map(|k| g.weights[k] * g.weights[k] * inv_mass[nodes[k] as usize])
                .sum();
            if im <= 0.0 || g.distance <= 0.0 {
                return None;
            }
            let c = ClothContact {
                nodes,
                weights: g.weights,
                normal: g.normal,
                distance: g.distance,
                thickness: eps,
                stiffness_h2: PENALTY / im,
            };
            (c.end_gap(v_pred, h) < eps).then_some(c)
        })
        .collect()
}
