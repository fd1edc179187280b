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
//!
//! With AVX2, runs of four cloth pairs of one kind go through proximity's cheap rejection tests
//! in one register (module `rejection`): about three quarters are decided there (dormant or far, CCD
//! settled); the others continue on the scalar path from where the lanes stopped, with the
//! same verdicts and collisions as screening every pair on the scalar path.

use rayon::prelude::*;

use super::impulses::{self, Collision};
use super::proximity::{self, NearList, NodeStats, StartState};
use super::rejection::{self, Lanes, Row};
use super::{Pair, PairKind, Scene};
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
/// proximity repulsion is off, else `Some(within_reach)` (see [`proximity::repel_screened`]); without
/// `within_reach`, inert pairs stay dormant ([`proximity::Verdict::Dormant`]).
pub fn screen(
    scene: &Scene,
    v: &[Vec3],
    candidates: &[Pair],
    policy: &dyn ContactPolicy,
    proximity: Option<bool>,
) -> Screened {
    screen_with(scene, v, candidates, policy, proximity, Lanes::detect())
}

/// [`screen`], with proximity's cheap rejection tests four cloth pairs at a time when `lanes`
/// is given ([`rejection`]: the same verdicts as the scalar path, which takes every pair the
/// lanes leave undecided; without `lanes`, every pair).
fn screen_with(
    scene: &Scene,
    v: &[Vec3],
    candidates: &[Pair],
    policy: &dyn ContactPolicy,
    proximity: Option<bool>,
    lanes: Option<Lanes>,
) -> Screened {
    let table = VertexTable::new(scene, v);
    // The cloth pairs' thickness, when the policy gives all the same (asked once).
    let uniform = policy.uniform_cloth().map(super::thickness_of);
    let thickness = |p: Pair, cloth: bool| match uniform {
        Some(t) if cloth => t,
        _ => scene.thickness(p, policy),
    };
    // The lanes decide proximity's verdicts (and the CCD tests they settle).
    let lanes = lanes.zip(proximity.map(|within_reach| rejection::Settings {
        h: scene.h,
        ccd_ratio: scene.ccd_ratio,
        lazy: !within_reach,
    }));
    let chunks: Vec<Screened> = candidates
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut out = Screened {
                near: NearList::with_capacity(if proximity.is_some() { chunk.len() } else { 0 }),
                collisions: Vec::new(),
            };
            let mut rest = chunk;
            while let Some(&p) = rest.first() {
                let cloth = matches!(p.kind, PairKind::VertexTriangle | PairKind::EdgeEdge);
                if let (Some((lanes, settings)), Some(four)) = (lanes, rest.get(..4)) {
                    if cloth && four.iter().all(|q| q.kind == p.kind) {
                        let eps: [Option<f64>; 4] =
                            std::array::from_fn(|l| thickness(four[l], true));
                        let nodes: [[u32; 4]; 4] =
                            std::array::from_fn(|l| cloth_nodes(scene, four[l]));
                        let decided = match eps {
                            [Some(a), Some(b), Some(c), Some(d)] => {
                                if p.kind == PairKind::VertexTriangle {
                                    lanes.reject4::<true>(
                                        &table.rows,
                                        &nodes,
                                        [a, b, c, d],
                                        settings,
                                    )
                                } else {
                                    lanes.reject4::<false>(
                                        &table.rows,
                                        &nodes,
                                        [a, b, c, d],
                                        settings,
                                    )
                                }
                            }
                            _ => None,
                        };
                        if let Some(early) = decided {
                            for l in 0..4 {
                                let (q, nodes) = (four[l], &nodes[l]);
                                if early.decided >> l & 1 != 0 {
                                    if early.dormant >> l & 1 != 0 {
                                        out.near.push_dormant(q, *nodes);
                                    }
                                    continue;
                                }
                                // What `screen_pair` would pass on to the closest points.
                                let next = (early.closest >> l & 1 != 0).then(|| {
                                    let start = StartState {
                                        gap: early.gap[l],
                                        scale: early.scale[l],
                                        distance: None,
                                    };
                                    (start, early.ccd_settled >> l & 1 != 0)
                                });
                                let eps = eps[l].expect("a thickness");
                                one(scene, v, &table, q, eps, nodes, proximity, next, &mut out);
                            }
                            rest = &rest[4..];
                            continue;
                        }
                    }
                }
                rest = &rest[1..];
                if let Some(eps) = thickness(p, cloth) {
                    one(
                        scene,
                        v,
                        &table,
                        p,
                        eps,
                        &scene.nodes(p),
                        proximity,
                        None,
                        &mut out,
                    );
                }
            }
            out
        })
        .collect();
    let mut collisions = Vec::with_capacity(chunks.iter().map(|c| c.collisions.len()).sum());
    let mut near = Vec::with_capacity(chunks.len());
    for c in chunks {
        collisions.extend(c.collisions);
        near.push(c.near);
    }
    collisions.sort_unstable_by_key(|c| c.pair);
    Screened {
        near: NearList::concat(near),
        collisions,
    }
}

