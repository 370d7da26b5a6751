//! Vector validation, replacement and smoothing on one [`VectorField`].
//!
//! Following OpenPIV, the steps are separate: [`validate`] only flags (and blanks) vectors,
//! [`replace_invalid`] fills the blanks by iterative local-mean inpainting, and [`smooth`] is an
//! optional Gaussian filter. Every step leaves nodes without data NaN; none invents a zero.

use crate::field::{Status, VectorField};
use serde::{Deserialize, Serialize};

/// Parameters of [`validate`]; a config-file section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ValidationParams {
    /// Normalized median test threshold (Westerweel & Scarano 2005 recommend 2).
    pub median_threshold: f64,
    /// Noise level ε of the median test, px/ms. Westerweel & Scarano give 0.1 px of
    /// displacement; ebiv applies it to velocities (the reference EBIV code uses 0.05 px/ms).
    pub median_epsilon: f64,
    /// Minimum number of events in a window; 0 disables the test.
    pub min_events: u32,
    /// Minimum first-to-second peak ratio; 0 disables the test. A NaN ratio never fails.
    pub min_peak_ratio: f64,
    /// Largest accepted velocity magnitude, px/ms; `None` disables the test.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_velocity: Option<f64>,
}

impl Default for ValidationParams {
    fn default() -> Self {
        ValidationParams {
            median_threshold: 2.0,
            median_epsilon: 0.1,
            min_events: 0,
            min_peak_ratio: 0.0,
            max_velocity: None,
        }
    }
}

impl ValidationParams {
    /// Check that every parameter is finite and in range.
    pub fn check(&self) -> crate::Result<()> {
        let positive = |name: &str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(crate::Error::parameter(
                    name,
                    format!("must be a positive number, got {x}"),
                ))
            }
        };
        let non_negative = |name: &str, x: f64| {
            if x.is_finite() && x >= 0.0 {
                Ok(())
            } else {
                Err(crate::Error::parameter(
                    name,
                    format!("must be zero or positive, got {x}"),
                ))
            }
        };
        positive("median-threshold", self.median_threshold)?;
        non_negative("median-epsilon", self.median_epsilon)?;
        non_negative("min-peak-ratio", self.min_peak_ratio)?;
        if let Some(m) = self.max_velocity {
            positive("max-velocity", m)?;
        }
        Ok(())
    }
}

impl ValidationParams {
    /// The tests in words, for file metadata, with the limits in `unit` (the unit of the
    /// vectors they were applied to, e.g. `px/ms`): "normalised median test threshold 2,
    /// epsilon 0.1 px/ms; minimum events off; minimum peak ratio 1.2; largest magnitude off".
    pub fn describe(&self, unit: &str) -> String {
        let limit = |on: bool, value: String| if on { value } else { "off".to_string() };
        format!(
            "normalised median test threshold {}, epsilon {} {unit}; minimum events {}; \
             minimum peak ratio {}; largest magnitude {}",
            self.median_threshold,
            self.median_epsilon,
            limit(self.min_events > 0, self.min_events.to_string()),
            limit(self.min_peak_ratio > 0.0, self.min_peak_ratio.to_string()),
            self.max_velocity
                .map_or("off".to_string(), |m| format!("{m} {unit}")),
        )
    }
}

impl ValidationParams {
    /// The first per-vector test a vector fails, in [`validate`]'s order: event count
    /// ([`Status::FEW_EVENTS`]), peak ratio ([`Status::LOW_PEAK_RATIO`]; a NaN ratio never
    /// fails), magnitude ([`Status::OUT_OF_RANGE`]); `None` if it passes them all.
    pub fn vector_test(&self, event_count: u32, peak_ratio: f64, u: f64, v: f64) -> Option<Status> {
        let speed = u.hypot(v);
        if event_count < self.min_events {
            Some(Status::FEW_EVENTS)
        } else if peak_ratio < self.min_peak_ratio {
            Some(Status::LOW_PEAK_RATIO)
        } else if self
            .max_velocity
            .is_some_and(|m| speed.is_nan() || speed > m)
        {
            Some(Status::OUT_OF_RANGE)
        } else {
            None
        }
    }
}

