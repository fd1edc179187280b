//! `untangle simulate IN.obj -o OUT.obj [--steps N] [--dt 0.02] [--body FILE|DIR] [--pin SPEC]
//! [--frames DIR] [--json PATH]`: implicit cloth simulation with full-proof collision handling.

use crate::output::{check_output, Context};
use anyhow::{anyhow, bail, Context as _, Result};
use std::path::{Path, PathBuf};
use untangle::analysis::{self, AnalysisMesh, ObjectKind};
use untangle::geom::{Aabb, Vec3};
use untangle::mesh::{obj, Garment, Mesh};
use untangle::sim::{Integrator, Obstacle, SimParams, Simulator, StepReport, UniformThickness};

/// Arguments of `simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The garment (OBJ; `vt` = sewing pattern in metres, else its own flat shape is the rest).
    pub input: PathBuf,
    /// Where to write the cloth after the last step.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Number of steps.
    #[arg(long, default_value_t = 100)]
    pub steps: usize,
    /// Step length in seconds.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.02)]
    pub dt: f64,
    /// Obstacle: an OBJ file (static), or a directory of OBJ frames (sorted by name, spread
    /// evenly over the steps and interpolated linearly). Frames meshed differently are first
    /// brought onto frame 0's mesh by closest-point tracking (`untangle::sim::obstacle::
    /// track_frames`), which needs consecutive frames to be close.
    #[arg(long)]
    pub body: Option<PathBuf>,
    /// How the body is placed: `--body-scale`, `--body-offset`, `--body-z-up`.
    #[command(flatten)]
    pub placement: Placement,
    /// Pinned vertices (repeatable): `corners`, `top`, `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX`, or
    /// 1-based vertex numbers `I,J,K` as in the OBJ file.
    #[arg(long, allow_hyphen_values = true)]
    pub pin: Vec<String>,
    /// Write the cloth as `frame_NNNN.obj` into this directory every `--frame-every` steps.
    #[arg(long)]
    pub frames: Option<PathBuf>,
    /// Steps between written frames.
    #[arg(long, default_value_t = 1)]
    pub frame_every: usize,
    /// Write a JSON report (parameters and one entry per step) here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Cloth-cloth thickness (m).
    #[arg(long, allow_negative_numbers = true, default_value_t = 2e-3)]
    pub thickness: f64,
    /// Body thickness (m).
    #[arg(long, allow_negative_numbers = true, default_value_t = 3e-3)]
    pub body_thickness: f64,
    /// Body friction coefficient.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.3)]
    pub body_friction: f64,
    /// Cloth-cloth friction coefficient.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.2)]
    pub friction: f64,
    /// Stretch stiffness (N/m).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
    pub stretch: f64,
    /// Bending stiffness (N m).
    #[arg(long, allow_negative_numbers = true, default_value_t = 5e-6)]
    pub bend: f64,
    /// Area density (kg/m^2).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.15)]
    pub density: f64,
    /// Gravity `X,Y,Z` (m/s^2).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, default_value = "0,-9.81,0")]
    pub gravity: Vec3,
    /// Time integrator: `baraff-witkin` (one Newton step of implicit Euler, CG) or
    /// `projective` (projective dynamics: local/global iterations with a pre-factored matrix).
    #[arg(long, value_enum, default_value_t = IntegratorArg::BaraffWitkin)]
    pub integrator: IntegratorArg,
    /// Local/global iterations per step of `--integrator projective`.
    #[arg(long, default_value_t = 10)]
    pub pd_iterations: usize,
    /// Thickness cap of cloth-cloth pairs that are neighbours on the cloth, as a fraction of
    /// the shortest edge at their nodes (keeps a thickness larger than the mesh's edges from
    /// inflating the cloth); 0 turns it off.
    #[arg(long, allow_negative_numbers = true, default_value_t = untangle::sim::step::NEAR_PAIR_FRACTION)]
    pub near_pair_fraction: f64,
}

/// `--integrator` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorArg {
    /// Baraff & Witkin 1998.
    BaraffWitkin,
    /// Projective dynamics (Bouaziz et al. 2014).
    Projective,
}

