//! Continuous collision handling (Bridson, Fedkiw & Anderson 2002; Harmon et al. 2008): a step
//! that starts free of intersections ends free of them.
//!
//! Pipeline of one step ([`handle`]): the broad phase finds candidate vertex-triangle and
//! edge-edge pairs from swept boxes ([`broad`]); proximity repulsion ([`proximity`]) makes close
//! or approaching pairs inelastic and pushes overlapping ones apart, with friction; iterated CCD
//! impulses ([`impulses`]) stop every pair that CCD still finds coming within its thickness;
//! rigid impact zones ([`impact_zones`]) are the fail-safe: zone by zone, colliding vertices
//! move as rigid bodies until CCD finds nothing. Every pair's thickness (or `Skip`) comes from
//! the [`ContactPolicy`].
//!
//! Cost: only the first pass looks at every candidate; later passes re-test the pairs of the
//! vertices whose velocity changed (queried from those vertices' primitives, see
//! [`broad::BroadPhase::candidates_of_changed`]) plus the pairs that still collided. Impulse
//! passes that stop making progress ([`STALL_PASSES`]) hand over to impact zones early.

pub mod broad;
pub mod impact_zones;
pub mod impulses;
pub mod proximity;
mod rejection;
pub mod screen;

use super::obstacle::Obstacles;
use super::policy::{Contact, ContactPolicy, ObstaclePair};
use crate::geom::Vec3;

/// CCD impulse passes in a row that do not lower the number of colliding pairs below its
/// minimum so far, after which impact zones take over before the impulse-pass cap.
pub const STALL_PASSES: usize = 3;

/// Flag marking an obstacle vertex in a node id (cloth vertices are plain indices).
pub const OBSTACLE: u32 = 1 << 31;

/// What two primitives a pair is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub enum PairKind {
    /// Cloth vertex `a`, cloth triangle `b`.
    VertexTriangle,
    /// Cloth edges `a`, `b`.
    EdgeEdge,
    /// Cloth vertex `a`, obstacle triangle `b`.
    VertexObstacle,
    /// Obstacle vertex `a`, cloth triangle `b`.
    ObstacleVertex,
    /// Cloth edge `a`, obstacle edge `b`.
    EdgeObstacleEdge,
}

/// A candidate pair of primitives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Pair {
    /// Kind.
    pub kind: PairKind,
    /// First primitive (vertex or edge).
    pub a: u32,
    /// Second primitive (triangle or edge).
    pub b: u32,
}

impl Pair {
    /// Whether the pair is a point and a triangle (else two edges).
    #[inline]
    pub fn is_vertex_triangle(&self) -> bool {
        !matches!(self.kind, PairKind::EdgeEdge | PairKind::EdgeObstacleEdge)
    }
}

/// The scene as collision handling sees it during one step: cloth start positions and
/// connectivity, obstacles (moving linearly over the step), inverse masses (0 = pinned).
pub struct Scene<'a> {
    /// Cloth positions at the start of the step.
    pub x0: &'a [Vec3],
    /// Step length.
    pub h: f64,
    /// Cloth triangles.
    pub triangles: &'a [[u32; 3]],
    /// Cloth edges.
    pub edges: &'a [[u32; 2]],
    /// Per cloth triangle, the vertex opposite each of its edges in the neighbouring triangle
    /// (`u32::MAX` on the boundary). Such hinge pairs ARE handled like any other: skipping them
    /// lets the vertex pass through the triangle and drag its other triangles (which share only
    /// a vertex with it) into an intersection.
    pub hinge: &'a [[u32; 3]],
    /// Obstacles.
    pub obstacles: &'a Obstacles,
    /// Inverse mass per cloth vertex (0 for pinned vertices).
    pub inv_mass: &'a [f64],
    /// Cloth-cloth friction coefficient.
    pub friction: f64,
    /// Fraction of a pair's thickness that CCD guarantees (proximity aims at the full one).
    pub ccd_ratio: f64,
}

