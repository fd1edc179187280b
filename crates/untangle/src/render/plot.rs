//! Per-step charts like Cha & Ko 2022, Fig. 15: a red curve (remaining red vertices, left axis,
//! linear) over grey bars (time per step, right axis, log scale), with axes, ticks, tick labels,
//! axis labels and a title.

use super::canvas::{Canvas, Rgb};
use super::font;

/// What to plot.
#[derive(Clone, Debug)]
pub struct StepChart<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Label of the x axis (steps).
    pub x_label: &'a str,
    /// Label of the left axis (the curve).
    pub y_label: &'a str,
    /// The curve: one value per step (step `k` at x = `k`).
    pub curve: &'a [f64],
    /// Optional bars on a log-scale right axis: its label and one positive value per step
    /// (non-positive values draw no bar).
    pub bars: Option<(&'a str, &'a [f64])>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// Curve colour.
pub const CURVE: Rgb = [200, 20, 20];
/// Bar colour.
pub const BAR: Rgb = [160, 170, 200];
/// Axis and text colour.
pub const INK: Rgb = [20, 20, 20];
/// Grid line colour.
pub const GRID: Rgb = [228, 228, 228];
/// Background colour.
pub const PAPER: Rgb = [255, 255, 255];

/// "Nice" tick values covering `[lo, hi]`: multiples of 1, 2 or 5 times a power of ten, from
/// the largest multiple `<= lo` to the smallest `>= hi`, at most about `max_ticks` of them.
pub fn nice_ticks(lo: f64, hi: f64, max_ticks: usize) -> Vec<f64> {
    let (lo, hi) = if hi > lo { (lo, hi) } else { (lo, lo + 1.0) };
    let raw = (hi - lo) / max_ticks.max(2) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).floor() as i64;
    let last = (hi / step).ceil() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// A tick label: as few decimals as the tick spacing needs.
