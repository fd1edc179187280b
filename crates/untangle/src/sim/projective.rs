//! Projective dynamics (Bouaziz et al. 2014, "Projective Dynamics: Fusing Constraint
//! Projections for Fast Simulation"; Liu et al. 2013 for the mass-spring special case): implicit
//! Euler as the minimisation of
//!
//! `E(x) = 1/(2 h^2) |M'^1/2 (x - y)|^2 + sum_i w_i/2 |A_i S_i x - p_i|^2 + kb/2 x^T B x
//!        + beta/(2h) (x - x_n)^T L (x - x_n)`
//!
//! over the end-of-step positions `x` (Bouaziz et al. Eq. 6/10), alternating a *local* step
//! (per-element projections `p_i`, in parallel, Sec. 4) and a *global* step, a linear solve with
//! the constant matrix `M'/h^2 + sum_i w_i S_i^T A_i^T A_i S_i` (Eq. 12) — the same scalar matrix
//! for `x`, `y` and `z`, factored once ([`super::cholesky`]).
//!
//! Terms (see `docs/projective.md` for the reasoning):
//! - Membrane, per triangle against its uv rest shape (`F = [w_u w_v] = Ds Dm^-1`, a 3x2
//!   deformation gradient, so `A_i S_i x = F` is linear in the corners with the coefficients of
//!   [`TriangleRest`]): an as-rigid-as-possible constraint (`p` = the closest 3x2 matrix with
//!   orthonormal columns, [`project_orthonormal`]) of weight `2 k_shear` per rest area, plus a
//!   per-column unit-length constraint (`p` = the columns normalised, [`project_unit_columns`]) of
//!   weight `k_stretch - 2 k_shear`. To second order in the strain this is exactly Baraff &
//!   Witkin's stretch (`k_stretch/2 (|w| - 1)^2` per column) and shear (`k_shear/2 (w_u.w_v)^2`)
//!   energy ([`super::forces::stretch`]), so both integrators share one set of parameters.
//! - Bending: the quadratic isometric bending of Bergou et al. 2006 ([`super::forces::bend`]);
//!   the rest shape is the flat uv panel, so the energy is quadratic with a constant matrix
//!   that goes straight into the factor (no projection).
//! - Inertia and mass damping: implicit Euler with damping force `-alpha M v` is the
//!   minimisation with `M' = (1 + h alpha) M` and `y = x_n + (h v_n + h^2 g) / (1 + h alpha)`.
//! - Stiffness damping: Rayleigh `beta K` with `K` replaced by the constant elastic matrix `L`
//!   (the exact Hessian at rest), the quadratic term above; it scales the elastic part of the
//!   global matrix by `1 + beta/h`.
//! - Contacts (the simulator's obstacle constraints, cloth-cloth springs and friction) enter the
//!   global system only; they change every step, so the global step solves the *current* system
//!   by conjugate gradients preconditioned with the factor of the base matrix
//!   ([`super::pcg::solve_factored`]), warm-started at the current iterate. The contact terms
//!   are applied next to the scalar matrix ([`ContactTerms`], no `3 x 3` blocks assembled) and
//!   the factor in single precision (the residual stays in double precision).
//!
//! Every local/global iteration never increases `E` (the local step minimises over `p` exactly,
//! the global step is CG on a convex quadratic started at the current iterate), which the tests
//! check.

use nalgebra::Matrix3x2;
use rayon::prelude::*;

use super::cholesky::{DisjointRows, ScalarCholesky};
use super::forces::stretch::TriangleRest;
use super::low_rank::LowRank;
use super::pcg::{self, Filter, PcgResult, PcgSettings};
use super::rest::RestShape;
use super::sparse::{BsrMatrix, BsrPattern, CHUNK};
use crate::geom::Vec3;

/// Triangles per parallel task of the local step.
const PROJECT_CHUNK: usize = 256;

/// Whether direct global steps solve for the increment with the factor in single precision.
const SINGLE_PRECISION_INCREMENTS: bool = true;

/// How CG global steps (under contact terms) apply the factor as preconditioner.
const CG_FACTOR_SOLVE: pcg::FactorSolve = pcg::FactorSolve::Single;

/// Per unit rest area, the weights `(arap, columns)` of the two membrane constraints that match
/// Baraff & Witkin's stretch stiffness `k_stretch` and shear stiffness `k_shear` to second order
/// (module docs). When `k_stretch < 2 k_shear` the column weight is 0 and the stretch stiffness
/// is `2 k_shear` (stiffer than asked).
pub fn membrane_weights(k_stretch: f64, k_shear: f64) -> (f64, f64) {
    let arap = 2.0 * k_shear;
    (arap, (k_stretch - arap).max(0.0))
}

/// The closest 3x2 matrix with orthonormal columns to `f` in the Frobenius norm, `U V^T` of the
/// thin SVD `f = U S V^T` (the "rotation" of a triangle's deformation gradient, Bouaziz et al.
/// 2014, Sec. 5.1 "strain"). In closed form `f (f^T f)^-1/2`; for a degenerate `f` (rank < 2)
/// any completion of the dominant direction is a closest point and a deterministic one is
/// returned. In 3D a 2D reflection is a rotation, so there is no inversion case.
pub fn project_orthonormal(f: &Matrix3x2<f64>) -> Matrix3x2<f64> {
    let c = f.transpose() * f;
    let (p, q, r) = (c[(0, 0)], c[(0, 1)], c[(1, 1)]);
    let tr = p + r;
    let det = p * r - q * q;
    if tr > 0.0 && det > 1e-12 * tr * tr {
        // sqrt(C) = (C + sqrt(det) I) / sqrt(tr + 2 sqrt(det)) for a 2x2 SPD C.
        let sd = det.sqrt();
        let s = 1.0 / (tr + 2.0 * sd).sqrt();
        let (a, b, d) = ((p + sd) * s, q * s, (r + sd) * s);
        let inv = 1.0 / (a * d - b * b);
        let (ia, ib, id) = (d * inv, -b * inv, a * inv);
        let u = f.column(0) * ia + f.column(1) * ib;
        let v = f.column(0) * ib + f.column(1) * id;
        return Matrix3x2::from_columns(&[u, v]);
    }
    // (Nearly) rank <= 1: f = s1 u v^T + s2 u2 v2^T with s2 ~ 0; u from the longer column,
    // v = f^T u normalised, u2 along f v2 (or any direction orthogonal to u when s2 = 0).
    let (cu, cv) = (f.column(0).into_owned(), f.column(1).into_owned());
    let d = if cv.norm_squared() > cu.norm_squared() {
        cv
    } else {
        cu
    };
    if d.norm() == 0.0 {
        return Matrix3x2::from_columns(&[Vec3::x(), Vec3::y()]);
    }
    let u = d.normalize();
    let v = (f.transpose() * u).normalize();
    let v2 = nalgebra::Vector2::new(-v.y, v.x);
    let mut u2 = f * v2;
    u2 -= u * u.dot(&u2);
    if u2.norm() <= 1e-14 * d.norm() {
        let axis = if u.x.abs() < 0.9 {
            Vec3::x()
        } else {
            Vec3::y()
        };
        u2 = axis - u * u.dot(&axis);
    }
    let u2 = u2.normalize();
    u * v.transpose() + u2 * v2.transpose()
}

/// The closest 3x2 matrix with unit columns: each column normalised (a zero column becomes the
/// corresponding column of `fallback`). Distance squared `(|w_u| - 1)^2 + (|w_v| - 1)^2`, Baraff &
/// Witkin's stretch condition.
pub fn project_unit_columns(f: &Matrix3x2<f64>, fallback: &Matrix3x2<f64>) -> Matrix3x2<f64> {
    let col = |k: usize| {
        let c = f.column(k);
        let l = c.norm();
        if l > 0.0 {
            c / l
        } else {
            fallback.column(k).into_owned()
        }
    };
    Matrix3x2::from_columns(&[col(0), col(1)])
}

/// `sum_s x[cols[s]] * values[s]` (one row of a scalar matrix applied to each coordinate),
/// accumulated from zero in slot order; with AVX2 when the CPU has it (the lanes are the
/// coordinates, each doing the scalar operations in the same order: the same bits).
#[inline]
pub fn row_times(cols: &[u32], values: &[f64], x: &[Vec3]) -> Vec3 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked above).
        return unsafe { row_times_avx2(cols, values, x) };
    }
    row_times_plain(cols, values, x)
}

