//! Standard uncertainty of a sum-of-correlation peak: the delete-a-block jackknife of
//! [`crate::estimate::uncertainty`] on the summed plane.
//!
//! The plane at lag `l` is a sum over the window's pixels `x` and the slice pairs `s` of the
//! mean-subtracted products `(a_s(x) − ā_s)(b_s(x + l) − b̄_s)`, weighted per slice by
//! `1/(σ_a σ_b)` and divided by the overlap area and the number of slices
//! ([`direct::correlations_at`](super::direct::correlations_at)). Grouping the products by the
//! block of `x` splits the plane near the peak into the contributions of the window's blocks,
//! which add up to it exactly. Taking a block's contribution out moves the fitted peak, to
//! first order, by minus the fit's gradient in the plane's values (smoothing and sub-pixel
//! fit as the estimator does them, [`fit_gradient`]) times the contribution: the
//! infinitesimal jackknife (Jaeckel 1972; Efron 1982, *The Jackknife, the Bootstrap and
//! Other Resampling Plans*, ch. 6), which taking whole blocks out of a nonlinear fit only
//! approximates, at the cost of one gradient per window instead of one fit per block. A
//! block weighs its contribution to the peak.

use super::fit::{fit_gradient, fit_reach, SmoothingKernel};
use super::voxels::{PlaneShape, SliceStats, SubVolume};
use crate::estimate::uncertainty::{jackknife_sigma, Blocks};
use crate::peak::{Peak, SubPixelFit};

/// Working memory of [`peak_sigma`], reused across windows.
#[derive(Debug, Clone, Default)]
pub(super) struct BlockPlanes {
    /// Per block, the contributions to the rectangle of the neighbourhood where the fit has
    /// a gradient, row-major.
    contributions: Vec<f64>,
    /// The neighbourhood of the plane.
    local: Vec<f64>,
    /// The fit's gradient in the neighbourhood's values, per axis, and over the rectangle.
    gradient: [Vec<f64>; 2],
    slope: [Vec<f64>; 2],
    /// The shifts of the peak with one block taken out.
    estimates: Vec<[f64; 2]>,
    /// Each block's contribution to the peak, its weight.
    weights: Vec<f64>,
    /// Per block, the products with the partners' slice means (see [`block_contributions`]).
    means: Vec<f64>,
}

