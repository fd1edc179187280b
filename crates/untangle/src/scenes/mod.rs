//! Procedural scenes with known answers, used by tests, benchmarks and `untangle scene`.
//!
//! Every scene is deterministic for a given seed and size. Coordinates avoid exact ties on
//! purpose (offsets such as `0.0123`), so the expected kinds do not hinge on the tie rule; the
//! tie rule is exercised separately.

pub mod exploded;
pub mod folded;
pub mod garment;
pub mod outfit;
pub mod rudimentary;
pub mod sagged;
pub mod sheet;

pub use sheet::handkerchief;

use crate::geom::Vec3;
use crate::mesh::Mesh;

/// A scene: cloth meshes (and what the analysis must find in them).
#[derive(Clone, Debug)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// The cloth pieces.
    pub meshes: Vec<Mesh>,
    /// Tanglement categories the analysis must report, with counts (empty when not fixed).
    pub expected: Vec<(&'static str, usize)>,
}

/// Names accepted by [`by_name`].
pub const NAMES: &[&str] = &[
    "closed",
    "ll",
    "eight",
    "cross",
    "bbii",
    "bibi",
    "bli",
    "bli-interior",
    "exploded",
    "folded",
    "tubes",
];

/// Builds a scene by name; `size` is the handkerchief resolution (cells per side, `None` for the
/// default) and `seed` drives random scenes.
///
/// For the loop-vertex cores (`ll`, `eight`, `cross`, `bli`, `bli-interior`) `size` is the
/// number of subdivision levels (default 2); for `folded` it is the cells per side (default 125: 31,250 triangles, 4
/// dents); for `exploded` the cells per side (default 14) and `seed` the random draw; for `skirt`
/// the cells around each panel (default 40, 3 dents); for `tubes` the segments around each tube
/// (default 32; offset 0.85).
pub fn by_name(name: &str, size: Option<usize>, seed: u64) -> Option<Scene> {
    Some(match name {
        "closed" => closed(size.unwrap_or(16)),
        "ll" => rudimentary::loop_loop(size.unwrap_or(2)),
        "eight" => rudimentary::eight(size.unwrap_or(2)),
        "cross" => rudimentary::cross(size.unwrap_or(2)),
        "bli" => rudimentary::bli(size.unwrap_or(2)),
        "bli-interior" => rudimentary::bli_interior(size.unwrap_or(2)),
        "bbii" => rudimentary::bb_ii(size.unwrap_or(16)),
        "bibi" => rudimentary::bi_bi(size.unwrap_or(16)),
        "exploded" => exploded::exploded(seed, size.unwrap_or(14)),
        "folded" => folded::folded(size.unwrap_or(125), 4),
        "skirt" => garment::skirt(size.unwrap_or(40), 3),
        "tubes" => garment::overlapping_tubes(size.unwrap_or(32), 0.85),
        _ => return None,
    })
}

/// CLOSED (Cha & Ko Fig. 13): handkerchief B lies above handkerchief A and a round dent of B
/// pokes through A; the intersection is one closed curve, a CLOSED path on each.
pub fn closed(n: usize) -> Scene {
    let a = handkerchief("A", n, n, 1.0, 1.0, |p| Vec3::new(p.x, p.y, 0.0123 * p.x));
    let b = handkerchief("B", n, n, 1.0, 1.0, |p| {
        let r2 = (p.x - 0.0311).powi(2) + (p.y + 0.0217).powi(2);
        Vec3::new(p.x + 0.0137, p.y - 0.0071, 0.08 - 0.3 * (-r2 / 0.02).exp())
    });
    Scene {
        name: "closed".into(),
        meshes: vec![a, b],
        expected: vec![("CLOSED", 1)],
    }
}