#[inline]
fn row_times_plain(cols: &[u32], values: &[f64], x: &[Vec3]) -> Vec3 {
    let mut acc = Vec3::zeros();
    for (&c, &w) in cols.iter().zip(values) {
        acc += x[c as usize] * w;
    }
    acc
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn row_times_avx2(cols: &[u32], values: &[f64], x: &[Vec3]) -> Vec3 {
    use std::arch::x86_64::*;
    let mask = _mm256_set_epi64x(0, -1, -1, -1);
    let mut acc = _mm256_setzero_pd();
    for (&c, &w) in cols.iter().zip(values) {
        let xc: &Vec3 = &x[c as usize];
        // SAFETY: the mask loads the three coordinates of `xc` only (the fourth lane is 0).
        let xv = unsafe { _mm256_maskload_pd(xc.as_ptr(), mask) };
        acc = _mm256_add_pd(acc, _mm256_mul_pd(xv, _mm256_set1_pd(w)));
    }
    let mut out = [0.0f64; 4];
    // SAFETY: `out` holds four doubles.
    unsafe { _mm256_storeu_pd(out.as_mut_ptr(), acc) };
    Vec3::new(out[0], out[1], out[2])
}

/// The deformation gradient `[w_u w_v]` (Baraff & Witkin 1998, Sec. 4.2) of triangle `tri`
/// with rest data `rest` at positions `x`, corners accumulated in order.
#[inline]
pub fn triangle_gradient(tri: &[u32; 3], rest: &TriangleRest, x: &[Vec3]) -> Matrix3x2<f64> {
    let mut wu = Vec3::zeros();
    let mut wv = Vec3::zeros();
    for k in 0..3 {
        let p = x[tri[k] as usize];
        wu += p * rest.a[k];
        wv += p * rest.b[k];
    }
    Matrix3x2::from_columns(&[wu, wv])
}

/// The weighted target `p = area (w_arap R + w_col U)` of a triangle with gradient `f`, its
/// projection `r` ([`project_orthonormal`]) and rest `area`, with `U` ([`project_unit_columns`])
/// when the column weight is positive (Bouaziz et al. 2014, Sec. 4: the local step).
#[inline]
fn weighted_target(
    f: &Matrix3x2<f64>,
    r: &Matrix3x2<f64>,
    area: f64,
    (wa, wc): (f64, f64),
) -> (Matrix3x2<f64>, Option<Matrix3x2<f64>>) {
    let mut p = r * (wa * area);
    if wc > 0.0 {
        let u = project_unit_columns(f, r);
        p += u * (wc * area);
        return (p, Some(u));
    }
    (p, None)
}

/// A triangle's weighted target `p` as its share of each corner's right-hand side,
/// `p_u a[k] + p_v b[k]` (`S_t^T A_t^T p_t`, Bouaziz et al. Eq. 12).
#[inline]
pub fn corner_shares(p: &Matrix3x2<f64>, rest: &TriangleRest) -> [Vec3; 3] {
    [0, 1, 2].map(|k| p.column(0) * rest.a[k] + p.column(1) * rest.b[k])
}

/// The local step of one triangle (corners `tri`, rest data `rest`, membrane weights
/// `(arap, columns)` per unit area) at positions `x`: the corner shares ([`corner_shares`]) of
/// `area (w_arap R + w_col U)`. The reference for the four-lane version in
/// [`Projective::project`].
pub fn project_triangle(
    tri: &[u32; 3],
    rest: &TriangleRest,
    x: &[Vec3],
    weights: (f64, f64),
) -> [Vec3; 3] {
    let f = triangle_gradient(tri, rest, x);
    let r = project_orthonormal(&f);
    let (p, _) = weighted_target(&f, &r, rest.area, weights);
    corner_shares(&p, rest)
}

/// The local step four triangles at a time: the operations of [`project_triangle`] in the same
/// order per lane (no fused multiply-adds, IEEE division and square root), so the same bits; a
/// lane whose gradient is (nearly) degenerate takes the scalar [`project_orthonormal`].
mod lanes {
    use super::{project_orthonormal, project_triangle, triangle_gradient, TriangleRest};
    use crate::geom::Vec3;
    use nalgebra::Matrix3x2;

    const L: usize = 4;

    /// [`project_triangle`] of every triangle of `tris` into `out`.
    pub fn project(
        tris: &[[u32; 3]],
        rest: &[TriangleRest],
        x: &[Vec3],
        weights: (f64, f64),
        out: &mut [[Vec3; 3]],
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked above).
            unsafe { project_avx2(tris, rest, x, weights, out) };
            return;
        }
        project_plain(tris, rest, x, weights, out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn project_avx2(
        tris: &[[u32; 3]],
        rest: &[TriangleRest],
        x: &[Vec3],
        weights: (f64, f64),
        out: &mut [[Vec3; 3]],
    ) {
        project_plain(tris, rest, x, weights, out);
    }

    #[inline(always)]
    fn project_plain(
        tris: &[[u32; 3]],
        rest: &[TriangleRest],
        x: &[Vec3],
        weights: (f64, f64),
        out: &mut [[Vec3; 3]],
    ) {
        let mut ts = tris.chunks_exact(L);
        let mut rs = rest.chunks_exact(L);
        let mut os = out.chunks_exact_mut(L);
        for ((t, r), o) in (&mut ts).zip(&mut rs).zip(&mut os) {
            four(t, r, x, weights, o);
        }
        let rem = ts.remainder().iter().zip(rs.remainder());
        for ((t, r), o) in rem.zip(os.into_remainder()) {
            *o = project_triangle(t, r, x, weights);
        }
    }

    #[inline(always)]
    fn four(
        tris: &[[u32; 3]],
        rest: &[TriangleRest],
        x: &[Vec3],
        (wa, wc): (f64, f64),
        out: &mut [[Vec3; 3]],
    ) {
        let (tris, rest, out) = (&tris[..L], &rest[..L], &mut out[..L]);
        // The gradient's columns w_u, w_v per lane: f[0..3] = w_u, f[3..6] = w_v.
        let mut f = [[0.0f64; L]; 6];
        for l in 0..L {
            let g = triangle_gradient(&tris[l], &rest[l], x);
            for c in 0..3 {
                f[c][l] = g[(c, 0)];
                f[3 + c][l] = g[(c, 1)];
            }
        }
        // project_orthonormal's regular case: f (f^T f)^-1/2 in closed form.
        let mut ok = [true; L];
        let mut rot = [[0.0f64; L]; 6];
        for l in 0..L {
            let (ux, uy, uz) = (f[0][l], f[1][l], f[2][l]);
            let (vx, vy, vz) = (f[3][l], f[4][l], f[5][l]);
            let p = ux * ux + uy * uy + uz * uz;
            let q = ux * vx + uy * vy + uz * vz;
            let r = vx * vx + vy * vy + vz * vz;
            let tr = p + r;
            let det = p * r - q * q;
            ok[l] = (tr > 0.0) & (det > 1e-12 * tr * tr);
            let sd = det.sqrt();
            let s = 1.0 / (tr + 2.0 * sd).sqrt();
            let (a, b, d) = ((p + sd) * s, q * s, (r + sd) * s);
            let inv = 1.0 / (a * d - b * b);
            let (ia, ib, id) = (d * inv, -b * inv, a * inv);
            rot[0][l] = ux * ia + vx * ib;
            rot[1][l] = uy * ia + vy * ib;
            rot[2][l] = uz * ia + vz * ib;
            rot[3][l] = ux * ib + vx * id;
            rot[4][l] = uy * ib + vy * id;
            rot[5][l] = uz * ib + vz * id;
        }
        for l in 0..L {
            if !ok[l] {
                let fl = Matrix3x2::new(f[0][l], f[3][l], f[1][l], f[4][l], f[2][l], f[5][l]);
                let rl = project_orthonormal(&fl);
                for c in 0..3 {
                    rot[c][l] = rl[(c, 0)];
                    rot[3 + c][l] = rl[(c, 1)];
                }
            }
        }
        // The weighted target area (w_arap R + w_col U), U the columns of f normalised.
        let mut t = [[0.0f64; L]; 6];
        for j in 0..6 {
            for l in 0..L {
                t[j][l] = rot[j][l] * (wa * rest[l].area);
            }
        }
        if wc > 0.0 {
            for col in 0..2 {
                let mut len = [0.0f64; L];
                for l in 0..L {
                    let c = [f[3 * col][l], f[3 * col + 1][l], f[3 * col + 2][l]];
                    len[l] = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                }
                for i in 0..3 {
                    let j = 3 * col + i;
                    for l in 0..L {
                        let unit = if len[l] > 0.0 {
                            f[j][l] / len[l]
                        } else {
                            rot[j][l]
                        };
                        t[j][l] += unit * (wc * rest[l].area);
                    }
                }
            }
        }
        // Corner shares, as corner_shares.
        for l in 0..L {
            let r = &rest[l];
            for k in 0..3 {
                out[l][k] = Vec3::new(
                    t[0][l] * r.a[k] + t[3][l] * r.b[k],
                    t[1][l] * r.a[k] + t[4][l] * r.b[k],
                    t[2][l] * r.a[k] + t[5][l] * r.b[k],
                );
            }
        }
    }
}

/// Elastic parameters of the projective system.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Elastic {
    /// Stretch stiffness (N/m).
    pub stretch: f64,
    /// Shear stiffness (N/m).
    pub shear: f64,
    /// Bending stiffness (N m).
    pub bend: f64,
}

/// The elastic part of the projective-dynamics system of one mesh: element data, the constant
/// elastic matrix `L` (scalar per node pair) and the local step.
#[derive(Clone, Debug)]
pub struct Projective {
    n: usize,
    triangles: Vec<[u32; 3]>,
    rest: Vec<TriangleRest>,
    pattern: BsrPattern,
    /// Per vertex: `(triangle, corner)` incidences (CSR), for the parallel gather.
    inc_offsets: Vec<u32>,
    inc: Vec<(u32, u8)>,
    /// Constant elastic matrix `L` per pattern slot (membrane + bending).
    stiff: Vec<f64>,
    elastic: Elastic,
    /// Per unit area `(arap, columns)` weights.
    weights: (f64, f64),
    bend: Vec<super::forces::bend::BendStencil>,
}

