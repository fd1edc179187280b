//! What a layer provides to the untangling: its field `f_i` (value and gradient) and its
//! influence region `h_i < 0` (Sec. 4, 6.1). Garments and the body use [`GarmentField`] (HRBF
//! fits cached on grids); tests use exact analytic fields.

use super::grid::Grid;
use crate::geom::Vec3;

/// A layer's implicit representation.
pub trait LayerField: Sync {
    /// `f_i(p)` and `∇f_i(p)`; `None` where the field is not defined (outside its grid), which
    /// makes the layer inactive at `p`.
    fn field(&self, p: &Vec3) -> Option<(f64, Vec3)>;
    /// Whether `p` lies in the layer's influence region (`h_i(p) < 0`).
    fn influences(&self, p: &Vec3) -> bool;
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
    /// Largest `|f_i|` at which the layer still counts as active: penetrations deeper than this
    /// are taken for different parts of the body (infinite for the body).
    pub depth_limit: f64,
    /// Time of each step, in milliseconds: sampling, fit of `f`, fit of `h`, grids.
    pub timing_ms: [f64; 4],
}

impl LayerField for GarmentField {
    #[inline]
    fn field(&self, p: &Vec3) -> Option<(f64, Vec3)> {
        self.f.sample(p)
    }
    #[inline]
    fn influences(&self, p: &Vec3) -> bool {
        let near = matches!(self.f.sample(p), Some((v, _)) if v.abs() <= self.depth_limit);
        near && match &self.h {
            None => true,
            Some(h) => matches!(h.sample(p), Some((v, _)) if v < self.h_margin),
        }
    }
}
