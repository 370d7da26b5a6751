//! Line, scatter and bar charts on data axes, for report figures: a panel holds layers drawn
//! in order over one pair of axes, and panels are laid side by side.

use super::axes::{Axes, GAP, INK, PAD, PAPER, TEXT, TICK};
use super::draw::{blend, fill_rect, line, Colour, Rect};
use super::font::{draw_text, text_height, text_width, Align};
use image::RgbImage;

/// Blue of bars and first series.
pub const BLUE: Colour = [70, 118, 178];
/// Orange of second series.
pub const ORANGE: Colour = [221, 132, 52];
/// Red of reference lines.
pub const RED: Colour = [200, 40, 40];
/// Grey of guides.
pub const GREY: Colour = [140, 140, 140];

/// Something drawn on a panel's axes.
#[derive(Debug, Clone)]
pub enum Layer {
    /// A polyline through the points (NaN points break it), with dots on the points.
    Line {
        /// Data points.
        points: Vec<(f64, f64)>,
        /// Colour.
        colour: Colour,
        /// Dots at the points.
        markers: bool,
    },
    /// Translucent dots.
    Points {
        /// Data points.
        points: Vec<(f64, f64)>,
        /// Colour.
        colour: Colour,
    },
    /// Bars from 0 between consecutive `edges` with the given heights.
    Bars {
        /// Bin edges, one more than heights.
        edges: Vec<f64>,
        /// Bar heights.
        heights: Vec<f64>,
        /// Colour.
        colour: Colour,
    },
    /// A dashed straight segment between two data points.
    Dashed {
        /// Start.
        from: (f64, f64),
        /// End.
        to: (f64, f64),
        /// Colour.
        colour: Colour,
    },
}

/// One chart: axes with labels, layers, a heading and notes in the upper left corner.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Heading above the plot.
    pub heading: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// Data range of the x axis.
    pub x_range: (f64, f64),
    /// Data range of the y axis (bottom, top).
    pub y_range: (f64, f64),
    /// What is drawn, in order.
    pub layers: Vec<Layer>,
    /// Lines of text in the plot's upper left corner, with an optional colour swatch.
    pub notes: Vec<(Option<Colour>, String)>,
}

/// Plot area of a panel, output px.
const PANEL_W: f64 = 380.0;
const PANEL_H: f64 = 280.0;

/// A range covering the finite `values` with 5 % margins, or `fallback` without any.
pub fn data_range(values: impl Iterator<Item = f64>, fallback: (f64, f64)) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return fallback;
    }
    if hi - lo < 1e-12 * lo.abs().max(1.0) {
        let d = lo.abs().max(1.0) * 0.5;
        return (lo - d, hi + d);
    }
    let m = 0.05 * (hi - lo);
    (lo - m, hi + m)
}

fn sane(r: (f64, f64)) -> (f64, f64) {
    if r.0.is_finite() && r.1.is_finite() && r.1 > r.0 {
        r
    } else {
        (0.0, 1.0)
    }
}