impl Projective {
    /// The system of `n` vertices, `triangles` with their rest shape.
    pub fn new(n: usize, triangles: &[[u32; 3]], rest: &RestShape, elastic: Elastic) -> Projective {
        let mut pairs = Vec::new();
        for t in triangles {
            pairs.extend([(t[0], t[1]), (t[1], t[2]), (t[0], t[2])]);
        }
        for s in &rest.bend {
            let w = s.vertices;
            for i in 0..4 {
                for j in i + 1..4 {
                    pairs.push((w[i], w[j]));
                }
            }
        }
        let pattern = BsrPattern::from_pairs(n, pairs);
        let mut count = vec![0u32; n + 1];
        for t in triangles {
            for &v in t {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut inc = vec![(0u32, 0u8); count[n] as usize];
        for (ti, t) in triangles.iter().enumerate() {
            for (k, &v) in t.iter().enumerate() {
                inc[fill[v as usize] as usize] = (ti as u32, k as u8);
                fill[v as usize] += 1;
            }
        }
        let mut p = Projective {
            n,
            triangles: triangles.to_vec(),
            rest: rest.triangles.clone(),
            pattern,
            inc_offsets: count,
            inc,
            stiff: Vec::new(),
            elastic,
            weights: membrane_weights(elastic.stretch, elastic.shear),
            bend: rest.bend.clone(),
        };
        p.rebuild_stiffness();
        p
    }

    /// Replaces the rest shape (same mesh) and rebuilds `L` (O(triangles + edges)).
    pub fn set_rest(&mut self, rest: &RestShape) {
        self.rest.clone_from(&rest.triangles);
        self.bend.clone_from(&rest.bend);
        self.rebuild_stiffness();
    }

    /// Applies a partial rest edit ([`super::rest::RestIndex::edit`]) and recomputes only the
    /// entries of `L` of the changed triangles and stencils, each summed over the same
    /// contributions in the same order as [`Projective::set_rest`] (the same bits).
    pub fn update_rest(&mut self, edit: &super::rest::RestEdit) {
        for (t, r) in &edit.triangles {
            self.rest[*t as usize] = *r;
        }
        for (k, b) in &edit.stencils {
            self.bend[*k as usize] = *b;
        }
        let mut slots = Vec::new();
        self.stiffness_terms(
            edit.triangles.iter().map(|&(t, _)| t as usize),
            edit.stencils.iter().map(|&(k, _)| k as usize),
            |k, _| slots.push(k),
        );
        slots.sort_unstable();
        slots.dedup();
        let mut stiff = std::mem::take(&mut self.stiff);
        super::rest::resum_slots(&mut stiff, &slots, |add| {
            self.stiffness_terms(
                edit.near_triangles.iter().map(|&t| t as usize),
                edit.near_stencils.iter().map(|&s| s as usize),
                add,
            )
        });
        self.stiff = stiff;
    }

    /// Changes the elastic parameters and rebuilds `L`.
    pub fn set_elastic(&mut self, elastic: Elastic) {
        self.elastic = elastic;
        self.weights = membrane_weights(elastic.stretch, elastic.shear);
        self.rebuild_stiffness();
    }

    /// The elastic parameters.
    pub fn elastic(&self) -> Elastic {
        self.elastic
    }

    fn rebuild_stiffness(&mut self) {
        let mut stiff = vec![0.0; self.pattern.nnz()];
        self.stiffness_terms(0..self.triangles.len(), 0..self.bend.len(), |k, v| {
            stiff[k] += v
        });
        self.stiff = stiff;
    }

    /// The terms of `L` (per pattern slot) of the given triangles, then of the given bending
    /// stencils, in the order given: `w area (a_i a_j + b_i b_j)` per triangle corner pair
    /// (`w` the sum of the ARAP and column weights) and [`super::rest::bend_terms`].
    fn stiffness_terms(
        &self,
        triangles: impl Iterator<Item = usize>,
        stencils: impl Iterator<Item = usize>,
        mut add: impl FnMut(usize, f64),
    ) {
        let w = self.weights.0 + self.weights.1;
        for t in triangles {
            let (tri, r) = (&self.triangles[t], &self.rest[t]);
            for i in 0..3 {
                for j in 0..3 {
                    let slot = self.pattern.slot(tri[i], tri[j]).expect("triangle pair");
                    add(slot, w * r.area * (r.a[i] * r.a[j] + r.b[i] * r.b[j]));
                }
            }
        }
        let kb = self.elastic.bend;
        for s in stencils {
            super::rest::bend_terms(&self.pattern, &self.bend[s], kb, &mut add);
        }
    }

    /// The block pattern of the system (node pairs sharing a triangle or a bending stencil).
    pub fn pattern(&self) -> &BsrPattern {
        &self.pattern
    }

    /// The global matrix `diag(inertia) + (1 + damping) L` per pattern slot (`inertia[i]` =
    /// `(1 + h alpha) m_i / h^2`, `damping` = `beta / h`).
    pub fn system_values(&self, inertia: &[f64], damping: f64) -> Vec<f64> {
        let mut v: Vec<f64> = self.stiff.iter().map(|s| s * (1.0 + damping)).collect();
        for (i, m) in inertia.iter().enumerate() {
            v[self.pattern.diag[i] as usize] += m;
        }
        v
    }

    /// `y = L x` (the scalar matrix applied to each coordinate).
    pub fn mul_stiffness(&self, x: &[Vec3], y: &mut [Vec3]) {
        self.mul_values(&self.stiff, x, y);
    }

    /// `y = V x` for the scalar matrix with `values` per pattern slot (each coordinate).
    pub fn mul_values(&self, values: &[f64], x: &[Vec3], y: &mut [Vec3]) {
        let p = &self.pattern;
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
            for (k, yi) in ys.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                let mut acc = Vec3::zeros();
                for s in p.offsets[i] as usize..p.offsets[i + 1] as usize {
                    acc += x[p.cols[s] as usize] * values[s];
                }
                *yi = acc;
            }
        });
    }

    /// `y = (V (x) I3 + C) x` for the scalar matrix with `values` per pattern slot and the
    /// contact terms `contacts` ([`ContactTerms::mul_add`]): the rows in parallel
    /// ([`row_times`]), then the terms in order.
    pub fn mul_with_contacts(
        &self,
        values: &[f64],
        contacts: Option<&ContactTerms>,
        x: &[Vec3],
        y: &mut [Vec3],
    ) {
        let p = &self.pattern;
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
            for (k, yi) in ys.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                let row = p.offsets[i] as usize..p.offsets[i + 1] as usize;
                *yi = row_times(&p.cols[row.clone()], &values[row], x);
            }
        });
        if let Some(c) = contacts {
            c.mul_add(x, y);
        }
    }

    fn gradient(&self, t: usize, x: &[Vec3]) -> Matrix3x2<f64> {
        triangle_gradient(&self.triangles[t], &self.rest[t], x)
    }

    /// The projections of the local step (Bouaziz et al. Sec. 4): per triangle the weighted
    /// target `p = area (w_arap R + w_col U)` of its deformation gradient at `x`
    /// ([`project_orthonormal`], [`project_unit_columns`]), stored as the triangle's share of
    /// each corner's right-hand side, `p_u a[k] + p_v b[k]` ([`Projective::gather`] sums them),
    /// into `targets` (resized). Parallel over chunks of triangles; within a chunk, four
    /// triangles at a time with the same operations per lane as [`project_triangle`] (so the
    /// same bits: test `lanes_match_the_scalar_projection`), in AVX2 registers when the CPU has
    /// them.
    pub fn project(&self, x: &[Vec3], targets: &mut Vec<[Vec3; 3]>) {
        let weights = self.weights;
        targets.resize(self.triangles.len(), [Vec3::zeros(); 3]);
        targets
            .par_chunks_mut(PROJECT_CHUNK)
            .enumerate()
            .for_each(|(c, ts)| {
                let first = c * PROJECT_CHUNK;
                let end = first + ts.len();
                let (tris, rest) = (&self.triangles[first..end], &self.rest[first..end]);
                lanes::project(tris, rest, x, weights, ts);
            });
    }

    /// [`Projective::project`] that also returns the membrane energy at `x`,
    /// `sum_t area/2 (w_arap |F - R|^2 + w_col |F - U|^2)` (the distance to the constraint sets,
    /// summed in a fixed order), for the safeguard of the Anderson acceleration.
    pub fn project_energy(&self, x: &[Vec3], targets: &mut Vec<[Vec3; 3]>) -> f64 {
        let (wa, wc) = self.weights;
        targets.resize(self.triangles.len(), [Vec3::zeros(); 3]);
        let energies: Vec<f64> = targets
            .par_chunks_mut(PROJECT_CHUNK)
            .enumerate()
            .map(|(c, ts)| {
                let mut e = 0.0;
                for (k, out) in ts.iter_mut().enumerate() {
                    let t = c * PROJECT_CHUNK + k;
                    let f = self.gradient(t, x);
                    let r = project_orthonormal(&f);
                    let rest = &self.rest[t];
                    let area = rest.area;
                    let (p, u) = weighted_target(&f, &r, area, (wa, wc));
                    let mut et = wa * (f - r).norm_squared();
                    if let Some(u) = u {
                        et += wc * (f - u).norm_squared();
                    }
                    *out = corner_shares(&p, rest);
                    e += 0.5 * area * et;
                }
                e
            })
            .collect();
        energies.iter().sum()
    }

    /// The bending energy at `x`, `kb/2 sum_e |sum_i k_ei x_i|^2` (quadratic, in the factor).
    pub fn bend_energy(&self, x: &[Vec3]) -> f64 {
        let kb = self.elastic.bend;
        self.bend.iter().map(|s| s.energy(x, kb)).sum()
    }

    /// Vertex `i`'s share `sum_t S_t^T A_t^T p_t` of the local step's right-hand side, from the
    /// per-corner shares of [`Projective::project`] (incident triangles in a fixed order).
    pub fn gather(&self, targets: &[[Vec3; 3]], i: usize) -> Vec3 {
        let mut acc = Vec3::zeros();
        for &(t, corner) in
            &self.inc[self.inc_offsets[i] as usize..self.inc_offsets[i + 1] as usize]
        {
            acc += targets[t as usize][corner as usize];
        }
        acc
    }

    /// Row `i` of the global step's residual `rhs - A x` in double precision (zero on fixed
    /// rows, whose targets the iterate already holds): the constant right-hand side, the local
    /// step's share [`Projective::gather`], minus the row of the step matrix times `xs`.
    fn residual_row(
        &self,
        problem: &StepProblem,
        rhs_const: &[Vec3],
        targets: &[[Vec3; 3]],
        i: usize,
        xs: &[Vec3],
    ) -> Vec3 {
        if problem.filter[i] == Filter::Fixed {
            return Vec3::zeros();
        }
        let p = &self.pattern;
        let row = p.offsets[i] as usize..p.offsets[i + 1] as usize;
        let ax = row_times(&p.cols[row.clone()], &problem.values[row], xs);
        rhs_const[i] + self.gather(targets, i) - ax
    }

    /// The elastic energy at `x`: membrane (distance of every triangle's gradient to the two
    /// constraint sets, computed from its singular values) plus bending.
    pub fn elastic_energy(&self, x: &[Vec3]) -> f64 {
        let (wa, wc) = self.weights;
        let membrane: f64 = (0..self.triangles.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|t| {
                let f = self.gradient(t, x);
                let c = f.transpose() * f;
                let sv = nalgebra::SymmetricEigen::new(c).eigenvalues;
                let arap: f64 = sv.iter().map(|&l| (l.max(0.0).sqrt() - 1.0).powi(2)).sum();
                let cols = (f.column(0).norm() - 1.0).powi(2) + (f.column(1).norm() - 1.0).powi(2);
                0.5 * self.rest[t].area * (wa * arap + wc * cols)
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum();
        let kb = self.elastic.bend;
        let bend: f64 = self.bend.iter().map(|s| s.energy(x, kb)).sum();
        membrane + bend
    }
}

/// A cloth-cloth contact spring of a global step, `k (w (x) n)(w (x) n)^T` (a rank-one term on
/// the four weighted nodes; [`super::contact::ClothContact`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringTerm {
    /// Nodes.
    pub nodes: [u32; 4],
    /// Closest-point weights.
    pub weights: [f64; 4],
    /// Unit normal.
    pub normal: Vec3,
    /// Stiffness (per `h^2`, as the global matrix).
    pub k: f64,
}

