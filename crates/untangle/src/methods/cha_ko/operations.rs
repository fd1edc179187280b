//! The operations of Cha & Ko 2022, Sec. 5.1: vertex pull (edge shortening toward a green
//! target, subject fan re-meshing: only the subject moves, the fan contour stays) and triangle
//! shrinkage (the two ends of a red* triangle's red edge move toward its third vertex), as
//! proposals checked by the triangle inversion test before they start. Revoke is
//! [`super::state::UvState::revoke`].
//!
//! Target choice (Sec. 5.1.2, "an out-most red vertex can have multiple candidate green
//! vertices"): among the green neighbours that pass the test, the one with the shortest
//! original subject edge (ties: lowest vertex index). By Eq. (1) a finesse needs
//! `n > ln(eps_RG / l) / ln(gamma)` levels, so the shortest edge `l` finishes first.

use super::fallback::{self, Fallback};
use super::fan::fan_triangles;
use super::seams;
use super::state::{reference_signs, MovedCopy, OpKind};
use super::tit::{tit, TitResult};
use crate::geom::Vec2;
use crate::mesh::topology::NONE;
use crate::mesh::Garment;

/// The garment's fixed data the operations need.
#[derive(Clone, Debug)]
pub struct UvMesh {
    /// The garment.
    pub garment: Garment,
    /// Reference orientation of each uv triangle.
    pub sign: Vec<f64>,
    /// Triangles degenerate or flipped in the input (not tested, sorted).
    pub skip: Vec<u32>,
    /// Smallest scale an operation reaches (`gamma^max_level`).
    pub s_min: f64,
}

/// An operation ready to start.
#[derive(Clone, Debug, PartialEq)]
pub struct Proposal {
    /// Pull or shrink.
    pub kind: OpKind,
    /// Subject world vertices.
    pub subjects: Vec<u32>,
    /// Target world vertex.
    pub target: u32,
    /// The red* triangle (shrinks) or [`NONE`].
    pub triangle: u32,
    /// Moved copies with anchors.
    pub copies: Vec<MovedCopy>,
    /// Copies with a virtual (seam) anchor.
    pub virtual_copies: u32,
    /// Copies left in place (ring not developable).
    pub unsupported: u32,
    /// Fallback used, if any.
    pub fallback: Option<Fallback>,
}

/// Outcome of looking for a regular operation on one subject.
#[derive(Clone, Debug, PartialEq)]
pub struct Choice {
    /// The operation to start, if one passes the test.
    pub proposal: Option<Proposal>,
    /// Candidates that failed the test (kept for the fallbacks).
    pub rejected: Vec<Proposal>,
}

impl UvMesh {
    /// Fixed data of `garment` for operations that go down to scale `s_min`.
    pub fn new(garment: Garment, s_min: f64) -> Self {
        let (sign, skip) = reference_signs(&garment);
        UvMesh {
            garment,
            sign,
            skip,
            s_min,
        }
    }

