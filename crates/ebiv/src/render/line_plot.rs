//! Line plots: a quantity against a parameter, one line per series with a shaded band (a
//! confidence interval), or as markers (scattered data), with a legend below the axes. The
//! x axis is linear, logarithmic, or a row of categories.

use super::axes::{format_value, nice_ticks, Axes, GAP, INK, PAD, PAPER, TEXT, TICK};
use super::draw::{blend, line, Colour, Rect};
use super::font::{draw_text, text_height, text_width, Align};
use image::RgbImage;

/// Line colours, in order (Okabe & Ito 2008, "Color universal design": distinguishable with
/// every common colour-vision deficiency), then repeated.
pub const SERIES_COLOURS: [Colour; 8] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
    [120, 120, 120],
    [240, 228, 66],
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesStyle {
    /// A solid line through the points, with a dot on each.
    Line,
    /// A dashed line through the points.
    Dashed,
    /// Small dots only.
    Markers,
}

/// One series of a [`LinePlot`].
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points (x, y); non-finite ones are skipped (a line breaks there).
    pub xy: Vec<(f64, f64)>,
    /// Band (low, high) at each point, shaded; empty for none.
    pub band: Vec<(f64, f64)>,
    /// How it is drawn.
    pub style: SeriesStyle,
    /// Colour; `None`: the next of [`SERIES_COLOURS`].
    pub colour: Option<Colour>,
}

/// The x axis of a [`LinePlot`].
#[derive(Debug, Clone, PartialEq)]
pub enum XAxis {
    /// Linear, with nice ticks.
    Linear,
    /// Logarithmic (positive x only), ticked at the given values.
    Log(Vec<f64>),
    /// Categories at x = 0, 1, …, labelled.
    Categories(Vec<String>),
}

/// A figure of series against one x axis.
#[derive(Debug, Clone, PartialEq)]
pub struct LinePlot {
    /// Title above the axes.
    pub title: String,
    /// x-axis label with units.
    pub x_label: String,
    /// y-axis label with units.
    pub y_label: String,
    /// The x axis.
    pub x_axis: XAxis,
    /// The series, drawn in order.
    pub series: Vec<Series>,
    /// Lines of notes below the legend.
    pub notes: Vec<String>,
}

const PLOT_W: f64 = 560.0;
const PLOT_H: f64 = 340.0;

