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
use crate::simd::avx2_available;

/// Working memory of [`correlate`] for one plane shape. `pairs` and `diff` are all zero
/// between calls (the final pass clears what it reads), so no window pays for clearing them;
/// `column` is reset on entry.
#[derive(Debug, Clone)]
pub(super) struct Accumulators {
    /// Σ over voxel pairs of `a·b(·+Δ)`, one cell per lag, in rows of [`PairLayout::stride`]
    /// cells: the plane's row `iy` at `iy · stride + pad ..`, flanked by cells that take the
    /// products of the pairs whose lag lies outside the plane (never read, cleared with the
    /// row). A power of two long ([`index_mask`]); the cells past `stride · ph` stay unused.
    pairs: Vec<f64>,
    /// The cell index `y · stride + x` of each voxel of the current `b` slice in `pairs`
    /// (offset per `a` voxel).
    linear: Vec<usize>,
    /// 2-D difference array of the rectangle corrections, `(pw + 1) × (ph + 1)`, in a
    /// power-of-two long vector ([`index_mask`]; the cells past it stay zero).
    diff: Vec<f64>,
    /// Running column sums of `diff` during the final pass, `pw`.
    column: Vec<f64>,
    /// The maximum of every row of the last plane ([`row_maximum`]), `ph`.
    row_max: Vec<f64>,
    /// The rectangles of the corrections in `diff`, per voxel coordinate.
    corners: Corners,
    /// The shape these accumulators were made for.
    shape: PlaneShape,
}

/// The corners in the difference array of the rectangle of lags that a voxel's correction
/// covers, clipped to the plane, per coordinate of the voxel (rectangles are products of a
/// range of columns and a range of rows): columns `[x0, x1 + 1]` and row offsets
/// `[y0 · dw, (y1 + 1) · dw]`, for `a`'s voxels (`Σ_O a`) and `b`'s (`Σ_O b(·+Δ)`). The
/// lookups replace the clipping and the products per voxel; the corners are the same.
/// Each table is a power of two long ([`table_mask`]), the entries past the window's
/// width (height) unused.
#[derive(Debug, Clone)]
struct Corners {
    a_cols: Vec<[usize; 2]>,
    a_rows: Vec<[usize; 2]>,
    b_cols: Vec<[usize; 2]>,
    b_rows: Vec<[usize; 2]>,
}

/// `table` padded with copies of its last entry to a power of two long (never read: voxel
/// coordinates lie within the window).
fn padded(mut table: Vec<[usize; 2]>) -> Vec<[usize; 2]> {
    let last = table.last().copied().unwrap_or_default();
    table.resize(table.len().next_power_of_two(), last);
    table
}

impl Corners {
    fn new(shape: PlaneShape) -> Self {
        let (rx, ry) = (shape.rx as isize, shape.ry as isize);
        let (w, h) = (shape.w as isize, shape.h as isize);
        let dw = shape.plane_width() + 1;
        // The lags `[lo, hi]` clipped to `[0, limit]`, the difference array's bounds of them.
        let span = |lo: isize, hi: isize, limit: isize, scale: usize| {
            [
                lo.max(0) as usize * scale,
                (hi.min(limit) as usize + 1) * scale,
            ]
        };
        Corners {
            // Voxel p counts for the lags with p + Δ inside the window.
            a_cols: padded(
                (0..w)
                    .map(|x| span(rx - x, rx + w - 1 - x, 2 * rx, 1))
                    .collect(),
            ),
            a_rows: padded(
                (0..h)
                    .map(|y| span(ry - y, ry + h - 1 - y, 2 * ry, dw))
                    .collect(),
            ),
            // Voxel q counts for the lags with q − Δ inside the window.
            b_cols: padded(
                (0..w)
                    .map(|x| span(rx + x - w + 1, rx + x, 2 * rx, 1))
                    .collect(),
            ),
            b_rows: padded(
                (0..h)
                    .map(|y| span(ry + y - h + 1, ry + y, 2 * ry, dw))
                    .collect(),
            ),
        }
    }
}

