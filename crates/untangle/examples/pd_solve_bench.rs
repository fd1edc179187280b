//! Benchmark of projective dynamics' global-step solve: the scalar system of the ARCSim t-shirt
//! refined `LEVEL` times (2: 4,950 vertices, 3: 19,566), pinned at the shoulders, factored
//! once; then `REPS` solves of three right-hand sides with faer's sparse-Cholesky solve called
//! directly (`LltRef::solve_in_place_with_conj`) and through `ScalarCholesky::solve_with` (as
//! the simulator's global step calls it: right-hand side evaluated in parallel, then faer) and
//! through `ScalarCholesky::solve_increment_with` (the same with the factor in single precision),
//! interleaved in rounds; and `REPS` local steps (projection + per-vertex gather). Prints per
//! solve / per local step the process CPU time (less sensitive to other processes than wall
//! clock) and the wall time, the factor size, and the largest difference between the two
//! solutions.
//!
//! `cargo run --release -p untangle --example pd_solve_bench [-- LEVEL REPS]`

mod common;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use std::time::Instant;
use untangle::geom::Vec3;
use untangle::mesh::{subdivide::subdivide, Garment, Topology};
use untangle::sim::cholesky::ScalarCholesky;
use untangle::sim::projective::{Elastic, Projective};
use untangle::sim::rest::{isometric_uv, RestShape};

