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

use super::{closest, impulse, Closest, Pair, Scene};
use crate::geom::Vec3;
use crate::sim::policy::ContactPolicy;

/// Fraction of a pair's overlap removed per step by the repulsion.
pub const PUSH_OUT: f64 = 0.25;
/// Gauss-Seidel sweeps over the close pairs.
pub const SWEEPS: usize = 4;

struct Near {
    nodes: [u32; 4],
    geom: Closest,
    target: f64,
    mu: f64,
}

/// Applies proximity impulses to `v`; returns the number of impulses applied.
pub fn repel(
    scene: &Scene,
    v: &mut [Vec3],
    candidates: &[Pair],
    policy: &dyn ContactPolicy,
) -> usize {
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
                let geom = closest(&x, p.is_vertex_triangle());
                // Only pairs that could come within eps during the step matter.
                let reach: f64 = (0..4)
                    .map(|k| geom.weights[k].abs() * scene.velocity(v, nodes[k]).norm())
                    .sum::<f64>()
                    * h;
                let gap = geom.distance - eps;
                if gap > 2.0 * reach {
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
                    nodes,
                    geom,
                    target,
                    mu: scene.friction_of(p),
                })
            })
            .collect()
    };
    let mut applied = 0;
    for _ in 0..SWEEPS {
        let mut any = false;
        for n in &near {
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
            }
        }
        if !any {
            break;
        }
    }
    applied
}
