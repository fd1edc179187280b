//! Screening: one parallel pass over a step's broad-phase candidates at the velocities the
//! collision handling starts with, shared by proximity repulsion and the first CCD pass
//! (Bridson et al. 2002, Secs. 7.2-7.3, evaluate the same pairs at the same start state).
//!
//! Per candidate, the policy's thickness, the nodes and their start positions are loaded once;
//! proximity's verdict ([`proximity::screen_pair`]) and the CCD result at the start velocities
//! ([`impulses::detect_screened`]) are computed from them, the start distance (a closest-point
//! computation, independent of the velocities) at most once for both. The first CCD pass then
//! re-tests only the pairs with a vertex whose velocity proximity changed and reuses the
//! results of the others: the same pairs, the same results, in the same (sorted) order as
//! testing every candidate again.

use rayon::prelude::*;

use super::impulses::{self, Collision};
use super::proximity::{self, NearList};
use super::{Pair, Scene};
use crate::geom::Vec3;
use crate::sim::policy::ContactPolicy;

/// Candidates per parallel task (results are concatenated in candidate order).
const CHUNK: usize = 1024;

/// What screening found.
#[derive(Default)]
pub struct Screened {
    /// Proximity's pairs in candidate order (empty when proximity is off).
    pub near: NearList,
    /// Pairs that CCD finds colliding at the start velocities, sorted by pair (the order of a
    /// CCD pass over the sorted candidates).
    pub collisions: Vec<Collision>,
}

/// Screens `candidates` (without duplicates) at velocities `v`. `proximity`: `None` when
/// proximity repulsion is off, else `Some(within_reach)` (see [`proximity::repel`]); without
/// `within_reach`, inert pairs stay dormant ([`proximity::Verdict::Dormant`]).
pub fn screen(
    scene: &Scene,
    v: &[Vec3],
    candidates: &[Pair],
    policy: &dyn ContactPolicy,
    proximity: Option<bool>,
) -> Screened {
    let chunks: Vec<Screened> = candidates
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut out = Screened::default();
            for &p in chunk {
                let Some(eps) = scene.thickness(p, policy) else {
                    continue;
                };
                let nodes = scene.nodes(p);
                let x0 = scene.positions(v, &nodes, 0.0);
                let start = match proximity {
                    Some(within_reach) => {
                        let (verdict, start) =
                            proximity::screen_pair(scene, v, p, eps, &nodes, &x0, !within_reach);
                        out.near.push(p, verdict);
                        Some(start)
                    }
                    None => None,
                };
                if let Some(c) = impulses::detect_screened(scene, v, p, eps, &nodes, &x0, start) {
                    out.collisions.push(c);
                }
            }
            out
        })
        .collect();
    let mut all = Screened::default();
    for c in chunks {
        all.near.append(c.near);
        all.collisions.extend(c.collisions);
    }
    all.collisions.sort_unstable_by_key(|c| c.pair);
    all
}
