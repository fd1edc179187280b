//! A few contact terms of the projective-dynamics global step as a low-rank correction of the
//! factored matrix, so that such a step stays one direct solve instead of a factor-preconditioned
//! CG ([`super::projective::Projective::global_step`]).
//!
//! The global system of a step with contacts is `(B (x) I3 + U K U^T) dx = r` with the
//! constraints `u_c^T dx = c_c` (obstacle contacts prescribe a vertex's normal motion), where
//! `B` is the factored scalar matrix (Bouaziz et al. 2014, Eq. 12), and every contact term is
//! a rank-one `k u u^T`: a cloth-cloth spring `u = w (x) n` (closest-point weights `w` on four
//! nodes, normal `n`), friction `u = e_i (x) t` for the two tangents of a contact vertex. With
//! `G = (B^-1 (x) I3) U` the solution is
//!
//! `dx = B^-1 r - G mu`, `(U^T G + diag(1/k)) mu = U^T B^-1 r - c`
//!
//! (the Sherman-Morrison-Woodbury identity for the penalties, the Schur complement of the KKT
//! system for the constraints, `1/k = 0`; `mu` are the constraint forces). A term
//! `u = w (x) d` needs one *scalar* solve `B^-1 w`, shared by all terms on the same node
//! weights, so a step with `s` distinct weight vectors costs `s` scalar solves once plus
//! `O(s n)` per global step.

use nalgebra::{DMatrix, DVector};

use super::cholesky::ScalarCholesky;
use crate::geom::Vec3;

/// The most distinct node-weight vectors handled as a low-rank correction; steps with more
/// contact terms solve by CG (the `s` scalar solves and the `O(s n)` update per global step
/// would cost more than CG's few preconditioned iterations).
pub const MAX_GROUPS: usize = 48;

/// Node weights shared by one or more terms (unused slots have weight 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Group {
    /// Nodes.
    pub nodes: [u32; 4],
    /// Weights.
    pub weights: [f64; 4],
}

/// One rank-one term `u = w_group (x) dir`: a penalty of stiffness `1 / inv_k`, or a constraint
/// `u^T x = u^T target` when `inv_k == 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Term {
    /// Index into the groups.
    pub group: u32,
    /// Unit direction.
    pub dir: Vec3,
    /// Inverse stiffness (0 for a constraint).
    pub inv_k: f64,
}

/// The factored correction of one global system: groups, terms, the scalar columns
/// `B^-1 w` per group and the Cholesky factor of the capacitance matrix `U^T G + diag(1/k)`.
#[derive(Debug)]
pub struct LowRank {
    n: usize,
    groups: Vec<Group>,
    terms: Vec<Term>,
    /// `n x groups`, column-major: `B^-1 w_g` with the weights of fixed nodes left out.
    columns: Vec<f64>,
    capacitance: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    /// Whether the columns were solved in single precision.
    single: bool,
}

impl LowRank {
    /// Factors the correction of `terms` over `groups` for the factored matrix `factor` (the
    /// nodes with `fixed[i]` eliminated); with `single`, the columns `B^-1 w` by the factor's
    /// single-precision substitution ([`ScalarCholesky::solve_many_single`]: for a global step
    /// that solves its increments in single precision and recomputes its residual in double,
    /// so the rounding only slows the iteration), else in double precision. `None` if there
    /// are more than [`MAX_GROUPS`] groups, no factor, or the capacitance matrix is not
    /// positive definite (e.g. two identical constraints).
    pub fn new(
        factor: &ScalarCholesky,
        fixed: &[bool],
        groups: Vec<Group>,
        terms: Vec<Term>,
        single: bool,
    ) -> Option<LowRank> {
        Self::reusing(factor, fixed, groups, terms, single, None)
    }

