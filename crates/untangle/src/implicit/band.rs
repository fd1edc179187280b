//! Narrow-band filling of a field grid (a speed-up of the grid cache of Buffet et al. 2019,
//! Sec. 4; not in the paper).
//!
//! A garment's layer is absent wherever `|f_i| ≥ depth_limit + depth_fade`, and its co-variant
//! field `h_i` only matters through the fade across `h_margin ≤ h_i ≤ h_margin + rim_fade`
//! (see [`super::field`]), so each field is only needed exactly in a band around one level
//! set (`f_i = 0`, `h_i = h_margin + rim_fade / 2`); beyond it, only the side matters. The grid
//! is cut into blocks of [`BLOCK`]³ cells. The field is evaluated exactly at the block corners
//! (a coarse grid, 1/64 of the nodes); a block is *exact* when it contains a seed point (a mesh
//! vertex), when its corners are not all on the same side of the level, or when the smallest corner `|f|`
//! is below `band + L · d / 2` (`d` the block diagonal, so every point is within `d / 2` of a
//! corner; `L` twice the largest corner gradient: a Lipschitz estimate with a safety factor),
//! with `f` measured from the level. All nodes of exact blocks are evaluated exactly.
//! Closure: an exact node on the border of a non-exact block whose `|f|` is below `band`, or
//! that lies on the other side of the level than the block's corners, makes that block exact too, until nothing changes.
//! The other nodes get the trilinear interpolation of their block's corners (value and
//! gradient): all corners are on one side, beyond the band, so the far-field value keeps the
//! side and stays beyond the band, and every cell that is not fully exact interpolates to a
//! value beyond the band on the right side: the fade computed from it is the same as with the
//! full grid (0 or 1, with a zero fade gradient), so the projection does not notice.

use super::grid::Grid;
use crate::geom::{Aabb, Vec3};
use rayon::prelude::*;

/// Edge of a block, in cells.
pub const BLOCK: usize = 4;

/// Which blocks of a grid were filled exactly (see the module documentation).
#[derive(Clone, Debug)]
pub struct BandMask {
    /// Number of blocks along x, y, z.
    pub bdims: [usize; 3],
    /// Per block (x fastest): evaluated exactly.
    pub exact: Vec<bool>,
}

impl BandMask {
    /// Fraction of the blocks filled exactly.
    pub fn exact_fraction(&self) -> f64 {
        self.exact.iter().filter(|&&e| e).count() as f64 / self.exact.len().max(1) as f64
    }
}

/// `eval_row(start, dx, first, out)`: the field at `start + (first + k) * dx * e_x` for
/// `k = 0..out.len()`, bit-identical to the same points evaluated as part of a whole row.
type RowEval<'a> = dyn Fn(&Vec3, f64, usize, &mut [(f64, Vec3)]) + Sync + 'a;

fn dims_of(bbox: &Aabb, cell: f64) -> [usize; 3] {
    let ext = bbox.extent();
    [0, 1, 2].map(|a| ((ext[a] / cell).ceil() as usize + 1).max(2))
}

/// Coarse node indices along one axis: every `BLOCK`-th node and the last one.
fn coarse_axis(n: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..n).step_by(BLOCK).collect();
    if *v.last().unwrap() != n - 1 {
        v.push(n - 1);
    }
    v
}

/// Exact values and gradients at the coarse nodes (x fastest).
fn coarse_values(
    origin: &Vec3,
    cell: f64,
    cax: &[Vec<usize>; 3],
    eval_row: &RowEval,
) -> Vec<(f64, Vec3)> {
    let (cx, cy, cz) = (&cax[0], &cax[1], &cax[2]);
    let regular = (cx.len() - 1) * BLOCK == *cx.last().unwrap();
    let mut out = vec![(0.0, Vec3::zeros()); cx.len() * cy.len() * cz.len()];
    out.par_chunks_mut(cx.len())
        .enumerate()
        .for_each(|(row, o)| {
            let (j, k) = (cy[row % cy.len()], cz[row / cy.len()]);
            let p = origin + Vec3::new(0.0, j as f64, k as f64) * cell;
            if regular {
                eval_row(&p, BLOCK as f64 * cell, 0, o);
            } else {
                let n = o.len();
                eval_row(&p, BLOCK as f64 * cell, 0, &mut o[..n - 1]);
                eval_row(&p, cell, cx[n - 1], &mut o[n - 1..]);
            }
        });
    out
}

