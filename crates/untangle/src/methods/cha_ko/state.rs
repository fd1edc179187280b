//! The uv layer being edited: the garment's original uv (rest shape) and the current uv, with the
//! operations in progress (Cha & Ko 2022, Sec. 5.1, Alg. 2 "Input: original uv-mesh and current
//! uv-mesh").
//!
//! Every displaced uv copy belongs to exactly one operation and sits at
//! `anchor + s (original - anchor)` with `s = gamma^level`. A pull or shrink adds a level, a revoke
//! removes one; at level 0 the copy is set back to its original uv bit for bit. Positions are
//! recomputed from `(anchor, original, level)` each time, never accumulated, so any sequence of
//! pulls and revokes lands on exactly the same numbers as a direct computation.

use crate::geom::{cross2, Vec2};
use crate::mesh::topology::NONE;
use crate::mesh::Garment;
use std::collections::BTreeMap;

/// One uv copy moved by an operation: its position is `anchor + s (original - anchor)`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MovedCopy {
    /// Index into the uv coordinates.
    pub uv: u32,
    /// Where the copy goes as the level grows (the target's uv, or a virtual or fallback point).
    #[serde(serialize_with = "ser_vec2")]
    pub anchor: Vec2,
}

pub(crate) fn ser_vec2<S: serde::Serializer>(v: &Vec2, s: S) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&[v.x, v.y], s)
}

/// The two operations of Sec. 5.1.1, and the BLI sector (ours).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum OpKind {
    /// Vertex pull of an out-most red vertex toward a green neighbour.
    Pull,
    /// Triangle shrinkage of a red* triangle: the red edge's ends move toward the third vertex.
    Shrink,
    /// BLI sector (ours, [`super::sectors`]): the boundary strand of a BLI path moves toward
    /// its interior loop vertex.
    Sector,
}

/// An operation in progress.
#[derive(Clone, Debug, PartialEq)]
pub struct Op {
    /// Its index in the finesse log.
    pub id: u32,
    /// Pull or shrink.
    pub kind: OpKind,
    /// Subject world vertices (one for a pull, the red edge's two ends for a shrink, the
    /// strand's corners for a sector).
    pub subjects: Vec<u32>,
    /// Target world vertex.
    pub target: u32,
    /// The red* triangle of a shrink ([`NONE`] for a pull).
    pub triangle: u32,
    /// Every moved uv copy of every subject.
    pub copies: Vec<MovedCopy>,
    /// Current level (`s = gamma^level`).
    pub level: u32,
    /// Deepest level allowed (the TIT was checked down to `gamma^level_cap`).
    pub level_cap: u32,
}

/// Original and current uv with the operations in progress.
#[derive(Clone, Debug)]
pub struct UvState {
    /// Original uv (rest shape of the input), never changed.
    pub orig: Vec<Vec2>,
    /// Current uv (the rest shape the simulator should use).
    pub cur: Vec<Vec2>,
    /// For each world vertex, the operation that displaces it ([`NONE`] = at its original uv).
    pub owner: Vec<u32>,
    /// Operations in progress, by id (ordered, so iteration is deterministic).
    pub ops: BTreeMap<u32, Op>,
    gamma: f64,
}

impl UvState {
    /// The state of an unedited uv layer.
    pub fn new(orig: Vec<Vec2>, num_world_vertices: usize, gamma: f64) -> Self {
        UvState {
            cur: orig.clone(),
            orig,
            owner: vec![NONE; num_world_vertices],
            ops: BTreeMap::new(),
            gamma,
        }
    }

    /// Scale `gamma^level` of a level.
    #[inline]
    pub fn scale(&self, level: u32) -> f64 {
        self.gamma.powi(level as i32)
    }

    /// Whether world vertex `v` is away from its original uv (owned by an operation).
    #[inline]
    pub fn is_displaced(&self, v: u32) -> bool {
        self.owner[v as usize] != NONE
    }

    /// Whether every vertex in `fan` is at its original uv (Alg. 2, lines 3 and 7).
    pub fn fan_is_original(&self, fan: &[u32]) -> bool {
        fan.iter().all(|&v| !self.is_displaced(v))
    }

    /// Starts an operation at level 0 and advances it to level 1. Its subjects must be free.
    pub fn start(&mut self, mut op: Op) {
        for &v in &op.subjects {
            debug_assert_eq!(self.owner[v as usize], NONE, "subject already displaced");
            self.owner[v as usize] = op.id;
        }
        op.level = 0;
        let id = op.id;
        self.ops.insert(id, op);
        self.set_level(id, 1);
    }

