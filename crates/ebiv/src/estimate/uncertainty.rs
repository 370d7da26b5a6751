//! Per-vector standard uncertainty from the vector's own evidence: a delete-a-block jackknife
//! over the image blocks that make up a correlation plane or a contrast objective.
//!
//! Every estimator of ebiv locates the maximum of a sum over pixels: the correlation plane is
//! a sum of per-pixel products (Wieneke 2015, Meas. Sci. Technol. 26:074002, "correlation
//! statistics"), and the contrast of the image of warped events a sum of per-pixel squares
//! (Gallego et al. 2018). Wieneke estimates the uncertainty of the correlation peak from the
//! scatter of the per-pixel contributions to the three values of its sub-pixel fit. Here the
//! window is cut into square blocks of [`BLOCK_PX`] pixels, and the estimate is repeated with
//! each block's contribution taken out (Quenouille–Tukey jackknife; Efron & Tibshirani 1993,
//! *An Introduction to the Bootstrap*, ch. 11): the spread of these estimates is the
//! uncertainty of the one from all blocks. Blocks rather than pixels, because the pixels of
//! one particle image, and of one particle's trail, are not independent; a block of 8 px holds
//! a particle image of 2–3 px with its neighbourhood and a part of its trail.
//!
//! For an estimate that does not change when its objective is scaled (a peak position), the
//! deletion of block `k` moves the estimate by `δ_k ≈ −f′·(c_k − c̄)`, `c_k` the block's
//! contribution and `c̄` their mean; the variance of the sum of `B` independent block
//! contributions is estimated by `B/(B − 1)·Σ (c_k − c̄)²`, so
//! `σ² = B/(B − 1)·Σ_k (θ_k − θ̄)²` ([`jackknife_sigma`]). With the objective's gradient and
//! Hessian at its maximum (motion compensation), the same in closed form: a Newton step
//! moves the estimate by `H⁻¹ g_k` when block `k`, of gradient `g_k`, is taken out, and
//! `Cov = H⁻¹ S H⁻¹` with `S = B/(B − 1)·Σ (g_k − ḡ)(g_k − ḡ)ᵀ` ([`sandwich_sigma`]; the
//! "sandwich" covariance of an M-estimator, Huber 1967).
//!
//! The factor `B/(B − 1)` assumes `B` blocks of equal standing. The blocks of a window are
//! not: most hold no particle, and a few hold most of the signal. With weights `w_k` (a
//! block's share of the correlation peak, or its events), the blocks count as Kish's
//! effective number `B_eff = (Σ w_k)²/Σ w_k²` (Kish 1965, *Survey Sampling*, §11.7), and the
//! factor is `B_eff/(B_eff − 1)` ([`effective_blocks`]): close to 1 in a window of many
//! particles, large in one of two or three, where a spread measured from so few
//! contributions is itself uncertain. With `B_eff ≤ 1` (one block holds all the signal) the
//! spread cannot be measured and σ is NaN.
//!
//! What this measures is the random error due to the particular particles, events and
//! pixels of the window. It does not see bias: peak locking, a velocity gradient across
//! the window that the estimator does not follow, or a wrong predictor.
//! `docs/uncertainty.md` gives its coverage on simulated recordings.

/// Side of the square blocks whose contributions the jackknife takes out one at a time, px.
pub const BLOCK_PX: usize = 8;

/// The blocks of [`BLOCK_PX`] pixels covering a `w × h` window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Blocks {
    across: usize,
    down: usize,
}

impl Blocks {
    /// The blocks of a window of `w × h` px (partial blocks at the right and bottom edges).
    pub fn of(w: usize, h: usize) -> Self {
        Blocks {
            across: w.div_ceil(BLOCK_PX).max(1),
            down: h.div_ceil(BLOCK_PX).max(1),
        }
    }

    /// Number of blocks.
    pub fn count(&self) -> usize {
        self.across * self.down
    }

