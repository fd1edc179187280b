//! Cross-sections of the layered untangling of the ARCSim outfit (diagnostics): for a few planes,
//! a PNG with the zero sets of the input fields and the input mesh sections (left) and the zero
//! sets of the corrected fields and the output mesh sections (right).
//!
//! `cargo run -p untangle --release --example layers_sections -- SUBDIV GARMENTS OUTDIR`
//! (GARMENTS comma-separated, e.g. `pants3,tshirt,dress3,jacket`).
use image::{Rgb, RgbImage};
use std::path::PathBuf;
use std::time::Instant;
use untangle::geom::{Aabb, Vec3};
use untangle::implicit::layers::{build_field, untangle_with_fields};
use untangle::implicit::projection::{Composer, Layer};
use untangle::implicit::*;
use untangle::mesh::Mesh;

const COLOURS: [[u8; 3]; 10] = [
    [90, 90, 90],
    [30, 80, 220],
    [20, 160, 40],
    [200, 30, 180],
    [230, 120, 0],
    [0, 170, 170],
    [150, 90, 30],
    [120, 0, 200],
    [200, 0, 0],
    [0, 0, 0],
];

struct Plane {
    name: String,
    origin: Vec3,
    u: Vec3,
    v: Vec3,
    normal: Vec3,
    w: f64,
    h: f64,
}

fn draw_line(img: &mut RgbImage, x0: f64, y0: f64, x1: f64, y1: f64, c: [u8; 3], ox: u32) {
    let n = ((x1 - x0).abs().max((y1 - y0).abs()) * 2.0).ceil().max(1.0) as usize;
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let x = x0 + (x1 - x0) * t;
        let y = y0 + (y1 - y0) * t;
        if x >= 0.0 && y >= 0.0 {
            let (x, y) = (x as u32 + ox, y as u32);
            if x < img.width() && y < img.height() {
                img.put_pixel(x, y, Rgb(c));
            }
        }
    }
}

