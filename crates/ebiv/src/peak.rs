//! Peak location in a correlation plane or objective map, with sub-pixel fits.
//!
//! Three-point estimators per axis through the integer maximum (Gaussian with parabolic
//! fall-back, as in Raffel et al., "Particle Image Velocimetry", 3rd ed., §5.4.3), a 2-D
//! Gaussian fit on the 3 × 3 neighbourhood (Nobach & Honkanen 2005, Exp. Fluids 38:511), and
//! the ratio of the highest to the second-highest local maximum (Keane & Adrian 1992).

use serde::{Deserialize, Serialize};

/// Sub-pixel peak estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SubPixelFit {
    /// 3-point Gaussian per axis; parabolic where a value is not positive.
    #[default]
    Gaussian3,
    /// 3-point parabola per axis.
    Parabolic3,
    /// 2-D Gaussian on the 3 × 3 neighbourhood (handles elliptic, tilted peaks); falls back
    /// to the 3-point Gaussian where a value is not positive.
    Gaussian2d,
}

impl SubPixelFit {
    /// The setting's name of this fit: `gauss3`, `parabolic` or `gauss2d`.
    pub fn name(self) -> &'static str {
        match self {
            SubPixelFit::Gaussian3 => "gauss3",
            SubPixelFit::Parabolic3 => "parabolic",
            SubPixelFit::Gaussian2d => "gauss2d",
        }
    }

    /// The per-axis 3-point fit this estimator uses (and the 2-D Gaussian falls back to).
    pub fn per_axis(self) -> SubPixelFit {
        match self {
            SubPixelFit::Gaussian2d => SubPixelFit::Gaussian3,
            fit => fit,
        }
    }

    /// Parse `gauss3`, `parabolic`, `gauss2d` (and the serde names).
    pub fn parse(text: &str) -> Option<Self> {
        match text {
            "gauss3" | "gaussian3" | "gaussian" => Some(SubPixelFit::Gaussian3),
            "parabolic" | "parabolic3" | "parabola" => Some(SubPixelFit::Parabolic3),
            "gauss2d" | "gaussian2d" => Some(SubPixelFit::Gaussian2d),
            _ => None,
        }
    }
}

/// A located peak.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Column of the integer maximum.
    pub col: usize,
    /// Row of the integer maximum.
    pub row: usize,
    /// Sub-pixel position along columns (`col` + fitted offset).
    pub x: f64,
    /// Sub-pixel position along rows.
    pub y: f64,
    /// Value at the integer maximum.
    pub value: f64,
    /// The maximum lies on the border of the map: no fit was possible there and the true
    /// peak may lie outside.
    pub on_edge: bool,
    /// Highest local maximum outside the exclusion zone around the first (NaN if none).
    pub second: f64,
}

impl Peak {
    /// First-to-second peak ratio, NaN where the second peak is missing or not positive.
    pub fn ratio(&self) -> f64 {
        if self.second > 0.0 && self.value.is_finite() {
            self.value / self.second
        } else {
            f64::NAN
        }
    }
}

/// Offset of the extremum of three equally spaced samples `a, b, c` (at −1, 0, +1) from the
/// centre, in sample steps; `None` if `b` is not a strict maximum of a concave triple.
pub fn three_point(a: f64, b: f64, c: f64, fit: SubPixelFit) -> Option<f64> {
    if !(a.is_finite() && b.is_finite() && c.is_finite()) || b < a || b < c {
        return None;
    }
    let gaussian = fit != SubPixelFit::Parabolic3 && a > 0.0 && b > 0.0 && c > 0.0;
    let (a, b, c) = if gaussian {
        (a.ln(), b.ln(), c.ln())
    } else {
        (a, b, c)
    };
    let denominator = 2.0 * a - 4.0 * b + 2.0 * c;
    if denominator >= 0.0 {
        return (a == b && b == c).then_some(0.0);
    }
    let d = (a - c) / denominator;
    (d.abs() <= 1.0).then_some(d)
}

