//! Coverage of the per-vector standard uncertainty: how often the true error lies within
//! ±1σ and ±2σ, and whether larger σ goes with larger errors (Spearman's rank correlation).
//!
//! For a standard uncertainty that describes Gaussian errors, 68.3 % of the errors lie within
//! ±1σ and 95.4 % within ±2σ (JCGM 100:2008, the GUM, §G); Sciacchitano et al. (Meas. Sci.
//! Technol. 26:074004, 2015) and Wieneke (Meas. Sci. Technol. 26:074002, 2015) validate PIV
//! uncertainties this way. Both components are pooled: each valid vector with a known σ
//! contributes two samples e_u/σ_u and e_v/σ_v.

use serde::Serialize;

/// Range of the histogram of normalised errors e/σ.
pub const NORMALISED_RANGE: f64 = 4.0;
/// Bins of the histogram of normalised errors over [−4, 4].
pub const NORMALISED_BINS: usize = 32;

/// Coverage statistics of the uncertainty, pooled over both components.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Coverage {
    /// Component samples with a finite, positive σ.
    pub samples: usize,
    /// Component samples of valid vectors left out because σ is unknown (NaN) or not
    /// positive.
    pub without_uncertainty: usize,
    /// Share of samples with |e| ≤ σ (0.683 for well-estimated Gaussian errors).
    pub within_1_sigma: f64,
    /// Share of samples with |e| ≤ 2σ (0.954 for well-estimated Gaussian errors).
    pub within_2_sigma: f64,
    /// Spearman rank correlation between |e| and σ (positive: larger σ, larger errors).
    pub spearman: f64,
    /// Root mean square of e/σ (1 for well-estimated uncertainties).
    pub rms_normalised: f64,
    /// Histogram of e/σ over [−4, 4] in [`NORMALISED_BINS`] bins.
    pub normalised_histogram: Vec<u64>,
    /// Samples with |e/σ| > 4.
    pub normalised_outside: u64,
    /// Up to a few thousand (σ, |e|) pairs for a scatter plot, evenly thinned.
    pub scatter: Vec<[f64; 2]>,
}

/// Largest number of (σ, |e|) pairs kept for plotting.
const MAX_SCATTER: usize = 5000;

impl Coverage {
    /// Coverage of component errors `errors[k]` with standard uncertainties `sigmas[k]`;
    /// pairs whose σ is not finite and positive are counted in `without_uncertainty`.
    pub fn of(errors: &[f64], sigmas: &[f64]) -> Coverage {
        let mut e_abs = Vec::new();
        let mut s_ok = Vec::new();
        let mut without = 0;
        let mut hist = vec![0u64; NORMALISED_BINS];
        let mut outside = 0;
        let (mut in1, mut in2, mut sq) = (0usize, 0usize, 0.0);
        for (&e, &s) in errors.iter().zip(sigmas) {
            if !(s.is_finite() && s > 0.0 && e.is_finite()) {
                without += 1;
                continue;
            }
            let z = e / s;
            in1 += usize::from(z.abs() <= 1.0);
            in2 += usize::from(z.abs() <= 2.0);
            sq += z * z;
            if z.abs() > NORMALISED_RANGE {
                outside += 1;
            } else {
                let b = ((z + NORMALISED_RANGE) / (2.0 * NORMALISED_RANGE) * NORMALISED_BINS as f64)
                    as usize;
                hist[b.min(NORMALISED_BINS - 1)] += 1;
            }
            e_abs.push(e.abs());
            s_ok.push(s);
        }
        let n = e_abs.len();
        let share = |k: usize| {
            if n == 0 {
                f64::NAN
            } else {
                k as f64 / n as f64
            }
        };
        let stride = n.div_ceil(MAX_SCATTER).max(1);
        let scatter = (0..n)
            .step_by(stride)
            .map(|i| [s_ok[i], e_abs[i]])
            .collect();
        Coverage {
            samples: n,
            without_uncertainty: without,
            within_1_sigma: share(in1),
            within_2_sigma: share(in2),
            spearman: spearman(&e_abs, &s_ok),
            rms_normalised: if n == 0 {
                f64::NAN
            } else {
                (sq / n as f64).sqrt()
            },
            normalised_histogram: hist,
            normalised_outside: outside,
            scatter,
        }
    }
}

/// Ranks of `values` from 1, ties given their average rank.
fn ranks(values: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut ranks = vec![0.0; values.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && values[order[j + 1]] == values[order[i]] {
            j += 1;
        }
        let average = (i + j) as f64 / 2.0 + 1.0;
        for &k in &order[i..=j] {
            ranks[k] = average;
        }
        i = j + 1;
    }
    ranks
}

/// Spearman's rank correlation coefficient of `a` and `b`: the Pearson correlation of their
/// ranks, ties given average ranks (Spearman 1904; Press et al., *Numerical Recipes*, §14.6).
/// NaN with fewer than two pairs or when either has no spread.
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 2 {
        return f64::NAN;
    }
    let (ra, rb) = (ranks(&a[..n]), ranks(&b[..n]));
    let mean = (n as f64 + 1.0) / 2.0;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - mean) * (y - mean);
        saa += (x - mean) * (x - mean);
        sbb += (y - mean) * (y - mean);
    }
    if saa == 0.0 || sbb == 0.0 {
        return f64::NAN;
    }
    sab / (saa * sbb).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spearman_of_monotonic_and_reversed_and_tied_data() {
        assert_eq!(spearman(&[1.0, 2.0, 3.0], &[10.0, 20.0, 300.0]), 1.0);
        assert_eq!(spearman(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]), -1.0);
        // Hand-computed: ranks a = 1 2 3 4, b = 1 3 2 4: 1 − 6·Σd²/(n(n²−1)) = 1 − 12/60.
        assert!((spearman(&[1.0, 2.0, 3.0, 4.0], &[1.0, 3.0, 2.0, 4.0]) - 0.8).abs() < 1e-12);
        // Ties: b ranks 1.5 1.5 3; Pearson of (1,2,3) and (1.5,1.5,3) = √3/2.
        let r = spearman(&[1.0, 2.0, 3.0], &[5.0, 5.0, 7.0]);
        assert!((r - 3f64.sqrt() / 2.0).abs() < 1e-12, "{r}");
        assert!(spearman(&[1.0], &[1.0]).is_nan());
        assert!(spearman(&[1.0, 2.0], &[1.0, 1.0]).is_nan());
    }

    #[test]
    fn coverage_counts_errors_within_one_and_two_sigma() {
        let errors = [0.5, -0.9, 1.5, -2.5, 0.1, 3.0];
        let sigmas = [1.0, 1.0, 1.0, 1.0, f64::NAN, 0.0];
        let c = Coverage::of(&errors, &sigmas);
        assert_eq!((c.samples, c.without_uncertainty), (4, 2));
        assert_eq!((c.within_1_sigma, c.within_2_sigma), (0.5, 0.75));
        let rms = ((0.25 + 0.81 + 2.25 + 6.25) / 4.0f64).sqrt();
        assert!((c.rms_normalised - rms).abs() < 1e-12);
        assert_eq!(c.normalised_histogram.iter().sum::<u64>(), 4);
        assert_eq!(c.scatter.len(), 4);
        let empty = Coverage::of(&[1.0], &[f64::NAN]);
        assert!(empty.within_1_sigma.is_nan() && empty.samples == 0);
    }
}
