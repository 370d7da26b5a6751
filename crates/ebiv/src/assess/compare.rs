//! [`compare`]: agreement of two field series, e.g. two methods on one recording or ebiv
//! against another tool, with the statistics of the EBIV paper's wall-flow comparison
//! (Willert & Klinner 2022: median |Δv| and the share of vectors differing by more than
//! 1 px/ms).
//!
//! Fields are matched in time: by index when both series hold the same number of fields and
//! either has no camera times (image pairs) or both hold one field; otherwise each field of
//! `a` with the field of `b` nearest in time within the tolerance. Vectors are matched in
//! space: on one grid node by node, else `b` is interpolated bilinearly to `a`'s nodes
//! ([`VectorField::sample`]) from its valid vectors, and nodes of `a` outside `b`'s grid are
//! left out.

use super::metrics::median;
use super::options::CompareOptions;
use crate::error::{Error, Result};
use crate::field::{FieldSeries, Status, VectorField};
use serde::Serialize;

/// Two matched fields: indices into the two series.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct MatchedPair {
    /// Field index in `a`.
    pub a: usize,
    /// Field index in `b`.
    pub b: usize,
}

/// Agreement statistics of two field series.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Agreement {
    /// Unit of the values and differences (`px/ms` or `px`).
    pub unit: String,
    /// Fields matched in time.
    pub pairs: Vec<MatchedPair>,
    /// Fields of `a` without a field of `b` within the time tolerance.
    pub unmatched_fields: usize,
    /// Valid vectors of `a` in the matched fields.
    pub a_valid: usize,
    /// Vector pairs compared: valid in `a`, with a valid (or interpolated) value of `b`.
    pub compared: usize,
    /// Valid vectors of `a` outside `b`'s grid or without a valid value of `b` there.
    pub without_b: usize,
    /// Whether `b` was interpolated to `a`'s nodes (the grids differ).
    pub interpolated: bool,
    /// Median end-point difference |Δv| = |v_a − v_b|.
    pub median_difference: f64,
    /// Mean end-point difference.
    pub mean_difference: f64,
    /// Root mean square end-point difference.
    pub rms_difference: f64,
    /// Mean difference a − b per component (u, v).
    pub mean_component_difference: [f64; 2],
    /// Standard deviation of the difference per component.
    pub sd_component_difference: [f64; 2],
    /// Share of compared pairs whose |Δv| exceeds `threshold`.
    pub beyond_share: f64,
    /// The threshold used.
    pub threshold: f64,
    /// Up to [`CompareOptions::max_scatter`] pairs `[u_a, v_a, u_b, v_b]`, evenly thinned,
    /// for scatter plots.
    pub scatter: Vec<[f32; 4]>,
    /// Every |Δv| of the compared pairs, for histograms.
    pub differences: Vec<f32>,
}