    /// Original uv length of the world edge `(a, b)` (shortest over its panels), or infinity
    /// when they are not adjacent.
    pub fn rest_length(&self, orig: &[Vec2], a: u32, b: u32) -> f64 {
        let g = &self.garment;
        let uv = g.uv();
        g.topology
            .vertex_triangles
            .row(a as usize)
            .iter()
            .filter_map(|&t| {
                let w = g.mesh.triangles[t as usize];
                let ka = w.iter().position(|&v| v == a)?;
                let kb = w.iter().position(|&v| v == b)?;
                let u = uv.triangles[t as usize];
                Some((orig[u[ka] as usize] - orig[u[kb] as usize]).norm())
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The pull of `x` toward its neighbour `t`, every uv copy of `x` included (seams).
    pub fn pull(&self, orig: &[Vec2], x: u32, t: u32) -> Proposal {
        let a = seams::anchors(&self.garment, orig, x, t);
        Proposal {
            kind: OpKind::Pull,
            subjects: vec![x],
            target: t,
            triangle: NONE,
            copies: a.copies,
            virtual_copies: a.virtual_copies,
            unsupported: a.unsupported,
            fallback: None,
        }
    }

    /// The shrinkage of triangle `tri`: subjects `j`, `k` (the red edge) toward `i`.
    pub fn shrink(&self, orig: &[Vec2], tri: u32, i: u32, j: u32, k: u32) -> Proposal {
        let aj = seams::anchors(&self.garment, orig, j, i);
        let ak = seams::anchors(&self.garment, orig, k, i);
        let mut copies = aj.copies;
        copies.extend(ak.copies);
        Proposal {
            kind: OpKind::Shrink,
            subjects: vec![j, k],
            target: i,
            triangle: tri,
            copies,
            virtual_copies: aj.virtual_copies + ak.virtual_copies,
            unsupported: aj.unsupported + ak.unsupported,
            fallback: None,
        }
    }

    /// The sector operation of `s` ([`super::sectors`]): its subjects toward its loop vertex.
    pub fn sector(&self, orig: &[Vec2], s: &super::sectors::Sector) -> Proposal {
        Proposal {
            kind: OpKind::Sector,
            subjects: s.subjects.clone(),
            target: s.vertex,
            triangle: NONE,
            copies: super::sectors::sector_copies(&self.garment, orig, s),
            virtual_copies: 0,
            unsupported: 0,
            fallback: None,
        }
    }

    /// The triangle inversion test of a proposal over all triangles of its subjects' fans.
    pub fn test(&self, orig: &[Vec2], p: &Proposal) -> TitResult {
        let tris = fan_triangles(&self.garment.topology, &p.subjects);
        tit(
            &self.garment.uv().triangles,
            orig,
            &self.sign,
            &self.skip,
            &tris,
            &p.copies,
            self.s_min,
        )
    }

    /// Chooses the pull of out-most red vertex `x` among the green neighbours `candidates`
    /// (Sec. 5.1.2, the rule in the module text).
    pub fn choose_pull(&self, orig: &[Vec2], x: u32, candidates: &[u32]) -> Choice {
        let mut order: Vec<(f64, u32)> = candidates
            .iter()
            .map(|&t| (self.rest_length(orig, x, t), t))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut rejected = Vec::new();
        for &(_, t) in &order {
            let p = self.pull(orig, x, t);
            if self.test(orig, &p).pass {
                return Choice {
                    proposal: Some(p),
                    rejected,
                };
            }
            rejected.push(p);
        }
        Choice {
            proposal: None,
            rejected,
        }
    }

    /// Checks the shrinkage of red* triangle `tri` (target `i`, red edge `(j, k)`).
    pub fn choose_shrink(&self, orig: &[Vec2], tri: u32, i: u32, j: u32, k: u32) -> Choice {
        let p = self.shrink(orig, tri, i, j, k);
        if self.test(orig, &p).pass {
            Choice {
                proposal: Some(p),
                rejected: Vec::new(),
            }
        } else {
            Choice {
                proposal: None,
                rejected: vec![p],
            }
        }
    }

    /// The fallback for candidates that all failed the test (see [`fallback`]): the kernel
    /// target for single-copy pulls, else shortened anchors.
    pub fn fallback(&self, orig: &[Vec2], rejected: &[Proposal]) -> Option<Proposal> {
        self.kernel_fallback(orig, rejected)
            .or_else(|| self.shortened_fallback(orig, rejected))
    }

    /// Kernel-target fallback for single-copy pulls: the candidate whose kernel anchor comes
    /// relatively closest to its target (ties: candidate order).
    fn kernel_fallback(&self, orig: &[Vec2], proposals: &[Proposal]) -> Option<Proposal> {
        let mut best: Option<(f64, Proposal)> = None;
        for p in proposals {
            if p.kind != OpKind::Pull || p.copies.len() != 1 || p.virtual_copies != 0 {
                continue;
            }
            let c = p.copies[0];
            let (o, target_uv) = (orig[c.uv as usize], c.anchor);
            let contour = self.contour(orig, p.subjects[0], c.uv);
            let Some(anchor) = fallback::kernel_anchor(&contour, o, target_uv) else {
                continue;
            };
            let d0 = (o - target_uv).norm();
            let ratio = (anchor - target_uv).norm() / d0;
            if ratio.is_nan() || ratio >= 1.0 - 1e-6 {
                continue;
            }
            let q = Proposal {
                copies: vec![MovedCopy { uv: c.uv, anchor }],
                fallback: Some(Fallback::KernelTarget),
                ..p.clone()
            };
            if self.test(orig, &q).pass && best.as_ref().is_none_or(|b| ratio < b.0) {
                best = Some((ratio, q));
            }
        }
        best.map(|b| b.1)
    }

    /// Shortened-anchor fallback: the largest `lambda` any candidate passes with (ties:
    /// candidate order).
    fn shortened_fallback(&self, orig: &[Vec2], proposals: &[Proposal]) -> Option<Proposal> {
        for &lambda in &fallback::LAMBDAS {
            for p in proposals {
                let q = Proposal {
                    copies: fallback::shortened(orig, &p.copies, lambda),
                    fallback: Some(Fallback::Shortened { lambda }),
                    ..p.clone()
                };
                if self.test(orig, &q).pass {
                    return Some(q);
                }
            }
        }
        None
    }

    /// Contour edges of uv copy `c` of world vertex `x`, oriented so that `c` must stay left of
    /// each (see [`fallback::kernel`]).
    fn contour(&self, orig: &[Vec2], x: u32, c: u32) -> Vec<(Vec2, Vec2)> {
        let g = &self.garment;
        let uv = g.uv();
        g.topology
            .vertex_triangles
            .row(x as usize)
            .iter()
            .filter_map(|&t| {
                let u = uv.triangles[t as usize];
                let k = u.iter().position(|&i| i == c)?;
                let (a, b) = (orig[u[(k + 1) % 3] as usize], orig[u[(k + 2) % 3] as usize]);
                Some(if self.sign[t as usize] > 0.0 {
                    (a, b)
                } else {
                    (b, a)
                })
            })
            .collect()
    }
}
