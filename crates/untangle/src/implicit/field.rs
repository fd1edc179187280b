//! What a layer provides to the untangling: its field `f_i` (value and gradient) and its
//! influence region `h_i < 0` (Sec. 4, 6.1). Garments and the body use [`GarmentField`] (HRBF
//! fits cached on grids); tests use exact analytic fields.
//!
//! Deviation: influence is not a yes/no test but a *fade* `s_i(p) ∈ [0, 1]` (0: the layer is
//! fully present, 1: absent). It rises smoothly from 0 to 1 across a band beyond the co-variant
//! field's rim (`h_i` from `h_margin` to `h_margin + rim_fade`) and across a band of depth
//! (`|f_i|` from `depth_limit` to `depth_limit + depth_fade`). The corrected fields blend the
//! operators of the configurations with and without the fading layers (see
//! [`super::projection::Composer`]), so the corrected surfaces move continuously where a layer's
//! influence ends instead of jumping there (a jump leaves the triangles that straddle it crossing
//! the other layer's rim).

use super::grid::Grid;
use crate::geom::Vec3;

/// A layer's field at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldSample {
    /// `f_i(p)`.
    pub value: f64,
    /// `∇f_i(p)`.
    pub gradient: Vec3,
    /// Fade `s_i(p)`: 0 inside the influence region, 1 outside it, in between across its
    /// border band.
    pub fade: f64,
    /// `∇s_i(p)`.
    pub fade_gradient: Vec3,
}

impl FieldSample {
    /// Whether the layer has any influence at the point (`s_i < 1`).
    pub fn influences(&self) -> bool {
        self.fade < 1.0
    }
}

/// A layer's implicit representation.
pub trait LayerField: Sync {
    /// `f_i(p)`, `∇f_i(p)` and the fade of its influence; `None` where the field is not defined
    /// (outside its grid), which makes the layer absent at `p`.
    fn sample(&self, p: &Vec3) -> Option<FieldSample>;

    /// `f_i(p)` and `∇f_i(p)`.
    fn field(&self, p: &Vec3) -> Option<(f64, Vec3)> {
        self.sample(p).map(|s| (s.value, s.gradient))
    }

    /// Whether `p` lies in the layer's influence region (fully or partly).
    fn influences(&self, p: &Vec3) -> bool {
        self.sample(p).is_some_and(|s| s.influences())
    }
}

/// `smoothstep` on `[0, 1]`: value and derivative.
#[inline]
pub fn smoothstep(x: f64) -> (f64, f64) {
    if x <= 0.0 {
        (0.0, 0.0)
    } else if x >= 1.0 {
        (1.0, 0.0)
    } else {
        (x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x))
    }
}

/// The cached fields of one garment (or of the closed body, which has no co-variant field).
#[derive(Clone, Debug)]
pub struct GarmentField {
    /// `f_i` on a grid.
    pub f: Grid,
    /// The co-variant field `h_i` on a grid; `None` for a closed surface (influence everywhere
    /// inside `f`'s grid).
    pub h: Option<Grid>,
    /// Number of surface samples of the HRBF `f_i`.
    pub num_samples: usize,
    /// Number of boundary samples of the HRBF `h_i`.
    pub num_boundary_samples: usize,
    /// Influence region: `h_i < h_margin` (a small positive margin keeps the garment's own
    /// boundary vertices, where `h_i = 0`, inside it).
    pub h_margin: f64,
    /// Width of the band beyond `h_margin` across which the influence fades out.
    pub rim_fade: f64,
    /// Largest `|f_i|` at which the layer is fully present: penetrations deeper than this are
    /// taken for different parts of the body (infinite for the body).
    pub depth_limit: f64,
    /// Width of the band beyond `depth_limit` across which the influence fades out.
    pub depth_fade: f64,
    /// Fraction of the grid blocks filled exactly, mean over `f` and `h` (1 without the narrow
    /// band, see [`super::band`]).
    pub exact_fraction: f64,
    /// Time of each step, in milliseconds: sampling, fit of `f`, fit of `h` (both fits run side
    /// by side), grids.
    pub timing_ms: [f64; 4],
}

impl LayerField for GarmentField {
    #[inline]
    fn sample(&self, p: &Vec3) -> Option<FieldSample> {
        let (value, gradient) = self.f.sample(p)?;
        let mut keep = 1.0;
        let mut keep_gradient = Vec3::zeros();
        if value.abs() > self.depth_limit {
            let (s, ds) = smoothstep((value.abs() - self.depth_limit) / self.depth_fade);
            keep = 1.0 - s;
            keep_gradient = gradient * (-ds * value.signum() / self.depth_fade);
        }
        if keep == 0.0 {
            // Absent by depth: the co-variant field cannot change that (and shares `f`'s grid
            // box, so it is defined here too).
            return Some(FieldSample {
                value,
                gradient,
                fade: 1.0,
                fade_gradient: Vec3::zeros(),
            });
        }
        if let Some(h) = &self.h {
            let (hv, hg) = h.sample(p)?;
            if hv > self.h_margin {
                let (s, ds) = smoothstep((hv - self.h_margin) / self.rim_fade);
                let k = 1.0 - s;
                let dk = hg * (-ds / self.rim_fade);
                keep_gradient = keep_gradient * k + dk * keep;
                keep *= k;
            }
        }
        Some(FieldSample {
            value,
            gradient,
            fade: 1.0 - keep,
            fade_gradient: -keep_gradient,
        })
    }
}
