//! From events to validated vector fields: multi-pass evaluation of one time slab, and the
//! time series of a whole recording streamed slab by slab.
//!
//! Multi-pass (Raffel et al., "Particle Image Velocimetry", 3rd ed., §5.5; Willert & Klinner
//! 2022 for the event estimators): a first pass on large windows gives a field that is
//! validated, gap-filled and optionally smoothed; it predicts the velocity at every window of
//! the next pass, whose estimator then shifts its second sub-volume (sum of correlation) or
//! centres its search (motion compensation) there. The last pass is validated; replacing its
//! outliers is a separate, optional step.

pub mod multipass;
mod plan;
mod predictor;
mod secondary;
mod stream;
mod times;

pub use multipass::{run_passes, MultiPass, PassEvaluator, PassReport, PassesOutcome};
pub use plan::{coverage, first_event_time, plan_fields, Coverage, PlannedFields, MAX_FIELDS};
pub(crate) use stream::run_attributes;
pub use stream::{
    lone_pixel_line, process_recording, scan_extent, BatchSource, FieldDone, MemorySource,
    RecordingExtent, RunSummary, SlidingEvents,
};
pub use times::{FieldTimes, TimeSteps};

use crate::error::Result;
use crate::estimate::Estimator;
use crate::event::{EventBuffer, Geometry, PolaritySelection};
use crate::field::{Status, VectorField};
use crate::grid::{Grid, GridSpec, Mask};
use crate::validate::{self, ValidationParams, ValidationSummary};
use crate::volume::Slab;
use rayon::prelude::*;

/// The ways of measuring a velocity field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Sum of correlation of two event sub-volumes (Willert & Klinner 2022, §2.3).
    CorrSum,
    /// Motion compensation: the velocity that sharpens the warped event image most
    /// (Willert & Klinner 2022, §2.4; Gallego et al. 2018).
    Motion,
    /// Cross-correlation PIV of image pairs or of frames rebuilt from events.
    Piv,
    /// PIV of one frame per light pulse (pulsed EBIV, Willert 2023).
    Pulsed,
}

impl Method {
    /// Parse `corrsum`, `motion`, `piv` or `pulsed` (and their long names).
    pub fn parse(text: &str) -> Option<Method> {
        match text {
            "corrsum" | "sum-of-correlation" | "correlation" => Some(Method::CorrSum),
            "motion" | "motion-compensation" | "cmax" => Some(Method::Motion),
            "piv" => Some(Method::Piv),
            "pulsed" | "pulsed-ebiv" => Some(Method::Pulsed),
            _ => None,
        }
    }
}

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
    /// Standard deviation, in grid nodes, of the Gaussian weights of the local linear fit
    /// that gives a later pass its predicted velocity and gradient (smoothing the previous
    /// pass; exact for linear fields up to the border). 0: bilinear interpolation of the
    /// unsmoothed field and central differences.
    pub predictor_smoothing: f64,
    /// Pixels to leave out; windows whose centre is masked are not evaluated.
    pub mask: Option<Mask>,
    /// Deform the events of later passes by the predictor's local velocity gradient
    /// ([`crate::deform::events::Deformation`]), so that vectors refer to their window centre.
    pub deform: bool,
    /// Times the last pass of a multi-pass run is repeated with its own result as the
    /// predictor (PIVlab's "repeat last pass"; Thielicke & Sonntag 2021, J. Open Res. Softw.
    /// 9:12): the gradient of a predictor on the final grid deforms the events better than
    /// that of the coarser previous pass. 0 = off; single-pass runs never repeat.
    pub last_pass_repeats: u32,
    /// Stop repeating the last pass once the mean |Δv| of its vectors between two
    /// repetitions is below this, px/ms.
    pub repeat_tolerance: f64,
    /// Re-evaluate the median-test outliers of a multi-pass run's last pass on a lower peak
    /// near their neighbours' median (multiple-peak validation, [`secondary`]; estimators
    /// with [`Estimator::finds_secondary_peaks`], i.e. sum of correlation). Single passes
    /// are never re-evaluated.
    pub secondary_peaks: bool,
    /// Estimate the per-vector uncertainty on the last pass ([`Estimator::skip_uncertainty`]
    /// on the others, and everywhere when false).
    pub uncertainty: bool,
    /// Leave the events of lone persistent pixels (hot pixels) out of every field's slab
    /// ([`Slab::drop_lone_pixels`]).
    pub drop_lone_pixels: bool,
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
            last_pass_repeats: 2,
            repeat_tolerance: 0.005,
            secondary_peaks: true,
            uncertainty: true,
            drop_lone_pixels: true,
        }
    }
}