/// Node range `[lo, hi]` of block `b` along an axis with `n` nodes.
#[inline]
fn block_nodes(b: usize, n: usize) -> (usize, usize) {
    (b * BLOCK, ((b + 1) * BLOCK).min(n - 1))
}

/// Blocks that contain node `i` along an axis with `nb` blocks (one, or two on a block border).
#[inline]
fn blocks_of(i: usize, nb: usize) -> [Option<usize>; 2] {
    let b = (i / BLOCK).min(nb - 1);
    let other = if i % BLOCK == 0 && i > 0 && b > 0 && b * BLOCK == i {
        Some(b - 1)
    } else {
        None
    };
    [Some(b), other]
}

struct Filler<'a> {
    origin: Vec3,
    cell: f64,
    dims: [usize; 3],
    bdims: [usize; 3],
    coarse: Vec<(f64, Vec3)>,
    cdims: [usize; 3],
    eval_row: &'a RowEval<'a>,
}

impl Filler<'_> {
    fn corner(&self, b: [usize; 3], c: usize) -> &(f64, Vec3) {
        let idx = [0, 1, 2].map(|a| b[a] + ((c >> a) & 1));
        &self.coarse[idx[0] + self.cdims[0] * (idx[1] + self.cdims[1] * idx[2])]
    }

    fn block_index(&self, b: [usize; 3]) -> usize {
        b[0] + self.bdims[0] * (b[1] + self.bdims[1] * b[2])
    }

    /// Evaluates exactly every node of the blocks in `todo` not yet exact (`done`).
    fn evaluate(&self, todo: &[bool], data: &mut [[f32; 4]], done: &mut [bool]) {
        let (nx, ny) = (self.dims[0], self.dims[1]);
        let bd = self.bdims;
        data.par_chunks_mut(nx)
            .zip(done.par_chunks_mut(nx))
            .enumerate()
            .for_each(|(row, (out, done))| {
                let (j, k) = (row % ny, row / ny);
                let mut need = vec![false; nx];
                let mut any = false;
                for bj in blocks_of(j, bd[1]).into_iter().flatten() {
                    for bk in blocks_of(k, bd[2]).into_iter().flatten() {
                        for bi in 0..bd[0] {
                            if todo[bi + bd[0] * (bj + bd[1] * bk)] {
                                let (lo, hi) = block_nodes(bi, nx);
                                need[lo..=hi].iter_mut().for_each(|x| *x = true);
                                any = true;
                            }
                        }
                    }
                }
                if !any {
                    return;
                }
                let mut buf = Vec::new();
                let mut i = 0;
                while i < nx {
                    if !need[i] || done[i] {
                        i += 1;
                        continue;
                    }
                    let s = i;
                    while i < nx && need[i] && !done[i] {
                        i += 1;
                    }
                    buf.clear();
                    buf.resize(i - s, (0.0, Vec3::zeros()));
                    let p = self.origin + Vec3::new(0.0, j as f64, k as f64) * self.cell;
                    (self.eval_row)(&p, self.cell, s, &mut buf);
                    for (t, (v, g)) in buf.iter().enumerate() {
                        out[s + t] = [*v as f32, g.x as f32, g.y as f32, g.z as f32];
                        done[s + t] = true;
                    }
                }
            });
    }

    /// Fills the nodes not evaluated exactly with the trilinear interpolation of their block's
    /// corners.
    fn interpolate_rest(&self, data: &mut [[f32; 4]], done: &[bool]) {
        let (nx, ny) = (self.dims[0], self.dims[1]);
        let bd = self.bdims;
        data.par_chunks_mut(nx)
            .zip(done.par_chunks(nx))
            .enumerate()
            .for_each(|(row, (out, done))| {
                let (j, k) = (row % ny, row / ny);
                let bj = (j / BLOCK).min(bd[1] - 1);
                let bk = (k / BLOCK).min(bd[2] - 1);
                let (jl, jh) = block_nodes(bj, ny);
                let (kl, kh) = block_nodes(bk, self.dims[2]);
                let ty = (j - jl) as f64 / (jh - jl) as f64;
                let tz = (k - kl) as f64 / (kh - kl) as f64;
                for i in 0..nx {
                    if done[i] {
                        continue;
                    }
                    let bi = (i / BLOCK).min(bd[0] - 1);
                    let (il, ih) = block_nodes(bi, nx);
                    let tx = (i - il) as f64 / (ih - il) as f64;
                    let mut acc = [0.0f64; 4];
                    for c in 0..8 {
                        let w = (if c & 1 != 0 { tx } else { 1.0 - tx })
                            * (if c & 2 != 0 { ty } else { 1.0 - ty })
                            * (if c & 4 != 0 { tz } else { 1.0 - tz });
                        let (v, g) = self.corner([bi, bj, bk], c);
                        acc[0] += w * v;
                        acc[1] += w * g.x;
                        acc[2] += w * g.y;
                        acc[3] += w * g.z;
                    }
                    out[i] = acc.map(|x| x as f32);
                }
            });
    }
}

