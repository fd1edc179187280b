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
        let mut all: Vec<(u32, u32)> = (0..n as u32).map(|i| (i, i)).collect();
        for (i, j) in pairs {
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

/// Block values over a [`BsrPattern`].
#[derive(Clone, Debug)]
pub struct BsrMatrix {
    /// One 3x3 block per pattern slot.
    pub values: Vec<Matrix3<f64>>,
}

impl BsrMatrix {
    /// All-zero values for `pattern`.
    pub fn zeros(pattern: &BsrPattern) -> BsrMatrix {
        BsrMatrix {
            values: vec![Matrix3::zeros(); pattern.nnz()],
        }
    }

    /// `y = A x`, parallel over block rows.
    pub fn mul(&self, pattern: &BsrPattern, x: &[Vec3], y: &mut [Vec3]) {
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ys)| {
            let r0 = c * CHUNK;
            for (k, yi) in ys.iter_mut().enumerate() {
                let i = r0 + k;
                let (s, e) = (pattern.offsets[i] as usize, pattern.offsets[i + 1] as usize);
                let mut acc = Vec3::zeros();
                for slot in s..e {
                    acc += self.values[slot] * x[pattern.cols[slot] as usize];
                }
                *yi = acc;
            }
        });
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
        d
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
        let yd = d * xd;
        for i in 0..n {
            for r in 0..3 {
                assert!((y[i][r] - yd[3 * i + r]).abs() < 1e-9 * (1.0 + yd[3 * i + r].abs()));
            }
        }
        assert_eq!(p.slot(5, 12), Some(p.slot(5, 12).unwrap()));
        assert!(p.slot(5, 13).is_none());
    }
}
