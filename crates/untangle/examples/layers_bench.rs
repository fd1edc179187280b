//! Benchmark of the layered untangling (Buffet et al. 2019, Tables 1 and 2 analogues):
//! field precomputation per garment, projection time against the number of vertices
//! (subdivision levels) and against the number of layers.
//!
//! `cargo run -p untangle --release --example layers_bench [LEVELS] [SHARED]`
//!
//! Environment: `LAYERS_BENCH_VERBOSE=1` prints, per row, the repair reports, the measured
//! separations (Table 3 analogue) and the result of the projection alone (a second run with the
//! repair off); `LAYERS_BENCH_ORDER=pants3,tshirt,...` changes the garments and their order;
//! `LAYERS_BENCH_FULL_GRID=1` fills the grids exactly everywhere (no narrow band);
//! `LAYERS_BENCH_ROWS=4:4,3:2` runs only these (subdivision : garments) rows;
//! `LAYERS_BENCH_SELF_GUARD=p|r|pr` turns the self-intersection guards on (projection / repair);
//! `LAYERS_BENCH_RELAX_SKIP=x`, `LAYERS_BENCH_NO_ACTIVE_SET=1`, `LAYERS_BENCH_GUARD_INTERVAL=n` set
//! projection knobs; `LAYERS_BENCH_FIELD_CHECK=1` (with VERBOSE) samples the lower layer's field
//! at the contact vertices;
//! `LAYERS_BENCH_COMPARE=1` also runs with full grids and prints how far the outputs differ;
//! `LAYERS_BENCH_SETTLE=n` sets the repair's settle rounds (0: off);
//! `LAYERS_BENCH_SNAP=x[,rounds[,follow]]` sets `RepairParams::snap_tolerance` (default 0.1;
//! negative: off) and optionally `snap_rounds` and `snap_follow` (1 / 0);
//! `LAYERS_BENCH_SETTLE_COARSE=n[,edge]` sets `RepairParams::settle_rounds_coarse` and
//! optionally `coarse_edge` (in thickness rules);
//! `LAYERS_BENCH_STREAK=n[,max]` sets the pair phase's acceleration of persistent crossings
//! (`RepairParams::pair_streak`, `pair_streak_max`; `0` restores fixed steps);
//! `LAYERS_BENCH_NO_SELF_SEPARATION=1` turns off the repair's separation of self-intersections,
//! `LAYERS_BENCH_SELF_SMOOTHING=x` sets its smoothing;
//! `LAYERS_BENCH_PLAIN_OFFSETS=1` uses eq. 13's thickness offsets as written (no gradient
//! scaling, see `implicit::thickness::scaled_offsets`); `LAYERS_BENCH_REPAIR=step,bump` sets the
//! repair's push step and bump radius (optional third and fourth values: push steps and pair
//! rounds without progress); `LAYERS_BENCH_GAP_CHECK=1` (with VERBOSE) rebuilds the
//! fields and prints, at the contact vertices, the mesh gap against the implicit gap between
//! the corrected surfaces, split by the length of the merged run.
use std::path::PathBuf;
use std::time::Instant;
use untangle::geom::Vec3;
use untangle::implicit::layers::Stage;
use untangle::implicit::layers::{build_field, measure_separation, Untangled};
use untangle::implicit::separation::{MeshDistance, Separation};
use untangle::implicit::GarmentField;
use untangle::implicit::*;
use untangle::mesh::Mesh;

