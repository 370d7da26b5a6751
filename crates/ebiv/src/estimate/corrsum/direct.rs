//! Direct kernel: the summed, mean-subtracted linear correlation accumulated over the voxel
//! pairs of each slice (spatial-domain correlation, Raffel et al. 2018 §5.3; fast when a
//! slice holds few voxels, as EBIV windows usually do).
//!
//! For lag `Δ` and overlap region `O(Δ) = {p : p, p + Δ in the window}` of `n(Δ)` pixels,
//!
//! ```text
//! Σ_O (a − ā)(b(·+Δ) − b̄) = Σ_O a·b(·+Δ) − b̄ Σ_O a − ā Σ_O b(·+Δ) + n(Δ) ā b̄.
//! ```
//!
//! The first term is a sum over voxel pairs; the middle terms add a constant over a rectangle
//! of lags per voxel (accumulated in a 2-D difference array); the last is analytic.

use super::voxels::{normalise, PlaneShape, SliceStats, Voxels};

/// Fill `plane` with the normalised correlation of the slices in `stats`; `diff` is
/// `(pw + 1) × (ph + 1)` working memory.
pub(super) fn correlate(
    a: &Voxels,
    b: &Voxels,
    stats: &[SliceStats],
    shape: PlaneShape,
    plane: &mut [f64],
    diff: &mut [f64],
) {
    let (pw, ph) = (shape.plane_width(), shape.plane_height());
    let dw = pw + 1;
    plane.fill(0.0);
    diff.fill(0.0);
    let (rx, ry) = (shape.rx as isize, shape.ry as isize);
    let (w, h) = (shape.w as isize, shape.h as isize);
    let mut constant = 0.0;
    let mut add_rect = |x0: isize, x1: isize, y0: isize, y1: isize, c: f64| {
        let (x0, x1) = (x0.max(0) as usize, x1.min(2 * rx) as usize + 1);
        let (y0, y1) = (y0.max(0) as usize, y1.min(2 * ry) as usize + 1);
        diff[y0 * dw + x0] += c;
        diff[y0 * dw + x1] -= c;
        diff[y1 * dw + x0] -= c;
        diff[y1 * dw + x1] += c;
    };
    for s in stats {
        let (ra, rb) = (a.range(s.z), b.range(s.z));
        for i in ra.clone() {
            let (xa, ya) = (a.x[i] as isize - rx, a.y[i] as isize - ry);
            let wa = s.weight * a.v[i];
            for j in rb.clone() {
                let ix = (b.x[j] as isize - xa) as usize;
                let iy = (b.y[j] as isize - ya) as usize;
                if ix < pw && iy < ph {
                    plane[iy * pw + ix] += wa * b.v[j];
                }
            }
            // Σ_O a: voxel p counts for the lags with p + Δ inside the window.
            let (x, y) = (a.x[i] as isize, a.y[i] as isize);
            let c = -s.weight * s.mean_b * a.v[i];
            add_rect(rx - x, rx + w - 1 - x, ry - y, ry + h - 1 - y, c);
        }
        // Σ_O b(·+Δ): voxel q counts for the lags with q − Δ inside the window.
        for j in rb {
            let (x, y) = (b.x[j] as isize, b.y[j] as isize);
            let c = -s.weight * s.mean_a * b.v[j];
            add_rect(rx + x - w + 1, rx + x, ry + y - h + 1, ry + y, c);
        }
        constant += s.weight * s.mean_a * s.mean_b;
    }
    // Prefix sums turn the difference array into the per-lag values.
    for iy in 0..ph {
        let mut run = 0.0;
        for ix in 0..pw {
            run += diff[iy * dw + ix];
            diff[iy * dw + ix] = run
                + if iy > 0 {
                    diff[(iy - 1) * dw + ix]
                } else {
                    0.0
                };
        }
    }
    for iy in 0..ph {
        let oy = (shape.h - iy.abs_diff(shape.ry)) as f64;
        for ix in 0..pw {
            let ox = (shape.w - ix.abs_diff(shape.rx)) as f64;
            plane[iy * pw + ix] += diff[iy * dw + ix] + ox * oy * constant;
        }
    }
    normalise(plane, shape, stats.len());
}