impl Grid {
    /// Like [`Grid::build_rows`], exact only in a band `|f − level| < band` around the level set
    /// `f = level` (and in the blocks holding a `seeds` point), with a far-field value elsewhere
    /// that stays beyond the band on the same side (see [`super::band`]). Returns the grid and
    /// its exact blocks.
    pub fn build_band(
        bbox: &Aabb,
        cell: f64,
        level: f64,
        band: f64,
        seeds: &[Vec3],
        eval_row: impl Fn(&Vec3, f64, usize, &mut [(f64, Vec3)]) + Sync,
    ) -> (Grid, BandMask) {
        let dims = dims_of(bbox, cell);
        let filler = Self::filler(bbox, cell, dims, &eval_row);
        let bd = filler.bdims;
        let nb = bd[0] * bd[1] * bd[2];
        // Initial exact blocks: seeds, sign changes, Lipschitz estimate.
        let mut exact: Vec<bool> = (0..nb)
            .into_par_iter()
            .map(|b| {
                let bi = [b % bd[0], (b / bd[0]) % bd[1], b / (bd[0] * bd[1])];
                let ext = [0, 1, 2].map(|a| {
                    let (lo, hi) = block_nodes(bi[a], dims[a]);
                    (hi - lo) as f64 * cell
                });
                let diag = (ext[0] * ext[0] + ext[1] * ext[1] + ext[2] * ext[2]).sqrt();
                let (mut neg, mut pos, mut minabs, mut lip) = (false, false, f64::MAX, 0.0f64);
                for c in 0..8 {
                    let (v, g) = filler.corner(bi, c);
                    let v = &(v - level);
                    if *v < 0.0 {
                        neg = true;
                    } else {
                        pos = true;
                    }
                    minabs = minabs.min(v.abs());
                    lip = lip.max(g.norm());
                }
                !minabs.is_finite() || (neg && pos) || minabs < band + lip * diag
            })
            .collect();
        for p in seeds {
            let q = (p - bbox.min) / cell;
            let mut b = [0usize; 3];
            let mut inside = true;
            for a in 0..3 {
                if !(q[a] >= 0.0 && q[a] <= (dims[a] - 1) as f64) {
                    inside = false;
                    break;
                }
                b[a] = ((q[a] as usize) / BLOCK).min(bd[a] - 1);
            }
            if inside {
                exact[filler.block_index(b)] = true;
            }
        }
        let mut data = vec![[0f32; 4]; dims[0] * dims[1] * dims[2]];
        let mut done = vec![false; data.len()];
        let mut todo = exact.clone();
        loop {
            filler.evaluate(&todo, &mut data, &mut done);
            // Closure: non-exact blocks with an exact node in the band or of the wrong sign.
            let grow: Vec<bool> = (0..nb)
                .into_par_iter()
                .map(|b| {
                    if exact[b] {
                        return false;
                    }
                    let bi = [b % bd[0], (b / bd[0]) % bd[1], b / (bd[0] * bd[1])];
                    let negative = filler.corner(bi, 0).0 < level;
                    let (il, ih) = block_nodes(bi[0], dims[0]);
                    let (jl, jh) = block_nodes(bi[1], dims[1]);
                    let (kl, kh) = block_nodes(bi[2], dims[2]);
                    for k in kl..=kh {
                        for j in jl..=jh {
                            let base = dims[0] * (j + dims[1] * k);
                            for i in il..=ih {
                                if done[base + i] {
                                    let v = data[base + i][0] as f64 - level;
                                    if v.abs() < band || (v < 0.0) != negative {
                                        return true;
                                    }
                                }
                            }
                        }
                    }
                    false
                })
                .collect();
            if !grow.iter().any(|&g| g) {
                break;
            }
            for (e, g) in exact.iter_mut().zip(&grow) {
                *e |= *g;
            }
            todo = grow;
        }
        filler.interpolate_rest(&mut data, &done);
        let grid = Grid {
            origin: bbox.min,
            cell,
            dims,
            data,
        };
        (grid, BandMask { bdims: bd, exact })
    }

