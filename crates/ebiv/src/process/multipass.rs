//! The one multi-pass loop of every method (Raffel et al., "Particle Image Velocimetry", 3rd
//! ed., §5.5; Scarano 2002, Meas. Sci. Technol. 13:R1; Willert & Klinner 2022 for the event
//! estimators):
//!
//! 1. each pass evaluates every window of its grid, with the previous pass's field as the
//!    predictor (window offset, search centre, deformation);
//! 2. its field is validated; between passes the method turns it into a predictor (gaps
//!    filled, smoothed: [`PassEvaluator::prepare_predictor`]);
//! 3. the last pass may be repeated with its own result as the predictor (PIVlab's repeated
//!    last pass; Thielicke & Sonntag 2021, J. Open Res. Softw. 9:12), until the mean change
//!    of the vectors valid in two successive repetitions falls below a tolerance;
//! 4. the last field may have its median-test outliers re-evaluated on secondary peaks, and
//!    its outliers replaced, each a separate, optional step.
//!
//! The event estimators ([`super::process_slab`]) and PIV of frames ([`crate::piv`]) differ
//! only in what [`PassEvaluator`] does.

use crate::field::VectorField;
use crate::grid::Grid;
use crate::validate::{self, ValidationParams, ValidationSummary};

/// What a method does in a pass.
pub trait PassEvaluator {
    /// Evaluate every window of `grid`, with `predictor` (a field prepared by
    /// [`PassEvaluator::prepare_predictor`]) from the previous pass, if any.
    fn evaluate(&self, grid: &Grid, predictor: Option<&VectorField>) -> VectorField;

    /// Turn a validated field into the predictor of the next pass.
    fn prepare_predictor(&self, field: &mut VectorField);

    /// Re-evaluate the median-test outliers of the final `field` on lower peaks near their
    /// neighbours' median; the number made valid. Methods without secondary peaks keep
    /// them flagged.
    fn reevaluate_outliers(
        &self,
        _grid: &Grid,
        _predictor: &VectorField,
        _field: &mut VectorField,
    ) -> usize {
        0
    }
}

/// The settings of the loop.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiPass<'a> {
    /// Outlier detection, after every pass.
    pub validation: &'a ValidationParams,
    /// Repetitions of the last pass at most.
    pub last_pass_repeats: u32,
    /// Whether a single pass is repeated too (PIV: its repetitions deform the frames); the
    /// event methods repeat only the last of several passes.
    pub repeat_single_pass: bool,
    /// The repetitions stop once the mean change of the vectors valid in two successive
    /// ones is below this, in the field's unit.
    pub repeat_tolerance: f64,
    /// Re-evaluate the final field's median-test outliers (multi-pass runs only).
    pub secondary_peaks: bool,
    /// Replace the outliers of the final field (they keep their flag plus `replaced`).
    pub replace_final: bool,
}

/// What one pass did.
#[derive(Debug, Clone, PartialEq)]
pub struct PassReport {
    /// Window width and height, px.
    pub window: [u32; 2],
    /// Vectors on the pass's grid.
    pub vectors: usize,
    /// Evaluations of the pass (1 + repetitions of the last pass).
    pub iterations: u32,
    /// Mean change of the field in the last repetition (NaN without repetitions).
    pub last_change: f64,
    /// Valid share after validation.
    pub valid_share: f64,
}

/// The result of the loop.
#[derive(Debug, Clone)]
pub struct PassesOutcome {
    /// The last pass's field.
    pub field: VectorField,
    /// What validation found in the last pass (after any secondary-peak re-evaluation).
    pub validation: ValidationSummary,
    /// Vectors replaced in the last pass (0 unless `replace_final`).
    pub replaced: usize,
    /// One report per pass.
    pub passes: Vec<PassReport>,
}

/// Run every pass of `grids` (not empty) with `evaluator`.
pub fn run_passes(
    evaluator: &impl PassEvaluator,
    grids: &[Grid],
    settings: &MultiPass,
) -> PassesOutcome {
    let last = grids.len() - 1;
    let repeats = if grids.len() > 1 || settings.repeat_single_pass {
        settings.last_pass_repeats
    } else {
        0
    };
    let evaluations = grids.len() + repeats as usize;
    let mut predictor: Option<VectorField> = None;
    let mut previous: Option<VectorField> = None;
    let mut reports = Vec::with_capacity(grids.len());
    let mut iterations = 0;
    let mut change = f64::NAN;
    for k in 0..evaluations {
        let grid = &grids[k.min(last)];
        let mut field = evaluator.evaluate(grid, predictor.as_ref());
        let mut validation = validate::validate(&mut field, settings.validation);
        iterations += 1;
        if let Some(p) = &previous {
            change = mean_change(p, &field).unwrap_or(f64::NAN);
        }
        let converged = previous.is_some() && change < settings.repeat_tolerance;
        let is_final = k + 1 == evaluations || converged;
        if k < last || is_final {
            // The repetitions of the last pass share one report, written when they end.
            reports.push(PassReport {
                window: grid.window,
                vectors: grid.len(),
                iterations,
                last_change: if iterations > 1 { change } else { f64::NAN },
                valid_share: field.valid_share(),
            });
            iterations = 0;
        }
        if !is_final {
            if k >= last {
                previous = Some(field.clone());
            }
            evaluator.prepare_predictor(&mut field);
            predictor = Some(field);
            continue;
        }
        if let Some(p) = predictor.as_ref().filter(|_| settings.secondary_peaks) {
            let n = evaluator.reevaluate_outliers(grid, p, &mut field);
            validation.median_test -= n;
            validation.valid_after += n;
            validation.secondary_peaks = n;
        }
        let replaced = if settings.replace_final {
            validate::replace_invalid(&mut field, &Default::default())
        } else {
            0
        };
        return PassesOutcome {
            field,
            validation,
            replaced,
            passes: reports,
        };
    }
    unreachable!("the last evaluation returns")
}

/// Mean |Δv| over the vectors valid (finite) in both fields of one grid; `None` if none is.
pub fn mean_change(a: &VectorField, b: &VectorField) -> Option<f64> {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for i in 0..a.len().min(b.len()) {
        if a.status[i].is_valid() && b.status[i].is_valid() {
            let d = ((a.u[i] - b.u[i]) as f64).hypot((a.v[i] - b.v[i]) as f64);
            if d.is_finite() {
                sum += d;
                n += 1;
            }
        }
    }
    (n > 0).then(|| sum / n as f64)
}
