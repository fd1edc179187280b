//! Proximity repulsion (Bridson et al. 2002, Sec. 7.2), before any CCD: for each candidate pair
//! closer than its thickness, or predicted (along the closest-point normal, to first order) to
//! come closer than its thickness by the end of the step, an inelastic impulse removes the
//! approaching normal velocity, and pairs already inside their thickness are pushed apart at a
//! fraction of the overlap per step; Coulomb friction acts on the tangential relative velocity.
//!
//! The closest-point geometry at the start of the step is computed once per pair (in parallel);
//! the impulses are then applied in a fixed pair order (Gauss-Seidel) for a few sweeps, so the
//! result does not depend on the thread count.

use rayon::prelude::*;

use super::{closest, impulse, Closest, Pair, PairKind, Scene};
use crate::geom::Vec3;
use crate::sim::policy::ContactPolicy;

/// Fraction of a pair's overlap removed per step by the repulsion.
pub const PUSH_OUT: f64 = 0.25;
/// Gauss-Seidel sweeps over the close pairs.
pub const SWEEPS: usize = 4;

struct Near {
    pair: Pair,
    nodes: [u32; 4],
    geom: Closest,
    target: f64,
    mu: f64,
    active: bool,
    close: bool,
}

/// Applies proximity impulses to `v`; returns the number of impulses applied and the cloth-cloth
/// pairs that started within twice their thickness or received an impulse, and with
/// `within_reach` also those that could come within it during the step (contacts the next step
/// treats inside the implicit solve, see [`crate::sim::contact`]).
pub fn repel(
    scene: &Scene,
    v: &mut [Vec3],
    candidates: &[Pair],
    policy: &dyn ContactPolicy,
    within_reach: bool,
) -> (usize, Vec<Pair>) {
    let h = scene.h;
    let near: Vec<Near> = {
        let v: &[Vec3] = v;
        candidates
            .par_iter()
            .with_min_len(512)
            .filter_map(|&p| {
                let eps = scene.thickness(p, policy)?;
                let nodes = scene.nodes(p);
                let x = scene.positions(v, &nodes, 0.0);
                // Cheap rejection: the reach below is at most the fastest node of each
                // primitive's speed times h, and the distance at least the gap of their boxes.
                let vt = p.is_vertex_triangle();
                let split = if vt { 1 } else { 2 };
                let speed = |r: std::ops::Range<usize>| {
                    r.map(|k| scene.velocity(v, nodes[k]).norm())
                        .fold(0.0f64, f64::max)
                };
                let reach_max = (speed(0..split) + speed(split..4)) * h;
                let far = (2.0 * eps).max(eps + 2.0 * reach_max);
                if super::swept_apart(&x, &x, vt, far) || super::sphere_apart(&x, vt, far) {
                    return None;
                }
                let geom = closest(&x, vt);
                // Only pairs that could come within eps during the step matter.
                let reach: f64 = (0..4)
                    .map(|k| geom.weights[k].abs() * scene.velocity(v, nodes[k]).norm())
                    .sum::<f64>()
                    * h;
                let gap = geom.distance - eps;
                let close = geom.distance < 2.0 * eps;
                let active = gap <= 2.0 * reach;
                if !active && !close {
                    return None;
                }
                // Target normal velocity: approach no closer than eps by the end of the step;
                // inside eps, move out at PUSH_OUT of the overlap per step.
                let target = if gap >= 0.0 {
                    -gap / h
                } else {
                    -PUSH_OUT * gap / h
                };
                Some(Near {
                    pair: p,
                    nodes,
                    geom,
                    target,
                    mu: scene.friction_of(p),
                    active,
                    close,
                })
            })
            .collect()
    };
    let mut impulsed = vec![false; near.len()];
    let mut applied = 0;
    for _ in 0..SWEEPS {
        let mut any = false;
        for (n, hit) in near
            .iter()
            .zip(impulsed.iter_mut())
            .filter(|(n, _)| n.active)
        {
            let g = &n.geom;
            let vn: f64 = (0..4)
                .map(|k| g.weights[k] * g.normal.dot(&scene.velocity(v, n.nodes[k])))
                .sum();
            if vn >= n.target - 1e-12 * n.target.abs() {
                continue;
            }
            if let Some(dv) = impulse(
                scene,
                v,
                &n.nodes,
                &g.weights,
                &g.normal,
                n.target - vn,
                n.mu,
            ) {
                for k in 0..4 {
                    if n.nodes[k] & super::OBSTACLE == 0 {
                        v[n.nodes[k] as usize] += dv[k];
                    }
                }
                applied += 1;
                any = true;
                *hit = true;
            }
        }
        if !any {
            break;
        }
    }
    // Resting contact for the next step: pairs that start close, and pairs whose approach an
    // impulse just stopped (they end the step near their thickness). Pairs that were merely
    // within reach of fast motion are not: linearised at the next step's start, far pairs of
    // fast cloth would all look like contacts.
    let resting = near
        .iter()
        .zip(&impulsed)
        .filter(|(n, &hit)| {
            matches!(n.pair.kind, PairKind::VertexTriangle | PairKind::EdgeEdge)
                && (hit || n.close || within_reach)
        })
        .map(|(n, _)| n.pair)
        .collect();
    (applied, resting)
}
