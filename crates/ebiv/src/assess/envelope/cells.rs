//! The cells of the envelope study: the tally of one cell's valid vectors against the true
//! velocity, its statistics, and the criterion that makes a cell fail.

use super::{EnvelopeSpec, RunSetting};
use crate::field::FieldSeries;

/// A valid vector is a gross error when its end-point error exceeds this, px/ms, or
/// [`GROSS_RELATIVE`] of the speed, whichever is larger.
pub const GROSS_ABSOLUTE: f64 = 0.2;
/// See [`GROSS_ABSOLUTE`].
pub const GROSS_RELATIVE: f64 = 0.1;
/// A cell fails when this share of its valid vectors, or more, are gross errors.
pub const FAIL_SHARE: f64 = 0.01;

/// The error beyond which a valid vector of a flow at `speed` px/ms counts as wrong:
/// max([`GROSS_ABSOLUTE`], [`GROSS_RELATIVE`] × speed), px/ms.
pub fn gross_limit(speed: f64) -> f64 {
    GROSS_ABSOLUTE.max(GROSS_RELATIVE * speed.abs())
}

/// Sums over the valid vectors of one cell.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Tally {
    recordings: usize,
    fields: usize,
    vectors: usize,
    valid: usize,
    squared_error: f64,
    error: [f64; 2],
    gross: usize,
    pub(super) seconds: f64,
}

impl Tally {
    /// Add the vectors of `series`, measured on a flow of velocity `truth` px/ms.
    pub(super) fn add(&mut self, series: &FieldSeries, truth: [f64; 2]) {
        let limit = gross_limit(truth[0].hypot(truth[1]));
        self.recordings += 1;
        self.fields += series.t_us.len();
        self.vectors += series.u.len();
        for i in 0..series.u.len() {
            let (u, v) = (series.u[i] as f64, series.v[i] as f64);
            if !series.status[i].is_valid() || !u.is_finite() || !v.is_finite() {
                continue;
            }
            let e = [u - truth[0], v - truth[1]];
            let end_point = e[0].hypot(e[1]);
            self.valid += 1;
            self.squared_error += end_point * end_point;
            self.error[0] += e[0];
            self.error[1] += e[1];
            self.gross += usize::from(end_point > limit);
        }
    }

    /// The cell's statistics.
    pub(super) fn stats(&self) -> CellStats {
        let n = self.valid as f64;
        let mean = |s: f64| if self.valid > 0 { s / n } else { f64::NAN };
        CellStats {
            recordings: self.recordings,
            fields: self.fields,
            vectors: self.vectors,
            valid: self.valid,
            rms: mean(self.squared_error).sqrt(),
            bias: [mean(self.error[0]), mean(self.error[1])],
            gross: self.gross,
            seconds: self.seconds,
        }
    }
}

/// One valid vector of the study, with its cell and the evidence it rests on.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidVector {
    /// The setting of its run.
    pub setting: RunSetting,
    /// Flow speed, px/ms.
    pub speed: f64,
    /// Seeding density, particles per pixel.
    pub density: f64,
    /// Simulation seed.
    pub seed: u64,
    /// Field time, µs.
    pub t_us: i64,
    /// Window centre, px.
    pub x: f64,
    /// Window centre, px.
    pub y: f64,
    /// Measured velocity, px/ms.
    pub u: f64,
    /// Measured velocity, px/ms.
    pub v: f64,
    /// The estimator's peak value.
    pub peak: f32,
    /// First-to-second peak ratio (NaN where not defined).
    pub peak_ratio: f32,
    /// Events the estimate is based on.
    pub event_count: u32,
    /// Slab T of the vector, µs.
    pub slab_us: u32,
    /// The displacement the vector claims, px: |v|·τ for sum of correlation, |v|·T for
    /// motion compensation.
    pub displacement_px: f64,
    /// End-point error, px/ms.
    pub error: f64,
    /// Whether the error exceeds [`gross_limit`].
    pub gross: bool,
}

impl ValidVector {
    /// The valid vectors of `series`, measured on a flow of velocity `truth` px/ms in the cell
    /// `(setting, speed, density, seed)`; `delay_ms` gives the time over which a vector of a
    /// slab of so many µs claims its displacement.
    pub(super) fn each<'a>(
        series: &'a FieldSeries,
        truth: [f64; 2],
        (setting, speed, density, seed): (&'a RunSetting, f64, f64, u64),
        delay_ms: impl Fn(u32) -> f64 + 'a,
    ) -> impl Iterator<Item = ValidVector> + 'a {
        let limit = gross_limit(truth[0].hypot(truth[1]));
        let per_field = series.x.len() * series.y.len();
        (0..series.u.len()).filter_map(move |i| {
            let (u, v) = (f64::from(series.u[i]), f64::from(series.v[i]));
            if !series.status[i].is_valid() || !u.is_finite() || !v.is_finite() {
                return None;
            }
            let within = i % per_field.max(1);
            let error = (u - truth[0]).hypot(v - truth[1]);
            Some(ValidVector {
                setting: setting.clone(),
                speed,
                density,
                seed,
                t_us: series.t_us[i / per_field.max(1)],
                x: series.x[within % series.x.len()],
                y: series.y[within / series.x.len()],
                u,
                v,
                peak: series.peak[i],
                peak_ratio: series.peak_ratio[i],
                event_count: series.event_count[i],
                slab_us: series.slab_us[i],
                displacement_px: u.hypot(v) * delay_ms(series.slab_us[i]),
                error,
                gross: error > limit,
            })
        })
    }
}

