//! Iterated CCD impulses (Bridson et al. 2002, Sec. 7.3): CCD over the step for every candidate
//! pair with the pair's CCD thickness; each pair that CCD finds coming within it receives, in a
//! fixed order (Gauss-Seidel), an inelastic impulse along the closest-point normal at the time
//! of impact that leaves a small separating normal velocity.
//!
//! CCD thickness: `ccd_ratio` times the policy's thickness, but at most half the pair's start
//! distance (so pairs that begin in contact, or that a policy change left inside a larger
//! thickness, are not reported for ever, while they still can never meet).

use rayon::prelude::*;

use super::proximity::StartState;
use super::{closest, impulse, Pair, Scene};
use crate::geom::ccd::{edge_edge_impact, vertex_triangle_impact, CcdOptions};
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

/// Search budget of the inclusion-based CCD per query: beyond it the kernel answers
/// conservatively (an early time of impact), which at worst costs an extra impulse.
const CCD_OPTIONS: CcdOptions = CcdOptions {
    tolerance: 1e-6,
    max_boxes: 2000,
    ..CcdOptions::DEFAULT
};

/// Runs CCD on one pair with thickness `eps`: first conservative advancement with the Lipschitz
/// bound of the distance (it shrinks by at most the largest relative displacement of the pair's
/// vertices over the step), which settles most pairs with one or a few distance evaluations, then
/// the conservative inclusion-based kernel ([`crate::geom::ccd`]) on the rest of the step.
#[inline]
pub fn ccd(scene: &Scene, v: &[Vec3], p: Pair, eps: f64) -> Option<f64> {
    let nodes = scene.nodes(p);
    let x0 = scene.positions(v, &nodes, 0.0);
    let x1 = scene.positions(v, &nodes, 1.0);
    let vt = p.is_vertex_triangle();
    let d0 = distance(&x0, vt);
    ccd_with_start_distance(&x0, &x1, vt, eps, d0, relative_reach(&x0, &x1, vt))
}

/// The largest displacement of a node of one primitive relative to a node of the other over
/// the step: a Lipschitz bound of how much the pair's distance can shrink.
///
/// One square root of the largest squared displacement: the same bits as the `f64::max` fold
/// (from 0) of the displacements' norms, since a correctly rounded square root is monotone and
/// a NaN is skipped either way (test `relative_reach_equals_the_fold_of_norms`).
#[inline]
fn relative_reach(x0: &[Vec3; 4], x1: &[Vec3; 4], vt: bool) -> f64 {
    let d: [Vec3; 4] = [0, 1, 2, 3].map(|k| x1[k] - x0[k]);
    let q = |i: usize, j: usize| (d[i] - d[j]).norm_squared();
    // `m` is never NaN: `f64::max(m, c)` is `c` if `c > m`, else `m`.
    let max = |m: f64, c: f64| if c > m { c } else { m };
    let m = if vt {
        max(max(max(0.0, q(0, 1)), q(0, 2)), q(0, 3))
    } else {
        max(max(max(max(0.0, q(0, 2)), q(0, 3)), q(1, 2)), q(1, 3))
    };
    m.sqrt()
}

/// The distance of a pair's primitives at positions `x`: [`closest`]'s distance, bit for bit,
/// without its weights and normal (what conservative advancement and the start distance need).
#[inline]
fn distance(x: &[Vec3; 4], vt: bool) -> f64 {
    let d2 = if vt {
        crate::geom::distance::point_triangle(&x[0], &x[1], &x[2], &x[3]).0
    } else {
        crate::geom::distance::segment_segment(&x[0], &x[1], &x[2], &x[3]).0
    };
    d2.max(0.0).sqrt()
}

/// Conservative advancement from the start distance `d0` with the Lipschitz bound `reach`
/// ([`relative_reach`]), then the inclusion-based kernel on the rest of the step.
fn ccd_with_start_distance(
    x0: &[Vec3; 4],
    x1: &[Vec3; 4],
    vt: bool,
    eps: f64,
    d0: f64,
    reach: f64,
) -> Option<f64> {
    let scale = super::coordinate_scale(x0).max(super::coordinate_scale(x1));
    let slack = eps * 1e-9 + 1e-12 * scale;
    // Conservative advancement (Mirtich 1996): no contact can happen before
    // t + (d(t) - eps) / reach. It settles separating and slowly approaching pairs in a few
    // distance evaluations; whatever is left goes to the inclusion-based kernel from time t on.
    let mut t = 0.0;
    let mut d = d0;
    for _ in 0..16 {
        if d <= eps + 2.0 * slack {
            break;
        }
        if reach <= 0.0 {
            return None;
        }
        t += 0.999 * (d - eps - slack) / (reach * (1.0 + 1e-9));
        if t >= 1.0 {
            return None;
        }
        let xt: [Vec3; 4] = [0, 1, 2, 3].map(|k| x0[k] + (x1[k] - x0[k]) * t);
        d = distance(&xt, vt);
    }
    let xs: [Vec3; 4] = if t > 0.0 {
        [0, 1, 2, 3].map(|k| x0[k] + (x1[k] - x0[k]) * t)
    } else {
        *x0
    };
    let hit = if vt {
        vertex_triangle_impact(&xs, x1, eps, &CCD_OPTIONS)
    } else {
        edge_edge_impact(&xs, x1, eps, &CCD_OPTIONS)
    };
    hit.map(|i| t + i.toi * (1.0 - t))
}

