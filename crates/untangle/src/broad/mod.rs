//! Broad phase: which primitives' boxes overlap. A bounding volume hierarchy with refit (for
//! meshes that move every step) and parallel, deterministic self- and cross-traversal.

pub mod bvh;

pub use bvh::Bvh;
