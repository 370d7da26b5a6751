//! A run over a recording by resolved settings, whatever the method: what `ebiv process`
//! and Python's `ebiv.process` both call, so that the two give the same fields, attributes
//! and messages. The caller watches the run through a [`RunObserver`] (progress bars,
//! figures, interrupts) and writes the result.

use super::{EstimatorTask, Resolved};
use crate::error::{Error, Result};
use crate::estimate::Estimator;
use crate::event::{Geometry, PolaritySelection};
use crate::field::FieldSeries;
use crate::frame::pulse::{PulseSource, PulseTiming};
use crate::grid::{describe_passes, Grid};
use crate::io::{DecodeReport, EventSource};
use crate::piv::images::ImageSeriesParams;
use crate::piv::{piv_events, EventPivParams, FrameClock, PivParams};
use crate::process::{process_recording, FieldDone, Method, PlannedFields, RunSummary};

/// A planned run, before its first field.
pub struct RunPlan<'a> {
    /// One line saying what is computed: the source, the field times, the method, the
    /// sensor and the passes.
    pub description: String,
    /// The sensor size.
    pub geometry: Geometry,
    /// Field centre times, µs (camera time).
    pub times: &'a [i64],
    /// The events a field needs before and after its time, µs.
    pub extent_us: (i64, i64),
}

/// What a caller sees of a run as it goes. Every method has a default that does nothing.
pub trait RunObserver {
    /// The run is planned; an error stops it before any field.
    fn planned(&mut self, _plan: &RunPlan) -> Result<()> {
        Ok(())
    }
    /// A finding on the way worth telling the user (the pulse timing detected).
    fn note(&mut self, _line: &str) {}
    /// A field is done; an error (an interrupt, a figure that cannot be written) stops the
    /// run.
    fn field(&mut self, _done: &FieldDone) -> Result<()> {
        Ok(())
    }
}

/// An observer that watches nothing.
impl RunObserver for () {}

/// The outcome of a run over a recording.
pub struct Measurement {
    /// The fields, with the run's calibration, time origin and `source` attribute.
    pub series: FieldSeries,
    /// Counts of fields, vectors and what validation flagged.
    pub summary: RunSummary,
    /// What the reader dropped or found odd.
    pub report: DecodeReport,
    /// Things the user should know about the result (empty fields, no valid vector).
    pub warnings: Vec<String>,
}

impl Resolved {
    /// Measure the fields of `source` by the run's method: the event estimators through the
    /// multi-pass engine, PIV of frames rebuilt from the events, or pulsed PIV with the
    /// pulse timing found in the recording. Image pairs (`images`) are measured by
    /// [`crate::piv::images::piv_image_series`] instead, and are an error here.
    ///
    /// An error when no field held an event of the selected polarity: whatever would be
    /// written from it would be blank.
    pub fn measure(
        &self,
        source: &EventSource,
        observer: &mut dyn RunObserver,
    ) -> Result<Measurement> {
        self.measure_fields(source, observer, true)
    }

    /// [`Resolved::measure`] of a part of a run (a shard of `ebiv.dask`, selected by `time`):
    /// fields without events are gaps with a warning even when all are, as they are in the
    /// whole run.
    pub fn measure_part(
        &self,
        source: &EventSource,
        observer: &mut dyn RunObserver,
    ) -> Result<Measurement> {
        self.measure_fields(source, observer, false)
    }

    fn measure_fields(
        &self,
        source: &EventSource,
        observer: &mut dyn RunObserver,
        all_empty_is_error: bool,
    ) -> Result<Measurement> {
        if let super::Source::Images(_) = self.source {
            return Err(Error::parameter(
                "images",
                "image pairs are measured by PIV of images (`ebiv process --images`, Python's `ebiv.piv`), not as a recording",
            ));
        }
        // The run's denoising, whatever the source was given with.
        let source = &source.denoised(self.denoise);
        let (mut series, summary, report, planned, polarity) = match self.method {
            Method::CorrSum | Method::Motion => self.with_event_estimator(EventRun {
                run: self,
                source,
                observer,
            })??,
            Method::Piv | Method::Pulsed => self.measure_frames(source, observer)?,
        };
        let warnings =
            check_found_events(source, &summary, &planned, polarity, all_empty_is_error)?;
        series.time_origin_us = Some(planned.time_origin_us);
        self.finish_series(&mut series)?;
        series.attributes.push(("source".into(), source.name()));
        if let Some(d) = &self.denoise {
            series.attributes.push(("denoise".into(), d.describe()));
        }
        if self.process.drop_lone_pixels && matches!(self.method, Method::CorrSum | Method::Motion)
        {
            series.attributes.push((
                "lone_pixel_events".into(),
                summary.lone_pixel_events.to_string(),
            ));
        }
        Ok(Measurement {
            series,
            summary,
            report,
            warnings,
        })
    }

