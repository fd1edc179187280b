//! Implicit untangling of layered garments (Buffet et al. 2019).
//!
//! Each garment is approximated by a Hermite RBF field `f_i` fitted to Poisson-disk samples with
//! normals and by a co-variant field `h_i` fitted to its open-boundary samples (Sec. 4), both
//! cached on grids. The N-ary untangling operators (Sec. 5) combine the fields of the layers active
//! at a point (Sec. 6.1), offset for the cloth thicknesses (Sec. 6.2); each mesh is then projected
//! onto its corrected iso-surface by Newton steps interleaved with tangential relaxation (Sec. 6.3).

pub mod operators;
pub mod field;
pub mod grid;
pub mod hrbf;
pub mod sampling;
pub mod shapes;
pub mod thickness;

pub use field::{GarmentField, LayerField};
pub mod layers;
pub mod projection;
pub mod separation;

pub use layers::{untangle_layers, verify, FieldParams, GarmentInput, Params, Untangled};

#[cfg(test)]
mod tests;
