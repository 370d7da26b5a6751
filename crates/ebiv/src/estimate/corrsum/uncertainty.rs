//! Standard uncertainty of a sum-of-correlation peak: the delete-a-block jackknife of
//! [`crate::estimate::uncertainty`] on the summed plane.
//!
//! The plane at lag `l` is a sum over the window's pixels `x` and the slice pairs `s` of the
//! mean-subtracted products `(a_s(x) − ā_s)(b_s(x + l) − b̄_s)`, weighted per slice by
//! `1/(σ_a σ_b)` and divided by the overlap area and the number of slices
//! ([`direct::correlations_at`](super::direct::correlations_at)). Grouping the products by the
//! block of `x` splits the plane near the peak into the contributions of the window's blocks,
//! which add up to it exactly; the peak is fitted again, as the estimator fits it (smoothing
//! and sub-pixel fit), with each block's contribution taken out. A block weighs its
//! contribution to the peak.

use super::fit::{fit_reach, refine_with_kernel, SmoothingKernel};
use super::voxels::{PlaneShape, SliceStats, SubVolume};
use crate::estimate::uncertainty::{jackknife_sigma, Blocks};
use crate::peak::{Peak, SubPixelFit};

/// Share of a block's contribution taken out (see [`peak_sigma`]).
const DELETED_SHARE: f64 = 0.1;

/// Working memory of [`peak_sigma`], reused across windows.
#[derive(Debug, Clone, Default)]
pub(super) struct BlockPlanes {
    /// Per block, the contributions to the neighbourhood of the peak, `side²` values each.
    contributions: Vec<f64>,
    /// The neighbourhood of the plane, and one with a block taken out.
    local: Vec<f64>,
    deleted: Vec<f64>,
    /// Peak positions with one block taken out.
    estimates: Vec<[f64; 2]>,
    /// Each block's contribution to the peak, its weight.
    weights: Vec<f64>,
    /// Block of each pixel of the window.
    labels: Vec<u32>,
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
    let cells = side * side;
    // Lags of the neighbourhood, in the sub-volumes' pixels.
    let lag = |cell: usize| {
        let (i, j) = ((cell / side) as i64, (cell % side) as i64);
        [
            peak.col as i64 - reach as i64 + j - shape.rx as i64,
            peak.row as i64 - reach as i64 + i - shape.ry as i64,
        ]
    };
    work.local.clear();
    for i in 0..side {
        let row = (peak.row - reach + i) * pw + peak.col - reach;
        work.local.extend_from_slice(&plane[row..row + side]);
    }
    let blocks = Blocks::of(shape.w, shape.h);
    let count = blocks.count();
    work.labels.clear();
    work.labels
        .extend((0..shape.w * shape.h).map(|i| blocks.at(i % shape.w, i / shape.w) as u32));
    block_contributions(
        (a, b),
        stats,
        shape,
        (&lag, cells),
        (&work.labels, count),
        image,
        &mut work.contributions,
    );
    let local_peak = Peak {
        col: reach,
        row: reach,
        x: peak.x - peak.col as f64 + reach as f64,
        y: peak.y - peak.row as f64 + reach as f64,
        on_edge: false,
        ..*peak
    };
    work.estimates.clear();
    for k in 0..count {
        let part = &work.contributions[k * cells..(k + 1) * cells];
        work.deleted.clear();
        work.deleted.extend(
            work.local
                .iter()
                .zip(part)
                .map(|(v, c)| v - DELETED_SHARE * c),
        );
        let position = refine_with_kernel(&work.deleted, [side, side], &local_peak, kernel, fit);
        work.estimates.push(position.map(|p| p / DELETED_SHARE));
    }
    let centre = reach * side + reach;
    work.weights.clear();
    work.weights
        .extend((0..count).map(|k| work.contributions[k * cells + centre]));
    jackknife_sigma(&work.estimates, &work.weights)
}