    /// The run's plan over `source`, without measuring: the field times, their origin, and
    /// the events each field needs before and after its time, µs. A run restricted by `time`
    /// to some of these fields (a shard) measures them exactly as the whole run does.
    pub fn plan(&self, source: &EventSource) -> Result<(PlannedFields, (i64, i64))> {
        let (extent, step) = match self.method {
            Method::CorrSum | Method::Motion => {
                (self.with_event_estimator(PlanningExtent)?, self.slab_us())
            }
            Method::Piv | Method::Pulsed => {
                let (before, after) = self.frame_params(source, &mut ())?.time_extent_us();
                ((before, after), before + after)
            }
        };
        Ok((self.plan_fields(source, extent, step)?, extent))
    }

    /// The parameters of PIV of frames rebuilt from `source`: regular frames, or one per
    /// pulse with the pulse timing found in the recording (told to `observer`).
    fn frame_params(
        &self,
        source: &EventSource,
        observer: &mut dyn RunObserver,
    ) -> Result<EventPivParams> {
        let clock = if self.method == Method::Pulsed {
            let timing = self.pulse_timing(source)?;
            observer.note(&describe_pulses(&timing));
            FrameClock::Pulsed(timing)
        } else {
            FrameClock::Regular {
                step_us: self.frame_step_us,
            }
        };
        self.event_piv_params(clock)
    }

    /// The parameters of PIV of frames rebuilt from events by `clock`, checked.
    pub(super) fn event_piv_params(&self, clock: FrameClock) -> Result<EventPivParams> {
        let params = EventPivParams {
            frames: self.frames,
            clock,
            pairs: self.pairs,
            piv: self.piv.clone(),
        };
        params.check()?;
        Ok(params)
    }

    /// PIV of frames rebuilt from the recording (regular frames, or one per pulse).
    fn measure_frames(
        &self,
        source: &EventSource,
        observer: &mut dyn RunObserver,
    ) -> Result<Outcome> {
        let mut params = self.frame_params(source, observer)?;
        let (before, after) = params.time_extent_us();
        let mut planned = self.plan_fields(source, (before, after), before + after)?;
        // Pulsed frames snap to the pulses, so the first frame may start before `before`.
        let first_frame = params.plan(planned.times[0]).starts.first().copied();
        let lead = first_frame.map_or(before, |start| before.max(planned.times[0] - start));
        skip_to_first_field(&mut planned, lead)?;
        let g = planned.geometry;
        params.piv.mask = self.mask_for(g)?;
        for pass in &params.piv.passes {
            Grid::new(pass, g)?;
        }
        let plan = params.plan(planned.times[0]);
        let description = format!(
            "{}: {}, PIV of {} {} frames ({} µs exposure, Δt {:.1} µs, {} pair(s) per field) on {g}, passes {}",
            source.name(),
            planned.describe_times(),
            self.frames.kind.name(),
            format!("{:?}", self.frames.polarity).to_lowercase(),
            plan.exposure_us,
            plan.dt_us,
            self.pairs,
            describe_piv(&params.piv)
        );
        observer.planned(&RunPlan {
            description,
            geometry: g,
            times: &planned.times,
            extent_us: (before, after),
        })?;
        let (series, summary) =
            piv_events(&mut planned.reader, g, &params, &planned.times, &mut |d| {
                observer.field(d)
            })?;
        let report = planned.reader.report();
        Ok((series, summary, report, planned, self.frames.polarity))
    }

    /// The parameters of PIV of image pairs of `geometry` by the run's settings, its mask
    /// loaded and its windows checked against the images.
    pub fn image_series_params(&self, geometry: Geometry) -> Result<ImageSeriesParams> {
        let mut params = ImageSeriesParams {
            piv: self.piv.clone(),
            sequence: self.sequence,
            ensemble: self.ensemble,
            dt_us: self.dt_us,
        };
        params.piv.mask = self.mask_for(geometry)?;
        for pass in &params.piv.passes {
            Grid::new(pass, geometry)?;
        }
        Ok(params)
    }

    /// The pulse timing, found from the start of `time` if given, else from the first event.
    fn pulse_timing(&self, source: &EventSource) -> Result<PulseTiming> {
        let mut reader = source.open()?;
        let start = match self.time.and_then(|t| t.start) {
            Some(start) if self.absolute_time => Some(start),
            Some(start) => Some(source.first_event_time()?.unwrap_or(0) + start),
            None => None,
        };
        crate::frame::scan_pulse_timing(
            &mut reader,
            self.frames.polarity,
            start,
            None,
            self.pulse_hz,
        )
    }
}

/// A run's fields, summary, reader report, plan and polarity, before the checks.
type Outcome = (
    FieldSeries,
    RunSummary,
    DecodeReport,
    PlannedFields,
    PolaritySelection,
);