impl Scene<'_> {
    /// The four nodes of a pair (`[p, a, b, c]` or `[ea0, ea1, eb0, eb1]`).
    #[inline]
    pub fn nodes(&self, p: Pair) -> [u32; 4] {
        let (a, b) = (p.a as usize, p.b as usize);
        match p.kind {
            PairKind::VertexTriangle => {
                let t = self.triangles[b];
                [p.a, t[0], t[1], t[2]]
            }
            PairKind::EdgeEdge => {
                let (e, f) = (self.edges[a], self.edges[b]);
                [e[0], e[1], f[0], f[1]]
            }
            PairKind::VertexObstacle => {
                let t = self.obstacles.triangles[b];
                [p.a, t[0] | OBSTACLE, t[1] | OBSTACLE, t[2] | OBSTACLE]
            }
            PairKind::ObstacleVertex => {
                let t = self.triangles[b];
                [p.a | OBSTACLE, t[0], t[1], t[2]]
            }
            PairKind::EdgeObstacleEdge => {
                let (e, f) = (self.edges[a], self.obstacles.edges[b]);
                [e[0], e[1], f[0] | OBSTACLE, f[1] | OBSTACLE]
            }
        }
    }

    /// Position of a node at fraction `t` of the step, cloth moving with velocity `v`.
    #[inline]
    pub fn position(&self, v: &[Vec3], node: u32, t: f64) -> Vec3 {
        if node & OBSTACLE != 0 {
            let i = (node & !OBSTACLE) as usize;
            let (s, e) = (&self.obstacles.start[i], &self.obstacles.end[i]);
            s + (e - s) * t
        } else {
            let i = node as usize;
            self.x0[i] + v[i] * (t * self.h)
        }
    }

    /// Velocity of a node over the step.
    #[inline]
    pub fn velocity(&self, v: &[Vec3], node: u32) -> Vec3 {
        if node & OBSTACLE != 0 {
            let i = (node & !OBSTACLE) as usize;
            (self.obstacles.end[i] - self.obstacles.start[i]) / self.h
        } else {
            v[node as usize]
        }
    }

    /// Inverse mass of a node (obstacles: 0).
    #[inline]
    pub fn inv_mass_of(&self, node: u32) -> f64 {
        if node & OBSTACLE != 0 {
            0.0
        } else {
            self.inv_mass[node as usize]
        }
    }

    /// The four node positions at fraction `t`.
    #[inline]
    pub fn positions(&self, v: &[Vec3], nodes: &[u32; 4], t: f64) -> [Vec3; 4] {
        nodes.map(|n| self.position(v, n, t))
    }

    /// The policy's thickness for a pair (`None` = skip).
    #[inline]
    pub fn thickness(&self, p: Pair, policy: &dyn ContactPolicy) -> Option<f64> {
        let c = match p.kind {
            PairKind::VertexTriangle => policy.vertex_triangle(p.a, p.b),
            PairKind::EdgeEdge => policy.edge_edge(p.a, p.b),
            PairKind::VertexObstacle => policy.obstacle(
                ObstaclePair::ClothVertex {
                    vertex: p.a,
                    triangle: p.b,
                },
                self.obstacle_thickness_of_triangle(p.b),
            ),
            PairKind::ObstacleVertex => policy.obstacle(
                ObstaclePair::ObstacleVertex {
                    vertex: p.a,
                    triangle: p.b,
                },
                self.obstacles.thickness_of_vertex(p.a),
            ),
            PairKind::EdgeObstacleEdge => policy.obstacle(
                ObstaclePair::EdgeEdge {
                    cloth_edge: p.a,
                    obstacle_edge: p.b,
                },
                self.obstacles
                    .thickness_of_vertex(self.obstacles.edges[p.b as usize][0]),
            ),
        };
        thickness_of(c)
    }

    fn obstacle_thickness_of_triangle(&self, t: u32) -> f64 {
        self.obstacles
            .thickness_of_vertex(self.obstacles.triangles[t as usize][0])
    }

    /// Friction coefficient of a pair.
    #[inline]
    pub fn friction_of(&self, p: Pair) -> f64 {
        match p.kind {
            PairKind::VertexTriangle | PairKind::EdgeEdge => self.friction,
            PairKind::VertexObstacle => self
                .obstacles
                .friction_of_vertex(self.obstacles.triangles[p.b as usize][0]),
            PairKind::ObstacleVertex => self.obstacles.friction_of_vertex(p.a),
            PairKind::EdgeObstacleEdge => self
                .obstacles
                .friction_of_vertex(self.obstacles.edges[p.b as usize][0]),
        }
    }
}

/// The thickness of a policy's decision (`None` = skip the pair): a finite, non-negative
/// thickness, anything else skips.
#[inline]
pub fn thickness_of(c: Contact) -> Option<f64> {
    match c {
        Contact::Skip => None,
        Contact::Thickness(t) if t.is_finite() && t >= 0.0 => Some(t),
        Contact::Thickness(_) => None,
    }
}

/// A coordinate for the collision code's bit-identity proptests: ordinary values, and now and
/// then a signed zero, a huge or tiny value, an infinity or a NaN.
#[cfg(test)]
pub(crate) fn coordinate_for_tests() -> impl proptest::strategy::Strategy<Value = f64> {
    use proptest::prelude::*;
    prop_oneof![
        8 => -3.0f64..3.0,
        1 => prop::sample::select(vec![
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e300,
            -1e-300,
        ]),
    ]
}

/// A cloth-only scene with `h = 0.02`, friction 0.1 and `ccd_ratio = 0.5` (unit tests).
#[cfg(test)]
pub(crate) fn obstacle_free_scene_for_tests<'a>(
    x0: &'a [Vec3],
    triangles: &'a [[u32; 3]],
    edges: &'a [[u32; 2]],
    hinge: &'a [[u32; 3]],
    obstacles: &'a Obstacles,
    inv_mass: &'a [f64],
) -> Scene<'a> {
    Scene {
        x0,
        h: 0.02,
        triangles,
        edges,
        hinge,
        obstacles,
        inv_mass,
        friction: 0.1,
        ccd_ratio: 0.5,
    }
}

/// Whether the two primitives of a pair (nodes `[p, a, b, c]` when `vt`, else two edges), moving
/// linearly from `x0` to `x1`, stay more than `d` apart during the whole step, as shown by their
/// swept axis-aligned boxes (a gap along one axis bounds the distance from below). Rounding is
/// covered by a relative slack, so `false` only means "maybe closer".
#[inline]
pub fn swept_apart(x0: &[Vec3; 4], x1: &[Vec3; 4], vt: bool, d: f64) -> bool {
    let split = if vt { 1 } else { 2 };
    let scale = coordinate_scale(x0).max(coordinate_scale(x1));
    let d = d * (1.0 + 1e-9) + 1e-12 * scale;
    for axis in 0..3 {
        let (mut lo_a, mut hi_a) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut lo_b, mut hi_b) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..4 {
            let (a, b) = (x0[k][axis], x1[k][axis]);
            let (lo, hi) = (a.min(b), a.max(b));
            if k < split {
                lo_a = lo_a.min(lo);
                hi_a = hi_a.max(hi);
            } else {
                lo_b = lo_b.min(lo);
                hi_b = hi_b.max(hi);
            }
        }
        if lo_b - hi_a > d || lo_a - hi_b > d {
            return true;
        }
    }
    false
}

