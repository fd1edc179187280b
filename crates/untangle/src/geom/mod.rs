//! Geometry kernel: vector aliases, boxes, exact predicates and the primitive tests built on them.
//!
//! Everything here is a pure function of coordinates (and, for the symbolically perturbed
//! predicates, of vertex indices), so every caller sees one consistent picture of the geometry.

pub mod aabb;
pub mod ccd;
pub mod ccd_queries;
pub mod distance;
pub mod predicates;
pub mod tri_pair;
pub mod tri_tri;

pub use aabb::Aabb;

/// Scalar type of the whole library.
pub type Real = f64;
/// A point or vector in world space.
pub type Vec3 = nalgebra::Vector3<Real>;
/// A point or vector in a panel's uv (parameter) space.
pub type Vec2 = nalgebra::Vector2<Real>;

/// Twice the signed area of the 2D triangle `(a, b, c)` (positive when counter-clockwise).
#[inline]
pub fn cross2(a: &Vec2, b: &Vec2, c: &Vec2) -> Real {
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

/// Area of the 3D triangle `(a, b, c)`.
#[inline]
pub fn triangle_area(a: &Vec3, b: &Vec3, c: &Vec3) -> Real {
    0.5 * (b - a).cross(&(c - a)).norm()
}
