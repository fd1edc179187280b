//! Iterated CCD impulses (Bridson et al. 2002, Sec. 7.3): CCD over the step for every candidate
//! pair with the pair's CCD thickness; each pair that CCD finds coming within it receives, in a
//! fixed order (Gauss-Seidel), an inelastic impulse along the closest-point normal at the time
//! of impact that leaves a small separating normal velocity.
//!
//! CCD thickness: `ccd_ratio` times the policy's thickness; a pair that already starts closer
//! than that is held to half its start distance instead (so pairs that begin in contact, or that
//! a policy change left inside a larger thickness, are not reported for ever, while they still
//! can never meet).

use rayon::prelude::*;

use super::{closest, impulse, kernels, Pair, Scene};
use crate::geom::Vec3;
use crate::sim::policy::ContactPolicy;

/// A pair CCD finds colliding.
#[derive(Clone, Copy, Debug)]
pub struct Collision {
    /// The pair.
    pub pair: Pair,
    /// Time of impact as a fraction of the step.
    pub toi: f64,
    /// The CCD thickness used.
    pub thickness: f64,
}

/// Runs CCD on one pair with thickness `eps`.
#[inline]
pub fn ccd(scene: &Scene, v: &[Vec3], p: Pair, eps: f64) -> Option<f64> {
    let nodes = scene.nodes(p);
    let x0 = scene.positions(v, &nodes, 0.0);
    let x1 = scene.positions(v, &nodes, 1.0);
    if p.is_vertex_triangle() {
        kernels::vertex_triangle_ccd(&x0, &x1, eps)
    } else {
        kernels::edge_edge_ccd(&x0, &x1, eps)
    }
}

/// The CCD thickness of a pair and its first time of impact, if any.
pub fn detect_pair(scene: &Scene, v: &[Vec3], p: Pair, policy: &dyn ContactPolicy) -> Option<Collision> {
    let eps = scene.thickness(p, policy)? * scene.ccd_ratio;
    let toi = ccd(scene, v, p, eps)?;
    let nodes = scene.nodes(p);
    let d0 = closest(&scene.positions(v, &nodes, 0.0), p.is_vertex_triangle()).distance;
    if d0 < 1.001 * eps {
        let e2 = 0.5 * d0;
        let toi = ccd(scene, v, p, e2)?;
        return Some(Collision { pair: p, toi, thickness: e2 });
    }
    Some(Collision { pair: p, toi, thickness: eps })
}

/// CCD over all candidates (in parallel, result in candidate order), skipping pairs for which
/// `skip` says so (pairs inside one impact zone).
pub fn detect(
    scene: &Scene,
    v: &[Vec3],
    candidates: &[Pair],
    policy: &dyn ContactPolicy,
    skip: &(dyn Fn(&[u32; 4]) -> bool + Sync),
) -> Vec<Collision> {
    candidates
        .par_iter()
        .with_min_len(256)
        .filter_map(|&p| {
            if skip(&scene.nodes(p)) {
                return None;
            }
            detect_pair(scene, v, p, policy)
        })
        .collect()
}

/// Resolves `collisions` in order (Gauss-Seidel): each pair is re-tested with the current
/// velocities and, if it still collides, receives an impulse at its time of impact. Returns how
/// many impulses were applied.
pub fn resolve(scene: &Scene, v: &mut [Vec3], collisions: &[Collision]) -> usize {
    let mut applied = 0;
    for c in collisions {
        let Some(toi) = ccd(scene, v, c.pair, c.thickness) else {
            continue;
        };
        let nodes = scene.nodes(c.pair);
        let x = scene.positions(v, &nodes, toi);
        let g = closest(&x, c.pair.is_vertex_triangle());
        let vn: f64 = (0..4)
            .map(|k| g.weights[k] * g.normal.dot(&scene.velocity(v, nodes[k])))
            .sum();
        // A small separating velocity: a quarter of the thickness over the step.
        let target = 0.25 * c.thickness.max(1e-9) / scene.h;
        if vn >= target {
            continue;
        }
        if let Some(dv) = impulse(
            scene,
            v,
            &nodes,
            &g.weights,
            &g.normal,
            target - vn,
            scene.friction_of(c.pair),
        ) {
            for k in 0..4 {
                if nodes[k] & super::OBSTACLE == 0 {
                    v[nodes[k] as usize] += dv[k];
                }
            }
            applied += 1;
        }
    }
    applied
}
