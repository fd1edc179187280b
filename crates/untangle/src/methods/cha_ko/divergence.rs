//! The divergence guard (ours; outside the paper, whose simulator never meets it): a uv edit
//! the world cannot follow must not take the simulation with it.
//!
//! A pull shortens its subject's edges in uv by `gamma` per step (Sec. 5.1) whether or not the
//! world follows. When contacts hold the subject, the stretch force on its fan grows step after
//! step; on dress4 sagged 60 steps one pull (vertex 502 toward 1838) held 99.7 % of the cloth's
//! stretch energy from step 13 on (a scratch measurement), the energy grew 4x, 4x and 8x in
//! steps 17-19 with the pull's rest shape held at its cap, and step 20 multiplied it by 1,170 (1.4e6 J to 1.7e9 J): vertices flung
//! across the scene, 20 M CCD candidates and 15 GB of memory in the steps after
//! (BENCHMARKS.md, session 32).
//!
//! After every simulator step of the loop the guard compares the stretch-plus-kinetic energy at
//! the step's end with that at its start (the same rest shape). The step *diverged* when the
//! end energy is not finite or exceeds `ratio` times the start energy, the start energy taken
//! at least as [`energy_floor`] (a 10 % stretch of the whole cloth) so that a cloth starting
//! at rest does not trip it. The energy growth of each triangle is then charged to the
//! operations whose subjects are its corners; every operation charged with at least `share` of
//! the growth is given up and restored to its original uv at once
//! ([`super::EndReason::Diverged`]), its subject-target pair (or red* triangle) barred like an
//! abandoned one, and the step is undone and run again with the restored rest shape, up to
//! `rounds` times. A diverged step no operation is charged for is kept and reported.
//!
//! With the default ratio of 10 the guard never acts on the exploded handkerchief: over seeds
//! 1-50 no step's energy grew more than 5.93x (seed 46).

use super::state::Op;
use crate::error::{Error, Result};
use crate::geom::cross2;
use crate::mesh::{Garment, Topology};

/// Settings of the guard (see the module text).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DivergenceGuard {
    /// A step diverged when its end energy exceeds this multiple of its start energy.
    pub ratio: f64,
    /// Operations charged with at least this fraction of the energy growth are given up.
    pub share: f64,
    /// Undo-and-retry rounds per step at most.
    pub rounds: usize,
}

impl Default for DivergenceGuard {
    fn default() -> Self {
        DivergenceGuard {
            ratio: 10.0,
            share: 0.25,
            rounds: 3,
        }
    }
}

impl DivergenceGuard {
    /// Refuses a ratio that is not finite and positive, a share outside `[0, 1]`.
    pub fn validate(&self) -> Result<()> {
        if !(self.ratio.is_finite() && self.ratio > 0.0) {
            return Err(Error::Parameter(format!(
                "divergence ratio {} must be finite and positive",
                self.ratio
            )));
        }
        if !(0.0..=1.0).contains(&self.share) {
            return Err(Error::Parameter(format!(
                "divergence share {} must be within [0, 1]",
                self.share
            )));
        }
        Ok(())
    }
}

/// What the guard did in one loop step.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct DivergenceReport {
    /// The kept step's end energy over its start energy (the start taken at least as
    /// [`energy_floor`]): what the guard compares with [`DivergenceGuard::ratio`]. 0 when the
    /// guard did not look (off, or the cloth was clean).
    pub growth: f64,
    /// Diverged simulator steps (the first try and the retries).
    pub diverged: usize,
    /// The largest growth of a diverged try (0 when none diverged).
    pub max_growth: f64,
    /// Operations given up, in the order they were.
    pub given_up: Vec<u32>,
    /// Whether the step kept a diverged result (nothing to charge, or out of rounds).
    pub kept_diverged: bool,
}

/// The energy of stretching every triangle of `garment` by 10 % along both uv directions
/// (`0.01 k_stretch` times the rest area): the least start energy [`diverged`] compares with.
pub fn energy_floor(garment: &Garment, stretch_stiffness: f64) -> f64 {
    let uv = garment.uv();
    let area: f64 = uv
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| uv.coords[i as usize]);
            0.5 * cross2(&a, &b, &c).abs()
        })
        .sum();
    0.01 * stretch_stiffness * area
}

/// The growth of a step from energy `start` to `end`: `end / max(start, floor)`; infinite
/// when `end` is not finite.
pub fn growth(start: f64, end: f64, floor: f64) -> f64 {
    if end.is_finite() {
        end / start.max(floor)
    } else {
        f64::INFINITY
    }
}

/// Whether a step from energy `start` to `end` diverged (see the module text).
pub fn diverged(start: f64, end: f64, ratio: f64, floor: f64) -> bool {
    !end.is_finite() || end > ratio * start.max(floor)
}

