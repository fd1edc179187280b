//! An RGB image in memory with the 2D drawing plots need: pixels, filled rectangles, lines and
//! bitmap text. Encoding to PNG is left to the caller (the CLI uses the `image` crate).

use super::font;

/// An 8-bit RGB colour.
pub type Rgb = [u8; 3];

/// A `width x height` RGB image, rows top to bottom, 3 bytes per pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel bytes, row-major from the top-left, `[r, g, b]` per pixel.
    pub rgb: Vec<u8>,
}

impl Canvas {
    /// A canvas filled with `background`.
    pub fn new(width: u32, height: u32, background: Rgb) -> Canvas {
        let mut rgb = Vec::with_capacity(width as usize * height as usize * 3);
        for _ in 0..width as usize * height as usize {
            rgb.extend_from_slice(&background);
        }
        Canvas { width, height, rgb }
    }

    fn index(&self, x: i64, y: i64) -> Option<usize> {
        (x >= 0 && y >= 0 && x < self.width as i64 && y < self.height as i64)
            .then(|| (y as usize * self.width as usize + x as usize) * 3)
    }

    /// The colour at (`x`, `y`) (`None` outside).
    pub fn get(&self, x: i64, y: i64) -> Option<Rgb> {
        self.index(x, y)
            .map(|i| [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }

    /// Sets (`x`, `y`) to `c`; points outside are ignored.
    pub fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if let Some(i) = self.index(x, y) {
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    /// Fills the rectangle `[x0, x1) x [y0, y1)` (clipped).
    pub fn fill_rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb) {
        for y in y0.max(0)..y1.min(self.height as i64) {
            for x in x0.max(0)..x1.min(self.width as i64) {
                self.set(x, y, c);
            }
        }
    }

    /// A line from (`x0`, `y0`) to (`x1`, `y1`), both ends included, `width` pixels thick
    /// (square brush centred on the line).
    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, width: u32, c: Rgb) {
        let n = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as usize;
        let w = width.max(1) as i64;
        let lo = -(w - 1) / 2;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let x = (x0 + (x1 - x0) * t).round() as i64;
            let y = (y0 + (y1 - y0) * t).round() as i64;
            for dy in lo..lo + w {
                for dx in lo..lo + w {
                    self.set(x + dx, y + dy, c);
                }
            }
        }
    }

    /// Draws `text` with its top-left corner at (`x`, `y`), each font pixel a `scale x scale`
    /// block.
    pub fn text(&mut self, x: i64, y: i64, text: &str, scale: u32, c: Rgb) {
        let s = scale.max(1) as i64;
        for (k, ch) in text.chars().enumerate() {
            let gx = x + k as i64 * font::ADVANCE as i64 * s;
            for fy in 0..font::GLYPH_H {
                for fx in 0..font::GLYPH_W {
                    if font::ink(ch, fx, fy) {
                        let px = gx + fx as i64 * s;
                        let py = y + fy as i64 * s;
                        self.fill_rect(px, py, px + s, py + s, c);
                    }
                }
            }
        }
    }

    /// Draws `text` turned 90 degrees counter-clockwise (reading bottom to top), its glyphs'
    /// top towards the left; (`x`, `y`) is the bottom-left corner of the turned text.
    pub fn text_vertical(&mut self, x: i64, y: i64, text: &str, scale: u32, c: Rgb) {
        let s = scale.max(1) as i64;
        for (k, ch) in text.chars().enumerate() {
            let gy = y - k as i64 * font::ADVANCE as i64 * s;
            for fy in 0..font::GLYPH_H {
                for fx in 0..font::GLYPH_W {
                    if font::ink(ch, fx, fy) {
                        let px = x + fy as i64 * s;
                        let py = gy - (fx as i64 + 1) * s;
                        self.fill_rect(px, py, px + s, py + s, c);
                    }
                }
            }
        }
    }

    /// Number of pixels whose colour is `c`.
    pub fn count(&self, c: Rgb) -> usize {
        self.rgb.chunks_exact(3).filter(|p| **p == c).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_rects_lines_and_text() {
        let mut c = Canvas::new(20, 10, [255; 3]);
        assert_eq!(c.rgb.len(), 600);
        c.set(-1, 3, [0; 3]);
        c.set(20, 3, [0; 3]);
        assert_eq!(c.count([0; 3]), 0);
        c.fill_rect(2, 3, 5, 5, [1, 2, 3]);
        assert_eq!(c.count([1, 2, 3]), 6);
        assert_eq!(c.get(4, 4), Some([1, 2, 3]));
        assert_eq!(c.get(5, 4), Some([255; 3]));
        // A horizontal line covers exactly its span.
        let mut c = Canvas::new(20, 10, [255; 3]);
        c.line(3.0, 2.0, 12.0, 2.0, 1, [0; 3]);
        assert_eq!(c.count([0; 3]), 10);
        assert!((3..=12).all(|x| c.get(x, 2) == Some([0; 3])));
        // Text: the ink of "1" at scale 2 is its glyph's ink count times 4.
        let mut c = Canvas::new(20, 20, [255; 3]);
        c.text(1, 1, "1", 2, [0; 3]);
        let ink: usize = font::glyph('1')
            .unwrap()
            .iter()
            .map(|r| r.matches('#').count())
            .sum();
        assert_eq!(c.count([0; 3]), ink * 4);
        let mut v = Canvas::new(20, 20, [255; 3]);
        v.text_vertical(1, 18, "1", 2, [0; 3]);
        assert_eq!(v.count([0; 3]), ink * 4);
    }
}