/// Draw `plot`.
pub fn line_plot(plot: &LinePlot) -> RgbImage {
    let tx = |x: f64| match plot.x_axis {
        XAxis::Log(_) => x.log10(),
        _ => x,
    };
    let xs: Vec<f64> = plot
        .series
        .iter()
        .flat_map(|s| s.xy.iter().map(|p| tx(p.0)))
        .filter(|x| x.is_finite())
        .collect();
    let ys: Vec<f64> = plot
        .series
        .iter()
        .flat_map(|s| {
            s.xy.iter()
                .map(|p| p.1)
                .chain(s.band.iter().flat_map(|b| [b.0, b.1]))
        })
        .filter(|y| y.is_finite())
        .collect();
    let (x_lo, x_hi) = padded(&xs, 0.05, 0.5);
    let (x_lo, x_hi) = match &plot.x_axis {
        XAxis::Categories(c) => (-0.5, c.len().max(1) as f64 - 0.5),
        _ => (x_lo, x_hi),
    };
    let (y_lo, y_hi) = padded(
        &ys,
        0.08,
        0.5 * ys.first().map_or(1.0, |y| y.abs().max(1e-9)),
    );
    let th = text_height(TEXT) as i64;
    let probe = Axes {
        area: Rect::new(0.0, 0.0, PLOT_W, PLOT_H),
        x_range: (x_lo, x_hi),
        y_range: (y_hi, y_lo),
    };
    let left = PAD + th + GAP + probe.y_label_width(TEXT) as i64 + GAP + TICK;
    let top = PAD + th + 2 * GAP;
    let legend: Vec<&Series> = plot.series.iter().filter(|s| !s.label.is_empty()).collect();
    let below = TICK + GAP + th + GAP + th + 2 * GAP;
    let lines = legend.len() as i64 + plot.notes.len() as i64;
    let height = top + PLOT_H as i64 + below + lines * (th + GAP) + PAD;
    let widest_note = plot
        .notes
        .iter()
        .chain(legend.iter().map(|s| &s.label))
        .map(|n| text_width(n, TEXT) as i64 + 40)
        .max()
        .unwrap_or(0);
    let width = (left + PLOT_W as i64 + 2 * PAD)
        .max(PAD + widest_note + PAD)
        .max(text_width(&plot.title, TEXT) as i64 + 2 * PAD);
    let mut img = RgbImage::from_pixel(width as u32, height as u32, PAPER.into());
    let axes = Axes {
        area: Rect::new(left as f64, top as f64, PLOT_W, PLOT_H),
        ..probe
    };
    draw_text(
        &mut img,
        width / 2,
        PAD,
        &plot.title,
        TEXT,
        INK,
        Align::Centre,
    );
    let clip = axes.area;
    let colours: Vec<Colour> = plot
        .series
        .iter()
        .enumerate()
        .map(|(i, s)| s.colour.unwrap_or(SERIES_COLOURS[i % SERIES_COLOURS.len()]))
        .collect();
    // Bands first, so that no line is hidden under another series' band.
    for (s, &colour) in plot.series.iter().zip(&colours) {
        let pts: Vec<(f64, f64, f64)> =
            s.xy.iter()
                .zip(&s.band)
                .map(|(p, b)| (axes.px(tx(p.0)), axes.py(b.0), axes.py(b.1)))
                .filter(|p| p.0.is_finite() && p.1.is_finite() && p.2.is_finite())
                .collect();
        shade(&mut img, &pts, colour, &clip);
    }
    for (s, &colour) in plot.series.iter().zip(&colours) {
        let pts: Vec<(f64, f64)> =
            s.xy.iter()
                .map(|p| (axes.px(tx(p.0)), axes.py(p.1)))
                .collect();
        match s.style {
            SeriesStyle::Markers => {
                for p in pts.iter().filter(|p| p.0.is_finite() && p.1.is_finite()) {
                    dot(&mut img, *p, 1.6, colour, &clip);
                }
            }
            SeriesStyle::Line | SeriesStyle::Dashed => {
                for w in pts.windows(2) {
                    let (a, b) = (w[0], w[1]);
                    if [a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
                        if s.style == SeriesStyle::Dashed {
                            dashed(&mut img, a, b, colour, &clip);
                        } else {
                            line(&mut img, a, b, 2.0, colour, &clip);
                        }
                    }
                }
                if s.style == SeriesStyle::Line {
                    for p in pts.iter().filter(|p| p.0.is_finite() && p.1.is_finite()) {
                        dot(&mut img, *p, 3.5, colour, &clip);
                    }
                }
            }
        }
    }
    let x_ticks: Vec<(f64, String)> = match &plot.x_axis {
        XAxis::Linear => {
            let (ticks, step) = nice_ticks(x_lo, x_hi, 6);
            ticks
                .into_iter()
                .map(|t| (t, format_value(t, step)))
                .collect()
        }
        XAxis::Log(values) => values
            .iter()
            .filter(|v| **v > 0.0)
            .map(|&v| (v.log10(), format_value(v, v.abs() / 100.0)))
            .collect(),
        XAxis::Categories(c) => c
            .iter()
            .enumerate()
            .map(|(i, c)| (i as f64, c.clone()))
            .collect(),
    };
    axes.draw_with_x_ticks(&mut img, &x_ticks, &plot.x_label, &plot.y_label, TEXT);
    let mut y = top + PLOT_H as i64 + below;
    for s in &legend {
        let i = plot
            .series
            .iter()
            .position(|t| std::ptr::eq(t, *s))
            .unwrap_or(0);
        let cy = (y + th / 2) as f64;
        let a = (PAD as f64, cy);
        let b = (PAD as f64 + 28.0, cy);
        let all = Rect::of(&img);
        match s.style {
            SeriesStyle::Markers => dot(&mut img, (a.0 + 14.0, cy), 2.5, colours[i], &all),
            SeriesStyle::Dashed => dashed(&mut img, a, b, colours[i], &all),
            SeriesStyle::Line => {
                if !s.band.is_empty() {
                    let band = Rect::new(a.0, cy - 6.0, 28.0, 12.0);
                    shade_rect(&mut img, band, colours[i]);
                }
                line(&mut img, a, b, 2.0, colours[i], &all);
            }
        }
        draw_text(&mut img, PAD + 36, y, &s.label, TEXT, INK, Align::Left);
        y += th + GAP;
    }
    for note in &plot.notes {
        draw_text(&mut img, PAD, y, note, TEXT, INK, Align::Left);
        y += th + GAP;
    }
    img
}

/// The range of `values` widened by `share` of it on each side; `±half` about a single
/// value; (0, 1) without values.
fn padded(values: &[f64], share: f64, half: f64) -> (f64, f64) {
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    if hi - lo <= hi.abs().max(lo.abs()) * 1e-9 {
        let h = if half.is_finite() && half > 0.0 {
            half
        } else {
            1.0
        };
        return (lo - h, hi + h);
    }
    let pad = (hi - lo) * share;
    (lo - pad, hi + pad)
}

