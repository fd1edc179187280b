//! Projection of garment meshes onto their corrected iso-surfaces (Buffet et al. 2019, Sec. 6).
//!
//! [`Composer`] evaluates the corrected field of a layer, `f̂_i(p) = O_i(f̃(p))` over the layers
//! active at `p` (eq. 12, influence region `h_j(p) < 0`), with the thickness offsets of eq. 13,
//! and its spatial gradient `∇f̂_i = Σ_j ∂O_i/∂f_j ∇f_j` (eq. 14).
//!
//! [`project_layer`] moves every vertex towards its *own original iso-value* `ε_v = f_i(p_v)`
//! (so details that the smooth field does not capture are kept; in contact the target is the
//! contact surface itself, see [`target_iso`]) by Newton steps along `∇f̂_i`,
//! interleaved with tangential relaxation (Sec. 6.3): for every edge, the minimal rotation about
//! its centre that makes it tangent to the field and the symmetric stretch that restores its
//! original length give target displacements of its two vertices; each vertex moves by the
//! tangential part of the average over its edges. Relaxation only acts in the deformed zone
//! (vertices moved by a Newton step, dilated by a few rings), so untouched regions stay exactly
//! as they were. After the interleaved phase, plain Newton steps converge every vertex onto its
//! target. Vertices are processed in parallel with Jacobi updates (read old, write new), so the
//! result does not depend on the thread count.

use super::field::{FieldSample, LayerField};
use super::operators::{check_weights, Operator, MAX_LAYERS};
use super::self_guard::SelfGuard;
use super::thickness;
use crate::error::{Error, Result};
use crate::geom::Vec3;
use crate::mesh::Topology;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::{Arc, OnceLock, RwLock};

/// One layer as seen by the operators: its field, stiffness weight and thickness.
pub struct Layer<'a> {
    /// The layer's fields.
    pub field: &'a dyn LayerField,
    /// Stiffness `w_i > 0`; `f64::INFINITY` only for the innermost layer (the body).
    pub weight: f64,
    /// Thickness `t_i ≥ 0` (Sec. 6.2).
    pub thickness: f64,
}

/// The corrected field of a layer at a point.
#[derive(Clone, Copy, Debug)]
pub struct Corrected {
    /// `f̂_i(p)`.
    pub value: f64,
    /// `∇f̂_i(p)` (eq. 14).
    pub gradient: Vec3,
    /// The merged run of the sector of `p`, in layer indices (`(i, i)`: not in contact).
    pub run: (usize, usize),
    /// Bit `j` set when layer `j` is active at `p` (eq. 12).
    pub active: u32,
    /// Distance in field units to the nearest contact with another active layer (0 in
    /// contact, infinite when no other layer is active): the budget for the vertex's details.
    pub margin: f64,
}

/// Most fading layers blended exactly at one point (`2^k` operator evaluations); further ones
/// are rounded to present or absent.
const MAX_FADING: usize = 3;

/// Margins above this are reported as this (field units), so that blends stay finite.
const MARGIN_CAP: f64 = 1e3;
const FADE_GRADIENT: f64 = 1.0;

/// Stacks of at most this many layers keep their operators in a table with one slot per
/// (layer, active set) (at most 10 × 2^10 slots); larger ones in a map.
const TABLE_LAYERS: usize = 10;

/// An operator of the [`Composer`]'s cache.
enum OpRef<'c> {
    Table(&'c Operator),
    Map(Arc<Operator>),
}

impl std::ops::Deref for OpRef<'_> {
    type Target = Operator;
    fn deref(&self) -> &Operator {
        match self {
            OpRef::Table(op) => op,
            OpRef::Map(op) => op,
        }
    }
}

/// Evaluates corrected fields, caching one operator per (layer, active set).
pub struct Composer<'a> {
    layers: &'a [Layer<'a>],
    /// With at most `TABLE_LAYERS` layers: slot `i · 2^n + mask`, built on first use (a
    /// lookup reads one slot: no lock and no reference count shared between the threads).
    table: Vec<OnceLock<Operator>>,
    cache: Vec<RwLock<HashMap<u32, Arc<Operator>>>>,
    scaled_offsets: bool,
}

/// One configuration's corrected value: value, gradient, run, margin.
type Config = (f64, Vec3, (usize, usize), f64);

