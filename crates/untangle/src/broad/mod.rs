//! Broad phase: which primitives' boxes overlap. A bounding volume hierarchy with refit (for
//! meshes that move every step) and parallel, deterministic self- and cross-traversal; a sweep
//! and prune along x for small, dense sets (self-overlaps only).

pub mod bvh;
pub mod sweep;

pub use bvh::Bvh;
pub use sweep::SweepAndPrune;
