//! Samples with normals for the implicit fields (Buffet et al. 2019, Sec. 4): Poisson-disk
//! samples of the surface with interpolated vertex normals (for `f_i`), and samples of the open
//! boundary with in-surface outward normals (for the co-variant field `h_i`).
//!
//! Normals point *outwards*: triangles are first oriented consistently within each connected
//! component (breadth-first over shared edges), then each component is turned so that its
//! normals point away from a reference centre (the body's centre, or the mesh's own), measured by
//! the area-weighted sum of `n · (c_t − centre)` over its triangles.

use crate::geom::{Aabb, Vec3};
use crate::mesh::topology::NONE;
use crate::mesh::{Mesh, Topology};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Points with unit normals.
#[derive(Clone, Debug, Default)]
pub struct Samples {
    /// Sample positions.
    pub points: Vec<Vec3>,
    /// Unit normals (the prescribed field gradients).
    pub normals: Vec<Vec3>,
    /// The minimum distance between samples (Poisson disk radius) or their spacing.
    pub spacing: f64,
}

/// Per triangle: whether its corner order must be reversed for a consistent, outward orientation.
pub fn outward_flips(mesh: &Mesh, topo: &Topology, centre: &Vec3) -> Vec<bool> {
    let nt = mesh.triangles.len();
    let mut flip = vec![false; nt];
    let mut seen = vec![false; nt];
    let mut stack = Vec::new();
    for start in 0..nt {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut component = Vec::new();
        while let Some(t) = stack.pop() {
            component.push(t);
            for k in 0..3 {
                let e = topo.triangle_edges[t][k] as usize;
                let [a, b] = topo.edge_triangles[e];
                let other = if a as usize == t { b } else { a };
                if other == NONE || seen[other as usize] {
                    continue;
                }
                let o = other as usize;
                // Same direction of the shared edge in both triangles = inconsistent.
                let (u, v) = (mesh.triangles[t][k], mesh.triangles[t][(k + 1) % 3]);
                let tri = mesh.triangles[o];
                let same = (0..3).any(|m| tri[m] == u && tri[(m + 1) % 3] == v);
                flip[o] = flip[t] ^ same;
                seen[o] = true;
                stack.push(o);
            }
        }
        let mut score = 0.0;
        for &t in &component {
            let [a, b, c] = mesh.triangles[t].map(|v| mesh.positions[v as usize]);
            let n = (b - a).cross(&(c - a)) * if flip[t] { -1.0 } else { 1.0 };
            score += n.dot(&((a + b + c) / 3.0 - centre));
        }
        if score < 0.0 {
            for &t in &component {
                flip[t] = !flip[t];
            }
        }
    }
    flip
}

/// Oriented, area-weighted unit normal of each triangle (`flips` from [`outward_flips`]), times
/// twice its area.
fn face_normals(mesh: &Mesh, flips: &[bool]) -> Vec<Vec3> {
    mesh.triangles
        .iter()
        .zip(flips)
        .map(|(t, &f)| {
            let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
            (b - a).cross(&(c - a)) * if f { -1.0 } else { 1.0 }
        })
        .collect()
}

/// Area-weighted outward vertex normals.
pub fn vertex_normals(mesh: &Mesh, flips: &[bool]) -> Vec<Vec3> {
    let fnorm = face_normals(mesh, flips);
    let mut n = vec![Vec3::zeros(); mesh.positions.len()];
    for (t, fn_) in mesh.triangles.iter().zip(&fnorm) {
        for &v in t {
            n[v as usize] += fn_;
        }
    }
    for x in &mut n {
        let l = x.norm();
        if l > 0.0 {
            *x /= l;
        }
    }
    n
}