/// CPU time (user + system, all threads) of this process so far, seconds (Linux `/proc`; 0
/// elsewhere). The machine is shared, so CPU time is reported beside wall-clock time.
fn cpu_s() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command name (which is in parentheses): state is field 3, utime 14,
    // stime 15, in clock ticks (100 per second on Linux).
    let rest = &stat[stat.rfind(')').map_or(0, |i| i + 1)..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| {
        f.get(i - 3)
            .and_then(|x| x.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (tick(14) + tick(15)) / 100.0
}

fn main() {
    let max_level: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let shared = std::env::args()
        .nth(2)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")));
    // LAYERS_BENCH_ORDER=a,b,c: another garment order (innermost first).
    let order: Option<Vec<String>> = std::env::var("LAYERS_BENCH_ORDER")
        .ok()
        .map(|s| s.split(',').map(str::to_string).collect());
    let owned: Vec<&str> = order
        .as_ref()
        .map(|o| o.iter().map(String::as_str).collect())
        .unwrap_or_else(|| untangle::scenes::outfit::GARMENTS.to_vec());
    let all = &owned[..];
    println!("threads: {}", rayon::current_num_threads());
    println!("| layers (incl. body) | subdiv | vertices | fields (s) | max field per garment (s) | projection (s) | repair (s) | passes | between | with body | self (in → out) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for level in 1..=max_level {
        for k in 1..=all.len() {
            if level < max_level && k < all.len() {
                continue;
            }
            if let Ok(rows) = std::env::var("LAYERS_BENCH_ROWS") {
                // LAYERS_BENCH_ROWS=4:4,3:2 — only these (subdivision : garments) rows.
                if !rows.split(',').any(|r| r == format!("{level}:{k}")) {
                    continue;
                }
            }
            let (body, garments) =
                untangle::scenes::outfit::arcsim_outfit(&shared, &all[..k], level).expect("data");
            let inputs = GarmentInput::all_alike(&garments, 0.01, 1.0);
            let mut params = Params::default();
            params.fields.narrow_band = std::env::var_os("LAYERS_BENCH_FULL_GRID").is_none();
            if let Some(x) = std::env::var("LAYERS_BENCH_RELAX_SKIP")
                .ok()
                .and_then(|s| s.parse().ok())
            {
                params.projection.relax_skip = x;
            }
            if let Ok(x) = std::env::var("LAYERS_BENCH_SELF_GUARD") {
                // p: projection, r: repair's pair phase, pr: both, none: off.
                params.projection.prevent_self_intersections = x.contains('p');
                params.repair.prevent_self_intersections = x.contains('r');
            }
            if let Some(x) = std::env::var("LAYERS_BENCH_GUARD_INTERVAL")
                .ok()
                .and_then(|s| s.parse().ok())
            {
                params.projection.self_guard_interval = x;
            }
            if let Ok(x) = std::env::var("LAYERS_BENCH_REPAIR") {
                // step,bump: the repair's push per step and bump radius (thickness rules).
                let v: Vec<f64> = x.split(',').filter_map(|s| s.parse().ok()).collect();
                if let [step, bump, ..] = v[..] {
                    params.repair.step = step;
                    params.repair.bump = bump;
                }
                // Optional third and fourth values: push steps and pair rounds.
                if let Some(&s) = v.get(2) {
                    params.repair.steps = s as usize;
                }
                if let Some(&r) = v.get(3) {
                    params.repair.pair_rounds = r as usize;
                }
            }
            if let Ok(x) = std::env::var("LAYERS_BENCH_STREAK") {
                // n[,max]: the pair phase's step acceleration of persistent crossings (0: off).
                let v: Vec<f64> = x.split(',').filter_map(|s| s.parse().ok()).collect();
                if let Some(&n) = v.first() {
                    params.repair.pair_streak = n as usize;
                }
                if let Some(&m) = v.get(1) {
                    params.repair.pair_streak_max = m;
                }
            }
            if let Some(x) = std::env::var("LAYERS_BENCH_SETTLE")
                .ok()
                .and_then(|s| s.parse().ok())
            {
                params.repair.settle_rounds = x;
            }
            if let Ok(x) = std::env::var("LAYERS_BENCH_SNAP") {
                // tolerance[,rounds]
                let v: Vec<f64> = x.split(',').filter_map(|s| s.parse().ok()).collect();
                if let Some(&t) = v.first() {
                    params.repair.snap_tolerance = t;
                }
                if let Some(&r) = v.get(1) {
                    params.repair.snap_rounds = r as usize;
                }
                if let Some(&f) = v.get(2) {
                    params.repair.snap_follow = f != 0.0;
                }
            }
            if let Ok(x) = std::env::var("LAYERS_BENCH_SETTLE_COARSE") {
                // rounds[,coarse edge in thickness rules]
                let v: Vec<f64> = x.split(',').filter_map(|s| s.parse().ok()).collect();
                if let Some(&n) = v.first() {
                    params.repair.settle_rounds_coarse = n as usize;
                }
                if let Some(&e) = v.get(1) {
                    params.repair.coarse_edge = e;
                }
            }
            if std::env::var_os("LAYERS_BENCH_NO_SELF_SEPARATION").is_some() {
                params.repair.separate_self_intersections = false;
            }
            if let Some(x) = std::env::var("LAYERS_BENCH_SELF_SMOOTHING")
                .ok()
                .and_then(|s| s.parse().ok())
            {
                params.repair.self_smoothing = x;
            }
            if std::env::var_os("LAYERS_BENCH_PLAIN_OFFSETS").is_some() {
                params.projection.scaled_offsets = false;
            }
            if std::env::var_os("LAYERS_BENCH_NO_ACTIVE_SET").is_some() {
                params.projection.active_set = false;
            }
            let t = Instant::now();
            // CPU time at the start, when the fields are done, and at the last projection pass.
            let cpu = std::sync::Mutex::new([cpu_s(), 0.0, 0.0]);
            let out = untangle_layers(Some(&body), &inputs, &params, &|s| match s {
                Stage::Field { done, total } if done == total => cpu.lock().unwrap()[1] = cpu_s(),
                Stage::Projection { .. } => cpu.lock().unwrap()[2] = cpu_s(),
                _ => {}
            })
            .unwrap();
            let [c0, c1, c2] = *cpu.lock().unwrap();
            let c3 = cpu_s();
            let total = t.elapsed().as_secs_f64();
            let fields: f64 =
                out.body_field_ms / 1e3 + out.reports.iter().map(|r| r.field_ms).sum::<f64>() / 1e3;
            let maxf = out.reports.iter().map(|r| r.field_ms).fold(0.0, f64::max) / 1e3;
            // The garments are projected side by side: the total wall time.
            let proj: f64 = out.projection_ms / 1e3;
            let nv: usize = garments.iter().map(|m| m.positions.len()).sum();
            let refs: Vec<&untangle::mesh::Mesh> = garments.iter().collect();
            let v = verify(Some(&body), &refs, &out.positions).unwrap();
            let passes: Vec<usize> = out.reports.iter().map(|r| r.iterations).collect();
            let input: Vec<Vec<untangle::geom::Vec3>> =
                garments.iter().map(|m| m.positions.clone()).collect();
            let v_in = verify(Some(&body), &refs, &input).unwrap();
            println!(
                "| {} | {level} | {nv} | {fields:.2} | {maxf:.2} | {proj:.2} | {:.2} | {passes:?} | {} | {} | {} → {} |",
                k + 1,
                out.repair_ms / 1e3,
                v.between_layers,
                v.with_body,
                v_in.self_intersections,
                v.self_intersections
            );
            eprintln!(
                "  CPU time (s): fields {:.2}, projection {:.2}, repair {:.2}; wall projection + repair {:.2}",
                c1 - c0,
                c2 - c1,
                c3 - c2,
                (out.projection_ms + out.repair_ms) / 1e3
            );
            // FNV-1a over the output coordinates' bits: changes iff any output vertex moved.
            let hash = out
                .positions
                .iter()
                .flatten()
                .flat_map(|p| [p.x, p.y, p.z])
                .fold(0xcbf2_9ce4_8422_2325u64, |h, x| {
                    (h ^ x.to_bits()).wrapping_mul(0x0100_0000_01b3)
                });
            eprintln!("  output hash {hash:016x}");
            let pr = &out.pair_repair;
            eprintln!(
                "  repair wall (s): push {:.3}, pairs {:.3}, self {:.3}, settle {:.3}; self pairs {} -> {} in {} rounds",
                pr.push_ms / 1e3,
                pr.pairs_ms / 1e3,
                pr.self_ms / 1e3,
                pr.settle_ms / 1e3,
                pr.self_pairs,
                pr.self_remaining,
                pr.self_rounds
            );
            if std::env::var_os("LAYERS_BENCH_VERBOSE").is_some() {
                eprintln!(
                    "  per layer {:?}, self {}, projection {:.0} ms, repair {:.0} ms",
                    v.per_layer, v.self_intersections, out.projection_ms, out.repair_ms
                );
                eprintln!(
                    "  input: between {}, with body {}, self {}",
                    v_in.between_layers, v_in.with_body, v_in.self_intersections
                );
                eprintln!("  pairs {:?}", out.pair_repair);
                print_separations(
                    "",
                    &measure_separation(Some(&body), &inputs, &out, params.body_thickness),
                );
                let mut noop = params.clone();
                noop.repair.steps = 0;
                noop.repair.pair_rounds = 0;
                let o2 = untangle_layers(Some(&body), &inputs, &noop, &|_| {}).unwrap();
                let v2 = verify(Some(&body), &refs, &o2.positions).unwrap();
                eprintln!(
                    "  projection only: between {}, with body {}, self {}",
                    v2.between_layers, v2.with_body, v2.self_intersections
                );
                print_separations(
                    "projection only: ",
                    &measure_separation(Some(&body), &inputs, &o2, params.body_thickness),
                );
                for r in &out.repair {
                    eprintln!("  repair {r:?}");
                }
                if std::env::var_os("LAYERS_BENCH_GAP_CHECK").is_some() {
                    gap_check(&body, &garments, &inputs, &params, &o2);
                }
                if std::env::var_os("LAYERS_BENCH_FIELD_CHECK").is_some() {
                    field_check(&body, &garments, &params, &o2);
                }
            }
            eprintln!(
                "  evaluations per garment {:?}, repair pairs {:?}",
                out.projections
                    .iter()
                    .map(|p| p.evaluations)
                    .collect::<Vec<_>>(),
                out.pair_repair
            );
            eprintln!(
                "  unconverged vertices per garment {:?}",
                out.reports
                    .iter()
                    .map(|r| r.unconverged)
                    .collect::<Vec<_>>()
            );
            eprintln!(
                "  grid exact fraction per garment {:?}",
                out.reports
                    .iter()
                    .map(|r| (r.grid_exact_fraction * 1000.0).round() / 1000.0)
                    .collect::<Vec<_>>()
            );
            eprintln!(
                "  field steps per garment (sampling, fit f, fit h, grids; ms) {:?}",
                out.reports
                    .iter()
                    .map(|r| r.field_steps_ms.map(|x| x.round()))
                    .collect::<Vec<_>>()
            );
            if std::env::var_os("LAYERS_BENCH_COMPARE").is_some() {
                let mut full = params.clone();
                full.fields.narrow_band = !params.fields.narrow_band;
                let t = Instant::now();
                let o2 = untangle_layers(Some(&body), &inputs, &full, &|_| {}).unwrap();
                let dt = t.elapsed().as_secs_f64();
                let v2 = verify(Some(&body), &refs, &o2.positions).unwrap();
                let maxd = out
                    .positions
                    .iter()
                    .flatten()
                    .zip(o2.positions.iter().flatten())
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                let moved = out
                    .positions
                    .iter()
                    .flatten()
                    .zip(o2.positions.iter().flatten())
                    .filter(|(a, b)| a != b)
                    .count();
                eprintln!(
                    "  compare (narrow band {} vs {}): fields {:.2} s vs {:.2} s, max |Δx| {:.3e} m, {} vertices differ; other: between {}, with body {}, self {}",
                    params.fields.narrow_band,
                    full.fields.narrow_band,
                    fields,
                    o2.body_field_ms / 1e3 + o2.reports.iter().map(|r| r.field_ms).sum::<f64>() / 1e3,
                    maxd,
                    moved,
                    v2.between_layers,
                    v2.with_body,
                    v2.self_intersections
                );
                let _ = dt;
            }
            let _ = total;
        }
    }
}

/// Prints the measured separations (`label` before each line).
fn print_separations(label: &str, seps: &[Option<Separation>]) {
    for s in seps.iter().flatten() {
        let (face, two, unrep) = (
            s.face.as_deref(),
            s.two_sided.as_deref(),
            s.unrepaired.as_deref(),
        );
        eprintln!(
            "  {label}separation {} over {}: expected {:.4}, {} vertices, mean {:.5}, median {:.5}, rel. error of mean {:.2}%; face to face: {} vertices, mean {:.5}, rel. error {:.2}%; two-sided: {} distances, mean {:.5}, median {:.5}, rel. error {:.2}%; unrepaired two-sided: {} distances, mean {:.5}, rel. error {:.2}%",
            s.layer, s.against, s.expected, s.count, s.mean, s.median, 100.0 * s.relative_error,
            face.map_or(0, |f| f.count), face.map_or(0.0, |f| f.mean),
            face.map_or(0.0, |f| 100.0 * f.relative_error),
            two.map_or(0, |f| f.count), two.map_or(0.0, |f| f.mean),
            two.map_or(0.0, |f| f.median),
            two.map_or(0.0, |f| 100.0 * f.relative_error),
            unrep.map_or(0, |f| f.count), unrep.map_or(0.0, |f| f.mean),
            unrep.map_or(0.0, |f| 100.0 * f.relative_error)
        );
    }
}

/// The face-to-face contact vertices of garment `k` (its layer `k + 1`) with garment `k - 1` in
/// `out`: vertices whose run reaches below and whose layer below is active, within 4 cm of the
/// lower mesh `md` and facing it (alignment >= 0.99); with their mesh distance.
fn contact_vertices<'a>(
    out: &'a Untangled,
    k: usize,
    md: &'a MeshDistance,
) -> impl Iterator<Item = (&'a Vec3, f64)> + 'a {
    let me = k + 1;
    out.positions[k]
        .iter()
        .zip(&out.projections[k].run)
        .zip(&out.projections[k].active)
        .filter(move |((_, run), &act)| run.0 < me && act & (1 << (me - 1)) != 0)
        .filter_map(move |((p, _), _)| {
            let (d, a) = md.distance_and_alignment_within(p, 0.04)?;
            (a >= 0.99).then_some((p, d))
        })
}

/// The centroid of the body, which orients the garments' normals (as in `untangle_layers`).
fn body_centre(body: &Mesh) -> Vec3 {
    body.positions.iter().sum::<Vec3>() / body.positions.len() as f64
}

/// `LAYERS_BENCH_GAP_CHECK`: where does the gap error come from? At the face-to-face contact
/// vertices p of garment k in the projection-only output `o2`: the mesh gap d to garment k-1,
/// the implicit gap f̂_{k-1}(p) / |∇f̂_{k-1}(p)| (the lower layer's corrected surface seen from
/// p), the lower layer's corrected value at the closest mesh point q (0 if its mesh lies on its
/// target surface), and the share of the lower triangle's vertices that are in contact.
fn gap_check(
    body: &Mesh,
    garments: &[Mesh],
    inputs: &[GarmentInput],
    params: &Params,
    o2: &Untangled,
) {
    use untangle::implicit::field::LayerField;
    use untangle::implicit::projection::{Composer, Layer};
    let centre = body_centre(body);
    let bf = build_field(body, &centre, true, &params.fields).unwrap();
    let gf: Vec<GarmentField> = garments
        .iter()
        .map(|g| build_field(g, &centre, false, &params.fields).unwrap())
        .collect();
    let mut lay = vec![Layer {
        field: &bf as &dyn LayerField,
        weight: f64::INFINITY,
        thickness: params.body_thickness,
    }];
    for (g, f) in inputs.iter().zip(&gf) {
        lay.push(Layer {
            field: f,
            weight: g.weight,
            thickness: g.thickness,
        });
    }
    let comp = Composer::new(&lay)
        .unwrap()
        .with_scaled_offsets(params.projection.scaled_offsets);
    for k in 1..garments.len() {
        let (me, lo) = (k + 1, k);
        let lower = &o2.projections[k - 1];
        let md = MeshDistance::new(&o2.positions[k - 1], &garments[k - 1].triangles);
        let mut acc = [0.0f64; 7];
        let mut n = 0usize;
        let mut hist = [0usize; 6];
        let mut gaps: Vec<(f64, f64, f64, f64, f64, f64)> = Vec::new();
        let mut by_run = [(0usize, 0.0f64, 0.0f64); 5];
        for (p, d) in contact_vertices(o2, k, &md) {
            let (q, t) = md.closest_within(p, 0.04).unwrap();
            let (Some(cu), Some(cl), Some(cq)) = (
                comp.evaluate(me, p),
                comp.evaluate(lo, p),
                comp.evaluate(lo, &q),
            ) else {
                continue;
            };
            let tri = garments[k - 1].triangles[t];
            let incontact = tri
                .iter()
                .filter(|&&v| lower.run[v as usize] != (lo, lo))
                .count() as f64
                / 3.0;
            let tau: f64 = tri.iter().map(|&v| lower.iso[v as usize]).sum::<f64>() / 3.0;
            let gap_impl = cl.value / cl.gradient.norm();
            n += 1;
            acc[0] += d;
            acc[1] += gap_impl;
            acc[2] += cq.value;
            acc[3] += incontact;
            acc[4] += cu.value;
            acc[5] += tau;
            acc[6] += cl.gradient.norm();
            let e = ((d - gap_impl) / 0.001).abs().floor() as usize;
            hist[e.min(5)] += 1;
            let res: f64 = tri
                .iter()
                .map(|&v| lower.residual[v as usize])
                .fold(0.0, f64::max);
            let (gl, gu) = (
                lay[lo].field.field(p).unwrap().1,
                lay[me].field.field(p).unwrap().1,
            );
            let cos = gl.dot(&gu) / (gl.norm() * gu.norm());
            gaps.push((d, gap_impl, res, cos, incontact, cq.value));
            let rl = (cu.run.1 - cu.run.0 + 1).min(4);
            by_run[rl].0 += 1;
            by_run[rl].1 += gap_impl;
            by_run[rl].2 += d;
        }
        let nn = n.max(1) as f64;
        eprintln!(
            "  gap check {} over {}: {n} face-to-face contact vertices; mean mesh gap {:.5}, implicit gap {:.5} (|grad| {:.3}), f̂_lower at closest mesh point {:+.5}, lower vertices in contact {:.2}, lower eps {:+.5}, f̂_upper at p {:+.6}; |mesh-implicit| histogram per mm {:?}",
            garments[k].name,
            garments[k - 1].name,
            acc[0] / nn,
            acc[1] / nn,
            acc[6] / nn,
            acc[2] / nn,
            acc[3] / nn,
            acc[5] / nn,
            acc[4] / nn,
            hist
        );
        let med = |mut x: Vec<f64>| {
            x.sort_by(f64::total_cmp);
            x.get(x.len() / 2).copied().unwrap_or(0.0)
        };
        let cosm = gaps.iter().map(|g| g.3).sum::<f64>() / nn;
        eprintln!(
            "    medians: mesh gap {:.5}, implicit {:.5}; mean cos(grad lower, grad upper) {:.3} (t/cos(θ/2) = {:.5}); outliers (|mesh-implicit| > 3 mm): {}",
            med(gaps.iter().map(|g| g.0).collect()),
            med(gaps.iter().map(|g| g.1).collect()),
            cosm,
            0.01 / ((1.0 + cosm) / 2.0).sqrt(),
            gaps.iter().filter(|g| (g.0 - g.1).abs() > 0.003).count()
        );
        for g in gaps.iter().filter(|g| (g.0 - g.1).abs() > 0.003).take(8) {
            eprintln!("      outlier: mesh {:.5} implicit {:.5} lower residual {:.2e} cos {:.3} lower in contact {:.2} f̂_lower(q) {:+.5}", g.0, g.1, g.2, g.3, g.4, g.5);
        }
        for (rl, &(n, gi, gm)) in by_run.iter().enumerate().filter(|x| x.1 .0 > 0) {
            eprintln!("    run of {rl} layers at p: {n} vertices, mean implicit gap {:.5}, mesh gap {:.5}", gi / n as f64, gm / n as f64);
        }
        eprintln!(
            "    lower layer unconverged vertices {}, passes {}",
            lower.unconverged, lower.iterations
        );
    }
}

/// `LAYERS_BENCH_FIELD_CHECK`: is the gap error in the fields? At the face-to-face contact
/// vertices of garment k in the projection-only output `o2`, the field of garment k-1: value
/// (the offset in field units), gradient norm, and the measured mesh distance.
fn field_check(body: &Mesh, garments: &[Mesh], params: &Params, o2: &Untangled) {
    use untangle::implicit::field::LayerField;
    let centre = body_centre(body);
    for k in 1..garments.len() {
        let f = build_field(&garments[k - 1], &centre, false, &params.fields).unwrap();
        let md = MeshDistance::new(&o2.positions[k - 1], &garments[k - 1].triangles);
        let (mut n, mut sv, mut sg, mut sd) = (0usize, 0.0, 0.0, 0.0);
        for (p, d) in contact_vertices(o2, k, &md) {
            let Some((v, g)) = f.field(p) else {
                continue;
            };
            n += 1;
            sv += v;
            sg += g.norm();
            sd += d;
        }
        let n = n.max(1) as f64;
        eprintln!(
            "  field check {} over {}: face-to-face contact vertices {n}, mean f_below {:.5}, mean |grad f_below| {:.3}, mean distance {:.5}",
            garments[k].name, garments[k - 1].name, sv / n, sg / n, sd / n
        );
    }
}
