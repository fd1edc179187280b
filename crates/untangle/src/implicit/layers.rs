//! The layered-untangling pipeline (Buffet et al. 2019, Fig. 2): fields per garment (Sec. 4),
//! the body as a closed field of infinite weight, projection of every garment (Sec. 6), and the
//! verification of the output with the global intersection analysis.

use super::field::GarmentField;
use super::grid::Grid;
use super::hrbf::Hrbf;
use super::operators::MAX_LAYERS;
use super::projection::{project_layer, Composer, Layer, LayerProjection, ProjectionParams};
use super::repair::{repair, LayerRepair, PairRepair, RepairLayer, RepairParams};
use super::sampling;
use crate::analysis::{self, AnalysisMesh, ObjectKind};
use crate::error::{Error, Result};
use crate::geom::{Aabb, Vec3};
use crate::mesh::{Mesh, Topology};
use rayon::prelude::*;
use std::time::Instant;

/// How the fields of one garment (or the body) are built and cached (Sec. 4).
#[derive(Clone, Debug)]
pub struct FieldParams {
    /// Target number of Poisson-disk samples of the surface (HRBF centres of `f_i`).
    pub samples: usize,
    /// Most boundary samples for the co-variant field `h_i`.
    pub boundary_samples: usize,
    /// Interior vertices where `h_i` is pinned to minus the distance to the boundary (0: the
    /// paper's boundary-only field).
    pub interior_samples: usize,
    /// Layers of value constraints beyond the open boundary in the co-variant field (0: none,
    /// see [`sampling::exterior_values`]).
    pub exterior_layers: usize,
    /// Grid cell; `None`: chosen so that the grid has about `max_nodes` nodes.
    pub cell: Option<f64>,
    /// Node budget of the grid when `cell` is `None`.
    pub max_nodes: usize,
    /// Margin around the mesh's box covered by the grid, relative to the box diagonal.
    pub margin: f64,
    /// Penetrations deeper than this fraction of the garment's box diagonal are not corrected
    /// (the layer is inactive where `|f_i|` exceeds it); the body has no limit.
    pub depth_limit: f64,
    /// The influence region is `h_i < rim_margin · s` (`s`: boundary sample spacing), so that the
    /// garment's own rim, where `h_i ≈ 0`, lies inside it.
    pub rim_margin: f64,
    /// Width of the band beyond the co-variant field's rim across which the influence fades
    /// out, relative to the box diagonal (see [`super::field`]).
    pub rim_fade: f64,
    /// Width of the band beyond `depth_limit` across which the influence fades out, relative to
    /// the box diagonal.
    pub depth_fade: f64,
    /// Fill the grids exactly only in the band where the layer can be present
    /// (`|f_i| < depth_limit + depth_fade`) and with a signed far-field value elsewhere (see
    /// [`super::band`]); the body (no depth limit) is always filled exactly.
    pub narrow_band: bool,
    /// Seed of the sampling.
    pub seed: u64,
}

impl Default for FieldParams {
    fn default() -> Self {
        FieldParams {
            samples: 600,
            boundary_samples: 300,
            interior_samples: 150,
            exterior_layers: 2,
            cell: None,
            max_nodes: 400_000,
            margin: 0.15,
            depth_limit: 0.1,
            rim_margin: 0.5,
            rim_fade: 0.04,
            depth_fade: 0.1,
            narrow_band: true,
            seed: 1,
        }
    }
}

/// Builds the cached fields of a mesh: `f` from Poisson-disk samples with outward normals
/// (outward = away from `centre`), `h` from the open-boundary samples (none when the mesh is
/// closed or `closed` is set, as for the body). Runs inside rayon's pool
/// ([`crate::pool::in_pool`]).
pub fn build_field(
    mesh: &Mesh,
    centre: &Vec3,
    closed: bool,
    params: &FieldParams,
) -> Result<GarmentField> {
    crate::pool::in_pool(|| build_field_in_pool(mesh, centre, closed, params))
}

