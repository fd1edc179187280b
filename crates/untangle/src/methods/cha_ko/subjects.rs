//! What the collision handling does differently at the running operations' subjects (ours,
//! off by default), so that m-CCH takes less of a pull's motion back.
//!
//! - Heavy subjects ([`collision_mass_factors`]): the vertices that running operations move
//!   are made heavier in the simulator's collision handling only, so that the CCD impulses,
//!   proximity impulses and impact zones of m-CCH (Sec. 5.2-5.3) take less of a pull's or
//!   shrink's motion back (docs/cha-ko.md, "Heavy subjects"). A pair's impulse then moves its
//!   other side more, and a zone's rigid motion follows the heavy subject; which pairs are
//!   handled, and that they end the step collision-free, does not depend on the masses, so
//!   the m-CCH guarantee (green-green pairs never cross) holds as before.
//! - Thin red-green pairs at the subjects ([`subject_flags`] for
//!   [`super::policy::MchPolicy::thin_rg`]): red-green pairs whose red primitive touches a
//!   subject keep a thickness below `epsilon_RG`; still a positive thickness, so such pairs
//!   never cross either.

use super::state::Op;
use crate::mesh::Topology;

/// Which vertices of a running operation are made heavy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum HeavyScope {
    /// The subjects only (the pulled vertex; a shrink's red-edge ends).
    #[default]
    Subjects,
    /// The subjects and their fans (every neighbour of a subject, Sec. 5.1's fan contour).
    SubjectsAndFans,
}

/// Per world vertex, its mass factor in the collision handling: `factor` for the vertices
/// `scope` selects of every operation in `ops`, 1 elsewhere. `factor <= 1` (or not finite)
/// turns the rule off and gives an empty vector (the true masses).
pub fn collision_mass_factors<'a>(
    ops: impl IntoIterator<Item = &'a Op>,
    topo: &Topology,
    num_vertices: usize,
    factor: f64,
    scope: HeavyScope,
) -> Vec<f64> {
    if !(factor.is_finite() && factor > 1.0) {
        return Vec::new();
    }
    let mut f = vec![1.0; num_vertices];
    for op in ops {
        for &s in &op.subjects {
            f[s as usize] = factor;
            if scope == HeavyScope::SubjectsAndFans {
                for &n in topo.vertex_neighbors.row(s as usize) {
                    f[n as usize] = factor;
                }
            }
        }
    }
    f
}

/// Per world vertex, whether it is a subject of an operation in `ops`.
pub fn subject_flags<'a>(ops: impl IntoIterator<Item = &'a Op>, num_vertices: usize) -> Vec<bool> {
    let mut f = vec![false; num_vertices];
    for op in ops {
        for &s in &op.subjects {
            f[s as usize] = true;
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::methods::cha_ko::state::OpKind;

    fn op(subjects: Vec<u32>) -> Op {
        Op {
            id: 0,
            kind: OpKind::Pull,
            subjects,
            target: 0,
            triangle: u32::MAX,
            copies: Vec::new(),
            level: 1,
            level_cap: 10,
        }
    }

    /// A 3 x 3 vertex grid (vertex 4 in the middle).
    fn grid() -> Topology {
        let m = crate::scenes::handkerchief("grid", 2, 2, 1.0, 1.0, |p| {
            crate::geom::Vec3::new(p.x, p.y, 0.0)
        });
        Topology::new(&m).unwrap()
    }

    #[test]
    fn subjects_only_or_with_their_fans() {
        let t = grid();
        let ops = [op(vec![4])];
        let f = collision_mass_factors(&ops, &t, 9, 8.0, HeavyScope::Subjects);
        let heavy: Vec<usize> = (0..9).filter(|&i| f[i] == 8.0).collect();
        assert_eq!(heavy, vec![4]);
        assert!(f.iter().all(|&x| x == 1.0 || x == 8.0));
        let f = collision_mass_factors(&ops, &t, 9, 8.0, HeavyScope::SubjectsAndFans);
        let mut want: Vec<usize> = t
            .vertex_neighbors
            .row(4)
            .iter()
            .map(|&v| v as usize)
            .collect();
        want.push(4);
        want.sort();
        let heavy: Vec<usize> = (0..9).filter(|&i| f[i] == 8.0).collect();
        assert_eq!(heavy, want);
    }

    #[test]
    fn flags_mark_every_subject() {
        let ops = [op(vec![1, 2]), op(vec![7])];
        let f = subject_flags(&ops, 9);
        let marked: Vec<usize> = (0..9).filter(|&i| f[i]).collect();
        assert_eq!(marked, vec![1, 2, 7]);
    }

    #[test]
    fn off_without_operations_effect_or_with_factor_one() {
        let t = grid();
        let ops = [op(vec![0, 1])];
        assert!(collision_mass_factors(&ops, &t, 9, 1.0, HeavyScope::Subjects).is_empty());
        assert!(collision_mass_factors(&ops, &t, 9, f64::NAN, HeavyScope::Subjects).is_empty());
        let f = collision_mass_factors(std::iter::empty(), &t, 9, 4.0, HeavyScope::Subjects);
        assert_eq!(f, vec![1.0; 9]);
    }
}
