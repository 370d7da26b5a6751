//! [`assess`]: every error metric of a field series against the truth, in one pass.

use super::binned::{equal_count, equal_width, ErrorBin, ErrorMap, Sample};
use super::coverage::Coverage;
use super::fractional::FractionalHistogram;
use super::options::AssessOptions;
use crate::field::{FieldSeries, Quantity};
use serde::Serialize;

/// The errors of a field series against the truth (see [`assess`] and `docs/assess.md`).
///
/// Errors are e = measured − true per component, in the series' unit ([`Assessment::unit`]):
/// px/ms for velocities, px for displacements. Statistics are over the *compared* vectors:
/// valid (status 0, finite) with a finite truth at their position and time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Assessment {
    /// Unit of the errors: `px/ms` or `px`.
    pub unit: String,
    /// Vectors in the series.
    pub total: usize,
    /// Valid vectors (status 0, both components finite).
    pub valid: usize,
    /// Valid vectors compared with a finite truth.
    pub compared: usize,
    /// Valid vectors where the truth is not known (NaN), left out.
    pub without_truth: usize,
    /// valid / total.
    pub valid_share: f64,
    /// Mean error (u, v): the bias.
    pub bias: [f64; 2],
    /// Standard deviation of the error (u, v): the random error.
    pub random: [f64; 2],
    /// Root mean square end-point error √⟨e_u² + e_v²⟩.
    pub rms: f64,
    /// Mean end-point error ⟨√(e_u² + e_v²)⟩ (AEE).
    pub aee: f64,
    /// Median end-point error.
    pub median: f64,
    /// Largest end-point error.
    pub max: f64,
    /// Compared vectors whose end-point error exceeds their outlier threshold
    /// ([`AssessOptions::outlier_threshold`]).
    pub outliers: usize,
    /// outliers / compared.
    pub outlier_share: f64,
    /// RMS end-point error of the compared vectors that are not outliers.
    pub rms_without_outliers: f64,
    /// Smallest and largest outlier threshold used, in the series' unit.
    pub outlier_threshold: [f64; 2],
    /// Largest true speed among the compared vectors.
    pub max_true_speed: f64,
    /// Dynamic velocity range: largest true speed over the RMS end-point error
    /// (Adrian 1997, Meas. Sci. Technol. 8:1393).
    pub dvr: f64,
    /// Mean end-point error per grid node over time.
    pub error_map: ErrorMap,
    /// Errors in bins of the true speed (equal widths from 0).
    pub by_speed: Vec<ErrorBin>,
    /// Errors in bins of the events per window (equal numbers of vectors); empty when the
    /// series carries no event counts.
    pub by_events: Vec<ErrorBin>,
    /// Coverage of the per-vector standard uncertainties.
    pub coverage: Coverage,
    /// Fractional-displacement histogram and peak-locking index.
    pub fractional: FractionalHistogram,
    /// The settings used.
    pub options: AssessOptions,
}