/// [`build_field`]'s body.
fn build_field_in_pool(
    mesh: &Mesh,
    centre: &Vec3,
    closed: bool,
    params: &FieldParams,
) -> Result<GarmentField> {
    mesh.validate()?;
    if params.samples < 4 {
        return Err(Error::Parameter(format!(
            "at least 4 surface samples are needed, got {}",
            params.samples
        )));
    }
    let t0 = Instant::now();
    let topo = Topology::new(mesh)?;
    let flips = sampling::outward_flips(mesh, &topo, centre);
    let vn = sampling::vertex_normals(mesh, &flips);
    let surf = sampling::poisson_disk(mesh, &vn, params.samples, params.seed);
    let boundary = if closed {
        sampling::Samples::default()
    } else {
        let b = sampling::boundary_samples(mesh, &topo, &flips, surf.spacing * 0.5);
        sampling::thin(b, params.boundary_samples)
    };
    let t1 = Instant::now();
    // The two fits are independent: run them side by side.
    let ((f, f_ms), (h, h_ms)) = rayon::join(
        || {
            let t = Instant::now();
            let f = Hrbf::fit(&surf.points, &surf.normals)
                .map_err(|e| Error::input(mesh.place(), format!("surface field: {e}")));
            (f, t.elapsed().as_secs_f64() * 1e3)
        },
        || {
            let t = Instant::now();
            if boundary.points.is_empty() {
                return (Ok(None), 0.0);
            }
            let (mut vp, mut vv) = sampling::interior_values(mesh, &topo, params.interior_samples);
            if params.exterior_layers > 0 {
                let (ep, ev) = sampling::exterior_values(
                    &boundary,
                    &surf,
                    2.0 * surf.spacing,
                    params.exterior_layers,
                );
                vp.extend(ep);
                vv.extend(ev);
            }
            let h = Hrbf::fit_mixed(&boundary.points, &boundary.normals, &vp, &vv)
                .map(Some)
                .map_err(|e| Error::input(mesh.place(), format!("co-variant field: {e}")));
            (h, t.elapsed().as_secs_f64() * 1e3)
        },
    );
    let (f, h) = (f?, h?);
    let t3 = Instant::now();
    let bbox0 = Aabb::from_points(&mesh.positions);
    let diag = bbox0.extent().norm();
    let bbox = bbox0.inflated(params.margin * diag);
    let cell = match params.cell {
        Some(c) if c > 0.0 && c.is_finite() => c,
        Some(c) => {
            return Err(Error::Parameter(format!(
                "grid cell must be positive, got {c}"
            )))
        }
        None => {
            let e = bbox.extent();
            (e.x * e.y * e.z / params.max_nodes.max(8) as f64).cbrt()
        }
    };
    let depth_limit = if closed {
        f64::INFINITY
    } else {
        params.depth_limit * diag
    };
    let depth_fade = (params.depth_fade * diag).max(1e-12);
    let (fg, hg, exact_fraction) = if params.narrow_band && depth_limit.is_finite() {
        // Beyond `depth_limit + depth_fade` the layer is absent (fade 1, see `super::field`).
        let band = depth_limit + depth_fade;
        let (fg, mask) = Grid::build_band(
            &bbox,
            cell,
            0.0,
            band,
            &mesh.positions,
            |p, dx, first, out| f.eval_row_from(p, dx, first, out),
        );
        // `h_i` only matters across its fade band (below it: fully present; beyond: absent).
        let h_margin = params.rim_margin * boundary.spacing;
        let rim_fade = (params.rim_fade * diag).max(1e-12);
        let hg = h.as_ref().map(|h| {
            Grid::build_band(
                &bbox,
                cell,
                h_margin + 0.5 * rim_fade,
                0.5 * rim_fade,
                &[],
                |p, dx, first, out| h.eval_row_from(p, dx, first, out),
            )
        });
        let hfrac = hg.as_ref().map_or(0.0, |g| g.1.exact_fraction());
        let parts = 1.0 + hg.is_some() as usize as f64;
        (fg, hg.map(|g| g.0), (mask.exact_fraction() + hfrac) / parts)
    } else {
        let fg = Grid::build_rows(&bbox, cell, |p, dx, out| f.eval_row(p, dx, out));
        let hg = h
            .as_ref()
            .map(|h| Grid::build_rows(&bbox, cell, |p, dx, out| h.eval_row(p, dx, out)));
        (fg, hg, 1.0)
    };
    let t4 = Instant::now();
    let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
    Ok(GarmentField {
        f: fg,
        h: hg,
        num_samples: surf.points.len(),
        num_boundary_samples: boundary.points.len(),
        h_margin: params.rim_margin * boundary.spacing,
        rim_fade: (params.rim_fade * diag).max(1e-12),
        depth_limit,
        depth_fade,
        exact_fraction,
        timing_ms: [ms(t0, t1), f_ms, h_ms, ms(t3, t4)],
    })
}