fn label(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// The plot rectangle `[x0, x1] x [y0, y1]` (pixels) of a chart.
pub fn plot_area(c: &StepChart) -> [i64; 4] {
    let right = if c.bars.is_some() { 80 } else { 24 };
    [80, 40, c.width as i64 - right, c.height as i64 - 56]
}

/// Draws the chart.
pub fn step_chart(c: &StepChart) -> Canvas {
    let mut img = Canvas::new(c.width, c.height, PAPER);
    let [x0, y0, x1, y1] = plot_area(c);
    if x1 <= x0 + 10 || y1 <= y0 + 10 {
        return img;
    }
    let n = c.curve.len().max(c.bars.map_or(0, |b| b.1.len()));
    let x_hi = (n.max(2) - 1) as f64;
    let x_ticks = nice_ticks(0.0, x_hi, 8);
    let x_max = *x_ticks.last().unwrap_or(&x_hi);
    let sx = |x: f64| x0 as f64 + (x1 - x0) as f64 * x / x_max.max(1e-12);
    let y_hi = c
        .curve
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let y_ticks = nice_ticks(0.0, y_hi.max(1.0), 6);
    let y_max = *y_ticks.last().unwrap_or(&1.0);
    let sy = |y: f64| y1 as f64 - (y1 - y0) as f64 * y / y_max.max(1e-12);
    // Grid.
    for &t in &y_ticks {
        let y = sy(t).round() as i64;
        img.fill_rect(x0, y, x1 + 1, y + 1, GRID);
    }
    // Bars (log scale, right axis).
    if let Some((blabel, bars)) = c.bars {
        let pos: Vec<f64> = bars
            .iter()
            .copied()
            .filter(|v| *v > 0.0 && v.is_finite())
            .collect();
        let lo = pos.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = pos.iter().copied().fold(0.0f64, f64::max);
        let (d0, d1) = if pos.is_empty() {
            (0, 1)
        } else {
            let d0 = lo.log10().floor() as i32;
            (d0, (hi.log10().ceil() as i32).max(d0 + 1))
        };
        let ly = |v: f64| {
            let f = (v.log10() - d0 as f64) / (d1 - d0) as f64;
            y1 as f64 - (y1 - y0) as f64 * f
        };
        let half = ((sx(1.0) - sx(0.0)) * 0.4).max(0.5);
        for (k, &v) in bars.iter().enumerate() {
            if v > 0.0 && v.is_finite() {
                let xc = sx(k as f64);
                let top = ly(v).round() as i64;
                img.fill_rect(
                    (xc - half).round() as i64,
                    top,
                    (xc + half).round() as i64 + 1,
                    y1,
                    BAR,
                );
            }
        }
        img.fill_rect(x1, y0, x1 + 1, y1 + 1, INK);
        for d in d0..=d1 {
            let y = ly(10f64.powi(d)).round() as i64;
            img.fill_rect(x1, y, x1 + 6, y + 1, INK);
            let s = label(10f64.powi(d), 10f64.powi(d.min(0)));
            img.text(x1 + 9, y - 6, &s, 2, INK);
        }
        let w = font::text_width(blabel, 2) as i64;
        img.text_vertical(c.width as i64 - 20, (y0 + y1) / 2 + w / 2, blabel, 2, INK);
    }
    // Axes, ticks and labels.
    img.fill_rect(x0, y0, x0 + 1, y1 + 1, INK);
    img.fill_rect(x0, y1, x1 + 1, y1 + 1, INK);
    let y_step = if y_ticks.len() > 1 {
        y_ticks[1] - y_ticks[0]
    } else {
        1.0
    };
    for &t in &y_ticks {
        let y = sy(t).round() as i64;
        img.fill_rect(x0 - 6, y, x0, y + 1, INK);
        let s = label(t, y_step);
        let w = font::text_width(&s, 2) as i64;
        img.text(x0 - 10 - w, y - 6, &s, 2, INK);
    }
    let x_step = if x_ticks.len() > 1 {
        x_ticks[1] - x_ticks[0]
    } else {
        1.0
    };
    for &t in &x_ticks {
        let x = sx(t).round() as i64;
        img.fill_rect(x, y1, x + 1, y1 + 6, INK);
        let s = label(t, x_step);
        let w = font::text_width(&s, 2) as i64;
        img.text(x - w / 2, y1 + 10, &s, 2, INK);
    }
    let w = font::text_width(c.x_label, 2) as i64;
    img.text(
        (x0 + x1) / 2 - w / 2,
        c.height as i64 - 20,
        c.x_label,
        2,
        INK,
    );
    let w = font::text_width(c.y_label, 2) as i64;
    img.text_vertical(6, (y0 + y1) / 2 + w / 2, c.y_label, 2, INK);
    let w = font::text_width(c.title, 2) as i64;
    img.text(c.width as i64 / 2 - w / 2, 12, c.title, 2, INK);
    // The curve on top.
    let pts: Vec<(f64, f64)> = c
        .curve
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .map(|(k, &v)| (sx(k as f64), sy(v)))
        .collect();
    for w in pts.windows(2) {
        img.line(w[0].0, w[0].1, w[1].0, w[1].1, 3, CURVE);
    }
    if let [(x, y)] = pts[..] {
        img.fill_rect(
            x as i64 - 2,
            y as i64 - 2,
            x as i64 + 3,
            y as i64 + 3,
            CURVE,
        );
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn ticks_are_nice_and_cover_the_range(lo in -1e4f64..1e4, span in 1e-3f64..1e5, m in 3usize..12) {
            let hi = lo + span;
            let t = nice_ticks(lo, hi, m);
            prop_assert!(t.len() >= 2);
            prop_assert!(t[0] <= lo && *t.last().unwrap() >= hi);
            let step = t[1] - t[0];
            let mag = 10f64.powf(step.log10().floor());
            let mant = step / mag;
            prop_assert!([1.0, 2.0, 5.0, 10.0].iter().any(|x| (mant - x).abs() < 1e-6), "{step}");
            // At most about m intervals (plus the two partial ends).
            prop_assert!(t.len() <= 2 * m + 3, "{t:?}");
            for w in t.windows(2) {
                prop_assert!(((w[1] - w[0]) - step).abs() <= 1e-9 * step.max(1.0) * 1e3);
            }
        }
    }

    #[test]
    fn labels() {
        assert_eq!(label(20.0, 10.0), "20");
        assert_eq!(label(0.5, 0.1), "0.5");
        assert_eq!(label(-0.0, 0.1), "0.0");
        assert_eq!(label(0.25, 0.05), "0.25");
    }

    #[test]
    fn chart_draws_axes_bars_and_the_curve_where_the_data_is() {
        let curve: Vec<f64> = (0..40).map(|k| (60.0 - 1.5 * k as f64).max(0.0)).collect();
        let bars: Vec<f64> = (0..40).map(|k| 1.0 + k as f64 * 0.3).collect();
        let c = StepChart {
            title: "Red vertices per step",
            x_label: "step",
            y_label: "red vertices",
            curve: &curve,
            bars: Some(("ms per step", &bars)),
            width: 640,
            height: 400,
        };
        let img = step_chart(&c);
        assert_eq!((img.width, img.height), (640, 400));
        assert_eq!(img.rgb.len(), 640 * 400 * 3);
        let [x0, y0, x1, y1] = plot_area(&c);
        // Axes: the left and bottom lines are ink along their whole length (or the curve,
        // drawn on top, where it meets them).
        let axis = |p: Option<Rgb>| p == Some(INK) || p == Some(CURVE);
        assert!((y0..=y1).all(|y| axis(img.get(x0, y))));
        assert!((x0..=x1).all(|x| axis(img.get(x, y1))));
        assert!((y0 + 10..=y1).all(|y| img.get(x0, y) == Some(INK)));
        assert!(img.count(CURVE) > 500 && img.count(BAR) > 1000);
        // The curve starts at (step 0, 60) and reaches 0 at step 40: its leftmost red pixel
        // is near the y-axis at the height of 60 on a 0..60 axis (the top of the plot).
        let reds: Vec<(i64, i64)> = (0..img.height as i64)
            .flat_map(|y| (0..img.width as i64).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get(x, y) == Some(CURVE))
            .collect();
        let left = reds.iter().min_by_key(|p| (p.0, p.1)).unwrap();
        assert!((left.0 - x0).abs() <= 2, "{left:?}");
        assert!((left.1 - y0).abs() <= 2, "{left:?}");
        // Never outside the plot area (apart from the brush width).
        assert!(reds
            .iter()
            .all(|&(x, y)| x >= x0 - 2 && x <= x1 + 2 && y >= y0 - 2 && y <= y1 + 2));
        // Text was drawn: ink outside the plot area (labels, ticks).
        let ink_outside = (0..img.height as i64)
            .flat_map(|y| (0..img.width as i64).map(move |x| (x, y)))
            .filter(|&(x, y)| (x < x0 - 6 || y > y1 + 6) && img.get(x, y) == Some(INK))
            .count();
        assert!(ink_outside > 200);
        // Degenerate input still gives a picture of the right size.
        let e = step_chart(&StepChart {
            curve: &[],
            bars: None,
            ..c.clone()
        });
        assert_eq!((e.width, e.height), (640, 400));
        let one = step_chart(&StepChart {
            curve: &[3.0],
            bars: None,
            ..c
        });
        assert!(one.count(CURVE) > 0);
    }
}