/// A lower bound of the distance between the two primitives of a pair (nodes `[p, a, b, c]`
/// when `vt`, else two edges) at positions `x`, from bounding spheres: the vertex's distance
/// to the triangle's centroid minus the triangle's circumradius about it, or the distance
/// between the edges' midpoints minus their half-lengths. Unlike axis-aligned boxes it is tight
/// for neighbouring primitives on an oblique surface, the bulk of the swept-box candidates.
#[inline]
pub fn sphere_gap(x: &[Vec3; 4], vt: bool) -> f64 {
    if vt {
        let c = (x[1] + x[2] + x[3]) / 3.0;
        let r = (x[1] - c)
            .norm_squared()
            .max((x[2] - c).norm_squared())
            .max((x[3] - c).norm_squared())
            .sqrt();
        (x[0] - c).norm() - r
    } else {
        let (m1, m2) = ((x[0] + x[1]) * 0.5, (x[2] + x[3]) * 0.5);
        (m1 - m2).norm() - 0.5 * ((x[1] - x[0]).norm() + (x[3] - x[2]).norm())
    }
}

/// A lower bound of the distance between the two primitives of a pair (nodes `[p, a, b, c]`
/// when `vt`, else two edges) at positions `x`, from two separating axes: the projections of
/// the primitives onto the axis through their centres (vertex and triangle centroid, or the
/// edges' midpoints) and onto the normal of the triangle's plane (or the common normal of the
/// edges' lines) cannot be closer than the primitives. At least [`sphere_gap`] (a projection is
/// never longer than the segment it projects), and much tighter for neighbouring primitives
/// side by side on one smooth sheet, the bulk of the swept-box candidates: two opposite edges
/// of a quad have a sphere gap of zero but an axis gap of the quad's width.
#[inline]
pub fn axis_gap(x: &[Vec3; 4], vt: bool) -> f64 {
    centre_gap(x, vt).max(normal_gap(x, vt))
}

/// The separating-axis bound of [`axis_gap`] along the axis through the primitives' centres
/// alone (the one that separates neighbours on a sheet).
#[inline]
pub fn centre_gap(x: &[Vec3; 4], vt: bool) -> f64 {
    if vt {
        separation_along(x, 1, &(x[0] - (x[1] + x[2] + x[3]) / 3.0))
    } else {
        separation_along(x, 2, &((x[2] + x[3] - x[0] - x[1]) * 0.5))
    }
}

/// The separating-axis bound of [`axis_gap`] along the triangle's normal (or the edges'
/// common normal) alone (the one that separates stacked layers).
#[inline]
pub fn normal_gap(x: &[Vec3; 4], vt: bool) -> f64 {
    if vt {
        separation_along(x, 1, &(x[2] - x[1]).cross(&(x[3] - x[1])))
    } else {
        separation_along(x, 2, &(x[1] - x[0]).cross(&(x[3] - x[2])))
    }
}

/// The gap between the projections onto the direction `u` of nodes `x[..split]` and
/// `x[split..]` (a lower bound of the distance of their convex hulls for any `u`, computed for
/// the `u` actually given, so rounding in `u` does not matter); `-inf` for `u = 0`.
#[inline]
fn separation_along(x: &[Vec3; 4], split: usize, u: &Vec3) -> f64 {
    let l = u.norm();
    if l == 0.0 || !l.is_finite() {
        return f64::NEG_INFINITY;
    }
    let (mut lo_a, mut hi_a) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut lo_b, mut hi_b) = (f64::INFINITY, f64::NEG_INFINITY);
    for (k, p) in x.iter().enumerate() {
        let s = (p - x[0]).dot(u);
        if k < split {
            lo_a = lo_a.min(s);
            hi_a = hi_a.max(s);
        } else {
            lo_b = lo_b.min(s);
            hi_b = hi_b.max(s);
        }
    }
    (lo_b - hi_a).max(lo_a - hi_b) / l
}

/// Largest absolute coordinate of the four nodes (the scale of rounding errors).
#[inline]
pub fn coordinate_scale(x: &[Vec3; 4]) -> f64 {
    abs_max(x)
}

/// The largest absolute coordinate of four vectors, at least 0: the same bits as
/// `x.iter().fold(0.0, |m, p| m.max(p.amax()))` for any input (nalgebra's `amax` compares
/// `a >= |c|` coordinate by coordinate, so a NaN after the first coordinate makes it NaN,
/// which the fold then skips), with plain comparisons instead of `f64::max`'s NaN selects.
#[inline]
pub fn abs_max(x: &[Vec3; 4]) -> f64 {
    max_of_abs_maxes(&x.map(|p| vec_abs_max(&p)))
}

/// One vector's part of [`abs_max`]: nalgebra's `amax` (`a >= |c|` coordinate by coordinate;
/// a NaN after the first coordinate makes it NaN).
#[inline(always)]
pub fn vec_abs_max(p: &Vec3) -> f64 {
    let mut a = p.x.abs();
    for c in [p.y.abs(), p.z.abs()] {
        a = if a >= c { a } else { c };
    }
    a
}

/// [`abs_max`] from the four vectors' [`vec_abs_max`] (e.g. tabulated per vertex): the fold from
/// 0 with `f64::max`, NaNs skipped.
#[inline(always)]
pub fn max_of_abs_maxes(a: &[f64; 4]) -> f64 {
    let mut m = 0.0f64;
    for &a in a {
        // `m` is never NaN: `f64::max(m, a)` is `a` if `a > m`, else `m`.
        if a > m {
            m = a;
        }
    }
    m
}

/// Whether a lower distance bound `gap` ([`axis_gap`]) of nodes with [`coordinate_scale`]
/// `scale` shows the pair farther apart than `d`, with a relative slack for rounding (so `false`
/// only means "maybe closer").
#[inline]
pub fn gap_exceeds(gap: f64, scale: f64, d: f64) -> bool {
    gap > d * (1.0 + 1e-9) + 1e-9 * scale
}