    /// [`LowRank::new`] taking the columns `B^-1 w` of the groups that `prev` (a correction
    /// of the same factor and fixed nodes, e.g. the previous release round's) has too, with
    /// the same node weights, from `prev` instead of solving them again: the same bits, as
    /// [`ScalarCholesky::solve_many_single`] solves each column alone (its lanes do not mix).
    /// Only single-precision columns are taken over (faer's many-column solve is not known to
    /// give each column the bits of its own solve).
    pub fn reusing(
        factor: &ScalarCholesky,
        fixed: &[bool],
        groups: Vec<Group>,
        terms: Vec<Term>,
        single: bool,
        prev: Option<&LowRank>,
    ) -> Option<LowRank> {
        let n = fixed.len();
        if groups.len() > MAX_GROUPS || !factor.is_factored() {
            return None;
        }
        let same = |a: &Group, b: &Group| {
            a.nodes == b.nodes
                && a.weights
                    .iter()
                    .zip(&b.weights)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
        };
        // Per group, the column of `prev` it takes over, if any.
        let taken: Vec<Option<usize>> = groups
            .iter()
            .map(|g| {
                let p = prev.filter(|p| single && p.single && p.n == n)?;
                p.groups.iter().position(|q| same(g, q))
            })
            .collect();
        let mut columns = vec![0.0; n * groups.len()];
        // The columns to solve, packed.
        let fresh: Vec<usize> = (0..groups.len()).filter(|&g| taken[g].is_none()).collect();
        let mut solve = vec![0.0; n * fresh.len()];
        for (&g, col) in fresh.iter().zip(solve.chunks_mut(n.max(1))) {
            let g = &groups[g];
            for k in 0..4 {
                let i = g.nodes[k] as usize;
                if !fixed[i] {
                    col[i] += g.weights[k];
                }
            }
        }
        if single {
            factor.solve_many_single(&mut solve);
        } else {
            factor.solve_many(&mut solve);
        }
        for (&g, col) in fresh.iter().zip(solve.chunks(n.max(1))) {
            columns[g * n..(g + 1) * n].copy_from_slice(col);
        }
        if let Some(p) = prev {
            for (g, t) in taken.iter().enumerate() {
                if let Some(q) = *t {
                    columns[g * n..(g + 1) * n].copy_from_slice(&p.columns[q * n..(q + 1) * n]);
                }
            }
        }
        // w_a^T B^-1 w_b per pair of groups, then per pair of terms times d_r . d_s.
        let wg = |a: &Group, b: usize| -> f64 {
            let col = &columns[b * n..(b + 1) * n];
            (0..4)
                .map(|k| a.weights[k] * col[a.nodes[k] as usize])
                .sum()
        };
        let s = terms.len();
        let mut c = DMatrix::<f64>::zeros(s, s);
        for (r, tr) in terms.iter().enumerate() {
            for (q, tq) in terms.iter().enumerate().skip(r) {
                let v = tr.dir.dot(&tq.dir) * wg(&groups[tr.group as usize], tq.group as usize);
                c[(r, q)] = v;
                c[(q, r)] = v;
            }
            c[(r, r)] += tr.inv_k;
        }
        // Symmetrise what rounding left (w_a^T B^-1 w_b vs w_b^T B^-1 w_a).
        let c = (&c + c.transpose()) * 0.5;
        let capacitance = c.cholesky()?;
        Some(LowRank {
            n,
            groups,
            terms,
            columns,
            capacitance,
            single,
        })
    }

    /// Number of distinct node-weight vectors.
    pub fn groups(&self) -> usize {
        self.groups.len()
    }

    /// Number of rank-one terms.
    pub fn terms(&self) -> usize {
        self.terms.len()
    }

    fn project(&self, t: &Term, x: &[Vec3]) -> f64 {
        let g = &self.groups[t.group as usize];
        (0..4)
            .map(|k| g.weights[k] * t.dir.dot(&x[g.nodes[k] as usize]))
            .sum()
    }

    /// The penalty terms' energy `sum_p k_p/2 (u_p^T x)^2` (the linear part is in the
    /// right-hand side).
    pub fn penalty_energy(&self, x: &[Vec3]) -> f64 {
        self.terms
            .iter()
            .filter(|t| t.inv_k > 0.0)
            .map(|t| 0.5 * self.project(t, x).powi(2) / t.inv_k)
            .sum()
    }

    /// Adds the penalty terms' `sum_p k_p u_p (u_p^T x)` to `out` (the correction's part of
    /// `A x`, all nodes included).
    pub fn add_penalties(&self, x: &[Vec3], out: &mut [Vec3]) {
        for t in &self.terms {
            if t.inv_k > 0.0 {
                let f = self.project(t, x) / t.inv_k;
                let g = &self.groups[t.group as usize];
                for k in 0..4 {
                    out[g.nodes[k] as usize] += t.dir * (f * g.weights[k]);
                }
            }
        }
    }

