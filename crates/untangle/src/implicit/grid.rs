//! A field cached on a regular grid: value and gradient stored at the nodes, both interpolated
//! trilinearly (Buffet et al. 2019, Sec. 4 "we pre-store the values of f_i(p) and ∇f_i(p) in a
//! grid"). Outside the grid the field is undefined (`None`): the layer is then inactive there.

use crate::geom::{Aabb, Vec3};
use rayon::prelude::*;

/// Value and gradient of a field on the nodes of a regular grid.
#[derive(Clone, Debug)]
pub struct Grid {
    /// Position of node (0, 0, 0).
    pub origin: Vec3,
    /// Edge length of a cell.
    pub cell: f64,
    /// Number of nodes along x, y, z.
    pub dims: [usize; 3],
    /// Per node (x fastest): value, gradient x, y, z.
    pub data: Vec<[f32; 4]>,
}

impl Grid {
    /// Samples `eval` (value, gradient) on the nodes of a grid covering `bbox` with cells of
    /// `cell`, in parallel (deterministic: each node is computed on its own).
    pub fn build(bbox: &Aabb, cell: f64, eval: impl Fn(&Vec3) -> (f64, Vec3) + Sync) -> Grid {
        let ext = bbox.extent();
        let dims = [0, 1, 2].map(|a| ((ext[a] / cell).ceil() as usize + 1).max(2));
        let origin = bbox.min;
        let (nx, ny) = (dims[0], dims[1]);
        let mut data = vec![[0f32; 4]; dims[0] * dims[1] * dims[2]];
        data.par_chunks_mut(nx).enumerate().for_each(|(row, out)| {
            let (j, k) = (row % ny, row / ny);
            for (i, o) in out.iter_mut().enumerate() {
                let p = origin + Vec3::new(i as f64, j as f64, k as f64) * cell;
                let (v, g) = eval(&p);
                *o = [v as f32, g.x as f32, g.y as f32, g.z as f32];
            }
        });
        Grid {
            origin,
            cell,
            dims,
            data,
        }
    }

    /// Like [`Grid::build`], with a function that fills a whole row of nodes along x at once:
    /// `eval_row(start, cell, out)` for the nodes `start + k * cell * e_x`.
    pub fn build_rows(
        bbox: &Aabb,
        cell: f64,
        eval_row: impl Fn(&Vec3, f64, &mut [(f64, Vec3)]) + Sync,
    ) -> Grid {
        let ext = bbox.extent();
        let dims = [0, 1, 2].map(|a| ((ext[a] / cell).ceil() as usize + 1).max(2));
        let origin = bbox.min;
        let (nx, ny) = (dims[0], dims[1]);
        let mut data = vec![[0f32; 4]; dims[0] * dims[1] * dims[2]];
        data.par_chunks_mut(nx).enumerate().for_each(|(row, out)| {
            let (j, k) = (row % ny, row / ny);
            let p = origin + Vec3::new(0.0, j as f64, k as f64) * cell;
            let mut buf = vec![(0.0, Vec3::zeros()); nx];
            eval_row(&p, cell, &mut buf);
            for (o, (v, g)) in out.iter_mut().zip(buf) {
                *o = [v as f32, g.x as f32, g.y as f32, g.z as f32];
            }
        });
        Grid {
            origin,
            cell,
            dims,
            data,
        }
    }

