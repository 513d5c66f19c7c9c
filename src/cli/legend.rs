//! The heat map's legend: a colour bar across the bottom of the picture, labelled with the traversal steps
//! that its ends and middle stand for, drawn with a built-in 3 x 5 pixel font (no font files needed).

/// Glyph rows, three bits each (bit 2 = left column), for the characters the legend writes.
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 2, 2],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        's' => [0, 7, 4, 3, 6],
        't' => [2, 7, 2, 2, 3],
        'e' => [0, 7, 7, 4, 7],
        'p' => [0, 7, 5, 7, 4],
        ' ' => [0; 5],
        _ => return None,
    })
}

/// An RGB8 image being drawn on.
pub struct Canvas<'a> {
    /// Pixels, row after row, 3 bytes each.
    pub pixels: &'a mut [u8],
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

impl Canvas<'_> {
    fn set(&mut self, x: usize, y: usize, color: [u8; 3]) {
        if x < self.width && y < self.height {
            let at = 3 * (y * self.width + x);
            self.pixels[at..at + 3].copy_from_slice(&color);
        }
    }

    fn fill(&mut self, x0: usize, y0: usize, w: usize, h: usize, color: [u8; 3]) {
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                self.set(x, y, color);
            }
        }
    }

    /// Writes `text` with its top-left corner at `(x, y)`, each font pixel `scale` pixels wide.
    fn text(&mut self, text: &str, x: usize, y: usize, scale: usize) {
        for (i, c) in text.chars().enumerate() {
            let rows = glyph(c).unwrap_or([7; 5]);
            for (r, bits) in rows.iter().enumerate() {
                for column in 0..3 {
                    if bits & (4 >> column) != 0 {
                        let px = x + (4 * i + column) * scale;
                        self.fill(px, y + r * scale, scale, scale, [255, 255, 255]);
                    }
                }
            }
        }
    }
}

/// Width in pixels of `text` at `scale`.
fn text_width(text: &str, scale: usize) -> usize {
    (4 * text.chars().count()).saturating_sub(1) * scale
}

/// Draws the legend for a heat map whose colours run from 0 to `most` steps through `ramp` (0..1 -> RGB in
/// 0..1) over the bottom of the canvas. Returns false (drawing nothing) when the picture is too small for it.
pub fn draw_heat_legend(canvas: &mut Canvas<'_>, most: u32, ramp: impl Fn(f32) -> [f32; 3]) -> bool {
    let scale = if canvas.width >= 600 { 2 } else { 1 };
    let band = 22 * scale;
    if canvas.width < 120 || canvas.height < 3 * band {
        return false;
    }
    let top = canvas.height - band;
    canvas.fill(0, top, canvas.width, band, [20, 20, 24]);
    let (left, right) = (8 * scale, canvas.width - 8 * scale);
    let bar_top = top + 3 * scale;
    for x in left..right {
        let t = (x - left) as f32 / (right - left - 1).max(1) as f32;
        let color = ramp(t).map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
        canvas.fill(x, bar_top, 1, 7 * scale, color);
    }
    let label_top = bar_top + 10 * scale;
    let half = most.div_ceil(2).to_string();
    let end = format!("{most} steps");
    canvas.text("0", left, label_top, scale);
    canvas.text(&half, (left + right) / 2 - text_width(&half, scale) / 2, label_top, scale);
    canvas.text(&end, right - text_width(&end, scale), label_top, scale);
    true
}
