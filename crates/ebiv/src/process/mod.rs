//! From events to validated vector fields: multi-pass evaluation of one time slab, and the
//! time series of a whole recording streamed slab by slab.
//!
//! Multi-pass (Raffel et al., "Particle Image Velocimetry", 3rd ed., §5.5; Willert & Klinner
//! 2022 for the event estimators): a first pass on large windows gives a field that is
//! validated, gap-filled and optionally smoothed; it predicts the velocity at every window of
//! the next pass, whose estimator then shifts its second sub-volume (sum of correlation) or
//! centres its search (motion compensation) there. The last pass is validated; replacing its
//! outliers is a separate, optional step.

mod stream;
mod times;

pub use stream::{
    process_recording, scan_extent, BatchSource, FieldDone, MemorySource, RecordingExtent,
    RunSummary, SlidingEvents,
};
pub use times::TimeSteps;

use crate::error::Result;
use crate::estimate::{Deformation, Estimator, Prediction};
use crate::event::{Geometry, PolaritySelection};
use crate::field::{Status, VectorField};
use crate::grid::{Grid, GridSpec, Mask};
use crate::validate::{self, ValidationParams, ValidationSummary};
use crate::volume::Slab;
use rayon::prelude::*;

/// Everything about a run besides the estimator: passes, events, validation.
#[derive(Debug, Clone)]
pub struct ProcessParams {
    /// Interrogation grids, first pass first; the last one is the output grid.
    pub passes: Vec<GridSpec>,
    /// Events used (the paper uses positive events only).
    pub polarity: PolaritySelection,
    /// Outlier detection, applied after every pass.
    pub validation: ValidationParams,
    /// Replace the outliers of the last pass by interpolation (they keep their flag plus
    /// [`Status::REPLACED`]); between passes they are always replaced.
    pub replace_final: bool,
    /// Gaussian smoothing of the predictor between passes, in grid nodes (0 = off).
    pub predictor_smoothing: f64,
    /// Pixels to leave out; windows whose centre is masked are not evaluated.
    pub mask: Option<Mask>,
    /// Deform the events of later passes by the predictor's local velocity gradient
    /// ([`crate::volume::Deformation`]), so that vectors refer to their window centre.
    pub deform: bool,
}

impl Default for ProcessParams {
    fn default() -> Self {
        ProcessParams {
            passes: vec![GridSpec::square(40, 20)],
            polarity: PolaritySelection::Positive,
            validation: ValidationParams::default(),
            replace_final: false,
            predictor_smoothing: 1.0,
            mask: None,
            deform: true,
        }
    }
}

impl ProcessParams {
    /// The grids of every pass on a sensor of `geometry`.
    pub fn grids(&self, geometry: Geometry) -> Result<Vec<Grid>> {
        if self.passes.is_empty() {
            return Err(crate::Error::parameter(
                "passes",
                "at least one pass is needed",
            ));
        }
        self.passes.iter().map(|p| Grid::new(p, geometry)).collect()
    }

    /// Side of the square tiles a slab is binned into: half the smallest window, so a
    /// window visits at most 9 tiles.
    pub fn tile_size(&self) -> u32 {
        let smallest = self
            .passes
            .iter()
            .map(|p| p.window[0].min(p.window[1]))
            .min()
            .unwrap_or(32);
        (smallest / 2).clamp(4, 64)
    }
}

/// The result of one time step.
#[derive(Debug, Clone)]
pub struct FieldResult {
    /// The last pass's field.
    pub field: VectorField,
    /// What validation found in the last pass.
    pub validation: ValidationSummary,
    /// Vectors replaced in the last pass (0 unless `replace_final`).
    pub replaced: usize,
}