/// One garment to dress, in layer order (innermost first).
#[derive(Clone, Copy, Debug)]
pub struct GarmentInput<'a> {
    /// The mesh.
    pub mesh: &'a Mesh,
    /// Cloth thickness `t_i` (Sec. 6.2).
    pub thickness: f64,
    /// Stiffness weight `w_i` (Sec. 5).
    pub weight: f64,
}

impl<'a> GarmentInput<'a> {
    /// Every mesh of `meshes`, in their order, with the same thickness and weight.
    pub fn all_alike(meshes: &'a [Mesh], thickness: f64, weight: f64) -> Vec<Self> {
        meshes
            .iter()
            .map(|mesh| GarmentInput {
                mesh,
                thickness,
                weight,
            })
            .collect()
    }
}

/// Parameters of [`untangle_layers`].
#[derive(Clone, Debug, Default)]
pub struct Params {
    /// Field construction for the garments.
    pub fields: FieldParams,
    /// Field construction for the body (`None`: same as the garments).
    pub body_fields: Option<FieldParams>,
    /// Thickness given to the body's surface (usually 0).
    pub body_thickness: f64,
    /// Projection; `tolerance` and `max_step` of 0 are derived from the scene (1e-3 of the
    /// smallest non-zero thickness or of the grid cell; twice the grid cell).
    pub projection: ProjectionParams,
    /// Repair of the crossings the projection leaves (`steps: 0` turns it off).
    pub repair: RepairParams,
}

/// Progress of [`untangle_layers`].
#[derive(Clone, Copy, Debug)]
pub enum Stage {
    /// Field `done` of `total` built (the body first when present).
    Field {
        /// Fields built so far.
        done: usize,
        /// Fields to build.
        total: usize,
    },
    /// Garment `layer` (0-based, innermost first): Newton pass `iteration` done.
    Projection {
        /// Garment index.
        layer: usize,
        /// Newton passes so far.
        iteration: usize,
    },
}

/// Per-garment outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LayerReport {
    /// The garment's name.
    pub name: String,
    /// Vertices.
    pub vertices: usize,
    /// Vertices that moved.
    pub moved: usize,
    /// Largest displacement.
    pub max_displacement: f64,
    /// Vertices that ended merged with another layer (in contact).
    pub in_contact: usize,
    /// Newton passes.
    pub iterations: usize,
    /// Largest final `|f̂_i − ε_v|`.
    pub max_residual: f64,
    /// Vertices above the tolerance.
    pub unconverged: usize,
    /// Surface samples of its HRBF.
    pub samples: usize,
    /// Boundary samples of its co-variant field.
    pub boundary_samples: usize,
    /// Grid nodes of its cache.
    pub grid_nodes: usize,
    /// Fraction of the grid nodes' blocks filled exactly (see [`super::band`]).
    pub grid_exact_fraction: f64,
    /// Field precomputation time, ms.
    pub field_ms: f64,
    /// Its steps, ms: sampling, fit of `f`, fit of `h`, grids.
    pub field_steps_ms: [f64; 4],
    /// Projection time of this garment, ms (wall; the garments are projected side by side, so
    /// these overlap: [`Untangled::projection_ms`] is the total).
    pub projection_ms: f64,
}