/// 2-D Gaussian fit of the 3 × 3 neighbourhood `n[row][col]` centred on the maximum, after
/// Nobach & Honkanen (2005): least squares of a quadratic to the logarithms. `None` where a
/// value is not positive or the quadratic is not a maximum.
pub fn gaussian_2d(n: [[f64; 3]; 3]) -> Option<(f64, f64)> {
    let mut l = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            if n[r][c].is_nan() || n[r][c] <= 0.0 {
                return None;
            }
            l[r][c] = n[r][c].ln();
        }
    }
    // Least-squares coefficients of ln f = c0 + cx x + cy y + cxx x² + cyy y² + cxy x y.
    let (mut cx, mut cy, mut cxy, mut cxx, mut cyy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (r, row) in l.iter().enumerate() {
        for (c, &v) in row.iter().enumerate() {
            let (x, y) = (c as f64 - 1.0, r as f64 - 1.0);
            cx += x * v / 6.0;
            cy += y * v / 6.0;
            cxy += x * y * v / 4.0;
            cxx += (3.0 * x * x - 2.0) * v / 6.0;
            cyy += (3.0 * y * y - 2.0) * v / 6.0;
        }
    }
    let det = 4.0 * cxx * cyy - cxy * cxy;
    if cxx >= 0.0 || det <= 0.0 || cxx.is_nan() || det.is_nan() {
        return None;
    }
    let dx = (cxy * cy - 2.0 * cyy * cx) / det;
    let dy = (cxy * cx - 2.0 * cxx * cy) / det;
    (dx.abs() <= 1.0 && dy.abs() <= 1.0).then_some((dx, dy))
}

/// Sub-pixel offset `[dx, dy]` of the maximum at the centre of the 3 × 3 neighbourhood
/// `n[row][col]`: the 2-D Gaussian for [`SubPixelFit::Gaussian2d`] where it succeeds, else
/// three-point fits per axis (0 where those fail), as [`find_peak`] fits.
pub fn fit_offsets(n: [[f64; 3]; 3], fit: SubPixelFit) -> [f64; 2] {
    if fit == SubPixelFit::Gaussian2d {
        if let Some((dx, dy)) = gaussian_2d(n) {
            return [dx, dy];
        }
    }
    let fit1 = fit.per_axis();
    [
        three_point(n[1][0], n[1][1], n[1][2], fit1).unwrap_or(0.0),
        three_point(n[0][1], n[1][1], n[2][1], fit1).unwrap_or(0.0),
    ]
}

/// Locate the maximum of a `width` × `height` row-major map, fit it to sub-pixel accuracy,
/// and find the second-highest local maximum at least `exclusion` samples (Chebyshev
/// distance) away. `None` for an empty map or one without a finite value.
pub fn find_peak(
    map: &[f64],
    width: usize,
    height: usize,
    fit: SubPixelFit,
    exclusion: usize,
) -> Option<Peak> {
    if width == 0 || height == 0 || map.len() < width * height {
        return None;
    }
    let best = argmax(&map[..width * height])?;
    peak_at(map, [width, height], best, fit, exclusion, None)
}

/// Index of the first maximum of `map` (the first value greater than all before it), `None`
/// if no value exceeds −∞ (empty, or all NaN / −∞).
pub fn argmax(map: &[f64]) -> Option<usize> {
    let (mut best, mut value) = (None, f64::NEG_INFINITY);
    for (i, &m) in map.iter().enumerate() {
        if m > value {
            value = m;
            best = Some(i);
        }
    }
    best
}

/// [`find_peak`] for a map whose maximum is already known to be at index `best` (as
/// [`argmax`] finds it, e.g. tracked while the map was computed). With the map's row maxima
/// (`row_max[r]`: the largest value of row `r` as [`argmax`] compares, −∞ if none; a NaN
/// only makes its row be scanned), as a kernel can track them while computing the map, the
/// search for the second peak scans only the rows whose maximum may exceed it
/// ([`second_peak`]); the peak is the same. `None` for an empty map, a
/// map shorter than `width × height`, `best` outside it, or `row_max` shorter than the map.
pub fn peak_at(
    map: &[f64],
    [width, height]: [usize; 2],
    best: usize,
    fit: SubPixelFit,
    exclusion: usize,
    row_max: Option<&[f64]>,
) -> Option<Peak> {
    let valid_map = width > 0 && height > 0 && map.len() >= width * height;
    if !valid_map || best >= width * height || row_max.is_some_and(|m| m.len() < height) {
        return None;
    }
    let at = [best / width, best % width];
    Some(fitted_peak(
        map,
        [width, height],
        at,
        fit,
        exclusion,
        row_max,
    ))
}

