//! Vector maps: arrows over a colour map of the velocity magnitude (or over a dimmed event
//! image), with axes in image pixels, a colour bar and a reference arrow.

use super::arrow::{ArrowSize, HALO};
use super::axes::{format_value, Axes, ColourBar, ImageFigure, GAP, INK, PAPER, TEXT};
use super::colormap::inferno;
use super::draw::{Colour, Rect};
use super::font::{draw_text, text_width, Align};
use crate::event::Geometry;
use crate::field::{Status, VectorField};
use image::RgbImage;
use rayon::prelude::*;

/// How a vector map is drawn. `Default` chooses everything automatically.
#[derive(Debug, Clone, PartialEq)]
pub struct VectorMapStyle {
    /// Arrow length in image pixels per unit of velocity (px per px/ms); `None`: the median
    /// magnitude is drawn 0.8 arrow spacings long (grid spacing × stride).
    pub scale: Option<f64>,
    /// Magnitudes at the ends of the colour map; `None`: 0 to the 99th percentile, rounded
    /// up to two significant digits.
    pub magnitude_range: Option<(f32, f32)>,
    /// Draw a colour bar (only with the magnitude map, i.e. without a background image).
    pub colour_bar: bool,
    /// Title above the plot.
    pub title: Option<String>,
    /// Velocity units for the colour bar and the reference arrow, e.g. "px/ms" or "m/s".
    pub units: String,
    /// Output pixels per image pixel; `None`: about 1000 px wide (integer when enlarging).
    pub pixel_scale: Option<f64>,
    /// Draw every `stride`-th arrow in x and y (1: all); `None`: thinned to a readable
    /// density, see [`auto_stride`].
    pub stride: Option<usize>,
}

impl Default for VectorMapStyle {
    fn default() -> Self {
        VectorMapStyle {
            scale: None,
            magnitude_range: None,
            colour_bar: true,
            title: None,
            units: "px/ms".into(),
            pixel_scale: None,
            stride: None,
        }
    }
}

const NO_DATA: Colour = [120, 120, 120];
const VALID: Colour = [255, 255, 255];
const REPLACED: Colour = [0, 225, 255];
/// Largest plot side in output pixels.
const MAX_SIDE: f64 = 8000.0;

/// Magnitudes of the vectors that carry a finite value (valid or replaced).
pub(crate) fn magnitudes(u: &[f32], v: &[f32], status: &[Status]) -> Vec<f32> {
    u.iter()
        .zip(v)
        .zip(status)
        .filter(|(_, s)| s.has_value())
        .map(|((&u, &v), _)| (u as f64).hypot(v as f64) as f32)
        .filter(|m| m.is_finite())
        .collect()
}

/// The 0-based `q` quantile (0–1) of `values` (sorted in place).
fn quantile(values: &mut [f32], q: f64) -> Option<f32> {
    values.sort_unstable_by(f32::total_cmp);
    let i = ((values.len() as f64 - 1.0) * q).round().max(0.0) as usize;
    values.get(i).copied()
}

/// Colour range: 0 to the 99th percentile of `mags` rounded up to two significant digits.
pub(crate) fn auto_range(mags: &[f32]) -> (f32, f32) {
    auto_range_at(mags, 0.99)
}

/// Colour range: 0 to the `q` quantile of `mags` rounded up to two significant digits.
pub(crate) fn auto_range_at(mags: &[f32], q: f64) -> (f32, f32) {
    auto_range_of(mags.to_vec(), q)
}

/// [`auto_range_at`] of values the caller no longer needs (no copy of them).
pub(crate) fn auto_range_of(mut mags: Vec<f32>, q: f64) -> (f32, f32) {
    let top = quantile(&mut mags, q).unwrap_or(0.0) as f64;
    if !(top.is_finite() && top > 0.0) {
        return (0.0, 1.0);
    }
    let unit = 10f64.powf(top.log10().floor() - 1.0);
    let hi = ((top / unit).ceil() * unit) as f32;
    (
        0.0,
        if hi.is_finite() && hi > 0.0 {
            hi
        } else {
            f32::MAX
        },
    )
}

/// Grid spacing in image pixels: the smaller of the median node steps in x and y.
fn grid_spacing(x: &[f64], y: &[f64], geometry: (f64, f64)) -> f64 {
    let step = |a: &[f64]| {
        let mut d: Vec<f32> = a.windows(2).map(|w| (w[1] - w[0]).abs() as f32).collect();
        d.retain(|v| v.is_finite() && *v > 0.0);
        quantile(&mut d, 0.5).map(f64::from)
    };
    match (step(x), step(y)) {
        (Some(a), Some(b)) => a.min(b),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => geometry.0.min(geometry.1) / 8.0,
    }
    .max(1e-3)
}

