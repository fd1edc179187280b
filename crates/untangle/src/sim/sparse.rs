//! A symmetric-pattern block-sparse matrix with 3x3 blocks (BSR), the system matrix of the
//! implicit step (Baraff & Witkin 1998, Sec. 5): one block row per simulation node, one block per
//! pair of nodes coupled by a force (triangle corners, bending stencils).
//!
//! The pattern is fixed at construction; values are overwritten every step. The product runs in
//! parallel over block rows; each row is computed independently, so the result is bit-identical
//! for any thread count.

use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::geom::Vec3;

/// Rows per parallel task in products and vector kernels.
pub(crate) const CHUNK: usize = 512;

/// The sparsity pattern: sorted column indices per block row (diagonal always present).
#[derive(Clone, Debug)]
pub struct BsrPattern {
    /// `cols[offsets[i]..offsets[i + 1]]` are the block columns of row `i`, sorted.
    pub offsets: Vec<u32>,
    /// Block column indices.
    pub cols: Vec<u32>,
    /// Slot of the diagonal block of each row.
    pub diag: Vec<u32>,
}

impl BsrPattern {
    /// The pattern of `n` rows holding the diagonal and both `(i, j)` and `(j, i)` for every given
    /// coupled pair.
    pub fn from_pairs(n: usize, pairs: impl IntoIterator<Item = (u32, u32)>) -> BsrPattern {
        // Bucketed by row (a counting sort), then each short row sorted and deduplicated: the
        // same pattern as sorting all entries, without the global sort.
        let pairs: Vec<(u32, u32)> = pairs.into_iter().collect();
        let mut start = vec![0u32; n + 1];
        for &(i, j) in &pairs {
            start[i as usize + 1] += 1;
            start[j as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i] + 1;
        }
        let mut fill: Vec<u32> = start[..n].to_vec();
        let mut raw = vec![0u32; start[n] as usize];
        for i in 0..n {
            raw[fill[i] as usize] = i as u32;
            fill[i] += 1;
        }
        for &(i, j) in &pairs {
            raw[fill[i as usize] as usize] = j;
            fill[i as usize] += 1;
            raw[fill[j as usize] as usize] = i;
            fill[j as usize] += 1;
        }
        let mut offsets = vec![0u32; n + 1];
        let mut cols: Vec<u32> = Vec::with_capacity(raw.len());
        for i in 0..n {
            let row = &mut raw[start[i] as usize..start[i + 1] as usize];
            row.sort_unstable();
            let first = cols.len();
            for &j in row.iter() {
                if cols.len() == first || cols[cols.len() - 1] != j {
                    cols.push(j);
                }
            }
            offsets[i + 1] = cols.len() as u32;
        }
        let diag = (0..n)
            .map(|i| {
                let (s, e) = (offsets[i] as usize, offsets[i + 1] as usize);
                (s + cols[s..e]
                    .binary_search(&(i as u32))
                    .expect("diagonal present")) as u32
            })
            .collect();
        BsrPattern {
            offsets,
            cols,
            diag,
        }
    }