impl<'a> Composer<'a> {
    /// Checks weights and thicknesses.
    pub fn new(layers: &'a [Layer<'a>]) -> Result<Composer<'a>> {
        let w: Vec<f64> = layers.iter().map(|l| l.weight).collect();
        check_weights(&w)?;
        for (j, l) in layers.iter().enumerate() {
            if !(l.thickness.is_finite() && l.thickness >= 0.0) {
                return Err(Error::Parameter(format!(
                    "thickness of layer {} must be finite and non-negative, got {}",
                    j + 1,
                    l.thickness
                )));
            }
        }
        let n = layers.len();
        let slots = if n <= TABLE_LAYERS { n << n } else { 0 };
        Ok(Composer {
            layers,
            table: (0..slots).map(|_| OnceLock::new()).collect(),
            cache: (0..layers.len())
                .map(|_| RwLock::new(HashMap::new()))
                .collect(),
            scaled_offsets: true,
        })
    }

    /// Whether the thickness offsets of eq. 13 are scaled to the fields' gradients at the point
    /// (default `true`; see [`thickness::scaled_offsets`]): `false` is the paper's literal eq.
    /// 13, whose gap between two layers in contact is the thickness rule divided by the norm of
    /// their (weighted mean) field gradient, e.g. 10 % too wide where the two garments' surfaces
    /// meet at 50°.
    pub fn with_scaled_offsets(mut self, on: bool) -> Self {
        self.scaled_offsets = on;
        self
    }

    /// Number of layers.
    pub fn len(&self) -> usize {
        self.layers.len()
    }

    /// Whether there is no layer.
    pub fn is_empty(&self) -> bool {
        self.layers.is_empty()
    }

    /// The layers.
    pub fn layers(&self) -> &[Layer<'a>] {
        self.layers
    }

    /// `O_i` over the layers of `mask` (which contains `i`).
    fn build_operator(&self, i: usize, mask: u32) -> Operator {
        let idx: Vec<usize> = (0..self.layers.len())
            .filter(|&j| mask & (1 << j) != 0)
            .collect();
        let me = idx
            .iter()
            .position(|&j| j == i)
            .expect("own layer in the mask");
        let w: Vec<f64> = idx.iter().map(|&j| self.layers[j].weight).collect();
        Operator::new(&w, me).expect("weights checked in Composer::new")
    }

    fn operator(&self, i: usize, mask: u32) -> OpRef<'_> {
        if !self.table.is_empty() {
            let slot = &self.table[(i << self.layers.len()) | mask as usize];
            return OpRef::Table(slot.get_or_init(|| self.build_operator(i, mask)));
        }
        if let Some(op) = self.cache[i].read().expect("not poisoned").get(&mask) {
            return OpRef::Map(op.clone());
        }
        let op = Arc::new(self.build_operator(i, mask));
        OpRef::Map(
            self.cache[i]
                .write()
                .expect("not poisoned")
                .entry(mask)
                .or_insert(op)
                .clone(),
        )
    }

    /// `f̂_i(p)` and its gradient (eq. 12–14); `None` where layer `i`'s own field is undefined.
    pub fn evaluate(&self, i: usize, p: &Vec3) -> Option<Corrected> {
        self.evaluate_forced(i, p, 0)
    }

    /// The operator of layer `i` over the layers of `mask` (which contains `i`).
    fn configuration(&self, i: usize, mask: u32, samples: &[Option<FieldSample>]) -> Config {
        let mut idx = [0usize; MAX_LAYERS];
        let mut grads = [Vec3::zeros(); MAX_LAYERS];
        let mut t = [0.0; MAX_LAYERS];
        let mut x = [0.0; MAX_LAYERS];
        let (mut m, mut me) = (0usize, 0usize);
        for (j, s) in samples.iter().enumerate() {
            if mask & (1 << j) == 0 {
                continue;
            }
            let s = s.expect("sampled");
            if j == i {
                me = m;
            }
            idx[m] = j;
            x[m] = s.value;
            grads[m] = s.gradient;
            t[m] = self.layers[j].thickness;
            m += 1;
        }
        if m == 1 {
            return (x[0], grads[0], (i, i), MARGIN_CAP);
        }
        let op = self.operator(i, mask);
        let off = if self.scaled_offsets {
            let mut w = [0.0; MAX_LAYERS];
            for k in 0..m {
                w[k] = self.layers[idx[k]].weight;
            }
            thickness::scaled_offsets(me, &t[..m], &w[..m], &x[..m], &grads[..m])
        } else {
            thickness::offsets(me, &t[..m])
        };
        for k in 0..m {
            x[k] += off[k];
        }
        let e = op.evaluate(&x);
        let mut gradient = Vec3::zeros();
        for k in 0..m {
            gradient += grads[k] * e.gradient[k];
        }
        // Margin to contact: how far (in field units) the point is from meeting any other
        // active layer, 0 in contact.
        let mut margin = MARGIN_CAP;
        if e.run != (me, me) {
            margin = 0.0;
        } else {
            for k in 0..m {
                if k != me {
                    let mk = if k < me { x[k] } else { -x[k] };
                    margin = margin.min(mk.max(0.0));
                }
            }
        }
        (e.value, gradient, (idx[e.run.0], idx[e.run.1]), margin)
    }

    /// Like [`Composer::evaluate`], with the layers of the bit set `force` (and layer `i`
    /// itself) fully present wherever their field is defined, whatever their influence regions
    /// (used by the repair of residual intersections, see [`super::repair`]).
    ///
    /// Layers whose influence fades at `p` (Sec. 6.1 with the fade of [`super::field`]) are
    /// present with probability `1 − s_j(p)`, independently; the corrected field is the
    /// expectation of the operator over these configurations (`O_i` over the present layers, or
    /// `f_i` alone when layer `i` itself is absent). Every layer's corrected field averages over
    /// the *same* configurations at `p`, and each configuration is nested (Sec. 5), so the
    /// blend keeps the layers in order where they meet, while moving continuously.
    pub fn evaluate_forced(&self, i: usize, p: &Vec3, force: u32) -> Option<Corrected> {
        let n = self.layers.len();
        let mut samples = [None; MAX_LAYERS];
        for (j, l) in self.layers.iter().enumerate() {
            samples[j] = l.field.sample(p);
        }
        samples[i]?;
        let forced = |j: usize| force & (1 << j) != 0 || (force != 0 && j == i);
        let mut base = 0u32;
        let mut fading: Vec<(usize, f64, Vec3)> = Vec::new();
        for j in 0..n {
            let Some(s) = samples[j] else { continue };
            if forced(j) || s.fade <= 0.0 {
                base |= 1 << j;
            } else if s.fade < 1.0 {
                fading.push((j, s.fade, s.fade_gradient));
            }
        }
        if fading.len() > MAX_FADING {
            // Keep the most uncertain ones; round the others.
            fading.sort_by(|a, b| {
                (a.1 - 0.5)
                    .abs()
                    .total_cmp(&(b.1 - 0.5).abs())
                    .then(a.0.cmp(&b.0))
            });
            for &(j, s, _) in &fading[MAX_FADING..] {
                if s < 0.5 {
                    base |= 1 << j;
                }
            }
            fading.truncate(MAX_FADING);
        }
        let nf = fading.len();
        let (mut value, mut gradient, mut margin) = (0.0, Vec3::zeros(), 0.0);
        let mut best = (-1.0, (i, i));
        for c in 0u32..(1 << nf) {
            let mut mask = base;
            let mut w = 1.0;
            for (k, &(j, s, _)) in fading.iter().enumerate() {
                if c & (1 << k) != 0 {
                    mask |= 1 << j;
                    w *= 1.0 - s;
                } else {
                    w *= s;
                }
            }
            let (v, g, run, mg) = if mask & (1 << i) == 0 {
                let s = samples[i].expect("sampled");
                (s.value, s.gradient, (i, i), MARGIN_CAP)
            } else {
                self.configuration(i, mask, &samples)
            };
            // ∇w: product rule over the fading layers.
            let mut dw = Vec3::zeros();
            for (k, &(_, s, ds)) in fading.iter().enumerate() {
                let mut rest = 1.0;
                for (l, &(_, s2, _)) in fading.iter().enumerate() {
                    if l != k {
                        rest *= if c & (1 << l) != 0 { 1.0 - s2 } else { s2 };
                    }
                }
                let _ = s;
                dw += ds * if c & (1 << k) != 0 { -rest } else { rest };
            }
            value += w * v;
            gradient += g * w + dw * v * FADE_GRADIENT;
            margin += w * mg;
            if w > best.0 {
                best = (w, run);
            }
        }
        let active = fading.iter().fold(base, |m, &(j, _, _)| m | 1 << j);
        Some(Corrected {
            value,
            gradient,
            run: best.1,
            active,
            margin,
        })
    }
}