/// Shade the band between the (x, low, high) points, column by column, interpolating
/// linearly between neighbouring points.
fn shade(img: &mut RgbImage, pts: &[(f64, f64, f64)], colour: Colour, clip: &Rect) {
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (x0, x1) = (a.0.min(b.0), a.0.max(b.0));
        let mut x = x0.floor();
        while x <= x1.ceil() && x1 - x0 < 1e5 {
            let s = if b.0 == a.0 {
                0.0
            } else {
                (x + 0.5 - a.0) / (b.0 - a.0)
            };
            let s = s.clamp(0.0, 1.0);
            let lo = a.1 + s * (b.1 - a.1);
            let hi = a.2 + s * (b.2 - a.2);
            let (y0, y1) = (lo.min(hi), lo.max(hi));
            let mut y = y0.floor();
            while y <= y1.ceil() && y1 - y0 < 1e5 {
                blend(img, x as i64, y as i64, colour, 0.18, clip);
                y += 1.0;
            }
            x += 1.0;
        }
    }
    // A band at a single point: a short bar.
    if pts.len() == 1 {
        let (x, lo, hi) = pts[0];
        line(img, (x, lo), (x, hi), 6.0, tint(colour), clip);
    }
}

/// `c` a third of the way from white.
fn tint(c: Colour) -> Colour {
    c.map(|v| ((u16::from(v) + 2 * 255) / 3) as u8)
}

fn shade_rect(img: &mut RgbImage, r: Rect, colour: Colour) {
    let clip = Rect::of(img);
    for y in r.y0 as i64..r.y1 as i64 {
        for x in r.x0 as i64..r.x1 as i64 {
            blend(img, x, y, colour, 0.18, &clip);
        }
    }
}

fn dot(img: &mut RgbImage, p: (f64, f64), radius: f64, colour: Colour, clip: &Rect) {
    line(img, p, p, 2.0 * radius, colour, clip);
}

fn dashed(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), colour: Colour, clip: &Rect) {
    let length = (b.0 - a.0).hypot(b.1 - a.1);
    if !(length.is_finite() && length > 0.0) {
        return;
    }
    let (dx, dy) = ((b.0 - a.0) / length, (b.1 - a.1) / length);
    let mut s = 0.0;
    while s < length && s < 1e5 {
        let e = (s + 8.0).min(length);
        line(
            img,
            (a.0 + dx * s, a.1 + dy * s),
            (a.0 + dx * e, a.1 + dy * e),
            2.0,
            colour,
            clip,
        );
        s += 13.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(img: &RgbImage, colour: Colour) -> usize {
        img.pixels().filter(|p| p.0 == colour).count()
    }

    #[test]
    fn lines_bands_and_markers_are_drawn_in_their_colours() {
        let plot = LinePlot {
            title: "rms against slab".into(),
            x_label: "slab [ms]".into(),
            y_label: "rms [px/ms]".into(),
            x_axis: XAxis::Linear,
            series: vec![
                Series {
                    label: "corrsum".into(),
                    xy: vec![(5.0, 0.1), (10.0, 0.05), (20.0, f64::NAN)],
                    band: vec![(0.08, 0.12), (0.04, 0.06), (f64::NAN, f64::NAN)],
                    style: SeriesStyle::Line,
                    colour: None,
                },
                Series {
                    label: "truth".into(),
                    xy: vec![(5.0, 0.0), (20.0, 0.2)],
                    band: vec![],
                    style: SeriesStyle::Dashed,
                    colour: Some([200, 0, 0]),
                },
            ],
            notes: vec!["mean of 3 seeds, 95 % band".into()],
        };
        let img = line_plot(&plot);
        assert!(count(&img, SERIES_COLOURS[0]) > 50);
        assert!(count(&img, [200, 0, 0]) > 50);
        let categories = LinePlot {
            x_axis: XAxis::Categories(vec!["corrsum".into(), "motion".into()]),
            series: vec![Series {
                label: String::new(),
                xy: vec![(0.0, 1.0), (1.0, 2.0)],
                band: vec![(0.5, 1.5), (1.5, 2.5)],
                style: SeriesStyle::Markers,
                colour: None,
            }],
            ..plot
        };
        let img = line_plot(&categories);
        assert!(count(&img, SERIES_COLOURS[0]) > 5);
        let empty = LinePlot {
            series: vec![],
            x_axis: XAxis::Log(vec![0.001, 0.01]),
            ..categories
        };
        let img = line_plot(&empty);
        assert!(img.width() > 100);
    }
}
