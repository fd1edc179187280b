//! Implicit untangling of layered garments (Buffet et al. 2019).
//!
//! Each garment is approximated by a Hermite RBF field `f_i` fitted to Poisson-disk samples with
//! normals ([`hrbf`], [`sampling`]) and by a co-variant field `h_i` fitted to its open-boundary
//! samples (Sec. 4), both cached on grids with trilinear interpolation ([`grid`], [`field`]). The
//! body is a closed field of infinite weight. The N-ary untangling operators ([`operators`],
//! Sec. 5) combine the fields of the layers active at a point (Sec. 6.1), offset for the cloth
//! thicknesses ([`thickness`], Sec. 6.2); each mesh is then projected onto its corrected
//! iso-surface by Newton steps interleaved with tangential relaxation ([`projection`], Sec. 6.3).
//! [`layers`] is the pipeline and the verification by the global intersection analysis;
//! [`separation`] measures the result against the thickness rule (Table 3); [`repair`] fixes the
//! crossings the projection leaves.
//!
//! Deviations from the paper, and why:
//! - The closest point on the zero set (the paper's supplement, unavailable) is derived in
//!   [`operators`]: Lawson–Hanson on the polar cone of each piece, exact, `O(N^3)` per piece.
//! - Sign of the operator: the side of the piece whose *sector* contains the point (the zero
//!   set is a graph over the other layers' values) instead of the closest piece's plane, which
//!   is undefined for a vertex lying on its own iso-surface inside a collision.
//! - The co-variant field is also pinned to minus the along-mesh distance to the boundary at
//!   ~150 interior vertices: from boundary samples alone, 4–21 % of a garment's own vertices
//!   fell outside its influence region on the ARCSim garments. The influence region is
//!   `h_i < margin` (half the boundary sample spacing), so the garment's own rim is inside it,
//!   and a garment is inactive where `|f_i|` exceeds a depth limit (10 % of its box diagonal),
//!   so far-away parts of the field (e.g. the sleeves of another garment) are not mistaken for
//!   penetrations. The body has no limit.
//! - Thickness offsets (Sec. 6.2): eq. 13 adds the rule `t_i/2 + t_j/2 (+ …)` in field units,
//!   which is a geometric gap only for unit, parallel gradients; two garments meeting at 50°
//!   (T-shirt and dress) or fields with `|∇f| ≈ 1.1` came out 2–10 % too far apart. By default
//!   every gap between neighbouring active layers is scaled by the tilt of the gradients of the
//!   layers that merge there (the blocks of a local isotonic-regression model,
//!   [`thickness::contact_blocks`], other layers blended in continuously by their fitted
//!   distance) and expressed in each field's gradient-norm units
//!   ([`thickness::scaled_offsets`]): exact to first order, same order of the layers;
//!   `ProjectionParams::scaled_offsets = false` is eq. 13 as written.
//! - Vertices keep their own iso-value `ε_v` away from contact; in contact the target is the
//!   contact surface itself, so neither details nor field error push a layer through another.
//! - Points outside a garment's grid do not see that garment (it is inactive there).
//! - Garment normals are made consistent and outward (away from the body's centre) before
//!   fitting, whatever the input winding.
//! - The projection evaluates only the vertices whose position changed since their last
//!   evaluation (same result as re-evaluating the whole deformed zone every pass) and skips
//!   relaxation moves below ten tolerances (so converged regions stop being re-evaluated).
//! - Self-intersection is out of the paper's scope (Sec. 7). By default the [`repair`]
//!   separates the pairs of triangles of one garment that the projection or the pushes made
//!   cross (a garment squeezed between two layers crumples: the outer triangle moves out and
//!   the crumple is smoothed, the layers above make room); [`self_guard`] optionally undoes
//!   the moves that make a garment intersect itself anew (off by default: it costs time and,
//!   at the largest sizes, leaves crossings between layers when on in the repair).

pub mod band;
pub mod field;
pub mod grid;
pub mod hrbf;
pub mod layers;
pub mod operators;
pub mod projection;
pub mod repair;
pub mod sampling;
pub mod self_guard;
pub mod separation;
pub mod shapes;
pub mod thickness;

pub use field::{GarmentField, LayerField};
pub use layers::{untangle_layers, verify, FieldParams, GarmentInput, Params, Untangled};

#[cfg(test)]
mod tests;