/// Whether [`axis_gap`] shows the pair farther apart than `d` (with a relative slack for
/// rounding, so `false` only means "maybe closer").
#[inline]
pub fn gap_apart(x: &[Vec3; 4], vt: bool, d: f64) -> bool {
    gap_exceeds(axis_gap(x, vt), coordinate_scale(x), d)
}

/// Closest-point geometry of a pair at one instant.
#[derive(Clone, Copy, Debug)]
pub struct Closest {
    /// Distance.
    pub distance: f64,
    /// Unit normal from the second primitive towards the first.
    pub normal: Vec3,
    /// Weights: the relative vector is `sum_k w[k] x_k` (first minus second primitive).
    pub weights: [f64; 4],
}

/// Closest points of a vertex-triangle (`vt`) or edge-edge pair with node positions `x`.
pub fn closest(x: &[Vec3; 4], vt: bool) -> Closest {
    let (d2, w, fallback) = if vt {
        let (d2, b) = crate::geom::distance::point_triangle(&x[0], &x[1], &x[2], &x[3]);
        let n = (x[2] - x[1]).cross(&(x[3] - x[1]));
        (d2, [1.0, -b[0], -b[1], -b[2]], n)
    } else {
        let (d2, s, t) = crate::geom::distance::segment_segment(&x[0], &x[1], &x[2], &x[3]);
        let (e, f) = (x[1] - x[0], x[3] - x[2]);
        let mut n = e.cross(&f);
        if n.norm_squared() <= 1e-24 * e.norm_squared() * f.norm_squared() {
            // Parallel edges: any direction orthogonal to the first.
            let a = if e.x.abs() < e.y.abs() {
                Vec3::x()
            } else {
                Vec3::y()
            };
            n = e.cross(&a);
        }
        (d2, [1.0 - s, s, -(1.0 - t), -t], n)
    };
    let r = x[0] * w[0] + x[1] * w[1] + x[2] * w[2] + x[3] * w[3];
    let distance = d2.max(0.0).sqrt();
    let rn = r.norm();
    let normal = if rn > 1e-14 * (1.0 + x[0].amax()) {
        r / rn
    } else {
        let l = fallback.norm();
        if l > 0.0 {
            fallback / l
        } else {
            Vec3::z()
        }
    };
    Closest {
        distance,
        normal,
        weights: w,
    }
}

/// Applies the impulse that raises the relative normal velocity of a pair by `dvn` (>= 0) along
/// `n`, with Coulomb friction `mu` reducing the tangential relative velocity by up to
/// `mu * dvn`; returns the velocity change of each node (zero for infinite mass), or `None`
/// when every node has infinite mass.
pub fn impulse(
    scene: &Scene,
    v: &[Vec3],
    nodes: &[u32; 4],
    w: &[f64; 4],
    n: &Vec3,
    dvn: f64,
    mu: f64,
) -> Option<[Vec3; 4]> {
    let im = nodes.map(|k| scene.inv_mass_of(k));
    let denom: f64 = (0..4).map(|k| w[k] * w[k] * im[k]).sum();
    if denom <= 0.0 {
        return None;
    }
    let j = dvn / denom;
    let rel: Vec3 = (0..4).fold(Vec3::zeros(), |a, k| a + scene.velocity(v, nodes[k]) * w[k]);
    let vt = rel - n * n.dot(&rel);
    let vtn = vt.norm();
    let tangential = if vtn > 0.0 && mu > 0.0 {
        let dt = (mu * dvn).min(vtn);
        vt * (-(dt / vtn) / denom)
    } else {
        Vec3::zeros()
    };
    let jv = n * j + tangential;
    Some([0, 1, 2, 3].map(|k| jv * (w[k] * im[k])))
}

/// Iteration caps and settings of the collision handling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionSettings {
    /// CCD impulse passes before impact zones take over.
    pub max_impulse_iterations: usize,
    /// Impact-zone passes before the fail-safe stops all cloth motion for the step.
    pub max_zone_iterations: usize,
    /// Run proximity repulsion first.
    pub proximity: bool,
    /// Resting contacts also include pairs merely within reach of the step's motion (see
    /// [`crate::sim::SimParams::contacts_within_reach`]).
    pub contacts_within_reach: bool,
    /// Rebuild the broad-phase hierarchies this step (else refit).
    pub rebuild: bool,
    /// How a free impact zone moves ([`impact_zones::ZoneMotion`]).
    pub zone_motion: impact_zones::ZoneMotion,
}

/// What the collision handling of one step did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct CollisionReport {
    /// Candidate pairs of the first broad-phase pass.
    pub candidates: usize,
    /// Pairs that received a proximity impulse.
    pub proximity_impulses: usize,
    /// CCD passes run (impulse passes plus zone passes).
    pub iterations: usize,
    /// Colliding pairs CCD found in the first impulse pass.
    pub first_pass_collisions: usize,
    /// CCD impulses applied.
    pub impulses: usize,
    /// Impact-zone passes run.
    pub zone_iterations: usize,
    /// Impact zones at the end.
    pub impact_zones: usize,
    /// Cloth vertices inside impact zones.
    pub zone_vertices: usize,
    /// The zone cap was reached and all cloth motion of the step was cancelled.
    pub stalled: bool,
    /// Collisions were still found at the end (only possible when moving obstacles pinch the
    /// cloth): the step ends with an administrative quit (Cha & Ko 2022, Sec. 1).
    pub administrative_quit: bool,
    /// Colliding pairs left at the end (0 unless administrative quit).
    pub remaining_collisions: usize,
    /// Milliseconds in broad phase, proximity, CCD impulses and impact zones.
    pub timing: CollisionTiming,
    /// Cloth-cloth pairs in (or approaching) contact during the step, in candidate order; the
    /// next step's implicit solve includes those still approaching.
    #[serde(skip)]
    pub resting: Vec<Pair>,
}

