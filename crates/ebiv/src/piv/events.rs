//! PIV of frames rebuilt from an event recording — the EBIV paper's third route (Willert &
//! Klinner 2022, Exp. Fluids 63:101; algorithms.md §6) — and pulsed EBIV, where one frame per
//! light pulse gives crisp particle images (Willert 2023, Exp. Fluids 64:98; §7).
//!
//! A field at centre time `t0` uses `pairs + 1` consecutive frames, evenly spaced by `Δt`
//! around `t0`; the correlation planes of their `pairs` consecutive pairs are summed (one pair
//! as in double-frame PIV; three for the paper's four-frame sequences), and the displacement
//! divided by `Δt` gives velocities in px/ms, the unit of the event estimators.

use super::{piv_ensemble, PivParams};
use crate::error::{Error, Result};
use crate::event::Geometry;
use crate::field::{FieldSeries, TimeBasis};
use crate::frame::events::{build_frame, FrameSpec};
use crate::frame::pulse::PulseTiming;
use crate::frame::Frame;
use crate::process::{BatchSource, FieldDone, RunSummary, SlidingEvents};

/// When frames are taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrameClock {
    /// Frames every `step_us` (Δt) around each field's time; exposure from the frame spec.
    Regular {
        /// Time between the starts of consecutive frames, µs.
        step_us: i64,
    },
    /// One frame per light pulse, exposure one period, starts in the dark gap before each
    /// pulse ([`crate::frame::pulse::detect_pulses`]).
    Pulsed(PulseTiming),
}

/// Everything about PIV on an event recording.
#[derive(Debug, Clone, PartialEq)]
pub struct EventPivParams {
    /// How frames are rebuilt (kind, exposure, polarity, splatting). In pulsed mode the
    /// exposure is replaced by the pulse period.
    pub frames: FrameSpec,
    /// When frames are taken.
    pub clock: FrameClock,
    /// Frame pairs per field whose correlation planes are summed (≥ 1).
    pub pairs: u32,
    /// The PIV engine's settings. Validation ε and limits are given in px/ms, like those of
    /// the event estimators, and converted to px of displacement with Δt.
    pub piv: PivParams,
}

/// The frames of one field: their starts, the time between them and the field's time.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePlan {
    /// Start of each frame, µs.
    pub starts: Vec<i64>,
    /// Exposure of each frame, µs.
    pub exposure_us: i64,
    /// Time between consecutive frames, µs (may be fractional in pulsed mode).
    pub dt_us: f64,
    /// Field time: centre of the frames' time span, µs.
    pub t0_us: i64,
}

impl FramePlan {
    /// The time span of the field's frames, from the start of the first to the end of the
    /// last, µs: `pairs × Δt + exposure` for regular frames. Every event of a frame lies in
    /// it; the field's vectors record it as their
    /// [`slab_us`](crate::field::VectorField::slab_us).
    pub fn span_us(&self) -> i64 {
        let first = self.starts.first().copied().unwrap_or(0);
        let last = self.starts.last().copied().unwrap_or(0);
        last.saturating_add(self.exposure_us).saturating_sub(first)
    }
}

/// Most frame pairs per field.
pub const MAX_PAIRS: u32 = 64;
/// Most memory the frames of one field may take (frames, resampling coefficients, deformed
/// copies), bytes.
pub const MAX_FIELD_MEMORY_BYTES: u64 = 8 << 30;

impl EventPivParams {
    /// Check every setting.
    pub fn check(&self) -> Result<()> {
        self.piv.check()?;
        if self.pairs == 0 || self.pairs > MAX_PAIRS {
            return Err(Error::parameter(
                "pairs",
                format!(
                    "{}: give 1 to {MAX_PAIRS} frame pairs per field",
                    self.pairs
                ),
            ));
        }
        match self.clock {
            FrameClock::Regular { step_us } => {
                self.frames.check()?;
                if step_us <= 0 || step_us > i64::MAX / (2 * MAX_PAIRS as i64 + 2) {
                    return Err(Error::parameter(
                        "frame-step",
                        format!("{step_us} µs: the time between frames must be positive and below years"),
                    ));
                }
                if self.frames.exposure_us > step_us {
                    return Err(Error::parameter(
                        "exposure",
                        format!(
                            "{} µs is longer than the frame step of {step_us} µs: consecutive frames would share events, whose zero-displacement peak biases the field; shorten --exposure or lengthen --frame-step",
                            self.frames.exposure_us
                        ),
                    ));
                }
            }
            FrameClock::Pulsed(t) => {
                if !(t.period_us.is_finite() && t.period_us >= 1.0 && t.offset_us.is_finite()) {
                    return Err(Error::parameter(
                        "pulse",
                        format!("unusable pulse timing (period {} µs)", t.period_us),
                    ));
                }
            }
        }
        let span = self.plan(0).span_us();
        if u32::try_from(span).is_err() {
            return Err(Error::parameter(
                "pairs",
                format!(
                    "the frames of one field would span {span} µs, longer than the {} µs (71 minutes) a vector's time slab can record; use fewer pairs or a shorter frame step",
                    u32::MAX
                ),
            ));
        }
        Ok(())
    }