/// What [`validate`] did: vectors flagged per test and valid vectors before and after.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ValidationSummary {
    /// Valid vectors (status 0) before validation.
    pub valid_before: usize,
    /// Valid vectors after validation.
    pub valid_after: usize,
    /// Flagged [`Status::FEW_EVENTS`].
    pub few_events: usize,
    /// Flagged [`Status::LOW_PEAK_RATIO`].
    pub low_peak_ratio: usize,
    /// Flagged [`Status::OUT_OF_RANGE`] by the magnitude limit.
    pub out_of_range: usize,
    /// Flagged [`Status::MEDIAN_TEST`] (and not re-evaluated on a secondary peak).
    pub median_test: usize,
    /// Median-test outliers that a lower peak near their neighbours' median made valid
    /// again (multiple-peak validation of `process`; counted in `valid_after`).
    pub secondary_peaks: usize,
}

impl ValidationSummary {
    /// Vectors flagged by this validation, all tests together.
    pub fn flagged(&self) -> usize {
        self.few_events + self.low_peak_ratio + self.out_of_range + self.median_test
    }
}

/// Flag outliers among the valid vectors of `field`; flagged vectors become NaN.
///
/// Tests, in order, each on the vectors still valid: event count ([`Status::FEW_EVENTS`]),
/// peak ratio ([`Status::LOW_PEAK_RATIO`]), velocity magnitude ([`Status::OUT_OF_RANGE`]) and
/// the normalized median test ([`Status::MEDIAN_TEST`]) of Westerweel & Scarano, "Universal
/// outlier detection for PIV data", Exp. Fluids 39:1096–1100 (2005). Vectors already invalid
/// (or replaced) are left alone.
///
/// The median test compares each component with the median `u_m` of the valid vectors in its
/// 3 × 3 neighbourhood (centre excluded): `r = |u_0 − u_m| / (r_m + ε)` with `r_m` the median
/// of `|u_i − u_m|`, and flags the vector if either component's `r` exceeds the threshold.
/// On the border the 3 × 3 block is shifted inwards so that it still holds 8 neighbours
/// (as the reference EBIV post-processing does); the truncated 5- or 3-point neighbourhood
/// would flag edge vectors of any flow with a gradient normal to the edge. A vector with fewer
/// than 3 valid neighbours is not median-tested, nor is a vector with a non-finite
/// component (which is no neighbour either). Neighbours flagged by the earlier tests of
/// this call are left out; all residuals are computed before the median test flags any
/// vector, so the result does not depend on the scan order. A corner vector is an
/// extrapolation from one side: where the flow changes by more than about 2ε per node along
/// both axes at once, a correct corner vector may be flagged.
pub fn validate(field: &mut VectorField, params: &ValidationParams) -> ValidationSummary {
    let mut summary = ValidationSummary {
        valid_before: count_valid(field),
        ..Default::default()
    };
    for i in 0..field.len() {
        if !field.status[i].is_valid() {
            continue;
        }
        let (u, v) = (field.u[i] as f64, field.v[i] as f64);
        let Some(reason) =
            params.vector_test(field.event_count[i], field.peak_ratio[i] as f64, u, v)
        else {
            continue;
        };
        match reason {
            Status::FEW_EVENTS => summary.few_events += 1,
            Status::LOW_PEAK_RATIO => summary.low_peak_ratio += 1,
            _ => summary.out_of_range += 1,
        }
        field.invalidate(i, reason);
    }
    let outliers = median_outliers(field, params.median_threshold, params.median_epsilon);
    summary.median_test = outliers.len();
    for i in outliers {
        field.invalidate(i, Status::MEDIAN_TEST);
    }
    summary.valid_after = count_valid(field);
    summary
}

fn count_valid(field: &VectorField) -> usize {
    field.status.iter().filter(|s| s.is_valid()).count()
}

/// Indices of the valid vectors failing the normalized median test, from an unchanged field.
fn median_outliers(field: &VectorField, threshold: f64, epsilon: f64) -> Vec<usize> {
    let mut outliers = Vec::new();
    for r in 0..field.height() {
        for c in 0..field.width() {
            let i0 = field.index(r, c);
            if !is_usable(field, i0) {
                continue;
            }
            let Some(reference) = neighbour_median(field, r, c) else {
                continue;
            };
            if !reference.passes(field.u[i0] as f64, field.v[i0] as f64, threshold, epsilon) {
                outliers.push(i0);
            }
        }
    }
    outliers
}