fn parse_vec3(s: &str) -> std::result::Result<Vec3, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("'{s}': {e}"))?;
    if v.len() != 3 || !v.iter().all(|x| x.is_finite()) {
        return Err(format!("'{s}': expected three finite numbers X,Y,Z"));
    }
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// Vertices selected by one `--pin` spec (0-based).
pub fn pin_spec(spec: &str, positions: &[Vec3], boundary: &[bool]) -> Result<Vec<u32>> {
    let n = positions.len();
    let bb = Aabb::from_points(positions);
    let ext = bb.extent();
    let tol = 1e-3 * ext.amax().max(1e-12);
    if spec == "top" {
        return Ok((0..n as u32)
            .filter(|&i| positions[i as usize].y >= bb.max.y - tol.max(0.01 * ext.y))
            .collect());
    }
    if spec == "corners" {
        // The boundary vertices extreme in the four diagonal directions of the two largest
        // box axes.
        let mut axes = [0usize, 1, 2];
        axes.sort_by(|&a, &b| ext[b].total_cmp(&ext[a]));
        let (a, b) = (axes[0], axes[1]);
        let mut out = Vec::new();
        for (sa, sb) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
            let best = (0..n)
                .filter(|&i| boundary[i])
                .max_by(|&i, &j| {
                    let f = |k: usize| sa * positions[k][a] + sb * positions[k][b];
                    f(i).total_cmp(&f(j)).then(j.cmp(&i))
                })
                .ok_or_else(|| anyhow!("--pin corners: the cloth has no boundary"))?;
            out.push(best as u32);
        }
        out.sort_unstable();
        out.dedup();
        return Ok(out);
    }
    if let Some(rest) = spec.strip_prefix("box:") {
        let v: Vec<f64> = rest
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| anyhow!("--pin {spec}: expected box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX"))?;
        if v.len() != 6 {
            bail!("--pin {spec}: expected box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX");
        }
        let lo = Vec3::new(v[0], v[1], v[2]);
        let hi = Vec3::new(v[3], v[4], v[5]);
        return Ok((0..n as u32)
            .filter(|&i| {
                let p = positions[i as usize];
                (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k])
            })
            .collect());
    }
    let mut out = Vec::new();
    for item in spec.split(',') {
        let k: u64 = item.trim().parse().map_err(|_| {
            anyhow!("--pin {spec}: expected corners, top, box:..., or vertex numbers I,J,K")
        })?;
        if k == 0 || k > n as u64 {
            bail!("--pin {spec}: vertex {k} out of range (the cloth has {n} vertices, numbered from 1)");
        }
        out.push((k - 1) as u32);
    }
    Ok(out)
}

/// The body: its mesh (placed) and, for an animation, the placed positions of every frame.
pub struct Body {
    /// Frame 0's mesh, placed.
    pub mesh: Mesh,
    /// Placed positions of every frame (one for a static body).
    pub frames: Vec<Vec<Vec3>>,
    /// The frames did not share one mesh: frame 0's vertices were tracked through them.
    pub tracked: bool,
}

/// How a body is placed (shared by `simulate` and `fix`): scaled, then turned Z-up to Y-up,
/// then offset.
#[derive(clap::Args, Debug, Clone)]
pub struct Placement {
    /// Scale applied to the body (e.g. 0.1 for meshes in decimetres), before the offset.
    #[arg(
        long = "body-scale",
        allow_negative_numbers = true,
        default_value_t = 1.0
    )]
    pub scale: f64,
    /// Offset added to the body after scaling: `X,Y,Z` in metres.
    #[arg(long = "body-offset", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub offset: Option<Vec3>,
    /// Rotate the body so that its +Z axis points up (+Y), for Z-up meshes.
    #[arg(long = "body-z-up")]
    pub z_up: bool,
}

fn place(p: &Vec3, pl: &Placement) -> Vec3 {
    let q = if pl.z_up {
        Vec3::new(p.x, p.z, -p.y)
    } else {
        *p
    };
    q * pl.scale + pl.offset.unwrap_or_else(Vec3::zeros)
}