    /// The block of pixel `(x, y)` of the window (which must lie in it).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> usize {
        (y / BLOCK_PX).min(self.down - 1) * self.across + (x / BLOCK_PX).min(self.across - 1)
    }
}

/// Kish's effective number of blocks `(Σ w)²/Σ w²` of blocks of weights `weights` (negative
/// weights count as zero); 0 when no weight is positive.
pub(crate) fn effective_blocks(weights: impl IntoIterator<Item = f64>) -> f64 {
    let (mut sum, mut squares) = (0.0, 0.0);
    for w in weights {
        let w = w.max(0.0);
        sum += w;
        squares += w * w;
    }
    if squares > 0.0 {
        sum * sum / squares
    } else {
        0.0
    }
}

/// The factor `B_eff/(B_eff − 1)` of the variance of [`jackknife_sigma`] and
/// [`sandwich_sigma`] for blocks of weights `weights`; NaN for `B_eff ≤ 1`.
fn small_sample_factor(weights: &[f64]) -> f64 {
    let n = effective_blocks(weights.iter().copied());
    if n > 1.0 {
        n / (n - 1.0)
    } else {
        f64::NAN
    }
}

/// Standard deviation per component of an estimate from the estimates `deleted` with one
/// block taken out each, the blocks weighing `weights`:
/// `σ² = B_eff/(B_eff − 1)·Σ (θ_k − θ̄)²` (see the module doc). NaN with fewer than two
/// blocks, an effective number of blocks of 1 or less, or a non-finite estimate among them.
pub(crate) fn jackknife_sigma(deleted: &[[f64; 2]], weights: &[f64]) -> [f64; 2] {
    let b = deleted.len();
    if b < 2 || deleted.iter().flatten().any(|v| !v.is_finite()) {
        return [f64::NAN; 2];
    }
    let factor = small_sample_factor(weights);
    let n = b as f64;
    [0, 1].map(|axis| {
        let mean = deleted.iter().map(|d| d[axis]).sum::<f64>() / n;
        let squares: f64 = deleted.iter().map(|d| (d[axis] - mean).powi(2)).sum();
        (factor * squares).sqrt()
    })
}

