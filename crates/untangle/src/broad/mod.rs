//! Broad phase: which primitives' boxes overlap. A bounding volume hierarchy with refit (for
//! meshes that move every step) and parallel, deterministic self- and cross-traversal; a sweep
//! and prune along x for small, dense sets (self-overlaps only); traversal fronts that let the
//! next traversal of refitted hierarchies start where the last one stopped; the leaves' box
//! tests eight boxes against eight at once on coordinate arrays; pairs of primitives that share
//! a vertex dropped at the leaves by vertex keys.

pub mod bvh;
pub mod front;
pub mod keys;
pub mod lanes;
pub mod sweep;

pub use bvh::Bvh;
pub use front::Front;
pub use sweep::SweepAndPrune;

/// Test input: boxes given by centre and half extent (the proptests' random boxes).
#[cfg(test)]
pub(crate) fn test_boxes(raw: &[([f64; 3], [f64; 3])]) -> Vec<crate::geom::Aabb> {
    use crate::geom::Vec3;
    raw.iter()
        .map(|(c, e)| {
            let (c, e) = (Vec3::new(c[0], c[1], c[2]), Vec3::new(e[0], e[1], e[2]));
            crate::geom::Aabb {
                min: c - e,
                max: c + e,
            }
        })
        .collect()
}