    /// Number of block rows.
    pub fn rows(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Number of stored blocks.
    pub fn nnz(&self) -> usize {
        self.cols.len()
    }

    /// The slot of block `(i, j)`, if it is in the pattern.
    pub fn slot(&self, i: u32, j: u32) -> Option<usize> {
        let (s, e) = (
            self.offsets[i as usize] as usize,
            self.offsets[i as usize + 1] as usize,
        );
        self.cols[s..e].binary_search(&j).ok().map(|k| s + k)
    }
}

/// Block values over a [`BsrPattern`], plus couplings outside the pattern.
#[derive(Clone, Debug)]
pub struct BsrMatrix {
    /// One 3x3 block per pattern slot.
    pub values: Vec<Matrix3<f64>>,
    /// Off-diagonal couplings of contact pairs (their diagonal blocks are in `values`).
    pub pairs: PairTerms,
}

/// Rank-3 couplings of contact pairs that the fixed pattern does not hold: pair `c` with nodes
/// `nodes[c]` (`u32::MAX`: a node without unknowns, e.g. an obstacle), weights `w` and a
/// symmetric 3x3 `S` contributes the blocks `w_k w_j S` for `k != j` (its diagonal blocks
/// `w_k^2 S` go into the pattern's diagonal, see [`BsrMatrix::add_pair`]). The product gathers
/// per row in a fixed order, so it is bit-identical for any thread count.
#[derive(Clone, Debug, Default)]
pub struct PairTerms {
    nodes: Vec<[u32; 4]>,
    weights: Vec<[f64; 4]>,
    blocks: Vec<Matrix3<f64>>,
    /// CSR over rows: `(pair, corner)` entries of row `i` at `offsets[i]..offsets[i + 1]`.
    offsets: Vec<u32>,
    entries: Vec<(u32, u8)>,
}

impl PairTerms {
    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    fn finish(&mut self, n: usize) {
        let mut count = vec![0u32; n + 1];
        for nodes in &self.nodes {
            for &k in nodes {
                if k != u32::MAX {
                    count[k as usize + 1] += 1;
                }
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut entries = vec![(0u32, 0u8); count[n] as usize];
        for (c, nodes) in self.nodes.iter().enumerate() {
            for (k, &v) in nodes.iter().enumerate() {
                if v != u32::MAX {
                    entries[fill[v as usize] as usize] = (c as u32, k as u8);
                    fill[v as usize] += 1;
                }
            }
        }
        self.offsets = count;
        self.entries = entries;
    }

    /// `y += (off-diagonal pair blocks) x`.
    fn mul_add(&self, x: &[Vec3], y: &mut [Vec3]) {
        if self.nodes.is_empty() {
            return;
        }
        let s: Vec<Vec3> = self
            .nodes
            .par_iter()
            .zip(&self.weights)
            .with_min_len(256)
            .map(|(nodes, w)| {
                let mut a = Vec3::zeros();
                for k in 0..4 {
                    if nodes[k] != u32::MAX {
                        a += x[nodes[k] as usize] * w[k];
                    }
                }
                a
            })
            .collect();
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
            for (k, yi) in ys.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                for &(p, corner) in
                    &self.entries[self.offsets[i] as usize..self.offsets[i + 1] as usize]
                {
                    let (p, corner) = (p as usize, corner as usize);
                    let w = self.weights[p][corner];
                    *yi += self.blocks[p] * ((s[p] - x[i] * w) * w);
                }
            }
        });
    }
}

impl BsrMatrix {
    /// All-zero values for `pattern`.
    pub fn zeros(pattern: &BsrPattern) -> BsrMatrix {
        BsrMatrix {
            values: vec![Matrix3::zeros(); pattern.nnz()],
            pairs: PairTerms::default(),
        }
    }

    /// Adds the pair terms `w_k w_j s` for all corners `k, j` of `nodes` (`u32::MAX` = no
    /// unknowns): diagonal blocks into the pattern, the others as [`PairTerms`]. Call
    /// [`BsrMatrix::finish_pairs`] after the last one.
    pub fn add_pair(
        &mut self,
        pattern: &BsrPattern,
        nodes: [u32; 4],
        w: [f64; 4],
        s: Matrix3<f64>,
    ) {
        for k in 0..4 {
            if nodes[k] != u32::MAX {
                self.values[pattern.diag[nodes[k] as usize] as usize] += s * (w[k] * w[k]);
            }
        }
        if nodes.iter().filter(|&&k| k != u32::MAX).count() > 1 {
            self.pairs.nodes.push(nodes);
            self.pairs.weights.push(w);
            self.pairs.blocks.push(s);
        }
    }

    /// Indexes the pairs added by [`BsrMatrix::add_pair`] for the product.
    pub fn finish_pairs(&mut self, pattern: &BsrPattern) {
        self.pairs.finish(pattern.rows());
    }