    /// Turns `z = (B^-1 (x) I3) r` (the factor's solve of the residual, zero at fixed nodes) into
    /// the increment `dx` of the corrected system with every constraint `u_c^T dx = c_c`,
    /// `c_c = u_c^T (targets - x)`; with `force`, writes the constraint forces
    /// `A dx - r = -sum_c mu_c u_c` there (zero elsewhere).
    pub fn correct(
        &self,
        x: &[Vec3],
        targets: &[Vec3],
        z: &mut [Vec3],
        force: Option<&mut Vec<Vec3>>,
    ) {
        let dirs = self.directions(x, targets, z, force);
        let n = self.n;
        for (g, d) in dirs.iter().enumerate() {
            if *d == Vec3::zeros() {
                continue;
            }
            let col = &self.columns[g * n..(g + 1) * n];
            for (zi, &c) in z.iter_mut().zip(col) {
                *zi -= d * c;
            }
        }
    }

    /// [`LowRank::correct`] added to the iterate: `x += dx` (`dx` the corrected `z`), in
    /// parallel over the rows, each row's operations those of `correct` followed by
    /// `x[i] += z[i]` (the same bits); `z` is left as it was.
    pub fn add_corrected(
        &self,
        x: &mut [Vec3],
        targets: &[Vec3],
        z: &[Vec3],
        force: Option<&mut Vec<Vec3>>,
    ) {
        use rayon::prelude::*;
        let n = self.n;
        let dirs = self.directions(x, targets, z, force);
        let used: Vec<(usize, Vec3)> = dirs
            .iter()
            .enumerate()
            .filter(|(_, d)| **d != Vec3::zeros())
            .map(|(g, d)| (g, *d))
            .collect();
        x.par_chunks_mut(ROW_CHUNK)
            .zip(z.par_chunks(ROW_CHUNK))
            .enumerate()
            .for_each(|(k, (xs, zs))| {
                for (j, (xi, zi)) in xs.iter_mut().zip(zs).enumerate() {
                    let i = k * ROW_CHUNK + j;
                    let mut d = *zi;
                    for (g, dir) in &used {
                        d -= dir * self.columns[g * n + i];
                    }
                    *xi += d;
                }
            });
    }

    /// The constraint forces' and penalties' multipliers `mu` for `z` (see
    /// [`LowRank::correct`]) summed per group into the direction `sum_r mu_r d_r`; with
    /// `force`, writes the constraint forces there.
    fn directions(
        &self,
        x: &[Vec3],
        targets: &[Vec3],
        z: &[Vec3],
        force: Option<&mut Vec<Vec3>>,
    ) -> Vec<Vec3> {
        let n = self.n;
        let q = DVector::from_iterator(
            self.terms.len(),
            self.terms.iter().map(|t| {
                let c = if t.inv_k > 0.0 {
                    0.0
                } else {
                    let g = &self.groups[t.group as usize];
                    (0..4)
                        .map(|k| {
                            let i = g.nodes[k] as usize;
                            g.weights[k] * t.dir.dot(&(targets[i] - x[i]))
                        })
                        .sum()
                };
                self.project(t, z) - c
            }),
        );
        let mu = self.capacitance.solve(&q);
        // Per group the direction sum_r mu_r d_r, then dx -= column (x) direction.
        let mut dirs = vec![Vec3::zeros(); self.groups.len()];
        for (t, m) in self.terms.iter().zip(mu.iter()) {
            dirs[t.group as usize] += t.dir * *m;
        }
        if let Some(f) = force {
            f.clear();
            f.resize(n, Vec3::zeros());
            for (t, m) in self.terms.iter().zip(mu.iter()) {
                if t.inv_k == 0.0 {
                    let g = &self.groups[t.group as usize];
                    for k in 0..4 {
                        f[g.nodes[k] as usize] -= t.dir * (m * g.weights[k]);
                    }
                }
            }
        }
        dirs
    }
}