/// The untangled garments.
#[derive(Clone, Debug)]
pub struct Untangled {
    /// New positions of each garment.
    pub positions: Vec<Vec<Vec3>>,
    /// The projection details of each garment.
    pub projections: Vec<LayerProjection>,
    /// Per-garment summary.
    pub reports: Vec<LayerReport>,
    /// Body field time, ms (0 without body).
    pub body_field_ms: f64,
    /// Tolerance used.
    pub tolerance: f64,
    /// What the repair did to each garment.
    pub repair: Vec<LayerRepair>,
    /// What the symmetric phase of the repair did.
    pub pair_repair: PairRepair,
    /// Projection time (all garments), ms.
    pub projection_ms: f64,
    /// Repair time, ms.
    pub repair_ms: f64,
}

/// Checks the inputs and returns the centre used to orient normals.
fn check_inputs(body: Option<&Mesh>, garments: &[GarmentInput]) -> Result<Vec3> {
    if garments.is_empty() {
        return Err(Error::Parameter("no garment to untangle".into()));
    }
    if garments.len() + 1 > MAX_LAYERS {
        return Err(Error::Parameter(format!(
            "at most {} garments are supported, got {}",
            MAX_LAYERS - 1,
            garments.len()
        )));
    }
    for g in garments {
        g.mesh.validate()?;
        if !(g.thickness.is_finite() && g.thickness >= 0.0) {
            return Err(Error::input(
                g.mesh.place(),
                format!("thickness must be finite and >= 0, got {}", g.thickness),
            ));
        }
        if !(g.weight.is_finite() && g.weight > 0.0) {
            return Err(Error::input(
                g.mesh.place(),
                format!("weight must be finite and > 0, got {}", g.weight),
            ));
        }
    }
    if let Some(b) = body {
        b.validate()?;
        return Ok(b.positions.iter().sum::<Vec3>() / b.positions.len().max(1) as f64);
    }
    let all: Vec<&Vec3> = garments.iter().flat_map(|g| &g.mesh.positions).collect();
    Ok(all.iter().copied().sum::<Vec3>() / all.len().max(1) as f64)
}

/// Dresses `body` in `garments` (innermost first): builds the fields and projects every garment
/// onto its untangled iso-surface (Sec. 4–6).
pub fn untangle_layers(
    body: Option<&Mesh>,
    garments: &[GarmentInput],
    params: &Params,
    progress: &(dyn Fn(Stage) + Sync),
) -> Result<Untangled> {
    let centre = check_inputs(body, garments)?;
    let total = garments.len() + body.is_some() as usize;
    let mut done = 0;
    progress(Stage::Field { done, total });
    let t = Instant::now();
    let body_field = match body {
        Some(b) => {
            let bp = params.body_fields.as_ref().unwrap_or(&params.fields);
            let f = build_field(b, &centre, true, bp)?;
            done += 1;
            progress(Stage::Field { done, total });
            Some(f)
        }
        None => None,
    };
    let body_field_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut fields = Vec::with_capacity(garments.len());
    let mut field_ms = Vec::with_capacity(garments.len());
    for g in garments {
        let t = Instant::now();
        fields.push(build_field(g.mesh, &centre, false, &params.fields)?);
        field_ms.push(t.elapsed().as_secs_f64() * 1e3);
        done += 1;
        progress(Stage::Field { done, total });
    }
    untangle_with_fields(
        body.zip(body_field.as_ref()),
        garments,
        &fields,
        &field_ms,
        body_field_ms,
        params,
        progress,
    )
}