/// Measure the valid vectors of `series` against `truth(x_px, y_px, t_us) → (u, v)` (image
/// coordinates; px/ms, or px for a displacement series) at each vector's position and time.
///
/// A truth that returns NaN (unknown there) leaves the vector out and counts it in
/// [`Assessment::without_truth`]. Never fails: an empty or all-invalid series gives counts of
/// zero and NaN statistics. `options` is used as given; check it with
/// [`AssessOptions::validate`].
pub fn assess(
    series: &FieldSeries,
    truth: &dyn Fn(f64, f64, f64) -> (f64, f64),
    options: &AssessOptions,
) -> Assessment {
    let displacement = series.quantity == Quantity::Displacement;
    let (nx, ny) = (series.x.len(), series.y.len());
    let mut map = ErrorMap::new(series.x.clone(), series.y.clone());
    let mut errors: Vec<[f64; 2]> = Vec::new();
    let mut epe: Vec<f64> = Vec::new();
    let mut speed_samples = Vec::new();
    let mut event_samples = Vec::new();
    let mut comp_errors = Vec::new();
    let mut comp_sigmas = Vec::new();
    let mut fractional = FractionalHistogram::new(options.fraction_bins);
    let (mut valid, mut without_truth, mut outliers) = (0usize, 0usize, 0usize);
    let mut inlier_sq = 0.0;
    let mut thresholds = [f64::INFINITY, f64::NEG_INFINITY];
    let mut max_true_speed = 0.0f64;
    let mut any_events = false;
    let total = series.u.len();
    for (ti, &t) in series.t_us.iter().enumerate() {
        for row in 0..ny {
            for col in 0..nx {
                let i = series.index(ti, row, col);
                if i >= total {
                    continue;
                }
                let (u, v) = (series.u[i] as f64, series.v[i] as f64);
                if !series.status[i].is_valid() || !u.is_finite() || !v.is_finite() {
                    continue;
                }
                valid += 1;
                let (ut, vt) = truth(series.x[col], series.y[row], t as f64);
                if !(ut.is_finite() && vt.is_finite()) {
                    without_truth += 1;
                    continue;
                }
                let e = [u - ut, v - vt];
                let norm = e[0].hypot(e[1]);
                let speed = ut.hypot(vt);
                max_true_speed = max_true_speed.max(speed);
                errors.push(e);
                epe.push(norm);
                map.add(row * nx + col, norm);
                let slab = series.slab_us.get(i).copied().unwrap_or(0);
                let threshold = options.outlier_threshold(slab, displacement);
                thresholds = [thresholds[0].min(threshold), thresholds[1].max(threshold)];
                if norm > threshold {
                    outliers += 1;
                } else {
                    inlier_sq += norm * norm;
                }
                speed_samples.push(Sample {
                    key: speed,
                    error: e,
                });
                let events = series.event_count.get(i).copied().unwrap_or(0);
                any_events |= events > 0;
                event_samples.push(Sample {
                    key: events as f64,
                    error: e,
                });
                let sigma = super::uncertainty(series, i);
                comp_errors.extend_from_slice(&e);
                comp_sigmas.extend_from_slice(&sigma);
                let scale = if displacement {
                    Some(1.0)
                } else if slab > 0 {
                    Some(slab as f64 / 1000.0)
                } else {
                    None
                };
                match scale {
                    Some(s) => {
                        fractional.add(u * s);
                        fractional.add(v * s);
                    }
                    None => fractional.without_slab += 1,
                }
            }
        }
    }
    map.finish();
    fractional.finish();
    let n = errors.len();
    let nan_if_empty = |x: f64| if n == 0 { f64::NAN } else { x };
    let mean = |k: usize| nan_if_empty(errors.iter().map(|e| e[k]).sum::<f64>() / n as f64);
    let bias = [mean(0), mean(1)];
    let sd = |k: usize| {
        nan_if_empty(
            (errors.iter().map(|e| (e[k] - bias[k]).powi(2)).sum::<f64>() / n as f64).sqrt(),
        )
    };
    let rms = nan_if_empty((epe.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt());
    let inliers = n - outliers;
    Assessment {
        unit: series.quantity.units().0.to_string(),
        total,
        valid,
        compared: n,
        without_truth,
        valid_share: if total == 0 {
            f64::NAN
        } else {
            valid as f64 / total as f64
        },
        bias,
        random: [sd(0), sd(1)],
        rms,
        aee: nan_if_empty(epe.iter().sum::<f64>() / n as f64),
        median: median(&mut epe.clone()),
        max: nan_if_empty(epe.iter().copied().fold(0.0, f64::max)),
        outliers,
        outlier_share: nan_if_empty(outliers as f64 / n as f64),
        rms_without_outliers: if inliers == 0 {
            f64::NAN
        } else {
            (inlier_sq / inliers as f64).sqrt()
        },
        outlier_threshold: if n == 0 { [f64::NAN; 2] } else { thresholds },
        max_true_speed: nan_if_empty(max_true_speed),
        dvr: nan_if_empty(max_true_speed / rms),
        error_map: map,
        by_speed: equal_width(&speed_samples, options.speed_bins),
        by_events: if any_events {
            equal_count(&event_samples, options.event_bins)
        } else {
            Vec::new()
        },
        coverage: Coverage::of(&comp_errors, &comp_sigmas),
        fractional,
        options: options.clone(),
    }
}

/// Median of `values` (sorted in place); NaN when empty.
pub(crate) fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}
