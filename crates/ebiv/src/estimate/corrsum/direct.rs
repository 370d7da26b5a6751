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

use super::voxels::{Overlap, PlaneShape, SliceStats, SubVolume};

/// Working memory of [`correlate`] for one plane shape. `pairs` and `diff` are all zero
/// between calls (the final pass clears what it reads), so no window pays for clearing them;
/// `column` is reset on entry.
#[derive(Debug, Clone)]
pub(super) struct Accumulators {
    /// Σ over voxel pairs of `a·b(·+Δ)`, one cell per lag.
    pairs: Vec<f64>,
    /// 2-D difference array of the rectangle corrections, `(pw + 1) × (ph + 1)`.
    diff: Vec<f64>,
    /// Running column sums of `diff` during the final pass, `pw`.
    column: Vec<f64>,
}

impl Accumulators {
    pub fn new(shape: PlaneShape) -> Self {
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        Accumulators {
            pairs: vec![0.0; pw * ph],
            diff: vec![0.0; (pw + 1) * (ph + 1)],
            column: vec![0.0; pw],
        }
    }
}

/// Fill `plane` with the normalised correlation of the slices in `stats` and return the
/// index of its first maximum (as [`crate::estimate::peak::argmax`] finds it), `None` if no
/// value exceeds −∞.
pub(super) fn correlate(
    a: SubVolume<'_>,
    b: SubVolume<'_>,
    stats: &[SliceStats],
    shape: PlaneShape,
    overlap: &Overlap,
    plane: &mut [f64],
    acc: &mut Accumulators,
) -> Option<usize> {
    let (pw, ph) = (shape.plane_width(), shape.plane_height());
    let dw = pw + 1;
    let Accumulators {
        pairs,
        diff,
        column,
    } = acc;
    if pairs.len() != pw * ph || diff.len() != dw * (ph + 1) || column.len() != pw {
        *acc = Accumulators::new(shape);
        return correlate(a, b, stats, shape, overlap, plane, acc);
    }
    let (rx, ry) = (shape.rx as isize, shape.ry as isize);
    let (w, h) = (shape.w as isize, shape.h as isize);
    let mut constant = 0.0;
    let limits = [2 * rx, 2 * ry];
    let mut add_rect = |x0: isize, x1: isize, y0: isize, y1: isize, c: f64| {
        add_rectangle(diff, dw, limits, [x0, x1, y0, y1], c)
    };
    let (ax, ay, av) = (&a.vox.x, &a.vox.y, &a.vox.v);
    for s in stats {
        let (bx, by, bv) = (&b.vox.x, &b.vox.y, &b.vox.v);
        for i in a.range(s.z) {
            let (x, y) = (ax[i] as isize, ay[i] as isize);
            let (xa, ya) = (x - rx, y - ry);
            let wa = s.weight * av[i];
            // Only the `b` rows within the search radius.
            let near = b.rows(s.z, ya..y + ry + 1);
            for ((&qx, &qy), &qv) in bx[near.clone()]
                .iter()
                .zip(&by[near.clone()])
                .zip(&bv[near])
            {
                let ix = (qx as isize - xa) as usize;
                if ix < pw {
                    let iy = (qy as isize - ya) as usize;
                    pairs[iy * pw + ix] += wa * qv;
                }
            }
            // Σ_O a: voxel p counts for the lags with p + Δ inside the window.
            let c = -s.weight * s.mean_b * av[i];
            add_rect(rx - x, rx + w - 1 - x, ry - y, ry + h - 1 - y, c);
        }
        // Σ_O b(·+Δ): voxel q counts for the lags with q − Δ inside the window.
        let rb = b.range(s.z);
        for ((&qx, &qy), &qv) in bx[rb.clone()].iter().zip(&by[rb.clone()]).zip(&bv[rb]) {
            let (x, y) = (qx as isize, qy as isize);
            let c = -s.weight * s.mean_a * qv;
            add_rect(rx + x - w + 1, rx + x, ry + y - h + 1, ry + y, c);
        }
        constant += s.weight * s.mean_a * s.mean_b;
    }
    // One pass: prefix sums turn the difference array into the per-lag values (row prefix
    // `run`, accumulated down the columns in `column`), the analytic term `n(Δ) ā b̄` is added,
    // the lag is normalised as by [`Overlap::normalise`] and the maximum is tracked. The
    // accumulators are cleared as they are read.
    let per_slice = 1.0 / stats.len().max(1) as f64;
    column.fill(0.0);
    let (mut best, mut best_value) = (None, f64::NEG_INFINITY);
    for iy in 0..ph {
        let mut run = 0.0;
        let lags = iy * pw..(iy + 1) * pw;
        let cells = plane[lags.clone()]
            .iter_mut()
            .zip(&mut pairs[lags.clone()])
            .zip(&mut diff[iy * dw..iy * dw + pw])
            .zip(column.iter_mut())
            .zip(&overlap.area[lags.clone()])
            .zip(&overlap.inverse[lags]);
        for (ix, (((((cell, pair), d), col), &area), &inverse)) in cells.enumerate() {
            run += std::mem::take(d);
            *col += run;
            let value = (std::mem::take(pair) + (*col + area * constant)) * (inverse * per_slice);
            *cell = value;
            if value > best_value {
                best_value = value;
                best = Some(iy * pw + ix);
            }
        }
        // The corrections' closing column lies outside the plane.
        diff[iy * dw + pw] = 0.0;
    }
    diff[ph * dw..].fill(0.0);
    best
}

/// Add `c` to the lags `[x0, x1] × [y0, y1]` (clipped to `[0, limits]`) of the difference
/// array `diff` of row length `dw`: four corner updates.
#[inline(always)]
fn add_rectangle(diff: &mut [f64], dw: usize, limits: [isize; 2], r: [isize; 4], c: f64) {
    let [x0, x1, y0, y1] = r;
    let (x0, x1) = (x0.max(0) as usize, x1.min(limits[0]) as usize + 1);
    let (y0, y1) = (y0.max(0) as usize, y1.min(limits[1]) as usize + 1);
    diff[y0 * dw + x0] += c;
    diff[y0 * dw + x1] -= c;
    diff[y1 * dw + x0] -= c;
    diff[y1 * dw + x1] += c;
}