/// Projection with precomputed fields (e.g. from a garment library), run inside rayon's pool
/// ([`crate::pool::in_pool`]).
pub fn untangle_with_fields(
    body: Option<(&Mesh, &GarmentField)>,
    garments: &[GarmentInput],
    fields: &[GarmentField],
    field_ms: &[f64],
    body_field_ms: f64,
    params: &Params,
    progress: &(dyn Fn(Stage) + Sync),
) -> Result<Untangled> {
    crate::pool::in_pool(|| {
        if fields.len() != garments.len() {
            return Err(Error::Parameter("one field per garment is needed".into()));
        }
        let mut layers: Vec<Layer> = Vec::new();
        if let Some((_, b)) = body {
            layers.push(Layer {
                field: b,
                weight: f64::INFINITY,
                thickness: params.body_thickness,
            });
        }
        let offset = layers.len();
        for (g, f) in garments.iter().zip(fields) {
            layers.push(Layer {
                field: f,
                weight: g.weight,
                thickness: g.thickness,
            });
        }
        let composer =
            Composer::new(&layers)?.with_scaled_offsets(params.projection.scaled_offsets);
        let min_cell = fields
            .iter()
            .map(|f| f.f.cell)
            .fold(f64::INFINITY, f64::min);
        let mut pp = params.projection.clone();
        let min_t = garments
            .iter()
            .map(|g| g.thickness)
            .filter(|&t| t > 0.0)
            .fold(f64::INFINITY, f64::min);
        if pp.tolerance <= 0.0 {
            pp.tolerance = 1e-3 * if min_t.is_finite() { min_t } else { min_cell };
        }
        if pp.max_step <= 0.0 {
            pp.max_step = 2.0 * min_cell;
        }
        let mut out = Untangled {
            positions: Vec::new(),
            projections: Vec::new(),
            reports: Vec::new(),
            body_field_ms,
            tolerance: pp.tolerance,
            repair: Vec::new(),
            pair_repair: PairRepair::default(),
            projection_ms: 0.0,
            repair_ms: 0.0,
        };
        let t_all = Instant::now();
        // The garments' topologies, side by side (each is sequential).
        let topos: Vec<Topology> = garments
            .par_iter()
            .map(|g| Topology::new(g.mesh))
            .collect::<Result<_>>()?;
        // Every garment is projected onto its own corrected iso-surface, which depends on the
        // fields only (Sec. 6.3), not on the other garments' meshes: the projections run side by
        // side (each is parallel over its vertices, with Jacobi updates, so the result does not
        // depend on the thread count or on the interleaving). On two cores this keeps both busy
        // through the sequential parts of each projection's passes.
        let projected: Vec<(LayerProjection, f64)> = garments
            .par_iter()
            .enumerate()
            .map(|(k, g)| {
                let t = Instant::now();
                let pr = project_layer(
                    &composer,
                    offset + k,
                    &g.mesh.positions,
                    &g.mesh.triangles,
                    &topos[k],
                    &pp,
                    &|iteration| {
                        progress(Stage::Projection {
                            layer: k,
                            iteration,
                        })
                    },
                );
                (pr, t.elapsed().as_secs_f64() * 1e3)
            })
            .collect();
        for (k, (g, (pr, ms))) in garments.iter().zip(projected).enumerate() {
            let max_displacement = pr
                .positions
                .iter()
                .zip(&g.mesh.positions)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            let f = &fields[k];
            out.reports.push(LayerReport {
                name: g.mesh.name.clone(),
                vertices: g.mesh.positions.len(),
                moved: pr.moved.iter().filter(|&&m| m).count(),
                max_displacement,
                in_contact: pr
                    .run
                    .iter()
                    .filter(|r| **r != (offset + k, offset + k))
                    .count(),
                iterations: pr.iterations,
                max_residual: pr.residual.iter().copied().fold(0.0, f64::max),
                unconverged: pr.unconverged,
                samples: f.num_samples,
                boundary_samples: f.num_boundary_samples,
                grid_nodes: f.f.num_nodes() + f.h.as_ref().map_or(0, |h| h.num_nodes()),
                grid_exact_fraction: f.exact_fraction,
                field_ms: field_ms.get(k).copied().unwrap_or(0.0),
                field_steps_ms: f.timing_ms,
                projection_ms: ms,
            });
            out.projections.push(pr);
        }
        out.projection_ms = t_all.elapsed().as_secs_f64() * 1e3;
        if params.repair.steps > 0 || params.repair.pair_rounds > 0 {
            let t = Instant::now();
            // Per garment vertex: merged with the layer below / above (the runs, as measured by
            // `measure_separation`).
            let contacts: Vec<Vec<u8>> = out
                .projections
                .iter()
                .enumerate()
                .map(|(k, pr)| {
                    let me = offset + k;
                    pr.run
                        .iter()
                        .zip(&pr.active)
                        .map(|(run, &act)| {
                            let below = me > 0 && run.0 < me && act & (1 << (me - 1)) != 0;
                            let above = run.1 > me && act & (1 << (me + 1)) != 0;
                            (below as u8 * super::repair::CONTACT_BELOW)
                                | (above as u8 * super::repair::CONTACT_ABOVE)
                        })
                        .collect()
                })
                .collect();
            let rl: Vec<RepairLayer> = garments
                .iter()
                .enumerate()
                .map(|(k, g)| RepairLayer {
                    mesh: g.mesh,
                    topo: &topos[k],
                    field: &fields[k],
                    weight: g.weight,
                    separation: 0.5 * g.thickness
                        + if k > 0 {
                            0.5 * garments[k - 1].thickness
                        } else {
                            0.5 * params.body_thickness
                        },
                    contacts: &contacts[k],
                })
                .collect();
            let mut positions: Vec<Vec<Vec3>> = out
                .projections
                .iter()
                .map(|p| p.positions.clone())
                .collect();
            (out.repair, out.pair_repair) = repair(
                body.map(|(m, f)| (m, f as &dyn super::field::LayerField)),
                &rl,
                &mut positions,
                &params.repair,
            );
            out.repair_ms = t.elapsed().as_secs_f64() * 1e3;
            for (k, p) in positions.into_iter().enumerate() {
                let pr = &mut out.projections[k];
                for (v, (a, b)) in p.iter().zip(&pr.positions).enumerate() {
                    if a != b {
                        pr.moved[v] = true;
                        pr.repaired[v] = true;
                    }
                }
                pr.positions = p;
                let r = &mut out.reports[k];
                r.moved = pr.moved.iter().filter(|&&m| m).count();
                r.max_displacement = pr
                    .positions
                    .iter()
                    .zip(&garments[k].mesh.positions)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
            }
        }
        out.positions = out
            .projections
            .iter()
            .map(|p| p.positions.clone())
            .collect();
        Ok(out)
    })
}