/// Panels side by side under an optional title, with caption lines below.
pub fn figure(panels: &[Panel], title: Option<&str>, caption: &[String]) -> RgbImage {
    let th = text_height(TEXT) as i64;
    let axes_at = |p: &Panel, x: f64, y: f64| Axes {
        area: Rect::new(x, y, PANEL_W, PANEL_H),
        x_range: sane(p.x_range),
        y_range: {
            let (lo, hi) = sane(p.y_range);
            (hi, lo)
        },
    };
    let lefts: Vec<i64> = panels
        .iter()
        .map(|p| th + GAP + axes_at(p, 0.0, 0.0).y_label_width(TEXT) as i64 + GAP + TICK)
        .collect();
    let top = PAD + title.map_or(0, |_| th + 2 * GAP) + th + GAP;
    let below = TICK + GAP + th + GAP + th + 2 * GAP;
    let panels_w = PAD
        + lefts
            .iter()
            .map(|l| l + PANEL_W as i64 + 3 * PAD)
            .sum::<i64>();
    let caption_w = caption
        .iter()
        .map(|c| text_width(c, TEXT) as i64 + 2 * PAD)
        .max()
        .unwrap_or(0);
    let width = panels_w.max(caption_w).max(2 * PAD + 1);
    let height = top + PANEL_H as i64 + below + caption.len() as i64 * (th + GAP) + PAD;
    let mut img = RgbImage::from_pixel(width as u32, height as u32, PAPER.into());
    if let Some(t) = title {
        draw_text(&mut img, width / 2, PAD, t, TEXT, INK, Align::Centre);
    }
    let mut x = PAD;
    for (p, left) in panels.iter().zip(&lefts) {
        x += left;
        let axes = axes_at(p, x as f64, top as f64);
        for layer in &p.layers {
            draw_layer(&mut img, &axes, layer);
        }
        for (i, (swatch, note)) in p.notes.iter().enumerate() {
            let ny = top + GAP + i as i64 * (th + 2);
            let mut nx = x + GAP;
            if let Some(c) = swatch {
                fill_rect(
                    &mut img,
                    Rect::new(nx as f64, (ny + 2) as f64, 14.0, 8.0),
                    *c,
                );
                nx += 20;
            }
            draw_text(&mut img, nx, ny, note, TEXT, INK, Align::Left);
        }
        let centre = x + PANEL_W as i64 / 2;
        draw_text(
            &mut img,
            centre,
            top - th - GAP,
            &p.heading,
            TEXT,
            INK,
            Align::Centre,
        );
        axes.draw(&mut img, &p.x_label, &p.y_label, TEXT);
        x += PANEL_W as i64 + 3 * PAD;
    }
    for (i, c) in caption.iter().enumerate() {
        let y = top + PANEL_H as i64 + below + i as i64 * (th + GAP);
        draw_text(&mut img, PAD, y, c, TEXT, INK, Align::Left);
    }
    img
}

fn draw_layer(img: &mut RgbImage, axes: &Axes, layer: &Layer) {
    let clip = axes.area;
    let at = |p: (f64, f64)| (axes.px(p.0), axes.py(p.1));
    match layer {
        Layer::Line {
            points,
            colour,
            markers,
        } => {
            for w in points.windows(2) {
                if [w[0].0, w[0].1, w[1].0, w[1].1]
                    .iter()
                    .all(|v| v.is_finite())
                {
                    line(img, at(w[0]), at(w[1]), 2.0, *colour, &clip);
                }
            }
            if *markers {
                for &p in points.iter().filter(|p| p.0.is_finite() && p.1.is_finite()) {
                    let (cx, cy) = at(p);
                    let r = Rect::new(cx - 3.0, cy - 3.0, 7.0, 7.0);
                    let r = intersect(r, clip);
                    fill_rect(img, r, *colour);
                }
            }
        }
        Layer::Points { points, colour } => {
            let alpha = (300.0 / points.len().max(1) as f64).clamp(0.15, 0.8);
            for &p in points.iter().filter(|p| p.0.is_finite() && p.1.is_finite()) {
                let (cx, cy) = at(p);
                let (cx, cy) = (cx.floor() as i64, cy.floor() as i64);
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        blend(img, cx + dx, cy + dy, *colour, alpha, &clip);
                    }
                }
            }
        }
        Layer::Bars {
            edges,
            heights,
            colour,
        } => {
            for (i, &h) in heights.iter().enumerate() {
                if !(h.is_finite() && h > 0.0) || i + 1 >= edges.len() {
                    continue;
                }
                let (x0, x1) = (axes.px(edges[i]).round(), axes.px(edges[i + 1]).round());
                let y = axes.py(h).round().max(clip.y0);
                let gap = if x1 - x0 > 4.0 { 1.0 } else { 0.0 };
                let r = Rect::new(x0, y, (x1 - x0 - gap).max(1.0), clip.y1 - y);
                fill_rect(img, intersect(r, clip), *colour);
            }
        }
        Layer::Dashed { from, to, colour } => {
            let (a, b) = (at(*from), at(*to));
            let len = (b.0 - a.0).hypot(b.1 - a.1);
            if !len.is_finite() || len == 0.0 {
                return;
            }
            let mut s = 0.0;
            while s < len {
                let e = (s + 8.0).min(len);
                let p = |t: f64| (a.0 + (b.0 - a.0) * t / len, a.1 + (b.1 - a.1) * t / len);
                line(img, p(s), p(e), 2.0, *colour, &clip);
                s += 14.0;
            }
        }
    }
}

fn intersect(a: Rect, b: Rect) -> Rect {
    Rect {
        x0: a.x0.max(b.x0),
        y0: a.y0.max(b.y0),
        x1: a.x1.min(b.x1),
        y1: a.y1.min(b.y1),
    }
}
