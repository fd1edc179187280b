//! Pulls across seams (Cha & Ko 2022, Sec. 8, Fig. 12). The paper's procedure (Appendices A/B)
//! is not available; this is our own design.
//!
//! A world vertex on a seam has one uv copy per panel it touches (two copies in one panel along
//! a dart). When it is pulled toward a target, *every* copy must move, or the panels whose copy
//! stays put resist the pull (Fig. 12: re-meshing only `fan(x0)` leaves `x5` in place and
//! `T(x5, x6, x7)` hinders the shortening of `E(x0, x2)`). Each copy is re-meshed in its own
//! panel (subject fan re-meshing per copy, contour fixed), in coordination:
//!
//! - **Real anchor.** In a panel where the subject edge exists (the copy and a copy of the
//!   target share a uv triangle), the copy moves toward that uv copy of the target, exactly as
//!   off the seam.
//! - **Virtual anchor.** Elsewhere the copy moves toward a *virtual target*: the subject-edge
//!   vector, carried into that panel's uv frame by *developing* the world one-ring of the
//!   vertex. Walking around the ring from the subject edge, each crossing of a seam edge changes
//!   the frame by the similarity (rotation and scale, a complex ratio) that maps the seam edge's
//!   uv vector on one side to its uv vector on the other. Around an intrinsically flat vertex
//!   the counter-clockwise and the clockwise walk give the same map, and the result is exactly
//!   the planar re-meshing of the unfolded fan (the property the paper asks of its own
//!   procedures, Sec. 8); around a cone vertex (angle sum not 2 pi, non-planar) they differ by
//!   the angle defect, and the two maps are blended in log space (angle and log-scale
//!   interpolated), weighting each walk by the angle the *other* walk had to turn, so the nearer
//!   side dominates. An open ring (a seam vertex on the garment boundary) has one walk.
//!
//! Only the original uv (rest shape) is used, never the tangled world positions, so the anchors
//! are intrinsic and fixed for the life of the operation. The inversion test then runs over the
//! triangles of every copy, in every panel. A ring that cannot be developed (non-manifold
//! vertex, inconsistently oriented triangles, panels mirrored against each other) leaves the
//! copies without a real anchor in place; the operation records that.

use super::state::MovedCopy;
use crate::geom::Vec2;
use crate::mesh::Garment;

/// Where a seam is, for the finesse statistics (Table 1 of the paper).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub enum SeamKind {
    /// Every subject has one uv copy (intrinsically planar case, covered by the theorem).
    OffSeam,
    /// A subject has copies in several panels (paper: Appendix A).
    OnSeamA,
    /// A subject has several copies in one panel, e.g. along a dart (paper: Appendix B).
    OnSeamB,
}

/// The anchors of all uv copies of one subject.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Anchors {
    /// Moving copies with their anchors.
    pub copies: Vec<MovedCopy>,
    /// How many of them have a virtual anchor.
    pub virtual_copies: u32,
    /// Copies left in place because the ring could not be developed.
    pub unsupported: u32,
}

/// One triangle of the world one-ring of a vertex, in counter-clockwise order.
#[derive(Clone, Copy, Debug, PartialEq)]
struct RingTri {
    /// uv copy of the centre in this triangle.
    copy: u32,
    /// World vertex after the centre (counter-clockwise) and its uv index here.
    next: u32,
    uv_next: u32,
    /// World vertex before the centre and its uv index here.
    prev: u32,
    uv_prev: u32,
}