/// The peak at the integer maximum `[row, col]` of the map: sub-pixel fit where it is not on
/// the map's border, and the second peak outside `exclusion` of it (with the row maxima,
/// if known, as in [`peak_at`]).
fn fitted_peak(
    map: &[f64],
    [width, height]: [usize; 2],
    [row, col]: [usize; 2],
    fit: SubPixelFit,
    exclusion: usize,
    row_max: Option<&[f64]>,
) -> Peak {
    let at = |r: usize, c: usize| map[r * width + c];
    let value = at(row, col);
    let on_edge_x = col == 0 || col + 1 == width;
    let on_edge_y = row == 0 || row + 1 == height;
    let mut x = col as f64;
    let mut y = row as f64;
    if !on_edge_x && !on_edge_y {
        let mut n = [[0.0; 3]; 3];
        for (dr, nr) in n.iter_mut().enumerate() {
            for (dc, v) in nr.iter_mut().enumerate() {
                *v = at(row + dr - 1, col + dc - 1);
            }
        }
        let [dx, dy] = fit_offsets(n, fit);
        x += dx;
        y += dy;
    } else {
        let fit1 = fit.per_axis();
        if !on_edge_x {
            x += three_point(at(row, col - 1), value, at(row, col + 1), fit1).unwrap_or(0.0);
        }
        if !on_edge_y {
            y += three_point(at(row - 1, col), value, at(row + 1, col), fit1).unwrap_or(0.0);
        }
    }
    let second = second_peak(map, [width, height], [row, col], exclusion, row_max);
    Peak {
        col,
        row,
        x,
        y,
        value,
        on_edge: on_edge_x || on_edge_y,
        second,
    }
}

/// The highest local maximum of the map (≥ its 8 neighbours, all finite) among the cells
/// strictly inside the box of columns `cols` and rows `rows` (clamped to the map), fitted as
/// by [`find_peak`]; `None` if the box holds no such maximum. A maximum that is only the
/// flank of a higher peak outside the box is no local maximum, so the box never turns a
/// slope into a peak. `second` is the highest other local maximum of the whole map (outside
/// `exclusion`), so [`Peak::ratio`] is below 1 when a higher peak lies elsewhere.
pub fn find_peak_within(
    map: &[f64],
    width: usize,
    height: usize,
    fit: SubPixelFit,
    exclusion: usize,
    cols: std::ops::Range<usize>,
    rows: std::ops::Range<usize>,
) -> Option<Peak> {
    if width == 0 || height == 0 || map.len() < width * height {
        return None;
    }
    let inside = |r: std::ops::Range<usize>, n: usize| r.start + 1..r.end.min(n).saturating_sub(1);
    let mut best: Option<[usize; 2]> = None;
    let mut value = f64::NEG_INFINITY;
    for row in inside(rows, height) {
        for col in inside(cols.clone(), width) {
            let v = map[row * width + col];
            if v > value && is_local_max(map, [width, height], [row, col], v) {
                value = v;
                best = Some([row, col]);
            }
        }
    }
    Some(fitted_peak(
        map,
        [width, height],
        best?,
        fit,
        exclusion,
        None,
    ))
}

/// True if `v` (the finite value at `[row, col]`) is ≥ each of its up to 8 neighbours, none
/// of them NaN.
#[inline(always)]
fn is_local_max(map: &[f64], [width, height]: [usize; 2], [row, col]: [usize; 2], v: f64) -> bool {
    if row > 0 && col > 0 && row + 1 < height && col + 1 < width {
        // Inside the map (the usual case): the row neighbours first, as most candidates of a
        // scan along rows that are no maximum lie on a slope along the row, then the rows
        // above and below.
        let around = &map[(row - 1) * width..(row + 2) * width];
        let c = width + col;
        let below = |k: usize| around[k] <= v;
        return v.is_finite()
            && below(c + 1)
            && below(c - 1)
            && below(c - width - 1)
            && below(c - width)
            && below(c - width + 1)
            && below(c + width - 1)
            && below(c + width)
            && below(c + width + 1);
    }
    v.is_finite()
        && (row.saturating_sub(1)..(row + 2).min(height))
            .all(|r| (col.saturating_sub(1)..(col + 2).min(width)).all(|c| map[r * width + c] <= v))
}