/// A valid vector with a finite value: one the median test may use as a neighbour.
fn is_usable(field: &VectorField, i: usize) -> bool {
    field.status[i].is_valid() && field.u[i].is_finite() && field.v[i].is_finite()
}

/// What the normalized median test compares a vector with: per component, the median `u_m`
/// of its valid neighbours and the median `r_m` of their residuals `|u_i − u_m|`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeighbourMedian {
    /// `[u_m, v_m]`, px/ms (or the field's unit).
    pub median: [f64; 2],
    /// `[r_m(u), r_m(v)]`.
    pub spread: [f64; 2],
}

impl NeighbourMedian {
    /// Largest normalized residual `|x − x_m| / (r_m + ε)` of the two components (NaN for a
    /// NaN component; 0 for a component equal to its median even where `r_m + ε` is 0).
    pub fn residual(&self, u: f64, v: f64, epsilon: f64) -> f64 {
        let r = |k: usize, x: f64| {
            let d = (x - self.median[k]).abs();
            if d == 0.0 {
                0.0
            } else {
                d / (self.spread[k] + epsilon)
            }
        };
        let (ru, rv) = (r(0, u), r(1, v));
        if ru.is_nan() || rv.is_nan() {
            f64::NAN
        } else {
            ru.max(rv)
        }
    }

    /// True if neither component's normalized residual exceeds `threshold`.
    pub fn passes(&self, u: f64, v: f64, threshold: f64, epsilon: f64) -> bool {
        self.residual(u, v, epsilon) <= threshold
    }
}

/// The median test's reference for node `(row, col)` from the valid vectors of its 3 × 3
/// block (shifted inside the grid on the border, centre excluded); `None` with fewer than 3.
pub fn neighbour_median(field: &VectorField, row: usize, col: usize) -> Option<NeighbourMedian> {
    let (h, w) = (field.height(), field.width());
    let i0 = field.index(row, col);
    let mut us = Vec::with_capacity(8);
    let mut vs = Vec::with_capacity(8);
    for rr in block(row, h) {
        for cc in block(col, w) {
            let i = field.index(rr, cc);
            if i != i0 && is_usable(field, i) {
                us.push(field.u[i] as f64);
                vs.push(field.v[i] as f64);
            }
        }
    }
    if us.len() < 3 {
        return None;
    }
    let (mu, ru) = median_and_spread(&mut us);
    let (mv, rv) = median_and_spread(&mut vs);
    Some(NeighbourMedian {
        median: [mu, mv],
        spread: [ru, rv],
    })
}

/// Rows (or columns) of the 3-node block around node `i` of `n`, shifted inside the grid.
fn block(i: usize, n: usize) -> std::ops::Range<usize> {
    if n <= 3 {
        return 0..n;
    }
    let start = i.saturating_sub(1).min(n - 3);
    start..start + 3
}

/// Median `m` of `xs` and median of `|x_i − m|` (Westerweel & Scarano's `r_m`); reorders `xs`.
fn median_and_spread(xs: &mut [f64]) -> (f64, f64) {
    let m = median(xs);
    for x in xs.iter_mut() {
        *x = (*x - m).abs();
    }
    (m, median(xs))
}

/// Median of a non-empty slice (mean of the two middle values for an even length).
fn median(xs: &mut [f64]) -> f64 {
    xs.sort_unstable_by(f64::total_cmp);
    let n = xs.len();
    if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// Parameters of [`replace_invalid`]; a config-file section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReplaceParams {
    /// Passes of local-mean inpainting; a hole's nodes further than this many nodes from any
    /// data stay NaN.
    pub max_iterations: u32,
}

impl Default for ReplaceParams {
    fn default() -> Self {
        ReplaceParams { max_iterations: 10 }
    }
}