/// The one-ring of `x`, ordered so that `ring[k].next == ring[k + 1].prev`; `closed` when it is
/// a full cycle. `None` when it is not a single fan (non-manifold vertex or inconsistent
/// orientation).
fn ring(g: &Garment, x: u32) -> Option<(Vec<RingTri>, bool)> {
    let uv = g.uv();
    let tris: Vec<RingTri> = g
        .topology
        .vertex_triangles
        .row(x as usize)
        .iter()
        .map(|&t| {
            let w = g.mesh.triangles[t as usize];
            let u = uv.triangles[t as usize];
            let k = w.iter().position(|&v| v == x).expect("corner");
            let (n, p) = ((k + 1) % 3, (k + 2) % 3);
            RingTri {
                copy: u[k],
                next: w[n],
                uv_next: u[n],
                prev: w[p],
                uv_prev: u[p],
            }
        })
        .collect();
    let start = tris
        .iter()
        .position(|r| !tris.iter().any(|q| q.next == r.prev))
        .unwrap_or(0);
    let closed = tris.iter().all(|r| tris.iter().any(|q| q.next == r.prev));
    let mut order = vec![tris[start]];
    let mut used = vec![false; tris.len()];
    used[start] = true;
    while order.len() < tris.len() {
        let last = order.last().expect("non-empty").next;
        let mut found = tris
            .iter()
            .enumerate()
            .filter(|(i, r)| !used[*i] && r.prev == last);
        let (i, r) = found.next()?;
        if found.next().is_some() {
            return None;
        }
        used[i] = true;
        order.push(*r);
    }
    if closed && order.last().map(|r| r.next) != Some(order[0].prev) {
        return None;
    }
    Some((order, closed))
}

#[inline]
fn cmul(a: Vec2, b: Vec2) -> Vec2 {
    Vec2::new(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x)
}

#[inline]
fn cdiv(a: Vec2, b: Vec2) -> Vec2 {
    let n = b.norm_squared();
    Vec2::new((a.x * b.x + a.y * b.y) / n, (a.y * b.x - a.x * b.y) / n)
}

fn angle(a: Vec2, b: Vec2) -> f64 {
    (a.x * b.y - a.y * b.x).abs().atan2(a.dot(&b))
}

/// Walks the ring from the subject edge toward `copy`: returns the subject-edge vector in
/// `copy`'s frame and the angle turned on the way.
fn walk(
    orig: &[Vec2],
    ring: &[RingTri],
    closed: bool,
    t: u32,
    copy: u32,
    ccw: bool,
) -> Option<(Vec2, f64)> {
    let n = ring.len();
    let p = |i: u32| orig[i as usize];
    // Start: the triangle just past the spoke to `t` in the walking direction.
    let start = ring
        .iter()
        .position(|r| if ccw { r.prev == t } else { r.next == t })?;
    let r0 = ring[start];
    let mut z = if ccw {
        p(r0.uv_prev) - p(r0.copy)
    } else {
        p(r0.uv_next) - p(r0.copy)
    };
    let mut turned = 0.0;
    let mut k = start;
    loop {
        let r = ring[k];
        if r.copy == copy {
            return Some((z, turned));
        }
        turned += angle(p(r.uv_next) - p(r.copy), p(r.uv_prev) - p(r.copy));
        let k2 = if ccw {
            if k + 1 == n && !closed {
                return None;
            }
            (k + 1) % n
        } else {
            if k == 0 && !closed {
                return None;
            }
            (k + n - 1) % n
        };
        if k2 == start {
            return None;
        }
        let q = ring[k2];
        // The shared spoke's uv vector on both sides.
        let (here, there) = if ccw {
            (p(r.uv_next) - p(r.copy), p(q.uv_prev) - p(q.copy))
        } else {
            (p(r.uv_prev) - p(r.copy), p(q.uv_next) - p(q.copy))
        };
        if here != there {
            z = cmul(cdiv(there, here), z);
        }
        k = k2;
    }
}

