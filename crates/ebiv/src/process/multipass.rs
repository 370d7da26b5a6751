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
    /// [`PassEvaluator::prepare_predictor`]) from the previous pass, if any; with the
    /// per-vector uncertainty when `uncertainty` (the passes on the last grid: the earlier
    /// ones only predict).
    fn evaluate(
        &self,
        grid: &Grid,
        predictor: Option<&VectorField>,
        uncertainty: bool,
    ) -> VectorField;

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
    /// Estimate the per-vector uncertainty in the evaluations of the last grid.
    pub uncertainty: bool,
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
    for k in 0..evaluations {
        let grid = &grids[k.min(last)];
        let mut field =
            evaluator.evaluate(grid, predictor.as_ref(), settings.uncertainty && k >= last);
        let mut validation = validate::validate(&mut field, settings.validation);
        iterations += 1;
        // Only repetitions of the last pass have a previous field to compare with.
        let change = previous.as_ref().and_then(|p| mean_change(p, &field));
        let converged = change.is_some_and(|c| c < settings.repeat_tolerance);
        let is_final = k + 1 == evaluations || converged;
        if k < last || is_final {
            // The repetitions of the last pass share one report, written when they end.
            reports.push(PassReport {
                window: grid.window,
                vectors: grid.len(),
                iterations,
                last_change: change.unwrap_or(f64::NAN),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::event::Geometry;
    use crate::grid::GridSpec;
    use std::cell::RefCell;

    /// Every window gets `values[k]` at the k-th evaluation; the grids seen, and whether
    /// each evaluation was asked for the uncertainty, are recorded.
    struct Scripted {
        values: Vec<f32>,
        seen: RefCell<Vec<u32>>,
        asked: RefCell<Vec<bool>>,
    }

    impl PassEvaluator for Scripted {
        fn evaluate(
            &self,
            grid: &Grid,
            _predictor: Option<&VectorField>,
            uncertainty: bool,
        ) -> VectorField {
            self.asked.borrow_mut().push(uncertainty);
            let mut seen = self.seen.borrow_mut();
            let value = self.values[seen.len()];
            seen.push(grid.window[0]);
            let mut field = VectorField::new(grid.x_centres(), grid.y_centres());
            field.u.fill(value);
            field.v.fill(0.0);
            field.status.fill(crate::field::Status::VALID);
            field
        }

        fn prepare_predictor(&self, _field: &mut VectorField) {}
    }

    fn grids(windows: &[u32]) -> Vec<Grid> {
        let g = Geometry::new(128, 128);
        windows
            .iter()
            .map(|&w| Grid::new(&GridSpec::square(w, w / 2), g).unwrap())
            .collect()
    }

    fn settings(validation: &ValidationParams, single: bool) -> MultiPass<'_> {
        MultiPass {
            validation,
            last_pass_repeats: 3,
            repeat_single_pass: single,
            repeat_tolerance: 0.01,
            secondary_peaks: false,
            replace_final: false,
            uncertainty: true,
        }
    }

    #[test]
    fn the_last_pass_repeats_until_its_vectors_stop_changing() {
        let validation = ValidationParams::default();
        // Changes between the last pass's evaluations: 0.5, then 0.005 (converged).
        let scripted = Scripted {
            values: vec![1.0, 2.0, 2.5, 2.505, 9.0],
            seen: RefCell::new(Vec::new()),
            asked: RefCell::new(Vec::new()),
        };
        let out = run_passes(&scripted, &grids(&[64, 32]), &settings(&validation, false));
        assert_eq!(*scripted.seen.borrow(), vec![64, 32, 32, 32]);
        // Only the evaluations of the last grid estimate the uncertainty, and none without it.
        assert_eq!(*scripted.asked.borrow(), vec![false, true, true, true]);
        let without = Scripted {
            values: vec![1.0, 2.0, 2.5, 2.505, 9.0],
            seen: RefCell::new(Vec::new()),
            asked: RefCell::new(Vec::new()),
        };
        let off = MultiPass {
            uncertainty: false,
            ..settings(&validation, false)
        };
        run_passes(&without, &grids(&[64, 32]), &off);
        assert!(without.asked.borrow().iter().all(|&a| !a));
        assert_eq!(out.field.u[0], 2.505);
        assert_eq!(out.passes.len(), 2);
        assert_eq!(out.passes[1].iterations, 3);
        assert!((out.passes[1].last_change - 0.005).abs() < 1e-4);
        assert!(out.passes[0].last_change.is_nan());
    }

    #[test]
    fn a_single_pass_repeats_only_when_asked() {
        let validation = ValidationParams::default();
        let scripted = || Scripted {
            values: vec![1.0, 2.0, 3.0, 4.0],
            seen: RefCell::new(Vec::new()),
            asked: RefCell::new(Vec::new()),
        };
        let once = scripted();
        run_passes(&once, &grids(&[32]), &settings(&validation, false));
        assert_eq!(once.seen.borrow().len(), 1);
        let repeated = scripted();
        let out = run_passes(&repeated, &grids(&[32]), &settings(&validation, true));
        assert_eq!(repeated.seen.borrow().len(), 4, "1 + last_pass_repeats");
        assert_eq!(out.passes[0].iterations, 4);
    }
}
