//! Repair of the crossings that the projection leaves (an addition to Buffet et al. 2019,
//! driven by the exact edge–triangle test of the intersection analysis).
//!
//! The operators guarantee nested *implicit* surfaces where the layers see each other with the
//! same active set; the meshes can still cross where that does not hold or where a triangle cuts
//! through a crease of the corrected surface that is sharper than the mesh (typically where a
//! layer comes out from under the rim of an outer one). The repair fixes the layers from the
//! inside out: the body and the garments below layer `k` are final and mutually clean; every
//! triangle of `k` that crosses one of them (exact test, same symbolic perturbation and vertex
//! numbering as the analysis, so "clean here" is "clean for the analysis") has its vertices
//! pushed outwards — along the gradient of the fields of the layers it crosses — by a fraction
//! of the thickness rule, with a decaying bump over a few rings of neighbours, until no crossing
//! is left or the step limit is reached. Pushing `k` outwards can only create crossings with the
//! layers above it, which are repaired afterwards. This is the sequential pairwise scheme the
//! paper's N-ary operators replace; it is used only on the few places the operators leave.

use super::field::LayerField;
use crate::broad::Bvh;
use crate::geom::tri_tri::{edge_crosses_triangle, triangles_may_intersect};
use crate::geom::{Aabb, Vec3};
use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;

/// Parameters of [`repair`].
#[derive(Clone, Debug)]
pub struct RepairParams {
    /// Most push steps per garment (0 turns the repair off).
    pub steps: usize,
    /// Push per step, relative to the thickness rule to the layer below (or to `min_step`).
    pub step: f64,
    /// Smallest push per step (length).
    pub min_step: f64,
    /// Rings of neighbours pushed along, with the push halved at every ring.
    pub rings: usize,
}

impl Default for RepairParams {
    fn default() -> Self {
        RepairParams {
            steps: 40,
            step: 0.25,
            min_step: 1e-4,
            rings: 3,
        }
    }
}

/// What the repair did to one garment.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct LayerRepair {
    /// Triangles crossing the layers below at the start.
    pub crossing_triangles: usize,
    /// Push steps run.
    pub steps: usize,
    /// Vertices pushed at least once.
    pub vertices: usize,
    /// Largest total push of a vertex.
    pub max_push: f64,
    /// Triangles still crossing the layers below at the end (0 unless the step limit was hit).
    pub remaining: usize,
}

/// One garment of the repair: its mesh, current positions, topology and thickness rule to the
/// layers below.
pub struct RepairLayer<'a> {
    /// The mesh (connectivity).
    pub mesh: &'a Mesh,
    /// Its topology.
    pub topo: &'a Topology,
    /// Its field (gives the push direction to the layers above it).
    pub field: &'a dyn LayerField,
    /// Thickness rule to the layer below (`t_k/2 + t_{k-1}/2`).
    pub separation: f64,
}

/// Triangles of `tris` (ids offset by `base` in `pos`) crossing a triangle of `others` (ids in
/// `pos`, boxes in `bvh`): per crossing triangle, the bit set of the objects it crosses.
fn crossing_triangles(
    tris: &[[u32; 3]],
    base: u32,
    pos: &[Vec3],
    others: &[[u32; 3]],
    object_of: &[u32],
    bvh: &Bvh,
) -> Vec<(usize, u32)> {
    tris.par_iter()
        .enumerate()
        .filter_map(|(k, t)| {
            let ta = t.map(|v| v + base);
            let pa = ta.map(|v| pos[v as usize]);
            let bbox = Aabb::from_points(pa.iter());
            let mut hit = 0u32;
            bvh.query(&bbox, |u| {
                let tb = others[u as usize];
                let pb = tb.map(|v| pos[v as usize]);
                if !triangles_may_intersect(&pa, &pb) {
                    return;
                }
                let cross = |x: [u32; 3], y: [u32; 3]| {
                    (0..3).any(|e| {
                        let (i, j) = (x[e], x[(e + 1) % 3]);
                        edge_crosses_triangle(
                            &pos[i as usize],
                            &pos[j as usize],
                            &pos[y[0] as usize],
                            &pos[y[1] as usize],
                            &pos[y[2] as usize],
                            [i, j, y[0], y[1], y[2]],
                        )
                    })
                };
                if cross(ta, tb) || cross(tb, ta) {
                    hit |= 1 << object_of[u as usize];
                }
            });
            (hit != 0).then_some((k, hit))
        })
        .collect()
}

