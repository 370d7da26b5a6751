//! Histograms of the velocity components and of the fractional part of the displacement,
//! the standard diagnosis of peak locking (Christensen 2004, Exp. Fluids 36:484–497;
//! `docs/algorithms.md` §16.7): without locking the fractional parts are uniform on [0, 1).

use super::axes::{Axes, GAP, INK, PAD, TEXT, TICK};
use super::draw::{fill_rect, line, Colour, Rect};
use super::font::{draw_text, text_height, Align};
use crate::field::Status;
use image::RgbImage;

/// Counts of values in equal bins over `[lo, hi]`; values outside are counted in `below` and
/// `above`, so `counts.sum() + below + above` is the number of finite values.
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram {
    /// Lower edge of the first bin.
    pub lo: f64,
    /// Upper edge of the last bin (included in it).
    pub hi: f64,
    /// Count per bin.
    pub counts: Vec<u64>,
    /// Finite values below `lo`.
    pub below: u64,
    /// Finite values above `hi`.
    pub above: u64,
}

impl Histogram {
    /// Number of finite values counted, in range or not.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum::<u64>() + self.below + self.above
    }
}

/// Histogram of the finite `values` in `bins` bins (0: about 2√n, 10 to 200) over `range`;
/// `None`: from the 0.1th to the 99.9th percentile, so a few outliers do not squash it.
pub fn histogram(values: &[f32], bins: usize, range: Option<(f64, f64)>) -> Histogram {
    let mut finite: Vec<f64> = values
        .iter()
        .filter(|v| v.is_finite())
        .map(|&v| v as f64)
        .collect();
    let n = finite.len();
    let bins = match bins {
        0 => ((2.0 * (n as f64).sqrt()) as usize).clamp(10, 200),
        b => b.min(100_000),
    };
    let (mut lo, mut hi) = match range.filter(|(a, b)| a.is_finite() && b.is_finite() && b > a) {
        Some(r) => r,
        None if n == 0 => (0.0, 1.0),
        None => {
            finite.sort_unstable_by(f64::total_cmp);
            let at = |q: f64| finite[((n - 1) as f64 * q).round() as usize];
            (at(0.001), at(0.999))
        }
    };
    if hi - lo <= lo.abs().max(hi.abs()) * 1e-12 {
        (lo, hi) = (lo - 0.5, hi + 0.5);
    }
    let mut h = Histogram {
        lo,
        hi,
        counts: vec![0; bins],
        below: 0,
        above: 0,
    };
    for v in finite {
        if v < lo {
            h.below += 1;
        } else if v > hi {
            h.above += 1;
        } else {
            let b = ((v - lo) / (hi - lo) * bins as f64) as usize;
            h.counts[b.min(bins - 1)] += 1;
        }
    }
    h
}

/// The u and v of the valid vectors (status 0, both components finite), e.g. of a
/// [`crate::field::VectorField`] or a whole [`crate::field::FieldSeries`].
pub fn valid_components(u: &[f32], v: &[f32], status: &[Status]) -> (Vec<f32>, Vec<f32>) {
    u.iter()
        .zip(v)
        .zip(status)
        .filter(|((u, v), s)| s.is_valid() && u.is_finite() && v.is_finite())
        .map(|((&u, &v), _)| (u, v))
        .unzip()
}

/// Peak-locking index `1 − H_min/H_max` of the 10-bin histogram of the fractional part of
/// `value · scale` over [0, 1) (`docs/algorithms.md` §16.7, anchors §2.2): 0 for uniform
/// fractional parts, 1 when all displacements are integers. `scale` turns values into
/// displacements in px (e.g. τ in ms for velocities in px/ms; 1 for displacements). With
/// n values the index of uniform data is still about `3·sqrt(10/n)` (sampling noise). NaN
/// without finite values.
pub fn peak_locking_index(values: &[f32], scale: f64) -> f64 {
    let h = fractional_histogram(values, scale);
    let max = h.iter().copied().max().unwrap_or(0);
    let min = h.iter().copied().min().unwrap_or(0);
    if max == 0 {
        return f64::NAN;
    }
    1.0 - min as f64 / max as f64
}

fn fractional_histogram(values: &[f32], scale: f64) -> [u64; 10] {
    let mut h = [0u64; 10];
    for &v in values {
        let d = v as f64 * scale;
        if d.is_finite() {
            h[((d.rem_euclid(1.0) * 10.0) as usize).min(9)] += 1;
        }
    }
    h
}