    /// The box covered by the grid.
    pub fn bbox(&self) -> Aabb {
        let ext = Vec3::new(
            (self.dims[0] - 1) as f64,
            (self.dims[1] - 1) as f64,
            (self.dims[2] - 1) as f64,
        ) * self.cell;
        Aabb {
            min: self.origin,
            max: self.origin + ext,
        }
    }

    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.data.len()
    }

    /// Trilinear interpolation of the value alone at `p`; `None` outside the grid.
    #[inline]
    pub fn sample_value(&self, p: &Vec3) -> Option<f64> {
        let q = (p - self.origin) / self.cell;
        let mut idx = [0usize; 3];
        let mut t = [0.0f64; 3];
        for a in 0..3 {
            let x = q[a];
            let last = (self.dims[a] - 1) as f64;
            if !(x >= 0.0 && x <= last) {
                return None;
            }
            // `x ≥ 0`: truncation is the floor (a call to `floor` without SSE4.1).
            let i = (x as usize).min(self.dims[a] - 2);
            idx[a] = i;
            t[a] = x - i as f64;
        }
        let (nx, ny) = (self.dims[0], self.dims[1]);
        let base = idx[0] + nx * (idx[1] + ny * idx[2]);
        let v =
            |dx: usize, dy: usize, dz: usize| self.data[base + dx + nx * (dy + ny * dz)][0] as f64;
        let lerp = |a: f64, b: f64, s: f64| a + (b - a) * s;
        let x00 = lerp(v(0, 0, 0), v(1, 0, 0), t[0]);
        let x10 = lerp(v(0, 1, 0), v(1, 1, 0), t[0]);
        let x01 = lerp(v(0, 0, 1), v(1, 0, 1), t[0]);
        let x11 = lerp(v(0, 1, 1), v(1, 1, 1), t[0]);
        Some(lerp(lerp(x00, x10, t[1]), lerp(x01, x11, t[1]), t[2]))
    }

    /// Trilinear interpolation of value and gradient at `p`; `None` outside the grid.
    #[inline]
    pub fn sample(&self, p: &Vec3) -> Option<(f64, Vec3)> {
        let q = (p - self.origin) / self.cell;
        let mut idx = [0usize; 3];
        let mut t = [0.0f64; 3];
        for a in 0..3 {
            let x = q[a];
            let last = (self.dims[a] - 1) as f64;
            if !(x >= 0.0 && x <= last) {
                return None;
            }
            // `x ≥ 0`: truncation is the floor (a call to `floor` without SSE4.1).
            let i = (x as usize).min(self.dims[a] - 2);
            idx[a] = i;
            t[a] = x - i as f64;
        }
        let (nx, ny) = (self.dims[0], self.dims[1]);
        let base = idx[0] + nx * (idx[1] + ny * idx[2]);
        // The two nodes along x of each of the four (y, z) corners, in one slice each.
        let (sy, sz) = (nx, nx * ny);
        let rows = [base, base + sy, base + sz, base + sy + sz].map(|r| &self.data[r..r + 2]);
        let (u, v) = ([1.0 - t[0], t[0]], [1.0 - t[1], t[1]]);
        let w = [1.0 - t[2], t[2]];
        let mut acc = [0.0f64; 4];
        for c in 0..8 {
            let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let wc = u[dx] * v[dy] * w[dz];
            let node = &rows[dy + 2 * dz][dx];
            for k in 0..4 {
                acc[k] += wc * node[k] as f64;
            }
        }
        Some((acc[0], Vec3::new(acc[1], acc[2], acc[3])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn linear_fields_are_reproduced_exactly(
            a in -2.0f64..2.0, b in -2.0f64..2.0, c in -2.0f64..2.0, d in -1.0f64..1.0,
            px in 0.0f64..1.0, py in 0.0f64..1.0, pz in 0.0f64..1.0,
        ) {
            let bbox = Aabb { min: Vec3::new(-1.0, -0.5, 0.0), max: Vec3::new(1.0, 0.5, 2.0) };
            let g = Vec3::new(a, b, c);
            let grid = Grid::build(&bbox, 0.13, |p| (g.dot(p) + d, g));
            let p = bbox.min + bbox.extent().component_mul(&Vec3::new(px, py, pz));
            let (v, gr) = grid.sample(&p).unwrap();
            prop_assert!((v - (g.dot(&p) + d)).abs() < 1e-5);
            prop_assert!((gr - g).norm() < 1e-5);
        }
    }

    #[test]
    fn outside_is_none_and_nodes_are_exact() {
        let bbox = Aabb {
            min: Vec3::zeros(),
            max: Vec3::new(1.0, 1.0, 1.0),
        };
        let grid = Grid::build(&bbox, 0.25, |p| (p.norm_squared(), 2.0 * p));
        assert!(grid.sample(&Vec3::new(-0.01, 0.5, 0.5)).is_none());
        assert!(grid.sample(&Vec3::new(0.5, 1.3, 0.5)).is_none());
        let p = Vec3::new(0.5, 0.25, 0.75);
        let (v, _) = grid.sample(&p).unwrap();
        assert!((v - p.norm_squared()).abs() < 1e-6);
        assert_eq!(grid.dims, [5, 5, 5]);
    }
}