/// Fill the vectors without a value (any invalid, non-masked node) by iterative local-mean
/// inpainting, as OpenPIV `replace_outliers` ('localmean'): each pass sets every empty node
/// that has at least one neighbour with a value in its 3 × 3 block to the mean of those
/// neighbours, using only values from the previous pass (so the result does not depend on the
/// scan order). Filled vectors keep their flag and gain [`Status::REPLACED`], with NaN
/// uncertainty: an interpolation is not a measurement. Nodes flagged
/// [`Status::MASKED`] are never filled nor used; nodes that no data reaches within
/// `max_iterations` passes stay NaN. Returns the number of vectors replaced.
pub fn replace_invalid(field: &mut VectorField, params: &ReplaceParams) -> usize {
    let (h, w) = (field.height(), field.width());
    let has_value = |f: &VectorField, i: usize| {
        f.status[i].has_value() && f.u[i].is_finite() && f.v[i].is_finite()
    };
    let mut replaced = 0;
    for _ in 0..params.max_iterations {
        let mut fills = Vec::new();
        for r in 0..h {
            for c in 0..w {
                let i0 = field.index(r, c);
                if has_value(field, i0) || field.status[i0].contains(Status::MASKED) {
                    continue;
                }
                let (mut su, mut sv, mut n) = (0.0f64, 0.0f64, 0u32);
                for rr in r.saturating_sub(1)..(r + 2).min(h) {
                    for cc in c.saturating_sub(1)..(c + 2).min(w) {
                        let i = field.index(rr, cc);
                        if i != i0 && has_value(field, i) {
                            su += field.u[i] as f64;
                            sv += field.v[i] as f64;
                            n += 1;
                        }
                    }
                }
                if n > 0 {
                    fills.push((i0, su / n as f64, sv / n as f64));
                }
            }
        }
        if fills.is_empty() {
            break;
        }
        replaced += fills.len();
        for (i, u, v) in fills {
            field.u[i] = u as f32;
            field.v[i] = v as f32;
            field.u_unc[i] = f32::NAN;
            field.v_unc[i] = f32::NAN;
            field.status[i] = field.status[i].with(Status::REPLACED);
        }
    }
    replaced
}

/// Gaussian smoothing of the vectors with a value by normalized convolution (Knutsson &
/// Westin 1993): `Σ g·w·u / Σ g·w` with `w` = 1 where a node carries a value, 0 elsewhere,
/// a separable Gaussian `g` of standard deviation `sigma_nodes` (grid nodes) truncated at
/// `ceil(2.5 σ)`. Nodes without a value stay NaN and contribute nothing; a constant field is
/// kept exactly everywhere, a linear one wherever the kernel lies fully inside the data.
/// Smoothed vectors get NaN uncertainty: their measurement's no longer describes them.
/// A non-positive or non-finite `sigma_nodes` leaves the field unchanged.
pub fn smooth(field: &mut VectorField, sigma_nodes: f64) {
    if !(sigma_nodes.is_finite() && sigma_nodes > 0.0) || field.is_empty() {
        return;
    }
    let (h, w) = (field.height(), field.width());
    let radius = (2.5 * sigma_nodes).ceil() as usize;
    let kernel: Vec<f64> = (0..=radius)
        .map(|k| (-0.5 * (k as f64 / sigma_nodes).powi(2)).exp())
        .collect();
    let carries =
        |i: usize| field.status[i].has_value() && field.u[i].is_finite() && field.v[i].is_finite();
    let has: Vec<bool> = (0..field.len()).map(carries).collect();
    let weight: Vec<f64> = has.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
    let masked = |x: &[f32]| -> Vec<f64> {
        x.iter()
            .zip(&has)
            .map(|(&x, &b)| if b { x as f64 } else { 0.0 })
            .collect()
    };
    let mut planes = [weight, masked(&field.u), masked(&field.v)];
    let mut tmp = vec![0.0f64; field.len()];
    for plane in planes.iter_mut() {
        // Along rows, then along columns.
        convolve_1d(plane, &mut tmp, &kernel, w, h, 1, w);
        convolve_1d(&tmp, plane, &kernel, h, w, w, 1);
    }
    let [weight, su, sv] = planes;
    for (i, _) in has.iter().enumerate().filter(|(_, &b)| b) {
        field.u[i] = (su[i] / weight[i]) as f32;
        field.v[i] = (sv[i] / weight[i]) as f32;
        field.u_unc[i] = f32::NAN;
        field.v_unc[i] = f32::NAN;
    }
}