/// The contributions of each block (`labels`: the block of each pixel, `blocks` of them) to
/// the plane at the `cells` lags `lag(0..cells)`, into `out` (block-major): the
/// mean-subtracted products `a(x)(b(x + l) − b̄)` of the voxels `a(x)` in the block. The rest
/// of the plane, `−ā Σ (b − b̄)` over the overlap, is a smooth function of the lag that
/// belongs to no block and is not taken out (split by the block of each partner pixel, it
/// would step between neighbouring blocks as the lag changes, and the steps, which cancel in
/// the sum, would pass for disagreement between the blocks). `image` is a zeroed `w × h` grid, left zeroed.
#[allow(clippy::too_many_arguments)]
fn block_contributions(
    (a, b): (SubVolume<'_>, SubVolume<'_>),
    stats: &[SliceStats],
    shape: PlaneShape,
    (lag, cells): (&dyn Fn(usize) -> [i64; 2], usize),
    (labels, blocks): (&[u32], usize),
    image: &mut Vec<f64>,
    out: &mut Vec<f64>,
) {
    let (w, h) = (shape.w as i64, shape.h as i64);
    out.clear();
    out.resize(blocks * cells, 0.0);
    image.resize(shape.w * shape.h, 0.0);
    let lags: Vec<[i64; 2]> = (0..cells).map(lag).collect();
    let slices = stats.len() as f64;
    // Per lag, the factor of every product: 1 / (overlap area × slices); 0 without overlap.
    let scale: Vec<f64> = lags
        .iter()
        .map(|&[dx, dy]| {
            let area = ((w - dx.abs()).max(0) * (h - dy.abs()).max(0)) as f64;
            if area > 0.0 {
                1.0 / (area * slices)
            } else {
                0.0
            }
        })
        .collect();
    let inside = |x: i64, y: i64| (0..w).contains(&x) && (0..h).contains(&y);
    let value = |v: SubVolume<'_>, i: usize| if v.vox.unit { 1.0 } else { v.vox.v[i] };
    for s in stats {
        let (ra, rb) = (a.range(s.z), b.range(s.z));
        for j in rb.clone() {
            image[b.vox.y[j] as usize * shape.w + b.vox.x[j] as usize] = value(b, j);
        }
        for i in ra {
            let (x, y, v) = (i64::from(a.vox.x[i]), i64::from(a.vox.y[i]), value(a, i));
            let block = labels[y as usize * shape.w + x as usize] as usize;
            let row = &mut out[block * cells..][..cells];
            for (l, &[dx, dy]) in lags.iter().enumerate() {
                let (qx, qy) = (x + dx, y + dy);
                if inside(qx, qy) {
                    let partner = image[(qy * w + qx) as usize];
                    row[l] += s.weight * scale[l] * v * (partner - s.mean_b);
                }
            }
        }
        for j in rb {
            image[b.vox.y[j] as usize * shape.w + b.vox.x[j] as usize] = 0.0;
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
        let lags = [[2, 1], [1, 1], [3, 1], [2, 0], [-4, 3]];
        let mut image = Vec::new();
        let mut expected = [0.0; 5];
        correlations_at((a, b), &stats, shape, &lags, &mut image, &mut expected);
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
        let labels: Vec<u32> = (0..16 * 12)
            .map(|i| blocks.at(i % 16, i / 16) as u32)
            .collect();
        let mut out = Vec::new();
        let lag = |l: usize| lags[l];
        block_contributions(
            (a, b),
            &stats,
            shape,
            (&lag, 5),
            (&labels, count),
            &mut image,
            &mut out,
        );
        assert!(image.iter().all(|&v| v == 0.0));
        for (l, e) in expected.iter().enumerate() {
            let total: f64 = (0..count).map(|k| out[k * 5 + l]).sum();
            assert!(
                (total - e).abs() < 1e-9 * (1.0 + e.abs()),
                "lag {l}: {total} vs {e}"
            );
        }
    }
}