/// The operations charged with at least `share` of the positive energy `growth` per triangle:
/// a triangle's growth is charged to every operation with a subject among its corners.
/// Non-finite growth counts as larger than any finite one.
pub fn charged<'a>(
    ops: impl IntoIterator<Item = &'a Op>,
    topology: &Topology,
    growth: &[f64],
    share: f64,
) -> Vec<u32> {
    let big = f64::MAX / (growth.len().max(1) as f64 * 4.0);
    let g = |t: u32| {
        let x = growth[t as usize];
        if x.is_finite() {
            x.clamp(0.0, big)
        } else {
            big
        }
    };
    let total: f64 = (0..growth.len() as u32).map(g).sum();
    if total <= 0.0 {
        return Vec::new();
    }
    ops.into_iter()
        .filter(|op| {
            let mut tris: Vec<u32> = op
                .subjects
                .iter()
                .flat_map(|&s| topology.vertex_triangles.row(s as usize).iter().copied())
                .collect();
            tris.sort_unstable();
            tris.dedup();
            tris.into_iter().map(g).sum::<f64>() >= share * total
        })
        .map(|op| op.id)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology::NONE;
    use crate::methods::cha_ko::{Op, OpKind};
    use proptest::prelude::*;

    /// 4 x 4 cells over the unit square (25 vertices, 32 triangles).
    fn sheet() -> crate::mesh::Mesh {
        crate::scenes::sheet::handkerchief("h", 4, 4, 1.0, 1.0, |p| {
            crate::geom::Vec3::new(p.x, p.y, 0.0)
        })
    }

    fn op(id: u32, subjects: Vec<u32>) -> Op {
        Op {
            id,
            kind: if subjects.len() == 1 {
                OpKind::Pull
            } else {
                OpKind::Shrink
            },
            subjects,
            target: 0,
            triangle: NONE,
            copies: Vec::new(),
            level: 1,
            level_cap: 15,
        }
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(DivergenceGuard::default().validate().is_ok());
        for ratio in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let g = DivergenceGuard {
                ratio,
                ..DivergenceGuard::default()
            };
            assert!(g.validate().is_err(), "{ratio}");
        }
        for share in [-0.1, 1.1, f64::NAN] {
            let g = DivergenceGuard {
                share,
                ..DivergenceGuard::default()
            };
            assert!(g.validate().is_err(), "{share}");
        }
    }

    #[test]
    fn divergence_needs_the_ratio_over_the_floor() {
        assert!(!diverged(1.0, 9.9, 10.0, 0.5));
        assert!(diverged(1.0, 10.1, 10.0, 0.5));
        // A start below the floor compares with the floor.
        assert!(!diverged(1e-9, 4.9, 10.0, 0.5));
        assert!(diverged(1e-9, 5.1, 10.0, 0.5));
        assert!(diverged(1.0, f64::NAN, 10.0, 0.5));
        assert!(diverged(1.0, f64::INFINITY, 10.0, 0.5));
    }

    #[test]
    fn the_floor_is_a_ten_percent_stretch_of_the_rest_area() {
        // 4 x 4 cells over the unit square: rest area 1.
        let g = Garment::new(sheet()).unwrap();
        assert!((energy_floor(&g, 1000.0) - 10.0).abs() < 1e-9);
        // The simulator's energy of that stretch per unit rest area: 0.5 k (0.1^2 + 0.1^2).
        let rest = crate::sim::forces::stretch::TriangleRest::new(
            &crate::geom::Vec2::new(0.0, 0.0),
            &crate::geom::Vec2::new(1.0, 0.0),
            &crate::geom::Vec2::new(0.0, 1.0),
        )
        .unwrap();
        let x = [
            crate::geom::Vec3::new(0.0, 0.0, 0.0),
            crate::geom::Vec3::new(1.1, 0.0, 0.0),
            crate::geom::Vec3::new(0.0, 1.1, 0.0),
        ];
        let e =
            crate::sim::forces::stretch::stretch_energy(&rest, [&x[0], &x[1], &x[2]], 1000.0, 0.0);
        assert!((e / rest.area - 10.0).abs() < 1e-9, "{e}");
    }

    proptest! {
        /// `charged` against a brute force that scans every triangle for a subject corner.
        #[test]
        fn charged_matches_a_scan_of_all_triangles(
            subjects in prop::collection::vec(prop::collection::vec(0u32..25, 1..3), 0..6),
            growth in prop::collection::vec(-1.0f64..1.0, 32),
            share in 0.0f64..0.6,
        ) {
            let g = Garment::new(sheet()).unwrap();
            let tris = &g.mesh.triangles;
            prop_assert_eq!(tris.len(), growth.len());
            let ops: Vec<Op> = subjects.iter().enumerate().map(|(i, s)| {
                let mut s = s.clone();
                s.dedup();
                op(i as u32, s)
            }).collect();
            let total: f64 = growth.iter().map(|x| x.max(0.0)).sum();
            let want: Vec<u32> = if total <= 0.0 { vec![] } else {
                ops.iter().filter(|o| {
                    let mine: f64 = tris.iter().zip(&growth)
                        .filter(|(t, _)| t.iter().any(|c| o.subjects.contains(c)))
                        .map(|(_, x)| x.max(0.0)).sum();
                    mine >= share * total
                }).map(|o| o.id).collect()
            };
            prop_assert_eq!(charged(&ops, &g.topology, &growth, share), want);
        }
    }

    #[test]
    fn non_finite_growth_is_charged_to_its_operation() {
        let g = Garment::new(sheet()).unwrap();
        let mut growth = vec![1.0; g.mesh.triangles.len()];
        let t = g.topology.vertex_triangles.row(12)[0];
        growth[t as usize] = f64::NAN;
        let ops = [op(0, vec![12]), op(1, vec![0])];
        assert_eq!(charged(&ops, &g.topology, &growth, 0.25), vec![0]);
    }
}
