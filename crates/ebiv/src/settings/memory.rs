//! Processing a recording held in memory (a simulation) with resolved settings, by any
//! method: what `ebiv process` does with a file, for studies that simulate their recordings
//! instead of reading them.

use super::{EstimatorTask, Resolved};
use crate::error::{Error, Result};
use crate::estimate::Estimator;
use crate::event::{EventBuffer, Geometry};
use crate::field::FieldSeries;
use crate::frame::pulse::detect_pulses;
use crate::piv::{piv_events, FrameClock};
use crate::process::{process_recording, MemorySource, Method, ProcessParams};

/// `n` field times spread evenly over `[first_us, last_us]` (the span a recording leaves
/// between its margins) for fields needing `(before, after)` µs of events around their
/// times; an error naming `slab` when a field does not fit.
pub fn spread_field_times(
    (before, after): (i64, i64),
    first_us: i64,
    last_us: i64,
    n: usize,
) -> Result<Vec<i64>> {
    let (first, last) = (first_us + before, last_us - after);
    if last < first || n == 0 {
        return Err(Error::parameter(
            "slab",
            format!(
                "a field spans {} µs, more than the {} µs the recording leaves between its margins",
                before + after,
                last_us - first_us
            ),
        ));
    }
    let n = n as i64;
    let mut times: Vec<i64> = (0..n)
        .map(|k| first + (last - first) * k / (n - 1).max(1))
        .collect();
    times.dedup();
    Ok(times)
}

/// Field times for fields needing `(before, after)` µs of events around their times.
pub type TimesFor<'a> = &'a dyn Fn((i64, i64)) -> Result<Vec<i64>>;

impl Resolved {
    /// The fields of `events` (a recording on `geometry`) at the times `times_for` gives for
    /// the method's time extent, by the run's method: the event estimators through the
    /// multi-pass engine, PIV of frames rebuilt from the events, or pulsed PIV with the pulse
    /// timing detected from the events' rate (or their trigger edges). Returns the series
    /// and the time over which a vector's displacement is measured, ms (τ, T or the frame
    /// step; `None` where it varies per vector, as with `slab = auto`).
    pub fn process_in_memory(
        &self,
        events: &EventBuffer,
        geometry: Geometry,
        times_for: TimesFor,
    ) -> Result<(FieldSeries, Option<f64>)> {
        match self.method {
            Method::CorrSum | Method::Motion => {
                let series = self.with_event_estimator(Fields {
                    params: &self.process,
                    events,
                    geometry,
                    times_for,
                })??;
                let delay = match (self.method, self.adaptive) {
                    (_, Some(_)) => None,
                    (Method::CorrSum, None) => Some(self.corrsum.tau_us as f64 / 1000.0),
                    _ => Some(self.motion.slab_us as f64 / 1000.0),
                };
                Ok((series, delay))
            }
            Method::Piv | Method::Pulsed => {
                let clock = if self.method == Method::Pulsed {
                    let times: Vec<i64> = (0..events.len())
                        .filter(|&i| self.frames.polarity.accepts(events.p[i]))
                        .map(|i| events.t[i])
                        .collect();
                    FrameClock::Pulsed(detect_pulses(&times, &events.triggers, self.pulse_hz)?)
                } else {
                    FrameClock::Regular {
                        step_us: self.frame_step_us,
                    }
                };
                let params = self.event_piv_params(clock)?;
                let times = times_for(params.time_extent_us())?;
                let delay = params.plan(times[0]).dt_us / 1000.0;
                let mut source = MemorySource::new(events);
                let (series, _) =
                    piv_events(&mut source, geometry, &params, &times, &mut |_| Ok(()))?;
                Ok((series, Some(delay)))
            }
        }
    }
}

/// The fields of one recording by an event estimator.
struct Fields<'a> {
    params: &'a ProcessParams,
    events: &'a EventBuffer,
    geometry: Geometry,
    times_for: TimesFor<'a>,
}

impl EstimatorTask for Fields<'_> {
    type Output = Result<FieldSeries>;
    fn run<E: Estimator>(self, estimator: &E) -> Result<FieldSeries> {
        let times = (self.times_for)(estimator.planning_extent_us())?;
        let mut source = MemorySource::new(self.events);
        let (series, _) = process_recording(
            &mut source,
            self.geometry,
            estimator,
            self.params,
            &times,
            &mut |_| Ok(()),
        )?;
        Ok(series)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_spread_between_the_margins() {
        let times = spread_field_times((10_000, 10_000), 5_000, 65_000, 3).unwrap();
        assert_eq!(times, [15_000, 35_000, 55_000]);
        let times = spread_field_times((1_000, 1_000), 5_000, 65_000, 3).unwrap();
        assert_eq!(times, [6_000, 35_000, 64_000]);
        assert_eq!(
            spread_field_times((1_000, 1_000), 0, 10_000, 1).unwrap(),
            [1_000]
        );
        assert!(spread_field_times((40_000, 40_000), 5_000, 65_000, 3).is_err());
    }
}
