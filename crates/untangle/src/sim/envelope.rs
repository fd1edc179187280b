//! Envelope (profile) Cholesky factorisation of a sparse symmetric positive definite matrix in a
//! bandwidth-reducing order (reverse Cuthill-McKee), for the coarse level of the CG
//! preconditioner ([`crate::sim::pcg::CoarseLevel`]): a coarse grid of a few hundred surface
//! aggregates couples each aggregate only to its neighbours, so after reordering the matrix is
//! banded and its factor costs `O(m b^2)` instead of the dense `O(m^3)` (`m` unknowns, `b` the
//! band width); the triangular solves cost `O(m b)`.
//!
//! Storage: row `k` of the lower triangle holds columns `first[k]..=k`. The Cholesky factor of
//! such a matrix has no entries left of `first[k]` in row `k` (fill stays inside the envelope;
//! George & Liu, "Computer Solution of Large Sparse Positive Definite Systems", 1981, Ch. 4), so
//! the factor overwrites the matrix in place.

/// A symmetric matrix stored by its lower envelope, factorised in place by
/// [`EnvelopeCholesky::factor`].
#[derive(Clone, Debug, PartialEq)]
pub struct EnvelopeCholesky {
    /// First stored column of each row.
    first: Vec<usize>,
    /// Offset of entry `(k, first[k])` in `values`; entry `(k, j)` is at `start[k] + j - first[k]`.
    start: Vec<usize>,
    values: Vec<f64>,
    factored: bool,
}

impl EnvelopeCholesky {
    /// An all-zero matrix whose row `k` stores columns `first[k]..=k` (`first[k] <= k`, clamped).
    pub fn zeros(first: &[usize]) -> EnvelopeCholesky {
        let first: Vec<usize> = first.iter().enumerate().map(|(k, &f)| f.min(k)).collect();
        let mut start = Vec::with_capacity(first.len() + 1);
        let mut len = 0;
        for (k, &f) in first.iter().enumerate() {
            start.push(len);
            len += k - f + 1;
        }
        start.push(len);
        EnvelopeCholesky {
            first,
            start,
            values: vec![0.0; len],
            factored: false,
        }
    }

    /// Order of the matrix.
    pub fn size(&self) -> usize {
        self.first.len()
    }

    /// Stored entries (the envelope's size).
    pub fn stored(&self) -> usize {
        self.values.len()
    }

    /// Whether `(k, j)` (lower triangle, `j <= k`) lies inside the envelope.
    #[inline]
    pub fn contains(&self, k: usize, j: usize) -> bool {
        j <= k && j >= self.first[k]
    }

    /// Mutable entry `(k, j)`, `j <= k`, inside the envelope (panics outside: a caller bug).
    #[inline]
    pub fn entry_mut(&mut self, k: usize, j: usize) -> &mut f64 {
        assert!(self.contains(k, j), "entry ({k}, {j}) outside the envelope");
        self.factored = false;
        &mut self.values[self.start[k] + j - self.first[k]]
    }

    /// Entry `(k, j)` of the lower triangle (0 outside the envelope).
    #[inline]
    pub fn get(&self, k: usize, j: usize) -> f64 {
        if self.contains(k, j) {
            self.values[self.start[k] + j - self.first[k]]
        } else {
            0.0
        }
    }

    /// The stored part of row `k`: columns `first[k]..=k`.
    #[inline]
    fn row(&self, k: usize) -> &[f64] {
        &self.values[self.start[k]..self.start[k + 1]]
    }

