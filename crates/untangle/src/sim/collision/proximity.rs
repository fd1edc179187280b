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

/// How far the closest points of a pair (nodes `nodes`, closest-point weights `w`, summing to
/// zero) move relative to each other during the step: `|sum_k w_k v_k| h`. A common motion of
/// the whole pair does not count (the weights sum to zero), unlike the sum of absolute speeds.
#[inline]
pub fn relative_reach(scene: &Scene, v: &[Vec3], nodes: &[u32; 4], w: &[f64; 4]) -> f64 {
    (0..4)
        .fold(Vec3::zeros(), |a, k| a + scene.velocity(v, nodes[k]) * w[k])
        .norm()
        * scene.h
}

/// An upper bound of [`relative_reach`] for any weights of a pair (positive ones summing to 1,
/// negative ones to -1) without the closest points: `2 max_k |v_k - v_0| h`, since
/// `sum_k w_k v_k = sum_k w_k (v_k - v_0)` and `sum_k |w_k| = 2`.
#[inline]
pub fn relative_reach_bound(scene: &Scene, v: &[Vec3], nodes: &[u32; 4]) -> f64 {
    let v0 = scene.velocity(v, nodes[0]);
    let m = (1..4)
        .map(|k| (scene.velocity(v, nodes[k]) - v0).norm())
        .fold(0.0f64, f64::max);
    // Slack for rounding (the bound is compared with distances, never used as a reach).
    2.0 * m * scene.h * (1.0 + 1e-12)
}

/// Applies proximity impulses to `v`; returns the number of impulses applied and the cloth-cloth
/// pairs that started within twice their thickness or received an impulse, and with
/// `within_reach` also those that could come within it during the step (contacts the next step
/// treats inside the implicit solve, see [`crate::sim::contact`]).
///
/// A pair is *active* (considered for impulses) when its gap to the thickness is at most twice
/// its reach over the step. Without `within_reach` the reach is the relative motion of its
/// closest points ([`relative_reach`]); with it, as validated for the Cha & Ko loop, the sum of
/// the absolute speeds of its nodes (weighted), which also counts a common motion of the pair and
/// so makes nearly every candidate of fast cloth active.
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
                let vt = p.is_vertex_triangle();
                // Cheap rejection before the closest points: the reach below is at most
                // `reach_bound`, and the distance at least the gap of the boxes or spheres.
                let reach_bound = if within_reach {
                    // Absolute speeds (the Cha & Ko loop's validated setting, kept as it was):
                    // the fastest node of each primitive, times h.
                    let split = if vt { 1 } else { 2 };
                    let speed = |r: std::ops::Range<usize>| {
                        r.map(|k| scene.velocity(v, nodes[k]).norm())
                            .fold(0.0f64, f64::max)
                    };
                    (speed(0..split) + speed(split..4)) * h
                } else {
                    relative_reach_bound(scene, v, &nodes)
                };
                let far = (2.0 * eps).max(eps + 2.0 * reach_bound);
                if super::swept_apart(&x, &x, vt, far) || super::sphere_apart(&x, vt, far) {
                    return None;
                }
                let geom = closest(&x, vt);
                // Only pairs that could come within eps during the step matter.
                let reach = if within_reach {
                    (0..4)
                        .map(|k| geom.weights[k].abs() * scene.velocity(v, nodes[k]).norm())
                        .sum::<f64>()
                        * h
                } else {
                    relative_reach(scene, v, &nodes, &geom.weights)
                };
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::obstacle::Obstacles;
    use proptest::prelude::*;

    fn vec3(a: [f64; 3]) -> Vec3 {
        Vec3::new(a[0], a[1], a[2])
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// The relative reach is the displacement of the closest points over the step (oracle:
        /// the weighted sum of the end positions minus that of the start positions), ignores a
        /// common velocity of the pair, and never exceeds its closest-point-free bound.
        #[test]
        fn relative_reach_is_bounded_and_ignores_common_motion(
            p in prop::array::uniform4(prop::array::uniform3(-1.0f64..1.0)),
            vel in prop::array::uniform4(prop::array::uniform3(-3.0f64..3.0)),
            common in prop::array::uniform3(-50.0f64..50.0),
            vt in proptest::bool::ANY,
        ) {
            let x0: Vec<Vec3> = p.iter().map(|a| vec3(*a)).collect();
            let triangles = [[1u32, 2, 3]];
            let edges = [[0u32, 1], [2, 3]];
            let hinge = [[u32::MAX; 3]];
            let obstacles = Obstacles::default();
            let inv_mass = [1.0; 4];
            let scene = Scene {
                x0: &x0,
                h: 0.02,
                triangles: &triangles,
                edges: &edges,
                hinge: &hinge,
                obstacles: &obstacles,
                inv_mass: &inv_mass,
                friction: 0.0,
                ccd_ratio: 0.5,
            };
            let pair = if vt {
                Pair { kind: PairKind::VertexTriangle, a: 0, b: 0 }
            } else {
                Pair { kind: PairKind::EdgeEdge, a: 0, b: 1 }
            };
            let nodes = scene.nodes(pair);
            let v: Vec<Vec3> = vel.iter().map(|a| vec3(*a)).collect();
            let x = scene.positions(&v, &nodes, 0.0);
            let w = closest(&x, vt).weights;
            let reach = relative_reach(&scene, &v, &nodes, &w);
            // Oracle: displacement of the closest points, from positions at both ends.
            let x1 = scene.positions(&v, &nodes, 1.0);
            let at = |y: &[Vec3; 4]| (0..4).fold(Vec3::zeros(), |a, k| a + y[k] * w[k]);
            let moved = (at(&x1) - at(&x)).norm();
            prop_assert!((reach - moved).abs() <= 1e-9 * (1.0 + moved), "{} vs {}", reach, moved);
            prop_assert!(reach <= relative_reach_bound(&scene, &v, &nodes));
            // A common velocity of all four nodes changes neither.
            let shifted: Vec<Vec3> = v.iter().map(|a| a + vec3(common)).collect();
            let reach2 = relative_reach(&scene, &shifted, &nodes, &w);
            prop_assert!((reach2 - reach).abs() <= 1e-9 * (1.0 + vec3(common).norm()));
            let b1 = relative_reach_bound(&scene, &v, &nodes);
            let b2 = relative_reach_bound(&scene, &shifted, &nodes);
            prop_assert!((b1 - b2).abs() <= 1e-9 * (1.0 + vec3(common).norm()));
        }
    }
}
