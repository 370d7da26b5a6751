//! The fractional-displacement histogram and the peak-locking index.
//!
//! Peak locking is the bias of sub-pixel peak estimators towards whole-pixel displacements
//! (Westerweel 1997, Meas. Sci. Technol. 8:1379; Raffel et al. 2018, §5.5). It shows in the
//! histogram of the fractional part of the displacement, d − round(d) ∈ [−0.5, 0.5) px: flat
//! for an unbiased estimator measuring displacements spread over several pixels, peaked at 0
//! with locking. The displacement of a velocity vector is u·T with T its time slab
//! (`slab_us`); a displacement field (PIV of an image pair) holds it directly.
//!
//! The index is Christensen's degree of peak locking (Exp. Fluids 36:484–497, 2004),
//! C = 1 − H_min / H_max, with H_min and H_max the smallest and largest bin of the
//! histogram: 0 for a flat histogram, 1 when every displacement is a whole pixel. With n
//! samples in B bins, sampling noise alone gives about 3·√(B/n) (the expected range of B
//! counts of n/B ± √(n/B)); only an index well above that shows locking, and only when the
//! true displacements spread over more than a pixel (a narrow displacement distribution is not
//! flat modulo 1 even when measured exactly). With 10 bins the index equals that of
//! [`crate::render::peak_locking_index`], which bins [0, 1) instead: the bin edges coincide
//! modulo 1.

use serde::Serialize;

/// Fractional part of a displacement `d`, px: d − round(d) in [−0.5, 0.5).
pub fn fractional_part(d: f64) -> f64 {
    d - (d + 0.5).floor()
}

/// Histogram of the fractional displacement of both components, with the peak-locking index.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FractionalHistogram {
    /// Counts of equal bins over [−0.5, 0.5) px.
    pub counts: Vec<u64>,
    /// Component samples counted (two per valid vector with a displacement).
    pub samples: u64,
    /// Valid velocity vectors left out because their slab length is unknown (0).
    pub without_slab: usize,
    /// Christensen's degree of peak locking 1 − H_min/H_max; NaN without samples.
    pub peak_locking_index: f64,
    /// The index sampling noise alone gives for this many samples, 3·√(B/n).
    pub noise_level: f64,
}

impl FractionalHistogram {
    /// An empty histogram of `bins` bins.
    pub(crate) fn new(bins: usize) -> Self {
        FractionalHistogram {
            counts: vec![0; bins.max(1)],
            samples: 0,
            without_slab: 0,
            peak_locking_index: f64::NAN,
            noise_level: f64::NAN,
        }
    }

    /// Count the displacement `d` px.
    pub(crate) fn add(&mut self, d: f64) {
        if !d.is_finite() {
            return;
        }
        let bins = self.counts.len();
        let b = ((fractional_part(d) + 0.5) * bins as f64) as usize;
        self.counts[b.min(bins - 1)] += 1;
        self.samples += 1;
    }

    /// Compute the index and the noise level from the counts.
    pub(crate) fn finish(&mut self) {
        let max = self.counts.iter().copied().max().unwrap_or(0);
        let min = self.counts.iter().copied().min().unwrap_or(0);
        self.peak_locking_index = peak_locking_index(min, max);
        self.noise_level = if self.samples == 0 {
            f64::NAN
        } else {
            (3.0 * (self.counts.len() as f64 / self.samples as f64).sqrt()).min(1.0)
        };
    }

    /// Lower edge of bin `b`, px.
    pub fn edge(&self, b: usize) -> f64 {
        -0.5 + b as f64 / self.counts.len() as f64
    }
}

/// 1 − min/max of a histogram's smallest and largest bin; NaN for an empty histogram.
fn peak_locking_index(min: u64, max: u64) -> f64 {
    if max == 0 {
        f64::NAN
    } else {
        1.0 - min as f64 / max as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fractional_parts_lie_in_the_half_open_interval() {
        assert_eq!(fractional_part(2.25), 0.25);
        assert_eq!(fractional_part(2.75), -0.25);
        assert_eq!(fractional_part(-1.5), -0.5);
        assert_eq!(fractional_part(0.5), -0.5);
        assert_eq!(fractional_part(-0.2), -0.2);
    }

    #[test]
    fn index_of_a_constructed_histogram() {
        // 4 bins: fractional parts −0.4, −0.1 ×3, 0.1 ×3, 0.3 ×2 → counts 1, 3, 3, 2.
        let mut h = FractionalHistogram::new(4);
        for d in [1.6, 0.9, 2.9, -0.1, 0.1, 5.1, -1.9, 0.3, 2.3] {
            h.add(d);
        }
        h.finish();
        assert_eq!(h.counts, vec![1, 3, 3, 2]);
        assert!((h.peak_locking_index - (1.0 - 1.0 / 3.0)).abs() < 1e-12);
        assert!((h.noise_level - (3.0 * (4.0f64 / 9.0).sqrt()).min(1.0)).abs() < 1e-12);
        assert_eq!(h.edge(1), -0.25);
        let mut flat = FractionalHistogram::new(2);
        for d in [0.25, -0.25, 1.25, 3.75] {
            flat.add(d);
        }
        flat.finish();
        assert_eq!(flat.peak_locking_index, 0.0);
        let mut empty = FractionalHistogram::new(10);
        empty.finish();
        assert!(empty.peak_locking_index.is_nan());
    }

    #[test]
    fn ten_bins_match_the_figure_index() {
        let values: Vec<f32> = (0..200).map(|i| (i as f32 * 0.37).sin() * 3.0).collect();
        let mut h = FractionalHistogram::new(10);
        values.iter().for_each(|&v| h.add(v as f64 * 2.0));
        h.finish();
        let figure = crate::render::peak_locking_index(&values, 2.0);
        assert!((h.peak_locking_index - figure).abs() < 1e-12);
    }
}