fn section(img: &mut RgbImage, m: &Mesh, pos: &[Vec3], pl: &Plane, px: f64, c: [u8; 3], ox: u32) {
    let hpx = pl.h / px;
    for t in &m.triangles {
        let p = t.map(|v| pos[v as usize]);
        let d = p.map(|q| (q - pl.origin).dot(&pl.normal));
        let mut pts = Vec::new();
        for k in 0..3 {
            let (a, b) = (k, (k + 1) % 3);
            if (d[a] < 0.0) != (d[b] < 0.0) {
                let s = d[a] / (d[a] - d[b]);
                pts.push(p[a] + (p[b] - p[a]) * s);
            }
        }
        if pts.len() == 2 {
            let uv = |q: &Vec3| {
                let r = q - pl.origin;
                (r.dot(&pl.u) / px, hpx - r.dot(&pl.v) / px)
            };
            let (a, b) = (uv(&pts[0]), uv(&pts[1]));
            draw_line(img, a.0, a.1, b.0, b.1, c, ox);
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let subdiv: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1);
    let names: Vec<String> = args
        .get(2)
        .map(|s| s.split(',').map(String::from).collect())
        .unwrap_or_else(|| {
            untangle::scenes::outfit::GARMENTS
                .iter()
                .map(|s| s.to_string())
                .collect()
        });
    let out = PathBuf::from(args.get(3).cloned().unwrap_or("/tmp/sections".into()));
    std::fs::create_dir_all(&out).unwrap();
    let shared = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared"));
    let nref: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
    let (body, garments) =
        untangle::scenes::outfit::arcsim_outfit(&shared, &nref, subdiv).expect("data");
    let mut params = Params::default();
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
    if let Some(d) = env("DEPTH") {
        params.fields.depth_limit = d;
    }
    if let Some(d) = env("SAMPLES") {
        params.fields.samples = d as usize;
    }
    if let Some(d) = env("NODES") {
        params.fields.max_nodes = d as usize;
    }
    if let Some(d) = env("INTERIOR") {
        params.fields.interior_samples = d as usize;
    }
    if let Some(d) = env("EXTERIOR") {
        params.fields.exterior_layers = d as usize;
    }
    if let Some(d) = env("BOUNDARY") {
        params.fields.boundary_samples = d as usize;
    }
    if let Some(d) = env("PASSES") {
        params.projection.max_iterations = d as usize;
    }
    if let Some(d) = env("ROUNDS") {
        params.repair.steps = d as usize;
    }
    if let Some(d) = env("RIMFADE") {
        params.fields.rim_fade = d;
    }
    if let Some(d) = env("RIMMARGIN") {
        params.fields.rim_margin = d;
    }
    if let Some(d) = env("RELAX") {
        params.projection.relaxation = d;
    }
    if let Some(d) = env("RELAXIT") {
        params.projection.relax_iterations = d as usize;
    }
    if let Some(d) = env("FLIPS") {
        params.projection.prevent_flips = d > 0.0;
    }
    if let Some(d) = env("DEPTHFADE") {
        params.fields.depth_fade = d;
    }
    let centre = body.positions.iter().sum::<Vec3>() / body.positions.len() as f64;
    let t = Instant::now();
    let bf = build_field(&body, &centre, true, &params.fields).unwrap();
    let fields: Vec<GarmentField> = garments
        .iter()
        .map(|g| build_field(g, &centre, false, &params.fields).unwrap())
        .collect();
    eprintln!("fields {:.2}s", t.elapsed().as_secs_f64());
    for (g, f) in garments.iter().zip(&fields) {
        let b = Aabb::from_points(&g.positions);
        eprintln!(
            "{}: mesh {:.3?}..{:.3?} grid {:.3?}..{:.3?} cell {:.4} depth {:.3} margin {:.4}",
            g.name,
            b.min.as_slice(),
            b.max.as_slice(),
            f.f.bbox().min.as_slice(),
            f.f.bbox().max.as_slice(),
            f.f.cell,
            f.depth_limit,
            f.h_margin
        );
    }
    {
        let mut e: Vec<f64> = body
            .positions
            .iter()
            .filter_map(|p| bf.f.sample(p))
            .map(|x| x.0)
            .collect();
        e.sort_by(|a, b| a.total_cmp(b));
        let q = |f: f64| e[((e.len() - 1) as f64 * f) as usize];
        eprintln!(
            "body eps min {:.4} p10 {:.4} median {:.4} p90 {:.4} max {:.4}",
            q(0.0),
            q(0.1),
            q(0.5),
            q(0.9),
            q(1.0)
        );
    }
    let inputs = GarmentInput::all_alike(&garments, 0.01, 1.0);
    let t = Instant::now();
    let res = untangle_with_fields(
        Some((&body, &bf)),
        &inputs,
        &fields,
        &vec![0.0; fields.len()],
        0.0,
        &params,
        &|_| {},
    )
    .unwrap();
    eprintln!(
        "projection+repair {:.2}s (projection {:.2}s, repair {:.2}s) repair {:?}",
        t.elapsed().as_secs_f64(),
        res.projection_ms / 1e3,
        res.repair_ms / 1e3,
        res.repair
    );
    for r in &res.reports {
        eprintln!(
            "{}: nv {} moved {} contact {} passes {} unconverged {} max residual {:.2e} max disp {:.3}",
            r.name, r.vertices, r.moved, r.in_contact, r.iterations, r.unconverged, r.max_residual,
            r.max_displacement
        );
    }
    for (k, pr) in res.projections.iter().enumerate() {
        let mut e: Vec<f64> = pr
            .iso
            .iter()
            .filter(|x| x.is_finite())
            .map(|x| x.abs())
            .collect();
        e.sort_by(|a, b| a.total_cmp(b));
        let q = |f: f64| e[((e.len() - 1) as f64 * f) as usize];
        eprintln!(
            "{}: |eps| median {:.4} p90 {:.4} p99 {:.4} max {:.4}",
            garments[k].name,
            q(0.5),
            q(0.9),
            q(0.99),
            q(1.0)
        );
    }
    let refs: Vec<&Mesh> = garments.iter().collect();
    let before: Vec<Vec<Vec3>> = garments.iter().map(|m| m.positions.clone()).collect();
    let v0 = verify(Some(&body), &refs, &before).unwrap();
    let v1 = verify(Some(&body), &refs, &res.positions).unwrap();
    eprintln!("before {v0:?}\nafter {v1:?}");

    // Wireframe views (front: x-z, side: y-z) of every mesh, input and output.
    {
        let px = 0.002;
        let mut bb = Aabb::from_points(&body.positions);
        for g in &garments {
            bb = bb.union(&Aabb::from_points(&g.positions));
        }
        let e = bb.extent();
        let (w, h) = ((e.x / px) as u32 + 2, (e.z / px) as u32 + 2);
        let ws = (e.y / px) as u32 + 2;
        let all: Vec<(&Mesh, &Vec<Vec3>, &Vec<Vec3>)> =
            std::iter::once((&body, &body.positions, &body.positions))
                .chain(
                    garments
                        .iter()
                        .zip(&res.positions)
                        .map(|(g, p)| (g, &g.positions, p)),
                )
                .collect();
        let mut img = RgbImage::from_pixel(
            (w + ws + 10) * all.len() as u32,
            2 * h + 10,
            Rgb([255, 255, 255]),
        );
        for (k, (m, p0, p1)) in all.iter().enumerate() {
            let col = COLOURS[k % COLOURS.len()];
            let ox = (w + ws + 10) * k as u32;
            for (row, pos) in [(0u32, p0), (h + 10, p1)] {
                for t in &m.triangles {
                    for c in 0..3 {
                        let (a, b) = (pos[t[c] as usize], pos[t[(c + 1) % 3] as usize]);
                        let f =
                            |q: &Vec3| ((q.x - bb.min.x) / px, (bb.max.z - q.z) / px + row as f64);
                        let s = |q: &Vec3| {
                            (
                                (q.y - bb.min.y) / px + w as f64 + 5.0,
                                (bb.max.z - q.z) / px + row as f64,
                            )
                        };
                        let (fa, fb) = (f(&a), f(&b));
                        draw_line(&mut img, fa.0, fa.1, fb.0, fb.1, col, ox);
                        let (sa, sb) = (s(&a), s(&b));
                        draw_line(&mut img, sa.0, sa.1, sb.0, sb.1, col, ox);
                    }
                }
            }
        }
        img.save(out.join("views.png")).unwrap();
    }
    // Diagnostics of the remaining intersections between layers.
    {
        use untangle::analysis::{analyze, AnalysisMesh, ObjectKind};
        let moved: Vec<Mesh> = garments
            .iter()
            .zip(&res.positions)
            .map(|(m, p)| Mesh {
                positions: p.clone(),
                ..m.clone()
            })
            .collect();
        let mut parts: Vec<(&Mesh, ObjectKind)> =
            moved.iter().map(|m| (m, ObjectKind::Cloth)).collect();
        parts.push((&body, ObjectKind::Obstacle));
        let (am, pos) = AnalysisMesh::new(&parts).unwrap();
        let a = analyze(&am, &pos).unwrap();
        let mut lyr: Vec<Layer> = vec![Layer {
            field: &bf,
            weight: f64::INFINITY,
            thickness: 0.0,
        }];
        for f in &fields {
            lyr.push(Layer {
                field: f,
                weight: 1.0,
                thickness: 0.01,
            });
        }
        let comp = Composer::new(&lyr).unwrap();
        let ng = garments.len();
        let mut stats = std::collections::BTreeMap::new();
        let mut spots: Vec<(usize, usize, Vec3)> = Vec::new();
        for s in &a.segments {
            let [ta, tb] = s.triangles;
            let (oa, ob) = (
                am.object_of_triangle[ta as usize] as usize,
                am.object_of_triangle[tb as usize] as usize,
            );
            let cen0 = |t: u32| {
                let tri = am.triangles[t as usize];
                (pos[tri[0] as usize] + pos[tri[1] as usize] + pos[tri[2] as usize]) / 3.0
            };
            if oa == ob {
                let c = cen0(ta);
                let b = (c.x * 10.0).round() / 10.0;
                let zb = (c.z * 10.0).round() / 10.0;
                *stats
                    .entry((oa, ob, format!("self x~{b:.1} z~{zb:.1}")))
                    .or_insert(0usize) += 1;
                continue;
            }
            let cen = |t: u32| {
                let tri = am.triangles[t as usize];
                (pos[tri[0] as usize] + pos[tri[1] as usize] + pos[tri[2] as usize]) / 3.0
            };
            spots.push((oa, ob, (cen(ta) + cen(tb)) * 0.5));
            // For each side: does the triangle's layer see the other layer at its vertices?
            let mut key = vec![(oa.min(ob), oa.max(ob))];
            let mut desc = String::new();
            for (t, o, other) in [(ta, oa, ob), (tb, ob, oa)] {
                if o >= ng {
                    continue;
                }
                let lt = t - am.objects[o].triangles.start;
                let tri = garments[o].triangles[lt as usize];
                let me = o + 1;
                let oth = if other >= ng { 0 } else { other + 1 };
                let mut sees = 0;
                let mut unconv = 0;
                let mut contact = 0;
                let mut own_in = 0;
                for &v in &tri {
                    let p = res.positions[o][v as usize];
                    if let Some(c) = comp.evaluate(me, &p) {
                        if c.active & (1 << oth) != 0 {
                            sees += 1;
                        }
                        if c.run != (me, me) {
                            contact += 1;
                        }
                    }
                    if res.projections[o].residual[v as usize] > res.tolerance {
                        unconv += 1;
                    }
                    if lyr[me].field.influences(&p) {
                        own_in += 1;
                    }
                }
                desc += &format!("L{me}[sees{sees} cont{contact} unc{unconv} own{own_in}] ");
            }
            key.clear();
            *stats
                .entry((oa.min(ob), oa.max(ob), desc))
                .or_insert(0usize) += 1;
        }
        for (k, v) in &stats {
            eprintln!("{v:5} {k:?}");
        }
        let mut hist = std::collections::BTreeMap::new();
        for (oa, ob, p) in &spots {
            *hist
                .entry((*oa, *ob, (p.z * 20.0).round() as i64))
                .or_insert(0usize) += 1;
        }
        for ((a, b, z), c) in hist {
            eprintln!("zhist {a}-{b} z~{:.2}: {c}", z as f64 / 20.0);
        }
        // Zoomed sections at a few spots of each object pair.
        let mut seen = std::collections::BTreeMap::new();
        let zoom = env("ZOOM").unwrap_or(0.0) as usize;
        for (oa, ob, p) in &spots {
            let c = seen.entry((*oa, *ob)).or_insert(0usize);
            *c += 1;
            if *c > zoom || (*c > 1 && *c % 7 != 0) {
                continue;
            }
            eprintln!("spot {oa}-{ob} #{c} at {:.3} {:.3} {:.3}", p.x, p.y, p.z);
            let half = 0.06;
            for (ax, u, v, n) in [
                ("z", Vec3::x(), Vec3::y(), Vec3::z()),
                ("x", Vec3::y(), Vec3::z(), Vec3::x()),
            ] {
                let pl = Plane {
                    name: format!("zoom_{oa}_{ob}_{c}_{ax}"),
                    origin: p - u * half - v * half,
                    u,
                    v,
                    normal: n,
                    w: 2.0 * half,
                    h: 2.0 * half,
                };
                render(
                    &pl,
                    0.0002,
                    &layers_of(&bf, &fields),
                    &body,
                    &garments,
                    &res.positions,
                    &out,
                );
            }
        }
    }
    // Planes through the scene.
    let mut bb = Aabb::from_points(&body.positions);
    for g in &garments {
        bb = bb.union(&Aabb::from_points(&g.positions));
    }
    let bb = bb.inflated(0.02);
    let c = untangle::scenes::outfit::TORSO;
    let e = bb.extent();
    let mut planes = vec![
        Plane {
            name: "x".into(),
            origin: Vec3::new(c.x, bb.min.y, bb.min.z),
            u: Vec3::y(),
            v: Vec3::z(),
            normal: Vec3::x(),
            w: e.y,
            h: e.z,
        },
        Plane {
            name: "y".into(),
            origin: Vec3::new(bb.min.x, c.y, bb.min.z),
            u: Vec3::x(),
            v: Vec3::z(),
            normal: Vec3::y(),
            w: e.x,
            h: e.z,
        },
    ];
    for (k, z) in [-0.1, 0.0, 0.1, 0.2, 0.3].iter().enumerate() {
        planes.push(Plane {
            name: format!("z{k}"),
            origin: Vec3::new(bb.min.x, bb.min.y, *z),
            u: Vec3::x(),
            v: Vec3::y(),
            normal: Vec3::z(),
            w: e.x,
            h: e.y,
        });
    }
    if let Ok(spec) = std::env::var("ZOOMAT") {
        let v: Vec<f64> = spec.split(',').map(|x| x.parse().unwrap()).collect();
        let (p, half) = (Vec3::new(v[0], v[1], v[2]), v[3]);
        for (ax, u, vv, n) in [
            ("x", Vec3::y(), Vec3::z(), Vec3::x()),
            ("y", Vec3::x(), Vec3::z(), Vec3::y()),
            ("z", Vec3::x(), Vec3::y(), Vec3::z()),
        ] {
            let pl = Plane {
                name: format!("at_{ax}"),
                origin: p - u * half - vv * half,
                u,
                v: vv,
                normal: n,
                w: 2.0 * half,
                h: 2.0 * half,
            };
            render(
                &pl,
                2.0 * half / 600.0,
                &layers_of(&bf, &fields),
                &body,
                &garments,
                &res.positions,
                &out,
            );
        }
        return;
    }
    if let Some(spec) = args.get(4) {
        // Extra plane "axis,value".
        let mut it = spec.split(',');
        let a = it.next().unwrap();
        let val: f64 = it.next().unwrap().parse().unwrap();
        planes.retain(|p| p.name == "none");
        let (origin, u, v, n, w, h) = match a {
            "x" => (
                Vec3::new(val, bb.min.y, bb.min.z),
                Vec3::y(),
                Vec3::z(),
                Vec3::x(),
                e.y,
                e.z,
            ),
            "y" => (
                Vec3::new(bb.min.x, val, bb.min.z),
                Vec3::x(),
                Vec3::z(),
                Vec3::y(),
                e.x,
                e.z,
            ),
            _ => (
                Vec3::new(bb.min.x, bb.min.y, val),
                Vec3::x(),
                Vec3::y(),
                Vec3::z(),
                e.x,
                e.y,
            ),
        };
        planes.push(Plane {
            name: format!("{a}{val}"),
            origin,
            u,
            v,
            normal: n,
            w,
            h,
        });
    }
    if env("INFL").is_some() {
        // Influence regions per garment: light = h < margin and |f| <= depth limit, grey = h < margin
        // only; dark contour = f zero set; the mesh section in colour.
        for pl in &planes {
            let px = 0.002;
            let (wpx, hpx) = ((pl.w / px) as u32, (pl.h / px) as u32);
            let mut img =
                RgbImage::from_pixel((wpx + 10) * fields.len() as u32, hpx, Rgb([255, 255, 255]));
            for (k, f) in fields.iter().enumerate() {
                let col = COLOURS[(k + 1) % COLOURS.len()];
                let light = col.map(|x| 255 - (255 - x) / 5);
                let ox = (wpx + 10) * k as u32;
                let mut val = vec![f64::NAN; (wpx * hpx) as usize];
                for b in 0..hpx {
                    for a in 0..wpx {
                        let p = pl.origin + pl.u * (a as f64 * px) + pl.v * ((hpx - b) as f64 * px);
                        if let Some((v, _)) = f.f.sample(&p) {
                            val[(b * wpx + a) as usize] = v;
                            let hin =
                                f.h.as_ref()
                                    .and_then(|h| h.sample(&p))
                                    .is_some_and(|(h, _)| h < f.h_margin);
                            if f.influences(&p) {
                                img.put_pixel(a + ox, b, Rgb(light));
                            } else if hin {
                                img.put_pixel(a + ox, b, Rgb([225, 225, 225]));
                            }
                        }
                    }
                }
                for b in 0..hpx - 1 {
                    for a in 0..wpx - 1 {
                        let k2 = (b * wpx + a) as usize;
                        let (v, r, d) = (val[k2], val[k2 + 1], val[k2 + wpx as usize]);
                        if v.is_finite()
                            && ((r.is_finite() && (v < 0.0) != (r < 0.0))
                                || (d.is_finite() && (v < 0.0) != (d < 0.0)))
                        {
                            img.put_pixel(a + ox, b, Rgb([120, 120, 120]));
                        }
                    }
                }
                section(
                    &mut img,
                    &garments[k],
                    &garments[k].positions,
                    pl,
                    px,
                    col,
                    ox,
                );
                section(&mut img, &body, &body.positions, pl, px, COLOURS[0], ox);
            }
            img.save(out.join(format!("influence_{}.png", pl.name)))
                .unwrap();
        }
    }
    for pl in &planes {
        render(
            pl,
            0.0015,
            &layers_of(&bf, &fields),
            &body,
            &garments,
            &res.positions,
            &out,
        );
    }
}

fn layers_of<'a>(bf: &'a GarmentField, fields: &'a [GarmentField]) -> Vec<Layer<'a>> {
    let mut layers: Vec<Layer> = vec![Layer {
        field: bf,
        weight: f64::INFINITY,
        thickness: 0.0,
    }];
    for f in fields {
        layers.push(Layer {
            field: f,
            weight: 1.0,
            thickness: 0.01,
        });
    }
    layers
}

fn render(
    pl: &Plane,
    px: f64,
    layers: &[Layer],
    body: &Mesh,
    garments: &[Mesh],
    positions: &[Vec<Vec3>],
    out: &std::path::Path,
) {
    let composer = Composer::new(layers).unwrap();
    {
        let (wpx, hpx) = ((pl.w / px) as u32, (pl.h / px) as u32);
        let mut img = RgbImage::from_pixel(2 * wpx + 10, hpx, Rgb([255, 255, 255]));
        let nl = layers.len();
        // Per pixel: original values (with influence) and corrected values.
        let mut orig = vec![vec![(f64::NAN, false); (wpx * hpx) as usize]; nl];
        let mut corr = vec![vec![f64::NAN; (wpx * hpx) as usize]; nl];
        for b in 0..hpx {
            for a in 0..wpx {
                let p = pl.origin + pl.u * (a as f64 * px) + pl.v * ((hpx - b) as f64 * px);
                let k = (b * wpx + a) as usize;
                for (j, l) in layers.iter().enumerate() {
                    if let Some((val, _)) = l.field.field(&p) {
                        orig[j][k] = (val, l.field.influences(&p));
                    }
                    if let Some(cc) = composer.evaluate(j, &p) {
                        corr[j][k] = cc.value;
                    }
                }
            }
        }
        for j in 0..nl {
            let col = COLOURS[j % COLOURS.len()];
            let light = col.map(|x| 255 - (255 - x) / 4);
            for b in 0..hpx - 1 {
                for a in 0..wpx - 1 {
                    let k = (b * wpx + a) as usize;
                    let (v, inf) = orig[j][k];
                    let r = orig[j][k + 1].0;
                    let d = orig[j][k + wpx as usize].0;
                    if v.is_finite()
                        && ((r.is_finite() && (v < 0.0) != (r < 0.0))
                            || (d.is_finite() && (v < 0.0) != (d < 0.0)))
                    {
                        img.put_pixel(a, b, Rgb(if inf { light } else { [235, 235, 235] }));
                    }
                    let v = corr[j][k];
                    let r = corr[j][k + 1];
                    let d = corr[j][k + wpx as usize];
                    if v.is_finite()
                        && ((r.is_finite() && (v < 0.0) != (r < 0.0))
                            || (d.is_finite() && (v < 0.0) != (d < 0.0)))
                    {
                        img.put_pixel(a + wpx + 10, b, Rgb(light));
                    }
                }
            }
        }
        section(&mut img, body, &body.positions, pl, px, COLOURS[0], 0);
        section(
            &mut img,
            body,
            &body.positions,
            pl,
            px,
            COLOURS[0],
            wpx + 10,
        );
        for (k, g) in garments.iter().enumerate() {
            let col = COLOURS[(k + 1) % COLOURS.len()];
            section(&mut img, g, &g.positions, pl, px, col, 0);
            section(&mut img, g, &positions[k], pl, px, col, wpx + 10);
        }
        let path = out.join(format!("section_{}.png", pl.name));
        img.save(&path).unwrap();
        eprintln!("wrote {}", path.display());
    }
}
