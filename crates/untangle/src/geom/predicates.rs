//! Exact orientation predicates with one consistent rule for ties.
//!
//! `orient3d` is evaluated exactly with Shewchuk's adaptive arithmetic (crate `robust`). When the
//! exact determinant is zero, the tie is broken by Simulation of Simplicity (Edelsbrunner and
//! Mücke 1990): coordinate `j` of the point with global index `i` is perturbed by
//! `eps^(2^(3 i - j))`, and the sign of the perturbed determinant for `eps -> 0+` is returned.
//! The perturbed configuration is a real configuration in general position, so every answer built
//! from these predicates (edge-triangle crossings, intersection segments, paths) is mutually
//! consistent, identical on every run and independent of evaluation order or thread count. This is
//! the "one consistent rule for ties" the global intersection analysis needs (Wicke et al. 2006,
//! Sec. 4; Baraff et al. 2003).

use super::Vec3;
use std::sync::LazyLock;

#[inline]
fn c3(p: &Vec3) -> robust::Coord3D<f64> {
    robust::Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// Exact `orient3d(a, b, c, d) = det[a - d; b - d; c - d]`: positive when `d` lies below the plane
/// through `a, b, c` (the side from which `a, b, c` appear clockwise), zero when coplanar.
///
/// This equals the 4x4 determinant with rows `(p, 1)` for `p = a, b, c, d`.
#[inline]
pub fn orient3d(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> f64 {
    robust::orient3d(c3(a), c3(b), c3(c), c3(d))
}

/// Exact `orient2d` on the coordinates `(u, v)` of three points: the determinant with rows
/// `(p_u, p_v, 1)`; positive when counter-clockwise.
#[inline]
fn orient2d_coords(a: &Vec3, b: &Vec3, c: &Vec3, u: usize, v: usize) -> f64 {
    robust::orient2d(
        robust::Coord { x: a[u], y: a[v] },
        robust::Coord { x: b[u], y: b[v] },
        robust::Coord { x: c[u], y: c[v] },
    )
}

/// One term of the Simulation-of-Simplicity expansion: the coefficient of a product of
/// perturbations at `(row, column)` positions, which is a signed complementary minor.
struct Term {
    rows: [usize; 3],
    cols: [usize; 3],
    len: usize,
    sign: i8,
}

/// Bit of the perturbation of coordinate `j` of the point in sorted row `k`: `eps^(2^bit)`.
#[inline]
const fn bit(k: usize, j: usize) -> usize {
    3 * k + (2 - j)
}

/// All terms with a possibly non-zero coefficient, in order of increasing power of `eps`.
static TERMS: LazyLock<Vec<Term>> = LazyLock::new(|| {
    let mut pos_of_bit = [(0usize, 0usize); 12];
    for k in 0..4 {
        for j in 0..3 {
            pos_of_bit[bit(k, j)] = (k, j);
        }
    }
    let mut terms = Vec::new();
    for mask in 1u32..(1 << 12) {
        let mut entries: Vec<(usize, usize)> = (0..12)
            .filter(|b| mask & (1 << b) != 0)
            .map(|b| pos_of_bit[b])
            .collect();
        if entries.len() > 3 {
            continue;
        }
        entries.sort();
        let distinct_rows = entries.windows(2).all(|w| w[0].0 != w[1].0);
        let mut cs: Vec<usize> = entries.iter().map(|e| e.1).collect();
        let mut sorted_cols = cs.clone();
        sorted_cols.sort();
        sorted_cols.dedup();
        if !distinct_rows || sorted_cols.len() != cs.len() {
            continue;
        }
        // Sign of the pairing rows -> columns, as a permutation of the sorted columns.
        let mut inversions = 0;
        for a in 0..cs.len() {
            for b in a + 1..cs.len() {
                if cs[a] > cs[b] {
                    inversions += 1;
                }
            }
        }
        let index_sum: usize = entries.iter().map(|e| e.0 + e.1).sum();
        let sign = if (inversions + index_sum) % 2 == 0 {
            1
        } else {
            -1
        };
        cs.sort();
        let mut rows = [0; 3];
        let mut cols = [0; 3];
        for (i, e) in entries.iter().enumerate() {
            rows[i] = e.0;
            cols[i] = cs[i];
        }
        terms.push(Term {
            rows,
            cols,
            len: entries.len(),
            sign,
        });
    }
    terms
});

/// Sign of the perturbed determinant for points already sorted by increasing global index, given
/// that the unperturbed determinant is exactly zero.
fn sos_tail(p: [&Vec3; 4]) -> i8 {
    for t in TERMS.iter() {
        let removed_rows = &t.rows[..t.len];
        let removed_cols = &t.cols[..t.len];
        let mut rows = [0usize; 3];
        let mut nr = 0;
        for k in 0..4 {
            if !removed_rows.contains(&k) {
                rows[nr] = k;
                nr += 1;
            }
        }
        let mut cols = [0usize; 2];
        let mut nc = 0;
        for j in 0..3 {
            if !removed_cols.contains(&j) {
                cols[nc] = j;
                nc += 1;
            }
        }
        let minor = match t.len {
            1 => orient2d_coords(p[rows[0]], p[rows[1]], p[rows[2]], cols[0], cols[1]),
            2 => p[rows[0]][cols[0]] - p[rows[1]][cols[0]],
            _ => 1.0,
        };
        if minor > 0.0 {
            return t.sign;
        }
        if minor < 0.0 {
            return -t.sign;
        }
    }
    unreachable!("the last Simulation-of-Simplicity term is the constant 1")
}

/// `orient3d` of the symbolically perturbed points: never zero for four distinct indices.
///
/// `ids` are global vertex indices; they must be pairwise distinct (a repeated index means the
/// caller asked about a degenerate simplex, which it must rule out structurally). With a repeated
/// index this returns 0.
pub fn orient3d_sos(p: [&Vec3; 4], ids: [u32; 4]) -> i8 {
    let det = orient3d(p[0], p[1], p[2], p[3]);
    if det > 0.0 {
        return 1;
    }
    if det < 0.0 {
        return -1;
    }
    let mut order = [0usize, 1, 2, 3];
    let mut swaps = 0;
    for i in 1..4 {
        let mut j = i;
        while j > 0 && ids[order[j - 1]] > ids[order[j]] {
            order.swap(j - 1, j);
            swaps += 1;
            j -= 1;
        }
    }
    if ids[order[0]] == ids[order[1]]
        || ids[order[1]] == ids[order[2]]
        || ids[order[2]] == ids[order[3]]
    {
        return 0;
    }
    let s = sos_tail([p[order[0]], p[order[1]], p[order[2]], p[order[3]]]);
    if swaps % 2 == 1 {
        -s
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeMap;

    /// Sparse polynomial in eps with exact integer coefficients: exponent -> coefficient.
    type Poly = BTreeMap<u64, i128>;

    fn mul(a: &Poly, b: &Poly) -> Poly {
        let mut r = Poly::new();
        for (ea, ca) in a {
            for (eb, cb) in b {
                *r.entry(ea + eb).or_insert(0) += ca * cb;
            }
        }
        r.retain(|_, c| *c != 0);
        r
    }

    /// Independent oracle: the perturbed 4x4 determinant as an exact polynomial in eps (small
    /// integer coordinates), by the Leibniz formula; its lowest-order non-zero coefficient is
    /// the sign for eps -> 0+.
    fn oracle(p: [[i64; 3]; 4]) -> i8 {
        let entry = |k: usize, j: usize| -> Poly {
            let mut e = Poly::new();
            if j == 3 {
                e.insert(0, 1);
                return e;
            }
            if p[k][j] != 0 {
                e.insert(0, p[k][j] as i128);
            }
            e.insert(1u64 << bit(k, j), 1);
            e
        };
        let perms: Vec<[usize; 4]> = {
            let mut v = Vec::new();
            for a in 0..4 {
                for b in 0..4 {
                    for c in 0..4 {
                        for d in 0..4 {
                            let s = [a, b, c, d];
                            let mut u = s.to_vec();
                            u.sort();
                            u.dedup();
                            if u.len() == 4 {
                                v.push(s);
                            }
                        }
                    }
                }
            }
            v
        };
        let mut total = Poly::new();
        for s in perms {
            let mut inv = 0;
            for i in 0..4 {
                for j in i + 1..4 {
                    if s[i] > s[j] {
                        inv += 1;
                    }
                }
            }
            let mut prod = Poly::new();
            prod.insert(0, if inv % 2 == 0 { 1 } else { -1 });
            for (k, &col) in s.iter().enumerate() {
                prod = mul(&prod, &entry(k, col));
            }
            for (e, c) in prod {
                *total.entry(e).or_insert(0) += c;
            }
        }
        total.retain(|_, c| *c != 0);
        let (_, c) = total
            .iter()
            .next()
            .expect("perturbed determinant is never zero");
        c.signum() as i8
    }

    fn v(p: [i64; 3]) -> Vec3 {
        Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
    }

    #[test]
    fn generic_sign_matches_determinant_convention() {
        let a = Vec3::new(0.0, 0.0, 0.0);
        let b = Vec3::new(1.0, 0.0, 0.0);
        let c = Vec3::new(0.0, 1.0, 0.0);
        let above = Vec3::new(0.0, 0.0, 1.0);
        // a, b, c counter-clockwise seen from +z: a point above is on the negative side.
        assert_eq!(orient3d_sos([&a, &b, &c, &above], [0, 1, 2, 3]), -1);
        assert_eq!(oracle([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]), -1);
    }

    #[test]
    fn fully_degenerate_configurations_match_the_oracle() {
        // All four points equal: every tie has to be broken by the perturbation alone.
        let p = [[0i64, 0, 0]; 4];
        let vs: Vec<Vec3> = p.iter().map(|q| v(*q)).collect();
        assert_eq!(
            orient3d_sos([&vs[0], &vs[1], &vs[2], &vs[3]], [0, 1, 2, 3]),
            oracle(p)
        );
        // Repeated indices are reported as 0, never as a guess.
        assert_eq!(
            orient3d_sos([&vs[0], &vs[1], &vs[2], &vs[3]], [0, 1, 1, 3]),
            0
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// On a tiny integer grid most quadruples are degenerate; the symbolic answer must equal
        /// the exact polynomial oracle for every input order of the points.
        #[test]
        fn matches_polynomial_oracle(
            coords in proptest::array::uniform4(proptest::array::uniform3(-1i64..=1)),
            perm in Just([0usize, 1, 2, 3]).prop_shuffle(),
        ) {
            let sorted_sign = oracle(coords);
            let pts: Vec<Vec3> = coords.iter().map(|q| v(*q)).collect();
            // ids follow the sorted order of `coords`; present them in the order `perm`.
            let ids = [perm[0] as u32, perm[1] as u32, perm[2] as u32, perm[3] as u32];
            let got = orient3d_sos([&pts[perm[0]], &pts[perm[1]], &pts[perm[2]], &pts[perm[3]]], ids);
            let mut inv = 0;
            for i in 0..4 { for j in i + 1..4 { if perm[i] > perm[j] { inv += 1; } } }
            let expected = if inv % 2 == 0 { sorted_sign } else { -sorted_sign };
            prop_assert_eq!(got, expected);
        }
    }
}