/// Index of the first value of `values` for which `holds` is true, as
/// `values.iter().position(|&v| holds(v))`, but testing `LANES` values at a time with one
/// branch (the test of a chunk compiles to vector comparisons): scans that pass over most
/// values whole (the second-peak search, the vote map's maxima) pay one branch per chunk.
pub(crate) fn first_where<T: Copy, const LANES: usize>(
    values: &[T],
    holds: impl Fn(T) -> bool,
) -> Option<usize> {
    let mut chunks = values.chunks_exact(LANES);
    let mut offset = 0;
    for chunk in &mut chunks {
        if chunk.iter().fold(false, |any, &v| any | holds(v)) {
            return chunk.iter().position(|&v| holds(v)).map(|k| offset + k);
        }
        offset += LANES;
    }
    let rest = chunks.remainder();
    rest.iter().position(|&v| holds(v)).map(|k| offset + k)
}

/// Index of the first value of `line` above `threshold` (NaN never is), four at a time
/// ([`first_where`]): most of a plane lies below the second peak found so far.
fn first_above(line: &[f64], threshold: f64) -> Option<usize> {
    first_where::<_, 4>(line, |v| v > threshold)
}

/// Highest finite local maximum (≥ its 8 neighbours, none NaN) farther than `exclusion`
/// (Chebyshev) from `(row, col)`, NaN if none. Only cells above the best found so far are
/// tested for being local maxima, and a tight search ([`first_above`]) skips to the next
/// such cell, so the scan costs little more than one comparison per cell; equal to the plain
/// scan of every cell ([`second_peak_reference`], tested). With the maxima of the rows
/// (`row_max`, see [`peak_at`]) the rows are visited from the highest maximum down, and the
/// visit ends at the first row none of whose values exceeds the second peak so far: the
/// peak's own rows and the few holding the highest side peaks are scanned, the rest of the
/// plane is not (the value is a maximum over the same cells in any order; of side peaks of
/// equal value, +0 and −0, the first visited is returned).
fn second_peak(
    map: &[f64],
    [width, height]: [usize; 2],
    [row, col]: [usize; 2],
    exclusion: usize,
    row_max: Option<&[f64]>,
) -> f64 {
    let mut scan = SideScan {
        map,
        size: [width, height],
        peak: [row, col],
        exclusion,
        second: f64::NEG_INFINITY,
        found: false,
    };
    match row_max {
        Some(maxima) if (1..=ORDERED_ROWS).contains(&height) => {
            // A NaN row maximum says nothing: that row is visited first (as +∞).
            let mut pending = [f64::NEG_INFINITY; ORDERED_ROWS];
            for (p, &m) in pending.iter_mut().zip(&maxima[..height]) {
                *p = if m.is_nan() { f64::INFINITY } else { m };
            }
            let pending = &mut pending[..height];
            loop {
                let (r, highest) = highest_row(pending);
                // (Neither is NaN: NaN maxima became +∞ above, and the second peak so far
                // is −∞ or a finite value.)
                if highest <= scan.second {
                    break;
                }
                pending[r] = f64::NEG_INFINITY;
                scan.row(r);
            }
        }
        _ => {
            for r in 0..height {
                if row_max.is_some_and(|m| m[r] <= scan.second) {
                    continue;
                }
                scan.row(r);
            }
        }
    }
    if scan.found {
        scan.second
    } else {
        f64::NAN
    }
}

/// Planes up to this many rows have their rows visited in order of their maxima by
/// [`second_peak`] (the order is kept on the stack); taller ones row by row.
const ORDERED_ROWS: usize = 64;