impl Accumulators {
    pub fn new(shape: PlaneShape) -> Self {
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        Accumulators {
            pairs: vec![0.0; (PairLayout::of(shape).stride * ph).next_power_of_two()],
            linear: Vec::new(),
            diff: vec![0.0; ((pw + 1) * (ph + 1)).next_power_of_two()],
            column: vec![0.0; pw],
            row_max: vec![f64::NEG_INFINITY; ph],
            corners: Corners::new(shape),
            shape,
        }
    }

    /// The maximum of every row of the last plane computed by [`correlate`] (or given to
    /// [`Accumulators::find_row_maxima`]), as [`crate::peak::peak_at`]
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

/// Where the pair products of each lag lie in [`Accumulators::pairs`]: rows of `stride`
/// cells, the plane's row `iy` at `iy · stride + pad .. + plane_width`. Two voxels of a window
/// are less than `w` columns apart, so the column lag `ix = qx − x + rx` of any pair lies in
/// `rx − (w − 1) ..= rx + w − 1`, and `ix + pad` in `0..stride`: every pair of rows within
/// the search radius has a cell of its row, so the pair loop needs no test of the column lag.
#[derive(Debug, Clone, Copy)]
struct PairLayout {
    stride: usize,
    pad: usize,
}

impl PairLayout {
    fn of(shape: PlaneShape) -> Self {
        let pad = shape.w.saturating_sub(1).saturating_sub(shape.rx);
        let stride = (shape.rx + shape.w).max(shape.plane_width()) + pad;
        PairLayout { stride, pad }
    }
}

/// Fill `plane` with the normalised correlation of the slices in `stats` and return the
/// index of its first maximum (as [`crate::peak::argmax`] finds it), `None` if no
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
    if acc.shape != shape {
        *acc = Accumulators::new(shape);
    }
    let inputs = Inputs {
        a,
        b,
        stats,
        shape,
        overlap,
    };
    if avx2_available() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the processor has AVX2 (`avx2_available`).
        return unsafe { correlate_avx2(inputs, plane, acc) };
    }
    correlate_portable(inputs, plane, acc)
}

/// What [`correlate`] correlates: the sub-volumes, their slice statistics, the plane's shape
/// and the overlap normalisation.
#[derive(Clone, Copy)]
pub(super) struct Inputs<'a> {
    pub a: SubVolume<'a>,
    pub b: SubVolume<'a>,
    pub stats: &'a [SliceStats],
    pub shape: PlaneShape,
    pub overlap: &'a Overlap,
}

/// [`correlate_portable`] compiled for AVX2 ([`crate::simd`]): the lag loops of the final
/// pass take four `f64` lanes per instruction instead of two; the same operations in the
/// same order (no fused multiply-add), so the same bits on every processor.
///
/// # Safety
/// Only where the processor has AVX2 ([`avx2_available`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn correlate_avx2(
    inputs: Inputs<'_>,
    plane: &mut [f64],
    acc: &mut Accumulators,
) -> Option<usize> {
    correlate_portable(inputs, plane, acc)
}