/// How [`velocity_histograms`] is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct HistogramStyle {
    /// Bins of the u and v histograms (0: automatic). Peak locking shows as a comb with a
    /// period of one pixel of displacement, so bins must be narrower than that.
    pub bins: usize,
    /// Time that turns a velocity into a displacement in px (τ in ms for px/ms); `None`: the
    /// values are displacements already.
    pub displacement_ms: Option<f64>,
    /// Units of the values, e.g. "px/ms".
    pub units: String,
    /// Title above the panels.
    pub title: Option<String>,
}

impl Default for HistogramStyle {
    fn default() -> Self {
        HistogramStyle {
            bins: 0,
            displacement_ms: None,
            units: "px/ms".into(),
            title: None,
        }
    }
}

const PANEL_W: f64 = 380.0;
const PANEL_H: f64 = 260.0;
const BAR: Colour = [70, 118, 178];

/// The peak-locking index that `n` values with uniformly distributed fractional parts give
/// through sampling noise alone, about `3·sqrt(10/n)`: each of the 10 bins holds n/10 ± its
/// square root, and the expected range of 10 such counts is about 3 of those standard
/// deviations; NaN without values.
pub fn peak_locking_noise(n: u64) -> f64 {
    if n == 0 {
        f64::NAN
    } else {
        (3.0 * (10.0 / n as f64).sqrt()).min(1.0)
    }
}

/// The caption of the fractional-displacement panel: what the peak-locking index is, what
/// it would be from sampling noise alone with `n` values, and when it means locking (a
/// narrow displacement distribution is not flat modulo 1 even when measured exactly).
pub fn peak_locking_caption(n: u64) -> [String; 2] {
    [
        "Peak-locking index = 1 - lowest/tallest bar of the fractional displacement: \
         0 flat, 1 all at whole pixels."
            .into(),
        format!(
            "Noise alone gives about {:.2} here (3·sqrt(10/n)). Far above that, tall bars at \
             0 and 1 with displacements spread over pixels: peak locking.",
            peak_locking_noise(n)
        ),
    ]
}

/// Three panels side by side: histograms of the finite `u` and `v` values, and of the
/// fractional part of the displacement (u and v together, 10 bins) with the uniform level
/// and the [`peak_locking_index`], and a caption explaining the index (see
/// [`peak_locking_caption`]). Pass valid values only (see [`valid_components`]).
pub fn velocity_histograms(u: &[f32], v: &[f32], style: &HistogramStyle) -> RgbImage {
    let scale = style
        .displacement_ms
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(1.0);
    let both: Vec<f32> = u.iter().chain(v).copied().collect();
    let frac = fractional_histogram(&both, scale);
    let frac = Histogram {
        lo: 0.0,
        hi: 1.0,
        counts: frac.to_vec(),
        below: 0,
        above: 0,
    };
    let index = peak_locking_index(&both, scale);
    let caption = peak_locking_caption(frac.total());
    let frac_label = match style.displacement_ms {
        Some(_) => "frac(u·τ), frac(v·τ) [px]".to_string(),
        None => format!("frac(u), frac(v) [{}]", style.units),
    };
    let panels = [
        (
            histogram(u, style.bins, None),
            format!("u [{}]", style.units),
            "u",
        ),
        (
            histogram(v, style.bins, None),
            format!("v [{}]", style.units),
            "v (+ down)",
        ),
        (frac, frac_label, "fractional displacement"),
    ];
    let th = text_height(TEXT) as i64;
    let axes_of = |h: &Histogram, x: f64, y: f64| Axes {
        area: Rect::new(x, y, PANEL_W, PANEL_H),
        x_range: (h.lo, h.hi),
        y_range: (
            h.counts.iter().copied().max().unwrap_or(0).max(1) as f64 * 1.3,
            0.0,
        ),
    };
    let lefts: Vec<i64> = panels
        .iter()
        .map(|(h, ..)| th + GAP + axes_of(h, 0.0, 0.0).y_label_width(TEXT) as i64 + GAP + TICK)
        .collect();
    let top = PAD + style.title.as_ref().map_or(0, |_| th + 2 * GAP) + th + GAP;
    let caption_top = TICK + GAP + th + GAP + th + 2 * GAP;
    let bottom = caption_top + caption.len() as i64 * (th + GAP) + PAD;
    let panels_width = PAD
        + lefts
            .iter()
            .map(|l| l + PANEL_W as i64 + 3 * PAD)
            .sum::<i64>();
    // Wide enough for the caption lines too, so that none is cut off.
    let caption_width = caption
        .iter()
        .map(|line| crate::render::font::text_width(line, TEXT) as i64 + 2 * PAD)
        .max()
        .unwrap_or(0);
    let width = panels_width.max(caption_width);
    let height = top + PANEL_H as i64 + bottom;
    let mut img = RgbImage::from_pixel(width as u32, height as u32, [255, 255, 255].into());
    if let Some(title) = &style.title {
        draw_text(&mut img, width / 2, PAD, title, TEXT, INK, Align::Centre);
    }
    let mut x = PAD;
    for (k, ((h, x_label, heading), left)) in panels.iter().zip(&lefts).enumerate() {
        x += left;
        let axes = axes_of(h, x as f64, top as f64);
        draw_bars(&mut img, &axes, h);
        let mut notes = vec![format!("n = {}", h.total())];
        if k == 2 {
            let uniform = h.total() as f64 / 10.0;
            if uniform > 0.0 {
                let y = axes.py(uniform);
                dashed(&mut img, (axes.area.x0, y), axes.area.x1, [200, 40, 40]);
            }
            notes.push(format!("index = {index:.2}"));
        } else if h.below + h.above > 0 {
            notes.push(format!("{} outside", h.below + h.above));
        }
        for (i, note) in notes.iter().enumerate() {
            let ny = top + GAP + i as i64 * (th + 2);
            draw_text(&mut img, x + GAP, ny, note, TEXT, INK, Align::Left);
        }
        let cx = x + PANEL_W as i64 / 2;
        draw_text(
            &mut img,
            cx,
            top - th - GAP,
            heading,
            TEXT,
            INK,
            Align::Centre,
        );
        axes.draw(&mut img, x_label, "count", TEXT);
        x += PANEL_W as i64 + 3 * PAD;
    }
    for (i, line) in caption.iter().enumerate() {
        let y = top + PANEL_H as i64 + caption_top + i as i64 * (th + GAP);
        draw_text(&mut img, PAD, y, line, TEXT, INK, Align::Left);
    }
    img
}