impl ProcessParams {
    /// What the previous pass's `field` predicts at point `c` (image px) for a field at
    /// `t0_us`, with this run's deformation and predictor smoothing.
    fn prediction(
        &self,
        field: &VectorField,
        c: [f64; 2],
        t0_us: i64,
    ) -> Option<crate::estimate::Prediction> {
        predictor::predict(field, c, t0_us, self.deform, self.predictor_smoothing)
    }

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

    /// The slab of a field: the events of `[start_us, end_us)` with the selected polarity,
    /// binned into tiles, without the lone persistent pixels when `drop_lone_pixels`.
    pub fn field_slab(
        &self,
        events: &EventBuffer,
        geometry: Geometry,
        start_us: i64,
        end_us: i64,
    ) -> Slab {
        let mut slab = Slab::build(
            &events.t,
            &events.x,
            &events.y,
            &events.p,
            geometry,
            start_us,
            end_us,
            self.polarity,
            self.tile_size(),
        );
        if self.drop_lone_pixels {
            slab.drop_lone_pixels((&events.t, &events.x, &events.y));
        }
        slab
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

/// Evaluate every pass of `params` on the events of `slab` around time `t0_us` with the
/// one multi-pass loop ([`multipass::run_passes`]); with more than one pass, the last one is
/// repeated (up to `last_pass_repeats` times) with the previous result as predictor until the
/// mean change of its vectors falls below `repeat_tolerance`.
pub fn process_slab<E: Estimator>(
    estimator: &E,
    slab: &Slab,
    t0_us: i64,
    grids: &[Grid],
    params: &ProcessParams,
) -> FieldResult {
    let passes = EventPasses {
        estimator,
        slab,
        t0_us,
        params,
    };
    let outcome = multipass::run_passes(
        &passes,
        grids,
        &MultiPass {
            validation: &params.validation,
            last_pass_repeats: params.last_pass_repeats,
            repeat_single_pass: false,
            repeat_tolerance: params.repeat_tolerance,
            secondary_peaks: params.secondary_peaks && estimator.finds_secondary_peaks(),
            replace_final: params.replace_final,
            uncertainty: params.uncertainty,
        },
    );
    FieldResult {
        field: outcome.field,
        validation: outcome.validation,
        replaced: outcome.replaced,
    }
}

/// The passes of an event estimator on one slab.
struct EventPasses<'a, E> {
    estimator: &'a E,
    slab: &'a Slab,
    t0_us: i64,
    params: &'a ProcessParams,
}

impl<E: Estimator> PassEvaluator for EventPasses<'_, E> {
    fn evaluate(
        &self,
        grid: &Grid,
        predictor: Option<&VectorField>,
        uncertainty: bool,
    ) -> VectorField {
        evaluate_pass(
            self.estimator,
            self.slab,
            self.t0_us,
            grid,
            self.params,
            (predictor, uncertainty),
        )
    }

    /// Gaps filled by interpolation; the smoothing is the predictor's local linear fit
    /// ([`ProcessParams::predictor_smoothing`]), applied where it is sampled.
    fn prepare_predictor(&self, field: &mut VectorField) {
        validate::replace_invalid(field, &Default::default());
    }

