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

use super::voxels::{PlaneShape, SliceStats, Voxels};

/// Voxels of a `b` slice from which the pair loop visits them sorted by row.
const SORT_MIN_VOXELS: usize = 32;

/// Fill `plane` with the normalised correlation of the slices in `stats`; `diff` is
/// `(pw + 1) × (ph + 1)` working memory, `sorted` holds one slice's `b` voxels by row.
pub(super) fn correlate(
    a: &Voxels,
    b: &Voxels,
    stats: &[SliceStats],
    shape: PlaneShape,
    plane: &mut [f64],
    diff: &mut [f64],
    sorted: &mut Vec<(u16, u16, f64)>,
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
        let (bx, by, bv) = (&b.x[rb.clone()], &b.y[rb.clone()], &b.v[rb.clone()]);
        // For a fixed `a` voxel every `b` voxel hits a different lag, so visiting them by
        // row (only the rows within the search radius) leaves every sum unchanged; worth the
        // sort only for slices with many voxels.
        let by_row = bx.len() >= SORT_MIN_VOXELS;
        if by_row {
            sorted.clear();
            sorted.extend(bx.iter().zip(by).zip(bv).map(|((&x, &y), &v)| (x, y, v)));
            sorted.sort_unstable_by_key(|q| q.1);
        }
        for i in ra {
            let (x, y) = (a.x[i] as isize, a.y[i] as isize);
            let (xa, ya) = (x - rx, y - ry);
            let wa = s.weight * a.v[i];
            if by_row {
                let lo = sorted.partition_point(|q| (q.1 as isize) < ya);
                let hi = sorted.partition_point(|q| (q.1 as isize) <= y + ry);
                for &(qx, qy, qv) in &sorted[lo..hi] {
                    let ix = (qx as isize - xa) as usize;
                    let iy = (qy as isize - ya) as usize;
                    if ix < pw {
                        plane[iy * pw + ix] += wa * qv;
                    }
                }
            } else {
                for ((&qx, &qy), &qv) in bx.iter().zip(by).zip(bv) {
                    let ix = (qx as isize - xa) as usize;
                    let iy = (qy as isize - ya) as usize;
                    if ix < pw && iy < ph {
                        plane[iy * pw + ix] += wa * qv;
                    }
                }
            }
            // Σ_O a: voxel p counts for the lags with p + Δ inside the window.
            let c = -s.weight * s.mean_b * a.v[i];
            add_rect(rx - x, rx + w - 1 - x, ry - y, ry + h - 1 - y, c);
        }
        // Σ_O b(·+Δ): voxel q counts for the lags with q − Δ inside the window.
        for ((&qx, &qy), &qv) in bx.iter().zip(by).zip(bv) {
            let (x, y) = (qx as isize, qy as isize);
            let c = -s.weight * s.mean_a * qv;
            add_rect(rx + x - w + 1, rx + x, ry + y - h + 1, ry + y, c);
        }
        constant += s.weight * s.mean_a * s.mean_b;
    }
    // One pass: prefix sums turn the difference array into the per-lag values, the analytic
    // term is added and the lag is normalised as by `voxels::normalise` (same operations, same
    // order).
    let n = stats.len().max(1) as f64;
    for iy in 0..ph {
        let oy = (shape.h - iy.abs_diff(shape.ry)) as f64;
        let mut run = 0.0;
        let (above, row) = diff.split_at_mut(iy * dw);
        let above = if iy > 0 {
            &above[(iy - 1) * dw..]
        } else {
            &[][..]
        };
        let cells = &mut plane[iy * pw..(iy + 1) * pw];
        for (ix, (cell, d)) in cells.iter_mut().zip(&mut row[..pw]).enumerate() {
            let ox = (shape.w - ix.abs_diff(shape.rx)) as f64;
            run += *d;
            *d = run + if iy > 0 { above[ix] } else { 0.0 };
            *cell = (*cell + (*d + ox * oy * constant)) / (ox * oy * n);
        }
    }
}