    /// Factorises in place (`A = L L^T`, row-oriented "bordering" method); `false` if the matrix
    /// is not numerically positive definite (then the values are garbage).
    pub fn factor(&mut self) -> bool {
        let m = self.size();
        for k in 0..m {
            let fk = self.first[k];
            let (sk, ek) = (self.start[k], self.start[k + 1]);
            for j in fk..k {
                let fj = self.first[j];
                let p0 = fk.max(fj);
                // L_kj = (A_kj - sum_{p0 <= p < j} L_kp L_jp) / L_jj
                let (before, rest) = self.values.split_at_mut(sk);
                let row_k = &mut rest[..ek - sk];
                let row_j = &before[self.start[j]..self.start[j + 1]];
                let mut s = row_k[j - fk];
                for p in p0..j {
                    s -= row_k[p - fk] * row_j[p - fj];
                }
                row_k[j - fk] = s / row_j[j - fj];
            }
            let row_k = &mut self.values[sk..ek];
            let mut d = row_k[k - fk];
            for v in &row_k[..k - fk] {
                d -= v * v;
            }
            if d.is_nan() || d <= 0.0 {
                self.factored = false;
                return false;
            }
            row_k[k - fk] = d.sqrt();
        }
        self.factored = true;
        true
    }

    /// Whether [`EnvelopeCholesky::factor`] succeeded on the current values.
    pub fn is_factored(&self) -> bool {
        self.factored
    }

    /// Solves `A x = b` in place (`b` becomes `x`) with the factor.
    pub fn solve_mut(&self, b: &mut [f64]) {
        assert!(self.factored, "solve without a factorisation");
        let m = self.size();
        // L y = b
        for k in 0..m {
            let fk = self.first[k];
            let row = self.row(k);
            let mut s = b[k];
            for p in fk..k {
                s -= row[p - fk] * b[p];
            }
            b[k] = s / row[k - fk];
        }
        // L^T x = y
        for k in (0..m).rev() {
            let fk = self.first[k];
            let row = self.row(k);
            b[k] /= row[k - fk];
            let xk = b[k];
            for p in fk..k {
                b[p] -= row[p - fk] * xk;
            }
        }
    }
}