    /// The frames of the field nearest to time `t0_us` (pulsed mode snaps to the pulses).
    pub fn plan(&self, t0_us: i64) -> FramePlan {
        let n = self.pairs as i64;
        match self.clock {
            FrameClock::Regular { step_us } => {
                let exposure = self.frames.exposure_us;
                let span = n * step_us + exposure;
                let first = t0_us - span / 2;
                FramePlan {
                    starts: (0..=n).map(|k| first + k * step_us).collect(),
                    exposure_us: exposure,
                    dt_us: step_us as f64,
                    t0_us: first + span / 2,
                }
            }
            FrameClock::Pulsed(t) => {
                let p = t.period_us;
                // Frames k = 0..=n start at offset + (m + k)·P; the centre of their span is
                // offset + (m + (n + 1)/2)·P.
                let m = ((t0_us as f64 - t.offset_us) / p - (n + 1) as f64 / 2.0).round();
                let start = |k: i64| (t.offset_us + (m + k as f64) * p).round() as i64;
                FramePlan {
                    starts: (0..=n).map(start).collect(),
                    exposure_us: t.exposure_us(),
                    dt_us: p,
                    t0_us: (t.offset_us + (m + (n + 1) as f64 / 2.0) * p).round() as i64,
                }
            }
        }
    }

    /// Time the frames of a field need before and after its time, µs.
    pub fn time_extent_us(&self) -> (i64, i64) {
        let plan = self.plan(0);
        let end = plan.starts.last().copied().unwrap_or(0) + plan.exposure_us;
        (-plan.starts[0] + plan.t0_us, end - plan.t0_us)
    }
}

/// PIV of an event recording at the field times `times_us` (sorted, deduplicated; snapped to
/// the pulses in pulsed mode): for each field the frames of [`EventPivParams::plan`] are
/// rebuilt from the events in memory and evaluated by [`piv_ensemble`]; velocities in px/ms.
/// Streams `source` once, so memory is bounded by one field's events.
/// `on_field` is called after every field; an error from it ends the run and is returned.
pub fn piv_events<S: BatchSource>(
    source: &mut S,
    geometry: Geometry,
    params: &EventPivParams,
    times_us: &[i64],
    on_field: &mut dyn FnMut(&FieldDone) -> Result<()>,
) -> Result<(FieldSeries, RunSummary)> {
    params.check()?;
    let pixels = geometry.width as u64 * geometry.height as u64;
    let bytes = (params.pairs as u64 + 1) * pixels * 4 * 3;
    if bytes > MAX_FIELD_MEMORY_BYTES {
        return Err(Error::parameter(
            "pairs",
            format!(
                "{} frame pairs of {geometry} need about {} GiB per field; use fewer pairs or a region of interest",
                params.pairs,
                bytes >> 30
            ),
        ));
    }
    let mut plans: Vec<FramePlan> = times_us.iter().map(|&t| params.plan(t)).collect();
    plans.sort_by_key(|p| p.t0_us);
    plans.dedup_by_key(|p| p.t0_us);
    let last_grid = params
        .piv
        .passes
        .last()
        .ok_or_else(|| Error::parameter("passes", "at least one pass is needed"))?;
    let grid = crate::grid::Grid::new(last_grid, geometry)?;
    let mut series = FieldSeries::on_grid(grid.x_centres(), grid.y_centres());
    series.attributes = attributes(params);
    series.time_basis = TimeBasis::FrameCentre;
    let mut sliding = SlidingEvents::default();
    let mut summary = RunSummary::default();
    for (k, plan) in plans.iter().enumerate() {
        let start = plan.starts[0];
        let end = plan.starts[plan.starts.len() - 1] + plan.exposure_us;
        sliding.advance(source, start, end)?;
        summary.events_read = sliding.events_read;
        let events = sliding.events();
        let spec = FrameSpec {
            exposure_us: plan.exposure_us,
            ..params.frames
        };
        let frames: Vec<Frame> = plan
            .starts
            .iter()
            .map(|&s| build_frame(events, geometry, s, &spec))
            .collect();
        let pairs: Vec<(&Frame, &Frame)> = frames.windows(2).map(|w| (&w[0], &w[1])).collect();
        let polarity = params.frames.polarity;
        let empty = !events
            .t
            .iter()
            .zip(&events.p)
            .any(|(&t, &p)| t >= start && t < end && polarity.accepts(p));
        summary.empty_fields += usize::from(empty);
        let dt_ms = plan.dt_us / 1000.0;
        let out = piv_ensemble(&pairs, &params.piv.over_interval(dt_ms))?;
        let mut field = out.field;
        field.scale(1.0 / dt_ms);
        // `check` keeps the span within u32.
        field.set_slab_us(u32::try_from(plan.span_us()).unwrap_or(u32::MAX));
        summary.fields += 1;
        summary.vectors += field.len();
        summary.valid += field.status.iter().filter(|s| s.is_valid()).count();
        summary.flagged += out.validation.valid_before - out.validation.valid_after;
        series.push(plan.t0_us, &field)?;
        on_field(&FieldDone {
            done: k + 1,
            total: plans.len(),
            t0_us: plan.t0_us,
            field: &field,
            events,
        })?;
    }
    Ok((series, summary))
}