    /// Adds one level (one more pull / shrink by gamma) unless the cap is reached; returns
    /// whether the level changed.
    pub fn advance(&mut self, id: u32) -> bool {
        let op = &self.ops[&id];
        if op.level >= op.level_cap {
            return false;
        }
        let l = op.level + 1;
        self.set_level(id, l);
        true
    }

    /// Removes up to `levels` levels (revoke by 1/gamma each, Sec. 5.1.1); at level 0 the
    /// operation ends and its copies are back at their original uv exactly. Returns whether the
    /// operation ended.
    pub fn revoke(&mut self, id: u32, levels: u32) -> bool {
        let l = self.ops[&id].level.saturating_sub(levels);
        self.set_level(id, l);
        if l == 0 {
            let op = self.ops.remove(&id).expect("present");
            for &v in &op.subjects {
                self.owner[v as usize] = NONE;
            }
            true
        } else {
            false
        }
    }

    fn set_level(&mut self, id: u32, level: u32) {
        let s = self.scale(level);
        let op = self.ops.get_mut(&id).expect("present");
        op.level = level;
        for c in &op.copies {
            let o = self.orig[c.uv as usize];
            self.cur[c.uv as usize] = if level == 0 {
                o
            } else {
                c.anchor + (o - c.anchor) * s
            };
        }
    }
}

/// Per-triangle reference orientation: the sign of its panel's total signed uv area (a panel may
/// be mirrored in uv as a whole). Also returns the triangles that are degenerate or flipped
/// against their panel in the input (the inversion test ignores them: there is no orientation
/// to preserve).
pub fn reference_signs(g: &Garment) -> (Vec<f64>, Vec<u32>) {
    let uv = g.uv();
    let area = |t: usize| {
        let [a, b, c] = uv.triangles[t].map(|i| uv.coords[i as usize]);
        cross2(&a, &b, &c)
    };
    let mut panel_area = vec![0.0; g.num_panels];
    for t in 0..uv.triangles.len() {
        panel_area[g.panel_of_triangle[t] as usize] += area(t);
    }
    let sign: Vec<f64> = (0..uv.triangles.len())
        .map(|t| {
            if panel_area[g.panel_of_triangle[t] as usize] < 0.0 {
                -1.0
            } else {
                1.0
            }
        })
        .collect();
    let bad = (0..uv.triangles.len())
        .filter(|&t| sign[t] * area(t) <= 0.0)
        .map(|t| t as u32)
        .collect();
    (sign, bad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn op(id: u32, subjects: Vec<u32>, copies: Vec<MovedCopy>) -> Op {
        Op {
            id,
            kind: OpKind::Pull,
            subjects,
            target: 9,
            triangle: NONE,
            copies,
            level: 0,
            level_cap: 100,
        }
    }

    #[test]
    fn levels_follow_gamma_powers_and_revoke_is_exact() {
        let orig = vec![Vec2::new(0.3, -1.7), Vec2::new(2.0, 5.0)];
        let mut st = UvState::new(orig.clone(), 2, 0.8);
        let anchor = Vec2::new(1.1, 0.4);
        st.start(op(0, vec![0], vec![MovedCopy { uv: 0, anchor }]));
        for n in 1..=12u32 {
            let want = anchor + (orig[0] - anchor) * 0.8f64.powi(n as i32);
            assert!((st.cur[0] - want).norm() < 1e-15);
            assert_eq!(st.cur[1], orig[1]);
            st.advance(0);
        }
        assert!(st.is_displaced(0) && !st.is_displaced(1));
        while !st.revoke(0, 1) {}
        assert_eq!(st.cur, orig, "bit-exact restore");
        assert!(!st.is_displaced(0) && st.ops.is_empty());
    }

    #[test]
    fn level_cap_holds() {
        let mut st = UvState::new(vec![Vec2::new(1.0, 0.0)], 1, 0.5);
        let mut o = op(
            3,
            vec![0],
            vec![MovedCopy {
                uv: 0,
                anchor: Vec2::zeros(),
            }],
        );
        o.level_cap = 2;
        st.start(o);
        assert!(st.advance(3));
        assert!(!st.advance(3));
        assert_eq!(st.cur[0], Vec2::new(0.25, 0.0));
    }
}
