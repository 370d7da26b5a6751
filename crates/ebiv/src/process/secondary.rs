//! Multiple-peak validation: a window whose highest peak fails the normalized median test is
//! re-evaluated on the highest peak within the test's tolerance of its neighbours' median.
//!
//! A correlation plane (or contrast objective) of a sparse window can hold two particle
//! patterns of nearly equal weight; the highest one is then wrong about as often as right.
//! PIV software keeps the next peaks for this reason and accepts the first one that passes
//! validation (the "2nd, 3rd, 4th choice" vectors of LaVision DaVis; multiple-peak
//! validation, Raffel et al., "Particle Image Velocimetry", 3rd ed., 2018, ch. 7). Here
//! the lower peak is found by the estimator itself, searching only within the median test's
//! tolerance around the neighbours' median velocity, and accepted only if
//! - it is a genuine maximum inside that range (not on its border),
//! - it is at least [`MIN_RELATIVE_HEIGHT`] of the window's highest peak (a second particle
//!   pattern, not a noise ripple), and
//! - it passes the same median test.
//!
//! Only the last pass of a multi-pass run is re-evaluated: there the neighbours come from
//! windows that were themselves evaluated around a validated predictor. In a single pass
//! through a vortex core (strong gradients, few particles) the neighbours' median is no
//! trustworthy reference: on the simulated Lamb–Oseen vortex, re-evaluation there accepted
//! wrong peaks (RMS 0.45 → 0.53 px/ms by sum of correlation, 0.28 → 0.30 by motion
//! compensation), while after 64 → 32 px passes it changed nothing measurable.
//!
//! An accepted vector is a measurement, so it is valid (status 0); its `peak_ratio` is its
//! height over the highest peak, below 1, which marks it in every output.

use super::{predictor, ProcessParams};
use crate::estimate::{Estimator, Prediction};
use crate::field::{Status, VectorField};
use crate::grid::Grid;
use crate::validate::neighbour_median;
use crate::volume::Slab;

/// Smallest height of an accepted secondary peak relative to the window's highest peak: a
/// first-to-second peak ratio of at most 2, two patterns of comparable weight. Lower peaks
/// are too weak to be trusted against the highest one.
pub const MIN_RELATIVE_HEIGHT: f64 = 0.5;

/// Re-evaluate the vectors of `field` flagged by the median test alone (and nothing else),
/// each with the deformation of the pass's `predictor` field, centred on its neighbours'
/// median; returns how many were accepted and became valid.
pub(super) fn reevaluate_outliers<E: Estimator>(
    estimator: &E,
    slab: &Slab,
    t0_us: i64,
    grid: &Grid,
    params: &ProcessParams,
    predictor: &VectorField,
    field: &mut VectorField,
) -> usize {
    let threshold = params.validation.median_threshold;
    let epsilon = params.validation.median_epsilon;
    let mut scratch = None;
    let mut accepted = Vec::new();
    for row in 0..field.height() {
        for col in 0..field.width() {
            let i = field.index(row, col);
            let has_peak = field.peak[i].is_finite() && field.peak[i] > 0.0;
            if field.status[i] != Status::MEDIAN_TEST || !has_peak {
                continue;
            }
            let Some(reference) = neighbour_median(field, row, col) else {
                continue;
            };
            let window = grid.window(i);
            let c = window.centre();
            let deformation = predictor::predict(
                predictor,
                c,
                t0_us,
                params.deform,
                params.predictor_smoothing,
            )
            .and_then(|p| p.deformation)
            .map(|mut d| {
                d.velocity = reference.median;
                d
            });
            let tolerance = (0..2)
                .map(|k| threshold * (reference.spread[k] + epsilon))
                .fold(0.0, f64::max);
            let prediction = Prediction {
                velocity: reference.median,
                deformation,
                search_radius: Some(tolerance),
            };
            let scratch = scratch.get_or_insert_with(|| estimator.scratch(grid.window));
            let e = estimator.estimate(slab, &window, t0_us, Some(&prediction), scratch);
            let height = e.peak as f64 / field.peak[i] as f64;
            if e.status.is_valid()
                && height >= MIN_RELATIVE_HEIGHT
                && reference.passes(e.u, e.v, threshold, epsilon)
            {
                accepted.push((i, e, height.min(1.0)));
            }
        }
    }
    for &(i, e, height) in &accepted {
        field.u[i] = e.u as f32;
        field.v[i] = e.v as f32;
        field.status[i] = Status::VALID;
        field.peak[i] = e.peak;
        field.peak_ratio[i] = height as f32;
        field.event_count[i] = e.event_count;
    }
    accepted.len()
}