    fn reevaluate_outliers(
        &self,
        grid: &Grid,
        predictor: &VectorField,
        field: &mut VectorField,
    ) -> usize {
        secondary::reevaluate_outliers(
            self.estimator,
            self.slab,
            self.t0_us,
            grid,
            self.params,
            predictor,
            field,
        )
    }
}

/// One pass: every window of `grid` in parallel, each with its predictor, with or without
/// the per-vector uncertainty.
fn evaluate_pass<E: Estimator>(
    estimator: &E,
    slab: &Slab,
    t0_us: i64,
    grid: &Grid,
    params: &ProcessParams,
    (predictor, uncertainty): (Option<&VectorField>, bool),
) -> VectorField {
    let estimates: Vec<_> = (0..grid.len())
        .into_par_iter()
        .map_init(
            || {
                let mut scratch = estimator.scratch(grid.window);
                estimator.skip_uncertainty(&mut scratch, !uncertainty);
                scratch
            },
            |scratch, i| {
                if grid.is_masked(i, params.mask.as_ref()) {
                    return crate::estimate::WindowEstimate::invalid(Status::MASKED, 0, 0);
                }
                let window = grid.window(i);
                let c = window.centre();
                let guess = predictor.and_then(|p| params.prediction(p, c, t0_us));
                estimator.estimate(slab, &window, t0_us, guess.as_ref(), scratch)
            },
        )
        .collect();
    let mut field = VectorField::new(grid.x_centres(), grid.y_centres());
    for (i, e) in estimates.into_iter().enumerate() {
        field.u[i] = e.u as f32;
        field.v[i] = e.v as f32;
        field.u_unc[i] = e.u_unc;
        field.v_unc[i] = e.v_unc;
        field.status[i] = e.status;
        field.peak[i] = e.peak;
        field.peak_ratio[i] = e.peak_ratio;
        field.event_count[i] = e.event_count;
        field.slab_us[i] = e.slab_us;
        if !e.status.is_valid() {
            field.u[i] = f32::NAN;
            field.v[i] = f32::NAN;
            field.u_unc[i] = f32::NAN;
            field.v_unc[i] = f32::NAN;
        }
    }
    field
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::corrsum::{CorrSumParams, SumOfCorrelation};
    use crate::estimate::motion::{ContrastMaximization, MotionParams};

    /// Every evaluated window records the estimator's slab T, with or without events; a
    /// masked window, which is not evaluated, records none.
    #[test]
    fn every_evaluated_window_records_its_slab_and_masked_ones_none() {
        let geometry = Geometry::new(64, 64);
        let slab = Slab::build(
            &[],
            &[],
            &[],
            &[],
            geometry,
            0,
            10_000,
            PolaritySelection::Both,
            8,
        );
        let mut masked = vec![false; 64 * 64];
        for row in masked.chunks_mut(64) {
            row[..32].fill(true);
        }
        let params = ProcessParams {
            passes: vec![GridSpec::square(32, 16)],
            mask: Some(Mask {
                width: 64,
                height: 64,
                masked,
            }),
            ..ProcessParams::default()
        };
        let grids = params.grids(geometry).unwrap();
        let corrsum = SumOfCorrelation::new(CorrSumParams {
            slab_us: 7000,
            ..CorrSumParams::default()
        })
        .unwrap();
        let motion = ContrastMaximization::new(MotionParams {
            slab_us: 7000,
            ..MotionParams::default()
        })
        .unwrap();
        let fields = [
            process_slab(&corrsum, &slab, 5000, &grids, &params).field,
            process_slab(&motion, &slab, 5000, &grids, &params).field,
        ];
        for field in fields {
            for i in 0..field.len() {
                if field.status[i].contains(Status::MASKED) {
                    assert_eq!(field.slab_us[i], 0, "masked vector {i}");
                } else {
                    assert_eq!(field.status[i], Status::NO_EVENTS);
                    assert_eq!(field.slab_us[i], 7000, "vector {i}");
                }
            }
            assert!(field.status.iter().any(|s| s.contains(Status::MASKED)));
            assert!(field.status.contains(&Status::NO_EVENTS));
        }
    }
}