/// Parameters of the projection (Sec. 6.3).
#[derive(Clone, Debug)]
pub struct ProjectionParams {
    /// Cap on the Newton passes.
    pub max_iterations: usize,
    /// Passes during which tangential relaxation is interleaved with the Newton steps.
    pub relax_iterations: usize,
    /// Fraction of the tangential relaxation displacement applied per pass.
    pub relaxation: f64,
    /// A vertex has converged when `|f̂_i − τ_v| ≤ tolerance` (field units ≈ length).
    pub tolerance: f64,
    /// Largest displacement of one Newton step.
    pub max_step: f64,
    /// Rings added around moved vertices to form the relaxed zone.
    pub zone_rings: usize,
    /// Share of the margin to contact that a vertex's detail may use: the target iso-value is
    /// `τ_v = clamp(ε_v, ±share · margin)` (see [`target_iso`]).
    pub detail_share: f64,
    /// Undo the relaxation moves that would invert a triangle (see `guard_flips`).
    pub prevent_flips: bool,
    /// Evaluate only the vertices whose position changed since their last evaluation (the
    /// others would give the same step), and relax only the vertices that moved in their last
    /// relaxation or whose one-ring (position or field normal) changed since (the others would
    /// make no move again). Gives the same result as evaluating and relaxing every vertex of
    /// the zone in every pass, with less work; `false` is the reference.
    pub active_set: bool,
    /// Relaxation moves shorter than `relax_skip · tolerance` are not made (the vertex keeps
    /// its position, so the active set need not evaluate it again); 0 makes every move.
    pub relax_skip: f64,
    /// Undo the moves that would make two triangles of the garment intersect that did not at
    /// the start (see [`super::self_guard`]).
    pub prevent_self_intersections: bool,
    /// Passes between two checks of the self-intersection guard (moves since the last check
    /// are undone where they made the garment intersect itself anew).
    pub self_guard_interval: usize,
    /// Scale the thickness offsets by the fields' gradient norms (see
    /// [`Composer::with_scaled_offsets`]); used by [`super::layers::untangle_layers`].
    pub scaled_offsets: bool,
}

