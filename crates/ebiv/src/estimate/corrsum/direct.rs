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
    /// The maximum of every row of the last plane ([`row_maximum`]), `ph`.
    row_max: Vec<f64>,
}

impl Accumulators {
    pub fn new(shape: PlaneShape) -> Self {
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        Accumulators {
            pairs: vec![0.0; pw * ph],
            diff: vec![0.0; (pw + 1) * (ph + 1)],
            column: vec![0.0; pw],
            row_max: vec![f64::NEG_INFINITY; ph],
        }
    }

    /// The maximum of every row of the last plane computed by [`correlate`] (or given to
    /// [`Accumulators::find_row_maxima`]), as [`crate::estimate::peak::peak_at_with_row_maxima`]
    /// takes them.
    pub fn row_maxima(&self) -> &[f64] {
        &self.row_max
    }

    /// Find the maximum of every row of `plane` (rows of `width` lags), for a plane computed
    /// by another kernel.
    pub fn find_row_maxima(&mut self, plane: &[f64], width: usize) {
        self.row_max.clear();
        self.row_max.extend(plane.chunks(width).map(row_maximum));
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
        row_max: row_maxima,
    } = acc;
    if pairs.len() != pw * ph
        || diff.len() != dw * (ph + 1)
        || column.len() != pw
        || row_maxima.len() != ph
    {
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
        let rb = b.range(s.z);
        let (bx, by, bv) = (&b.vox.x[rb.clone()], &b.vox.y[rb.clone()], &b.vox.v[rb]);
        let ra = a.range(s.z);
        let a_slice = (&ax[ra.clone()], &ay[ra.clone()], &av[ra]);
        if b.vox.unit {
            add_pair_products(pairs, shape, s.weight, a_slice, (bx, by), |_| 1.0);
        } else {
            add_pair_products(pairs, shape, s.weight, a_slice, (bx, by), |j| bv[j]);
        }
        // Σ_O a: voxel p counts for the lags with p + Δ inside the window.
        for i in a.range(s.z) {
            let (x, y) = (ax[i] as isize, ay[i] as isize);
            let c = -s.weight * s.mean_b * av[i];
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
    // Per row of lags: prefix sums turn the difference array into the corrections (row
    // prefix `run`, accumulated down the columns in `column`); then, independently per lag
    // (the compiler can vectorise it), the analytic term `n(Δ) ā b̄` is added and the lag is
    // normalised as by [`Overlap::normalise`]. The accumulators are cleared as they are read.
    // The maximum is kept per row (`row_maximum`), the row holding the first maximum by a
    // comparison per row, and the lag found in that row.
    let per_slice = 1.0 / stats.len().max(1) as f64;
    column.fill(0.0);
    let (mut best_row, mut best_value) = (None, f64::NEG_INFINITY);
    for iy in 0..ph {
        let mut run = 0.0;
        for (d, col) in diff[iy * dw..iy * dw + pw]
            .iter_mut()
            .zip(column.iter_mut())
        {
            run += std::mem::take(d);
            *col += run;
        }
        // The corrections' closing column lies outside the plane.
        diff[iy * dw + pw] = 0.0;
        let lags = iy * pw..(iy + 1) * pw;
        let cells = plane[lags.clone()]
            .iter_mut()
            .zip(&mut pairs[lags.clone()])
            .zip(column.iter())
            .zip(&overlap.area[lags.clone()])
            .zip(&overlap.inverse[lags.clone()]);
        for ((((cell, pair), &col), &area), &inverse) in cells {
            *cell = (std::mem::take(pair) + (col + area * constant)) * (inverse * per_slice);
        }
        let row_max = row_maximum(&plane[lags]);
        row_maxima[iy] = row_max;
        if row_max > best_value {
            best_value = row_max;
            best_row = Some(iy);
        }
    }
    diff[ph * dw..].fill(0.0);
    let row = best_row?;
    let first = plane[row * pw..(row + 1) * pw]
        .iter()
        .position(|&v| v == best_value)?;
    Some(row * pw + first)
}

/// Add `weight · a · b` of every voxel pair of one slice with a lag in the plane to the lag's
/// cell of `pairs`; `b_value(j)` is the value of `b`'s voxel `j`. Binary voxels pass `|_| 1`,
/// and the compiler drops the loads and products (`x · 1 = x` exactly).
#[inline(always)]
fn add_pair_products(
    pairs: &mut [f64],
    shape: PlaneShape,
    weight: f64,
    (ax, ay, av): (&[u16], &[u16], &[f64]),
    (bx, by): (&[u16], &[u16]),
    b_value: impl Fn(usize) -> f64,
) {
    let pw = shape.plane_width();
    let (rx, ry) = (shape.rx as isize, shape.ry as isize);
    // The voxels of a slice are sorted by row, so the `b` voxels within the search radius of
    // an `a` voxel's row, `lo..hi`, slide down `b`'s list as `a`'s rows grow.
    let (mut lo, mut hi) = (0, 0);
    for ((&x, &y), &v) in ax.iter().zip(ay).zip(av) {
        let (x, y) = (x as isize, y as isize);
        let (xa, ya) = (x - rx, y - ry);
        let wa = weight * v;
        while lo < by.len() && (by[lo] as isize) < ya {
            lo += 1;
        }
        hi = hi.max(lo);
        while hi < by.len() && (by[hi] as isize) <= y + ry {
            hi += 1;
        }
        for (k, (&qx, &qy)) in bx[lo..hi].iter().zip(&by[lo..hi]).enumerate() {
            let ix = (qx as isize - xa) as usize;
            if ix < pw {
                let iy = (qy as isize - ya) as usize;
                pairs[iy * pw + ix] += wa * b_value(lo + k);
            }
        }
    }
}

/// The largest value of `values` that exceeds −∞ and all values before it, as
/// [`crate::estimate::peak::argmax`] keeps it (NaN never exceeds; −∞ if no value does), in
/// two independent lanes (`maxsd`/`maxpd`, no branch per value). Of values equal to the
/// maximum the scan's choice is the first, which the caller finds by comparing; the lanes
/// may return another of them (such as −0 for +0), equal all the same.
fn row_maximum(values: &[f64]) -> f64 {
    let mut lanes = [f64::NEG_INFINITY; 2];
    let mut pairs = values.chunks_exact(2);
    for pair in &mut pairs {
        lanes[0] = max_above(pair[0], lanes[0]);
        lanes[1] = max_above(pair[1], lanes[1]);
    }
    let max = max_above(lanes[1], lanes[0]);
    pairs
        .remainder()
        .iter()
        .fold(max, |max, &v| max_above(v, max))
}

/// `value` if it exceeds `max`, else `max` (NaN never exceeds): one `maxsd`.
#[inline(always)]
fn max_above(value: f64, max: f64) -> f64 {
    if value > max {
        value
    } else {
        max
    }
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
