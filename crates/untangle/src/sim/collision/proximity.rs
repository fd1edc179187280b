//! Proximity repulsion (Bridson et al. 2002, Sec. 7.2), before any CCD: for each candidate pair
//! closer than its thickness, or predicted (along the closest-point normal, to first order) to
//! come closer than its thickness by the end of the step, an inelastic impulse removes the
//! approaching normal velocity, and pairs already inside their thickness are pushed apart at a
//! fraction of the overlap per step; Coulomb friction acts on the tangential relative velocity.
//! Velocity changes are averaged per vertex over its pairs (Jacobi), in pair order, so the
//! result does not depend on the thread count.

use rayon::prelude::*;

use super::{closest, impulse, Pair, Scene};
use crate::geom::Vec3;
use crate::sim::policy::ContactPolicy;

/// Fraction of a pair's overlap removed per step by the repulsion.
pub const PUSH_OUT: f64 = 0.25;

/// Applies proximity impulses to `v`; returns the number of pairs that received one.
pub fn repel(scene: &Scene, v: &mut [Vec3], candidates: &[Pair], policy: &dyn ContactPolicy) -> usize {
    let h = scene.h;
    let responses: Vec<([u32; 4], [Vec3; 4])> = {
        let v: &[Vec3] = v;
        candidates
            .par_iter()
            .with_min_len(512)
            .filter_map(|&p| {
                let eps = scene.thickness(p, policy)?;
                let nodes = scene.nodes(p);
                let x = scene.positions(v, &nodes, 0.0);
                let c = closest(&x, p.is_vertex_triangle());
                let vn: f64 = (0..4)
                    .map(|k| c.weights[k] * c.normal.dot(&scene.velocity(v, nodes[k])))
                    .sum();
                // Target normal velocity: approach no closer than eps by the end of the step;
                // inside eps, move out at PUSH_OUT of the overlap per step.
                let gap = c.distance - eps;
                let target = if gap >= 0.0 { -gap / h } else { -PUSH_OUT * gap / h };
                if vn >= target {
                    return None;
                }
                let dv = impulse(scene, v, &nodes, &c.weights, &c.normal, target - vn, scene.friction_of(p))?;
                Some((nodes, dv))
            })
            .collect()
    };
    let n = v.len();
    let mut sum = vec![Vec3::zeros(); n];
    let mut count = vec![0u32; n];
    for (nodes, dv) in &responses {
        for k in 0..4 {
            let node = nodes[k];
            if node & super::OBSTACLE == 0 {
                sum[node as usize] += dv[k];
                count[node as usize] += 1;
            }
        }
    }
    for i in 0..n {
        if count[i] > 0 {
            v[i] += sum[i] / count[i] as f64;
        }
    }
    responses.len()
}