/// [`Scene::nodes`] of a cloth pair (vertex-triangle or edge-edge), inlined into the lanes'
/// loop.
#[inline(always)]
fn cloth_nodes(scene: &Scene, p: Pair) -> [u32; 4] {
    if p.kind == PairKind::VertexTriangle {
        let t = scene.triangles[p.b as usize];
        [p.a, t[0], t[1], t[2]]
    } else {
        debug_assert_eq!(p.kind, PairKind::EdgeEdge);
        let (e, f) = (scene.edges[p.a as usize], scene.edges[p.b as usize]);
        [e[0], e[1], f[0], f[1]]
    }
}

/// Screens one candidate `p` with thickness `eps` and nodes `nodes` on the scalar path:
/// proximity's verdict ([`proximity::screen_pair`], when `proximity` is on) and the CCD test
/// at the start velocities, added to `out`. `next`: when the lanes found the pair undecided by
/// every cheap test, the start state and CCD settlement they pass on to the closest points
/// ([`proximity::screen_closest`], a cloth pair with proximity on).
#[allow(clippy::too_many_arguments)]
#[inline]
fn one(
    scene: &Scene,
    v: &[Vec3],
    table: &VertexTable,
    p: Pair,
    eps: f64,
    nodes: &[u32; 4],
    proximity: Option<bool>,
    next: Option<(StartState, bool)>,
    out: &mut Screened,
) {
    let cloth = matches!(p.kind, PairKind::VertexTriangle | PairKind::EdgeEdge);
    let (x0, vel, stats) = if cloth {
        // Cloth nodes only: from the table.
        let rows = nodes.map(|k| &table.rows[k as usize]);
        (
            rows.map(|r| Vec3::from(r.x)),
            rows.map(|r| Vec3::from(r.v)),
            rows.map(|r| NodeStats {
                speed: r.speed,
                vel_max: r.vel_max,
                pos_max: r.pos_max,
            }),
        )
    } else {
        proximity::pair_inputs(scene, v, nodes)
    };
    let ccd_eps = eps * scene.ccd_ratio;
    let start = match proximity {
        Some(within_reach) => {
            let (verdict, start, ccd_settled) = if let Some((start, settled)) = next {
                proximity::screen_closest(scene, p, eps, nodes, &x0, &stats, start, settled)
            } else {
                proximity::screen_pair(
                    scene,
                    p,
                    eps,
                    nodes,
                    &x0,
                    &vel,
                    &stats,
                    !within_reach,
                    ccd_eps,
                )
            };
            out.near.push(p, verdict);
            if ccd_settled {
                return;
            }
            Some(start)
        }
        None => None,
    };
    if let Some(c) = impulses::detect_screened(scene, v, p, eps, nodes, &x0, start) {
        out.collisions.push(c);
    }
}

/// Per cloth vertex, its start position (as [`Scene::position`] gives it at `t = 0`), its
/// velocity and its [`NodeStats`] at the velocities of the pass: computed once instead of once
/// per pair of the vertex (a vertex is in dozens of candidate pairs), in the layout the lanes
/// gather from.
struct VertexTable {
    rows: Vec<Row>,
}