/// Arrows drawn at least this many output pixels apart by default.
pub const MIN_ARROW_GAP: f64 = 16.0;
/// At most this many arrows across the longer side of the grid by default.
pub const MAX_ARROWS_ACROSS: usize = 40;

/// The default arrow stride: draw every `stride`-th node in x and y so that arrows are at
/// least [`MIN_ARROW_GAP`] output pixels apart and at most [`MAX_ARROWS_ACROSS`] span the
/// longer side of a grid of `nodes_across` nodes, given the grid `spacing` in output
/// pixels. Denser arrows overlap and hide the flow.
pub fn auto_stride(spacing: f64, nodes_across: usize) -> usize {
    let by_gap = (MIN_ARROW_GAP / spacing).ceil();
    let by_count = nodes_across.div_ceil(MAX_ARROWS_ACROSS) as f64;
    by_gap.max(by_count).clamp(1.0, 1e6) as usize
}

/// Output pixels per image pixel: `style.pixel_scale`, or about 1000 px wide (an integer
/// when enlarging), and at most [`MAX_SIDE`] px on a side.
fn pixel_scale(geometry: Geometry, style: &VectorMapStyle) -> f64 {
    let (w, h) = extent(geometry);
    let auto = if w <= 1000.0 {
        (1000.0 / w).min(800.0 / h).round().max(1.0)
    } else {
        (1000.0 / w).min(800.0 / h)
    };
    style
        .pixel_scale
        .filter(|k| k.is_finite() && *k > 0.0)
        .unwrap_or(auto)
        .min(MAX_SIDE / w)
        .min(MAX_SIDE / h)
}

/// The stride of the arrows of a vector map of the grid `x`, `y`: `style.stride`, or
/// [`auto_stride`] for the grid spacing in output pixels.
pub(crate) fn arrow_stride(
    x: &[f64],
    y: &[f64],
    geometry: Geometry,
    style: &VectorMapStyle,
) -> usize {
    style.stride.filter(|&s| s > 0).unwrap_or_else(|| {
        let spacing = grid_spacing(x, y, extent(geometry)) * pixel_scale(geometry, style);
        auto_stride(spacing, x.len().max(y.len()))
    })
}

/// Arrow scale that draws the median magnitude 0.8 grid spacings long.
pub(crate) fn auto_scale(mags: &[f32], x: &[f64], y: &[f64], geometry: Geometry) -> f64 {
    let spacing = grid_spacing(x, y, extent(geometry));
    let mut positive: Vec<f32> = mags.iter().copied().filter(|&m| m > 0.0).collect();
    let median = quantile(&mut positive, 0.5).unwrap_or(0.0) as f64;
    let s = 0.8 * spacing / median;
    if s.is_finite() && s > 0.0 {
        s
    } else {
        1.0
    }
}

fn extent(g: Geometry) -> (f64, f64) {
    (g.width.max(1) as f64, g.height.max(1) as f64)
}

/// Draw `field` on a sensor of `geometry`: arrows (tail at the node) over a colour map of the
/// velocity magnitude, or over `background` (e.g. [`super::time_coded_image`]) dimmed.
/// Valid vectors are white arrows, replaced ones cyan, vectors without a value red crosses,
/// masked nodes grey dots; grey areas have no data. Axes are in image pixels, y down as in
/// the image. Never panics: empty, all-NaN and infinite fields give a frame with markers.
pub fn vector_map(
    field: &VectorField,
    geometry: Geometry,
    background: Option<&RgbImage>,
    style: &VectorMapStyle,
) -> RgbImage {
    let layer = match background {
        Some(image) => Layer::Image(image),
        None => {
            let range = style
                .magnitude_range
                .filter(|(a, b)| a.is_finite() && b.is_finite() && b > a)
                .unwrap_or_else(|| auto_range(&magnitudes(&field.u, &field.v, &field.status)));
            let values = (0..field.len())
                .map(|i| {
                    let m = (field.u[i] as f64).hypot(field.v[i] as f64) as f32;
                    if field.status[i].has_value() && m.is_finite() {
                        m
                    } else {
                        f32::NAN
                    }
                })
                .collect();
            Layer::Scalar(ScalarLayer {
                values,
                range,
                colours: inferno,
                label: format!("|V| [{}]", style.units),
            })
        }
    };
    draw_map(field, geometry, layer, style, true)
}