/// The contact terms of a projective global step that the factored scalar matrix does not hold:
/// cloth-cloth springs ([`SpringTerm`]) and tangential friction penalties `k (I - n n^T)` at
/// single vertices. Applied next to the scalar matrix without assembling `3 x 3` blocks
/// ([`Projective::mul_with_contacts`]): the global step's CG then costs one scalar row pass
/// plus `O(terms)` per product.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactTerms {
    /// Springs.
    pub springs: Vec<SpringTerm>,
    /// Friction penalties: vertex, unit normal, stiffness.
    pub friction: Vec<(u32, Vec3, f64)>,
}

impl ContactTerms {
    /// Whether there is no term.
    pub fn is_empty(&self) -> bool {
        self.springs.is_empty() && self.friction.is_empty()
    }

    /// `y += C x` for the terms `C`, in term order (sequential: deterministic).
    pub fn mul_add(&self, x: &[Vec3], y: &mut [Vec3]) {
        for s in &self.springs {
            let mut d = 0.0;
            for k in 0..4 {
                d += s.weights[k] * s.normal.dot(&x[s.nodes[k] as usize]);
            }
            let f = s.normal * (s.k * d);
            for k in 0..4 {
                y[s.nodes[k] as usize] += f * s.weights[k];
            }
        }
        for &(i, n, k) in &self.friction {
            let xi = x[i as usize];
            y[i as usize] += (xi - n * n.dot(&xi)) * k;
        }
    }
}

/// One implicit step's problem for [`Projective::global_step`]: inertia, damping, constraints and the extra
/// (contact) terms of the global system.
pub struct StepProblem<'a> {
    /// Start-of-step positions `x_n`.
    pub x0: &'a [Vec3],
    /// Inertial target `y`.
    pub y: &'a [Vec3],
    /// `(1 + h alpha) m_i / h^2` per vertex.
    pub inertia: &'a [f64],
    /// `beta / h` (stiffness damping on the elastic matrix).
    pub damping: f64,
    /// The contact terms of the global matrix (`values` plus these); `None` when it is exactly
    /// `values`.
    pub contacts: Option<&'a ContactTerms>,
    /// The scalar part of the global matrix ([`Projective::system_values`]).
    pub values: &'a [f64],
    /// Whether the matrix is exactly `values` (no contact terms) and the factor is of `values`
    /// with the fixed nodes of `filter` eliminated and no other constraint: then the global
    /// step is one direct solve.
    pub exact: bool,
    /// A few contact terms as a low-rank correction of the factor ([`super::low_rank`]), with
    /// the factor exact for `values`: the global step is then one direct solve plus the
    /// correction instead of CG (`contacts` is not used).
    pub low_rank: Option<&'a LowRank>,
    /// Constant right-hand-side terms (contacts, friction) added to inertia and damping.
    pub rhs_extra: &'a [Vec3],
    /// Constrained directions of each vertex.
    pub filter: &'a [Filter],
    /// Prescribed positions in the constrained directions.
    pub targets: &'a [Vec3],
}

/// Reused buffers of the local/global iterations (no allocation per iteration).
#[derive(Clone, Debug, Default)]
pub struct Workspace {
    /// The local step's weighted projections, per triangle as its share of each corner's
    /// right-hand side ([`Projective::project`]).
    pub targets: Vec<[Vec3; 3]>,
    /// The eliminated constant right-hand side of a direct global step.
    rhs: Vec<Vec3>,
    /// A CG global step's `A x`, right-hand side `b`, prescribed increments and increment.
    ax: Vec<Vec3>,
    b: Vec<Vec3>,
    z: Vec<Vec3>,
    dx: Vec<Vec3>,
}

/// What the local/global iterations of one step did (`StepReport::projective`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ProjectiveResult {
    /// Local/global iterations run.
    pub iterations: usize,
    /// Conjugate-gradient iterations summed over the global steps.
    pub cg_iterations: usize,
    /// Relative residual of the last global step.
    pub relative_residual: f64,
    /// Whether the factor was recomputed in this step.
    pub refactored: bool,
    /// Milliseconds spent in the local steps.
    pub local_ms: f64,
    /// Milliseconds spent in the global steps.
    pub global_ms: f64,
    /// Milliseconds spent factoring.
    pub factor_ms: f64,
    /// Anderson extrapolations rejected by the energy safeguard (each costs one more local
    /// step).
    pub rejected: usize,
}

impl Projective {
    /// The constant right-hand side `M' y / h^2 + (beta/h) L x_n + extra`.
    pub fn constant_rhs(&self, problem: &StepProblem) -> Vec<Vec3> {
        let mut lx = vec![Vec3::zeros(); self.n];
        // Without stiffness damping (the simulator's case) `L x_n` is not needed.
        if problem.damping != 0.0 {
            self.mul_stiffness(problem.x0, &mut lx);
        }
        (0..self.n)
            .map(|i| {
                problem.y[i] * problem.inertia[i] + lx[i] * problem.damping + problem.rhs_extra[i]
            })
            .collect()
    }

    /// One local/global iteration from `x` (constrained directions already at their targets):
    /// [`Projective::project`], then [`Projective::global_step`].
    pub fn iterate(
        &self,
        problem: &StepProblem,
        rhs_const: &[Vec3],
        factor: &ScalarCholesky,
        settings: PcgSettings,
        x: &mut [Vec3],
        work: &mut Workspace,
    ) -> PcgResult {
        self.project(x, &mut work.targets);
        self.global_step(problem, rhs_const, factor, settings, x, None, work)
    }

    /// The global step with the local step's projections in `work.targets`
    /// ([`Projective::project`]). When the factor is exact for the problem (`problem.exact`)
    /// and no force is asked: one direct solve of the eliminated system, the local step's
    /// per-vertex gather evaluated while the right-hand side is written into the solver's buffer
    /// ([`ScalarCholesky::solve_with`]). Otherwise CG on
    /// `A x = rhs_const + local` for the increment from the current iterate (warm start),
    /// preconditioned with `factor`; with `force`, also the residual force `A x - rhs` at the
    /// new iterate (the constraint forces at constrained vertices).
    #[allow(clippy::too_many_arguments)]
    pub fn global_step(
        &self,
        problem: &StepProblem,
        rhs_const: &[Vec3],
        factor: &ScalarCholesky,
        settings: PcgSettings,
        x: &mut [Vec3],
        force: Option<&mut Vec<Vec3>>,
        work: &mut Workspace,
    ) -> PcgResult {
        let n = self.n;
        let targets = &work.targets;
        if problem.exact && force.is_none() {
            if SINGLE_PRECISION_INCREMENTS {
                // The increment from the current iterate (fixed nodes at their targets): the
                // residual `rhs - A x` per free row in double precision, evaluated while it is
                // written into the solver's buffer, then one single-precision solve.
                // The increment is added to `x` inside the solve's parallel parts.
                factor.add_increment_with(
                    |i, xs| self.residual_row(problem, rhs_const, targets, i, xs),
                    x,
                );
                return PcgResult {
                    iterations: 1,
                    relative_residual: 0.0,
                    converged: true,
                };
            }
            // Direct solve of the eliminated system: fixed rows `d x = d target`, free rows
            // `B_ff x_f = rhs_f - B_fc target_c`.
            let p = &self.pattern;
            let base = &mut work.rhs;
            base.clear();
            base.extend_from_slice(rhs_const);
            for (j, f) in problem.filter.iter().enumerate() {
                if *f == Filter::Fixed {
                    let t = problem.targets[j];
                    for s in p.offsets[j] as usize..p.offsets[j + 1] as usize {
                        let i = p.cols[s] as usize;
                        if i != j && problem.filter[i] != Filter::Fixed {
                            base[i] -= t * problem.values[s];
                        }
                    }
                    base[j] = t * problem.values[p.diag[j] as usize];
                }
            }
            let base = &*base;
            factor.solve_with(
                |i| {
                    if problem.filter[i] == Filter::Fixed {
                        base[i]
                    } else {
                        base[i] + self.gather(targets, i)
                    }
                },
                x,
            );
            for (i, xi) in x.iter_mut().enumerate() {
                if problem.filter[i] == Filter::Fixed {
                    *xi = problem.targets[i];
                }
            }
            return PcgResult {
                iterations: 1,
                relative_residual: 0.0,
                converged: true,
            };
        }
        if let Some(lr) = problem.low_rank {
            // r = rhs - A x at the free nodes (the penalties' part of `A x` first, a few
            // nodes), evaluated per row in double precision while it is written into the
            // solver's buffer; dx = B^-1 r, then the low-rank correction for the contact terms.
            // With single-precision increments (as the exact step) the correction's columns
            // `B^-1 w` stay double precision; the increment's rounding is relative to the
            // increment, so the fixed point is unchanged.
            let (pen, b) = (&mut work.ax, &mut work.b);
            pen.clear();
            pen.resize(n, Vec3::zeros());
            lr.add_penalties(x, pen);
            b.clear();
            b.resize(n, Vec3::zeros());
            let (p, pen, xs) = (&self.pattern, &*pen, &*x);
            let residual = |i: usize| {
                if problem.filter[i] == Filter::Fixed {
                    return Vec3::zeros();
                }
                let row = p.offsets[i] as usize..p.offsets[i + 1] as usize;
                let ax = row_times(&p.cols[row.clone()], &problem.values[row], xs);
                rhs_const[i] + self.gather(targets, i) - ax - pen[i]
            };
            if SINGLE_PRECISION_INCREMENTS {
                factor.solve_increment_with(residual, b);
            } else {
                factor.solve_with(residual, b);
            }
            lr.add_corrected(x, problem.targets, b, force);
            return PcgResult {
                iterations: 1,
                relative_residual: 0.0,
                converged: true,
            };
        }
        let (ax, b, z, dx) = (&mut work.ax, &mut work.b, &mut work.z, &mut work.dx);
        ax.clear();
        ax.resize(n, Vec3::zeros());
        self.mul_with_contacts(problem.values, problem.contacts, x, ax);
        b.clear();
        b.extend((0..n).map(|i| rhs_const[i] + self.gather(targets, i) - ax[i]));
        z.clear();
        z.extend((0..n).map(|i| problem.targets[i] - x[i]));
        dx.clear();
        dx.resize(n, Vec3::zeros());
        let apply = |v: &[Vec3], out: &mut [Vec3]| {
            self.mul_with_contacts(problem.values, problem.contacts, v, out)
        };
        let r = pcg::solve_factored(
            &apply,
            b,
            problem.filter,
            z,
            dx,
            settings,
            factor,
            CG_FACTOR_SOLVE,
        );
        for i in 0..n {
            x[i] += dx[i];
        }
        if let Some(f) = force {
            apply(dx, ax);
            f.resize(n, Vec3::zeros());
            for i in 0..n {
                f[i] = ax[i] - b[i];
            }
        }
        r
    }