/// [`correlate`] with accumulators of the plane's shape, in the build for every x86-64
/// processor (or, inlined into [`correlate_avx2`], the AVX2 build).
#[inline(always)]
pub(super) fn correlate_portable(
    inputs: Inputs<'_>,
    plane: &mut [f64],
    acc: &mut Accumulators,
) -> Option<usize> {
    let Inputs {
        a,
        b,
        stats,
        shape,
        overlap,
    } = inputs;
    debug_assert_eq!(acc.shape, shape, "accumulators of another plane shape");
    let (pw, ph) = (shape.plane_width(), shape.plane_height());
    let dw = pw + 1;
    let layout = PairLayout::of(shape);
    // `find_row_maxima` may have left the row maxima of another plane.
    acc.row_max.resize(ph, f64::NEG_INFINITY);
    let Accumulators {
        pairs,
        linear,
        diff,
        column,
        row_max: row_maxima,
        corners,
        shape: _,
    } = acc;
    let mut constant = 0.0;
    let (ax, ay, av) = (&a.vox.x, &a.vox.y, &a.vox.v);
    for s in stats {
        let rb = b.range(s.z);
        let (bx, by, bv) = (&b.vox.x[rb.clone()], &b.vox.y[rb.clone()], &b.vox.v[rb]);
        linear.clear();
        linear.extend(
            bx.iter()
                .zip(by)
                .map(|(&x, &y)| y as usize * layout.stride + x as usize),
        );
        let ra = a.range(s.z);
        let a_slice = (&ax[ra.clone()], &ay[ra.clone()], &av[ra]);
        let b_slice = (by, &linear[..]);
        if b.vox.unit {
            add_pair_products(pairs, layout, shape, s.weight, a_slice, b_slice, |_| 1.0);
        } else {
            add_pair_products(pairs, layout, shape, s.weight, a_slice, b_slice, |j| bv[j]);
        }
        // Σ_O a and Σ_O b(·+Δ), as [`Corners`] gives the rectangles.
        let (ca, cb) = (-s.weight * s.mean_b, -s.weight * s.mean_a);
        let (a_cols, a_rows) = (&corners.a_cols[..], &corners.a_rows[..]);
        let (b_cols, b_rows) = (&corners.b_cols[..], &corners.b_rows[..]);
        if a.vox.unit {
            add_rectangles(diff, (a_cols, a_rows), (a_slice.0, a_slice.1), |_| ca);
        } else {
            add_rectangles(diff, (a_cols, a_rows), (a_slice.0, a_slice.1), |i| {
                ca * a_slice.2[i]
            });
        }
        if b.vox.unit {
            add_rectangles(diff, (b_cols, b_rows), (bx, by), |_| cb);
        } else {
            add_rectangles(diff, (b_cols, b_rows), (bx, by), |j| cb * bv[j]);
        }
        constant += s.weight * s.mean_a * s.mean_b;
    }
    // Per row of lags: prefix sums turn the difference array into the corrections (row
    // prefix `run`, accumulated down the columns in `column`); then, independently per lag
    // (the compiler can vectorise it), the analytic term `n(Δ) ā b̄` is added and the lag is
    // normalised as by [`Overlap::normalise`]. The accumulators are cleared as they are read
    // (the whole row of `pairs`, with the cells of the lags outside the plane).
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
        let pair_row = &mut pairs[iy * layout.stride..(iy + 1) * layout.stride];
        let cells = plane[lags.clone()]
            .iter_mut()
            .zip(&pair_row[layout.pad..layout.pad + pw])
            .zip(column.iter())
            .zip(&overlap.area[lags.clone()])
            .zip(&overlap.inverse[lags.clone()]);
        for ((((cell, &pair), &col), &area), &inverse) in cells {
            *cell = (pair + (col + area * constant)) * (inverse * per_slice);
        }
        pair_row.fill(0.0);
        let row_max = row_maximum(&plane[lags]);
        row_maxima[iy] = row_max;
        if row_max > best_value {
            best_value = row_max;
            best_row = Some(iy);
        }
    }
    diff[ph * dw..(ph + 1) * dw].fill(0.0);
    let row = best_row?;
    let first = plane[row * pw..(row + 1) * pw]
        .iter()
        .position(|&v| v == best_value)?;
    Some(row * pw + first)
}

