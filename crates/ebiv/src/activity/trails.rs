//! Width of the particle trails of one time slab.
//!
//! A particle moving through the slab lights a band of pixels — its trail in the time-coded
//! event image (Willert & Klinner, Exp. Fluids 63:101, 2022, Fig. 4: trails 2–5 px wide). The
//! width is measured on the image of the pixels with at least one event in the slab: each
//! 8-connected group of such pixels is one trail; its length `L` is its extent along its
//! principal axis (the eigenvector of the larger eigenvalue of its pixel coordinates'
//! covariance) plus one pixel, and its width the number of its pixels divided by `L` (a band
//! of width `w` and length `L` holds `w·L` pixels). Only elongated groups are trails: at least
//! [`MIN_TRAIL_PIXELS`] pixels and `L ≥ ELONGATION · width`; round blobs (slow particles, noise
//! clusters) and single pixels are left out, and trails that cross merge into one group, which
//! the elongation test mostly rejects.

/// Fewest pixels of a group measured as a trail.
pub const MIN_TRAIL_PIXELS: usize = 6;
/// Smallest ratio of length to width of a group measured as a trail.
pub const ELONGATION: f64 = 2.0;

/// The widths, px, of the trails in a `width × height` image of active pixels (row-major).
pub fn trail_widths(active: &[bool], width: usize, height: usize) -> Vec<f64> {
    debug_assert_eq!(active.len(), width * height);
    let mut seen = vec![false; active.len()];
    let mut stack = Vec::new();
    let mut group: Vec<(f64, f64)> = Vec::new();
    let mut widths = Vec::new();
    for start in 0..active.len() {
        if !active[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        group.clear();
        while let Some(i) = stack.pop() {
            let (x, y) = (i % width, i / width);
            group.push((x as f64, y as f64));
            for ny in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                    let j = ny * width + nx;
                    if active[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        if let Some(w) = group_width(&group) {
            widths.push(w);
        }
    }
    widths
}

/// The width of one group of pixel centres, if it is a trail (see the module documentation).
fn group_width(group: &[(f64, f64)]) -> Option<f64> {
    if group.len() < MIN_TRAIL_PIXELS {
        return None;
    }
    let n = group.len() as f64;
    let (mx, my) = group
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x / n, b + y / n));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for &(x, y) in group {
        let (dx, dy) = (x - mx, y - my);
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
    }
    // Principal axis of the 2×2 covariance: angle ½·atan2(2 s_xy, s_xx − s_yy).
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (c, s) = (angle.cos(), angle.sin());
    let (lo, hi) = group
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &(x, y)| {
            let p = (x - mx) * c + (y - my) * s;
            (lo.min(p), hi.max(p))
        });
    let length = hi - lo + 1.0;
    let w = n / length;
    (length >= ELONGATION * w).then_some(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: usize, height: usize, lit: impl Fn(usize, usize) -> bool) -> Vec<bool> {
        (0..width * height)
            .map(|i| lit(i % width, i / width))
            .collect()
    }

    #[test]
    fn horizontal_and_vertical_bands() {
        // A 3×15 band along x and a 2×12 band along y, apart: widths 3 and 2.
        let img = image(40, 30, |x, y| {
            (2..17).contains(&x) && (4..7).contains(&y)
                || (30..32).contains(&x) && (10..22).contains(&y)
        });
        let mut w = trail_widths(&img, 40, 30);
        w.sort_by(f64::total_cmp);
        assert_eq!(w.len(), 2);
        assert!(
            (w[0] - 2.0).abs() < 1e-9 && (w[1] - 3.0).abs() < 1e-9,
            "{w:?}"
        );
    }

    #[test]
    fn diagonal_band() {
        // Pixels with |x − y| ≤ 1 for 0 ≤ x, y < 20: 58 pixels; the principal axis is the
        // diagonal, the extent along it 19·√2 + 1 = 27.87, width 58/27.87 = 2.081.
        let img = image(20, 20, |x, y| (x as i64 - y as i64).abs() <= 1);
        let w = trail_widths(&img, 20, 20);
        assert_eq!(w.len(), 1);
        let want = 58.0 / (19.0 * 2f64.sqrt() + 1.0);
        assert!((w[0] - want).abs() < 1e-9, "{w:?} vs {want}");
    }

    #[test]
    fn blobs_and_dots_are_not_trails() {
        // A 5×5 square (not elongated), a 1×5 line (too few pixels), a lone pixel.
        let img = image(30, 10, |x, y| {
            (1..6).contains(&x) && (1..6).contains(&y)
                || (10..15).contains(&x) && y == 3
                || x == 25 && y == 8
        });
        assert!(trail_widths(&img, 30, 10).is_empty());
        assert!(trail_widths(&[], 0, 0).is_empty());
    }
}