impl Default for ProjectionParams {
    fn default() -> Self {
        ProjectionParams {
            max_iterations: 60,
            relax_iterations: 20,
            relaxation: 0.5,
            tolerance: 1e-5,
            max_step: 0.02,
            zone_rings: 2,
            detail_share: 0.5,
            prevent_flips: true,
            active_set: true,
            relax_skip: 10.0,
            prevent_self_intersections: false,
            self_guard_interval: 8,
            scaled_offsets: true,
        }
    }
}

/// One vertex's Newton step: new position, unit field normal, run, residual, step factor.
type Step = (Vec3, Vec3, ((usize, usize), u32), f64, f64);

/// Result of projecting one layer.
#[derive(Clone, Debug)]
pub struct LayerProjection {
    /// New vertex positions.
    pub positions: Vec<Vec3>,
    /// Each vertex's original iso-value `ε_v` (NaN where the field is undefined).
    pub iso: Vec<f64>,
    /// Whether a vertex moved.
    pub moved: Vec<bool>,
    /// Whether the repair of residual crossings moved the vertex afterwards (see
    /// [`super::repair`]; all `false` out of the projection).
    pub repaired: Vec<bool>,
    /// Whether a vertex ended in contact (merged with another layer), and the run.
    pub run: Vec<(usize, usize)>,
    /// Per vertex, the layers that influence it at the end (bit `j`: layer `j`, eq. 12).
    pub active: Vec<u32>,
    /// Final `|f̂_i − τ_v|` per vertex (0 where undefined).
    pub residual: Vec<f64>,
    /// Newton passes run.
    pub iterations: usize,
    /// Vertices whose residual is above the tolerance at the end.
    pub unconverged: usize,
    /// Vertex evaluations of the corrected field (work measure).
    pub evaluations: usize,
    /// Vertex relaxations computed (work measure; with the active set, a vertex whose last
    /// relaxation made no move is skipped while neither it nor a neighbour changes).
    pub relaxations: usize,
}

/// What the repair of residual intersections changes in a projection (see [`super::repair`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Overrides<'a> {
    /// Only these vertices move (all when `None`).
    pub movable: Option<&'a [bool]>,
    /// Per vertex, layers forced active ([`Composer::evaluate_forced`]).
    pub force: Option<&'a [u32]>,
    /// Per vertex, a shift added to the target iso-value (negative: further in).
    pub bias: Option<&'a [f64]>,
}