/// Add `weight · a · b` of every voxel pair of one slice whose rows are within the search
/// radius to the pair's cell of `pairs` ([`PairLayout`]); `b_value(j)` is the value of `b`'s
/// voxel `j`, `linear[j]` its cell `y · stride + x`. Binary voxels pass `|_| 1`, and the
/// compiler drops the loads and products (`x · 1 = x` exactly). The cells of the plane's
/// lags take the same products in the same order as a loop over the pairs with a lag in the
/// plane; the other pairs add to cells outside the plane, which are never read.
#[inline(always)]
fn add_pair_products(
    pairs: &mut [f64],
    layout: PairLayout,
    shape: PlaneShape,
    weight: f64,
    (ax, ay, av): (&[u16], &[u16], &[f64]),
    (by, linear): (&[u16], &[usize]),
    b_value: impl Fn(usize) -> f64,
) {
    let ry = shape.ry as isize;
    // The cell of the pair of `a` voxel (x, y) and `b` voxel j at (qx, qy), of lag
    // (qx − x + rx, qy − y + ry): `(qy − y + ry) · stride + qx − x + rx + pad`, that is
    // `linear[j] − shift` with `shift = y · stride + x − origin` (modular arithmetic, as
    // `shift` may be negative).
    let origin = shape.ry * layout.stride + shape.rx + layout.pad;
    let mask = index_mask(pairs);
    // The voxels of a slice are sorted by row, so the `b` voxels within the search radius of
    // an `a` voxel's row, `lo..hi`, slide down `b`'s list as `a`'s rows grow.
    let (mut lo, mut hi) = (0, 0);
    for ((&x, &y), &v) in ax.iter().zip(ay).zip(av) {
        let shift = (y as usize * layout.stride + x as usize).wrapping_sub(origin);
        let (y, ya) = (y as isize, y as isize - ry);
        let wa = weight * v;
        while lo < by.len() && (by[lo] as isize) < ya {
            lo += 1;
        }
        hi = hi.max(lo);
        while hi < by.len() && (by[hi] as isize) <= y + ry {
            hi += 1;
        }
        // Two pairs per turn, in the old order, so that the loop's own instructions are paid
        // once per two products (the two cells differ: the voxels of a slice are distinct,
        // so the second addition does not wait for the first).
        let mut two_at_a_time = linear[lo..hi].chunks_exact(2);
        let mut j = lo;
        for two in &mut two_at_a_time {
            pairs[two[0].wrapping_sub(shift) & mask] += wa * b_value(j);
            pairs[two[1].wrapping_sub(shift) & mask] += wa * b_value(j + 1);
            j += 2;
        }
        if let [l] = two_at_a_time.remainder() {
            pairs[l.wrapping_sub(shift) & mask] += wa * b_value(j);
        }
    }
}

/// The largest value of `values` that exceeds −∞ and all values before it, as
/// [`crate::peak::argmax`] keeps it (NaN never exceeds; −∞ if no value does), in
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

/// Add `coefficient(i)` to the lags of the rectangle of voxel `i` at `(xs[i], ys[i])`, the
/// columns `[x0, x1)` of `cols[x]` and the rows `[y0, y1)` (row offsets `y · dw`) of
/// `rows[y]`, in the difference array `diff`: four corner updates per voxel. Binary voxels
/// pass a constant coefficient (`c · 1 = c` exactly, so the product with the voxel value is
/// left out). Every index lies within its array (voxels within the window, corners within
/// the difference array); masking them ([`index_mask`], [`table_mask`]) changes none and
/// leaves out the test per access.
#[inline(always)]
fn add_rectangles(
    diff: &mut [f64],
    (cols, rows): (&[[usize; 2]], &[[usize; 2]]),
    (xs, ys): (&[u16], &[u16]),
    coefficient: impl Fn(usize) -> f64,
) {
    let (mask, col_mask, row_mask) = (index_mask(diff), table_mask(cols), table_mask(rows));
    // Tables exactly `col_mask + 1` and `row_mask + 1` long, so that the compiler sees every
    // masked index in bounds.
    let (cols, rows) = (&cols[..=col_mask], &rows[..=row_mask]);
    for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
        debug_assert!(x as usize <= col_mask && y as usize <= row_mask);
        let [x0, x1] = cols[x as usize & col_mask];
        let [y0, y1] = rows[y as usize & row_mask];
        debug_assert!(y1 + x1 <= mask, "a corner past the difference array");
        let c = coefficient(i);
        diff[(y0 + x0) & mask] += c;
        diff[(y0 + x1) & mask] -= c;
        diff[(y1 + x0) & mask] -= c;
        diff[(y1 + x1) & mask] += c;
    }
}

/// The mask of the indices of a corner table, a power of two long ([`Corners`]).
#[inline(always)]
fn table_mask(table: &[[usize; 2]]) -> usize {
    assert!(table.len().is_power_of_two());
    table.len() - 1
}