/// Standard deviation per component of the maximum of an objective of Hessian `hessian` at
/// the maximum, from the gradients `gradients` of its blocks there, the blocks weighing
/// `weights`: the diagonal of `H⁻¹ S H⁻¹`, `S = B_eff/(B_eff − 1)·Σ (g_k − ḡ)(g_k − ḡ)ᵀ` (see
/// the module doc). NaN with fewer than two blocks, an effective number of blocks of 1 or
/// less, or a Hessian that is not negative definite (no maximum).
pub(crate) fn sandwich_sigma(
    hessian: [[f64; 2]; 2],
    gradients: &[[f64; 2]],
    weights: &[f64],
) -> [f64; 2] {
    let b = gradients.len();
    let [[a, c], [_, d]] = hessian;
    let det = a * d - c * c;
    if b < 2 || !(a < 0.0 && det > 0.0) || !det.is_finite() {
        return [f64::NAN; 2];
    }
    let n = b as f64;
    let mean = [0, 1].map(|i| gradients.iter().map(|g| g[i]).sum::<f64>() / n);
    let mut s = [[0.0; 2]; 2];
    for g in gradients {
        let e = [g[0] - mean[0], g[1] - mean[1]];
        for i in 0..2 {
            for j in 0..2 {
                s[i][j] += e[i] * e[j];
            }
        }
    }
    let scale = small_sample_factor(weights);
    // H⁻¹ of the symmetric 2 × 2 Hessian.
    let inv = [[d / det, -c / det], [-c / det, a / det]];
    let mut cov = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            let mut sum = 0.0;
            for k in 0..2 {
                for l in 0..2 {
                    sum += inv[i][k] * s[k][l] * inv[l][j];
                }
            }
            cov[i][j] = scale * sum;
        }
    }
    [cov[0][0].max(0.0).sqrt(), cov[1][1].max(0.0).sqrt()]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deletion estimates that move by minus each block's value (a location estimate with
    /// `f′ = 1`) of blocks of equal weight give the standard deviation of the sum of the
    /// values, `√(n/(n − 1)·Σ(v − v̄)²)`.
    #[test]
    fn jackknife_of_block_deletion_gives_the_spread_of_a_sum() {
        let values = [3.0, 5.0, 4.0, 8.0, 6.0, 2.0];
        let equal = [1.0; 6];
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let deleted: Vec<[f64; 2]> = values.iter().map(|&v| [-v, 2.0 * v]).collect();
        let expected =
            (n / (n - 1.0) * values.iter().map(|v| (v - mean).powi(2)).sum::<f64>()).sqrt();
        let [sx, sy] = jackknife_sigma(&deleted, &equal);
        assert!((sx - expected).abs() < 1e-12);
        assert!((sy - 2.0 * expected).abs() < 1e-12);
        assert!(jackknife_sigma(&deleted[..1], &equal[..1])[0].is_nan());
        assert!(jackknife_sigma(&[[1.0, f64::NAN], [2.0, 3.0]], &equal[..2])[0].is_nan());
    }

    /// Kish's effective number: equal weights count fully, empty blocks not at all, and two
    /// blocks of weights 3 and 1 as 16/10; the variance factor follows it, NaN for one block.
    #[test]
    fn effective_blocks_and_the_small_sample_factor() {
        assert!((effective_blocks([2.0; 5]) - 5.0).abs() < 1e-12);
        assert!((effective_blocks([2.0, 0.0, 2.0, -1.0, 0.0]) - 2.0).abs() < 1e-12);
        assert!((effective_blocks([3.0, 1.0]) - 1.6).abs() < 1e-12);
        assert_eq!(effective_blocks([0.0, 0.0]), 0.0);
        assert!((small_sample_factor(&[3.0, 1.0]) - 1.6 / 0.6).abs() < 1e-12);
        assert!(small_sample_factor(&[0.0, 4.0, 0.0]).is_nan());
        // Deletions of empty blocks move nothing, and the few full blocks set the factor.
        let deleted = [[1.0, 0.0], [-1.0, 0.0], [0.0, 0.0], [0.0, 0.0]];
        let [sx, _] = jackknife_sigma(&deleted, &[1.0, 1.0, 0.0, 0.0]);
        assert!((sx - (2.0f64 * 2.0).sqrt()).abs() < 1e-12);
    }

    /// For a quadratic objective `−½ a x²` per axis the sandwich covariance of a scatter of
    /// block gradients `g` is `Σ(g − ḡ)²·B/(B − 1) / a²`.
    #[test]
    fn sandwich_of_a_diagonal_hessian() {
        let gradients = [[1.0, 0.0], [-1.0, 2.0], [3.0, -2.0], [1.0, 0.0]];
        let equal = [1.0; 4];
        let [sx, sy] = sandwich_sigma([[-2.0, 0.0], [0.0, -4.0]], &gradients, &equal);
        // x: mean 1, deviations 0, −2, 2, 0 → Σ = 8, ×4/3 → 32/3, / 2² → 8/3.
        assert!((sx - (8.0f64 / 3.0).sqrt()).abs() < 1e-12);
        // y: mean 0, Σ = 8, ×4/3, / 16 → 2/3.
        assert!((sy - (2.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!(sandwich_sigma([[2.0, 0.0], [0.0, -4.0]], &gradients, &equal)[0].is_nan());
    }

    #[test]
    fn blocks_cover_the_window_with_partial_blocks_at_the_edges() {
        let b = Blocks::of(20, 9);
        assert_eq!(b.count(), 3 * 2);
        assert_eq!(b.at(0, 0), 0);
        assert_eq!(b.at(19, 8), 5);
        assert_eq!(b.at(8, 7), 1);
    }
}