/// Projects the vertices `start` of layer `i` (Sec. 6.3); `progress(iteration)` is called after
/// every Newton pass.
pub fn project_layer(
    composer: &Composer,
    i: usize,
    start: &[Vec3],
    triangles: &[[u32; 3]],
    topo: &Topology,
    params: &ProjectionParams,
    progress: &(dyn Fn(usize) + Sync),
) -> LayerProjection {
    let own = composer.layers[i].field;
    let iso: Vec<f64> = start
        .par_iter()
        .map(|p| own.field(p).map_or(f64::NAN, |(v, _)| v))
        .collect();
    let rest: Vec<f64> = topo
        .edges
        .iter()
        .map(|e| (start[e[0] as usize] - start[e[1] as usize]).norm())
        .collect();
    project_from(
        composer,
        i,
        start,
        &iso,
        &rest,
        triangles,
        topo,
        params,
        &Overrides::default(),
        progress,
    )
}

/// The projection loop of [`project_layer`] from positions `start`, with the vertices' own
/// iso-values `iso`, the edges' rest lengths `rest`, and the repair's overrides.
pub fn project_from(
    composer: &Composer,
    i: usize,
    start: &[Vec3],
    iso: &[f64],
    rest: &[f64],
    triangles: &[[u32; 3]],
    topo: &Topology,
    params: &ProjectionParams,
    over: &Overrides,
    progress: &(dyn Fn(usize) + Sync),
) -> LayerProjection {
    let nv = start.len();
    let own = composer.layers[i].field;
    // Reference orientation of every triangle against the field normals at the start: a
    // triangle that starts positively oriented must stay so (see `guard_flips`).
    let mut normal: Vec<Vec3> = start
        .par_iter()
        .map(|p| own.field(p).map_or(Vec3::zeros(), |(_, g)| g.normalize()))
        .collect();
    let oriented: Vec<bool> = triangles
        .par_iter()
        .map(|t| orientation(t, start, &normal) > 0.0)
        .collect();
    let movable = |v: usize| over.movable.is_none_or(|m| m[v]) && !iso[v].is_nan();
    let mut pos = start.to_vec();
    let mut moved = vec![false; nv];
    let mut zone = vec![false; nv];
    let mut zone_list: Vec<usize> = Vec::new();
    // Pass (plus one) in which a vertex last joined the ball around the newly moved vertices.
    let mut ball_mark = vec![0usize; nv];
    // Pass (plus one) in which a triangle was last listed by `guard_flips`.
    let mut tri_mark = vec![
        0usize;
        if params.prevent_flips {
            triangles.len()
        } else {
            0
        }
    ];
    let mut run = vec![(i, i); nv];
    let mut active = vec![0u32; nv];
    let mut residual = vec![0.0; nv];
    let mut evaluated = vec![false; nv];
    // Position of every vertex at its last evaluation (active set: unchanged ⇒ same step).
    let mut at = start.to_vec();
    // Per-vertex step factor: halved when a step made the residual grow (the corrected field
    // is only piecewise smooth: pieces and active sets switch), regrown when it shrinks.
    let mut factor = vec![1.0f64; nv];
    let mut last = vec![f64::INFINITY; nv];
    let mut iterations = 0;
    let mut evaluations = 0;
    let mut relaxations = 0;
    let mut guard = params
        .prevent_self_intersections
        .then(|| SelfGuard::new(triangles, topo, start));
    // Self-intersection checkpoint: positions free of new self-intersections, and the
    // vertices changed since (checked every `self_guard_interval` passes and at the end).
    let mut checkpoint = if guard.is_some() {
        start.to_vec()
    } else {
        Vec::new()
    };
    let mut since: Vec<usize> = Vec::new();
    let mut in_since = vec![false; if guard.is_some() { nv } else { 0 }];
    // Vertices are evaluated along a Morton curve of their start positions, so that
    // consecutive evaluations read nearby grid cells (each vertex's step depends only on its
    // own state: any order gives the same result).
    let visit = morton_order(start);
    // Rank of every vertex along that curve, and the zone's vertices in that order: after the
    // first pass every movable vertex has been evaluated, so only zone vertices are needed,
    // and a pass of the active set visits these instead of every vertex (same order, same
    // steps; the scan of every vertex was ~0.17 s of sequential work at the Table-2 size).
    let mut rank = vec![0u32; nv];
    for (r, &v) in visit.iter().enumerate() {
        rank[v] = r as u32;
    }
    let mut zone_ranked: Vec<usize> = Vec::new();
    // Relaxation cache: `quiet[v]` when the last relaxation of `v` made no move and neither
    // `v` nor a neighbour has changed position or normal since (the relaxation of `v` reads
    // only these, so it would make no move again).
    let mut quiet = vec![false; nv];
    let unquiet = |quiet: &mut [bool], v: usize| {
        quiet[v] = false;
        for &u in topo.vertex_neighbors.row(v) {
            quiet[u as usize] = false;
        }
    };
    for it in 0..params.max_iterations.max(1) {
        iterations = it + 1;

        let needed = |v: usize| movable(v) && (!evaluated[v] || zone[v]);
        let candidates: &[usize] = if it == 0 { &visit } else { &zone_ranked };
        let todo: Vec<usize> = if params.active_set {
            let mut todo = Vec::new();
            for &v in candidates {
                if !needed(v) {
                    continue;
                }
                if evaluated[v] && at[v] == pos[v] {
                    // Same position, same evaluation: only the step factor would change (the
                    // residual did not grow, so it doubles, see below).
                    factor[v] = (2.0 * factor[v]).min(1.0);
                } else {
                    todo.push(v);
                }
            }
            todo
        } else {
            // The reference scans every vertex.
            visit.iter().copied().filter(|&v| needed(v)).collect()
        };
        evaluations += todo.len();
        let step: Vec<(usize, Option<Step>)> = todo
            .par_iter()
            .map(|&v| {
                let force = over.force.map_or(0, |f| f[v]);
                let Some(c) = composer.evaluate_forced(i, &pos[v], force) else {
                    return (v, None);
                };
                let bias = over.bias.map_or(0.0, |b| b[v]);
                let r = c.value - target_iso(iso[v], c.margin, params.detail_share) - bias;
                let f = if r.abs() > last[v] {
                    0.5 * factor[v]
                } else {
                    (2.0 * factor[v]).min(1.0)
                };
                let g2 = c.gradient.norm_squared();
                let nrm = if g2 > 0.0 {
                    c.gradient / g2.sqrt()
                } else {
                    Vec3::zeros()
                };
                if r.abs() <= params.tolerance || g2 < 1e-24 {
                    return (v, Some((pos[v], nrm, (c.run, c.active), r.abs(), f)));
                }
                let mut d = c.gradient * (-f.max(1.0 / 64.0) * r / g2);
                let l = d.norm();
                if l > params.max_step {
                    d *= params.max_step / l;
                }
                (v, Some((pos[v] + d, nrm, (c.run, c.active), r.abs(), f)))
            })
            .collect();
        let mut any = false;
        let mut newly = Vec::new();
        let mut changed = Vec::new();
        for (v, s) in step {
            evaluated[v] = true;
            // Undefined there: evaluated again next time (NaN never compares equal).
            at[v] = if s.is_some() {
                pos[v]
            } else {
                Vec3::repeat(f64::NAN)
            };
            if let Some((p, nrm, rn, res, f)) = s {
                factor[v] = f;
                last[v] = res;
                if p != pos[v] || (nrm != Vec3::zeros() && nrm != normal[v]) {
                    unquiet(&mut quiet, v);
                }
                if p != pos[v] {
                    any = true;
                    if !moved[v] {
                        newly.push(v);
                    }
                    moved[v] = true;
                    changed.push(v);
                }
                pos[v] = p;
                if nrm != Vec3::zeros() {
                    normal[v] = nrm;
                }
                run[v] = rn.0;
                active[v] = rn.1;
                residual[v] = res;
            }
        }
        // The zone: moved vertices, dilated (`moved` only grows, so the zone grows by the
        // dilation of the newly moved vertices).
        // Ball of `zone_rings` rings around them (breadth-first, each vertex once per pass).
        for &v in &newly {
            ball_mark[v] = it + 1;
        }
        let mut ball = newly;
        let mut from = 0;
        for _ in 0..params.zone_rings {
            let to = ball.len();
            for k in from..to {
                for &u in topo.vertex_neighbors.row(ball[k]) {
                    let u = u as usize;
                    if ball_mark[u] != it + 1 {
                        ball_mark[u] = it + 1;
                        ball.push(u);
                    }
                }
            }
            from = to;
        }
        // The zone in the order its vertices joined it (the relaxation of a vertex does not
        // depend on the others' order).
        let joined = zone_list.len();
        for v in ball {
            if !zone[v] {
                zone[v] = true;
                zone_list.push(v);
            }
        }
        if zone_list.len() > joined {
            let mut fresh = zone_list[joined..].to_vec();
            fresh.sort_unstable_by_key(|&v| rank[v]);
            zone_ranked = merge_by_rank(&zone_ranked, &fresh, &rank);
        }
        progress(it + 1);
        let mut relaxed = 0.0f64;
        let before = pos.clone();
        if it < params.relax_iterations && params.relaxation > 0.0 {
            let moves = relax(
                &pos,
                &normal,
                &zone_list,
                &|v| movable(v) && evaluated[v] && !(params.active_set && quiet[v]),
                topo,
                rest,
                params.relaxation,
                params.relax_skip * params.tolerance,
            );
            relaxations += moves.len();
            for (v, m) in moves {
                match m {
                    Some((p, d)) => {
                        pos[v] = p;
                        relaxed = relaxed.max(d);
                        changed.push(v);
                        unquiet(&mut quiet, v);
                    }
                    None => quiet[v] = true,
                }
            }
        }
        if params.prevent_flips {
            let reverted = guard_flips(
                &before,
                &mut pos,
                &normal,
                triangles,
                &oriented,
                topo,
                &changed,
                (&mut tri_mark, it + 1),
            );
            for v in reverted {
                unquiet(&mut quiet, v);
            }
        }
        let mut stop = !any && relaxed <= params.tolerance;
        if let Some(g) = guard.as_mut() {
            for &v in &changed {
                if !in_since[v] {
                    in_since[v] = true;
                    since.push(v);
                }
            }
            let last = it + 1 == params.max_iterations.max(1);
            if stop || last || (it + 1) % params.self_guard_interval.max(1) == 0 {
                since.sort_unstable();
                for v in g.revert_new(&checkpoint, &mut pos, &since) {
                    // Put back: evaluate again next pass (its neighbours may have moved on).
                    at[v] = Vec3::repeat(f64::NAN);
                    unquiet(&mut quiet, v);
                    stop = false;
                }
                for &v in &since {
                    checkpoint[v] = pos[v];
                    in_since[v] = false;
                }
                since.clear();
            }
        }
        if stop {
            break;
        }
    }
    let unconverged = residual.iter().filter(|&&r| r > params.tolerance).count();
    LayerProjection {
        positions: pos,
        iso: iso.to_vec(),
        repaired: vec![false; moved.len()],
        moved,
        run,
        active,
        residual,
        iterations,
        unconverged,
        evaluations,
        relaxations,
    }
}