/// The time extent an event estimator plans its fields with.
struct PlanningExtent;

impl EstimatorTask for PlanningExtent {
    type Output = (i64, i64);
    fn run<E: Estimator>(self, estimator: &E) -> (i64, i64) {
        estimator.planning_extent_us()
    }
}

/// A run of an event estimator ([`Resolved::with_event_estimator`]).
struct EventRun<'a> {
    run: &'a Resolved,
    source: &'a EventSource,
    observer: &'a mut dyn RunObserver,
}

impl EstimatorTask for EventRun<'_> {
    type Output = Result<Outcome>;
    fn run<E: Estimator>(self, estimator: &E) -> Result<Outcome> {
        let EventRun {
            run,
            source,
            observer,
        } = self;
        let extent_us = estimator.planning_extent_us();
        let mut planned = run.plan_fields(source, extent_us, run.slab_us())?;
        // The longest slab's extent: with slabs per window, longer than the planning one.
        skip_to_first_field(&mut planned, estimator.time_extent_us().0)?;
        let g = planned.geometry;
        let mut params = run.process.clone();
        params.mask = run.mask_for(g)?;
        params.grids(g)?; // a window that does not fit, before anything else
        let description = format!(
            "{}: {}, {} on {g}, passes {}",
            source.name(),
            planned.describe_times(),
            estimator.name(),
            describe_passes(&params.passes)
        );
        observer.planned(&RunPlan {
            description,
            geometry: g,
            times: &planned.times,
            extent_us,
        })?;
        let (series, summary) = process_recording(
            &mut planned.reader,
            g,
            estimator,
            &params,
            &planned.times,
            &mut |d| observer.field(d),
        )?;
        let report = planned.reader.report();
        Ok((series, summary, report, planned, params.polarity))
    }
}

/// Skip the events before the first field needs them (`before` µs ahead of its time), by
/// the file's index where it has one: what the fields read is unchanged, as they drop the
/// events before their slabs themselves.
fn skip_to_first_field(planned: &mut PlannedFields, before: i64) -> Result<()> {
    let first = planned.times[0].saturating_sub(before);
    planned.reader.skip_to(first)
}

/// After a run, before anything is written: an error when no field held an event of the
/// selected polarity (a `time` beyond the recording, or a polarity the camera did not
/// record); warnings when some fields were empty or no vector is valid.
fn check_found_events(
    source: &EventSource,
    summary: &RunSummary,
    planned: &PlannedFields,
    polarity: PolaritySelection,
    all_empty_is_error: bool,
) -> Result<Vec<String>> {
    let polarity = match polarity {
        PolaritySelection::Both => "either polarity".to_string(),
        p => format!("{} polarity", format!("{p:?}").to_lowercase()),
    };
    let described_times = planned.describe_times();
    if all_empty_is_error && summary.fields > 0 && summary.empty_fields == summary.fields {
        return Err(Error::empty(
            source.name(),
            format!(
                "no event of {polarity} in any field's time interval ({described_times}), so no field file is written. `ebiv info {}` shows the recording's span and polarities: check --time and --polarity",
                source.name()
            ),
        ));
    }
    let mut warnings = Vec::new();
    if summary.empty_fields > 0 {
        warnings.push(format!(
            "{} of {} field(s) had no event of {polarity} in their time interval; their vectors are gaps (check --time against the recording's span from `ebiv info`)",
            summary.empty_fields, summary.fields
        ));
    }
    if summary.vectors > 0 && summary.valid == 0 {
        warnings.push(
            "no vector is valid. Look at the events (`ebiv render`) and see Troubleshooting in the README: too few particles per window (larger --window), a --slab too short for the particles to move a pixel or so long they leave the window, or --max-velocity too low".into(),
        );
    }
    Ok(warnings)
}

/// "pulses: 1000.000 Hz (period …), frames start … from trigger edges (…)".
fn describe_pulses(timing: &PulseTiming) -> String {
    format!(
        "pulses: {:.3} Hz (period {:.3} µs), frames start {:.1} µs into each period, from {} ({} periods, modulation contrast {:.2})",
        timing.frequency_hz,
        timing.period_us,
        timing.phase_us(),
        match timing.source {
            PulseSource::Triggers => "trigger edges",
            PulseSource::EventHistogram => "the event rate",
        },
        timing.periods,
        timing.contrast
    )
}

/// "64x64 px step 32 -> …, fft correlation, bicubic symmetric deformation".
pub fn describe_piv(p: &PivParams) -> String {
    format!(
        "{}, {:?} correlation, {:?} {:?} deformation",
        describe_passes(&p.passes),
        p.correlation,
        p.interpolation,
        p.deformation
    )
    .to_lowercase()
}