/// The CCD thickness of a pair and its first time of impact, if any. The CCD thickness is
/// `min(ccd_ratio * thickness, d0 / 2)` with `d0` the start distance: a pair is never allowed
/// closer than half its start distance, so pairs that start in contact (or inside a thickness a
/// policy change just raised) are held apart without being reported for ever.
pub fn detect_pair(
    scene: &Scene,
    v: &[Vec3],
    p: Pair,
    policy: &dyn ContactPolicy,
) -> Option<Collision> {
    let thickness = scene.thickness(p, policy)?;
    let nodes = scene.nodes(p);
    let x0 = scene.positions(v, &nodes, 0.0);
    detect_screened(scene, v, p, thickness, &nodes, &x0, None)
}

/// [`detect_pair`] for a pair whose policy `thickness`, nodes and start positions `x0` are
/// known, and possibly what screening learnt about its start state (lower distance bound,
/// start distance: neither depends on the velocities).
pub fn detect_screened(
    scene: &Scene,
    v: &[Vec3],
    p: Pair,
    thickness: f64,
    nodes: &[u32; 4],
    x0: &[Vec3; 4],
    start: Option<StartState>,
) -> Option<Collision> {
    let eps_c = thickness * scene.ccd_ratio;
    let x1 = scene.positions(v, nodes, 1.0);
    let vt = p.is_vertex_triangle();
    let start = start.unwrap_or_else(|| StartState {
        gap: super::axis_gap(x0, vt),
        scale: super::coordinate_scale(x0),
        distance: None,
    });
    // The distance shrinks by at most the largest relative displacement of the pair's nodes
    // over the step (see `ccd_with_start_distance`): a start gap beyond it and eps_c settles
    // the pair without a closest-point computation (conservative advancement would settle it
    // in its first few steps).
    let reach = relative_reach(x0, &x1, vt);
    if super::gap_exceeds(start.gap, start.scale, eps_c + reach) {
        return None;
    }
    // The candidate boxes were inflated by the largest thickness of the policy; pairs farther
    // apart than their own CCD thickness over the whole step are shown so by the swept boxes
    // of the two primitives.
    if super::swept_apart(x0, &x1, vt, eps_c) {
        return None;
    }
    let d0 = start.distance.unwrap_or_else(|| distance(x0, vt));
    let eps = eps_c.min(0.5 * d0);
    let toi = ccd_with_start_distance(x0, &x1, vt, eps, d0, reach)?;
    Some(Collision {
        pair: p,
        toi,
        thickness: eps,
    })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::collision::coordinate_for_tests as coordinate;
    use proptest::prelude::*;

    fn v3(a: [f64; 3]) -> Vec3 {
        Vec3::new(a[0], a[1], a[2])
    }

    /// Plain oracle of [`relative_reach`]: the `f64::max` fold (from 0) of the norms of the
    /// relative displacements of the node pairs across the two primitives.
    fn plain_relative_reach(x0: &[Vec3; 4], x1: &[Vec3; 4], vt: bool) -> f64 {
        let d: [Vec3; 4] = [0, 1, 2, 3].map(|k| x1[k] - x0[k]);
        let split = if vt { 1 } else { 2 };
        let mut m = 0.0f64;
        for i in 0..split {
            for j in split..4 {
                m = m.max((d[i] - d[j]).norm());
            }
        }
        m
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// [`relative_reach`] (one square root of the largest squared displacement) gives the
        /// bits of the fold of norms, also with signed zeros, infinities and NaNs.
        #[test]
        fn relative_reach_equals_the_fold_of_norms(
            a in prop::array::uniform4(prop::array::uniform3(coordinate())),
            b in prop::array::uniform4(prop::array::uniform3(coordinate())),
            vt in any::<bool>(),
        ) {
            let (x0, x1) = (a.map(v3), b.map(v3));
            let got = relative_reach(&x0, &x1, vt);
            let want = plain_relative_reach(&x0, &x1, vt);
            prop_assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "{got} vs {want}");
        }

        /// [`distance`] is [`closest`]'s distance, bit for bit (random pairs, and pairs on
        /// a 2 mm lattice where coincident, parallel and touching primitives are common).
        #[test]
        fn distance_equals_the_closest_points_distance(
            a in prop::array::uniform4(prop::array::uniform3(coordinate())),
            lattice in prop::array::uniform4(prop::array::uniform3(-2i32..3)),
            on_lattice in any::<bool>(),
            vt in any::<bool>(),
        ) {
            let x = if on_lattice {
                lattice.map(|p| Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * 2e-3)
            } else {
                a.map(v3)
            };
            let got = distance(&x, vt);
            let want = closest(&x, vt).distance;
            prop_assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "{got} vs {want}");
        }
    }
}