impl VertexTable {
    fn new(scene: &Scene, v: &[Vec3]) -> VertexTable {
        VertexTable {
            rows: (0..scene.x0.len())
                .into_par_iter()
                .with_min_len(1024)
                .map(|i| {
                    let x = scene.position(v, i as u32, 0.0);
                    let s = NodeStats::of(&x, &v[i]);
                    Row {
                        x: x.into(),
                        v: v[i].into(),
                        speed: s.speed,
                        vel_max: s.vel_max,
                        pos_max: s.pos_max,
                    }
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec2;
    use crate::mesh::Topology;
    use crate::sim::collision::broad::BroadPhase;
    use crate::sim::collision::obstacle_free_scene_for_tests as scene_of;
    use crate::sim::policy::UniformThickness;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// [`UniformThickness`] answered pair by pair, without [`ContactPolicy::uniform_cloth`].
    struct PerPair(UniformThickness);

    impl ContactPolicy for PerPair {
        fn max_thickness(&self) -> f64 {
            self.0.max_thickness()
        }
        fn vertex_triangle(&self, v: u32, t: u32) -> crate::sim::policy::Contact {
            self.0.vertex_triangle(v, t)
        }
        fn edge_edge(&self, a: u32, b: u32) -> crate::sim::policy::Contact {
            self.0.edge_edge(a, b)
        }
    }

    /// Oracle for [`screen`]'s CCD part: the collisions are exactly those of a plain CCD pass
    /// ([`impulses::detect`]) over the sorted candidates, bit for bit and in the same order,
    /// with proximity off, with lazy and with eager proximity screening, on crumpled sheets
    /// thrown at random velocities (many collisions); with the policy's uniform thickness
    /// asked once per pass (the default policy) and pair by pair (same lists); and screening
    /// with the lanes ([`rejection`]) gives the scalar path's verdicts and collisions, bit for
    /// bit.
    #[test]
    fn screened_collisions_are_those_of_a_full_ccd_pass() {
        let (mut total, mut lanes_used) = (0, false);
        for seed in 0..6u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let sheet = crate::scenes::handkerchief("s", 10, 11, 0.1, 0.1, |uv: Vec2| {
                Vec3::new(uv.x, 0.03 * (60.0 * uv.x).sin() * (45.0 * uv.y).cos(), uv.y)
            });
            let topo = Topology::new(&sheet).unwrap();
            let n = sheet.positions.len();
            let (hinge, inv_mass) = (vec![[u32::MAX; 3]; sheet.triangles.len()], vec![1.0; n]);
            let obstacles = Default::default();
            let scene = scene_of(
                &sheet.positions,
                &sheet.triangles,
                &topo.edges,
                &hinge,
                &obstacles,
                &inv_mass,
            );
            let swing = Vec3::new(0.5, -0.3, 0.2);
            let v: Vec<Vec3> = (0..n)
                .map(|_| {
                    swing
                        + Vec3::new(
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                        )
                })
                .collect();
            let policy = UniformThickness(2e-3);
            let margin = 2e-3 * 1.0001;
            let mut broad = BroadPhase::default();
            broad.update(&scene, &v, margin, true);
            let cands = broad.candidates(&scene, &v, margin);
            let mut sorted = cands.clone();
            sorted.sort_unstable();
            let want = impulses::detect(&scene, &v, &sorted, &policy, &|_: &[u32; 4]| false);
            total += want.len();
            for proximity in [None, Some(false), Some(true)] {
                let screened = screen(&scene, &v, &cands, &policy, proximity);
                // The scalar path alone (no lanes): the same verdicts, bit for bit, and the
                // same collisions.
                let scalar = screen_with(&scene, &v, &cands, &policy, proximity, None);
                assert_eq!(screened.near.fingerprint(), scalar.near.fingerprint());
                assert_eq!(screened.collisions.len(), scalar.collisions.len());
                for (a, b) in screened.collisions.iter().zip(&scalar.collisions) {
                    assert_eq!(a.pair, b.pair);
                    assert_eq!(a.toi.to_bits(), b.toi.to_bits());
                    assert_eq!(a.thickness.to_bits(), b.thickness.to_bits());
                }
                lanes_used |= proximity.is_some() && Lanes::detect().is_some();
                // The same policy asked pair by pair (not declared uniform): the same lists.
                let per_pair = screen(&scene, &v, &cands, &PerPair(policy), proximity);
                assert_eq!(screened.near.evaluated(), per_pair.near.evaluated());
                assert_eq!(screened.near.dormant(), per_pair.near.dormant());
                for got in [screened.collisions, per_pair.collisions] {
                    assert_eq!(got.len(), want.len(), "seed {seed} {proximity:?}");
                    for (a, b) in got.iter().zip(&want) {
                        assert_eq!(a.pair, b.pair, "seed {seed} {proximity:?}");
                        assert_eq!(a.toi.to_bits(), b.toi.to_bits(), "seed {seed}");
                        assert_eq!(a.thickness.to_bits(), b.thickness.to_bits());
                    }
                }
            }
        }
        assert!(total > 50, "{total} collisions: too few to test");
        assert!(lanes_used || Lanes::detect().is_none());
    }
}