/// Loads a body: an OBJ file, or a directory of OBJ frames (sorted by name).
pub fn load_body(path: &Path, pl: &Placement) -> Result<Body> {
    if !(pl.scale > 0.0 && pl.scale.is_finite()) {
        bail!("--body-scale must be positive, got {}", pl.scale);
    }
    let files: Vec<PathBuf> = if path.is_dir() {
        let mut f: Vec<PathBuf> = std::fs::read_dir(path)
            .with_context(|| path.display().to_string())?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")))
            .collect();
        f.sort();
        if f.is_empty() {
            bail!("{}: no .obj frames in this directory", path.display());
        }
        f
    } else {
        vec![path.to_path_buf()]
    };
    let mut meshes = Vec::with_capacity(files.len());
    for f in &files {
        let mut m = obj::read_obj(f)?;
        m.positions = m.positions.iter().map(|p| place(p, pl)).collect();
        meshes.push(m);
    }
    let mut mesh = meshes[0].clone();
    let tracked = meshes
        .iter()
        .any(|m| m.positions.len() != mesh.positions.len() || m.triangles != mesh.triangles);
    let frames = if tracked {
        // Frames meshed differently: carry frame 0's vertices along by closest points.
        untangle::sim::obstacle::track_frames(&mesh, &meshes[1..])
            .with_context(|| path.display().to_string())?
    } else {
        meshes.into_iter().map(|m| m.positions).collect()
    };
    mesh.positions = frames[0].clone();
    Ok(Body {
        mesh,
        frames,
        tracked,
    })
}

/// Body positions at the end of step `k` (of `steps`): frames spread evenly, linear in between.
pub fn body_at(body: &Body, k: usize, steps: usize) -> Vec<Vec3> {
    let f = body.frames.len();
    if f == 1 {
        return body.frames[0].clone();
    }
    let s = (k as f64 / steps.max(1) as f64) * (f - 1) as f64;
    let i = (s.floor() as usize).min(f - 2);
    let t = s - i as f64;
    body.frames[i]
        .iter()
        .zip(&body.frames[i + 1])
        .map(|(a, b)| a + (b - a) * t)
        .collect()
}

