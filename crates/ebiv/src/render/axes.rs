//! Axes for figures: "nice" tick positions, number labels, a framed plot area with ticks and
//! axis labels, and a vertical colour bar.

use super::draw::{fill_rect, outline, Colour, Rect};
use super::font::{draw_text, draw_text_vertical, text_height, text_width, Align};
use image::RgbImage;

/// Ink colour of frames, ticks and labels.
pub const INK: Colour = [20, 20, 20];
/// Length of tick marks in output pixels.
pub const TICK: i64 = 6;
/// Gap between a tick mark and its label.
pub const GAP: i64 = 6;

/// Tick positions within `[lo, hi]` at a step of 1, 2 or 5 × 10ⁿ giving about `target`
/// intervals (Heckbert, "Nice numbers for graph labels", Graphics Gems, 1990), with the step.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> (Vec<f64>, f64) {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return (if lo.is_finite() { vec![lo] } else { vec![] }, 1.0);
    }
    let raw = (hi - lo) / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    let ticks = (first..=last.min(first + 1000))
        .map(|i| i as f64 * step)
        .map(|v| if v.abs() < step * 1e-9 { 0.0 } else { v })
        .collect();
    (ticks, step)
}

/// Format `v` for a label, with as many decimals as `resolution` needs, trailing zeros
/// trimmed; scientific notation for very large or very small values.
pub fn format_value(v: f64, resolution: f64) -> String {
    if !v.is_finite() {
        return if v.is_nan() {
            "nan".into()
        } else {
            "inf".into()
        };
    }
    let res = if resolution.is_finite() && resolution > 0.0 {
        resolution
    } else {
        v.abs().max(1e-12) * 1e-3
    };
    if v.abs() >= 1e5 || (res < 1e-4 && v != 0.0) {
        return format!("{v:.2e}");
    }
    let decimals = (-res.log10()).ceil().clamp(0.0, 6.0) as usize;
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    }
    if s == "-0" {
        s = "0".into();
    }
    s
}

/// Maps data coordinates to output pixels in a plot rectangle.
#[derive(Debug, Clone, Copy)]
pub struct Axes {
    /// Plot area in output pixels.
    pub area: Rect,
    /// Data x at the left and right edges.
    pub x_range: (f64, f64),
    /// Data y at the top and bottom edges (top < bottom for image coordinates, y down).
    pub y_range: (f64, f64),
}

impl Axes {
    /// Output x of data x.
    pub fn px(&self, x: f64) -> f64 {
        let (a, b) = self.x_range;
        self.area.x0 + (x - a) / (b - a) * (self.area.x1 - self.area.x0)
    }

    /// Output y of data y.
    pub fn py(&self, y: f64) -> f64 {
        let (a, b) = self.y_range;
        self.area.y0 + (y - a) / (b - a) * (self.area.y1 - self.area.y0)
    }

    /// Width of the widest y tick label, to size the left margin.
    pub fn y_label_width(&self, scale: u32) -> u32 {
        let (lo, hi) = order(self.y_range);
        let (ticks, step) = nice_ticks(lo, hi, y_target(self.area));
        ticks
            .iter()
            .map(|&t| text_width(&format_value(t, step), scale))
            .max()
            .unwrap_or(0)
    }

    /// Draw the frame, outward ticks with labels on the left and bottom, and the axis labels.
    pub fn draw(&self, img: &mut RgbImage, x_label: &str, y_label: &str, scale: u32) {
        let (x0, y0) = (self.area.x0 as i64, self.area.y0 as i64);
        let (x1, y1) = (self.area.x1 as i64, self.area.y1 as i64);
        outline(img, x0 - 1, y0 - 1, x1, y1, INK);
        let th = text_height(scale) as i64;
        let (lo, hi) = order(self.x_range);
        let target = ((x1 - x0) / 90).clamp(2, 10) as usize;
        let (ticks, step) = nice_ticks(lo, hi, target);
        for t in ticks {
            let x = self.px(t).floor() as i64;
            fill_rect(img, Rect::new(x as f64, y1 as f64, 1.0, TICK as f64), INK);
            let label = format_value(t, step);
            draw_text(img, x, y1 + TICK + GAP, &label, scale, INK, Align::Centre);
        }
        let label_y = y1 + TICK + GAP + th + GAP;
        draw_text(
            img,
            (x0 + x1) / 2,
            label_y,
            x_label,
            scale,
            INK,
            Align::Centre,
        );
        let (lo, hi) = order(self.y_range);
        let (ticks, step) = nice_ticks(lo, hi, y_target(self.area));
        let mut widest = 0;
        for t in ticks {
            let y = self.py(t).floor() as i64;
            fill_rect(
                img,
                Rect::new((x0 - 1 - TICK) as f64, y as f64, TICK as f64, 1.0),
                INK,
            );
            let label = format_value(t, step);
            widest = widest.max(text_width(&label, scale) as i64);
            // Digits occupy the 7 upper rows of the cell: centre those on the tick.
            let top = y - (7 * scale as i64) / 2;
            draw_text(
                img,
                x0 - 1 - TICK - GAP,
                top,
                &label,
                scale,
                INK,
                Align::Right,
            );
        }
        let lx = x0 - 1 - TICK - GAP - widest - GAP - th;
        draw_text_vertical(img, lx, (y0 + y1) / 2, y_label, scale, INK);
    }
}