/// The union of `a` and `b` (disjoint, each sorted by `rank`), sorted by `rank`.
fn merge_by_rank(a: &[usize], b: &[usize], rank: &[u32]) -> Vec<usize> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if rank[a[i]] < rank[b[j]] {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(b[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// The vertex indices of `pos` sorted along a Morton (Z-order) curve over their bounding box
/// (ties by index).
fn morton_order(pos: &[Vec3]) -> Vec<usize> {
    let (_, order) = crate::broad::bvh::morton_sorted(pos);
    order.into_iter().map(|v| v as usize).collect()
}

/// `((b − a) × (c − a)) · (n_a + n_b + n_c)` of triangle `t`.
#[inline]
fn orientation(t: &[u32; 3], pos: &[Vec3], normal: &[Vec3]) -> f64 {
    let [a, b, c] = t.map(|v| v as usize);
    (pos[b] - pos[a])
        .cross(&(pos[c] - pos[a]))
        .dot(&(normal[a] + normal[b] + normal[c]))
}

/// Undoes this pass's moves of the vertices of every triangle that was positively oriented
/// against the field normals at the start and no longer is (the moves would fold the mesh over
/// itself: on a surface, a mesh without inverted triangles does not overlap itself locally).
/// Repeats until no such triangle has a vertex that moved; returns the reverted vertices.
/// `changed` may list a vertex more than once; `mark` (one entry per triangle, none equal to
/// `stamp`) lists each triangle once.
#[allow(clippy::too_many_arguments)]
fn guard_flips(
    before: &[Vec3],
    pos: &mut [Vec3],
    normal: &[Vec3],
    triangles: &[[u32; 3]],
    oriented: &[bool],
    topo: &Topology,
    changed: &[usize],
    (mark, stamp): (&mut [usize], usize),
) -> Vec<usize> {
    let mut reverted = Vec::new();
    // Only the triangles of the vertices that moved can have flipped (each listed once; the
    // outcome does not depend on their order).
    let mut cand: Vec<usize> = Vec::new();
    for &v in changed {
        for &t in topo.vertex_triangles.row(v) {
            let t = t as usize;
            if mark[t] != stamp {
                mark[t] = stamp;
                cand.push(t);
            }
        }
    }
    loop {
        let bad: Vec<usize> = cand
            .par_iter()
            .copied()
            .filter(|&k| {
                let t = &triangles[k];
                oriented[k]
                    && t.iter().any(|&v| pos[v as usize] != before[v as usize])
                    && orientation(t, pos, normal) <= 0.0
            })
            .collect();
        if bad.is_empty() {
            break;
        }
        for k in bad {
            for &v in &triangles[k] {
                let v = v as usize;
                if pos[v] != before[v] {
                    pos[v] = before[v];
                    reverted.push(v);
                }
            }
        }
    }
    reverted.sort_unstable();
    reverted.dedup();
    reverted
}

/// The iso-value a vertex is driven to: its own `ε_v` (details kept), limited to `share` of its
/// margin to contact. Away from every other layer this is `ε_v`; in contact it is `0`, the
/// contact surface itself; in between it varies continuously with the position (so Newton's
/// iteration has a fixed point, unlike a switch between `ε_v` and `0`). Other layers see the
/// smooth surface `f_i = 0`, not the details: with `share ≤ 1/2` a detail uses at most half of
/// the gap, the other layer's detail the other half, so the meshes keep the thickness rule's
/// distance between them.
pub fn target_iso(eps: f64, margin: f64, share: f64) -> f64 {
    let b = share * margin;
    eps.clamp(-b, b)
}

/// One tangential relaxation step (Sec. 6.3) of the zone vertices: for every edge, the minimal
/// rotation about its centre that makes it tangent to the field and the symmetric stretch that
/// restores its rest length give target displacements of its two vertices; each vertex moves
/// by `amount` times the tangential part of their average (moves shorter than `skip` are not
/// made). Returns, for every zone vertex that passes `movable` (in zone order), its new
/// position and displacement, or `None` when it does not move.
#[allow(clippy::type_complexity)]
fn relax(
    pos: &[Vec3],
    normal: &[Vec3],
    zone: &[usize],
    movable: &(dyn Fn(usize) -> bool + Sync),
    topo: &Topology,
    rest: &[f64],
    amount: f64,
    skip: f64,
) -> Vec<(usize, Option<(Vec3, f64)>)> {
    zone.par_iter()
        .filter_map(|&v| {
            if !movable(v) {
                return None;
            }
            Some((v, relax_vertex(v, pos, normal, topo, rest, amount, skip)))
        })
        .collect()
}

/// The relaxation move of vertex `v` (see [`relax`]): new position and displacement, `None`
/// when it does not move.
fn relax_vertex(
    v: usize,
    pos: &[Vec3],
    normal: &[Vec3],
    topo: &Topology,
    rest: &[f64],
    amount: f64,
    skip: f64,
) -> Option<(Vec3, f64)> {
    let nv = normal[v];
    let mut acc = Vec3::zeros();
    let mut count = 0usize;
    for (&u, &e) in topo
        .vertex_neighbors
        .row(v)
        .iter()
        .zip(topo.vertex_edges.row(v))
    {
        let u = u as usize;
        let nu = normal[u];
        let mut ne = nv + nu;
        let l = ne.norm();
        if l < 1e-12 {
            continue;
        }
        ne /= l;
        let c = (pos[v] + pos[u]) * 0.5;
        let d = pos[v] - pos[u];
        let dt = d - ne * d.dot(&ne);
        let lt = dt.norm();
        if lt < 1e-15 {
            continue;
        }
        let target = c + dt * (0.5 * rest[e as usize] / lt);
        acc += target - pos[v];
        count += 1;
    }
    if count == 0 {
        return None;
    }
    let mut d = acc / count as f64;
    d -= nv * d.dot(&nv);
    d *= amount;
    let l = d.norm();
    if l < skip || l == 0.0 {
        return None;
    }
    Some((pos[v] + d, l))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Oracle: merging two disjoint rank-sorted lists equals sorting their concatenation.
        #[test]
        fn merge_by_rank_equals_sorting(
            perm in Just((0..60usize).collect::<Vec<_>>()).prop_shuffle(),
            split in proptest::collection::vec(any::<bool>(), 60),
        ) {
            let mut rank = vec![0u32; perm.len()];
            for (r, &v) in perm.iter().enumerate() {
                rank[v] = r as u32;
            }
            let (mut a, mut b): (Vec<usize>, Vec<usize>) = (0..60).partition(|&v| split[v]);
            a.sort_unstable_by_key(|&v| rank[v]);
            b.sort_unstable_by_key(|&v| rank[v]);
            let mut all: Vec<usize> = (0..60).collect();
            all.sort_unstable_by_key(|&v| rank[v]);
            prop_assert_eq!(merge_by_rank(&a, &b, &rank), all);
        }
    }
}
