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

use super::field::LayerField;
use super::operators::{check_weights, FieldVec, Operator, MAX_LAYERS};
use super::thickness;
use crate::error::{Error, Result};
use crate::geom::Vec3;
use crate::mesh::Topology;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::{Arc, RwLock};

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
}

/// Evaluates corrected fields, caching one operator per (layer, active set).
pub struct Composer<'a> {
    layers: &'a [Layer<'a>],
    cache: Vec<RwLock<HashMap<u32, Arc<Operator>>>>,
}

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
        Ok(Composer {
            layers,
            cache: (0..layers.len())
                .map(|_| RwLock::new(HashMap::new()))
                .collect(),
        })
    }

    /// Number of layers.
    pub fn len(&self) -> usize {
        self.layers.len()
    }

    /// Whether there is no layer.
    pub fn is_empty(&self) -> bool {
        self.layers.is_empty()
    }

    fn operator(&self, i: usize, mask: u32, idx: &[usize], me: usize) -> Arc<Operator> {
        if let Some(op) = self.cache[i].read().expect("not poisoned").get(&mask) {
            return op.clone();
        }
        let w: Vec<f64> = idx.iter().map(|&j| self.layers[j].weight).collect();
        let op = Arc::new(Operator::new(&w, me).expect("weights checked in Composer::new"));
        self.cache[i]
            .write()
            .expect("not poisoned")
            .entry(mask)
            .or_insert(op)
            .clone()
    }

    /// `f̂_i(p)` and its gradient (eq. 12–14); `None` where layer `i`'s own field is undefined.
    pub fn evaluate(&self, i: usize, p: &Vec3) -> Option<Corrected> {
        let n = self.layers.len();
        let mut idx = [0usize; MAX_LAYERS];
        let mut vals: FieldVec = [0.0; MAX_LAYERS];
        let mut grads = [Vec3::zeros(); MAX_LAYERS];
        let mut t = [0.0; MAX_LAYERS];
        let (mut m, mut me, mut mask) = (0usize, 0usize, 0u32);
        for j in 0..n {
            let l = &self.layers[j];
            let fg = if j == i {
                Some(l.field.field(p)?)
            } else if l.field.influences(p) {
                l.field.field(p)
            } else {
                None
            };
            if let Some((v, g)) = fg {
                if j == i {
                    me = m;
                }
                idx[m] = j;
                vals[m] = v;
                grads[m] = g;
                t[m] = l.thickness;
                mask |= 1 << j;
                m += 1;
            }
        }
        let op = self.operator(i, mask, &idx[..m], me);
        let off = thickness::offsets(me, &t[..m]);
        let mut x = [0.0; MAX_LAYERS];
        for k in 0..m {
            x[k] = vals[k] + off[k];
        }
        let e = op.evaluate(&x);
        let mut gradient = Vec3::zeros();
        for k in 0..m {
            gradient += grads[k] * e.gradient[k];
        }
        Some(Corrected {
            value: e.value,
            gradient,
            run: (idx[e.run.0], idx[e.run.1]),
            active: mask,
        })
    }
}

/// Parameters of the projection (Sec. 6.3).
#[derive(Clone, Debug)]
pub struct ProjectionParams {
    /// Newton steps interleaved with tangential relaxation.
    pub relax_iterations: usize,
    /// Cap on all Newton steps (interleaved and final).
    pub max_iterations: usize,
    /// Step factor of the interleaved Newton steps (the final ones use 1).
    pub damping: f64,
    /// Fraction of the tangential relaxation displacement applied per step.
    pub relaxation: f64,
    /// A vertex has converged when `|f̂_i − ε_v| ≤ tolerance` (field units ≈ length).
    pub tolerance: f64,
    /// Largest displacement of one Newton step.
    pub max_step: f64,
    /// Rings added around moved vertices to form the relaxed zone.
    pub zone_rings: usize,
}

impl Default for ProjectionParams {
    fn default() -> Self {
        ProjectionParams {
            relax_iterations: 10,
            max_iterations: 80,
            damping: 0.6,
            relaxation: 0.5,
            tolerance: 1e-5,
            max_step: 0.02,
            zone_rings: 2,
        }
    }
}

/// One vertex's Newton step: new position, unit field normal, run, residual, step factor.
type Step = (Vec3, Vec3, (usize, usize), f64, f64);