/// What fills the plot area of a map.
pub(crate) enum Layer<'a> {
    /// An image (e.g. events), dimmed, without a colour bar.
    Image(&'a RgbImage),
    /// Values at the nodes, interpolated bilinearly, with a colour bar.
    Scalar(ScalarLayer),
}

/// Values at the nodes of a field (NaN: no data) drawn in colour.
pub(crate) struct ScalarLayer {
    /// One value per node, indexed like the field.
    pub values: Vec<f32>,
    /// Values at the ends of the colour map.
    pub range: (f32, f32),
    /// The colour map.
    pub colours: fn(f32) -> Colour,
    /// The colour bar's title, with units.
    pub label: String,
}

/// A map of `field` over `layer`, with arrows when `arrows`.
pub(crate) fn draw_map(
    field: &VectorField,
    geometry: Geometry,
    layer: Layer<'_>,
    style: &VectorMapStyle,
    arrows: bool,
) -> RgbImage {
    let (w, h) = extent(geometry);
    let mags = magnitudes(&field.u, &field.v, &field.status);
    let k = pixel_scale(geometry, style);
    let spacing = grid_spacing(&field.x, &field.y, (w, h)) * k;
    let stride = arrow_stride(&field.x, &field.y, geometry, style);
    let scale = style
        .scale
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or_else(|| auto_scale(&mags, &field.x, &field.y, geometry) * stride as f64);
    let (pw, ph) = ((w * k).round().max(1.0), (h * k).round().max(1.0));
    let bar = match &layer {
        Layer::Scalar(l) if style.colour_bar => {
            let range = (l.range.0 as f64, l.range.1 as f64);
            Some(ColourBar::linear(range, l.label.clone(), l.colours))
        }
        _ => None,
    };
    // One blank note line: the reference arrow and the vector counts are drawn into it.
    let (figure, mut img) = ImageFigure::new(
        (w, h),
        (pw, ph),
        style.title.clone(),
        bar,
        vec![String::new()],
    );
    let axes = figure.axes;

    paint_plot(&mut img, &axes, field, &layer, geometry);
    let arrow = ArrowSize::for_spacing(spacing * stride as f64);
    let rows = if arrows { field.height() } else { 0 };
    for r in (0..rows).step_by(stride) {
        for c in (0..field.width()).step_by(stride) {
            let i = field.index(r, c);
            let p = (axes.px(field.x[c]), axes.py(field.y[r]));
            let (u, v, s) = (field.u[i] as f64, field.v[i] as f64, field.status[i]);
            let d = (u * scale * k, v * scale * k);
            let finite = d.0.is_finite() && d.1.is_finite();
            if s.contains(Status::MASKED) && !s.has_value() {
                arrow.dot(&mut img, p, [170, 170, 170], &axes.area);
            } else if !s.has_value() || !finite {
                arrow.cross(&mut img, p, &axes.area);
            } else {
                let colour = if s.is_valid() { VALID } else { REPLACED };
                arrow.draw(&mut img, p, d, colour, HALO, &axes.area);
            }
        }
    }
    figure.decorate(&mut img);

    // Reference arrow and vector counts along the bottom.
    let (x0, x1) = (axes.area.x0 as i64, axes.area.x1 as i64);
    let row = figure.note_y(0);
    let mut key_end = x0;
    let median_len = 0.8 * spacing * stride as f64 / k / scale;
    let reference = nice_floor(1.2 * median_len).filter(|r| arrows && r * scale * k >= 8.0);
    if let Some(r) = reference {
        let len = r * scale * k;
        let y = row as f64 + 7.0;
        let a = (x0 as f64 + 2.0, y);
        let clip = Rect::of(&img);
        arrow.draw(&mut img, a, (len, 0.0), INK, PAPER, &clip);
        let label = format!("{} {}", format_value(r, r / 10.0), style.units);
        let tx = x0 + len.ceil() as i64 + 2 * GAP;
        draw_text(&mut img, tx, row, &label, TEXT, INK, Align::Left);
        key_end = tx + text_width(&label, TEXT) as i64;
    }
    let count = |f: &dyn Fn(Status) -> bool| field.status.iter().filter(|&&s| f(s)).count();
    let counts = format!(
        "{} valid, {} replaced, {} invalid",
        count(&|s| s.is_valid()),
        count(&|s| !s.is_valid() && s.has_value()),
        count(&|s| !s.has_value() && !s.contains(Status::MASKED)),
    );
    if x1 - text_width(&counts, TEXT) as i64 > key_end + 3 * GAP {
        draw_text(&mut img, x1, row, &counts, TEXT, INK, Align::Right);
    }
    img
}