    fn filler<'a>(bbox: &Aabb, cell: f64, dims: [usize; 3], eval_row: &'a RowEval) -> Filler<'a> {
        let cax = [0, 1, 2].map(|a| coarse_axis(dims[a]));
        let coarse = coarse_values(&bbox.min, cell, &cax, eval_row);
        Filler {
            origin: bbox.min,
            cell,
            dims,
            bdims: [0, 1, 2].map(|a| cax[a].len() - 1),
            cdims: [0, 1, 2].map(|a| cax[a].len()),
            coarse,
            eval_row,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sphere(c: Vec3, r: f64) -> impl Fn(&Vec3, f64, usize, &mut [(f64, Vec3)]) + Sync {
        move |p, dx, first, out| {
            for (k, o) in out.iter_mut().enumerate() {
                let q = Vec3::new(p.x + ((first + k) as f64) * dx, p.y, p.z) - c;
                let n = q.norm();
                *o = (n - r, if n > 0.0 { q / n } else { Vec3::x() });
            }
        }
    }

    /// Exact in the band, beyond it on the same side elsewhere (nodes).
    fn check(full: &Grid, band_grid: &Grid, level: f64, band: f64) -> Result<usize, TestCaseError> {
        prop_assert_eq!(full.dims, band_grid.dims);
        let mut exact = 0;
        for (a, b) in full.data.iter().zip(&band_grid.data) {
            if a == b {
                exact += 1;
            } else {
                let (a, b) = (a[0] as f64 - level, b[0] as f64 - level);
                prop_assert!(a.abs() >= band, "full {} not beyond band", a);
                prop_assert!(b.abs() >= band, "band grid {} inside band", b);
                prop_assert_eq!(a < 0.0, b < 0.0);
            }
        }
        Ok(exact)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn band_grid_is_exact_near_the_level_set_and_on_the_right_side_beyond(
            cx in 0.3f64..0.7, cy in 0.3f64..0.7, cz in 0.3f64..0.7,
            r in 0.1f64..0.35, level in -0.05f64..0.1, band in 0.01f64..0.15,
            cell in 0.011f64..0.03, seeded in proptest::bool::ANY,
        ) {
            let bbox = Aabb { min: Vec3::zeros(), max: Vec3::new(1.0, 0.9, 1.1) };
            let c = Vec3::new(cx, cy, cz);
            let f = sphere(c, r);
            let full = Grid::build_rows(&bbox, cell, |p, dx, out| f(p, dx, 0, out));
            let seeds = if seeded { vec![c + Vec3::x() * r] } else { vec![] };
            let (g, mask) = Grid::build_band(&bbox, cell, level, band, &seeds, &f);
            let exact = check(&full, &g, level, band)?;
            prop_assert!(exact > 0);
            prop_assert!(mask.exact_fraction() > 0.0);
            // Points whose interpolated value is in the band (in either grid) interpolate
            // identically; elsewhere both are on the same side of the band.
            for k in 0..400 {
                let t = k as f64 / 400.0;
                let p = Vec3::new(t, (t * 7.3).fract() * 0.9, (t * 3.1).fract() * 1.1);
                let (a, b) = (full.sample(&p).unwrap(), g.sample(&p).unwrap());
                if (a.0 - level).abs() < band || (b.0 - level).abs() < band {
                    prop_assert_eq!(a, b);
                } else {
                    prop_assert_eq!(a.0 < level, b.0 < level);
                }
            }
        }
    }

    #[test]
    fn narrow_band_skips_most_of_a_small_sphere_grid() {
        let bbox = Aabb {
            min: Vec3::zeros(),
            max: Vec3::repeat(1.0),
        };
        let f = sphere(Vec3::repeat(0.5), 0.2);
        let (g, mask) = Grid::build_band(&bbox, 0.01, 0.0, 0.03, &[], &f);
        let full = Grid::build_rows(&bbox, 0.01, |p, dx, out| f(p, dx, 0, out));
        let exact = check(&full, &g, 0.0, 0.03).unwrap();
        assert!(mask.exact_fraction() < 0.5, "{}", mask.exact_fraction());
        assert!(exact < full.num_nodes() / 2);
    }
}