/// Compare `a` with `b` (see the module documentation): both must hold the same quantity
/// (velocities or displacements) in image units.
pub fn compare(a: &FieldSeries, b: &FieldSeries, options: &CompareOptions) -> Result<Agreement> {
    if a.quantity != b.quantity {
        return Err(Error::parameter(
            "fields",
            format!(
                "the first holds {}, the second {}: compare like with like (give the time \
                 between frames to turn displacements into velocities)",
                a.quantity.noun(),
                b.quantity.noun()
            ),
        ));
    }
    if !(options.threshold.is_finite() && options.threshold > 0.0) {
        return Err(Error::parameter(
            "threshold",
            format!("must be a positive number, got {}", options.threshold),
        ));
    }
    let pairs = match_times(a, b, options.time_tolerance_us);
    let same_grid = a.x == b.x && a.y == b.y;
    let mut diffs: Vec<[f64; 2]> = Vec::new();
    let mut scatter_all: Vec<[f32; 4]> = Vec::new();
    let (mut a_valid, mut without_b) = (0usize, 0usize);
    let inside = |p: f64, axis: &[f64]| match (axis.first(), axis.last()) {
        (Some(&lo), Some(&hi)) => p >= lo - 1e-9 && p <= hi + 1e-9,
        _ => false,
    };
    for pair in &pairs {
        let fb = valid_only(b.field(pair.b));
        for (row, &y) in a.y.iter().enumerate() {
            for (col, &x) in a.x.iter().enumerate() {
                let i = a.index(pair.a, row, col);
                let (ua, va) = (a.u[i], a.v[i]);
                if !a.status[i].is_valid() || !ua.is_finite() || !va.is_finite() {
                    continue;
                }
                a_valid += 1;
                let vb = if same_grid {
                    let j = fb.index(row, col);
                    (fb.status[j].is_valid() && fb.u[j].is_finite() && fb.v[j].is_finite())
                        .then(|| [fb.u[j] as f64, fb.v[j] as f64])
                } else if inside(x, &b.x) && inside(y, &b.y) {
                    fb.sample(x, y)
                } else {
                    None
                };
                let Some([ub, vb]) = vb else {
                    without_b += 1;
                    continue;
                };
                diffs.push([ua as f64 - ub, va as f64 - vb]);
                scatter_all.push([ua, va, ub as f32, vb as f32]);
            }
        }
    }
    let n = diffs.len();
    let nan_if_empty = |x: f64| if n == 0 { f64::NAN } else { x };
    let norms: Vec<f64> = diffs.iter().map(|d| d[0].hypot(d[1])).collect();
    let mean = |k: usize| nan_if_empty(diffs.iter().map(|d| d[k]).sum::<f64>() / n as f64);
    let m = [mean(0), mean(1)];
    let sd = |k: usize| {
        nan_if_empty((diffs.iter().map(|d| (d[k] - m[k]).powi(2)).sum::<f64>() / n as f64).sqrt())
    };
    let stride = n.div_ceil(options.max_scatter.max(1)).max(1);
    Ok(Agreement {
        unit: a.quantity.units().0.to_string(),
        unmatched_fields: a.t_us.len() - pairs.len(),
        pairs,
        a_valid,
        compared: n,
        without_b,
        interpolated: !same_grid,
        median_difference: median(&mut norms.clone()),
        mean_difference: nan_if_empty(norms.iter().sum::<f64>() / n as f64),
        rms_difference: nan_if_empty((norms.iter().map(|d| d * d).sum::<f64>() / n as f64).sqrt()),
        mean_component_difference: m,
        sd_component_difference: [sd(0), sd(1)],
        beyond_share: nan_if_empty(
            norms.iter().filter(|&&d| d > options.threshold).count() as f64 / n as f64,
        ),
        threshold: options.threshold,
        scatter: scatter_all.into_iter().step_by(stride).collect(),
        differences: norms.iter().map(|&d| d as f32).collect(),
    })
}

/// `field` with replaced vectors made invalid, so that interpolation uses measurements only.
fn valid_only(mut field: VectorField) -> VectorField {
    for i in 0..field.len() {
        if !field.status[i].is_valid() {
            field.invalidate(i, Status::VALID);
        }
    }
    field
}

/// The fields of `b` matched to those of `a` (see the module documentation).
fn match_times(a: &FieldSeries, b: &FieldSeries, tolerance_us: Option<i64>) -> Vec<MatchedPair> {
    let (na, nb) = (a.t_us.len(), b.t_us.len());
    let no_times = !a.time_basis.is_camera_time() || !b.time_basis.is_camera_time();
    if na == nb && (no_times || na == 1) {
        return (0..na).map(|i| MatchedPair { a: i, b: i }).collect();
    }
    if nb == 0 {
        return Vec::new();
    }
    let tolerance = tolerance_us.unwrap_or_else(|| {
        let mut sorted = a.t_us.clone();
        sorted.sort_unstable();
        sorted
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|&d| d > 0)
            .min()
            .map_or(i64::MAX, |d| d / 2)
    });
    (0..na)
        .filter_map(|ia| {
            let t = a.t_us[ia];
            let (ib, dt) = b
                .t_us
                .iter()
                .enumerate()
                .map(|(ib, &tb)| (ib, (tb - t).unsigned_abs()))
                .min_by_key(|&(_, d)| d)?;
            (dt <= tolerance.unsigned_abs()).then_some(MatchedPair { a: ia, b: ib })
        })
        .collect()
}