    /// `y = A x`, parallel over block rows.
    pub fn mul(&self, pattern: &BsrPattern, x: &[Vec3], y: &mut [Vec3]) {
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
            mul_rows(&self.values, pattern, x, c * CHUNK, ys);
        });
        self.pairs.mul_add(x, y);
    }

    /// `y = A x`, then `post(first_row, rows)` on each chunk of `CHUNK` (512) rows of `y`; returns
    /// the sum of the `post` results in chunk order (deterministic for any thread count).
    /// Without pair couplings the product and `post` run in one parallel pass (one fork-join
    /// per CG iteration fewer, and `y` is still in cache for `post`); the result is the same as
    /// [`BsrMatrix::mul`] followed by the separate pass.
    pub fn mul_then_sum(
        &self,
        pattern: &BsrPattern,
        x: &[Vec3],
        y: &mut [Vec3],
        post: impl Fn(usize, &mut [Vec3]) -> f64 + Sync,
    ) -> f64 {
        let parts: Vec<f64> = if self.pairs.is_empty() {
            y.par_chunks_mut(CHUNK)
                .enumerate()
                .map(|(c, ys)| {
                    mul_rows(&self.values, pattern, x, c * CHUNK, ys);
                    post(c * CHUNK, ys)
                })
                .collect()
        } else {
            self.mul(pattern, x, y);
            y.par_chunks_mut(CHUNK)
                .enumerate()
                .map(|(c, ys)| post(c * CHUNK, ys))
                .collect()
        };
        parts.iter().sum()
    }

    /// The dense matrix (for tests and small checks).
    pub fn to_dense(&self, pattern: &BsrPattern) -> nalgebra::DMatrix<f64> {
        let n = pattern.rows();
        let mut d = nalgebra::DMatrix::zeros(3 * n, 3 * n);
        for i in 0..n {
            for slot in pattern.offsets[i] as usize..pattern.offsets[i + 1] as usize {
                let j = pattern.cols[slot] as usize;
                d.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                    .copy_from(&self.values[slot]);
            }
        }
        let pt = &self.pairs;
        for c in 0..pt.len() {
            for k in 0..4 {
                for j in 0..4 {
                    let (a, b) = (pt.nodes[c][k], pt.nodes[c][j]);
                    if k != j && a != u32::MAX && b != u32::MAX {
                        let blk = pt.blocks[c] * (pt.weights[c][k] * pt.weights[c][j]);
                        let mut v = d.fixed_view_mut::<3, 3>(3 * a as usize, 3 * b as usize);
                        v += blk;
                    }
                }
            }
        }
        d
    }
}

/// `ys[k] = (row r0 + k of the pattern part of A) x`, with AVX2 when the CPU has it.
///
/// The result is bit-identical with and without AVX2: both accumulate
/// `y_i += (A_ij[.,0] x_j.x + A_ij[.,1] x_j.y) + A_ij[.,2] x_j.z` over the row's blocks in
/// pattern order; the AVX2 lanes are the three rows of a block, each doing the scalar
/// operations in the same order (Rust never contracts them to fused multiply-adds).
fn mul_rows(values: &[Matrix3<f64>], pattern: &BsrPattern, x: &[Vec3], r0: usize, ys: &mut [Vec3]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { mul_rows_avx2(values, pattern, x, r0, ys) };
            return;
        }
    }
    mul_rows_generic(values, pattern, x, r0, ys);
}

/// [`mul_rows_generic`] with one 4-lane vector per block column (lanes = the block's rows, the
/// fourth lane unused): per lane the same operations in the same order, so bit-identical.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn mul_rows_avx2(
    values: &[Matrix3<f64>],
    pattern: &BsrPattern,
    x: &[Vec3],
    r0: usize,
    ys: &mut [Vec3],
) {
    use std::arch::x86_64::*;
    for (k, yi) in ys.iter_mut().enumerate() {
        let i = r0 + k;
        let (s, e) = (pattern.offsets[i] as usize, pattern.offsets[i + 1] as usize);
        let mut acc = _mm256_setzero_pd();
        for (m, &c) in values[s..e].iter().zip(&pattern.cols[s..e]) {
            let xv = &x[c as usize];
            let d: &[f64; 9] = m.as_slice().try_into().expect("a 3x3 block has 9 entries");
            // SAFETY: every load reads 4 consecutive entries inside the 9 of `d` (columns 0 and
            // 1 start at entries 0 and 3; column 2 is entries 5..9 shifted down by one lane).
            let (c0, c1, c2) = unsafe {
                (
                    _mm256_loadu_pd(d.as_ptr()),
                    _mm256_loadu_pd(d.as_ptr().add(3)),
                    _mm256_permute4x64_pd::<0b11_11_10_01>(_mm256_loadu_pd(d.as_ptr().add(5))),
                )
            };
            let t = _mm256_add_pd(
                _mm256_mul_pd(c0, _mm256_set1_pd(xv.x)),
                _mm256_mul_pd(c1, _mm256_set1_pd(xv.y)),
            );
            let t = _mm256_add_pd(t, _mm256_mul_pd(c2, _mm256_set1_pd(xv.z)));
            acc = _mm256_add_pd(acc, t);
        }
        let mut out = [0.0f64; 4];
        // SAFETY: `out` has 4 entries.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), acc) };
        *yi = Vec3::new(out[0], out[1], out[2]);
    }
}