fn draw_bars(img: &mut RgbImage, axes: &Axes, h: &Histogram) {
    let n = h.counts.len().max(1) as f64;
    let edge = |i: usize| axes.px(h.lo + (h.hi - h.lo) * i as f64 / n);
    let gap = if axes.area.x1 - axes.area.x0 > 4.0 * n {
        1.0
    } else {
        0.0
    };
    for (i, &c) in h.counts.iter().enumerate() {
        if c == 0 {
            continue;
        }
        let (x0, x1) = (edge(i).round(), edge(i + 1).round());
        let y = axes.py(c as f64).round();
        let w = (x1 - x0 - gap).max(1.0);
        fill_rect(img, Rect::new(x0, y, w, axes.area.y1 - y), BAR);
    }
}

fn dashed(img: &mut RgbImage, from: (f64, f64), to_x: f64, colour: Colour) {
    let clip = Rect::of(img);
    let mut x = from.0;
    while x < to_x {
        let end = (x + 8.0).min(to_x);
        line(img, (x, from.1), (end, from.1), 2.0, colour, &clip);
        x += 14.0;
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Heights in output px of the bars right of `x_from`, left to right (runs of columns
    /// holding bar colour, each with its tallest column).
    pub fn bar_heights(img: &RgbImage, x_from: u32) -> Vec<u32> {
        let mut bars = Vec::new();
        let mut current: Option<u32> = None;
        for x in x_from..img.width() {
            let n = (0..img.height())
                .filter(|&y| img.get_pixel(x, y).0 == BAR)
                .count() as u32;
            match (n, current) {
                (0, Some(h)) => {
                    bars.push(h);
                    current = None;
                }
                (0, None) => {}
                (n, c) => current = Some(c.unwrap_or(0).max(n)),
            }
        }
        bars.extend(current);
        bars
    }

    /// Ink pixels in the caption lines at the bottom of a [`velocity_histograms`] figure.
    pub fn caption_ink(img: &RgbImage) -> usize {
        let th = text_height(TEXT) as i64;
        let top = img.height() as i64 - PAD - 2 * (th + GAP);
        crate::render::axes::probe::ink_in(img, 0, top as u32, img.width(), img.height())
    }

    #[test]
    fn the_caption_explains_the_peak_locking_index() {
        let [what, noise] = peak_locking_caption(1000);
        assert!(what.contains("0 flat, 1 all at whole pixels"), "{what}");
        assert!(noise.contains("about 0.30 here"), "{noise}");
        assert!((peak_locking_noise(40) - 1.0).abs() < 1e-12);
        assert!(peak_locking_noise(0).is_nan());
        let img = velocity_histograms(
            &[0.3, 1.2, 2.5],
            &[0.1, 0.4, 0.9],
            &HistogramStyle::default(),
        );
        assert!(caption_ink(&img) > 500);
    }

    #[test]
    fn counts_sum_to_the_number_of_finite_values() {
        let mut v: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.37).sin() * 3.0).collect();
        v.extend([f32::NAN, f32::INFINITY, 1e30, -1e30]);
        let h = histogram(&v, 0, None);
        assert_eq!(h.total(), 1002);
        assert!(h.below + h.above >= 2);
        let h = histogram(&v, 7, Some((-1.0, 1.0)));
        assert_eq!((h.counts.len(), h.total()), (7, 1002));
        assert_eq!(histogram(&[], 5, None).total(), 0);
        assert_eq!(histogram(&[2.0; 9], 5, None).counts.iter().sum::<u64>(), 9);
    }

    #[test]
    fn peak_locking_index_bounds() {
        let ints: Vec<f32> = (-50..50).map(|i| i as f32).collect();
        assert_eq!(peak_locking_index(&ints, 1.0), 1.0);
        // Velocities that are integer displacements after scaling by τ = 0.5 ms.
        let v: Vec<f32> = (0..100).map(|i| 2.0 * i as f32).collect();
        assert_eq!(peak_locking_index(&v, 0.5), 1.0);
        // A low-discrepancy (golden-ratio) sequence: fractional parts spread evenly.
        let u: Vec<f32> = (0..10_000)
            .map(|i| (i as f64 * 0.618_034).fract() as f32 + 3.0)
            .collect();
        assert!(peak_locking_index(&u, 1.0) < 0.01);
        assert!(peak_locking_index(&[f32::NAN], 1.0).is_nan());
        // Pseudo-random uniform values: the index is only sampling noise, whose mean over
        // many samples the noise level states (to within the scatter of 40 samples).
        let mut state = 7u64;
        let mut uniform = |n: usize| -> Vec<f32> {
            (0..n)
                .map(|_| {
                    state = state
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1);
                    ((state >> 40) as f64 / (1u64 << 24) as f64 * 20.0 - 10.0) as f32
                })
                .collect()
        };
        assert!(peak_locking_index(&uniform(100_000), 1.0) < 0.05);
        let mean = (0..40)
            .map(|_| peak_locking_index(&uniform(10_000), 1.0))
            .sum::<f64>()
            / 40.0;
        let ratio = mean / peak_locking_noise(10_000);
        assert!(
            (0.8..1.2).contains(&ratio),
            "mean index {mean}, ratio {ratio}"
        );
    }

    #[test]
    fn the_caption_fits_the_figure() {
        let u: Vec<f32> = (0..1000).map(|i| i as f32 * 0.01).collect();
        let style = HistogramStyle {
            displacement_ms: Some(1.0),
            ..HistogramStyle::default()
        };
        let img = velocity_histograms(&u, &u, &style);
        for line in peak_locking_caption(2000) {
            let needed = crate::render::font::text_width(&line, TEXT) + 2 * PAD as u32;
            assert!(needed <= img.width(), "{needed} > {}: {line}", img.width());
        }
    }

    #[test]
    fn degenerate_inputs_draw() {
        let s = HistogramStyle::default();
        let img = velocity_histograms(&[], &[], &s);
        assert!(img.width() > 900);
        let odd = [f32::NAN, f32::INFINITY, 1e30, 0.0, 0.0];
        let s = HistogramStyle {
            bins: 3,
            displacement_ms: Some(f64::NAN),
            ..s
        };
        velocity_histograms(&odd, &[f32::MAX, -f32::MAX], &s);
    }

    #[test]
    fn valid_components_skip_flagged_and_nan() {
        let s = [
            Status::VALID,
            Status::MEDIAN_TEST | Status::REPLACED,
            Status::VALID,
        ];
        let (u, v) = valid_components(&[1.0, 2.0, f32::NAN], &[4.0, 5.0, 6.0], &s);
        assert_eq!((u, v), (vec![1.0], vec![4.0]));
    }
}