/// About `target` Poisson-disk samples of the surface (dart throwing over area-weighted random
/// candidates, accepted when no accepted sample is closer than the disk radius), with normals
/// interpolated from the vertex normals. Deterministic for a seed.
pub fn poisson_disk(mesh: &Mesh, normals: &[Vec3], target: usize, seed: u64) -> Samples {
    let tris = &mesh.triangles;
    let mut cum = Vec::with_capacity(tris.len());
    let mut total = 0.0;
    for t in tris {
        let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
        total += 0.5 * (b - a).cross(&(c - a)).norm();
        cum.push(total);
    }
    let target = target.max(1);
    if total <= 0.0 {
        return Samples::default();
    }
    // Random maximal disk packings cover about 1.44 r^2 of area per sample.
    let radius = (total / (1.44 * target as f64)).sqrt();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let bbox = Aabb::from_points(&mesh.positions).inflated(radius);
    let cell = radius;
    let dims = (bbox.extent() / cell).map(|x| (x.ceil() as usize).max(1));
    let mut buckets: std::collections::HashMap<(usize, usize, usize), Vec<u32>> =
        std::collections::HashMap::new();
    let key = |p: &Vec3| {
        let q = (p - bbox.min) / cell;
        (
            (q.x as usize).min(dims.x - 1),
            (q.y as usize).min(dims.y - 1),
            (q.z as usize).min(dims.z - 1),
        )
    };
    let mut out = Samples {
        spacing: radius,
        ..Default::default()
    };
    let candidates = 30 * target;
    for _ in 0..candidates {
        let u = rng.random::<f64>() * total;
        let t = cum.partition_point(|&c| c < u).min(tris.len() - 1);
        let (mut s, mut r) = (rng.random::<f64>(), rng.random::<f64>());
        if s + r > 1.0 {
            s = 1.0 - s;
            r = 1.0 - r;
        }
        let [ia, ib, ic] = tris[t].map(|v| v as usize);
        let [a, b, c] = [ia, ib, ic].map(|v| mesh.positions[v]);
        let p = a + (b - a) * s + (c - a) * r;
        let (kx, ky, kz) = key(&p);
        let mut free = true;
        'search: for x in kx.saturating_sub(1)..=(kx + 1).min(dims.x - 1) {
            for y in ky.saturating_sub(1)..=(ky + 1).min(dims.y - 1) {
                for z in kz.saturating_sub(1)..=(kz + 1).min(dims.z - 1) {
                    if let Some(list) = buckets.get(&(x, y, z)) {
                        for &q in list {
                            if (out.points[q as usize] - p).norm_squared() < radius * radius {
                                free = false;
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        if !free {
            continue;
        }
        let n = normals[ia] * (1.0 - s - r) + normals[ib] * s + normals[ic] * r;
        let l = n.norm();
        if l < 1e-12 {
            continue;
        }
        buckets
            .entry((kx, ky, kz))
            .or_default()
            .push(out.points.len() as u32);
        out.points.push(p);
        out.normals.push(n / l);
    }
    out
}

/// Samples of the open boundary, about `spacing` apart, with the unit normal lying in the
/// surface, orthogonal to the boundary and pointing away from the surface (Sec. 4).
pub fn boundary_samples(mesh: &Mesh, topo: &Topology, flips: &[bool], spacing: f64) -> Samples {
    let mut out = Samples {
        spacing,
        ..Default::default()
    };
    for (e, tris) in topo.edge_triangles.iter().enumerate() {
        if tris[1] != NONE {
            continue;
        }
        let t = tris[0] as usize;
        let [a, b] = topo.edges[e].map(|v| mesh.positions[v as usize]);
        let third = mesh.triangles[t]
            .iter()
            .copied()
            .find(|&v| v != topo.edges[e][0] && v != topo.edges[e][1])
            .expect("a triangle has a third corner");
        let c = mesh.positions[third as usize];
        let [p0, p1, p2] = mesh.triangles[t].map(|v| mesh.positions[v as usize]);
        let fnrm = (p1 - p0).cross(&(p2 - p0)) * if flips[t] { -1.0 } else { 1.0 };
        let dir = b - a;
        let mut m = dir.cross(&fnrm);
        if m.dot(&(c - a)) > 0.0 {
            m = -m;
        }
        let l = m.norm();
        if l < 1e-300 {
            continue;
        }
        let m = m / l;
        let k = ((dir.norm() / spacing).ceil() as usize).max(1);
        for s in 0..k {
            out.points.push(a + dir * ((s as f64 + 0.5) / k as f64));
            out.normals.push(m);
        }
    }
    out
}

/// About `count` interior vertices with minus their distance to the open boundary along mesh
/// edges (Dijkstra from the boundary vertices): value constraints that keep the whole garment
/// inside its own influence region `h_i < 0`. Empty for a closed mesh.
pub fn interior_values(mesh: &Mesh, topo: &Topology, count: usize) -> (Vec<Vec3>, Vec<f64>) {
    let nv = mesh.positions.len();
    let dist = topo.distances_to_boundary(|v, u, _| {
        (mesh.positions[v as usize] - mesh.positions[u as usize]).norm()
    });
    let interior: Vec<usize> = (0..nv)
        .filter(|&v| dist[v] > 0.0 && dist[v].is_finite())
        .collect();
    if interior.is_empty() || count == 0 {
        return (Vec::new(), Vec::new());
    }
    let step = (interior.len() as f64 / count as f64).max(1.0);
    let mut pts = Vec::new();
    let mut vals = Vec::new();
    let mut k = 0.0;
    while (k as usize) < interior.len() {
        let v = interior[k as usize];
        pts.push(mesh.positions[v]);
        vals.push(-dist[v]);
        k += step;
    }
    (pts, vals)
}

/// Value constraints beyond the open boundary: for every boundary sample `b` with in-surface
/// outward normal `m`, the points `b + k·step·m` (`k = 1..=layers`) with the value `k·step`,
/// unless another part of the surface (a sample of `surface`) is closer to the point than its own
/// rim. Without them the co-variant field, fitted to the rim alone, extrapolates freely away from
/// the rim and can be negative beside a garment (e.g. beyond a vest's armholes, where a T-shirt's
/// sleeve passes), making the garment influence places it does not cover.
pub fn exterior_values(
    boundary: &Samples,
    surface: &Samples,
    step: f64,
    layers: usize,
) -> (Vec<Vec3>, Vec<f64>) {
    let mut pts = Vec::new();
    let mut vals = Vec::new();
    for (b, m) in boundary.points.iter().zip(&boundary.normals) {
        for k in 1..=layers {
            let d = k as f64 * step;
            let q = b + m * d;
            let clear = surface
                .points
                .iter()
                .all(|s| (s - q).norm_squared() >= 0.81 * d * d);
            if clear {
                pts.push(q);
                vals.push(d);
            }
        }
    }
    (pts, vals)
}

/// Keeps every `k`-th sample so that at most `max` remain (deterministic thinning).
pub fn thin(s: Samples, max: usize) -> Samples {
    if s.points.len() <= max || max == 0 {
        return s;
    }
    let step = s.points.len() as f64 / max as f64;
    let idx: Vec<usize> = (0..max).map(|k| (k as f64 * step) as usize).collect();
    Samples {
        points: idx.iter().map(|&i| s.points[i]).collect(),
        normals: idx.iter().map(|&i| s.normals[i]).collect(),
        spacing: s.spacing * step,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uv_sphere(n: usize) -> Mesh {
        crate::implicit::shapes::sphere_mesh("s", &Vec3::zeros(), 1.0, n)
    }

    #[test]
    fn poisson_samples_keep_their_distance_and_cover_the_sphere() {
        let m = uv_sphere(24);
        let topo = Topology::new(&m).unwrap();
        let flips = outward_flips(&m, &topo, &Vec3::zeros());
        let vn = vertex_normals(&m, &flips);
        let s = poisson_disk(&m, &vn, 300, 1);
        assert!(
            s.points.len() > 200 && s.points.len() < 420,
            "{}",
            s.points.len()
        );
        let r = s.spacing;
        assert!((r - (4.0 * std::f64::consts::PI / (1.44 * 300.0)).sqrt()).abs() < 0.01);
        // Brute-force oracle: no pair closer than the radius, normals outward and unit.
        for i in 0..s.points.len() {
            assert!((s.normals[i].norm() - 1.0).abs() < 1e-12);
            assert!(s.normals[i].dot(&s.points[i]) > 0.9);
            for j in 0..i {
                assert!((s.points[i] - s.points[j]).norm() >= r);
            }
        }
        // Same seed, same samples.
        let t = poisson_disk(&m, &vn, 300, 1);
        assert_eq!(s.points, t.points);
    }

    #[test]
    fn inverted_triangles_are_reoriented_outwards() {
        let mut m = uv_sphere(12);
        for (k, t) in m.triangles.iter_mut().enumerate() {
            if k % 3 == 0 {
                t.swap(1, 2);
            }
        }
        let topo = Topology::new(&m).unwrap();
        let flips = outward_flips(&m, &topo, &Vec3::zeros());
        let vn = vertex_normals(&m, &flips);
        for (p, n) in m.positions.iter().zip(&vn) {
            assert!(n.dot(p) > 0.9);
        }
    }

    #[test]
    fn boundary_normals_of_an_open_cylinder_point_out_of_the_surface() {
        let m = crate::implicit::shapes::cylinder_mesh("c", 1.0, 2.0, 24, 8, false);
        let topo = Topology::new(&m).unwrap();
        let flips = outward_flips(&m, &topo, &Vec3::zeros());
        let s = boundary_samples(&m, &topo, &flips, 0.1);
        assert!(!s.points.is_empty());
        for (p, n) in s.points.iter().zip(&s.normals) {
            // Top rim (z = 1) points up, bottom rim (z = -1) points down.
            assert!((p.z.abs() - 1.0).abs() < 1e-12);
            assert!((n.z - p.z.signum()).abs() < 1e-9, "{n:?} at {p:?}");
        }
    }
}