/// Blends two estimates of the same vector in log space (angle and log-length), with weight
/// `w` on `b`.
fn blend(a: Vec2, b: Vec2, w: f64) -> Vec2 {
    let (la, lb) = (a.norm().ln(), b.norm().ln());
    let (pa, pb) = (a.y.atan2(a.x), b.y.atan2(b.x));
    let mut d = pb - pa;
    while d > std::f64::consts::PI {
        d -= 2.0 * std::f64::consts::PI;
    }
    while d <= -std::f64::consts::PI {
        d += 2.0 * std::f64::consts::PI;
    }
    let (l, ph) = ((1.0 - w) * la + w * lb, pa + w * d);
    Vec2::new(ph.cos(), ph.sin()) * l.exp()
}

/// Anchors of every uv copy of world vertex `x` pulled toward its neighbour `t` (see the module
/// text). Copies come in the order of `g.uv_copies`.
pub fn anchors(g: &Garment, orig: &[Vec2], x: u32, t: u32) -> Anchors {
    let uv = g.uv();
    let copies = g.uv_copies.row(x as usize);
    let mut out = Anchors::default();
    // Real anchors: a triangle holding both this copy and a copy of the target.
    let real = |c: u32| -> Option<u32> {
        g.topology
            .vertex_triangles
            .row(x as usize)
            .iter()
            .find_map(|&tri| {
                let w = g.mesh.triangles[tri as usize];
                let u = uv.triangles[tri as usize];
                let kx = w.iter().position(|&v| v == x)?;
                let kt = w.iter().position(|&v| v == t)?;
                (u[kx] == c).then_some(u[kt])
            })
    };
    let mut ring_cache: Option<Option<(Vec<RingTri>, bool)>> = None;
    for &c in copies {
        if let Some(tc) = real(c) {
            out.copies.push(MovedCopy {
                uv: c,
                anchor: orig[tc as usize],
            });
            continue;
        }
        let rc = ring_cache.get_or_insert_with(|| ring(g, x).filter(|(r, _)| consistent(orig, r)));
        let Some((r, closed)) = rc.as_ref() else {
            out.unsupported += 1;
            continue;
        };
        let a = walk(orig, r, *closed, t, c, true);
        let b = walk(orig, r, *closed, t, c, false);
        let z = match (a, b) {
            (Some((za, ta)), Some((zb, tb))) => {
                let w = if ta + tb > 0.0 { ta / (ta + tb) } else { 0.5 };
                blend(za, zb, w)
            }
            (Some((z, _)), None) | (None, Some((z, _))) => z,
            (None, None) => {
                out.unsupported += 1;
                continue;
            }
        };
        out.copies.push(MovedCopy {
            uv: c,
            anchor: orig[c as usize] + z,
        });
        out.virtual_copies += 1;
    }
    out
}

/// Whether all ring triangles have the same uv orientation (a similarity between frames is then
/// a rotation and scale, never a reflection).
fn consistent(orig: &[Vec2], ring: &[RingTri]) -> bool {
    let s = |r: &RingTri| {
        let (a, b) = (
            orig[r.uv_next as usize] - orig[r.copy as usize],
            orig[r.uv_prev as usize] - orig[r.copy as usize],
        );
        (a.x * b.y - a.y * b.x).signum()
    };
    let s0 = s(&ring[0]);
    s0 != 0.0 && ring.iter().all(|r| s(r) == s0)
}

/// Seam kind of an operation on `subjects`: [`SeamKind::OnSeamA`] if a subject has copies in
/// several panels, else [`SeamKind::OnSeamB`] if a subject has several copies, else off-seam.
pub fn seam_kind(g: &Garment, subjects: &[u32]) -> SeamKind {
    let (mut a, mut b) = (false, false);
    for &v in subjects {
        let copies = g.uv_copies.row(v as usize);
        if copies.len() < 2 {
            continue;
        }
        let p0 = g.panel_of_uv[copies[0] as usize];
        if copies.iter().any(|&c| g.panel_of_uv[c as usize] != p0) {
            a = true;
        } else {
            b = true;
        }
    }
    if a {
        SeamKind::OnSeamA
    } else if b {
        SeamKind::OnSeamB
    } else {
        SeamKind::OffSeam
    }
}