/// Reverse Cuthill-McKee order of a graph given by sorted adjacency lists (`adjacency[i]`, may
/// contain `i`): `order[new] = old`. Each connected component starts from a vertex of least
/// degree; neighbours are visited by increasing degree (ties by index), so the result is
/// deterministic.
pub fn reverse_cuthill_mckee(adjacency: &[Vec<u32>]) -> Vec<u32> {
    let n = adjacency.len();
    let degree: Vec<usize> = adjacency.iter().map(|a| a.len()).collect();
    let mut by_degree: Vec<u32> = (0..n as u32).collect();
    by_degree.sort_by_key(|&i| (degree[i as usize], i));
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut next = Vec::new();
    for &root in &by_degree {
        if seen[root as usize] {
            continue;
        }
        seen[root as usize] = true;
        let mut head = order.len();
        order.push(root);
        while head < order.len() {
            let i = order[head] as usize;
            head += 1;
            next.clear();
            next.extend(adjacency[i].iter().copied().filter(|&j| !seen[j as usize]));
            next.sort_by_key(|&j| (degree[j as usize], j));
            for &j in &next {
                if !seen[j as usize] {
                    seen[j as usize] = true;
                    order.push(j);
                }
            }
        }
    }
    order.reverse();
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random sparse SPD matrix on a random graph (a sum of PSD edge terms plus a positive
    /// diagonal), in the given vertex order, with its adjacency.
    fn random_spd(n: usize, edges: usize, seed: u64) -> (DMatrix<f64>, Vec<Vec<u32>>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut adj = vec![Vec::new(); n];
        for _ in 0..edges {
            let (i, j) = (rng.random_range(0..n), rng.random_range(0..n));
            if i == j {
                continue;
            }
            let (u, v) = (rng.random_range(0.1..3.0), rng.random_range(-2.0..2.0));
            // [u v; v v^2/u + 0.01] is PSD.
            a[(i, i)] += u;
            a[(j, j)] += v * v / u + 0.01;
            a[(i, j)] += v;
            a[(j, i)] += v;
            adj[i].push(j as u32);
            adj[j].push(i as u32);
        }
        for (i, l) in adj.iter_mut().enumerate() {
            a[(i, i)] += rng.random_range(0.01..1.0);
            l.sort_unstable();
            l.dedup();
        }
        (a, adj)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// In RCM order, the envelope factor solves like a dense Cholesky factor (oracle:
        /// nalgebra's dense Cholesky of the same matrix), and RCM returns a permutation.
        #[test]
        fn envelope_solve_matches_dense_cholesky(
            n in 1usize..60,
            density in 0usize..4,
            seed in 0u64..100_000,
        ) {
            let (a, adj) = random_spd(n, n * density, seed);
            let order = reverse_cuthill_mckee(&adj);
            let mut sorted = order.clone();
            sorted.sort_unstable();
            prop_assert_eq!(sorted, (0..n as u32).collect::<Vec<_>>());
            let mut inv = vec![0usize; n];
            for (new, &old) in order.iter().enumerate() {
                inv[old as usize] = new;
            }
            let first: Vec<usize> = (0..n)
                .map(|k| {
                    let old = order[k] as usize;
                    adj[old].iter().map(|&j| inv[j as usize]).fold(k, usize::min)
                })
                .collect();
            let mut e = EnvelopeCholesky::zeros(&first);
            let pa = DMatrix::from_fn(n, n, |r, c| a[(order[r] as usize, order[c] as usize)]);
            for k in 0..n {
                for j in 0..=k {
                    if pa[(k, j)] != 0.0 {
                        prop_assert!(e.contains(k, j), "({}, {}) outside", k, j);
                        *e.entry_mut(k, j) = pa[(k, j)];
                    }
                }
            }
            prop_assert!(e.factor());
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xabc);
            let b = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
            let mut x = b.as_slice().to_vec();
            e.solve_mut(&mut x);
            let expect = pa.clone().cholesky().unwrap().solve(&b);
            let scale = expect.amax().max(1e-300);
            for k in 0..n {
                prop_assert!((x[k] - expect[k]).abs() <= 1e-9 * scale, "{} vs {}", x[k], expect[k]);
            }
            // The factor's entries reproduce A = L L^T.
            let l = DMatrix::from_fn(n, n, |r, c| if c <= r { e.get(r, c) } else { 0.0 });
            let err = (&l * l.transpose() - &pa).amax();
            prop_assert!(err <= 1e-10 * pa.amax(), "{}", err);
        }
    }

    /// An indefinite matrix is refused.
    #[test]
    fn indefinite_is_refused() {
        let mut e = EnvelopeCholesky::zeros(&[0, 0, 1]);
        for (k, j, v) in [
            (0, 0, 1.0),
            (1, 0, 2.0),
            (1, 1, 1.0),
            (2, 1, 0.5),
            (2, 2, 3.0),
        ] {
            *e.entry_mut(k, j) = v;
        }
        assert!(!e.factor());
        assert!(!e.is_factored());
    }

    /// On a path graph numbered badly, RCM recovers a band of width one.
    #[test]
    fn rcm_finds_the_band_of_a_path() {
        let n = 40u32;
        // Path visiting vertices in a scrambled order.
        let seq: Vec<u32> = (0..n).map(|k| (k * 17) % n).collect();
        let mut adj = vec![Vec::new(); n as usize];
        for w in seq.windows(2) {
            adj[w[0] as usize].push(w[1]);
            adj[w[1] as usize].push(w[0]);
        }
        for l in &mut adj {
            l.sort_unstable();
        }
        let order = reverse_cuthill_mckee(&adj);
        let mut inv = vec![0i64; n as usize];
        for (new, &old) in order.iter().enumerate() {
            inv[old as usize] = new as i64;
        }
        for w in seq.windows(2) {
            assert_eq!((inv[w[0] as usize] - inv[w[1] as usize]).abs(), 1);
        }
    }
}
