//! Joint histogram of the two velocity components, drawn as an image with a logarithmic
//! colour scale. Peak locking shows in it as clustering of the measured (u, v) on a lattice
//! of whole-pixel displacements: the "star-shaped" pattern of the EBIV paper's motion
//! compensation results (Willert & Klinner 2022, Exp. Fluids 63:101), where a 1-D histogram
//! of each component hides it among the other component's values.

use super::axes::{Axes, ColourBar, GAP, INK, PAD, PAPER, TEXT, TICK};
use super::colormap::inferno;
use super::draw::{fill_rect, line, Rect};
use super::font::{draw_text, text_height, text_width, Align};
use image::RgbImage;

/// Counts of (u, v) pairs in `bins × bins` equal cells over `u_range × v_range`.
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram2d {
    /// u range, px/ms.
    pub u_range: (f64, f64),
    /// v range, px/ms.
    pub v_range: (f64, f64),
    /// Cells per axis.
    pub bins: usize,
    /// Counts, row-major with v rows (first row: lowest v).
    pub counts: Vec<u64>,
    /// Pairs outside the ranges.
    pub outside: u64,
}

impl Histogram2d {
    /// The histogram of the finite pairs of `u`, `v` (`bins` clamped to 1…2000).
    pub fn new(
        u: &[f64],
        v: &[f64],
        u_range: (f64, f64),
        v_range: (f64, f64),
        bins: usize,
    ) -> Self {
        let bins = bins.clamp(1, 2000);
        let mut h = Histogram2d {
            u_range,
            v_range,
            bins,
            counts: vec![0; bins * bins],
            outside: 0,
        };
        let cell = |x: f64, (lo, hi): (f64, f64)| {
            let s = (x - lo) / (hi - lo);
            (0.0..=1.0)
                .contains(&s)
                .then(|| ((s * bins as f64) as usize).min(bins - 1))
        };
        for (&a, &b) in u.iter().zip(v) {
            if !(a.is_finite() && b.is_finite()) {
                continue;
            }
            match (cell(a, u_range), cell(b, v_range)) {
                (Some(i), Some(j)) => h.counts[j * bins + i] += 1,
                _ => h.outside += 1,
            }
        }
        h
    }

    /// Pairs counted in the cells.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }
}

const SIDE: f64 = 420.0;

/// The histogram as a figure: u to the right, v upwards, cell colours on a logarithmic
/// scale of the count (empty cells white), a colour bar, `title` above and `notes` below.
pub fn histogram2d_figure(h: &Histogram2d, title: &str, notes: &[String]) -> RgbImage {
    let th = text_height(TEXT) as i64;
    let axes_at = |x: f64, y: f64| Axes {
        area: Rect::new(x, y, SIDE, SIDE),
        x_range: h.u_range,
        y_range: (h.v_range.1, h.v_range.0),
    };
    let left = PAD + th + GAP + axes_at(0.0, 0.0).y_label_width(TEXT) as i64 + GAP + TICK;
    let top = PAD + th + 2 * GAP;
    let max = h.counts.iter().copied().max().unwrap_or(0).max(1);
    let log_max = (max as f64).log10().max(1e-9);
    let bar = ColourBar {
        colours: inferno,
        ticks: {
            let mut t = vec![(0.0, "1".to_string())];
            let mut p = 10u64;
            while p <= max {
                t.push(((p as f64).log10() / log_max, p.to_string()));
                p *= 10;
            }
            t.push((1.0, max.to_string()));
            t.dedup_by(|a, b| (a.0 - b.0).abs() < 0.08);
            t
        },
        title: "vectors per cell".into(),
    };
    let widest = notes
        .iter()
        .chain(std::iter::once(&title.to_string()))
        .map(|n| text_width(n, TEXT) as i64 + 2 * PAD)
        .max()
        .unwrap_or(0);
    let width = (left + SIDE as i64 + 2 * GAP + bar.width(TEXT) as i64 + PAD).max(widest);
    let below = TICK + GAP + th + GAP + th + 2 * GAP;
    let height = top + SIDE as i64 + below + notes.len() as i64 * (th + GAP) + PAD;
    let mut img = RgbImage::from_pixel(width.max(200) as u32, height as u32, PAPER.into());
    draw_text(&mut img, width / 2, PAD, title, TEXT, INK, Align::Centre);
    let axes = axes_at(left as f64, top as f64);
    let n = h.bins as f64;
    for j in 0..h.bins {
        for i in 0..h.bins {
            let c = h.counts[j * h.bins + i];
            if c == 0 {
                continue;
            }
            let s = ((c as f64).log10() / log_max) as f32;
            let (x0, x1) = (
                axes.area.x0 + SIDE * i as f64 / n,
                axes.area.x0 + SIDE * (i + 1) as f64 / n,
            );
            let (y1, y0) = (
                axes.area.y1 - SIDE * j as f64 / n,
                axes.area.y1 - SIDE * (j + 1) as f64 / n,
            );
            let r = Rect::new(
                x0.floor(),
                y0.floor(),
                (x1.floor() - x0.floor()).max(1.0),
                (y1.floor() - y0.floor()).max(1.0),
            );
            fill_rect(&mut img, r, inferno(0.15 + 0.85 * s.clamp(0.0, 1.0)));
        }
    }
    // Zero lines, faint, for orientation.
    let clip = axes.area;
    let grey = [170, 170, 170];
    if h.u_range.0 < 0.0 && h.u_range.1 > 0.0 {
        let x = axes.px(0.0);
        line(&mut img, (x, clip.y0), (x, clip.y1), 1.0, grey, &clip);
    }
    if h.v_range.0 < 0.0 && h.v_range.1 > 0.0 {
        let y = axes.py(0.0);
        line(&mut img, (clip.x0, y), (clip.x1, y), 1.0, grey, &clip);
    }
    axes.draw(
        &mut img,
        "u [px/ms]",
        "v [px/ms] (+ down in the image)",
        TEXT,
    );
    bar.draw(
        &mut img,
        left + SIDE as i64 + 2 * GAP,
        top,
        SIDE as i64,
        TEXT,
    );
    let mut y = top + SIDE as i64 + below;
    for note in notes {
        draw_text(&mut img, PAD, y, note, TEXT, INK, Align::Left);
        y += th + GAP;
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_fall_in_their_cells() {
        let u = [0.0, 0.49, 0.51, 1.0, 5.0, f64::NAN];
        let v = [0.0, 0.0, 0.99, 1.0, 0.0, 0.0];
        let h = Histogram2d::new(&u, &v, (0.0, 1.0), (0.0, 1.0), 2);
        assert_eq!(h.counts, [2, 0, 0, 2]);
        assert_eq!((h.total(), h.outside), (4, 1));
        let img = histogram2d_figure(&h, "test", &["note".into()]);
        let dark = img.pixels().filter(|p| p.0 == inferno(1.0)).count();
        assert!(dark > 1000, "{dark}");
    }
}