/// Standard uncertainty, px per axis, of the sub-pixel position of `peak` on `plane` (the
/// summed correlation of the sub-volumes `a`, `b` over the slices of `stats`, fitted with
/// `kernel` and `fit`). `image` is a zeroed `w × h` grid, left zeroed.
#[allow(clippy::too_many_arguments)]
pub(super) fn peak_sigma(
    (a, b): (SubVolume<'_>, SubVolume<'_>),
    stats: &[SliceStats],
    shape: PlaneShape,
    plane: &[f64],
    peak: &Peak,
    (kernel, fit): (&SmoothingKernel, SubPixelFit),
    image: &mut Vec<f64>,
    work: &mut BlockPlanes,
) -> [f64; 2] {
    let (pw, ph) = (shape.plane_width(), shape.plane_height());
    let reach = fit_reach(kernel, [pw, ph], peak);
    if peak.on_edge || peak.col < reach || peak.row < reach || stats.is_empty() {
        return [f64::NAN; 2];
    }
    let side = 2 * reach + 1;
    work.local.clear();
    for i in 0..side {
        let row = (peak.row - reach + i) * pw + peak.col - reach;
        work.local.extend_from_slice(&plane[row..row + side]);
    }
    let local_peak = Peak {
        col: reach,
        row: reach,
        x: peak.x - peak.col as f64 + reach as f64,
        y: peak.y - peak.row as f64 + reach as f64,
        on_edge: false,
        ..*peak
    };
    // The shift of the fitted peak when a block's contribution is taken out, to first
    // order: minus the fit's gradient in the plane's values times the contribution.
    fit_gradient(
        &work.local,
        [side, side],
        &local_peak,
        kernel,
        fit,
        &mut work.gradient,
    );
    // Only the values the fit reads have a gradient (the 3 × 3 block around the smoothed
    // maximum and the kernel's reach): the blocks' contributions are needed there, and at
    // the peak (their weights), only.
    let (mut lo, mut hi, mut moves) = ([reach, reach], [reach, reach], false);
    for cell in 0..side * side {
        if work.gradient[0][cell] != 0.0 || work.gradient[1][cell] != 0.0 {
            let (c, r) = (cell % side, cell / side);
            lo = [lo[0].min(c), lo[1].min(r)];
            hi = [hi[0].max(c), hi[1].max(r)];
            moves = true;
        }
    }
    // A fit that no change of the plane moves (it fell back to a fixed position) says
    // nothing about the spread: no σ rather than σ = 0.
    if !moves || work.gradient.iter().flatten().any(|g| !g.is_finite()) {
        return [f64::NAN; 2];
    }
    let size = [hi[0] - lo[0] + 1, hi[1] - lo[1] + 1];
    let cells = size[0] * size[1];
    // The lag of the rectangle's first cell, in the sub-volumes' pixels.
    let origin = [
        (peak.col - reach + lo[0]) as i64 - shape.rx as i64,
        (peak.row - reach + lo[1]) as i64 - shape.ry as i64,
    ];
    let blocks = Blocks::of(shape.w, shape.h);
    let count = blocks.count();
    block_contributions(
        (a, b),
        stats,
        shape,
        (origin, size),
        blocks,
        (image, &mut work.means),
        &mut work.contributions,
    );
    // The gradient over the rectangle, row by row as the contributions.
    for (slope, g) in work.slope.iter_mut().zip(&work.gradient) {
        slope.clear();
        for r in lo[1]..=hi[1] {
            slope.extend_from_slice(&g[r * side + lo[0]..=r * side + hi[0]]);
        }
    }
    work.estimates.clear();
    for part in work.contributions.chunks_exact(cells) {
        let shift = work
            .slope
            .each_ref()
            .map(|g| -g.iter().zip(part).map(|(g, c)| g * c).sum::<f64>());
        work.estimates.push(shift);
    }
    let centre = (reach - lo[1]) * size[0] + reach - lo[0];
    work.weights.clear();
    work.weights
        .extend((0..count).map(|k| work.contributions[k * cells + centre]));
    jackknife_sigma(&work.estimates, &work.weights)
}

