//! Rigid impact zones (Provot 1997; Bridson et al. 2002, Sec. 7.4; Harmon et al. 2008): the
//! vertices of pairs that still collide are merged into zones, and each zone moves as one rigid
//! body with its linear and angular momentum. Along straight-line trajectories a rigid velocity
//! field maps the zone by `I + t h [omega]x`, an invertible affine map whose singular values are
//! at least 1, so no distance inside a zone shrinks and pairs inside one zone need no further
//! test; CCD is repeated on the rest until it finds nothing. A zone that touches a pinned vertex
//! or an obstacle takes their (mean) velocity instead.
//!
//! Variants ([`ZoneMotion`], ours): a zone may drop its spin and translate (distances kept
//! exactly, no growth), and a *soft* zone first keeps part of its deformation, its own pairs
//! still tested by CCD, becoming rigid only after colliding again `soft_levels` times; the
//! guarantee is the rigid zone's in the end. Why: a tangled cloth under large stretch forces
//! formed one rigid zone over nearly all of its vertices in every step, so it could not deform
//! at all, and the linearised spin grew it step by step (docs/cha-ko.md).

use super::{Scene, OBSTACLE};
use crate::geom::Vec3;
use nalgebra::Matrix3;

/// How a free impact zone (no pinned vertex, no obstacle) moves. The default is Bridson et
/// al.'s rigid zone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ZoneMotion {
    /// `true` (Bridson et al. 2002, Sec. 7.4): the zone keeps its linear and angular momentum,
    /// the rotation linearised (`v = v_c + omega x r`, straight-line trajectories), so every
    /// distance in it grows by up to `sqrt(1 + (h |omega|)^2)` per step. `false`: it keeps its
    /// linear momentum only and translates, every distance in it stays exactly as it is (its
    /// angular momentum is dissipated, as in an inelastic impact).
    pub spin: bool,
    /// `0`: a zone moves rigidly at once. `k > 0` (ours): a zone first keeps half of its
    /// deformation (`v = v_rigid + alpha (v_0 - v_rigid)`, `v_0` the velocities the zone phase
    /// started with, `alpha = 1/2`), and its own pairs are still tested; each pass that finds it
    /// colliding again halves `alpha`, and after `k` halvings it moves rigidly. A cloth that keeps
    /// forming one zone over most of its vertices (a tangle under large elastic forces) can then
    /// still deform a little each step instead of freezing.
    pub soft_levels: u32,
}

impl Default for ZoneMotion {
    fn default() -> Self {
        ZoneMotion {
            spin: true,
            soft_levels: 0,
        }
    }
}

/// Union-find over cloth vertices with per-vertex obstacle anchors.
pub struct Zones {
    parent: Vec<u32>,
    in_zone: Vec<bool>,
    anchor_sum: Vec<Vec3>,
    anchor_count: Vec<u32>,
    /// Per zone root: whether the zone moves rigidly (false when pinned vertices with different
    /// prescribed velocities are in it; its pairs are then still tested).
    rigid: Vec<bool>,
    /// Per vertex: its zone gained members or anchors since the last [`Zones::rigidify`] (read
    /// at the zone's root).
    dirty: Vec<bool>,
    /// Per zone root: how many times it has been made (more) rigid.
    level: Vec<u32>,
    /// Per zone root: the fraction of its deformation it still keeps (0: rigid).
    alpha: Vec<f64>,
}

impl Zones {
    /// No zone yet over `n` cloth vertices.
    pub fn new(n: usize) -> Zones {
        Zones {
            parent: (0..n as u32).collect(),
            in_zone: vec![false; n],
            anchor_sum: vec![Vec3::zeros(); n],
            anchor_count: vec![0; n],
            rigid: vec![true; n],
            dirty: vec![false; n],
            level: vec![0; n],
            alpha: vec![0.0; n],
        }
    }