/// Convolve `lines` lines of `len` samples (`stride` apart, lines `line_stride` apart) with a
/// symmetric kernel given by its non-negative half, truncated at the line ends.
fn convolve_1d(
    src: &[f64],
    dst: &mut [f64],
    half: &[f64],
    len: usize,
    lines: usize,
    stride: usize,
    line_stride: usize,
) {
    let radius = half.len() - 1;
    for l in 0..lines {
        let base = l * line_stride;
        for k in 0..len {
            let lo = k.saturating_sub(radius);
            let hi = (k + radius).min(len - 1);
            dst[base + k * stride] = (lo..=hi)
                .map(|j| half[k.abs_diff(j)] * src[base + j * stride])
                .sum();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_are_described_in_words_with_their_unit() {
        let mut p = ValidationParams::default();
        assert_eq!(
            p.describe("px/ms"),
            "normalised median test threshold 2, epsilon 0.1 px/ms; minimum events off; \
             minimum peak ratio off; largest magnitude off"
        );
        p.min_events = 5;
        p.min_peak_ratio = 1.2;
        p.max_velocity = Some(8.0);
        let text = p.describe("px");
        assert!(
            text.ends_with("minimum events 5; minimum peak ratio 1.2; largest magnitude 8 px"),
            "{text}"
        );
    }
    use crate::test_rng::xorshift;

    /// A field of `h` rows and `w` columns with velocities `f(row, col)`, all valid, with an
    /// uncertainty of 0.05 px/ms.
    fn field_from(
        h: usize,
        w: usize,
        mut f: impl FnMut(usize, usize) -> (f32, f32),
    ) -> VectorField {
        let x = (0..w).map(|c| 16.0 * c as f64).collect();
        let y = (0..h).map(|r| 16.0 * r as f64).collect();
        let mut field = VectorField::new(x, y);
        for r in 0..h {
            for c in 0..w {
                let i = field.index(r, c);
                (field.u[i], field.v[i]) = f(r, c);
                (field.u_unc[i], field.v_unc[i]) = (0.05, 0.05);
                field.status[i] = Status::VALID;
                field.event_count[i] = 100;
                field.peak_ratio[i] = 3.0;
            }
        }
        field
    }

    fn transpose(f: &VectorField) -> VectorField {
        let mut t = VectorField::new(f.y.clone(), f.x.clone());
        for r in 0..f.height() {
            for c in 0..f.width() {
                let (i, j) = (f.index(r, c), t.index(c, r));
                t.u[j] = f.v[i];
                t.v[j] = f.u[i];
                t.status[j] = f.status[i];
                t.peak_ratio[j] = f.peak_ratio[i];
                t.event_count[j] = f.event_count[i];
            }
        }
        t
    }

    /// Smooth swirl plus a shear normal to the top and bottom edges (0.25 px/ms per node).
    fn smooth_flow(r: usize, c: usize) -> (f32, f32) {
        let (r, c) = (r as f32, c as f32);
        (
            3.0 + 0.4 * (0.25 * c + 0.1 * r).sin(),
            0.25 * r - 0.3 * (0.2 * c).cos(),
        )
    }

    const OUTLIERS: [(usize, usize); 7] = [
        (5, 7),   // interior
        (5, 8),   // its neighbour: a pair
        (0, 6),   // top edge
        (9, 13),  // right edge
        (0, 0),   // corner
        (13, 16), // opposite corner
        (13, 3),  // bottom edge
    ];

    fn with_outliers() -> VectorField {
        let mut f = field_from(14, 17, smooth_flow);
        for (k, &(r, c)) in OUTLIERS.iter().enumerate() {
            let i = f.index(r, c);
            if k % 2 == 0 {
                f.u[i] += 2.0;
            } else {
                f.v[i] -= 1.5;
            }
        }
        f
    }

    #[test]
    fn median_test_flags_outliers_only() {
        let mut f = with_outliers();
        let s = validate(&mut f, &ValidationParams::default());
        for r in 0..f.height() {
            for c in 0..f.width() {
                let i = f.index(r, c);
                let expected = OUTLIERS.contains(&(r, c));
                assert_eq!(
                    f.status[i] == Status::MEDIAN_TEST,
                    expected,
                    "({r}, {c}) status {:?}",
                    f.status[i]
                );
                assert_eq!(f.u[i].is_nan(), expected);
            }
        }
        assert_eq!(s.median_test, OUTLIERS.len());
        assert_eq!(s.flagged(), OUTLIERS.len());
        assert_eq!(s.valid_before, 14 * 17);
        assert_eq!(s.valid_after, 14 * 17 - OUTLIERS.len());
    }

    #[test]
    fn median_test_does_not_depend_on_scan_order() {
        let mut f = with_outliers();
        // A borderline cluster: flagging while scanning (row by row or column by column)
        // would change the neighbourhoods of the vectors tested later.
        for (r, c, du) in [
            (9, 9, 0.3),
            (9, 10, 0.5),
            (10, 9, 0.5),
            (8, 4, 0.15),
            (8, 5, 0.3),
            (9, 4, 0.3),
        ] {
            let i = f.index(r, c);
            f.u[i] += du;
        }
        let mut t = transpose(&f);
        validate(&mut f, &ValidationParams::default());
        validate(&mut t, &ValidationParams::default());
        assert_eq!(transpose(&t).status, f.status);
        assert!(f.status.contains(&Status::MEDIAN_TEST));
    }

    #[test]
    fn epsilon_keeps_a_noisy_uniform_field_valid() {
        let mut rng = xorshift(0x2545_f491_4f6c_dd1d);
        let mut noise = || (rng() >> 40) as f32 / (1u64 << 24) as f32 * 2e-3 - 1e-3;
        let f = field_from(12, 12, |_, _| (1.5 + noise(), -0.5 + noise()));
        let mut g = f.clone();
        let s = validate(&mut g, &ValidationParams::default());
        assert_eq!(s.median_test, 0);
        let mut g = f.clone();
        let no_eps = ValidationParams {
            median_epsilon: 0.0,
            ..Default::default()
        };
        assert!(validate(&mut g, &no_eps).median_test > 0, "noise alone");
    }

    #[test]
    fn event_count_peak_ratio_and_magnitude_flags() {
        let mut f = field_from(4, 4, |_, _| (1.0, 1.0));
        f.event_count[0] = 5;
        f.peak_ratio[1] = 1.1;
        f.peak_ratio[2] = f32::NAN;
        f.u[3] = 9.0;
        f.invalidate(4, Status::NO_EVENTS);
        f.event_count[4] = 0;
        let p = ValidationParams {
            min_events: 10,
            min_peak_ratio: 1.5,
            max_velocity: Some(5.0),
            ..Default::default()
        };
        let s = validate(&mut f, &p);
        assert_eq!(f.status[0], Status::FEW_EVENTS);
        assert_eq!(f.status[1], Status::LOW_PEAK_RATIO);
        assert_eq!(f.status[2], Status::VALID);
        assert_eq!(f.status[3], Status::OUT_OF_RANGE);
        assert_eq!(f.status[4], Status::NO_EVENTS);
        assert!(f.u[0].is_nan() && f.v[1].is_nan() && f.u[3].is_nan());
        assert_eq!((s.few_events, s.low_peak_ratio, s.out_of_range), (1, 1, 1));
        assert_eq!((s.median_test, s.valid_before, s.valid_after), (0, 15, 12));
    }

    #[test]
    fn params_parse_and_check() {
        let p: ValidationParams = serde_json::from_str(r#"{"min_events": 20}"#).unwrap();
        assert_eq!(p.min_events, 20);
        assert_eq!(p.median_threshold, 2.0);
        assert!(p.check().is_ok());
        assert!(serde_json::from_str::<ValidationParams>(r#"{"threshold": 2}"#).is_err());
        let bad = ValidationParams {
            median_threshold: f64::NAN,
            ..Default::default()
        };
        assert!(bad.check().is_err());
    }

    fn linear(r: usize, c: usize) -> (f32, f32) {
        let (r, c) = (r as f32, c as f32);
        (1.0 + 0.5 * c + 0.2 * r, -0.3 * c + 0.1 * r)
    }

    #[test]
    fn replacement_restores_a_linear_field_at_isolated_holes() {
        let mut f = field_from(8, 9, linear);
        let holes = [(2, 2), (4, 6), (6, 3)];
        for &(r, c) in &holes {
            let i = f.index(r, c);
            f.invalidate(i, Status::MEDIAN_TEST);
        }
        let masked = f.index(1, 6);
        f.invalidate(masked, Status::MASKED);
        assert_eq!(
            replace_invalid(&mut f, &ReplaceParams::default()),
            holes.len()
        );
        for &(r, c) in &holes {
            let i = f.index(r, c);
            let (u, v) = linear(r, c);
            assert!((f.u[i] - u).abs() < 1e-5 && (f.v[i] - v).abs() < 1e-5);
            assert_eq!(f.status[i], Status::MEDIAN_TEST | Status::REPLACED);
            assert!(f.status[i].has_value());
            // An interpolation, not a measurement: no uncertainty.
            assert!(f.u_unc[i].is_nan() && f.v_unc[i].is_nan());
        }
        let kept = f.index(2, 3);
        assert_eq!((f.u_unc[kept], f.v_unc[kept]), (0.05, 0.05));
        assert!(f.u[masked].is_nan() && f.v[masked].is_nan());
        assert_eq!(f.status[masked], Status::MASKED);
    }

    #[test]
    fn replacement_fills_large_holes_in_passes_and_leaves_empty_fields() {
        let hole = |f: &mut VectorField| {
            for r in 1..6 {
                for c in 1..6 {
                    let i = f.index(r, c);
                    f.invalidate(i, Status::NO_EVENTS);
                }
            }
        };
        let mut f = field_from(7, 7, |_, _| (2.0, -1.0));
        hole(&mut f);
        let once = ReplaceParams { max_iterations: 1 };
        assert_eq!(replace_invalid(&mut f, &once), 16);
        assert!(f.u[f.index(3, 3)].is_nan());
        let mut f = field_from(7, 7, |_, _| (2.0, -1.0));
        hole(&mut f);
        assert_eq!(replace_invalid(&mut f, &ReplaceParams::default()), 25);
        assert!(f.u.iter().all(|&u| u == 2.0) && f.v.iter().all(|&v| v == -1.0));

        let mut empty = VectorField::new(vec![0.0, 1.0, 2.0], vec![0.0, 1.0]);
        assert_eq!(replace_invalid(&mut empty, &ReplaceParams::default()), 0);
        assert!(empty.u.iter().all(|u| u.is_nan()));
        assert!(empty.status.iter().all(|&s| s == Status::NO_EVENTS));
    }

    #[test]
    fn smoothing_keeps_constant_and_linear_fields() {
        let mut f = field_from(9, 11, |_, _| (1.25, -0.75));
        f.invalidate(f.index(4, 5), Status::MEDIAN_TEST);
        f.invalidate(f.index(0, 0), Status::NO_EVENTS);
        smooth(&mut f, 1.0);
        for i in 0..f.len() {
            if i == f.index(4, 5) || i == 0 {
                assert!(f.u[i].is_nan() && f.v[i].is_nan());
            } else {
                assert!((f.u[i] - 1.25).abs() < 1e-6 && (f.v[i] + 0.75).abs() < 1e-6);
            }
        }

        let mut f = field_from(12, 13, linear);
        let sigma = 1.0;
        smooth(&mut f, sigma);
        let radius = 3;
        for r in radius..12 - radius {
            for c in radius..13 - radius {
                let i = f.index(r, c);
                let (u, v) = linear(r, c);
                assert!((f.u[i] - u).abs() < 1e-5 && (f.v[i] - v).abs() < 1e-5);
            }
        }
        // Near the border the truncated kernel biases a gradient but keeps the values finite.
        assert!(f.u.iter().all(|u| u.is_finite()));
    }

    #[test]
    fn smoothing_reduces_noise() {
        let mut f = field_from(10, 10, |r, c| {
            let s = if (r + c) % 2 == 0 { 0.1 } else { -0.1 };
            (1.0 + s, s)
        });
        smooth(&mut f, 1.5);
        let i = f.index(5, 5);
        assert!((f.u[i] - 1.0).abs() < 0.02 && f.v[i].abs() < 0.02);
    }
}