    /// Whether [`Projective::global_step_extrapolated`] can take `problem`'s global step: a
    /// direct one with the exact factor and no contact terms, solved in single precision.
    pub fn fuses_extrapolation(problem: &StepProblem) -> bool {
        problem.exact && SINGLE_PRECISION_INCREMENTS
    }

    /// [`Projective::global_step`] of a problem that [`Projective::fuses_extrapolation`]
    /// (without constraint forces) followed by Chebyshev's extrapolation (Wang 2015), inside
    /// the substitution's parallel parts where each row's increment is added: `save[i]` gets
    /// the iterate `x[i]` before the step, and with `prev = Some((omega, p))` the new row is
    /// `(x_hat[i] - p[i]) omega + p[i]` (`x_hat` the plain global step's), else `x_hat[i]`.
    /// The same operations per row as the global step, a copy of `x` before it and the
    /// extrapolation loop after it (the same bits), without those two sequential passes.
    #[allow(clippy::too_many_arguments)]
    pub fn global_step_extrapolated(
        &self,
        problem: &StepProblem,
        rhs_const: &[Vec3],
        factor: &ScalarCholesky,
        x: &mut [Vec3],
        work: &Workspace,
        prev: Option<(f64, &[Vec3])>,
        save: &mut [Vec3],
    ) -> PcgResult {
        assert!(Self::fuses_extrapolation(problem), "a direct global step");
        assert_eq!(save.len(), x.len(), "a saved row per row");
        assert!(
            prev.is_none_or(|(_, p)| p.len() == x.len()),
            "a row per row"
        );
        let targets = &work.targets;
        let saved = DisjointRows(save.as_mut_ptr());
        factor.add_increment_map(
            |i, xs| self.residual_row(problem, rhs_const, targets, i, xs),
            x,
            |i, old, new| {
                // SAFETY: `i` < n = `save.len()` (asserted); each row is mapped once, so no
                // two threads write the same row, and `save` is not read meanwhile.
                unsafe { *saved.at(i) = old };
                match prev {
                    Some((omega, p)) => (new - p[i]) * omega + p[i],
                    None => new,
                }
            },
        );
        PcgResult {
            iterations: 1,
            relative_residual: 0.0,
            converged: true,
        }
    }

    /// The variational energy `E(x)` of the step (module docs) without contact terms.
    pub fn step_energy(&self, problem: &StepProblem, x: &[Vec3]) -> f64 {
        let inertial: f64 = (0..self.n)
            .map(|i| 0.5 * problem.inertia[i] * (x[i] - problem.y[i]).norm_squared())
            .sum();
        let d: Vec<Vec3> = (0..self.n).map(|i| x[i] - problem.x0[i]).collect();
        let mut ld = vec![Vec3::zeros(); self.n];
        self.mul_stiffness(&d, &mut ld);
        let damping = 0.5 * problem.damping * crate::sim::sparse::dot(&d, &ld);
        inertial + self.elastic_energy(x) + damping
    }
}

