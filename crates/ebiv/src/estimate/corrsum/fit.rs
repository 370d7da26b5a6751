//! Sub-pixel refinement of tilted, narrow correlation peaks.

use crate::estimate::peak::{gaussian_2d, three_point, Peak, SubPixelFit};

/// Peak position. For the 2-D Gaussian fit, a log-domain least-squares Gaussian over the
/// positive values of the 3 × 3 neighbourhood, weighted by value² (Nobach & Honkanen 2005):
/// beside the narrow, tilted peaks of event correlation one of the nine values is often not
/// positive, and [`find_peak`](crate::estimate::peak::find_peak)'s axis-wise fall-back is then biased (up to 0.3 px).
pub(super) fn refine_tilted(
    plane: &[f64],
    width: usize,
    peak: &Peak,
    fit: SubPixelFit,
) -> [f64; 2] {
    if fit != SubPixelFit::Gaussian2d || peak.on_edge {
        return [peak.x, peak.y];
    }
    // Normal equations of ln f = c0 + c1 x + c2 y + c3 x² + c4 y² + c5 x y.
    let mut m = [[0.0f64; 7]; 6];
    let mut points = 0;
    for r in 0..3 {
        for c in 0..3 {
            let v = plane[(peak.row + r - 1) * width + peak.col + c - 1];
            if v.is_nan() || v <= 0.0 {
                continue;
            }
            points += 1;
            let (x, y) = (c as f64 - 1.0, r as f64 - 1.0);
            let basis = [1.0, x, y, x * x, y * y, x * y];
            let w = v * v;
            for i in 0..6 {
                for j in 0..6 {
                    m[i][j] += w * basis[i] * basis[j];
                }
                m[i][6] += w * basis[i] * v.ln();
            }
        }
    }
    let solved = (points >= 6).then(|| solve6(m)).flatten();
    let Some([_, cx, cy, cxx, cyy, cxy]) = solved else {
        return [peak.x, peak.y];
    };
    let det = 4.0 * cxx * cyy - cxy * cxy;
    if !(cxx < 0.0 && det > 0.0) {
        return [peak.x, peak.y];
    }
    let dx = (cxy * cy - 2.0 * cyy * cx) / det;
    let dy = (cxy * cx - 2.0 * cxx * cy) / det;
    if dx.abs() <= 1.0 && dy.abs() <= 1.0 {
        [peak.col as f64 + dx, peak.row as f64 + dy]
    } else {
        [peak.x, peak.y]
    }
}

/// Solve the 6 × 6 system in the augmented matrix `m` by Gaussian elimination with partial
/// pivoting; `None` if singular.
fn solve6(mut m: [[f64; 7]; 6]) -> Option<[f64; 6]> {
    for col in 0..6 {
        let pivot = (col..6).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        let size = m[pivot][col].abs();
        if size.is_nan() || size <= 1e-12 * m[0][0].abs() {
            return None;
        }
        m.swap(col, pivot);
        for row in col + 1..6 {
            let f = m[row][col] / m[col][col];
            let pivot_row = m[col];
            for (x, p) in m[row].iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
        }
    }
    let mut x = [0.0; 6];
    for row in (0..6).rev() {
        let s: f64 = (row + 1..6).map(|k| m[row][k] * x[k]).sum();
        x[row] = (m[row][6] - s) / m[row][row];
    }
    Some(x)
}

/// The same peak as [`find_peak`](crate::estimate::peak::find_peak) (maximum, sub-pixel fit
/// and second peak) for a non-empty `width` × `height` plane, with a cheaper second-peak
/// scan: the excluded block is skipped by ranges instead of tested per cell, and the
/// neighbourhood is only examined for cells above the current second peak.
pub(super) fn find_peak_fast(
    map: &[f64],
    width: usize,
    height: usize,
    fit: SubPixelFit,
    exclusion: usize,
) -> Option<Peak> {
    if width == 0 || height == 0 || map.len() < width * height {
        return None;
    }
    let map = &map[..width * height];
    let (mut best, mut value) = (usize::MAX, f64::NEG_INFINITY);
    for (i, &m) in map.iter().enumerate() {
        if m > value {
            value = m;
            best = i;
        }
    }
    if best == usize::MAX {
        return None;
    }
    let (row, col) = (best / width, best % width);
    let at = |r: usize, c: usize| map[r * width + c];
    let on_edge_x = col == 0 || col + 1 == width;
    let on_edge_y = row == 0 || row + 1 == height;
    let mut x = col as f64;
    let mut y = row as f64;
    let mut fitted = false;
    if fit == SubPixelFit::Gaussian2d && !on_edge_x && !on_edge_y {
        let mut n = [[0.0; 3]; 3];
        for (dr, nr) in n.iter_mut().enumerate() {
            for (dc, v) in nr.iter_mut().enumerate() {
                *v = at(row + dr - 1, col + dc - 1);
            }
        }
        if let Some((dx, dy)) = gaussian_2d(n) {
            x += dx;
            y += dy;
            fitted = true;
        }
    }
    if !fitted {
        let fit1 = if fit == SubPixelFit::Gaussian2d {
            SubPixelFit::Gaussian3
        } else {
            fit
        };
        if !on_edge_x {
            x += three_point(at(row, col - 1), value, at(row, col + 1), fit1).unwrap_or(0.0);
        }
        if !on_edge_y {
            y += three_point(at(row - 1, col), value, at(row + 1, col), fit1).unwrap_or(0.0);
        }
    }
    let second = second_peak(map, width, height, row, col, exclusion);
    Some(Peak {
        col,
        row,
        x,
        y,
        value,
        on_edge: on_edge_x || on_edge_y,
        second,
    })
}

/// Highest finite local maximum (≥ its 8 neighbours, none NaN) farther than `exclusion`
/// (Chebyshev) from `(row, col)`, NaN if none: the order-independent result of the peak
/// module's row-major scan.
fn second_peak(
    map: &[f64],
    width: usize,
    height: usize,
    row: usize,
    col: usize,
    exclusion: usize,
) -> f64 {
    let mut second = f64::NEG_INFINITY;
    let mut found = false;
    let (ex0, ex1) = (
        col.saturating_sub(exclusion),
        (col + exclusion + 1).min(width),
    );
    for r in 0..height {
        let line = &map[r * width..(r + 1) * width];
        let excluded = r.abs_diff(row) <= exclusion;
        let (first, rest) = if excluded {
            ((0, ex0), (ex1, width))
        } else {
            ((0, width), (width, width))
        };
        for (c0, c1) in [first, rest] {
            for (c, &v) in line.iter().enumerate().take(c1).skip(c0) {
                // Only finite values above the current second peak (NaN fails `>`).
                if v.partial_cmp(&second) != Some(std::cmp::Ordering::Greater) || !v.is_finite() {
                    continue;
                }
                let is_local_max = (r.saturating_sub(1)..(r + 2).min(height)).all(|rr| {
                    (c.saturating_sub(1)..(c + 2).min(width)).all(|cc| map[rr * width + cc] <= v)
                });
                if is_local_max {
                    second = v;
                    found = true;
                }
            }
        }
    }
    if found {
        second
    } else {
        f64::NAN
    }
}
