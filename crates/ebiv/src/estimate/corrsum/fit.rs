//! Sub-pixel refinement of tilted, narrow correlation peaks.

use crate::peak::{three_point, Peak, SubPixelFit};

/// Peak position. For the 2-D Gaussian fit, a log-domain least-squares Gaussian over the
/// positive values of the 3 × 3 neighbourhood, weighted by value² (Nobach & Honkanen 2005):
/// beside the narrow, tilted peaks of event correlation one of the nine values is often not
/// positive, and [`find_peak`](crate::peak::find_peak)'s axis-wise fall-back is then biased (up to 0.3 px).
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
            let (w, ln_v) = (v * v, v.ln());
            for i in 0..6 {
                for j in i..6 {
                    m[i][j] += w * basis[i] * basis[j];
                }
                m[i][6] += w * basis[i] * ln_v;
            }
        }
    }
    // The matrix is symmetric, and exactly so: the basis values are −1, 0 or 1, so
    // `w·bᵢ·bⱼ` is the same number in either order and the lower triangle repeats the sums.
    let upper = m;
    for (i, row) in m.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate().take(i) {
            *cell = upper[j][i];
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
        let pivot_row = m[col];
        for row in &mut m[col + 1..] {
            let f = row[col] / pivot_row[col];
            // The entry below the pivot is left as it is (it would become ≈ 0) and is never
            // read again: only the columns after it are updated, as contiguous slices the
            // compiler vectorises.
            for (x, p) in row[col + 1..].iter_mut().zip(&pivot_row[col + 1..]) {
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

/// Peak position on the plane smoothed by a Gaussian of `sigma` px (0: the plane itself).
///
/// A summed event correlation peak is narrow: the pairs of pixel-quantised events give a
/// histogram of integer displacements, about one pixel wide, whose three-point fits lock onto
/// integer displacements (peak locking, Raffel et al. 2018 §5.4.2; up to 0.1 px here for
/// half-pixel displacements). Smoothing near the peak widens it so that the Gaussian fit
/// recovers the histogram's centre, as a particle image diameter of 2–3 px does in PIV
/// (Westerweel 1997, Meas. Sci. Technol. 8:1379). The smoothed values are computed only
/// around the integer maximum; the peak height and ratio stay those of the plane.
#[cfg(test)]
pub(super) fn refine_smoothed(
    plane: &[f64],
    size: [usize; 2],
    peak: &Peak,
    sigma: f64,
    fit: SubPixelFit,
) -> [f64; 2] {
    refine_with_kernel(plane, size, peak, &SmoothingKernel::new(sigma), fit)
}

/// [`refine_smoothed`] with the kernel of σ tabulated once (per estimator, not per window).
pub(super) fn refine_with_kernel(
    plane: &[f64],
    [width, height]: [usize; 2],
    peak: &Peak,
    kernel: &SmoothingKernel,
    fit: SubPixelFit,
) -> [f64; 2] {
    match smoothed_block(plane, [width, height], peak, kernel) {
        None => refine_tilted(plane, width, peak, fit),
        Some(([r0, c0], smoothed)) => {
            let local = smoothed.block();
            let [x, y] = fit_block(&local, fit);
            [c0 as f64 - 1.0 + x, r0 as f64 - 1.0 + y]
        }
    }
}

/// The smoothed plane's maximum next to `peak` and the 3 × 3 block of smoothed values
/// around it, which [`refine_with_kernel`] fits; `None` where it does not smooth.
fn smoothed_block(
    plane: &[f64],
    [width, height]: [usize; 2],
    peak: &Peak,
    kernel: &SmoothingKernel,
) -> Option<([isize; 2], Smoothed)> {
    let (w, h) = (width as isize, height as isize);
    let (r0, c0) = (peak.row as isize, peak.col as isize);
    let sigma = kernel.sigma;
    // Near the plane's border the kernel would be one-sided and pull the fit toward the
    // border: no smoothing there (nor for σ too small to matter, or on small planes).
    let room = r0.min(c0).min(h - 1 - r0).min(w - 1 - c0);
    if sigma.is_nan() || sigma < MIN_SIGMA || peak.on_edge || room < reach(sigma) + BLOCK {
        return None;
    }
    let smoothed = Smoothed::around(plane, [w, h], [r0, c0], kernel);
    // The smoothed maximum lies at or next to the plane's (not on the plane's border).
    let mut best = (r0, c0, smoothed.at(r0, c0));
    for r in (r0 - 1).max(1)..=(r0 + 1).min(h - 2) {
        for c in (c0 - 1).max(1)..=(c0 + 1).min(w - 2) {
            let v = smoothed.at(r, c);
            if v > best.2 {
                best = (r, c, v);
            }
        }
    }
    let (r1, c1, _) = best;
    // Usually the plane's maximum stays the smoothed one and its block is the fit's
    // neighbourhood; otherwise the block around the new maximum (every smoothed value
    // depends only on the plane, not on the block it is computed in).
    let smoothed = if (r1, c1) == (r0, c0) {
        smoothed
    } else {
        Smoothed::around(plane, [w, h], [r1, c1], kernel)
    };
    Some(([r1, c1], smoothed))
}

/// The sub-pixel position, in the coordinates of the 3 × 3 block `local` (centre cell at
/// (1, 1)), that `fit` finds in it: the three-point fits per axis, refined by the 2-D
/// Gaussian fit where `fit` is one.
fn fit_block(local: &[f64; 9], fit: SubPixelFit) -> [f64; 2] {
    let axis = |a: f64, b: f64, c: f64| 1.0 + three_point(a, b, c, fit.per_axis()).unwrap_or(0.0);
    let centre = Peak {
        col: 1,
        row: 1,
        x: axis(local[3], local[4], local[5]),
        y: axis(local[1], local[4], local[7]),
        value: local[4],
        on_edge: false,
        second: f64::NAN,
    };
    refine_tilted(local, 3, &centre, fit)
}

/// The first-order response of [`refine_with_kernel`]'s position to each value of the
/// `width × height` plane `plane` around `peak`: into `gradient[axis]` (one value per plane
/// cell), so that adding `Δ` to the plane moves the position by about `Σ gradient·Δ` per axis
/// (the influence of each value; Jaeckel 1972, the infinitesimal jackknife). The fit reads
/// a 3 × 3 block of values, smoothed or not; its derivatives in them (forward differences)
/// are spread back over the plane through the smoothing kernel's weights. The block is the
/// one the fit of `plane` itself reads, so a change large enough to move the maximum to
/// another cell is not followed; where the 2-D Gaussian fit of an unsmoothed block fails,
/// the gradient is that of the three-point fits, not of the peak's own fall-back. A block
/// holding an exact zero (where the fits switch form) gets no gradient.
pub(super) fn fit_gradient(
    plane: &[f64],
    [width, height]: [usize; 2],
    peak: &Peak,
    kernel: &SmoothingKernel,
    fit: SubPixelFit,
    gradient: &mut [Vec<f64>; 2],
) {
    for g in gradient.iter_mut() {
        g.clear();
        g.resize(width * height, 0.0);
    }
    let smoothed = smoothed_block(plane, [width, height], peak, kernel);
    let (centre, local) = match &smoothed {
        Some((centre, s)) => (*centre, s.block()),
        None if peak.on_edge || peak.row == 0 || peak.col == 0 => return,
        None if peak.row + 1 >= height || peak.col + 1 >= width => return,
        None => {
            let (r0, c0) = (peak.row, peak.col);
            let block = std::array::from_fn(|k| plane[(r0 + k / 3 - 1) * width + c0 + k % 3 - 1]);
            ([r0 as isize, c0 as isize], block)
        }
    };
    if local.contains(&0.0) {
        return;
    }
    // ∂position/∂(block value k), forward differences with a step relative to the value
    // (truncation error of the order of the step, 10⁻⁶ of the value: ample for a σ).
    let mut partial = [[0.0; 9]; 2];
    let base = fit_block(&local, fit);
    for k in 0..9 {
        let step = 1e-6 * local[k].abs().max(f64::MIN_POSITIVE.sqrt());
        let mut moved = local;
        moved[k] += step;
        let shifted = fit_block(&moved, fit);
        for axis in 0..2 {
            partial[axis][k] = (shifted[axis] - base[axis]) / step;
        }
    }
    let [r0, c0] = centre;
    let taps: &[f64] = match smoothed {
        Some(_) => &kernel.taps[..2 * reach(kernel.sigma) as usize + 1],
        None => &[1.0],
    };
    let half = (taps.len() / 2) as isize;
    // Inside the plane every smoothed value is Σ tᵢ tⱼ v / (Σ t)² ([`Smoothed::around`]).
    let total: f64 = taps.iter().sum();
    let norm = 1.0 / (total * total);
    for (k, (du, dv)) in partial[0].iter().zip(&partial[1]).enumerate() {
        let (rk, ck) = (r0 + k as isize / 3 - 1, c0 + k as isize % 3 - 1);
        for (i, ti) in taps.iter().enumerate() {
            for (j, tj) in taps.iter().enumerate() {
                let (r, c) = (rk + i as isize - half, ck + j as isize - half);
                let cell = (r * width as isize + c) as usize;
                let weight = ti * tj * norm;
                gradient[0][cell] += du * weight;
                gradient[1][cell] += dv * weight;
            }
        }
    }
}

/// Half-width of the neighbourhood of the integer maximum `peak` of a `width × height`
/// plane whose values [`refine_with_kernel`] reads: the smoothed candidates at ±1 with their
/// 3 × 3 blocks and the kernel's reach, or the 3 × 3 neighbourhood where it does not smooth.
pub(super) fn fit_reach(
    kernel: &SmoothingKernel,
    [width, height]: [usize; 2],
    peak: &Peak,
) -> usize {
    let (w, h) = (width as isize, height as isize);
    let (r0, c0) = (peak.row as isize, peak.col as isize);
    let sigma = kernel.sigma;
    let room = r0.min(c0).min(h - 1 - r0).min(w - 1 - c0);
    if sigma.is_nan() || sigma < MIN_SIGMA || peak.on_edge || room < reach(sigma) + BLOCK {
        1
    } else {
        (reach(sigma) + BLOCK) as usize
    }
}

/// How far from the plane's maximum smoothed values are used: candidates at ±1 and their
/// 3 × 3 neighbourhoods.
const BLOCK: isize = 2;
/// Half-width of a block of smoothed values ([`Smoothed`]): 3 × 3.
const HALF: isize = 1;
/// Cells per side of a block.
const SIDE: usize = 2 * HALF as usize + 1;
/// Widest kernel half-width, taps (σ ≤ 5 px).
const MAX_REACH: usize = 10;
/// Smaller σ smooths nothing measurable (and `2σ²` could underflow).
const MIN_SIGMA: f64 = 1e-3;

/// Kernel half-width for `sigma`: the Gaussian truncated at ±2σ.
fn reach(sigma: f64) -> isize {
    ((2.0 * sigma).ceil() as usize).min(MAX_REACH) as isize
}

/// The taps of the truncated Gaussian (±2σ) that smooths the plane near its peak.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SmoothingKernel {
    sigma: f64,
    taps: [f64; 2 * MAX_REACH + 1],
}

impl SmoothingKernel {
    /// The kernel of standard deviation `sigma` px (no taps where σ is too small to smooth).
    pub fn new(sigma: f64) -> Self {
        let mut taps = [0.0; 2 * MAX_REACH + 1];
        if !sigma.is_nan() && sigma >= MIN_SIGMA {
            let reach = reach(sigma) as usize;
            for (k, t) in taps.iter_mut().take(2 * reach + 1).enumerate() {
                let d = k as f64 - reach as f64;
                *t = (-d * d / (2.0 * sigma * sigma)).exp();
            }
        }
        SmoothingKernel { sigma, taps }
    }
}

/// The plane smoothed by a truncated Gaussian (±2σ) on the 3 × 3 block around a point,
/// renormalised where the kernel leaves the plane or meets non-finite values: a separable
/// pass along rows, then along columns, carrying values and weights.
struct Smoothed {
    origin: [isize; 2],
    values: [[f64; SIDE]; SIDE],
}

impl Smoothed {
    fn around(
        plane: &[f64],
        [w, h]: [isize; 2],
        [r0, c0]: [isize; 2],
        kernel: &SmoothingKernel,
    ) -> Self {
        let reach = reach(kernel.sigma) as usize;
        let taps = &kernel.taps[..2 * reach + 1];
        let reach = reach as isize;
        // Row pass: for each row of the block's reach, Σ t v and Σ t at the block's columns.
        let rows = (2 * (HALF + reach) + 1) as usize;
        let mut across = [[(0.0, 0.0); SIDE]; 2 * (HALF as usize + MAX_REACH) + 1];
        // Inside the plane and all finite (the usual case): the same sums without tests.
        let (top, left) = (r0 - HALF - reach, c0 - HALF - reach);
        let inside = top >= 0 && left >= 0 && top + rows as isize <= h && left + rows as isize <= w;
        let region = |k: usize| {
            let start = ((top + k as isize) * w + left) as usize;
            &plane[start..start + rows]
        };
        if inside && (0..rows).all(|k| region(k).iter().all(|v| v.is_finite())) {
            // Every cell's weight is then the sum of all taps, added in the same order.
            let total = taps.iter().fold(0.0, |sum, t| sum + t);
            for (k, line) in across.iter_mut().take(rows).enumerate() {
                let source = region(k);
                for (m, cell) in line.iter_mut().enumerate() {
                    for (v, t) in source[m..].iter().zip(taps) {
                        cell.0 += t * v;
                    }
                    cell.1 = total;
                }
            }
            return Smoothed::columns(&across, taps, [r0, c0]);
        }
        for (k, line) in across.iter_mut().take(rows).enumerate() {
            let r = r0 - HALF - reach + k as isize;
            if r < 0 || r >= h {
                continue;
            }
            for (m, cell) in line.iter_mut().enumerate() {
                let c = c0 - HALF + m as isize;
                for (j, t) in (-reach..=reach).zip(taps) {
                    let cc = c + j;
                    if cc < 0 || cc >= w {
                        continue;
                    }
                    let v = plane[(r * w + cc) as usize];
                    if v.is_finite() {
                        cell.0 += t * v;
                        cell.1 += t;
                    }
                }
            }
        }
        Smoothed::columns(&across, taps, [r0, c0])
    }

    /// Column pass over the row sums `across` (value, weight) of the block's columns.
    fn columns(across: &[[(f64, f64); SIDE]], taps: &[f64], [r0, c0]: [isize; 2]) -> Self {
        let mut values = [[f64::NAN; SIDE]; SIDE];
        for (n, row) in values.iter_mut().enumerate() {
            for (m, out) in row.iter_mut().enumerate() {
                let (mut sum, mut weight) = (0.0, 0.0);
                for (i, t) in taps.iter().enumerate() {
                    let (v, wt) = across[n + i][m];
                    sum += t * v;
                    weight += t * wt;
                }
                *out = sum / weight;
            }
        }
        Smoothed {
            origin: [r0 - HALF, c0 - HALF],
            values,
        }
    }

    /// The smoothed value at plane row `r`, column `c` (within the block).
    fn at(&self, r: isize, c: isize) -> f64 {
        self.values[(r - self.origin[0]) as usize][(c - self.origin[1]) as usize]
    }

    /// The 3 × 3 values, row-major.
    fn block(&self) -> [f64; 9] {
        std::array::from_fn(|k| self.values[k / 3][k % 3])
    }
}