fn order((a, b): (f64, f64)) -> (f64, f64) {
    (a.min(b), a.max(b))
}

fn y_target(area: Rect) -> usize {
    ((area.y1 - area.y0) / 50.0).clamp(2.0, 10.0) as usize
}

/// Width of a colour bar drawn by [`colour_bar`] including its labels.
pub fn colour_bar_width(range: (f64, f64), scale: u32) -> u32 {
    let labels = bar_labels(range);
    let widest = labels
        .iter()
        .map(|(_, s)| text_width(s, scale))
        .max()
        .unwrap_or(0);
    BAR_WIDTH + (TICK + GAP) as u32 + widest + GAP as u32 + text_height(scale)
}

const BAR_WIDTH: u32 = 22;

fn bar_labels((lo, hi): (f64, f64)) -> Vec<(f64, String)> {
    let res = (hi - lo).abs() / 100.0;
    [lo, 0.5 * (lo + hi), hi]
        .into_iter()
        .map(|v| (v, format_value(v, res)))
        .collect()
}

/// Draw a vertical colour bar with `colour_of(s)`, s ∈ [0, 1] bottom to top, in the
/// rectangle with top-left `(x, y)` and height `h`, labelled at the minimum, middle and
/// maximum of `range` and with `title` rotated alongside.
#[allow(clippy::too_many_arguments)]
pub fn colour_bar(
    img: &mut RgbImage,
    x: i64,
    y: i64,
    h: i64,
    range: (f64, f64),
    title: &str,
    scale: u32,
    colour_of: impl Fn(f32) -> Colour,
) {
    let h = h.max(2);
    let w = BAR_WIDTH as i64;
    for row in 0..h {
        let s = 1.0 - row as f32 / (h - 1) as f32;
        fill_rect(
            img,
            Rect::new(x as f64, (y + row) as f64, w as f64, 1.0),
            colour_of(s),
        );
    }
    outline(img, x - 1, y - 1, x + w, y + h, INK);
    let mut widest = 0;
    for (k, (_, label)) in bar_labels(range).into_iter().enumerate() {
        let ty = y + h - 1 - (k as i64 * (h - 1)) / 2;
        fill_rect(
            img,
            Rect::new((x + w) as f64, ty as f64, TICK as f64, 1.0),
            INK,
        );
        let top = ty - (7 * scale as i64) / 2;
        draw_text(
            img,
            x + w + TICK + GAP,
            top,
            &label,
            scale,
            INK,
            Align::Left,
        );
        widest = widest.max(text_width(&label, scale) as i64);
    }
    let tx = x + w + TICK + GAP + widest + GAP;
    draw_text_vertical(img, tx, y + h / 2, title, scale, INK);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_ticks_are_round_and_inside() {
        let (t, step) = nice_ticks(0.0, 1279.0, 7);
        assert_eq!(step, 200.0);
        assert_eq!(t.first(), Some(&0.0));
        assert_eq!(t.last(), Some(&1200.0));
        let (t, step) = nice_ticks(-0.37, 0.81, 5);
        assert_eq!(step, 0.5);
        assert_eq!(t, vec![0.0, 0.5]);
        assert!(nice_ticks(f64::NAN, 1.0, 5).0.is_empty());
        assert!(nice_ticks(0.0, 1e300, 5).0.len() <= 1001);
    }

    #[test]
    fn values_are_formatted_compactly() {
        assert_eq!(format_value(200.0, 100.0), "200");
        assert_eq!(format_value(0.5, 0.1), "0.5");
        assert_eq!(format_value(-0.0, 0.1), "0");
        assert_eq!(format_value(1.75, 0.035), "1.75");
        assert_eq!(format_value(3e7, 1e6), "3.00e7");
        assert_eq!(format_value(f64::INFINITY, 1.0), "inf");
    }
}