/// Intersections left between the garments and with the body, by the global intersection
/// analysis (Wicke et al. 2006).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Verification {
    /// Intersecting triangle pairs between two different garments.
    pub between_layers: usize,
    /// Intersecting triangle pairs between a garment and the body.
    pub with_body: usize,
    /// Self-intersecting triangle pairs within one garment (not the untangler's job, reported).
    pub self_intersections: usize,
    /// Per garment: triangle pairs it shares with another garment or the body.
    pub per_layer: Vec<usize>,
}

impl Verification {
    /// No intersection between layers or with the body.
    pub fn is_clean(&self) -> bool {
        self.between_layers == 0 && self.with_body == 0
    }
}

/// Runs the analysis on the garments at `positions` (and the body, unchanged).
pub fn verify(
    body: Option<&Mesh>,
    garments: &[&Mesh],
    positions: &[Vec<Vec3>],
) -> Result<Verification> {
    let moved: Vec<Mesh> = garments
        .iter()
        .zip(positions)
        .map(|(m, p)| Mesh {
            positions: p.clone(),
            ..(*m).clone()
        })
        .collect();
    let mut parts: Vec<(&Mesh, ObjectKind)> =
        moved.iter().map(|m| (m, ObjectKind::Cloth)).collect();
    if let Some(b) = body {
        parts.push((b, ObjectKind::Obstacle));
    }
    let (am, pos) = AnalysisMesh::new(&parts)?;
    let a = analysis::analyze(&am, &pos)
        .map_err(|e| Error::Parameter(format!("intersection analysis failed: {e:?}")))?;
    let ng = garments.len();
    let mut v = Verification {
        per_layer: vec![0; ng],
        ..Default::default()
    };
    for s in &a.segments {
        let [oa, ob] = s
            .triangles
            .map(|t| am.object_of_triangle[t as usize] as usize);
        if oa == ob {
            v.self_intersections += 1;
        } else if oa >= ng || ob >= ng {
            v.with_body += 1;
            v.per_layer[oa.min(ob)] += 1;
        } else {
            v.between_layers += 1;
            v.per_layer[oa] += 1;
            v.per_layer[ob] += 1;
        }
    }
    Ok(v)
}