/// The contributions of each block of `blocks` to the plane at the `side × down` lags from
/// `origin` (`side` per row, row-major), into `out` (block-major):
/// the mean-subtracted products `a(x)(b(x + l) − b̄)` of the voxels `a(x)` in the block. The
/// rest of the plane, `−ā Σ (b − b̄)` over the overlap, is a smooth function of the lag that
/// belongs to no block and is not taken out (split by the block of each partner pixel, it
/// would step between neighbouring blocks as the lag changes, and the steps, which cancel in
/// the sum, would pass for disagreement between the blocks). `image` is a zeroed `w × h`
/// grid, left zeroed; `means` is working memory.
///
/// A voxel whose lags all fall inside the window adds its products with one contiguous
/// `side`-wide row of the partner image per lag row, and its share `a·b̄` of the mean term
/// once per block (`means`); the products and the per-lag normalisation `1/(area × slices)`
/// are combined at the end.
fn block_contributions(
    (a, b): (SubVolume<'_>, SubVolume<'_>),
    stats: &[SliceStats],
    shape: PlaneShape,
    (origin, [side, down]): ([i64; 2], [usize; 2]),
    blocks: Blocks,
    (image, means): (&mut Vec<f64>, &mut Vec<f64>),
    out: &mut Vec<f64>,
) {
    let (w, h) = (shape.w as i64, shape.h as i64);
    let cells = side * down;
    out.clear();
    out.resize(blocks.count() * cells, 0.0);
    means.clear();
    means.resize(blocks.count(), 0.0);
    image.resize(shape.w * shape.h, 0.0);
    let value = |v: SubVolume<'_>, i: usize| if v.vox.unit { 1.0 } else { v.vox.v[i] };
    let span = side as i64;
    for s in stats {
        let (ra, rb) = (a.range(s.z), b.range(s.z));
        for j in rb.clone() {
            image[b.vox.y[j] as usize * shape.w + b.vox.x[j] as usize] = value(b, j);
        }
        for i in ra {
            let (x, y) = (i64::from(a.vox.x[i]), i64::from(a.vox.y[i]));
            let c = s.weight * value(a, i);
            let block = blocks.at(x as usize, y as usize);
            let row = &mut out[block * cells..][..cells];
            let (x0, y0) = (x + origin[0], y + origin[1]);
            if x0 >= 0 && y0 >= 0 && x0 + span <= w && y0 + down as i64 <= h {
                means[block] += c * s.mean_b;
                let first = (y0 * w + x0) as usize;
                match side {
                    // The widths of the default smoothing (7) and of none (3), unrolled.
                    7 => add_rows::<7>(row, &image[first..], shape.w, c),
                    3 => add_rows::<3>(row, &image[first..], shape.w, c),
                    _ => {
                        for (r, lags) in row.chunks_exact_mut(side).enumerate() {
                            let start = first + r * shape.w;
                            for (sum, partner) in lags.iter_mut().zip(&image[start..start + side]) {
                                *sum += c * partner;
                            }
                        }
                    }
                }
            } else {
                // The lags whose partner lies in the window: columns `first..last` of the
                // rows inside it.
                let first = (-x0).clamp(0, span) as usize;
                let last = (w - x0).clamp(0, span) as usize;
                for (r, lags) in row.chunks_exact_mut(side).enumerate() {
                    let qy = y0 + r as i64;
                    if !(0..h).contains(&qy) || first >= last {
                        continue;
                    }
                    // x0 may be negative: the index of the row's first partner in i64.
                    let start = (qy * w + x0 + first as i64) as usize;
                    let partners = &image[start..start + (last - first)];
                    for (sum, partner) in lags[first..last].iter_mut().zip(partners) {
                        *sum += c * (partner - s.mean_b);
                    }
                }
            }
        }
        for j in rb {
            image[b.vox.y[j] as usize * shape.w + b.vox.x[j] as usize] = 0.0;
        }
    }
    // Per lag, the factor of every product: 1 / (overlap area × slices), the product of a
    // factor per lag column and one per lag row; 0 without overlap.
    let slices = stats.len() as f64;
    let extent = |n: i64, from: i64, k: usize| (n - (from + k as i64).abs()).max(0) as f64;
    for (row, mean) in out.chunks_exact_mut(cells).zip(means.iter()) {
        for (r, lags) in row.chunks_exact_mut(side).enumerate() {
            let height = extent(h, origin[1], r);
            for (j, sum) in lags.iter_mut().enumerate() {
                let area = extent(w, origin[0], j) * height;
                *sum = if area > 0.0 {
                    (*sum - mean) / (area * slices)
                } else {
                    0.0
                };
            }
        }
    }
}

