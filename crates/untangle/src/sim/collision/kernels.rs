//! The distance and CCD kernels the collision handling calls (same signatures as
//! `geom::distance` / `geom::ccd`). TEMPORARY stand-in until the `ccd` branch lands: distances
//! by closest-point projection (Ericson 2005, Sec. 5.1.5 and 5.1.9) and CCD by conservative
//! advancement (the distance can shrink no faster than the largest relative vertex speed).

use crate::geom::Vec3;

/// Squared distance from `p` to triangle `(a, b, c)` and the barycentric coordinates of the
/// closest point.
pub fn point_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> (f64, [f64; 3]) {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    let bary = if d1 <= 0.0 && d2 <= 0.0 {
        [1.0, 0.0, 0.0]
    } else {
        let bp = p - b;
        let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
        if d3 >= 0.0 && d4 <= d3 {
            [0.0, 1.0, 0.0]
        } else {
            let vc = d1 * d4 - d3 * d2;
            if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
                let v = d1 / (d1 - d3);
                [1.0 - v, v, 0.0]
            } else {
                let cp = p - c;
                let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
                if d6 >= 0.0 && d5 <= d6 {
                    [0.0, 0.0, 1.0]
                } else {
                    let vb = d5 * d2 - d1 * d6;
                    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
                        let w = d2 / (d2 - d6);
                        [1.0 - w, 0.0, w]
                    } else {
                        let va = d3 * d6 - d5 * d4;
                        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
                            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
                            [0.0, 1.0 - w, w]
                        } else {
                            let denom = 1.0 / (va + vb + vc);
                            let (v, w) = (vb * denom, vc * denom);
                            [1.0 - v - w, v, w]
                        }
                    }
                }
            }
        }
    };
    let q = a * bary[0] + b * bary[1] + c * bary[2];
    ((p - q).norm_squared(), bary)
}

/// Squared distance between segments `p0p1` and `q0q1` and the parameters of the closest points.
pub fn segment_segment(p0: &Vec3, p1: &Vec3, q0: &Vec3, q1: &Vec3) -> (f64, f64, f64) {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let eps = 1e-30;
    let (s, t);
    if a <= eps && e <= eps {
        s = 0.0;
        t = 0.0;
    } else if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 1e-14 * a * e {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    let d = (p0 + d1 * s) - (q0 + d2 * t);
    (d.norm_squared(), s, t)
}

fn advance(x0: &[Vec3; 4], x1: &[Vec3; 4], thickness: f64, vt: bool) -> Option<f64> {
    let dist = |t: f64| {
        let p: [Vec3; 4] = [0, 1, 2, 3].map(|k| x0[k] + (x1[k] - x0[k]) * t);
        if vt {
            point_triangle(&p[0], &p[1], &p[2], &p[3]).0.sqrt()
        } else {
            segment_segment(&p[0], &p[1], &p[2], &p[3]).0.sqrt()
        }
    };
    let d: [Vec3; 4] = [0, 1, 2, 3].map(|k| x1[k] - x0[k]);
    let speed = if vt {
        (1..4).map(|k| (d[0] - d[k]).norm()).fold(0.0, f64::max)
    } else {
        let mut m = 0.0f64;
        for i in 0..2 {
            for j in 2..4 {
                m = m.max((d[i] - d[j]).norm());
            }
        }
        m
    };
    let scale = x0.iter().chain(x1).fold(0.0f64, |m, p| m.max(p.amax()));
    let tol = 1e-12 * (1.0 + scale) + 1e-3 * thickness;
    let mut t = 0.0;
    for _ in 0..200 {
        let dd = dist(t);
        if dd <= thickness + tol {
            return Some(t);
        }
        if speed <= 0.0 {
            return None;
        }
        t += 0.999 * (dd - thickness - 0.5 * tol) / speed;
        if t > 1.0 {
            return None;
        }
    }
    Some(t)
}

/// Conservative earliest time in `[0, 1]` at which vertex `x[0]` comes within `thickness` of
/// triangle `x[1..4]` moving linearly from `x0` to `x1`.
pub fn vertex_triangle_ccd(x0: &[Vec3; 4], x1: &[Vec3; 4], thickness: f64) -> Option<f64> {
    advance(x0, x1, thickness, true)
}

/// Conservative earliest time in `[0, 1]` at which edges `x[0]x[1]` and `x[2]x[3]` come within
/// `thickness`.
pub fn edge_edge_ccd(x0: &[Vec3; 4], x1: &[Vec3; 4], thickness: f64) -> Option<f64> {
    advance(x0, x1, thickness, false)
}
