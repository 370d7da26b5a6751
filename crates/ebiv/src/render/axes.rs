//! Axes for figures: "nice" tick positions, number labels, a framed plot area with ticks and
//! axis labels, a vertical colour bar, and the frame shared by figures of sensor images.

use super::draw::{fill_rect, outline, Colour, Rect};
use super::font::{draw_text, draw_text_vertical, text_height, text_width, Align};
use crate::error::{Error, Result};
use crate::units::format_us;
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
        let (lo, hi) = order(self.x_range);
        let target = ((self.area.x1 - self.area.x0) as i64 / 90).clamp(2, 10) as usize;
        let (ticks, step) = nice_ticks(lo, hi, target);
        let ticks: Vec<(f64, String)> = ticks
            .into_iter()
            .map(|t| (t, format_value(t, step)))
            .collect();
        self.draw_with_x_ticks(img, &ticks, x_label, y_label, scale);
    }

    /// [`Axes::draw`] with the x ticks given as (data x, label): categories, or values on a
    /// logarithmic axis.
    pub fn draw_with_x_ticks(
        &self,
        img: &mut RgbImage,
        x_ticks: &[(f64, String)],
        x_label: &str,
        y_label: &str,
        scale: u32,
    ) {
        let (x0, y0) = (self.area.x0 as i64, self.area.y0 as i64);
        let (x1, y1) = (self.area.x1 as i64, self.area.y1 as i64);
        outline(img, x0 - 1, y0 - 1, x1, y1, INK);
        let th = text_height(scale) as i64;
        for (t, label) in x_ticks {
            let x = self.px(*t).floor() as i64;
            fill_rect(img, Rect::new(x as f64, y1 as f64, 1.0, TICK as f64), INK);
            draw_text(img, x, y1 + TICK + GAP, label, scale, INK, Align::Centre);
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

const BAR_WIDTH: u32 = 22;

/// A vertical colour bar: what the colours of a figure mean, with numbers.
#[derive(Debug, Clone)]
pub struct ColourBar {
    /// Colour at `s` ∈ [0, 1], bottom to top.
    pub colours: fn(f32) -> Colour,
    /// Labelled ticks: position `s` ∈ [0, 1] (bottom to top) and label.
    pub ticks: Vec<(f64, String)>,
    /// What the colours show, with units, drawn rotated alongside.
    pub title: String,
}

impl ColourBar {
    /// A bar over the linear `range` (bottom to top), labelled at its minimum, middle and
    /// maximum.
    pub fn linear(range: (f64, f64), title: impl Into<String>, colours: fn(f32) -> Colour) -> Self {
        let (lo, hi) = range;
        let res = (hi - lo).abs() / 100.0;
        let ticks = [0.0, 0.5, 1.0]
            .into_iter()
            .map(|s| (s, format_value(lo + s * (hi - lo), res)))
            .collect();
        ColourBar {
            colours,
            ticks,
            title: title.into(),
        }
    }

    /// Width in output pixels including tick labels and title.
    pub fn width(&self, scale: u32) -> u32 {
        let widest = self
            .ticks
            .iter()
            .map(|(_, s)| text_width(s, scale))
            .max()
            .unwrap_or(0);
        BAR_WIDTH + (TICK + GAP) as u32 + widest + GAP as u32 + text_height(scale)
    }

    /// Draw the bar with its top-left corner at `(x, y)` and height `h`.
    pub fn draw(&self, img: &mut RgbImage, x: i64, y: i64, h: i64, scale: u32) {
        let h = h.max(2);
        let w = BAR_WIDTH as i64;
        for row in 0..h {
            let s = 1.0 - row as f32 / (h - 1) as f32;
            fill_rect(
                img,
                Rect::new(x as f64, (y + row) as f64, w as f64, 1.0),
                (self.colours)(s),
            );
        }
        outline(img, x - 1, y - 1, x + w, y + h, INK);
        let mut widest = 0;
        for (s, label) in &self.ticks {
            let ty = y + ((1.0 - s.clamp(0.0, 1.0)) * (h - 1) as f64).round() as i64;
            fill_rect(
                img,
                Rect::new((x + w) as f64, ty as f64, TICK as f64, 1.0),
                INK,
            );
            let top = ty - (7 * scale as i64) / 2;
            draw_text(img, x + w + TICK + GAP, top, label, scale, INK, Align::Left);
            widest = widest.max(text_width(label, scale) as i64);
        }
        let tx = x + w + TICK + GAP + widest + GAP;
        draw_text_vertical(img, tx, y + h / 2, &self.title, scale, INK);
    }
}

/// Margin around figures, output pixels.
pub const PAD: i64 = 14;
/// Text scale of figure labels (font pixels are `TEXT × TEXT` blocks).
pub const TEXT: u32 = 2;
/// Background colour of figures.
pub const PAPER: Colour = [255, 255, 255];

/// The frame of a figure showing an image of the sensor: a plot area of a given size in
/// output pixels spanning image pixels `[−0.5, w − 0.5] × [−0.5, h − 0.5]` with axes in image
/// pixels (y down, as in the image), an optional title above, an optional colour bar to the
/// right and lines of notes below the x-axis label. Event images, rate maps and vector maps
/// share it, so their axes, bars and captions look alike.
#[derive(Debug, Clone)]
pub struct ImageFigure {
    /// Maps image pixels to output pixels in the plot area.
    pub axes: Axes,
    title: Option<String>,
    bar: Option<ColourBar>,
    notes: Vec<String>,
}

impl ImageFigure {
    /// Lay out a figure of an image `extent` = (width, height) px drawn `plot` = (width,
    /// height) output px large, and return it with a blank canvas of the right size.
    /// An empty note reserves a line for the caller to draw in (see [`ImageFigure::note_y`]).
    /// The canvas is widened when the title or a note is wider than the figure.
    pub fn new(
        extent: (f64, f64),
        plot: (f64, f64),
        title: Option<String>,
        bar: Option<ColourBar>,
        notes: Vec<String>,
    ) -> (Self, RgbImage) {
        let (pw, ph) = (plot.0.round().max(1.0), plot.1.round().max(1.0));
        let th = text_height(TEXT) as i64;
        let probe = Axes {
            area: Rect::new(0.0, 0.0, pw, ph),
            x_range: (-0.5, extent.0 - 0.5),
            y_range: (-0.5, extent.1 - 0.5),
        };
        let left = PAD + th + GAP + probe.y_label_width(TEXT) as i64 + GAP + TICK;
        let top = PAD + title.as_ref().map_or(0, |_| th + 2 * GAP);
        let below_notes: i64 = (0..notes.len())
            .map(|i| if i == 0 { 2 * GAP + th } else { GAP + th })
            .sum();
        let bottom = TICK + GAP + th + GAP + th + below_notes + PAD;
        let right = PAD
            + match &bar {
                Some(b) => 4 * GAP + b.width(TEXT) as i64,
                None => 3 * GAP,
            };
        let texts = title.iter().chain(&notes);
        let text_w = texts.map(|t| text_width(t, TEXT) as i64).max().unwrap_or(0);
        let width = (left + pw as i64 + right).max(left + text_w + PAD);
        let canvas = RgbImage::from_pixel(
            width as u32,
            (top + ph as i64 + bottom) as u32,
            PAPER.into(),
        );
        let axes = Axes {
            area: Rect::new(left as f64, top as f64, pw, ph),
            ..probe
        };
        let figure = ImageFigure {
            axes,
            title,
            bar,
            notes,
        };
        (figure, canvas)
    }

    /// Top of note line `i` (output pixels).
    pub fn note_y(&self, i: usize) -> i64 {
        let th = text_height(TEXT) as i64;
        self.axes.area.y1 as i64 + TICK + GAP + th + GAP + th + 2 * GAP + i as i64 * (th + GAP)
    }

    /// Draw the frame with ticks and labels, the title, the colour bar and the notes; after
    /// the plot area is painted, so that they stay on top.
    pub fn decorate(&self, img: &mut RgbImage) {
        self.axes.draw(img, "x [px]", "y [px]", TEXT);
        let a = self.axes.area;
        let (x0, x1) = (a.x0 as i64, a.x1 as i64);
        if let Some(title) = &self.title {
            let centre = ((x0 + x1) / 2).max(x0 + text_width(title, TEXT) as i64 / 2);
            draw_text(img, centre, PAD, title, TEXT, INK, Align::Centre);
        }
        if let Some(bar) = &self.bar {
            let h = (a.y1 - a.y0) as i64;
            bar.draw(img, x1 + 4 * GAP, a.y0 as i64, h, TEXT);
        }
        for (i, note) in self.notes.iter().enumerate() {
            draw_text(img, x0, self.note_y(i), note, TEXT, INK, Align::Left);
        }
    }

    /// A finished figure of `image` enlarged `k` times (nearest neighbour, so sensor pixels
    /// stay visible as pixels).
    pub fn of_image(
        image: &RgbImage,
        k: u32,
        title: Option<String>,
        bar: Option<ColourBar>,
        notes: Vec<String>,
    ) -> RgbImage {
        let k = k.max(1);
        let (w, h) = image.dimensions();
        let extent = (w as f64, h as f64);
        let plot = ((w * k) as f64, (h * k) as f64);
        let (figure, mut canvas) = ImageFigure::new(extent, plot, title, bar, notes);
        let (x0, y0) = (figure.axes.area.x0 as i64, figure.axes.area.y0 as i64);
        let big = super::upscale(image, k);
        image::imageops::replace(&mut canvas, &big, x0, y0);
        figure.decorate(&mut canvas);
        canvas
    }
}

/// Largest side of a figure of a sensor image, output pixels.
pub const MAX_FIGURE_SIDE: u32 = 16_384;
/// Largest enlargement of a sensor image.
pub const MAX_PIXEL_SCALE: u32 = 16;

/// How a figure of a sensor image (event image, event-rate map) is drawn.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImageFigureStyle {
    /// Title above the plot.
    pub title: Option<String>,
    /// Output pixels per sensor pixel, 1 to [`MAX_PIXEL_SCALE`]; `None`: so that the image
    /// is at least 640 px wide (at most 8).
    pub pixel_scale: Option<u32>,
    /// Time subtracted from the times in the caption, µs (e.g. the first event's, so that
    /// times read as in the command line); 0 shows camera time.
    pub time_origin_us: i64,
}

impl ImageFigureStyle {
    /// The enlargement for a sensor of `width × height` px; an error naming `scale` for 0,
    /// more than [`MAX_PIXEL_SCALE`], or a figure over [`MAX_FIGURE_SIDE`] px.
    pub fn scale_for(&self, width: u32, height: u32) -> Result<u32> {
        let Some(k) = self.pixel_scale else {
            return Ok(640u32.div_ceil(width.max(1)).clamp(1, 8));
        };
        if !(1..=MAX_PIXEL_SCALE).contains(&k) {
            return Err(Error::parameter(
                "scale",
                format!("{k}: the enlargement must be a whole number from 1 to {MAX_PIXEL_SCALE}"),
            ));
        }
        let side = width.max(height) as u64 * k as u64;
        if side > MAX_FIGURE_SIDE as u64 {
            return Err(Error::parameter(
                "scale",
                format!(
                    "{k} makes the {width}x{height} px image {side} px large; at most {MAX_FIGURE_SIDE}"
                ),
            ));
        }
        Ok(k)
    }

    /// `t` relative to the time origin, for captions ("25.000 ms").
    pub fn time(&self, t: i64) -> String {
        format_us(t.saturating_sub(self.time_origin_us))
    }
}

/// Helpers for tests that read figures back.
#[cfg(test)]
pub(crate) mod probe {
    use super::INK;
    use image::RgbImage;

    /// The plot frame (left, top, right, bottom): the first two rows with about the most
    /// ink, and the first two columns inked over the whole height between them.
    pub fn plot_frame(img: &RgbImage) -> (u32, u32, u32, u32) {
        let ink = |x: u32, y: u32| img.get_pixel(x, y).0 == INK;
        let rows: Vec<usize> = (0..img.height())
            .map(|y| (0..img.width()).filter(|&x| ink(x, y)).count())
            .collect();
        let m = *rows.iter().max().unwrap();
        let mut full = (0..img.height()).filter(|&y| rows[y as usize] * 10 >= m * 9);
        let (top, bottom) = (full.next().unwrap(), full.next().unwrap());
        let mut sides = (0..img.width()).filter(|&x| (top..=bottom).all(|y| ink(x, y)));
        (sides.next().unwrap(), top, sides.next().unwrap(), bottom)
    }

    /// Whether two colours differ by less than 12 in every channel.
    pub fn near(a: [u8; 3], b: [u8; 3]) -> bool {
        (0..3).all(|k| a[k].abs_diff(b[k]) < 12)
    }

    /// The first column right of the plot frame with `top_colour` in the first row inside
    /// the frame and `bottom_colour` in the last: a colour bar as high as the plot.
    pub fn colour_bar_column(
        img: &RgbImage,
        top_colour: [u8; 3],
        bottom_colour: [u8; 3],
    ) -> Option<u32> {
        let (_, top, right, bottom) = plot_frame(img);
        (right + 1..img.width()).find(|&x| {
            near(img.get_pixel(x, top + 1).0, top_colour)
                && near(img.get_pixel(x, bottom - 1).0, bottom_colour)
        })
    }

    /// Ink pixels in the rectangle `[x0, x1) × [y0, y1)` (clipped to the image).
    pub fn ink_in(img: &RgbImage, x0: u32, y0: u32, x1: u32, y1: u32) -> usize {
        let (x1, y1) = (x1.min(img.width()), y1.min(img.height()));
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0 == INK)
            .count()
    }
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

    #[test]
    fn image_figures_have_axes_bar_title_and_notes() {
        use super::probe::{colour_bar_column, ink_in, plot_frame};
        let image = RgbImage::from_pixel(100, 40, [200, 0, 0].into());
        let bar = ColourBar::linear((0.0, 8.0), "v", super::super::inferno);
        assert_eq!(
            bar.ticks.iter().map(|t| t.1.as_str()).collect::<Vec<_>>(),
            ["0", "4", "8"]
        );
        let note = "a note".to_string();
        let img = ImageFigure::of_image(&image, 3, Some("title".into()), Some(bar), vec![note]);
        let (l, t, r, b) = plot_frame(&img);
        // The plot shows the image 3 times enlarged, inside a 1 px frame.
        assert_eq!((r - l - 1, b - t - 1), (300, 120));
        assert_eq!(img.get_pixel(l + 1, t + 1).0, [200, 0, 0]);
        assert_eq!(img.get_pixel(r - 1, b - 1).0, [200, 0, 0]);
        // Tick labels left of and below the frame, the title above, the note at the bottom.
        assert!(ink_in(&img, 0, t, l - TICK as u32, b) > 50, "y tick labels");
        assert!(
            ink_in(&img, l, b + 1 + TICK as u32, r, b + 30) > 50,
            "x tick labels"
        );
        assert!(ink_in(&img, l, 0, r, t) > 20, "title");
        let note_top = b + 1 + (TICK + GAP + 2 * text_height(TEXT) as i64 + 3 * GAP) as u32;
        assert!(
            ink_in(&img, l, note_top, img.width(), img.height()) > 100,
            "note"
        );
        let inferno = super::super::inferno;
        assert!(colour_bar_column(&img, inferno(1.0), inferno(0.0)).is_some());
        // A note wider than the figure widens it.
        let long = "a note much wider than the plot and its margins".to_string();
        let img = ImageFigure::of_image(&image, 3, None, None, vec![long.clone()]);
        assert!(img.width() as i64 >= text_width(&long, TEXT) as i64 + 2 * PAD);
    }
}