/// Evaluate every pass of `params` on the events of `slab` around time `t0_us`.
pub fn process_slab<E: Estimator>(
    estimator: &E,
    slab: &Slab,
    t0_us: i64,
    grids: &[Grid],
    params: &ProcessParams,
) -> FieldResult {
    let mut predictor: Option<VectorField> = None;
    let mut last = None;
    for (k, grid) in grids.iter().enumerate() {
        let mut field = evaluate_pass(estimator, slab, t0_us, grid, params, predictor.as_ref());
        let validation = validate::validate(&mut field, &params.validation);
        let is_last = k + 1 == grids.len();
        if !is_last {
            validate::replace_invalid(&mut field, &Default::default());
            if params.predictor_smoothing > 0.0 {
                validate::smooth(&mut field, params.predictor_smoothing);
            }
            predictor = Some(field);
        } else {
            let replaced = if params.replace_final {
                validate::replace_invalid(&mut field, &Default::default())
            } else {
                0
            };
            last = Some(FieldResult {
                field,
                validation,
                replaced,
            });
        }
    }
    last.expect("grids is not empty")
}

/// The prediction of `field` at point `c`: velocity by bilinear interpolation and, with
/// `deform`, the velocity gradient by central differences over one grid spacing.
fn predict(field: &VectorField, c: [f64; 2], t0_us: i64, deform: bool) -> Option<Prediction> {
    let velocity = field.sample(c[0], c[1])?;
    let spacing = |axis: &[f64]| axis.windows(2).map(|w| w[1] - w[0]).next().unwrap_or(0.0);
    let (hx, hy) = (spacing(&field.x), spacing(&field.y));
    let gradient = (deform && hx > 0.0 && hy > 0.0).then(|| {
        let xp = field.sample(c[0] + hx, c[1])?;
        let xm = field.sample(c[0] - hx, c[1])?;
        let yp = field.sample(c[0], c[1] + hy)?;
        let ym = field.sample(c[0], c[1] - hy)?;
        // The predictor is clamped at the grid edge; difference over the true distance.
        let dx = (c[0] + hx).min(field.x[field.x.len() - 1]) - (c[0] - hx).max(field.x[0]);
        let dy = (c[1] + hy).min(field.y[field.y.len() - 1]) - (c[1] - hy).max(field.y[0]);
        (dx > 0.0 && dy > 0.0).then(|| {
            [
                [(xp[0] - xm[0]) / dx, (yp[0] - ym[0]) / dy],
                [(xp[1] - xm[1]) / dx, (yp[1] - ym[1]) / dy],
            ]
        })
    });
    let deformation = gradient.flatten().map(|gradient| Deformation {
        centre: c,
        velocity,
        gradient,
        t0_us,
    });
    Some(Prediction {
        velocity,
        deformation,
    })
}

/// One pass: every window of `grid` in parallel, each with its predictor.
fn evaluate_pass<E: Estimator>(
    estimator: &E,
    slab: &Slab,
    t0_us: i64,
    grid: &Grid,
    params: &ProcessParams,
    predictor: Option<&VectorField>,
) -> VectorField {
    let estimates: Vec<_> = (0..grid.len())
        .into_par_iter()
        .map_init(
            || estimator.scratch(grid.window),
            |scratch, i| {
                if grid.is_masked(i, params.mask.as_ref()) {
                    return crate::estimate::WindowEstimate::invalid(Status::MASKED, 0);
                }
                let window = grid.window(i);
                let c = window.centre();
                let guess = predictor.and_then(|p| predict(p, c, t0_us, params.deform));
                estimator.estimate(slab, &window, t0_us, guess.as_ref(), scratch)
            },
        )
        .collect();
    let mut field = VectorField::new(grid.x_centres(), grid.y_centres());
    for (i, e) in estimates.into_iter().enumerate() {
        field.u[i] = e.u as f32;
        field.v[i] = e.v as f32;
        field.status[i] = e.status;
        field.peak[i] = e.peak;
        field.peak_ratio[i] = e.peak_ratio;
        field.event_count[i] = e.event_count;
        if !e.status.is_valid() {
            field.u[i] = f32::NAN;
            field.v[i] = f32::NAN;
        }
    }
    field
}