/// The run's settings as output attributes (the writers add the software, the time basis and
/// the status legend).
fn attributes(params: &EventPivParams) -> Vec<(String, String)> {
    let f = &params.frames;
    let clock = match params.clock {
        FrameClock::Regular { step_us } => format!("regular, frame step {step_us} us"),
        FrameClock::Pulsed(t) => format!(
            "one frame per light pulse: {:.3} Hz, period {:.3} us, phase {:.1} us (from {})",
            t.frequency_hz,
            t.period_us,
            t.phase_us(),
            t.source.describe()
        ),
    };
    // The exposure the frames are built with: the setting for regular frames, the pulse
    // period (dark gap to dark gap) for one frame per pulse, as the plan uses it.
    let exposure_us = params.plan(0).exposure_us;
    let mut a = vec![
        (
            "method".to_string(),
            match params.clock {
                FrameClock::Regular { .. } => "piv of event frames",
                FrameClock::Pulsed(_) => "pulsed ebiv (piv of one frame per pulse)",
            }
            .to_string(),
        ),
        ("frames".to_string(), clock),
        (
            "frame_kind".to_string(),
            format!(
                "{}, exposure {} us, polarity {}, splat sigma {} px",
                f.kind.name(),
                exposure_us,
                f.polarity.name(),
                f.splat_sigma
            ),
        ),
        (
            "frame_pairs_per_field".to_string(),
            params.pairs.to_string(),
        ),
    ];
    // `params.piv` holds the validation limits as given, in px/ms; the engine runs on
    // `over_interval` of them.
    a.extend(super::attributes(&params.piv, "px/ms"));
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::pulse::PulseSource;

    fn params(clock: FrameClock, pairs: u32) -> EventPivParams {
        EventPivParams {
            frames: FrameSpec {
                exposure_us: 1000,
                ..FrameSpec::default()
            },
            clock,
            pairs,
            piv: PivParams::default(),
        }
    }

    #[test]
    fn regular_frames_are_centred_on_the_field_time() {
        let p = params(FrameClock::Regular { step_us: 2000 }, 3);
        let plan = p.plan(10_000);
        // Span 3·2000 + 1000 = 7000 µs around 10 000.
        assert_eq!(plan.starts, vec![6500, 8500, 10_500, 12_500]);
        assert_eq!(
            (plan.t0_us, plan.exposure_us, plan.dt_us),
            (10_000, 1000, 2000.0)
        );
        assert_eq!(p.time_extent_us(), (3500, 3500));
    }

    #[test]
    fn pulsed_frames_snap_to_the_pulses() {
        let timing = PulseTiming {
            frequency_hz: 3000.0,
            period_us: 1e6 / 3000.0,
            offset_us: 100.0,
            source: PulseSource::Triggers,
            contrast: 1.0,
            periods: 100,
        };
        let p = params(FrameClock::Pulsed(timing), 2);
        let plan = p.plan(10_000);
        let period = 1e6 / 3000.0;
        for (k, &s) in plan.starts.iter().enumerate() {
            let phase = (s as f64 - 100.0).rem_euclid(period);
            assert!(phase < 0.6 || period - phase < 0.6, "frame {k} at {s}");
        }
        assert_eq!(plan.exposure_us, 333);
        // The output attributes state the exposure the frames were built with (the period),
        // not the regular-frame setting (1000 µs here).
        let kind = attributes(&p)
            .into_iter()
            .find(|(k, _)| k == "frame_kind")
            .unwrap()
            .1;
        assert!(kind.contains("exposure 333 us"), "{kind}");
        // Three frames: the field time is the centre of their span, near the request.
        let centre = (plan.starts[0] as f64 + plan.starts[2] as f64 + period) / 2.0;
        assert!((plan.t0_us as f64 - centre).abs() <= 1.0);
        assert!((plan.t0_us - 10_000).abs() as f64 <= period / 2.0 + 1.0);
        assert!(params(FrameClock::Regular { step_us: 500 }, 1)
            .check()
            .is_err());
        assert!(params(FrameClock::Regular { step_us: 2000 }, 0)
            .check()
            .is_err());
    }
}