/// What one cell measured, pooled over its seeds and fields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellStats {
    /// Recordings (seeds) processed.
    pub recordings: usize,
    /// Fields evaluated.
    pub fields: usize,
    /// Vectors in those fields.
    pub vectors: usize,
    /// Valid vectors among them.
    pub valid: usize,
    /// RMS end-point error of the valid vectors, px/ms (NaN without valid vectors).
    pub rms: f64,
    /// Mean error (u, v) of the valid vectors, px/ms.
    pub bias: [f64; 2],
    /// Valid vectors off by more than [`gross_limit`].
    pub gross: usize,
    /// Wall time of the processing runs, s (the one figure that depends on the machine).
    pub seconds: f64,
}

impl CellStats {
    /// Share of the vectors that are valid.
    pub fn valid_share(&self) -> f64 {
        self.valid as f64 / self.vectors.max(1) as f64
    }

    /// Share of the valid vectors that are gross errors; NaN without valid vectors.
    pub fn gross_share(&self) -> f64 {
        if self.valid == 0 {
            f64::NAN
        } else {
            self.gross as f64 / self.valid as f64
        }
    }

    /// Whether [`FAIL_SHARE`] or more of the valid vectors are gross errors.
    pub fn fails(&self) -> bool {
        self.gross_share() >= FAIL_SHARE
    }
}

/// One cell of the study: a setting on the recordings of one speed and density.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// Flow speed, px/ms.
    pub speed: f64,
    /// Seeding density, particles per pixel.
    pub density: f64,
    /// The processing setting.
    pub setting: RunSetting,
    /// What it measured, or why it could not run (the library's message).
    pub outcome: std::result::Result<CellStats, String>,
}

impl Cell {
    /// Whether the cell ran and failed ([`CellStats::fails`]).
    pub fn fails(&self) -> bool {
        self.outcome.as_ref().is_ok_and(CellStats::fails)
    }
}

/// The study's results: its specification and every cell, in the order of
/// [`EnvelopeSpec::settings`] within density within speed.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvelopeResults {
    /// What was evaluated.
    pub spec: EnvelopeSpec,
    /// Every cell.
    pub cells: Vec<Cell>,
}

impl EnvelopeResults {
    /// The cells that fail.
    pub fn failing(&self) -> impl Iterator<Item = &Cell> {
        self.cells.iter().filter(|c| c.fails())
    }

    /// The cell of `setting` at `speed` and `density`.
    pub fn cell(&self, speed: f64, density: f64, setting: &RunSetting) -> Option<&Cell> {
        self.cells
            .iter()
            .find(|c| c.speed == speed && c.density == density && &c.setting == setting)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Status;

    #[test]
    fn gross_errors_are_counted_against_the_larger_limit() {
        assert_eq!(gross_limit(1.0), 0.2);
        assert!((gross_limit(5.0) - 0.5).abs() < 1e-12);
        let mut s = FieldSeries::new(vec![0.0, 1.0, 2.0, 3.0], vec![0.0], vec![0]);
        // Truth (5, 0): errors 0.1, 0.6 (gross, above 0.5), 0.4, and one invalid vector.
        s.u = vec![5.1, 5.6, 4.6, f32::NAN];
        s.v = vec![0.0; 4];
        s.status = vec![
            Status::VALID,
            Status::VALID,
            Status::VALID,
            Status::MEDIAN_TEST,
        ];
        let mut t = Tally::default();
        t.add(&s, [5.0, 0.0]);
        let c = t.stats();
        assert_eq!((c.vectors, c.valid, c.gross), (4, 3, 1));
        let rms = ((0.01 + 0.36 + 0.16) / 3.0f64).sqrt();
        assert!((c.rms - rms).abs() < 1e-6, "{c:?}");
        assert!((c.gross_share() - 1.0 / 3.0).abs() < 1e-12 && c.fails());
        assert!((c.valid_share() - 0.75).abs() < 1e-12);
    }

    #[test]
    fn a_cell_without_valid_vectors_does_not_fail() {
        let c = Tally::default().stats();
        assert!(c.rms.is_nan() && c.gross_share().is_nan() && !c.fails());
    }
}
