//! Errors grouped by where and under which conditions they occur: per grid node (error maps)
//! and in bins of a quantity such as the true speed or the events per window.

use serde::Serialize;

/// Error statistics of the vectors whose quantity falls in `[lo, hi]`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorBin {
    /// Lower edge of the bin.
    pub lo: f64,
    /// Upper edge of the bin.
    pub hi: f64,
    /// Vectors in the bin.
    pub count: usize,
    /// Mean end-point error.
    pub aee: f64,
    /// Root mean square end-point error.
    pub rms: f64,
    /// Mean error per component (u, v).
    pub bias: [f64; 2],
}

/// One error sample: the quantity it is binned by and the error (e_u, e_v).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sample {
    pub key: f64,
    pub error: [f64; 2],
}

fn bin_of(lo: f64, hi: f64, samples: &[Sample]) -> ErrorBin {
    let n = samples.len();
    let (mut sum, mut sq, mut bias) = (0.0, 0.0, [0.0; 2]);
    for s in samples {
        let e = s.error[0].hypot(s.error[1]);
        sum += e;
        sq += e * e;
        bias[0] += s.error[0];
        bias[1] += s.error[1];
    }
    let mean = |x: f64| if n == 0 { f64::NAN } else { x / n as f64 };
    ErrorBin {
        lo,
        hi,
        count: n,
        aee: mean(sum),
        rms: mean(sq).sqrt(),
        bias: [mean(bias[0]), mean(bias[1])],
    }
}

/// `bins` bins of equal width from 0 to the largest key (true speeds); empty bins are kept,
/// with NaN statistics, so that the bins of two assessments line up.
pub(crate) fn equal_width(samples: &[Sample], bins: usize) -> Vec<ErrorBin> {
    let max = samples.iter().map(|s| s.key).fold(0.0f64, f64::max);
    if samples.is_empty() || bins == 0 {
        return Vec::new();
    }
    let width = if max > 0.0 { max / bins as f64 } else { 1.0 };
    let mut groups: Vec<Vec<Sample>> = vec![Vec::new(); bins];
    for s in samples {
        let b = ((s.key / width) as usize).min(bins - 1);
        groups[b].push(*s);
    }
    groups
        .iter()
        .enumerate()
        .map(|(b, g)| bin_of(b as f64 * width, (b + 1) as f64 * width, g))
        .collect()
}

/// Up to `bins` bins holding equal numbers of samples, sorted by key (events per window, whose
/// distribution is skewed); samples of equal keys stay in one bin.
pub(crate) fn equal_count(samples: &[Sample], bins: usize) -> Vec<ErrorBin> {
    if samples.is_empty() || bins == 0 {
        return Vec::new();
    }
    let mut sorted = samples.to_vec();
    sorted.sort_by(|a, b| a.key.total_cmp(&b.key));
    let n = sorted.len();
    let mut out = Vec::new();
    let mut start = 0;
    for b in 1..=bins {
        let mut end = (n * b / bins).max(start);
        // Keep equal keys together.
        while end < n && end > 0 && sorted[end].key == sorted[end - 1].key {
            end += 1;
        }
        if end > start {
            let g = &sorted[start..end];
            out.push(bin_of(g[0].key, g[g.len() - 1].key, g));
            start = end;
        }
    }
    out
}

/// The mean end-point error per grid node over the fields of a series.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorMap {
    /// Grid column positions, px.
    pub x: Vec<f64>,
    /// Grid row positions, px.
    pub y: Vec<f64>,
    /// Mean end-point error per node, indexed `[row][column]`; NaN where no valid vector was
    /// compared.
    pub mean_error: Vec<f64>,
    /// Valid vectors compared per node.
    pub count: Vec<usize>,
}

impl ErrorMap {
    /// An empty map on a grid.
    pub(crate) fn new(x: Vec<f64>, y: Vec<f64>) -> Self {
        let n = x.len() * y.len();
        ErrorMap {
            x,
            y,
            mean_error: vec![0.0; n],
            count: vec![0; n],
        }
    }

    /// Add the end-point error `e` of node `node`.
    pub(crate) fn add(&mut self, node: usize, e: f64) {
        self.mean_error[node] += e;
        self.count[node] += 1;
    }

    /// Turn the sums into means (NaN where empty).
    pub(crate) fn finish(&mut self) {
        for (m, &c) in self.mean_error.iter_mut().zip(&self.count) {
            *m = if c == 0 { f64::NAN } else { *m / c as f64 };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(key: f64, e: f64) -> Sample {
        Sample {
            key,
            error: [e, 0.0],
        }
    }

    #[test]
    fn equal_width_bins_from_zero_to_the_largest_key() {
        let bins = equal_width(&[s(0.0, 1.0), s(1.0, 3.0), s(4.0, -2.0)], 2);
        assert_eq!(bins.len(), 2);
        assert_eq!((bins[0].lo, bins[0].hi, bins[0].count), (0.0, 2.0, 2));
        assert_eq!((bins[0].aee, bins[0].bias[0]), (2.0, 2.0));
        assert!((bins[0].rms - 5f64.sqrt()).abs() < 1e-12);
        assert_eq!(
            (bins[1].count, bins[1].aee, bins[1].bias[0]),
            (1, 2.0, -2.0)
        );
    }

    #[test]
    fn equal_count_bins_keep_equal_keys_together() {
        let samples: Vec<Sample> = [5.0, 1.0, 2.0, 2.0, 3.0, 9.0]
            .iter()
            .map(|&k| s(k, k))
            .collect();
        let bins = equal_count(&samples, 3);
        let counts: Vec<usize> = bins.iter().map(|b| b.count).collect();
        assert_eq!(counts.iter().sum::<usize>(), 6);
        assert_eq!((bins[0].lo, bins[0].hi), (1.0, 2.0));
        assert_eq!(counts[0], 3, "both 2s in the first bin");
        assert_eq!(bins.last().unwrap().hi, 9.0);
    }
}