/// Repairs `positions` (one array per garment, innermost first) against each other and the
/// body (see the module docs). `body_field` and the garments' fields give the push directions.
/// Vertex numbering for the exact test is that of the analysis: the garments concatenated in
/// order, then the body.
pub fn repair(
    body: Option<(&Mesh, &dyn LayerField)>,
    layers: &[RepairLayer],
    positions: &mut [Vec<Vec3>],
    params: &RepairParams,
) -> Vec<LayerRepair> {
    let ng = layers.len();
    let mut starts = Vec::with_capacity(ng + 1);
    let mut n = 0u32;
    for l in layers {
        starts.push(n);
        n += l.mesh.positions.len() as u32;
    }
    let body_start = n;
    let mut pos: Vec<Vec3> = positions.iter().flatten().copied().collect();
    if let Some((b, _)) = body {
        pos.extend_from_slice(&b.positions);
    }
    let mut reports = vec![LayerRepair::default(); ng];
    if params.steps == 0 {
        return reports;
    }
    for k in 0..ng {
        // The layers below: body (object 0) and garments 0..k (objects 1..=k).
        let mut others: Vec<[u32; 3]> = Vec::new();
        let mut object_of: Vec<u32> = Vec::new();
        if let Some((b, _)) = body {
            others.extend(b.triangles.iter().map(|t| t.map(|v| v + body_start)));
            object_of.resize(others.len(), 0);
        }
        for j in 0..k {
            others.extend(
                layers[j]
                    .mesh
                    .triangles
                    .iter()
                    .map(|t| t.map(|v| v + starts[j])),
            );
            object_of.resize(others.len(), j as u32 + 1);
        }
        if others.is_empty() {
            continue;
        }
        let boxes: Vec<Aabb> = others
            .iter()
            .map(|t| Aabb::from_points(t.iter().map(|&v| &pos[v as usize])))
            .collect();
        let bvh = Bvh::build(&boxes);
        let layer = &layers[k];
        let nv = layer.mesh.positions.len();
        let base = starts[k] as usize;
        let step = (params.step * layer.separation).max(params.min_step);
        let mut total = vec![0.0f64; nv];
        let rep = &mut reports[k];
        for it in 0..=params.steps {
            let hits = crossing_triangles(
                &layer.mesh.triangles,
                starts[k],
                &pos,
                &others,
                &object_of,
                &bvh,
            );
            if it == 0 {
                rep.crossing_triangles = hits.len();
            }
            rep.remaining = hits.len();
            if hits.is_empty() || it == params.steps {
                break;
            }
            rep.steps = it + 1;
            // Per vertex: the objects crossed around it.
            let mut crossed = vec![0u32; nv];
            for &(t, bits) in &hits {
                for &v in &layer.mesh.triangles[t] {
                    crossed[v as usize] |= bits;
                }
            }
            // Push direction: the sum of the gradients of the crossed layers' fields.
            let dir: Vec<Vec3> = (0..nv)
                .into_par_iter()
                .map(|v| {
                    if crossed[v] == 0 {
                        return Vec3::zeros();
                    }
                    let p = pos[base + v];
                    let mut d = Vec3::zeros();
                    for o in 0..=k {
                        if crossed[v] & (1 << o) == 0 {
                            continue;
                        }
                        let f: Option<&dyn LayerField> = if o == 0 {
                            body.map(|b| b.1)
                        } else {
                            Some(layers[o - 1].field)
                        };
                        if let Some((_, g)) = f.and_then(|f| f.field(&p)) {
                            let l = g.norm();
                            if l > 0.0 {
                                d += g / l;
                            }
                        }
                    }
                    let l = d.norm();
                    if l > 0.0 {
                        d / l
                    } else {
                        // No field there: the layer's own field, else stay.
                        layer
                            .field
                            .field(&p)
                            .map_or(Vec3::zeros(), |(_, g)| g.normalize())
                    }
                })
                .collect();
            // Bump: full push at the crossing vertices, halved per ring, direction inherited.
            let mut amount = vec![0.0f64; nv];
            let mut bump_dir = dir.clone();
            let mut frontier: Vec<usize> = (0..nv).filter(|&v| crossed[v] != 0).collect();
            for &v in &frontier {
                amount[v] = step;
            }
            let mut a = step;
            for _ in 0..params.rings {
                a *= 0.5;
                let mut next = Vec::new();
                for &v in &frontier {
                    for &u in layer.topo.vertex_neighbors.row(v) {
                        let u = u as usize;
                        if amount[u] == 0.0 {
                            amount[u] = a;
                            bump_dir[u] = bump_dir[v];
                            next.push(u);
                        }
                    }
                }
                frontier = next;
            }
            for v in 0..nv {
                if amount[v] > 0.0 {
                    pos[base + v] += bump_dir[v] * amount[v];
                    total[v] += amount[v];
                }
            }
        }
        rep.vertices = total.iter().filter(|&&x| x > 0.0).count();
        rep.max_push = total.iter().copied().fold(0.0, f64::max);
        positions[k].copy_from_slice(&pos[base..base + nv]);
    }
    reports
}
