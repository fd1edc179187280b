//! Procedural scenes with known answers, used by tests, benchmarks and `untangle scene`.
//!
//! Every scene is deterministic for a given seed and size. Coordinates avoid exact ties on
//! purpose (offsets such as `0.0123`), so the expected kinds do not hinge on the tie rule; the
//! tie rule is exercised separately.

pub mod exploded;
pub mod sheet;

pub use exploded::exploded_handkerchief;
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
pub const NAMES: &[&str] = &["closed", "exploded"];

/// Builds a scene by name; `size` is the handkerchief resolution (cells per side, `None` for the
/// default) and `seed` drives random scenes.
pub fn by_name(name: &str, size: Option<usize>, seed: u64) -> Option<Scene> {
    match name {
        "closed" => Some(closed(size.unwrap_or(16))),
        "exploded" => Some(Scene {
            name: "exploded".into(),
            meshes: vec![exploded_handkerchief(size.unwrap_or(14), 0.2, 0.25, seed)],
            expected: vec![],
        }),
        _ => None,
    }
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