/// Result of projecting one layer.
#[derive(Clone, Debug)]
pub struct LayerProjection {
    /// New vertex positions.
    pub positions: Vec<Vec3>,
    /// Each vertex's original iso-value `ε_v` (NaN where the field is undefined).
    pub iso: Vec<f64>,
    /// Whether a vertex moved.
    pub moved: Vec<bool>,
    /// Whether a vertex ended in contact (merged with another layer), and the run.
    pub run: Vec<(usize, usize)>,
    /// Final `|f̂_i − ε_v|` per vertex (0 where undefined).
    pub residual: Vec<f64>,
    /// Newton passes run.
    pub iterations: usize,
    /// Vertices whose residual is above the tolerance at the end.
    pub unconverged: usize,
}

/// Projects the vertices `start` of layer `i` (Sec. 6.3); `progress(iteration)` is called after
/// every Newton pass.
pub fn project_layer(
    composer: &Composer,
    i: usize,
    start: &[Vec3],
    topo: &Topology,
    params: &ProjectionParams,
    progress: &(dyn Fn(usize) + Sync),
) -> LayerProjection {
    let nv = start.len();
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
    let mut pos = start.to_vec();
    let mut moved = vec![false; nv];
    let mut zone = vec![false; nv];
    let mut normal = vec![Vec3::zeros(); nv];
    let mut run = vec![(i, i); nv];
    let mut residual = vec![0.0; nv];
    let mut evaluated = vec![false; nv];
    // Per-vertex step factor: halved when a step made the residual grow (the corrected field
    // is only piecewise smooth: pieces and active sets switch), regrown when it shrinks.
    let mut factor = vec![1.0f64; nv];
    let mut last = vec![f64::INFINITY; nv];
    let mut iterations = 0;
    for it in 0..params.max_iterations.max(1) {
        iterations = it + 1;
        let interleaved = it < params.relax_iterations;
        let sigma = if interleaved { params.damping } else { 1.0 };
        let step: Vec<Option<Step>> = (0..nv)
            .into_par_iter()
            .map(|v| {
                if iso[v].is_nan() || (evaluated[v] && !zone[v]) {
                    return None;
                }
                let c = composer.evaluate(i, &pos[v])?;
                let r = c.value - target_iso(iso[v], c.run, i);
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
                    return Some((pos[v], nrm, c.run, r.abs(), f));
                }
                let mut d = c.gradient * (-sigma * f.max(1.0 / 64.0) * r / g2);
                let l = d.norm();
                if l > params.max_step {
                    d *= params.max_step / l;
                }
                Some((pos[v] + d, nrm, c.run, r.abs(), f))
            })
            .collect();
        let mut any = false;
        for (v, s) in step.into_iter().enumerate() {
            if let Some((p, nrm, rn, res, f)) = s {
                factor[v] = f;
                last[v] = res;
                evaluated[v] = true;
                if p != pos[v] {
                    any = true;
                    moved[v] = true;
                }
                pos[v] = p;
                normal[v] = nrm;
                run[v] = rn;
                residual[v] = res;
            } else if !iso[v].is_nan() {
                evaluated[v] = true;
            }
        }
        // The zone: moved vertices, dilated.
        let mut z: Vec<bool> = moved.clone();
        for _ in 0..params.zone_rings {
            let prev = z.clone();
            for v in 0..nv {
                if prev[v] {
                    for &u in topo.vertex_neighbors.row(v) {
                        z[u as usize] = true;
                    }
                }
            }
        }
        zone = z;
        progress(it + 1);
        if interleaved && params.relaxation > 0.0 {
            pos = relax(&pos, &normal, &zone, &iso, topo, &rest, params.relaxation);
        } else if !any {
            break;
        }
    }
    let unconverged = residual.iter().filter(|&&r| r > params.tolerance).count();
    LayerProjection {
        positions: pos,
        iso,
        moved,
        run,
        residual,
        iterations,
        unconverged,
    }
}

/// The iso-value a vertex is driven to: its own `ε_v` away from contact (details kept), and the
/// contact surface itself (`0`) when merged with another layer, so that neither a detail nor the
/// field's approximation error at the vertex can push a layer through the one it touches: the
/// offsets of eq. 13 alone then set the separation.
pub fn target_iso(eps: f64, run: (usize, usize), i: usize) -> f64 {
    if run == (i, i) {
        eps
    } else {
        0.0
    }
}

/// One tangential relaxation step (Sec. 6.3) of the zone vertices.
fn relax(
    pos: &[Vec3],
    normal: &[Vec3],
    zone: &[bool],
    iso: &[f64],
    topo: &Topology,
    rest: &[f64],
    amount: f64,
) -> Vec<Vec3> {
    (0..pos.len())
        .into_par_iter()
        .map(|v| {
            if !zone[v] || iso[v].is_nan() {
                return pos[v];
            }
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
                return pos[v];
            }
            let mut d = acc / count as f64;
            d -= nv * d.dot(&nv);
            pos[v] + d * amount
        })
        .collect()
}