/// CPU time of the process (all threads) in seconds.
fn thread_cpu() -> f64 {
    let t = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = t.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|s| s.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let level = common::arg(1, 2);
    let reps = common::arg(2, 400);
    let Some(mut m) = common::arcsim_mesh("tshirt") else {
        return;
    };
    for _ in 0..level {
        m = subdivide(&m);
    }
    m.uv = Some(isometric_uv(&m.positions, &m.triangles));
    let g = Garment::new(m.clone()).expect("valid garment");
    let uv = g.mesh.uv.as_ref().expect("uv");
    let topology = Topology::new(&g.mesh).expect("topology");
    let rest = RestShape::new(&g.mesh.triangles, &uv.triangles, &uv.coords, &topology)
        .expect("rest shape");
    let n = m.positions.len();
    // The simulator's defaults (SimParams), lumped masses from the rest areas.
    let p = untangle::sim::SimParams::default();
    let elastic = Elastic {
        stretch: p.stretch_stiffness,
        shear: p.shear_stiffness,
        bend: p.bend_stiffness,
    };
    let system = Projective::new(n, &g.mesh.triangles, &rest, elastic);
    let mut mass = vec![0.0; n];
    for (t, r) in g.mesh.triangles.iter().zip(&rest.triangles) {
        for &v in t {
            mass[v as usize] += p.density * r.area / 3.0;
        }
    }
    let h = p.dt;
    let inertia: Vec<f64> = mass.iter().map(|m| m / (h * h)).collect();
    let values = system.system_values(&inertia, 0.0);
    let top = m.positions.iter().map(|q| q.z).fold(f64::MIN, f64::max);
    let fixed: Vec<bool> = m.positions.iter().map(|q| q.z >= top - 0.01).collect();
    let pattern = system.pattern();

    let t0 = Instant::now();
    let mut chol = ScalarCholesky::new(pattern).expect("symbolic");
    assert!(chol.factor(pattern, &values, &fixed));
    let factor_ms = t0.elapsed().as_secs_f64() * 1e3;

    // faer directly, the same matrix (fixed rows/columns replaced by the diagonal).
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    let mut vals = Vec::new();
    for j in 0..n {
        for s in pattern.offsets[j] as usize..pattern.offsets[j + 1] as usize {
            let i = pattern.cols[s] as usize;
            if i >= j {
                row_idx.push(i);
                vals.push(if i != j && (fixed[i] || fixed[j]) {
                    0.0
                } else {
                    values[s]
                });
            }
        }
        col_ptr.push(row_idx.len());
    }
    let sym = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
    let symbolic = factorize_symbolic_cholesky(
        sym,
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams::default(),
    )
    .expect("symbolic");
    let mut lval = vec![0.0; symbolic.len_val()];
    let mut scratch =
        MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()));
    symbolic
        .factorize_numeric_llt::<f64>(
            &mut lval,
            SparseColMatRef::new(sym, &vals),
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut scratch),
            Default::default(),
        )
        .expect("factor");
    let mut solve_scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
    let llt = LltRef::<'_, usize, f64>::new(&symbolic, &lval);

    let b: Vec<Vec3> = (0..n)
        .map(|i| {
            let q = m.positions[i];
            Vec3::new(q.x.sin(), q.y.cos(), q.z) * inertia[i]
        })
        .collect();
    let faer_solve = |out: &mut Vec<Vec3>, buf: &mut Vec<f64>, stack: &mut MemBuffer| {
        buf.clear();
        buf.resize(3 * n, 0.0);
        for (i, v) in b.iter().enumerate() {
            buf[i] = v.x;
            buf[n + i] = v.y;
            buf[2 * n + i] = v.z;
        }
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(buf, n, 3),
            Par::Seq,
            MemStack::new(stack),
        );
        for (i, o) in out.iter_mut().enumerate() {
            *o = Vec3::new(buf[i], buf[n + i], buf[2 * n + i]);
        }
    };
    let mut xa = vec![Vec3::zeros(); n];
    let mut xb = vec![Vec3::zeros(); n];
    let mut xc = vec![Vec3::zeros(); n];
    let mut buf = Vec::new();
    let (mut cpu_a, mut cpu_b, mut wall_a, mut wall_b) = (0.0, 0.0, 0.0, 0.0);
    let (mut cpu_c, mut wall_c) = (0.0, 0.0);
    let rounds = 10;
    let per = reps.div_ceil(rounds);
    // Everything inside the pool, as the simulator's iterations run.
    rayon::scope(|_| {
        for _ in 0..rounds {
            let (c, w) = (thread_cpu(), Instant::now());
            for _ in 0..per {
                faer_solve(&mut xa, &mut buf, &mut solve_scratch);
            }
            cpu_a += thread_cpu() - c;
            wall_a += w.elapsed().as_secs_f64();
            let (c, w) = (thread_cpu(), Instant::now());
            for _ in 0..per {
                chol.solve_with(|i| b[i], &mut xb);
            }
            cpu_b += thread_cpu() - c;
            wall_b += w.elapsed().as_secs_f64();
            let (c, w) = (thread_cpu(), Instant::now());
            for _ in 0..per {
                chol.solve_increment_with(|i| b[i], &mut xc);
            }
            cpu_c += thread_cpu() - c;
            wall_c += w.elapsed().as_secs_f64();
        }
    });
    let diff = xa
        .iter()
        .zip(&xb)
        .map(|(a, b)| (a - b).norm() / (1.0 + a.norm()))
        .fold(0.0, f64::max);
    let total = (rounds * per) as f64;
    // The local step at the (stretched) rest positions scaled by 1.05.
    let x: Vec<Vec3> = m.positions.iter().map(|q| q * 1.05).collect();
    let mut targets = Vec::new();
    let mut sink = 0.0;
    let (local_cpu, local_wall) = rayon::scope(|_| {
        let (c, w) = (thread_cpu(), Instant::now());
        for _ in 0..reps {
            system.project(&x, &mut targets);
            sink += (0..n).map(|i| system.gather(&targets, i).x).sum::<f64>();
        }
        (thread_cpu() - c, w.elapsed().as_secs_f64())
    });
    println!(
        "level {level}: {n} vertices, factor {} values; factor {:.1} ms; threads {}",
        chol.factor_entries(),
        factor_ms,
        rayon::current_num_threads()
    );
    println!(
        "faer solve:        {:.3} ms wall, {:.3} ms CPU (process) per solve",
        wall_a / total * 1e3,
        cpu_a / total * 1e3
    );
    println!(
        "ScalarCholesky::solve_with: {:.3} ms wall, {:.3} ms CPU (process) per solve; max rel. difference {:.1e}",
        wall_b / total * 1e3,
        cpu_b / total * 1e3,
        diff
    );
    let diff32 = xa
        .iter()
        .zip(&xc)
        .map(|(a, c)| (a - c).norm() / (1.0 + a.norm()))
        .fold(0.0, f64::max);
    println!(
        "ScalarCholesky::solve_increment_with (single precision): {:.3} ms wall, {:.3} ms CPU (process) per solve; max rel. difference {:.1e}",
        wall_c / total * 1e3,
        cpu_c / total * 1e3,
        diff32
    );
    println!(
        "local step (project + gather): {:.3} ms wall, {:.3} ms CPU (process) per iteration ({sink:.3e})",
        local_wall / reps as f64 * 1e3,
        local_cpu / reps as f64 * 1e3
    );
}
