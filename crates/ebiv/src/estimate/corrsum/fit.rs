//! Sub-pixel refinement of tilted, narrow correlation peaks.

use crate::estimate::peak::{Peak, SubPixelFit};

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