/// Rows per parallel task of [`LowRank::add_corrected`].
const ROW_CHUNK: usize = 1024;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::sparse::BsrPattern;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    fn unit(rng: &mut impl Rng) -> Vec3 {
        loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if v.norm() > 0.1 {
                return v.normalize();
            }
        }
    }

    proptest! {
        /// On a random sparse SPD scalar matrix with random fixed nodes, random springs (four
        /// weighted nodes), constrained vertices and friction-like tangential penalties, the
        /// corrected increment and the constraint forces equal a dense solve of the full
        /// `3n x 3n` KKT system (nalgebra LU): `H dx + C^T lambda = r`, `C dx = c`, with `C` the
        /// fixed coordinates and the constraint rows.
        #[test]
        fn correction_matches_dense_kkt(seed in 0u64..1000, n in 4usize..24, springs in 0usize..6,
                                        contacts in 0usize..4) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut pairs = Vec::new();
            for i in 0..n as u32 {
                let j = rng.random_range(0..n as u32);
                if j != i { pairs.push((i, j)); }
                if i > 0 { pairs.push((i - 1, i)); }
            }
            let pattern = BsrPattern::from_pairs(n, pairs);
            let mut b = DMatrix::<f64>::zeros(n, n);
            for i in 0..n {
                for s in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                    let j = pattern.cols[s] as usize;
                    if j < i {
                        let v: f64 = rng.random_range(-1.0..0.0);
                        b[(i, j)] = v;
                        b[(j, i)] = v;
                    }
                }
            }
            for i in 0..n {
                let row: f64 = (0..n).filter(|&j| j != i).map(|j| b[(i, j)].abs()).sum();
                b[(i, i)] = row + rng.random_range(0.05..1.0);
            }
            let mut values = vec![0.0; pattern.nnz()];
            for i in 0..n {
                for s in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                    values[s] = b[(i, pattern.cols[s] as usize)];
                }
            }
            let fixed: Vec<bool> = (0..n).map(|_| rng.random_bool(0.15)).collect();
            let mut chol = ScalarCholesky::new(&pattern).unwrap();
            prop_assert!(chol.factor(&pattern, &values, &fixed));
            let mut groups = Vec::new();
            let mut terms = Vec::new();
            for _ in 0..springs {
                let mut nodes = [0u32; 4];
                let mut weights = [0.0; 4];
                for k in 0..4 {
                    nodes[k] = rng.random_range(0..n as u32);
                    weights[k] = rng.random_range(-1.0..1.0);
                }
                terms.push(Term { group: groups.len() as u32, dir: unit(&mut rng),
                                  inv_k: 1.0 / rng.random_range(0.1..100.0) });
                groups.push(Group { nodes, weights });
            }
            // Constraints on distinct free vertices, some with two tangential penalties.
            let free: Vec<u32> = (0..n as u32).filter(|&i| !fixed[i as usize]).collect();
            for &v in free.iter().take(contacts) {
                let d = unit(&mut rng);
                let g = groups.len() as u32;
                groups.push(Group { nodes: [v; 4], weights: [1.0, 0.0, 0.0, 0.0] });
                terms.push(Term { group: g, dir: d, inv_k: 0.0 });
                if rng.random_bool(0.5) {
                    let t1 = d.cross(&Vec3::new(0.3, -0.5, 0.8)).normalize();
                    for dir in [t1, d.cross(&t1)] {
                        terms.push(Term { group: g, dir, inv_k: 1.0 / rng.random_range(0.1..10.0) });
                    }
                }
            }
            let lr = LowRank::new(&chol, &fixed, groups.clone(), terms.clone(), false).unwrap();
            let r: Vec<Vec3> = (0..n)
                .map(|i| if fixed[i] { Vec3::zeros() } else { unit(&mut rng) * rng.random_range(0.0..2.0) })
                .collect();
            let x = vec![Vec3::zeros(); n];
            let targets: Vec<Vec3> = (0..n).map(|_| unit(&mut rng) * 0.1).collect();
            let mut dx = r.clone();
            chol.solve3(&mut dx);
            let mut force = Vec::new();
            lr.correct(&x, &targets, &mut dx, Some(&mut force));

            // Dense oracle.
            let m = 3 * n;
            let mut h = DMatrix::<f64>::zeros(m, m);
            for i in 0..n { for j in 0..n { for d in 0..3 { h[(3 * i + d, 3 * j + d)] = b[(i, j)]; } } }
            let dense_u = |t: &Term| {
                let g = &groups[t.group as usize];
                let mut u = DVector::<f64>::zeros(m);
                for k in 0..4 { for d in 0..3 { u[3 * g.nodes[k] as usize + d] += g.weights[k] * t.dir[d]; } }
                u
            };
            let mut rows: Vec<(DVector<f64>, f64)> = Vec::new();
            for i in (0..n).filter(|&i| fixed[i]) {
                for d in 0..3 {
                    let mut e = DVector::<f64>::zeros(m);
                    e[3 * i + d] = 1.0;
                    rows.push((e, 0.0));
                }
            }
            for t in &terms {
                let u = dense_u(t);
                if t.inv_k > 0.0 {
                    h += &u * u.transpose() / t.inv_k;
                } else {
                    let c = (0..n).map(|i| (0..3).map(|d| u[3 * i + d] * targets[i][d]).sum::<f64>()).sum();
                    rows.push((u, c));
                }
            }
            let k = rows.len();
            let mut kkt = DMatrix::<f64>::zeros(m + k, m + k);
            kkt.view_mut((0, 0), (m, m)).copy_from(&h);
            let mut rhs = DVector::<f64>::zeros(m + k);
            for i in 0..n { for d in 0..3 { rhs[3 * i + d] = r[i][d]; } }
            for (q, (u, c)) in rows.iter().enumerate() {
                for a in 0..m {
                    kkt[(m + q, a)] = u[a];
                    kkt[(a, m + q)] = u[a];
                }
                rhs[m + q] = *c;
            }
            let sol = kkt.lu().solve(&rhs).unwrap();
            let want = sol.rows(0, m).into_owned();
            let scale = 1.0 + want.amax();
            let hdx = &h * &want;
            for i in 0..n {
                for d in 0..3 {
                    prop_assert!((dx[i][d] - want[3 * i + d]).abs() <= 1e-8 * scale,
                        "dx[{}][{}] = {} vs {}", i, d, dx[i][d], want[3 * i + d]);
                    if !fixed[i] {
                        let f = hdx[3 * i + d] - r[i][d];
                        prop_assert!((force[i][d] - f).abs() <= 1e-7 * scale * (1.0 + h.amax()),
                            "force[{}][{}] = {} vs {}", i, d, force[i][d], f);
                    }
                }
            }
            // The columns by the single-precision substitution: the same solution to the
            // rounding of single precision (the global step iterates that away).
            let lr32 = LowRank::new(&chol, &fixed, groups.clone(), terms.clone(), true).unwrap();
            let mut dx32 = r.clone();
            chol.solve3(&mut dx32);
            let mut z32 = dx32.clone();
            lr32.correct(&x, &targets, &mut dx32, None);
            // Added to an iterate in parallel: the bits of `correct`, then `x + dx`.
            let x1: Vec<Vec3> = (0..n).map(|_| unit(&mut rng)).collect();
            let mut got = x1.clone();
            let want_force = {
                let mut f = Vec::new();
                lr32.correct(&x1, &targets, &mut z32.clone(), Some(&mut f));
                f
            };
            let mut got_force = Vec::new();
            lr32.add_corrected(&mut got, &targets, &z32, Some(&mut got_force));
            lr32.correct(&x1, &targets, &mut z32, None);
            for i in 0..n {
                prop_assert_eq!(got[i], x1[i] + z32[i]);
            }
            prop_assert_eq!(got_force, want_force);
            for i in 0..n {
                for d in 0..3 {
                    prop_assert!((dx32[i][d] - want[3 * i + d]).abs() <= 1e-5 * scale,
                        "single: dx[{}][{}] = {} vs {}", i, d, dx32[i][d], want[3 * i + d]);
                }
            }
            // A release round keeps some groups (and adds a new one): taken over from `lr32`,
            // the same bits as solved afresh.
            let mut sub_groups = Vec::new();
            let mut sub_terms = Vec::new();
            for (g, grp) in groups.iter().enumerate().filter(|(g, _)| g % 2 == seed as usize % 2) {
                for t in terms.iter().filter(|t| t.group as usize == g) {
                    sub_terms.push(Term { group: sub_groups.len() as u32, ..*t });
                }
                sub_groups.push(*grp);
            }
            let v = rng.random_range(0..n as u32);
            sub_terms.push(Term { group: sub_groups.len() as u32, dir: unit(&mut rng), inv_k: 0.5 });
            sub_groups.push(Group { nodes: [v, 0, 0, 0], weights: [1.0, 0.0, 0.0, 0.0] });
            let fresh = LowRank::new(&chol, &fixed, sub_groups.clone(), sub_terms.clone(), true);
            let reused = LowRank::reusing(&chol, &fixed, sub_groups, sub_terms, true, Some(&lr32));
            prop_assert_eq!(fresh.is_some(), reused.is_some());
            if let (Some(a), Some(b)) = (fresh, reused) {
                prop_assert!(a.columns.iter().zip(&b.columns).all(|(p, q)| p.to_bits() == q.to_bits()));
                let mut za = r.clone();
                chol.solve3(&mut za);
                let mut zb = za.clone();
                a.correct(&x, &targets, &mut za, None);
                b.correct(&x, &targets, &mut zb, None);
                prop_assert!(za.iter().zip(&zb).all(|(p, q)| p == q));
            }
        }
    }
}