    fn find(&self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            x = self.parent[x as usize];
        }
        x
    }

    fn find_mut(&mut self, x: u32) -> u32 {
        let r = self.find(x);
        let mut y = x;
        while self.parent[y as usize] != r {
            let next = self.parent[y as usize];
            self.parent[y as usize] = r;
            y = next;
        }
        r
    }

    /// Whether all four nodes are cloth vertices of one zone.
    pub fn same_zone(&self, nodes: &[u32; 4]) -> bool {
        if nodes
            .iter()
            .any(|&n| n & OBSTACLE != 0 || !self.in_zone[n as usize])
        {
            return false;
        }
        let r = self.find(nodes[0]);
        self.rigid[r as usize]
            && self.alpha[r as usize] == 0.0
            && nodes[1..].iter().all(|&n| self.find(n) == r)
    }

    /// Merges the cloth nodes of a colliding pair into one zone; obstacle nodes anchor it.
    pub fn merge(&mut self, scene: &Scene, v: &[Vec3], nodes: &[u32; 4]) {
        let cloth: Vec<u32> = nodes
            .iter()
            .copied()
            .filter(|n| n & OBSTACLE == 0)
            .collect();
        let obst: Vec<u32> = nodes
            .iter()
            .copied()
            .filter(|n| n & OBSTACLE != 0)
            .collect();
        if cloth.is_empty() {
            return;
        }
        let mut r = self.find_mut(cloth[0]);
        for &c in &cloth {
            self.in_zone[c as usize] = true;
            let rc = self.find_mut(c);
            if rc != r {
                let (lo, hi) = (r.min(rc), r.max(rc));
                self.parent[hi as usize] = lo;
                self.level[lo as usize] = self.level[lo as usize].max(self.level[hi as usize]);
                r = lo;
            }
        }
        self.dirty[r as usize] = true;
        if !obst.is_empty() {
            let mean = obst
                .iter()
                .fold(Vec3::zeros(), |a, &o| a + scene.velocity(v, o))
                / obst.len() as f64;
            for &c in &cloth {
                self.anchor_sum[c as usize] += mean;
                self.anchor_count[c as usize] += 1;
            }
        }
    }

    fn groups(&self) -> Vec<Vec<u32>> {
        let n = self.parent.len();
        let mut index = vec![u32::MAX; n];
        let mut groups: Vec<Vec<u32>> = Vec::new();
        for i in 0..n as u32 {
            if !self.in_zone[i as usize] {
                continue;
            }
            let r = self.find(i) as usize;
            if index[r] == u32::MAX {
                index[r] = groups.len() as u32;
                groups.push(Vec::new());
            }
            groups[index[r] as usize].push(i);
        }
        groups
    }

    /// Number of zones and of vertices in them.
    pub fn stats(&self) -> (usize, usize) {
        let g = self.groups();
        (g.len(), g.iter().map(|z| z.len()).sum())
    }

    /// Replaces the velocities of every zone that gained members since the last call by its
    /// rigid motion. The other zones already move rigidly: recomputing their rigid motion from
    /// rigid velocities would only add rounding, and would make every one of their vertices
    /// look changed to the next CCD pass. With `motion.soft_levels > 0` a zone keeps part of its
    /// deformation relative to `v0` (the velocities at the start of the zone phase) until it
    /// has collided `soft_levels` times (see [`ZoneMotion`]).
    pub fn rigidify(&mut self, scene: &Scene, v: &mut [Vec3], v0: &[Vec3], motion: ZoneMotion) {
        for zone in self.groups() {
            let root = self.find(zone[0]) as usize;
            if !self.dirty[root] {
                continue;
            }
            self.dirty[root] = false;
            self.rigid[root] = true;
            self.level[root] += 1;
            self.alpha[root] = 0.0;
            let mut first_pinned: Option<Vec3> = None;
            let (mut pinned, mut pinned_count) = (Vec3::zeros(), 0u32);
            let (mut anchor, mut anchors) = (Vec3::zeros(), 0u32);
            for &i in &zone {
                let i = i as usize;
                if scene.inv_mass[i] == 0.0 {
                    pinned += v[i];
                    pinned_count += 1;
                    match first_pinned {
                        None => first_pinned = Some(v[i]),
                        Some(f) if f != v[i] => self.rigid[root] = false,
                        _ => {}
                    }
                }
                anchor += self.anchor_sum[i];
                anchors += self.anchor_count[i];
            }
            // Pinned vertices (prescribed motion) dominate obstacle anchors; either way the
            // whole zone translates uniformly, which is rigid.
            let a = if pinned_count > 0 {
                Some(pinned / pinned_count as f64)
            } else if anchors > 0 {
                Some(anchor / anchors as f64)
            } else {
                None
            };
            if let Some(a) = a {
                for &i in &zone {
                    if scene.inv_mass[i as usize] > 0.0 {
                        v[i as usize] = a;
                    }
                }
                continue;
            }
            // Soft zones take their momenta from the start velocities (the blend keeps them).
            let soft = motion.soft_levels > 0;
            let src: &[Vec3] = if soft { v0 } else { v };
            let alpha = if soft && self.level[root] <= motion.soft_levels {
                0.5f64.powi(self.level[root] as i32)
            } else {
                0.0
            };
            self.alpha[root] = alpha;
            let mass = |i: u32| 1.0 / scene.inv_mass[i as usize];
            let total: f64 = zone.iter().map(|&i| mass(i)).sum();
            let c = zone
                .iter()
                .fold(Vec3::zeros(), |a, &i| a + scene.x0[i as usize] * mass(i))
                / total;
            let mut p = Vec3::zeros();
            let mut l = Vec3::zeros();
            let mut inertia = Matrix3::zeros();
            for &i in &zone {
                let (m, r) = (mass(i), scene.x0[i as usize] - c);
                p += src[i as usize] * m;
                l += r.cross(&src[i as usize]) * m;
                inertia += (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * m;
            }
            // omega = I^+ L with a relative cut-off: directions of (near) zero inertia (a zone
            // of collinear vertices) get no spin, instead of an arbitrary huge one.
            let eig = nalgebra::SymmetricEigen::new(inertia);
            let top = eig.eigenvalues.iter().fold(0.0f64, |m, &e| m.max(e));
            let mut omega = Vec3::zeros();
            for k in 0..3 {
                let e = eig.eigenvalues[k];
                if e > 1e-6 * top && e > 0.0 {
                    let axis: Vec3 = eig.eigenvectors.column(k).into();
                    omega += axis * (axis.dot(&l) / e);
                }
            }
            if !motion.spin {
                omega = Vec3::zeros();
            }
            let vc = p / total;
            for &i in &zone {
                let rigid = vc + omega.cross(&(scene.x0[i as usize] - c));
                v[i as usize] = if alpha > 0.0 {
                    rigid + (v0[i as usize] - rigid) * alpha
                } else {
                    rigid
                };
            }
        }
    }
}