/// The matrix `values` (one scalar per slot) as identity blocks.
pub fn scalar_blocks(pattern: &BsrPattern, values: &[f64]) -> BsrMatrix {
    let mut m = BsrMatrix::zeros(pattern);
    for (b, &v) in m.values.iter_mut().zip(values) {
        *b = nalgebra::Matrix3::identity() * v;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::low_rank;
    use proptest::prelude::*;

    fn mat(m: &[f64; 6]) -> Matrix3x2<f64> {
        Matrix3x2::new(m[0], m[1], m[2], m[3], m[4], m[5])
    }

    proptest! {
        /// The four-lane local step gives the bits of the scalar one ([`project_triangle`],
        /// the per-triangle code it replaced) for every triangle, including degenerate
        /// gradients (collapsed corners, collinear corners: the scalar fallback per lane) and
        /// zero columns, with and without the column weight, at every chunk length.
        #[test]
        fn lanes_match_the_scalar_projection(seed in 0u64..10_000, count in 1usize..23,
                                             wc in prop::sample::select(vec![0.0, 0.7])) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut x: Vec<Vec3> = (0..12)
                .map(|_| Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0),
                                   rng.random_range(-1.0..1.0)))
                .collect();
            x[1] = x[0];
            x[2] = x[0] * 2.0 - x[3];
            let tris: Vec<[u32; 3]> = (0..count)
                .map(|_| [0, 1, 2].map(|_| rng.random_range(0..12u32)))
                .collect();
            let rest: Vec<TriangleRest> = (0..count)
                .map(|_| {
                    let mut c = || rng.random_range(-3.0..3.0);
                    let (a, b) = ([c(), c(), c()], [c(), c(), c()]);
                    let pick = rng.random_range(0..4);
                    TriangleRest {
                        a: if pick == 0 { [0.0; 3] } else { a },
                        b: if pick == 1 { [0.0; 3] } else { b },
                        area: rng.random_range(0.1..2.0),
                    }
                })
                .collect();
            let weights = (1.3, wc);
            let mut got = vec![[Vec3::zeros(); 3]; count];
            lanes::project(&tris, &rest, &x, weights, &mut got);
            for t in 0..count {
                let want = project_triangle(&tris[t], &rest[t], &x, weights);
                for k in 0..3 {
                    for c in 0..3 {
                        prop_assert_eq!(got[t][k][c].to_bits(), want[k][c].to_bits(),
                                        "triangle {} corner {}", t, k);
                    }
                }
            }
        }

        /// The AVX2 row product gives the bits of the plain one (and of `Vec3` accumulation).
        #[test]
        fn row_times_matches_the_plain_sum(seed in 0u64..10_000, len in 0usize..30) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let x: Vec<Vec3> = (0..20)
                .map(|_| Vec3::new(rng.random_range(-1e3..1e3), rng.random_range(-1.0..1.0),
                                   rng.random_range(-1e-3..1e-3)))
                .collect();
            let cols: Vec<u32> = (0..len).map(|_| rng.random_range(0..20u32)).collect();
            let values: Vec<f64> = (0..len).map(|_| rng.random_range(-1e4..1e4)).collect();
            let got = row_times(&cols, &values, &x);
            let want = row_times_plain(&cols, &values, &x);
            for c in 0..3 {
                prop_assert_eq!(got[c].to_bits(), want[c].to_bits());
            }
        }

        /// The projection equals `U V^T` of nalgebra's SVD, has orthonormal columns, is
        /// idempotent, and no sampled orthonormal 3x2 matrix is closer.
        #[test]
        fn orthonormal_projection_matches_svd(m in prop::array::uniform6(-2.0f64..2.0),
                                              angles in prop::collection::vec(-3.2f64..3.2, 60)) {
            let f = mat(&m);
            let svd = f.svd(true, true);
            prop_assume!(svd.singular_values[1] > 1e-3 * svd.singular_values[0].max(1e-9));
            let r = project_orthonormal(&f);
            let want = svd.u.unwrap() * svd.v_t.unwrap();
            prop_assert!((r - want).norm() < 1e-8, "{} vs {}", r, want);
            let rtr = r.transpose() * r;
            prop_assert!((rtr - nalgebra::Matrix2::identity()).norm() < 1e-10);
            // Re-projecting an `r` whose columns are orthonormal to `delta` moves it by about
            // `delta / 2`: the same bound as the line above (the closed form's error grows with
            // the condition number squared, up to 1e6 here; a saved case had 1.7e-11).
            prop_assert!((project_orthonormal(&r) - r).norm() < 1e-10);
            let best = (f - r).norm_squared();
            for a in angles.chunks(3) {
                let rot = nalgebra::Rotation3::from_euler_angles(a[0], a[1], a[2]);
                let q = rot.matrix().fixed_view::<3, 2>(0, 0).into_owned();
                prop_assert!((f - q).norm_squared() >= best - 1e-12);
            }
        }

        /// Degenerate gradients (rank 0 or 1) still give orthonormal columns at the closest
        /// distance `sum (sigma_i - 1)^2`.
        #[test]
        fn degenerate_projection_is_orthonormal(m in prop::array::uniform3(-2.0f64..2.0), s in -1.0f64..1.0, zero in any::<bool>()) {
            let c = Vec3::new(m[0], m[1], m[2]);
            let f = if zero { Matrix3x2::zeros() } else { Matrix3x2::from_columns(&[c, c * s]) };
            let r = project_orthonormal(&f);
            prop_assert!((r.transpose() * r - nalgebra::Matrix2::identity()).norm() < 1e-10);
            let sv = f.svd(false, false).singular_values;
            let dist: f64 = sv.iter().map(|x| (x - 1.0).powi(2)).sum();
            prop_assert!(((f - r).norm_squared() - dist).abs() < 1e-9);
        }

        /// Unit-column projection: idempotent, unit columns, and the closest such matrix
        /// (distance `sum (|c| - 1)^2`).
        #[test]
        fn unit_column_projection(m in prop::array::uniform6(-2.0f64..2.0)) {
            let f = mat(&m);
            let r = project_orthonormal(&f);
            let p = project_unit_columns(&f, &r);
            prop_assert!((p.column(0).norm() - 1.0).abs() < 1e-12);
            prop_assert!((p.column(1).norm() - 1.0).abs() < 1e-12);
            prop_assert!((project_unit_columns(&p, &r) - p).norm() < 1e-12);
            let d = (f.column(0).norm() - 1.0).powi(2) + (f.column(1).norm() - 1.0).powi(2);
            prop_assert!(((f - p).norm_squared() - d).abs() < 1e-9);
        }
    }

    proptest! {
        /// The membrane energy the local step returns (distance to its own projections) equals
        /// the one `elastic_energy` computes from the singular values (minus bending).
        #[test]
        fn local_step_energy_matches_singular_values(seed in 0u64..1000, amp in 0.0f64..0.2) {
            let s = small(4, 3, seed, amp, Elastic { stretch: 50.0, shear: 8.0, bend: 1e-4 });
            let mut targets = Vec::new();
            let e = s.system.project_energy(&s.y, &mut targets);
            let mut plain = Vec::new();
            s.system.project(&s.y, &mut plain);
            prop_assert_eq!(&plain, &targets);
            let want = s.system.elastic_energy(&s.y) - s.system.bend_energy(&s.y);
            prop_assert!((e - want).abs() <= 1e-9 * (1.0 + want.abs()), "{} vs {}", e, want);
        }
    }

    /// The membrane weights reproduce Baraff & Witkin's stretch/shear energy to second order:
    /// for a small strain, the two energies agree up to O(strain^3).
    #[test]
    fn membrane_matches_baraff_witkin_to_second_order() {
        use crate::geom::Vec2;
        use crate::sim::forces::stretch::stretch_terms;
        let uv = [
            Vec2::new(0.0, 0.0),
            Vec2::new(0.1, 0.0),
            Vec2::new(0.03, 0.08),
        ];
        let rest = TriangleRest::new(&uv[0], &uv[1], &uv[2]).unwrap();
        let (ks, ksh) = (1000.0, 100.0);
        let (wa, wc) = membrane_weights(ks, ksh);
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        for (e, ratio_tol) in [(1e-2, 0.05), (1e-3, 0.005)] {
            let strain = nalgebra::Matrix2::new(0.7 * e, 0.4 * e, 0.4 * e, -0.5 * e);
            let fm = nalgebra::Matrix2::identity() + strain;
            let x: Vec<Vec3> = uv
                .iter()
                .map(|p| {
                    let q = fm * p;
                    rot * Vec3::new(q.x, q.y, 0.0)
                })
                .collect();
            let bw = stretch_terms(&rest, [&x[0], &x[1], &x[2]], ks, ksh).energy;
            let f = Matrix3x2::from_columns(&[
                x[0] * rest.a[0] + x[1] * rest.a[1] + x[2] * rest.a[2],
                x[0] * rest.b[0] + x[1] * rest.b[1] + x[2] * rest.b[2],
            ]);
            let r = project_orthonormal(&f);
            let p = project_unit_columns(&f, &r);
            let pd = 0.5 * rest.area * (wa * (f - r).norm_squared() + wc * (f - p).norm_squared());
            assert!(
                ((pd - bw) / bw).abs() < ratio_tol,
                "strain {e}: pd {pd} bw {bw}"
            );
        }
    }

    /// A small sheet problem: `nx x ny` cells of a 0.3 m x 0.2 m sheet, rest = flat uv, start
    /// positions and inertial target perturbed (seeded), two corners pinned.
    struct Small {
        system: Projective,
        x0: Vec<Vec3>,
        y: Vec<Vec3>,
        inertia: Vec<f64>,
        damping: f64,
        fixed: Vec<bool>,
        rest: RestShape,
        triangles: Vec<[u32; 3]>,
    }

    /// The global step with Chebyshev's extrapolation inside the substitution
    /// ([`Projective::global_step_extrapolated`]) against [`Projective::global_step`] followed
    /// by the extrapolation loop: the same bits for the new iterate, and the saved rows are the
    /// iterate before the step; without a previous iterate, the plain global step. Sheets with
    /// a sequential and a split substitution, pools of one and two threads.
    #[test]
    fn extrapolated_global_step_gives_the_bits_of_step_then_extrapolation() {
        use rand::{Rng, SeedableRng};
        for (nx, ny) in [(4, 3), (40, 30)] {
            let s = small(
                nx,
                ny,
                11,
                0.01,
                Elastic {
                    stretch: 300.0,
                    shear: 30.0,
                    bend: 1e-4,
                },
            );
            let n = s.x0.len();
            let setup = Plain::new(&s, 1.0);
            let (problem, chol) = (setup.problem(&s), &setup.chol);
            assert!(Projective::fuses_extrapolation(&problem));
            let rhs = s.system.constant_rhs(&problem);
            let x: Vec<Vec3> = (0..n)
                .map(|i| if s.fixed[i] { s.x0[i] } else { s.y[i] })
                .collect();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
            let prev: Vec<Vec3> = x
                .iter()
                .map(|p| {
                    p + Vec3::new(
                        rng.random_range(-1e-3..1e-3),
                        0.0,
                        rng.random_range(-1e-3..1e-3),
                    )
                })
                .collect();
            let mut work = Workspace::default();
            s.system.project(&x, &mut work.targets);
            let settings = PcgSettings {
                tolerance: 1e-12,
                absolute: 0.0,
                max_iterations: 10,
            };
            let omega = 1.7;
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| {
                    let mut plain = x.clone();
                    s.system
                        .global_step(&problem, &rhs, chol, settings, &mut plain, None, &mut work);
                    let want: Vec<Vec3> = (0..n)
                        .map(|i| (plain[i] - prev[i]) * omega + prev[i])
                        .collect();
                    for (p, w) in [(Some((omega, &prev[..])), &want), (None, &plain)] {
                        let mut got = x.clone();
                        let mut save = vec![Vec3::zeros(); n];
                        s.system.global_step_extrapolated(
                            &problem, &rhs, chol, &mut got, &work, p, &mut save,
                        );
                        for i in 0..n {
                            for c in 0..3 {
                                assert_eq!(
                                    got[i][c].to_bits(),
                                    w[i][c].to_bits(),
                                    "{nx}x{ny}, row {i}"
                                );
                                assert_eq!(save[i][c].to_bits(), x[i][c].to_bits());
                            }
                        }
                    }
                });
            }
        }
    }

    fn small(nx: usize, ny: usize, seed: u64, amp: f64, elastic: Elastic) -> Small {
        use rand::{Rng, SeedableRng};
        let mesh =
            crate::scenes::handkerchief("s", nx, ny, 0.3, 0.2, |uv| Vec3::new(uv.x, uv.y, 0.0));
        let g = crate::mesh::Garment::new(mesh.clone()).unwrap();
        let uv = g.uv();
        let rest = RestShape::new(&mesh.triangles, &uv.triangles, &uv.coords, &g.topology).unwrap();
        let n = mesh.positions.len();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut jitter = |a: f64| {
            Vec3::new(
                rng.random_range(-a..a),
                rng.random_range(-a..a),
                rng.random_range(-a..a),
            )
        };
        let x0: Vec<Vec3> = mesh.positions.iter().map(|p| p + jitter(amp)).collect();
        let y: Vec<Vec3> = x0
            .iter()
            .map(|p| p + jitter(amp) + Vec3::new(0.0, 0.0, -0.004))
            .collect();
        let mut mass = vec![0.0; n];
        for (t, r) in mesh.triangles.iter().zip(&rest.triangles) {
            for &v in t {
                mass[v as usize] += 0.15 * r.area / 3.0;
            }
        }
        let h = 0.02;
        let inertia = mass.iter().map(|m| m / (h * h)).collect();
        let mut fixed = vec![false; n];
        fixed[0] = true;
        fixed[nx] = true;
        Small {
            system: Projective::new(n, &mesh.triangles, &rest, elastic),
            x0,
            y,
            inertia,
            damping: 0.05,
            fixed,
            rest,
            triangles: mesh.triangles.clone(),
        }
    }

    /// What a [`StepProblem`] of a [`Small`] sheet without contacts refers to: the system's
    /// values, the factor of the system with the inertia scaled by `factor_scale` (1: exact),
    /// the pinned vertices' filter and zero extra right-hand sides.
    struct Plain {
        values: Vec<f64>,
        chol: ScalarCholesky,
        exact: bool,
        filter: Vec<Filter>,
        extra: Vec<Vec3>,
    }

    impl Plain {
        fn new(s: &Small, factor_scale: f64) -> Plain {
            let values = s.system.system_values(&s.inertia, s.damping);
            let fi: Vec<f64> = s.inertia.iter().map(|m| m * factor_scale).collect();
            let mut chol = ScalarCholesky::new(s.system.pattern()).unwrap();
            let factored = s.system.system_values(&fi, s.damping);
            assert!(chol.factor(s.system.pattern(), &factored, &s.fixed));
            let filter = s
                .fixed
                .iter()
                .map(|&f| if f { Filter::Fixed } else { Filter::Free })
                .collect();
            Plain {
                values,
                chol,
                exact: factor_scale == 1.0,
                filter,
                extra: vec![Vec3::zeros(); s.x0.len()],
            }
        }

        /// The step problem: start and targets at `s.x0`, no contacts.
        fn problem<'a>(&'a self, s: &'a Small) -> StepProblem<'a> {
            StepProblem {
                x0: &s.x0,
                y: &s.y,
                inertia: &s.inertia,
                damping: s.damping,
                contacts: None,
                low_rank: None,
                values: &self.values,
                exact: self.exact,
                rhs_extra: &self.extra,
                filter: &self.filter,
                targets: &s.x0,
            }
        }
    }

    /// Runs `iterations` local/global iterations from `x` (pinned vertices held at `x0`), with
    /// the factor of the system with the inertia scaled by `factor_scale` (1: exact, else the
    /// global step runs CG preconditioned with the factor of another matrix); returns the
    /// step energies, first the start's.
    fn run(s: &Small, x: &mut [Vec3], iterations: usize, factor_scale: f64) -> Vec<f64> {
        let setup = Plain::new(s, factor_scale);
        let (problem, chol) = (setup.problem(s), &setup.chol);
        for i in 0..x.len() {
            if s.fixed[i] {
                x[i] = s.x0[i];
            }
        }
        let rhs = s.system.constant_rhs(&problem);
        let settings = PcgSettings {
            tolerance: 1e-12,
            absolute: 0.0,
            max_iterations: 500,
        };
        let mut energies = vec![s.system.step_energy(&problem, x)];
        let mut work = Workspace::default();
        for _ in 0..iterations {
            s.system
                .iterate(&problem, &rhs, chol, settings, x, &mut work);
            energies.push(s.system.step_energy(&problem, x));
        }
        energies
    }

    fn column_sum(x: &[Vec3], t: &[u32; 3], c: &[f64; 3]) -> Vec3 {
        (0..3).fold(Vec3::zeros(), |a, k| a + x[t[k] as usize] * c[k])
    }

    /// The step energy and its gradient written independently of the solver: singular values
    /// and the ARAP gradient `F - U V^T` from nalgebra's SVD, the column term, bending from the
    /// stencils and the damping quadratic assembled per element.
    fn oracle_energy_gradient(s: &Small, x: &[Vec3]) -> (f64, Vec<Vec3>) {
        let e = s.system.elastic();
        let (wa, wc) = membrane_weights(e.stretch, e.shear);
        let mut energy = 0.0;
        let mut grad = vec![Vec3::zeros(); x.len()];
        for (i, p) in x.iter().enumerate() {
            let d = p - s.y[i];
            energy += 0.5 * s.inertia[i] * d.norm_squared();
            grad[i] += d * s.inertia[i];
        }
        let d: Vec<Vec3> = (0..x.len()).map(|i| x[i] - s.x0[i]).collect();
        for (t, r) in s.triangles.iter().zip(&s.rest.triangles) {
            let f = Matrix3x2::from_columns(&[column_sum(x, t, &r.a), column_sum(x, t, &r.b)]);
            let svd = f.svd(true, true);
            let rot = svd.u.unwrap() * svd.v_t.unwrap();
            let sv = svd.singular_values;
            energy += 0.5 * r.area * wa * ((sv[0] - 1.0).powi(2) + (sv[1] - 1.0).powi(2));
            let (lu, lv) = (f.column(0).norm(), f.column(1).norm());
            energy += 0.5 * r.area * wc * ((lu - 1.0).powi(2) + (lv - 1.0).powi(2));
            let cols = Matrix3x2::from_columns(&[
                f.column(0) * (1.0 - 1.0 / lu),
                f.column(1) * (1.0 - 1.0 / lv),
            ]);
            let gf = (f - rot) * (wa * r.area) + cols * (wc * r.area);
            // Stiffness damping beta/(2h) |x - x0|_L^2 of this triangle's membrane part.
            let (du, dv) = (column_sum(&d, t, &r.a), column_sum(&d, t, &r.b));
            let wd = s.damping * (wa + wc) * r.area;
            energy += 0.5 * wd * (du.norm_squared() + dv.norm_squared());
            for k in 0..3 {
                grad[t[k] as usize] += gf.column(0) * r.a[k] + gf.column(1) * r.b[k];
                grad[t[k] as usize] += (du * r.a[k] + dv * r.b[k]) * wd;
            }
        }
        for b in &s.rest.bend {
            let stencil = |v: &[Vec3]| {
                (0..4).fold(Vec3::zeros(), |a, k| {
                    a + v[b.vertices[k] as usize] * b.weights[k]
                })
            };
            let (q, qd) = (stencil(x), stencil(&d));
            energy += 0.5 * e.bend * (q.norm_squared() + s.damping * qd.norm_squared());
            for k in 0..4 {
                grad[b.vertices[k] as usize] += (q + qd * s.damping) * (e.bend * b.weights[k]);
            }
        }
        (energy, grad)
    }

    /// Dense damped Newton on the oracle energy (Hessian by central differences of the oracle
    /// gradient), over the free vertices, to a gradient norm of 1e-10 relative.
    fn newton(s: &Small, mut x: Vec<Vec3>) -> Vec<Vec3> {
        let free: Vec<usize> = (0..x.len()).filter(|&i| !s.fixed[i]).collect();
        let m = 3 * free.len();
        let pack = |g: &[Vec3]| {
            nalgebra::DVector::from_iterator(m, free.iter().flat_map(|&i| [g[i].x, g[i].y, g[i].z]))
        };
        let scale = pack(&oracle_energy_gradient(s, &x).1).norm().max(1e-30);
        for _ in 0..100 {
            let (e, g) = oracle_energy_gradient(s, &x);
            let gv = pack(&g);
            if gv.norm() <= 1e-10 * scale {
                break;
            }
            let mut hess = nalgebra::DMatrix::<f64>::zeros(m, m);
            let eps = 1e-7;
            for (c, &i) in free.iter().enumerate() {
                for d in 0..3 {
                    let (mut xp, mut xm) = (x.clone(), x.clone());
                    xp[i][d] += eps;
                    xm[i][d] -= eps;
                    let col = (pack(&oracle_energy_gradient(s, &xp).1)
                        - pack(&oracle_energy_gradient(s, &xm).1))
                        / (2.0 * eps);
                    hess.set_column(3 * c + d, &col);
                }
            }
            let hess = (&hess + hess.transpose()) * 0.5;
            let step = hess.cholesky().expect("convex near the minimum").solve(&gv);
            let mut t = 1.0;
            loop {
                let mut xn = x.clone();
                for (c, &i) in free.iter().enumerate() {
                    xn[i] -= Vec3::new(step[3 * c], step[3 * c + 1], step[3 * c + 2]) * t;
                }
                if oracle_energy_gradient(s, &xn).0 <= e || t < 1e-6 {
                    x = xn;
                    break;
                }
                t *= 0.5;
            }
        }
        x
    }

    /// The converged projective-dynamics solution is the minimiser of the step energy found by
    /// an independent dense Newton method; the oracle's energy equals the solver's and its
    /// gradient vanishes there.
    #[test]
    fn converged_solution_matches_dense_newton() {
        let elastic = Elastic {
            stretch: 40.0,
            shear: 5.0,
            bend: 1e-4,
        };
        let s = small(3, 2, 11, 0.004, elastic);
        let mut x = s.y.clone();
        let energies = run(&s, &mut x, 3000, 1.0);
        let mut start = s.y.clone();
        for i in 0..start.len() {
            if s.fixed[i] {
                start[i] = s.x0[i];
            }
        }
        let xn = newton(&s, start);
        let err = x
            .iter()
            .zip(&xn)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(err < 1e-8, "PD vs Newton: {err} m");
        let (e_oracle, g) = oracle_energy_gradient(&s, &x);
        let e_pd = *energies.last().unwrap();
        assert!(
            (e_oracle - e_pd).abs() <= 1e-10 * e_oracle.abs(),
            "{e_oracle} vs {e_pd}"
        );
        let gmax = (0..x.len())
            .filter(|&i| !s.fixed[i])
            .map(|i| g[i].norm())
            .fold(0.0, f64::max);
        let fscale = s.inertia[1] * 0.004;
        assert!(
            gmax < 1e-8 * fscale,
            "gradient {gmax} vs force scale {fscale}"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Bouaziz et al.'s guarantee: no local/global iteration increases the step energy,
        /// with the exact factor and with CG preconditioned by the factor of another matrix.
        #[test]
        fn energy_never_increases(seed in 0u64..10_000, amp in 0.001f64..0.03,
                                  ks in 10.0f64..2000.0, ksh in 1.0f64..200.0,
                                  scale in 0.5f64..2.0) {
            let elastic = Elastic { stretch: ks, shear: ksh, bend: 1e-5 };
            let s = small(4, 3, seed, amp, elastic);
            for sc in [1.0, scale] {
                let mut x = s.y.clone();
                let e = run(&s, &mut x, 15, sc);
                for w in e.windows(2) {
                    prop_assert!(w[1] <= w[0] + 1e-12 * w[0].abs(), "{:?}", e);
                }
                prop_assert!(e.last().unwrap() < &e[0]);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// A CG global step under contact terms (springs on four weighted nodes, friction
        /// penalties, obstacle-like normal constraints, pinned nodes), applied next to the
        /// scalar matrix and preconditioned by the factor of a different matrix, converges to
        /// the minimiser of the global step's quadratic found by a dense KKT solve (nalgebra LU)
        /// of the assembled `3n x 3n` system with the constraints as rows.
        #[test]
        fn contact_global_step_matches_dense_kkt(seed in 0u64..10_000, springs in 0usize..8,
                                                 normals in 0usize..4, scale in 0.5f64..2.0) {
            use rand::{Rng, SeedableRng};
            let s = small(4, 3, seed, 0.01, Elastic { stretch: 300.0, shear: 30.0, bend: 1e-4 });
            let n = s.x0.len();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
            let unit = |rng: &mut rand_chacha::ChaCha8Rng| loop {
                let v = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0),
                                  rng.random_range(-1.0..1.0));
                if v.norm() > 0.1 {
                    return v.normalize();
                }
            };
            let mut terms = ContactTerms::default();
            for _ in 0..springs {
                let mut nodes = [0u32; 4];
                let mut weights = [0.0; 4];
                for k in 0..4 {
                    nodes[k] = rng.random_range(0..n as u32);
                    weights[k] = rng.random_range(-1.0..1.0);
                }
                let k = rng.random_range(0.1..20.0) * s.inertia[1];
                terms.springs.push(SpringTerm { nodes, weights, normal: unit(&mut rng), k });
            }
            let mut filter: Vec<Filter> = s.fixed.iter()
                .map(|&f| if f { Filter::Fixed } else { Filter::Free }).collect();
            let mut targets = s.x0.clone();
            for _ in 0..normals {
                let v = rng.random_range(0..n);
                if filter[v] != Filter::Free {
                    continue;
                }
                let nn = unit(&mut rng);
                filter[v] = Filter::Normal(nn);
                targets[v] += nn * rng.random_range(-0.01..0.01);
                if rng.random_bool(0.5) {
                    terms.friction.push((v as u32, nn, rng.random_range(0.1..5.0) * s.inertia[v]));
                }
            }
            let values = s.system.system_values(&s.inertia, s.damping);
            let fi: Vec<f64> = s.inertia.iter().map(|m| m * scale).collect();
            let mut chol = ScalarCholesky::new(s.system.pattern()).unwrap();
            prop_assert!(chol.factor(s.system.pattern(), &s.system.system_values(&fi, s.damping),
                                     &s.fixed));
            let extra: Vec<Vec3> = (0..n).map(|_| unit(&mut rng) * s.inertia[1] * 1e-3).collect();
            let problem = StepProblem {
                x0: &s.x0,
                y: &s.y,
                inertia: &s.inertia,
                damping: s.damping,
                contacts: Some(&terms),
                low_rank: None,
                values: &values,
                exact: false,
                rhs_extra: &extra,
                filter: &filter,
                targets: &targets,
            };
            let rhs = s.system.constant_rhs(&problem);
            // The start: the constrained directions at their targets.
            let mut x: Vec<Vec3> = (0..n).map(|i| match filter[i] {
                Filter::Free => s.y[i],
                Filter::Fixed => targets[i],
                Filter::Normal(nn) => s.y[i] + nn * nn.dot(&(targets[i] - s.y[i])),
            }).collect();
            let mut work = Workspace::default();
            s.system.project(&x, &mut work.targets);
            let local: Vec<Vec3> = (0..n).map(|i| s.system.gather(&work.targets, i)).collect();
            let settings = PcgSettings { tolerance: 1e-12, absolute: 0.0, max_iterations: 500 };
            let mut force = Vec::new();
            let r = s.system.global_step(&problem, &rhs, &chol, settings, &mut x,
                                         Some(&mut force), &mut work);
            prop_assert!(r.converged, "{:?}", r);

            // Dense oracle: H = V (x) I3 + sum k u u^T + friction, rows for the constraints.
            let m = 3 * n;
            let p = s.system.pattern();
            let mut h = nalgebra::DMatrix::<f64>::zeros(m, m);
            for i in 0..n {
                for slot in p.offsets[i] as usize..p.offsets[i + 1] as usize {
                    let j = p.cols[slot] as usize;
                    for d in 0..3 {
                        h[(3 * i + d, 3 * j + d)] += values[slot];
                    }
                }
            }
            for t in &terms.springs {
                let mut u = nalgebra::DVector::<f64>::zeros(m);
                for k in 0..4 {
                    for d in 0..3 {
                        u[3 * t.nodes[k] as usize + d] += t.weights[k] * t.normal[d];
                    }
                }
                h += &u * u.transpose() * t.k;
            }
            for &(v, nn, k) in &terms.friction {
                let t = (nalgebra::Matrix3::identity() - nn * nn.transpose()) * k;
                let mut blk = h.fixed_view_mut::<3, 3>(3 * v as usize, 3 * v as usize);
                blk += t;
            }
            let mut rows: Vec<(nalgebra::DVector<f64>, f64)> = Vec::new();
            for i in 0..n {
                let dirs: Vec<Vec3> = match filter[i] {
                    Filter::Free => vec![],
                    Filter::Fixed => vec![Vec3::x(), Vec3::y(), Vec3::z()],
                    Filter::Normal(nn) => vec![nn],
                };
                for e in dirs {
                    let mut u = nalgebra::DVector::<f64>::zeros(m);
                    for d in 0..3 {
                        u[3 * i + d] = e[d];
                    }
                    rows.push((u, e.dot(&targets[i])));
                }
            }
            let q = rows.len();
            let mut kkt = nalgebra::DMatrix::<f64>::zeros(m + q, m + q);
            kkt.view_mut((0, 0), (m, m)).copy_from(&h);
            let mut b = nalgebra::DVector::<f64>::zeros(m + q);
            for i in 0..n {
                for d in 0..3 {
                    b[3 * i + d] = rhs[i][d] + local[i][d];
                }
            }
            for (r, (u, c)) in rows.iter().enumerate() {
                for a in 0..m {
                    kkt[(m + r, a)] = u[a];
                    kkt[(a, m + r)] = u[a];
                }
                b[m + r] = *c;
            }
            let sol = kkt.lu().solve(&b).unwrap();
            let scale_x = 1.0 + sol.rows(0, m).amax();
            for i in 0..n {
                for d in 0..3 {
                    prop_assert!((x[i][d] - sol[3 * i + d]).abs() <= 1e-7 * scale_x,
                                 "x[{}][{}] = {} vs {}", i, d, x[i][d], sol[3 * i + d]);
                }
            }
            // The residual force `A x - b` at the solution is the constraint force: zero in
            // the free directions, matching the oracle's multipliers in the constrained ones.
            let hx = &h * sol.rows(0, m);
            let fscale = 1.0 + b.rows(0, m).amax();
            for i in 0..n {
                let want = Vec3::new(hx[3 * i] - b[3 * i], hx[3 * i + 1] - b[3 * i + 1],
                                     hx[3 * i + 2] - b[3 * i + 2]);
                prop_assert!((force[i] - want).norm() <= 1e-6 * fscale,
                             "force[{}] = {} vs {}", i, force[i], want);
            }

            // The same terms as a low-rank correction of the exact factor (the direct path):
            // springs and friction tangents as penalties, the normal constraints as rank-one
            // constraints. One step solves in single precision, so it lands near the oracle;
            // a second step from there (same projections) corrects the rounding, since the
            // residual is double precision: the fixed point is the oracle's.
            let mut exact = ScalarCholesky::new(s.system.pattern()).unwrap();
            prop_assert!(exact.factor(s.system.pattern(), &values, &s.fixed));
            let mut groups = Vec::new();
            let mut lr_terms = Vec::new();
            for t in &terms.springs {
                lr_terms.push(low_rank::Term { group: groups.len() as u32, dir: t.normal,
                                               inv_k: 1.0 / t.k });
                groups.push(low_rank::Group { nodes: t.nodes, weights: t.weights });
            }
            for i in 0..n {
                if let Filter::Normal(nn) = filter[i] {
                    let g = groups.len() as u32;
                    groups.push(low_rank::Group { nodes: [i as u32; 4],
                                                  weights: [1.0, 0.0, 0.0, 0.0] });
                    lr_terms.push(low_rank::Term { group: g, dir: nn, inv_k: 0.0 });
                    for &(v, _, k) in terms.friction.iter().filter(|f| f.0 as usize == i) {
                        let t1 = nn.cross(&Vec3::new(0.3, -0.5, 0.8)).normalize();
                        for dir in [t1, nn.cross(&t1)] {
                            debug_assert_eq!(v as usize, i);
                            lr_terms.push(low_rank::Term { group: g, dir, inv_k: 1.0 / k });
                        }
                    }
                }
            }
            let lr = LowRank::new(&exact, &s.fixed, groups, lr_terms, true);
            prop_assert!(lr.is_some());
            let direct = StepProblem { contacts: None, low_rank: lr.as_ref(), ..problem };
            let mut x: Vec<Vec3> = (0..n).map(|i| match filter[i] {
                Filter::Free => s.y[i],
                Filter::Fixed => targets[i],
                Filter::Normal(nn) => s.y[i] + nn * nn.dot(&(targets[i] - s.y[i])),
            }).collect();
            let dist = |x: &[Vec3]| (0..n)
                .flat_map(|i| (0..3).map(move |d| (i, d)))
                .map(|(i, d)| (x[i][d] - sol[3 * i + d]).abs())
                .fold(0.0, f64::max);
            for (round, tol) in [(0, 1e-5), (1, 1e-8), (2, 1e-8)] {
                s.system.global_step(&direct, &rhs, &exact, settings, &mut x, Some(&mut force),
                                     &mut work);
                prop_assert!(dist(&x) <= tol * scale_x, "round {}: {} (scale {})", round,
                             dist(&x), scale_x);
            }
            // The direct path's forces are the obstacle constraints' (what the caller reads:
            // release rule, friction bound), zero elsewhere.
            for i in (0..n).filter(|&i| matches!(filter[i], Filter::Normal(_))) {
                let want = Vec3::new(hx[3 * i] - b[3 * i], hx[3 * i + 1] - b[3 * i + 1],
                                     hx[3 * i + 2] - b[3 * i + 2]);
                prop_assert!((force[i] - want).norm() <= 1e-6 * fscale,
                             "direct force[{}] = {} vs {}", i, force[i], want);
            }
        }
    }
}
