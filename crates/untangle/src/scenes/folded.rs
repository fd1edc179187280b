//! A large sheet folded onto itself with dents poking through (Wicke et al. 2006, Table 1 scale).
//!
//! An `n x n`-cell sheet of 2 x 1 (`2 n^2` triangles; `n = 125` gives Wicke's 31,250) is folded in half around a
//! half-cylinder of radius `R`, so the top layer lies `2 R` above the bottom one; `k` Gaussian
//! dents on the top layer push through the bottom layer. Each dent makes exactly one CLOSED
//! tanglement (a CLOSED path on each layer), so the expected answer is `k` CLOSED.

use super::{handkerchief, Scene};
use crate::geom::Vec3;

/// The folded sheet with `dents` dents (placed on a grid over the overlap; at most 36).
pub fn folded(n: usize, dents: usize) -> Scene {
    let n = n.max(8);
    let length = 2.0;
    let width = 1.0;
    let radius = 0.02;
    let half = 0.5 * length - 0.5 * std::f64::consts::PI * radius;
    let side = (dents as f64).sqrt().ceil().max(1.0) as usize;
    let centers: Vec<(f64, f64)> = (0..dents.min(36))
        .map(|k| {
            let (i, j) = (k % side, k / side);
            // Over the overlap: top-layer distance from the fold in (0.15, 0.85) x half.
            let s = 0.15 + 0.7 * (i as f64 + 0.5) / side as f64;
            let t = 0.15 + 0.7 * (j as f64 + 0.5) / side as f64;
            (s * half + 0.0123, (t - 0.5) * width + 0.0071)
        })
        .collect();
    // Spacing of the dents; with sigma = spacing / 4 the sum of two neighbours' tails halfway
    // between them stays far below the depth needed to pierce, so the curves stay separate.
    let sigma = 0.25 * 0.7 * half / side as f64;
    let m = handkerchief("folded", n, n, length, width, |p| {
        // Arc length along the sheet from its left end.
        let u = p.x + 0.5 * length;
        let fold_arc = std::f64::consts::PI * radius;
        if u <= half {
            return Vec3::new(u, p.y, 0.0);
        }
        if u < half + fold_arc {
            let th = (u - half) / radius;
            return Vec3::new(half + radius * th.sin(), p.y, radius - radius * th.cos());
        }
        let back = u - half - fold_arc; // distance from the fold on the top layer
        let mut z = 2.0 * radius;
        for &(c, y) in &centers {
            let d2 = (back - c).powi(2) + (p.y - y).powi(2);
            z -= 4.0 * radius * (-d2 / (sigma * sigma)).exp();
        }
        Vec3::new(half - back, p.y, z)
    });
    Scene {
        name: format!("folded-{n}-{dents}"),
        meshes: vec![m],
        expected: vec![("CLOSED", dents.min(36))],
    }
}