/// The first index of the highest value of `values` (not empty, no NaN) and the value.
///
/// The highest value first, in two lanes without a branch per value (`maxpd`), then the
/// first value equal to it, four at a time ([`first_where`]): the index a scan keeping the
/// first strictly higher value finds (+0 and −0 compare equal in both), in a fraction of
/// its instructions, as the second-peak search asks again after every row it visits.
fn highest_row(values: &[f64]) -> (usize, f64) {
    // (No NaN: `if v > m` is then the maximum.)
    let higher = |m: f64, v: f64| if v > m { v } else { m };
    let mut lanes = [values[0]; 2];
    let mut pairs = values.chunks_exact(2);
    for pair in &mut pairs {
        lanes[0] = higher(lanes[0], pair[0]);
        lanes[1] = higher(lanes[1], pair[1]);
    }
    let highest = pairs
        .remainder()
        .iter()
        .fold(higher(lanes[0], lanes[1]), |m, &v| higher(m, v));
    // (Always found: `highest` is one of the values, none NaN.)
    let first = first_where::<_, 4>(values, |v| v == highest).unwrap_or(0);
    (first, values[first])
}

/// The state of [`second_peak`]'s scan: the highest local maximum outside the exclusion
/// box found so far.
struct SideScan<'a> {
    map: &'a [f64],
    size: [usize; 2],
    peak: [usize; 2],
    exclusion: usize,
    second: f64,
    found: bool,
}

impl SideScan<'_> {
    /// Test the cells of row `r` outside the exclusion box that exceed the second peak so
    /// far.
    fn row(&mut self, r: usize) {
        let [width, height] = self.size;
        let [row, col] = self.peak;
        let line = &self.map[r * width..(r + 1) * width];
        let (left_end, right_start) = (
            col.saturating_sub(self.exclusion),
            col.saturating_add(self.exclusion).saturating_add(1),
        );
        let segments = if r.abs_diff(row) <= self.exclusion {
            [0..left_end.min(width), right_start.min(width)..width]
        } else {
            [0..width, width..width]
        };
        for segment in segments {
            let mut c = segment.start;
            // Only values above the current second peak (NaN fails `>`).
            while let Some(k) = first_above(&line[c..segment.end], self.second) {
                c += k;
                let v = line[c];
                if v.is_finite() && is_local_max(self.map, [width, height], [r, c], v) {
                    self.second = v;
                    self.found = true;
                }
                c += 1;
            }
        }
    }
}