/// The mask of the indices of `cells`, a power of two long (as [`Accumulators::new`]
/// allocates `pairs` and `diff`, at least as long as the cells the kernel uses). Every index the
/// kernel computes lies within the cells used, so masking it changes no index; it shows the
/// compiler that the index is in bounds, and the test per update is left out.
#[inline(always)]
fn index_mask(cells: &[f64]) -> usize {
    assert!(cells.len().is_power_of_two());
    cells.len() - 1
}

/// The normalised correlation of the slices in `stats` at each of the lags `lags` (at most
/// [`MAX_SINGLE_LAGS`]), the values [`correlate`] puts in those lags' cells (whatever the
/// search radius), into `out`: per lag, the sum over the overlap region of the
/// mean-subtracted products, per slice weighted by `1 / (σ_a σ_b)`, over the overlap area and
/// the number of slices; 0 for a lag with no overlap. Each slice of `b` is spread into
/// `image` (a zeroed `w × h` grid, left zeroed), so that every voxel of `a` finds its partner
/// at each lag by one lookup: the cost is linear in the voxels and the lags.
pub(super) fn correlations_at(
    (a, b): (SubVolume<'_>, SubVolume<'_>),
    stats: &[SliceStats],
    shape: PlaneShape,
    lags: &[[i64; 2]],
    image: &mut Vec<f64>,
    out: &mut [f64],
) {
    let (w, h) = (shape.w as i64, shape.h as i64);
    debug_assert!(lags.len() <= MAX_SINGLE_LAGS && out.len() >= lags.len());
    let n = lags.len().min(MAX_SINGLE_LAGS);
    image.resize(shape.w * shape.h, 0.0);
    let mut total = [0.0; MAX_SINGLE_LAGS];
    let inside = |x: i64, y: i64| (0..w).contains(&x) && (0..h).contains(&y);
    for s in stats {
        let (ra, rb) = (a.range(s.z), b.range(s.z));
        let value = |v: SubVolume<'_>, i: usize| if v.vox.unit { 1.0 } else { v.vox.v[i] };
        for j in rb.clone() {
            image[b.vox.y[j] as usize * shape.w + b.vox.x[j] as usize] = value(b, j);
        }
        let mut sum_a = [0.0; MAX_SINGLE_LAGS];
        let mut sum_b = [0.0; MAX_SINGLE_LAGS];
        let mut sum_ab = [0.0; MAX_SINGLE_LAGS];
        for i in ra {
            let (x, y, v) = (i64::from(a.vox.x[i]), i64::from(a.vox.y[i]), value(a, i));
            for (l, &[dx, dy]) in lags[..n].iter().enumerate() {
                let (qx, qy) = (x + dx, y + dy);
                if inside(qx, qy) {
                    sum_a[l] += v;
                    sum_ab[l] += v * image[(qy * w + qx) as usize];
                }
            }
        }
        for j in rb {
            let (x, y, v) = (i64::from(b.vox.x[j]), i64::from(b.vox.y[j]), value(b, j));
            image[y as usize * shape.w + x as usize] = 0.0;
            for (l, &[dx, dy]) in lags[..n].iter().enumerate() {
                if inside(x - dx, y - dy) {
                    sum_b[l] += v;
                }
            }
        }
        for (l, &[dx, dy]) in lags[..n].iter().enumerate() {
            let area = ((w - dx.abs()).max(0) * (h - dy.abs()).max(0)) as f64;
            let covariance =
                sum_ab[l] - s.mean_b * sum_a[l] - s.mean_a * sum_b[l] + area * s.mean_a * s.mean_b;
            if area > 0.0 {
                total[l] += s.weight * covariance / area;
            }
        }
    }
    let slices = stats.len().max(1) as f64;
    for (o, t) in out.iter_mut().zip(&total[..n]) {
        *o = t / slices;
    }
}

/// Most lags [`correlations_at`] takes at once.
pub(super) const MAX_SINGLE_LAGS: usize = 5;
