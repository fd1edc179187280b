//! Reader for the query files of the CCD benchmark of Wang, Ferguson, Schneider, Jiang, Attene,
//! Panozzo 2021 ("A Large Scale Benchmark and an Inclusion-Based Algorithm for Continuous
//! Collision Detection", ACM TOG 40(5)), used to validate and time [`super::ccd`].
//!
//! A file holds `8 n` rows `x_num,x_den,y_num,y_den,z_num,z_den,truth`: four points at `t = 0`,
//! then the same four at `t = 1` (vertex–face: `v, f0, f1, f2`; edge–edge: `ea0, ea1, eb0, eb1`).
//! Every coordinate is a rational whose denominator is a power of two and whose numerator fits in
//! 53 bits, so it is exactly one `f64`; the reader checks this and rejects anything else.

use super::Vec3;
use crate::{Error, Result};
use std::path::Path;

/// One benchmark query with its exact ground truth.
#[derive(Clone, Debug, PartialEq)]
pub struct CcdQuery {
    /// The four points at `t = 0`.
    pub x0: [Vec3; 4],
    /// The four points at `t = 1`.
    pub x1: [Vec3; 4],
    /// True when the primitives touch at some `t` in `[0, 1]` (exact ground truth).
    pub truth: bool,
}

/// Parses the text of one query file; `name` is used in error messages.
pub fn parse_queries(name: &str, text: &str) -> Result<Vec<CcdQuery>> {
    let mut rows: Vec<([f64; 3], bool)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let place = || format!("{name}:{}", i + 1);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 7 {
            return Err(Error::input(
                place(),
                format!("expected 7 fields, found {}", fields.len()),
            ));
        }
        let mut xyz = [0.0; 3];
        for k in 0..3 {
            xyz[k] = exact_ratio(fields[2 * k], fields[2 * k + 1])
                .map_err(|m| Error::input(place(), m))?;
        }
        let truth = match fields[6] {
            "0" => false,
            "1" => true,
            other => {
                return Err(Error::input(
                    place(),
                    format!("truth must be 0 or 1, found '{other}'"),
                ))
            }
        };
        rows.push((xyz, truth));
    }
    if rows.len() % 8 != 0 {
        return Err(Error::input(
            name,
            format!(
                "{} rows is not a multiple of 8 (one query = 8 rows)",
                rows.len()
            ),
        ));
    }
    Ok(rows
        .chunks_exact(8)
        .map(|q| {
            let p = |k: usize| Vec3::new(q[k].0[0], q[k].0[1], q[k].0[2]);
            CcdQuery {
                x0: [p(0), p(1), p(2), p(3)],
                x1: [p(4), p(5), p(6), p(7)],
                truth: q[0].1,
            }
        })
        .collect())
}

/// Reads one query file.
pub fn read_queries(path: &Path) -> Result<Vec<CcdQuery>> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_queries(&path.display().to_string(), &text)
}

/// `num / den` as the exactly equal `f64`, or an error message when it is not representable.
fn exact_ratio(num: &str, den: &str) -> std::result::Result<f64, String> {
    let n: i64 = num.parse().map_err(|_| format!("bad numerator '{num}'"))?;
    if n.unsigned_abs() > (1u64 << 53) {
        return Err(format!("numerator '{num}' does not fit in 53 bits"));
    }
    // A power of two parses exactly (correct rounding of an exactly representable value).
    let d: f64 = den
        .parse()
        .map_err(|_| format!("bad denominator '{den}'"))?;
    let is_power_of_two = d.is_finite() && d >= 1.0 && (d.to_bits() & ((1u64 << 52) - 1)) == 0;
    if !is_power_of_two || !den.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("denominator '{den}' is not a power of two"));
    }
    Ok(n as f64 / d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_exact_values() {
        let row = "-8388609,8388608,1,1,-1,1,0\n";
        let text = row.repeat(7) + "3,5192296858534827628530496329220096,1,2,0,1,0\n";
        let q = parse_queries("t", &text).unwrap();
        assert_eq!(q.len(), 1);
        assert_eq!(q[0].x0[0], Vec3::new(-1.0 - 2f64.powi(-23), 1.0, -1.0));
        assert_eq!(q[0].x1[3], Vec3::new(3.0 * 2f64.powi(-112), 0.5, 0.0));
        assert!(!q[0].truth);
    }

    #[test]
    fn rejects_bad_input() {
        assert!(parse_queries("t", "1,3,1,1,1,1,0\n").is_err()); // not a power of two
        assert!(parse_queries("t", "1,1,1,1,1,1,0\n").is_err()); // not 8 rows
        assert!(parse_queries("t", "1,1,1,1,1,1\n").is_err()); // 6 fields
        assert!(parse_queries("t", "1,1,1,1,1,1,2\n").is_err()); // bad truth
        assert!(parse_queries("t", "x,1,1,1,1,1,0\n").is_err());
    }
}