/// Wall-clock milliseconds per phase of the collision handling.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CollisionTiming {
    /// Box updates, hierarchy refits and traversals.
    pub broad: f64,
    /// Proximity repulsion.
    pub proximity: f64,
    /// CCD and impulses.
    pub impulses: f64,
    /// Impact zones (CCD passes and rigidification).
    pub zones: f64,
}

/// Runs the whole collision handling of one step on the cloth velocities `v` (modified in
/// place): afterwards, moving every cloth vertex from `scene.x0` along `v` for the step keeps an
/// intersection-free start intersection-free, unless the report says administrative quit.
pub fn handle(
    scene: &Scene,
    v: &mut [Vec3],
    policy: &dyn ContactPolicy,
    settings: CollisionSettings,
    broad: &mut broad::BroadPhase,
) -> CollisionReport {
    use std::time::Instant;
    let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
    let mut rep = CollisionReport::default();
    let margin = policy.max_thickness().max(scene.obstacles.max_thickness()) * 1.0001 + 1e-12;
    let no_skip = |_: &[u32; 4]| false;

    let t = Instant::now();
    broad.update(scene, v, margin, settings.rebuild);
    let cands = broad.candidates(scene, v, margin);
    rep.candidates = cands.len();
    rep.timing.broad += ms(t);
    let t = Instant::now();
    let n = scene.x0.len();
    let v_start = v.to_vec();
    // Proximity's verdicts and the first CCD pass's tests at the start velocities, in one pass.
    let screened = screen::screen(
        scene,
        v,
        &cands,
        policy,
        settings.proximity.then_some(settings.contacts_within_reach),
    );
    if settings.proximity {
        let (applied, resting) = proximity::repel_screened(
            scene,
            v,
            &v_start,
            screened.near,
            policy,
            settings.contacts_within_reach,
        );
        rep.proximity_impulses = applied;
        rep.resting = resting;
    }
    rep.timing.proximity += ms(t);

    // Only pairs with a vertex whose velocity changed since the last CCD pass, or that
    // collided in it, can collide now; everything else was already found free. The first pass
    // reuses the screening's results for the candidates whose vertices proximity left alone
    // (same boxes, same velocities), and tests the pairs of the vertices it changed, queried
    // afresh.
    let mut changed: Vec<bool> = (0..n).map(|i| v[i] != v_start[i]).collect();
    let mut first = Some(screened.collisions);
    drop(cands);
    let mut previous: Vec<Pair> = Vec::new();
    // Few changed vertices: query from them (see `BroadPhase::candidates_of_changed`) and add
    // the previous pass's colliding pairs that none of them touches; many: filter everything.
    let select =
        |broad: &broad::BroadPhase, v: &[Vec3], changed: &[bool], previous: &[Pair]| -> Vec<Pair> {
            let touched = |p: &Pair| {
                scene
                    .nodes(*p)
                    .iter()
                    .any(|&k| k & OBSTACLE == 0 && changed[k as usize])
            };
            let count = changed.iter().filter(|&&c| c).count();
            if count * 4 > n {
                return broad
                    .candidates(scene, v, margin)
                    .into_iter()
                    .filter(|p| touched(p) || previous.binary_search(p).is_ok())
                    .collect();
            }
            let mut out = broad.candidates_of_changed(scene, v, margin, changed);
            out.extend(previous.iter().filter(|p| !touched(p)));
            out.sort_unstable();
            out.dedup();
            out
        };
    // The CCD collisions of one pass (impulse or zone pass), in the order of its candidates;
    // `skip` leaves out pairs inside one rigid impact zone. The broad-phase part is timed into
    // `broad`.
    let pass_collisions = |broad: &broad::BroadPhase,
                           v: &[Vec3],
                           changed: &[bool],
                           previous: &[Pair],
                           first: &mut Option<Vec<impulses::Collision>>,
                           skip: &(dyn Fn(&[u32; 4]) -> bool + Sync),
                           broad_ms: &mut f64|
     -> Vec<impulses::Collision> {
        let tb = Instant::now();
        match first.take() {
            Some(screened) if 4 * changed.iter().filter(|&&c| c).count() <= n => {
                let untouched = |p: &Pair| {
                    scene
                        .nodes(*p)
                        .iter()
                        .all(|&k| k & OBSTACLE != 0 || !changed[k as usize])
                };
                let fresh = broad.candidates_of_changed(scene, v, margin, changed);
                *broad_ms += ms(tb);
                let mut cols = impulses::detect(scene, v, &fresh, policy, skip);
                cols.extend(
                    screened
                        .into_iter()
                        .filter(|c| untouched(&c.pair) && !skip(&scene.nodes(c.pair))),
                );
                cols.sort_unstable_by_key(|c| c.pair);
                cols
            }
            Some(_) => {
                let cands = broad.candidates(scene, v, margin);
                *broad_ms += ms(tb);
                impulses::detect(scene, v, &cands, policy, skip)
            }
            None => {
                let cands = select(broad, v, changed, previous);
                *broad_ms += ms(tb);
                impulses::detect(scene, v, &cands, policy, skip)
            }
        }
    };
    let (mut fewest, mut no_progress) = (usize::MAX, 0);
    for it in 0..settings.max_impulse_iterations {
        let t = Instant::now();
        broad.update_changed(scene, v, margin, &changed);
        rep.timing.broad += ms(t);
        let t = Instant::now();
        let mut broad_ms = 0.0;
        let cols = pass_collisions(
            broad,
            v,
            &changed,
            &previous,
            &mut first,
            &no_skip,
            &mut broad_ms,
        );
        rep.timing.broad += broad_ms;
        rep.iterations += 1;
        if it == 0 {
            rep.first_pass_collisions = cols.len();
        }
        if cols.is_empty() {
            rep.timing.impulses += ms(t) - broad_ms;
            return rep;
        }
        let before = v.to_vec();
        rep.impulses += impulses::resolve(scene, v, &cols);
        for i in 0..n {
            changed[i] = v[i] != before[i];
        }
        previous = cols.iter().map(|c| c.pair).collect();
        previous.sort_unstable();
        rep.timing.impulses += ms(t) - broad_ms;
        // Impulses that keep chasing the same few pairs (a vertex trapped in a closing fold, a
        // tangled spot the policy still guards) do not converge: hand over to impact zones.
        if cols.len() < fewest {
            fewest = cols.len();
            no_progress = 0;
        } else {
            no_progress += 1;
            if no_progress >= STALL_PASSES {
                break;
            }
        }
    }

    let t = Instant::now();
    let mut zones = impact_zones::Zones::new(n);
    let v_zone_start = v.to_vec();
    let mut done = false;
    for _ in 0..settings.max_zone_iterations {
        let tb = Instant::now();
        broad.update_changed(scene, v, margin, &changed);
        rep.timing.broad += ms(tb);
        let skip = |nodes: &[u32; 4]| zones.same_zone(nodes);
        let mut broad_ms = 0.0;
        let cols = pass_collisions(
            broad,
            v,
            &changed,
            &previous,
            &mut first,
            &skip,
            &mut broad_ms,
        );
        rep.timing.broad += broad_ms;
        rep.iterations += 1;
        rep.zone_iterations += 1;
        if cols.is_empty() {
            done = true;
            break;
        }
        for c in &cols {
            zones.merge(scene, v, &scene.nodes(c.pair));
        }
        let before = v.to_vec();
        zones.rigidify(scene, v, &v_zone_start, settings.zone_motion);
        for i in 0..n {
            changed[i] = v[i] != before[i];
        }
        previous = cols.iter().map(|c| c.pair).collect();
        previous.sort_unstable();
    }
    let (count, verts) = zones.stats();
    rep.impact_zones = count;
    rep.zone_vertices = verts;
    if !done {
        // Fail-safe: the start state is intersection-free, so keeping every cloth vertex where
        // it is keeps it so; only moving obstacles can still collide.
        rep.stalled = true;
        v.iter_mut().for_each(|x| *x = Vec3::zeros());
        let tb = Instant::now();
        broad.update(scene, v, margin, false);
        let cands = broad.candidates(scene, v, margin);
        rep.timing.broad += ms(tb);
        let cols = impulses::detect(scene, v, &cands, policy, &no_skip);
        rep.iterations += 1;
        rep.remaining_collisions = cols.len();
        rep.administrative_quit = !cols.is_empty();
    }
    rep.timing.zones += ms(t);
    rep
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec2;
    use crate::mesh::Topology;
    use crate::sim::obstacle::Obstacle;
    use crate::sim::policy::UniformThickness;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn rand_vec(rng: &mut ChaCha8Rng, s: f64) -> Vec3 {
        Vec3::new(
            rng.random_range(-s..s),
            rng.random_range(-s..s),
            rng.random_range(-s..s),
        )
    }

    /// Oracle for [`BroadPhase::candidates_of_changed`]: the full candidate list filtered to
    /// pairs with a changed cloth vertex, on a crumpled sheet with a floor obstacle, random
    /// velocities and random changed sets (including after an incremental box update).
    #[test]
    fn candidates_of_changed_match_the_filtered_full_list() {
        for seed in 0..6u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let sheet = crate::scenes::handkerchief("s", 12, 12, 0.2, 0.2, |uv: Vec2| {
                Vec3::new(uv.x, 0.02 * (40.0 * uv.x).sin() * (30.0 * uv.y).cos(), uv.y)
            });
            let floor = crate::scenes::handkerchief("f", 6, 6, 0.3, 0.3, |uv: Vec2| {
                Vec3::new(uv.x, -0.01 + 0.005 * uv.y, uv.y)
            });
            let mut obstacles = Obstacles::default();
            obstacles
                .add(Obstacle::from_mesh(&floor, 2e-3, 0.1).unwrap())
                .unwrap();
            let topo = Topology::new(&sheet).unwrap();
            let hinge = vec![[u32::MAX; 3]; sheet.triangles.len()];
            let n = sheet.positions.len();
            let x0: Vec<Vec3> = sheet
                .positions
                .iter()
                .map(|p| p + rand_vec(&mut rng, 2e-3))
                .collect();
            let inv_mass = vec![1.0; n];
            let scene = Scene {
                x0: &x0,
                h: 0.02,
                triangles: &sheet.triangles,
                edges: &topo.edges,
                hinge: &hinge,
                obstacles: &obstacles,
                inv_mass: &inv_mass,
                friction: 0.1,
                ccd_ratio: 0.5,
            };
            let margin = UniformThickness(3e-3).max_thickness();
            let mut v: Vec<Vec3> = (0..n).map(|_| rand_vec(&mut rng, 0.6)).collect();
            let mut broad = broad::BroadPhase::default();
            broad.update(&scene, &v, margin, true);
            for round in 0..4 {
                let frac = [0.02, 0.1, 0.2, 0.5][round];
                let changed: Vec<bool> = (0..n).map(|_| rng.random_bool(frac)).collect();
                if round > 0 {
                    // New velocities on the changed vertices only, boxes updated incrementally.
                    for i in 0..n {
                        if changed[i] {
                            v[i] = rand_vec(&mut rng, 0.6);
                        }
                    }
                    broad.update_changed(&scene, &v, margin, &changed);
                }
                let mut want: Vec<Pair> = broad
                    .candidates(&scene, &v, margin)
                    .into_iter()
                    .filter(|p| {
                        scene
                            .nodes(*p)
                            .iter()
                            .any(|&k| k & OBSTACLE == 0 && changed[k as usize])
                    })
                    .collect();
                want.sort_unstable();
                let got = broad.candidates_of_changed(&scene, &v, margin, &changed);
                assert_eq!(got, want, "seed {seed} round {round}");
                assert!(!want.is_empty());
                // The incrementally updated hierarchy gives what a fresh one gives.
                let mut fresh = broad::BroadPhase::default();
                fresh.update(&scene, &v, margin, true);
                let mut a = fresh.candidates(&scene, &v, margin);
                let mut b = broad.candidates(&scene, &v, margin);
                a.sort_unstable();
                b.sort_unstable();
                assert_eq!(a, b, "seed {seed} round {round}");
            }
        }
    }

    /// Oracle for [`sphere_gap`]: never above the closest-point distance, and close to it for
    /// far pairs (not vacuous).
    #[test]
    fn sphere_gap_is_a_lower_bound_of_the_distance() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut tight = 0;
        for case in 0..20000 {
            let vt = case % 2 == 0;
            let spread = rng.random_range(0.001..0.3);
            let offset = rand_vec(&mut rng, 1.0);
            let x: [Vec3; 4] = std::array::from_fn(|k| {
                let o = if (vt && k == 0) || (!vt && k < 2) {
                    offset
                } else {
                    Vec3::zeros()
                };
                o + rand_vec(&mut rng, spread)
            });
            let d = closest(&x, vt).distance;
            let g = sphere_gap(&x, vt);
            assert!(g <= d + 1e-12, "case {case}: gap {g} > distance {d}");
            let a = axis_gap(&x, vt);
            assert!(a <= d + 1e-12, "case {case}: axis gap {a} > distance {d}");
            assert!(a >= g - 1e-12, "case {case}: axis gap {a} < sphere gap {g}");
            if g > 0.5 * d {
                tight += 1;
            }
            if gap_apart(&x, vt, 0.01) {
                assert!(d > 0.01, "case {case}");
            }
        }
        assert!(tight > 5000, "{tight}");
    }

    mod axis_gap_props {
        use super::super::{axis_gap, closest, coordinate_scale, gap_exceeds};
        use crate::geom::Vec3;
        use proptest::prelude::*;

        fn v3(a: [f64; 3]) -> Vec3 {
            Vec3::new(a[0], a[1], a[2])
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(3000))]
            /// Oracle for [`axis_gap`] on adversarial input (coplanar, parallel, degenerate
            /// and far-offset primitives): never above the closest-point distance, and
            /// `gap_exceeds` never claims a pair farther than it is.
            #[test]
            fn axis_gap_never_exceeds_the_distance(
                vt in any::<bool>(),
                x in prop::array::uniform4(prop::array::uniform3(-1.0f64..1.0)),
                flat in 0usize..4,
                offset in prop::array::uniform3(-100.0f64..100.0),
                d in 0.0f64..0.5,
            ) {
                let o = v3(offset);
                let mut x = x.map(|a| v3(a) + o);
                match flat {
                    // All four in one plane (neighbours on a flat sheet).
                    1 => x.iter_mut().for_each(|p| p.z = o.z),
                    // Parallel edges / a vertex on the triangle's edge line.
                    2 => { let e = x[1] - x[0]; x[3] = x[2] + e * 0.7; }
                    // A degenerate (collinear) triangle or zero-length edge.
                    3 => { x[3] = x[1] + (x[2] - x[1]) * 0.3; x[1] = x[0] + (x[1] - x[0]) * 1e-12; }
                    _ => {}
                }
                let dist = closest(&x, vt).distance;
                let g = axis_gap(&x, vt);
                prop_assert!(g <= dist + 1e-12 * (1.0 + o.amax()), "gap {} > distance {}", g, dist);
                if gap_exceeds(g, coordinate_scale(&x), d) {
                    prop_assert!(dist > d);
                }
            }
        }

        /// Not vacuous: on a flat grid, the axis gap of neighbouring primitives that are not
        /// adjacent is most of their distance (the sphere gap of two opposite quad edges is 0).
        #[test]
        fn axis_gap_is_tight_for_neighbours_on_a_sheet() {
            let q = |x: f64, y: f64| Vec3::new(x, y, 0.0);
            // Opposite edges of a unit quad.
            let ee = [q(0.0, 0.0), q(1.0, 0.0), q(0.0, 1.0), q(1.0, 1.0)];
            assert!((axis_gap(&ee, false) - 1.0).abs() < 1e-12);
            assert!(super::super::sphere_gap(&ee, false) <= 1e-12);
            // A vertex one cell beyond a triangle's edge.
            let vt = [q(0.5, 2.0), q(0.0, 0.0), q(1.0, 0.0), q(0.0, 1.0)];
            let dist = closest(&vt, true).distance;
            assert!(
                axis_gap(&vt, true) > 0.6 * dist,
                "{} vs {dist}",
                axis_gap(&vt, true)
            );
        }
    }

    /// Oracle for [`swept_apart`]: whenever it says apart, the distance sampled along the step
    /// (closest points at 201 instants) stays above `d`; and it does say so for well separated
    /// pairs (not vacuous).
    #[test]
    fn swept_apart_never_hides_a_close_approach() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (mut apart, mut maybe) = (0, 0);
        for case in 0..4000 {
            let vt = case % 2 == 0;
            let spread = rng.random_range(0.01..0.2);
            let x0: [Vec3; 4] = std::array::from_fn(|_| rand_vec(&mut rng, spread));
            let x1: [Vec3; 4] = std::array::from_fn(|k| x0[k] + rand_vec(&mut rng, 0.05));
            let d = rng.random_range(0.0..0.03);
            if swept_apart(&x0, &x1, vt, d) {
                apart += 1;
                for s in 0..=200 {
                    let t = s as f64 / 200.0;
                    let x: [Vec3; 4] = std::array::from_fn(|k| x0[k] + (x1[k] - x0[k]) * t);
                    let dist = closest(&x, vt).distance;
                    assert!(dist > d, "case {case}: distance {dist} <= {d} at t = {t}");
                }
            } else {
                maybe += 1;
            }
        }
        assert!(apart > 500 && maybe > 500, "apart {apart}, maybe {maybe}");
    }

    /// Impact zones alone (no proximity, no impulse passes) on two sheets 1 mm apart, the top
    /// one thrown down onto the bottom one with a random spin, for every `ZoneMotion`: the
    /// collision handling ends without a stall, a fresh CCD pass over all candidates (the
    /// rigid zones' skip switched off) finds nothing, the linear momentum is kept (rigid with
    /// spin: the angular momentum about the centre of mass too), and a translating zone gives
    /// all of its vertices one velocity.
    #[test]
    fn every_zone_motion_ends_collision_free_and_keeps_momentum() {
        use impact_zones::ZoneMotion;
        let a =
            crate::scenes::handkerchief("a", 5, 5, 0.1, 0.1, |uv: Vec2| Vec3::new(uv.x, 0.0, uv.y));
        let na = a.positions.len() as u32;
        let mut positions = a.positions.clone();
        positions.extend(
            a.positions
                .iter()
                .map(|p| p + Vec3::new(0.013, 1e-3, 0.007)),
        );
        let mut triangles = a.triangles.clone();
        triangles.extend(a.triangles.iter().map(|t| t.map(|k| k + na)));
        let sheet = crate::mesh::Mesh::new("two", positions, triangles).unwrap();
        let topo = Topology::new(&sheet).unwrap();
        let hinge = vec![[u32::MAX; 3]; sheet.triangles.len()];
        let n = sheet.positions.len();
        let obstacles = Obstacles::default();
        let inv_mass = vec![1.0; n];
        let scene = Scene {
            x0: &sheet.positions,
            h: 0.02,
            triangles: &sheet.triangles,
            edges: &topo.edges,
            hinge: &hinge,
            obstacles: &obstacles,
            inv_mass: &inv_mass,
            friction: 0.0,
            ccd_ratio: 0.5,
        };
        let policy = UniformThickness(2e-4);
        for seed in 0..4u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let spin = rand_vec(&mut rng, 3.0);
            let c = Vec3::new(0.05, 1e-3, 0.05);
            let v0: Vec<Vec3> = (0..n)
                .map(|i| {
                    if i < na as usize {
                        rand_vec(&mut rng, 0.01)
                    } else {
                        Vec3::new(0.0, -1.0, 0.0)
                            + spin.cross(&(sheet.positions[i] - c))
                            + rand_vec(&mut rng, 0.2)
                    }
                })
                .collect();
            let momenta = |v: &[Vec3]| {
                let cm = sheet.positions.iter().sum::<Vec3>() / n as f64;
                let p: Vec3 = v.iter().sum();
                let l = (0..n).fold(Vec3::zeros(), |s, i| {
                    s + (sheet.positions[i] - cm).cross(&v[i])
                });
                (p, l)
            };
            let (p0, l0) = momenta(&v0);
            for (spin_on, soft) in [(true, 0), (false, 0), (true, 4), (false, 4), (true, 16)] {
                let motion = ZoneMotion {
                    spin: spin_on,
                    soft_levels: soft,
                };
                let mut v = v0.clone();
                let mut broad = broad::BroadPhase::default();
                let rep = handle(
                    &scene,
                    &mut v,
                    &policy,
                    CollisionSettings {
                        max_impulse_iterations: 0,
                        max_zone_iterations: 1000,
                        proximity: false,
                        contacts_within_reach: false,
                        rebuild: true,
                        zone_motion: motion,
                    },
                    &mut broad,
                );
                let what = format!("seed {seed}, {motion:?}");
                assert!(rep.impact_zones > 0, "{what}: zones must be exercised");
                assert!(!rep.stalled && !rep.administrative_quit, "{what}");
                let mut fresh = broad::BroadPhase::default();
                let margin = policy.max_thickness() * 1.0001;
                fresh.update(&scene, &v, margin, true);
                let cands = fresh.candidates(&scene, &v, margin);
                let left = impulses::detect(&scene, &v, &cands, &policy, &|_: &[u32; 4]| false);
                // Pairs inside a rigid zone keep (linearised spin: never shrink) their start
                // distance, which CCD with half that distance may still report only if they
                // were below the CCD thickness at the start; here every pair starts farther.
                assert!(left.is_empty(), "{what}: {} pairs collide", left.len());
                let (p1, l1) = momenta(&v);
                assert!(
                    (p1 - p0).norm() <= 1e-9 * (1.0 + p0.norm()),
                    "{what}: {p1} vs {p0}"
                );
                if spin_on && soft == 0 {
                    assert!((l1 - l0).norm() <= 1e-9 * (1.0 + l0.norm()), "{what}: L");
                }
                if !spin_on && soft == 0 {
                    // One zone over both sheets (they collide everywhere): one velocity.
                    let moved: Vec<Vec3> =
                        (0..n).filter(|&i| v[i] != v0[i]).map(|i| v[i]).collect();
                    assert!(moved.windows(2).all(|w| w[0] == w[1]), "{what}");
                }
            }
        }
    }
}