/// The largest 1, 2 or 5 × 10ⁿ not above `x`.
fn nice_floor(x: f64) -> Option<f64> {
    if !(x.is_finite() && x > 0.0) {
        return None;
    }
    let mag = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|&v| v <= x * (1.0 + 1e-9))
}

/// Fill the plot area: the dimmed background image, or the values of a scalar layer (bilinear
/// between nodes with a value; grey where the nearest node has none or outside the grid).
fn paint_plot(
    img: &mut RgbImage,
    axes: &Axes,
    field: &VectorField,
    layer: &Layer<'_>,
    geometry: Geometry,
) {
    let (w, h) = extent(geometry);
    let a = axes.area;
    let (pw, ph) = ((a.x1 - a.x0) as usize, (a.y1 - a.y0) as usize);
    let to_image = |i: usize, n: usize, len: f64| (i as f64 + 0.5) / n as f64 * len - 0.5;
    let (background, mags, range, colours): (_, &[f32], _, fn(f32) -> Colour) = match layer {
        Layer::Image(image) => (Some(*image), &[], (0.0, 1.0), inferno),
        Layer::Scalar(l) => (None, &l.values, l.range, l.colours),
    };
    let spacing = grid_spacing(&field.x, &field.y, (w, h));
    let cols: Vec<_> = (0..pw)
        .map(|i| bracket(&field.x, to_image(i, pw, w), spacing))
        .collect();
    let mut pixels = vec![NO_DATA; pw * ph];
    pixels
        .par_chunks_mut(pw.max(1))
        .enumerate()
        .for_each(|(j, out)| {
            let yi = to_image(j, ph, h);
            if let Some(bg) = background.filter(|b| b.width() > 0 && b.height() > 0) {
                let by = ((yi + 0.5) / h * bg.height() as f64) as u32;
                for (i, o) in out.iter_mut().enumerate() {
                    let bx = ((to_image(i, pw, w) + 0.5) / w * bg.width() as f64) as u32;
                    let p = bg.get_pixel(bx.min(bg.width() - 1), by.min(bg.height() - 1));
                    *o = p.0.map(|c| (c as f32 * 0.6) as u8);
                }
                return;
            }
            let Some((r0, r1, fy)) = bracket(&field.y, yi, spacing) else {
                return;
            };
            for (o, col) in out.iter_mut().zip(&cols) {
                let Some((c0, c1, fx)) = *col else { continue };
                let nearest = field.index(
                    if fy < 0.5 { r0 } else { r1 },
                    if fx < 0.5 { c0 } else { c1 },
                );
                if mags[nearest].is_nan() {
                    continue;
                }
                let (mut sum, mut weight) = (0.0, 0.0);
                for (r, wy) in [(r0, 1.0 - fy), (r1, fy)] {
                    for (c, wx) in [(c0, 1.0 - fx), (c1, fx)] {
                        let m = mags[field.index(r, c)];
                        if !m.is_nan() && wx * wy > 0.0 {
                            sum += wx * wy * m as f64;
                            weight += wx * wy;
                        }
                    }
                }
                let s = (sum / weight - range.0 as f64) / (range.1 as f64 - range.0 as f64);
                *o = colours(s as f32);
            }
        });
    for (j, row) in pixels.chunks(pw.max(1)).enumerate() {
        for (i, &c) in row.iter().enumerate() {
            img.put_pixel(a.x0 as u32 + i as u32, a.y0 as u32 + j as u32, c.into());
        }
    }
}

/// Nodes of an ascending `axis` around `p` and the fraction between them; `None` more than
/// half a grid spacing beyond the first or last node.
fn bracket(axis: &[f64], p: f64, spacing: f64) -> Option<(usize, usize, f64)> {
    let last = axis.len().checked_sub(1)?;
    if p < axis[0] - spacing / 2.0 || p > axis[last] + spacing / 2.0 {
        return None;
    }
    let hi = axis.partition_point(|&a| a <= p);
    if hi == 0 {
        return Some((0, 0, 0.0));
    }
    if hi > last {
        return Some((last, last, 0.0));
    }
    let span = axis[hi] - axis[hi - 1];
    let f = if span > 0.0 {
        (p - axis[hi - 1]) / span
    } else {
        0.0
    };
    Some((hi - 1, hi, f))
}

#[cfg(test)]
#[path = "vector_map_tests.rs"]
pub(crate) mod tests;