/// Runs `simulate`; exit code 0 when the result is intersection-free and no step quit early, 1
/// otherwise.
pub fn run(args: Args, ctx: &Context) -> Result<u8> {
    let mut inputs: Vec<&Path> = vec![&args.input];
    if let Some(b) = &args.body {
        inputs.push(b);
    }
    for out in [Some(&args.output), args.json.as_ref()]
        .into_iter()
        .flatten()
    {
        check_output(out, &inputs)?;
    }
    if args.frame_every == 0 {
        bail!("--frame-every must be at least 1");
    }
    let mesh = obj::read_obj(&args.input)?;
    let garment = Garment::new(mesh.clone())?;
    let params = SimParams {
        dt: args.dt,
        density: args.density,
        stretch_stiffness: args.stretch,
        shear_stiffness: 0.1 * args.stretch,
        bend_stiffness: args.bend,
        friction: args.friction,
        gravity: args.gravity,
        integrator: match args.integrator {
            IntegratorArg::BaraffWitkin => Integrator::BaraffWitkin,
            IntegratorArg::Projective => Integrator::Projective,
        },
        projective_iterations: args.pd_iterations,
        near_pair_fraction: args.near_pair_fraction,
        ..SimParams::default()
    };
    let mut sim = Simulator::new(&garment, params.clone())
        .with_context(|| args.input.display().to_string())?;
    let mut pinned = Vec::new();
    for spec in &args.pin {
        pinned.extend(pin_spec(
            spec,
            &mesh.positions,
            &garment.topology.boundary_vertex,
        )?);
    }
    pinned.sort_unstable();
    pinned.dedup();
    for &v in &pinned {
        sim.set_pinned(v, true)?;
    }
    let body = match &args.body {
        Some(p) => Some(load_body(p, &args.placement)?),
        None => None,
    };
    if let Some(b) = &body {
        if b.tracked {
            ctx.say(format!(
                "note: the {} body frames do not share one mesh; frame 0's {} vertices were carried through them by closest points",
                b.frames.len(),
                b.mesh.positions.len()
            ));
        }
        sim.add_obstacle(Obstacle::from_mesh(
            &b.mesh,
            args.body_thickness,
            args.body_friction,
        )?)?;
    }
    if !(args.thickness > 0.0 && args.thickness.is_finite()) {
        bail!("--thickness must be positive, got {}", args.thickness);
    }
    // The start must be intersection-free for the guarantee to hold: say so if it is not.
    let mut parts = vec![(&mesh, ObjectKind::Cloth)];
    if let Some(b) = &body {
        parts.push((&b.mesh, ObjectKind::Obstacle));
    }
    let (am, mut pos) = AnalysisMesh::new(&parts)?;
    let start = analysis::analyze(&am, &pos).context("intersection analysis")?;
    if !start.is_clean() {
        ctx.say(format!(
            "warning: the start already has {} intersecting triangle pairs; collision handling keeps them (use an untangling method to remove them)",
            start.segments.len()
        ));
    }
    if let Some(d) = &args.frames {
        std::fs::create_dir_all(d).with_context(|| d.display().to_string())?;
    }
    let policy = UniformThickness(args.thickness);
    let pb = ctx.progress(args.steps as u64, "simulating");
    let mut reports: Vec<StepReport> = Vec::with_capacity(args.steps);
    let mut out_mesh = mesh.clone();
    for k in 0..args.steps {
        if let Some(b) = &body {
            if b.frames.len() > 1 {
                sim.set_obstacle_next_positions(0, &body_at(b, k + 1, args.steps))?;
            }
        }
        let r = sim.step(&policy);
        pb.inc(1);
        if r.administrative_quit() {
            pb.println(format!(
                "step {k}: administrative quit ({} collisions left)",
                r.collisions.remaining_collisions
            ));
        }
        reports.push(r);
        if let Some(d) = &args.frames {
            if (k + 1) % args.frame_every == 0 || k + 1 == args.steps {
                out_mesh.positions.copy_from_slice(sim.positions());
                obj::write_obj(
                    &d.join(format!("frame_{:04}.obj", k + 1)),
                    &out_mesh,
                    None,
                    &format!("untangle simulate: step {}", k + 1),
                )?;
            }
        }
    }
    pb.finish_and_clear();
    out_mesh.positions.copy_from_slice(sim.positions());
    obj::write_obj(
        &args.output,
        &out_mesh,
        None,
        &format!(
            "untangle simulate {} --steps {}",
            args.input.display(),
            args.steps
        ),
    )?;
    let n = sim.positions().len();
    pos[..n].copy_from_slice(sim.positions());
    pos[n..].copy_from_slice(&sim.obstacles().start);
    let end = analysis::analyze(&am, &pos).context("intersection analysis")?;
    let quits = reports.iter().filter(|r| r.administrative_quit()).count();
    let stalls = reports.iter().filter(|r| r.collisions.stalled).count();
    let total_ms: f64 = reports.iter().map(|r| r.timing.total).sum();
    let cg: usize = reports.iter().map(|r| r.cg.iterations).sum();
    if let Some(p) = &args.json {
        let doc = serde_json::json!({
            "input": args.input.display().to_string(),
            "body": args.body.as_ref().map(|b| b.display().to_string()),
            "vertices": n,
            "triangles": mesh.triangles.len(),
            "pinned": pinned.len(),
            "steps": args.steps,
            "dt": args.dt,
            "thickness": args.thickness,
            "near_pair_fraction": args.near_pair_fraction,
            "start_intersecting_pairs": start.segments.len(),
            "end_intersecting_pairs": end.segments.len(),
            "administrative_quits": quits,
            "stalled_steps": stalls,
            "reports": reports,
        });
        untangle::fsio::write_atomic(p, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    ctx.say(format!(
        "simulated {} steps of {} ({} vertices, {} pinned) in {:.2} s ({:.1} ms/step, {:.1} CG iterations/step)",
        args.steps,
        args.input.display(),
        n,
        pinned.len(),
        total_ms / 1e3,
        total_ms / args.steps.max(1) as f64,
        cg as f64 / args.steps.max(1) as f64
    ));
    ctx.say(format!(
        "collisions: {} impact-zone steps, {} stalled steps, {} administrative quits; end state: {}",
        reports.iter().filter(|r| r.collisions.impact_zones > 0).count(),
        stalls,
        quits,
        if end.is_clean() {
            "intersection-free".to_string()
        } else {
            format!("{} intersecting triangle pairs", end.segments.len())
        }
    ));
    ctx.say(format!("wrote {}", args.output.display()));
    Ok(if end.is_clean() && quits == 0 { 0 } else { 1 })
}