/// Add `c` times the rows of `N` partners (rows `stride` apart in `image`, from its start)
/// to the rows of `N` lags of `sums`.
#[inline(always)]
fn add_rows<const N: usize>(sums: &mut [f64], image: &[f64], stride: usize, c: f64) {
    for (r, lags) in sums.chunks_exact_mut(N).enumerate() {
        let lags: &mut [f64; N] = lags.try_into().expect("rows of N lags");
        let partners: &[f64; N] = image[r * stride..r * stride + N]
            .try_into()
            .expect("N partners");
        for (sum, partner) in lags.iter_mut().zip(partners) {
            *sum += c * partner;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::direct::correlations_at;
    use super::super::voxels::{slice_statistics, Voxeliser, Voxels};
    use super::*;

    /// Voxels of `slices` slices of a 16 × 12 window from `(x, y, slice)` points.
    fn voxels(points: &[(u16, u16, usize)], slices: usize) -> Voxels {
        let mut out = Voxels::default();
        let mut v = Voxeliser::new(16, 12);
        v.begin(slices as i64, slices, false);
        for &(x, y, z) in points {
            v.add(x as f32, y as f32, z as f32 + 0.5);
        }
        v.finish(&mut out);
        out
    }

    #[test]
    fn block_contributions_add_up_to_the_plane_but_its_smooth_part() {
        let shape = PlaneShape {
            w: 16,
            h: 12,
            rx: 5,
            ry: 4,
        };
        // Three particles, each a trail moving by (2, 1) px from a to b, in three slices.
        let mut points_a = Vec::new();
        let mut points_b = Vec::new();
        for z in 0..3u16 {
            for (x, y) in [(1 + z, 1), (11 + z, 8), (6, 5 + z / 2)] {
                points_a.push((x, y, z as usize));
                points_b.push((x + 2, y + 1, z as usize));
            }
        }
        let (va, vb) = (voxels(&points_a, 3), voxels(&points_b, 3));
        let (a, b) = (va.all(), vb.all());
        let mut stats = Vec::new();
        slice_statistics(a, b, shape, &mut stats);
        assert_eq!(stats.len(), 3);
        // The 5 × 5 lags from (0, −1), the 4 × 3 from (−3, 1), and the 7 × 7 and 3 × 3
        // (unrolled widths) around (2, 1): its neighbours, and lags whose partners fall
        // outside the window, right or left, for voxels near its edges.
        for (origin, [side, down]) in [
            ([0i64, -1i64], [5usize, 5usize]),
            ([-3, 1], [4, 3]),
            ([-1, -2], [7, 7]),
            ([1, 0], [3, 3]),
            // Partners left of the window on its top row (a negative row start).
            ([-3, -3], [7, 7]),
        ] {
            let lags: Vec<[i64; 2]> = (0..side * down)
                .map(|c| [origin[0] + (c % side) as i64, origin[1] + (c / side) as i64])
                .collect();
            let mut image = Vec::new();
            let mut expected = vec![0.0; lags.len()];
            for (some, into) in lags.chunks(4).zip(expected.chunks_mut(4)) {
                correlations_at((a, b), &stats, shape, some, &mut image, into);
            }
            // The part that belongs to no block: −ā Σ (b − b̄) over the overlap, per slice.
            for (l, &[dx, dy]) in lags.iter().enumerate() {
                let area = ((16 - dx.abs()) * (12 - dy.abs())) as f64;
                for st in &stats {
                    let r = b.range(st.z);
                    let sum_b = r
                        .filter(|&j| {
                            let (x, y) = (i64::from(vb.x[j]) - dx, i64::from(vb.y[j]) - dy);
                            (0..16).contains(&x) && (0..12).contains(&y)
                        })
                        .count() as f64;
                    let common = -st.mean_a * (sum_b - st.mean_b * area);
                    expected[l] -= st.weight * common / (area * stats.len() as f64);
                }
            }
            let blocks = Blocks::of(16, 12);
            let count = blocks.count();
            let (mut out, mut means) = (Vec::new(), Vec::new());
            block_contributions(
                (a, b),
                &stats,
                shape,
                (origin, [side, down]),
                blocks,
                (&mut image, &mut means),
                &mut out,
            );
            assert!(image.iter().all(|&v| v == 0.0));
            let cells = side * down;
            for (l, e) in expected.iter().enumerate() {
                let total: f64 = (0..count).map(|k| out[k * cells + l]).sum();
                assert!(
                    (total - e).abs() < 1e-9 * (1.0 + e.abs()),
                    "lag {l}: {total} vs {e}"
                );
            }
        }
    }
}