#[cfg(test)]
/// The plain scan [`second_peak`] must equal: every cell tested.
fn second_peak_reference(
    map: &[f64],
    width: usize,
    height: usize,
    row: usize,
    col: usize,
    exclusion: usize,
) -> f64 {
    let mut second = f64::NAN;
    for r in 0..height {
        for c in 0..width {
            if r.abs_diff(row) <= exclusion && c.abs_diff(col) <= exclusion {
                continue;
            }
            let v = map[r * width + c];
            if !(v > second || second.is_nan()) || !v.is_finite() {
                continue;
            }
            let is_local_max = (r.saturating_sub(1)..(r + 2).min(height)).all(|rr| {
                (c.saturating_sub(1)..(c + 2).min(width)).all(|cc| map[rr * width + cc] <= v)
            });
            if is_local_max {
                second = v;
            }
        }
    }
    second
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::xorshift;

    fn gaussian_map(w: usize, h: usize, cx: f64, cy: f64, sx: f64, sy: f64) -> Vec<f64> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (-(x - cx).powi(2) / (2.0 * sx * sx) - (y - cy).powi(2) / (2.0 * sy * sy)).exp()
            })
            .collect()
    }

    #[test]
    fn three_point_gaussian_is_exact_for_gaussians() {
        for &d in &[-0.45, -0.2, 0.0, 0.13, 0.49] {
            let g = |x: f64| (-(x - d).powi(2) / 2.0).exp();
            let got = three_point(g(-1.0), g(0.0), g(1.0), SubPixelFit::Gaussian3).unwrap();
            assert!((got - d).abs() < 1e-12, "{got} vs {d}");
        }
        let p = |x: f64| 5.0 - (x - 0.3).powi(2);
        let got = three_point(p(-1.0), p(0.0), p(1.0), SubPixelFit::Parabolic3).unwrap();
        assert!((got - 0.3).abs() < 1e-12);
        // Non-positive values fall back to the parabola.
        let q = |x: f64| -(x - 0.2).powi(2);
        let got = three_point(q(-1.0), q(0.0), q(1.0), SubPixelFit::Gaussian3).unwrap();
        assert!((got - 0.2).abs() < 1e-12);
        assert_eq!(three_point(1.0, 0.5, 0.2, SubPixelFit::Gaussian3), None);
    }

    #[test]
    fn gaussian_2d_recovers_tilted_peaks_and_falls_back() {
        let m = gaussian_map(9, 7, 4.3, 2.8, 1.2, 0.9);
        let p = find_peak(&m, 9, 7, SubPixelFit::Gaussian2d, 2).unwrap();
        assert!(
            (p.x - 4.3).abs() < 1e-9 && (p.y - 2.8).abs() < 1e-9,
            "{p:?}"
        );
        let p3 = find_peak(&m, 9, 7, SubPixelFit::Gaussian3, 2).unwrap();
        assert!((p3.x - 4.3).abs() < 1e-9 && (p3.y - 2.8).abs() < 1e-9);
        // A rotated elliptic peak: the 2-D fit is exact, the axis-wise fit is not.
        let rot: Vec<f64> = (0..81)
            .map(|i| {
                let (x, y) = ((i % 9) as f64 - 4.2, (i / 9) as f64 - 3.7);
                let (a, b) = (x + y, x - y);
                (-(a * a) / 6.0 - b * b / 1.0).exp()
            })
            .collect();
        let p = find_peak(&rot, 9, 9, SubPixelFit::Gaussian2d, 2).unwrap();
        assert!(
            (p.x - 4.2).abs() < 1e-9 && (p.y - 3.7).abs() < 1e-9,
            "{p:?}"
        );
    }

    #[test]
    fn edge_peaks_are_flagged_and_second_peak_found() {
        let mut m = gaussian_map(8, 8, 0.0, 3.0, 1.0, 1.0);
        let p = find_peak(&m, 8, 8, SubPixelFit::Gaussian3, 2).unwrap();
        assert!(p.on_edge);
        assert_eq!(p.x, 0.0);
        m[6 * 8 + 6] += 0.25;
        let p = find_peak(&m, 8, 8, SubPixelFit::Gaussian3, 2).unwrap();
        assert!((p.ratio() - 1.0 / (0.25 + m[6 * 8 + 6] - 0.25)).abs() < 1e-9);
        assert!(find_peak(&[], 0, 0, SubPixelFit::Gaussian3, 1).is_none());
        assert!(find_peak(&[f64::NAN; 4], 2, 2, SubPixelFit::Gaussian3, 1).is_none());
    }

    #[test]
    fn restricted_search_finds_the_lower_peak_inside_its_box() {
        // A high peak at (3, 3) and a lower one at (12.3, 11.6) on a 16 × 16 map.
        let mut m = gaussian_map(16, 16, 3.0, 3.0, 1.0, 1.0);
        let low = gaussian_map(16, 16, 12.3, 11.6, 1.0, 1.0);
        for (a, b) in m.iter_mut().zip(&low) {
            *a += 0.5 * b;
        }
        let fit = SubPixelFit::Gaussian3;
        let p = find_peak_within(&m, 16, 16, fit, 2, 9..16, 8..15).unwrap();
        assert_eq!((p.col, p.row), (12, 12));
        assert!(!p.on_edge);
        assert!(
            (p.x - 12.3).abs() < 0.01 && (p.y - 11.6).abs() < 0.01,
            "{p:?}"
        );
        assert_eq!(p.value, m[12 * 16 + 12]);
        // Its ratio compares it with the higher peak elsewhere in the map.
        assert!(
            (p.ratio() - m[12 * 16 + 12] / m[3 * 16 + 3]).abs() < 1e-12,
            "{p:?}"
        );
        // The whole map as the box: the highest peak, ratio above 1.
        let q = find_peak_within(&m, 16, 16, fit, 2, 0..16, 0..16).unwrap();
        assert_eq!((q.col, q.row), (3, 3));
        assert!(q.ratio() > 1.0);
        // A box on the high peak's flank holds no local maximum; neither do boxes without an
        // interior (2 cells wide) or outside the map.
        assert!(find_peak_within(&m, 16, 16, fit, 2, 5..9, 0..8).is_none());
        assert!(find_peak_within(&m, 16, 16, fit, 2, 2..4, 2..5).is_none());
        assert!(find_peak_within(&m, 16, 16, fit, 2, 20..30, 0..4).is_none());
        // Boxes are clamped to the map.
        assert!(find_peak_within(&m, 16, 16, fit, 2, 10..99, 10..99).is_some());
    }

    #[test]
    fn first_above_equals_position() {
        let line = [
            0.0,
            f64::NAN,
            2.0,
            -1.0,
            3.0,
            1.0,
            f64::INFINITY,
            0.5,
            2.5,
            -0.0,
            1.5,
        ];
        let thresholds = [
            f64::NEG_INFINITY,
            -2.0,
            0.0,
            1.0,
            2.0,
            2.5,
            3.0,
            f64::INFINITY,
        ];
        for start in 0..line.len() {
            for end in start..=line.len() {
                for t in thresholds {
                    let part = &line[start..end];
                    let plain = part.iter().position(|&v| v > t);
                    assert_eq!(first_above(part, t), plain, "{start}..{end} above {t}");
                }
            }
        }
    }

    /// The two-lane maximum finds the index and value the plain scan keeps (the first of
    /// the highest values), with ties, infinities and both zeros, at every length.
    #[test]
    fn highest_row_equals_the_plain_scan() {
        let mut next = xorshift(11);
        for case in 0..2000usize {
            let values: Vec<f64> = (0..1 + case % 70)
                .map(|_| match next() % 12 {
                    0 => f64::INFINITY,
                    1 => f64::NEG_INFINITY,
                    2 => -0.0,
                    3 => 0.0,
                    k => (k % 5) as f64 - 2.0,
                })
                .collect();
            let mut plain = (0, values[0]);
            for (i, &v) in values.iter().enumerate().skip(1) {
                if v > plain.1 {
                    plain = (i, v);
                }
            }
            let fast = highest_row(&values);
            assert_eq!(fast.0, plain.0, "case {case}: {values:?}");
            assert_eq!(fast.1.to_bits(), plain.1.to_bits(), "case {case}");
        }
    }

    #[test]
    fn second_peak_equals_the_plain_scan() {
        let mut next = xorshift(7);
        for case in 0..400usize {
            // Some planes taller than ORDERED_ROWS, whose rows are visited in order.
            let (w, h) = if case % 50 == 49 {
                (5, ORDERED_ROWS + 1 + case % 7)
            } else {
                (1 + case % 13, 1 + (case / 13) % 11)
            };
            let plane: Vec<f64> = (0..w * h)
                .map(|_| match next() % 50 {
                    0 => f64::NAN,
                    1 => f64::INFINITY,
                    2 => f64::NEG_INFINITY,
                    k => (k % 9) as f64 - 3.0 + if case % 2 == 0 { 0.0 } else { 0.1 * k as f64 },
                })
                .collect();
            // Also without NaN and with ties.
            let clean: Vec<f64> = plane
                .iter()
                .map(|&v| if v.is_nan() { 0.0 } else { v })
                .collect();
            let rounded: Vec<f64> = clean.iter().map(|&v| v.round()).collect();
            for map in [&plane, &clean, &rounded] {
                for (row, col) in [(0, 0), (h / 2, w / 2), (h - 1, w - 1)] {
                    for exclusion in [0, 1, 2] {
                        let fast = second_peak(map, [w, h], [row, col], exclusion, None);
                        let slow = second_peak_reference(map, w, h, row, col, exclusion);
                        assert_eq!(format!("{fast:?}"), format!("{slow:?}"), "case {case}");
                        // The row maxima as a kernel tracks them: only a skip.
                        let row_max: Vec<f64> = map
                            .chunks(w)
                            .map(|line| {
                                let above = |m: f64, &v: &f64| if v > m { v } else { m };
                                line.iter().fold(f64::NEG_INFINITY, above)
                            })
                            .collect();
                        let bounded =
                            second_peak(map, [w, h], [row, col], exclusion, Some(&row_max));
                        // (By value: of equal side peaks +0 and −0 the order decides.)
                        assert!(
                            bounded == slow || bounded.is_nan() && slow.is_nan(),
                            "case {case}"
                        );
                        // A NaN row maximum only costs the skip of its row.
                        let mut unknown = row_max.clone();
                        unknown[case % h] = f64::NAN;
                        let partly =
                            second_peak(map, [w, h], [row, col], exclusion, Some(&unknown));
                        assert!(
                            partly == slow || partly.is_nan() && slow.is_nan(),
                            "case {case}"
                        );
                    }
                }
            }
        }
    }
}