/// Measured separation of every garment from the layer directly below it (the previous garment,
/// or the body for the innermost), over the vertices that ended merged with it (Table 3
/// analogue; see [`super::separation::Separation`] for the one-sided, face-to-face and
/// two-sided figures). `None` entries: nothing below (innermost garment without body).
pub fn measure_separation(
    body: Option<&Mesh>,
    garments: &[GarmentInput],
    out: &Untangled,
    body_thickness: f64,
) -> Vec<Option<super::separation::Separation>> {
    use super::separation::{summarize, MeshDistance};
    let offset = body.is_some() as usize;
    (0..garments.len())
        .map(|k| {
            let (below_pos, below_tris, below_t, name): (&[Vec3], &[[u32; 3]], f64, String) =
                if k > 0 {
                    (
                        &out.positions[k - 1],
                        &garments[k - 1].mesh.triangles,
                        garments[k - 1].thickness,
                        garments[k - 1].mesh.name.clone(),
                    )
                } else if let Some(b) = body {
                    (&b.positions, &b.triangles, body_thickness, "body".into())
                } else {
                    return None;
                };
            let expected = 0.5 * (garments[k].thickness + below_t);
            let me = offset + k;
            let md = MeshDistance::new(below_pos, below_tris);
            let radius = 3.0 * expected + 0.01;
            let no_repair = vec![false; below_pos.len()];
            let below_repaired: &[bool] = if k > 0 {
                &out.projections[k - 1].repaired
            } else {
                &no_repair
            };
            let pk = &out.projections[k];
            // (distance, |cos|, untouched by the repair) per contact vertex of this layer.
            let d: Vec<(f64, f64, bool)> = out.positions[k]
                .iter()
                .enumerate()
                .filter(|&(v, _)| pk.run[v].0 < me && pk.active[v] & (1 << (me - 1)) != 0)
                .filter_map(|(v, p)| {
                    let (d, c, t) = md.nearest_within(p, radius)?;
                    let kept = !pk.repaired[v]
                        && below_tris[t].iter().all(|&u| !below_repaired[u as usize]);
                    Some((d, c, kept))
                })
                .collect();
            // The other way: vertices of the layer below merged with this one, to this mesh
            // (the body never moves and has no run: only the one-sided figure applies).
            let inner: Option<Vec<(f64, f64, bool)>> = (k > 0).then(|| {
                let tris = &garments[k].mesh.triangles;
                let up = MeshDistance::new(&out.positions[k], tris);
                let (lo, pl) = (me - 1, &out.projections[k - 1]);
                out.positions[k - 1]
                    .iter()
                    .enumerate()
                    .filter(|&(v, _)| pl.run[v].1 > lo && pl.active[v] & (1 << me) != 0)
                    .filter_map(|(v, p)| {
                        let (d, c, t) = up.nearest_within(p, radius)?;
                        let kept =
                            !pl.repaired[v] && tris[t].iter().all(|&u| !pk.repaired[u as usize]);
                        Some((d, c, kept))
                    })
                    .collect()
            });
            let face = |x: &[(f64, f64, bool)], only_kept: bool| -> Vec<f64> {
                x.iter()
                    .filter(|e| e.1 >= 0.99 && (e.2 || !only_kept))
                    .map(|e| e.0)
                    .collect()
            };
            let inner = inner.unwrap_or_default();
            let mut s = summarize(k, name.clone(), expected, d.iter().map(|x| x.0).collect());
            let both = |only_kept| {
                Box::new(super::separation::two_sided(
                    k,
                    name.clone(),
                    expected,
                    &face(&d, only_kept),
                    &face(&inner, only_kept),
                ))
            };
            s.two_sided = Some(both(false));
            s.unrepaired = Some(both(true));
            if k > 0 {
                s.inner_face = Some(Box::new(summarize(
                    k,
                    name.clone(),
                    expected,
                    face(&inner, false),
                )));
            }
            s.face = Some(Box::new(summarize(k, name, expected, face(&d, false))));
            Some(s)
        })
        .collect()
}