fn mul_rows_generic(
    values: &[Matrix3<f64>],
    pattern: &BsrPattern,
    x: &[Vec3],
    r0: usize,
    ys: &mut [Vec3],
) {
    for (k, yi) in ys.iter_mut().enumerate() {
        let i = r0 + k;
        let (s, e) = (pattern.offsets[i] as usize, pattern.offsets[i + 1] as usize);
        let (mut a0, mut a1, mut a2) = (0.0, 0.0, 0.0);
        for (m, &c) in values[s..e].iter().zip(&pattern.cols[s..e]) {
            // Column-major 3x3 times x, written out (the generic product is slower here).
            let xv = &x[c as usize];
            let d = m.as_slice();
            a0 += d[0] * xv.x + d[3] * xv.y + d[6] * xv.z;
            a1 += d[1] * xv.x + d[4] * xv.y + d[7] * xv.z;
            a2 += d[2] * xv.x + d[5] * xv.y + d[8] * xv.z;
        }
        *yi = Vec3::new(a0, a1, a2);
    }
}

/// Deterministic parallel dot product: fixed chunks summed in order.
pub fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    let parts: Vec<f64> = a
        .par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p.dot(q)).sum::<f64>())
        .collect();
    parts.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]
        /// The bucketed pattern equals the one read off the sorted, deduplicated list of all
        /// entries (the diagonal, every pair both ways), including repeated pairs, self pairs
        /// and empty rows.
        #[test]
        fn from_pairs_matches_a_global_sort(n in 1usize..40,
                                            raw in proptest::collection::vec((0u32..40, 0u32..40), 0..120)) {
            let pairs: Vec<(u32, u32)> = raw.iter().map(|&(i, j)| (i % n as u32, j % n as u32)).collect();
            let got = BsrPattern::from_pairs(n, pairs.iter().copied());
            let mut all: Vec<(u32, u32)> = (0..n as u32).map(|i| (i, i)).collect();
            for &(i, j) in &pairs {
                all.push((i, j));
                all.push((j, i));
            }
            all.sort_unstable();
            all.dedup();
            let mut offsets = vec![0u32; n + 1];
            for &(i, _) in &all {
                offsets[i as usize + 1] += 1;
            }
            for i in 0..n {
                offsets[i + 1] += offsets[i];
            }
            let cols: Vec<u32> = all.iter().map(|&(_, j)| j).collect();
            proptest::prop_assert_eq!(&got.offsets, &offsets);
            proptest::prop_assert_eq!(&got.cols, &cols);
            for i in 0..n {
                proptest::prop_assert_eq!(got.cols[got.diag[i] as usize], i as u32);
                proptest::prop_assert!(got.diag[i] >= offsets[i] && got.diag[i] < offsets[i + 1]);
            }
        }

        /// The dispatched product (AVX2 on CPUs that have it) is bit-identical to the scalar
        /// reference [`mul_rows_generic`] on random patterns and values of mixed magnitudes, and
        /// [`BsrMatrix::mul_then_sum`] to the product followed by a separate pass.
        #[test]
        fn vector_product_is_bit_identical_to_the_scalar_one(
            n in 1usize..300,
            links in 0usize..5,
            seed in 0u64..1_000_000,
        ) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let pairs: Vec<(u32, u32)> = (0..n * links)
                .map(|_| (rng.random_range(0..n as u32), rng.random_range(0..n as u32)))
                .filter(|(i, j)| i != j)
                .collect();
            let p = BsrPattern::from_pairs(n, pairs);
            let mut a = BsrMatrix::zeros(&p);
            let value = |rng: &mut rand_chacha::ChaCha8Rng| {
                rng.random_range(-1.0..1.0) * 10f64.powi(rng.random_range(-12..12))
            };
            for v in a.values.iter_mut() {
                *v = Matrix3::from_fn(|_, _| value(&mut rng));
            }
            let x: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(value(&mut rng), value(&mut rng), value(&mut rng)))
                .collect();
            let mut y = vec![Vec3::zeros(); n];
            a.mul(&p, &x, &mut y);
            let mut reference = vec![Vec3::zeros(); n];
            mul_rows_generic(&a.values, &p, &x, 0, &mut reference);
            for i in 0..n {
                for r in 0..3 {
                    proptest::prop_assert_eq!(y[i][r].to_bits(), reference[i][r].to_bits());
                }
            }
            // The fused product-and-reduce gives the same vector and the same sum as the
            // product followed by a separate pass, with and without pair couplings.
            let post = |first: usize, ys: &mut [Vec3]| {
                let mut acc = 0.0;
                for (k, yk) in ys.iter_mut().enumerate() {
                    *yk *= 0.5 + (first + k) as f64;
                    acc += yk.dot(&x[first + k]);
                }
                acc
            };
            for with_pairs in [false, true] {
                if with_pairs && n > 2 {
                    let nn = Vec3::new(0.3, 0.4, 0.5);
                    a.add_pair(&p, [0, 1, 2, u32::MAX], [1.0, -0.5, -0.5, 0.0], nn * nn.transpose());
                    a.finish_pairs(&p);
                }
                let mut fused = vec![Vec3::zeros(); n];
                let s1 = a.mul_then_sum(&p, &x, &mut fused, post);
                let mut separate = vec![Vec3::zeros(); n];
                a.mul(&p, &x, &mut separate);
                let s2: f64 = separate
                    .chunks_mut(CHUNK)
                    .enumerate()
                    .map(|(c, ys)| post(c * CHUNK, ys))
                    .collect::<Vec<f64>>()
                    .iter()
                    .sum();
                proptest::prop_assert_eq!(s1.to_bits(), s2.to_bits());
                for i in 0..n {
                    for r in 0..3 {
                        proptest::prop_assert_eq!(fused[i][r].to_bits(), separate[i][r].to_bits());
                    }
                }
            }
        }
    }

    #[test]
    fn product_matches_dense() {
        let n = 1200;
        let pairs: Vec<(u32, u32)> = (0..n as u32 - 1)
            .map(|i| (i, i + 1))
            .chain((0..n as u32 - 7).map(|i| (i, i + 7)))
            .collect();
        let p = BsrPattern::from_pairs(n, pairs);
        assert_eq!(p.nnz(), n + 2 * (n - 1) + 2 * (n - 7));
        let mut a = BsrMatrix::zeros(&p);
        for (k, v) in a.values.iter_mut().enumerate() {
            *v = Matrix3::from_fn(|r, c| ((k * 31 + r * 7 + c * 3) % 11) as f64 - 5.0);
        }
        let x: Vec<Vec3> = (0..n)
            .map(|i| Vec3::new(i as f64, (i % 5) as f64, -(i as f64).sqrt()))
            .collect();
        let mut y = vec![Vec3::zeros(); n];
        a.mul(&p, &x, &mut y);
        let d = a.to_dense(&p);
        let xd = nalgebra::DVector::from_iterator(3 * n, x.iter().flat_map(|v| [v.x, v.y, v.z]));
        let yd = &d * &xd;
        for i in 0..n {
            for r in 0..3 {
                assert!((y[i][r] - yd[3 * i + r]).abs() < 1e-9 * (1.0 + yd[3 * i + r].abs()));
            }
        }
        // Pair couplings (also between rows the pattern does not couple) against the dense
        // matrix built independently.
        let mut dense = d.clone();
        for c in 0..40u32 {
            let nodes = [
                c * 29 % n as u32,
                (c * 13 + 500) % n as u32,
                u32::MAX,
                (c * 7 + 3) % n as u32,
            ];
            let w = [1.0, -0.3 - c as f64 * 0.01, -0.5, -0.2];
            let v = Vec3::new(1.0, c as f64 * 0.1, -0.5);
            let s = v * v.transpose() + Matrix3::identity() * 0.25;
            a.add_pair(&p, nodes, w, s);
            for k in 0..4 {
                for j in 0..4 {
                    if nodes[k] != u32::MAX && nodes[j] != u32::MAX {
                        let mut blk = dense
                            .fixed_view_mut::<3, 3>(3 * nodes[k] as usize, 3 * nodes[j] as usize);
                        blk += s * (w[k] * w[j]);
                    }
                }
            }
        }
        a.finish_pairs(&p);
        a.mul(&p, &x, &mut y);
        let yd = &dense
            * nalgebra::DVector::from_iterator(3 * n, x.iter().flat_map(|v| [v.x, v.y, v.z]));
        for i in 0..n {
            for r in 0..3 {
                assert!((y[i][r] - yd[3 * i + r]).abs() < 1e-9 * (1.0 + yd[3 * i + r].abs()));
            }
        }
        assert!((a.to_dense(&p) - dense).amax() < 1e-12);
        assert_eq!(p.slot(5, 12), Some(p.slot(5, 12).unwrap()));
        assert!(p.slot(5, 13).is_none());
    }
}
