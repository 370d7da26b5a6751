//! Phase averaging by trigger: the trigger edges of a recording ([`read_trigger_times`]) and
//! the phase of a field between them.
//!
//! The field times of `ebiv process` are µs of the camera clock, as the recording's events
//! and triggers are stamped; a field series whose `time_origin_us` (the first event of the
//! recording it was measured from) differs from the first event of the recording read here
//! was measured from another recording, or read with another time shift, and is refused.

use crate::error::{Error, Result};
use crate::event::{EventBuffer, Trigger};
use crate::field::FieldSeries;
use crate::io::ReadOptions;
use std::path::Path;

/// Which trigger edges mark the start of a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TriggerPolarity {
    /// Rising edges (value 1; formats with pulse semantics report 1).
    #[default]
    Rising,
    /// Falling edges (value 0).
    Falling,
    /// Every edge.
    Any,
}

impl TriggerPolarity {
    /// `rising`, `falling` or `any`.
    pub fn parse(text: &str) -> Option<TriggerPolarity> {
        match text.trim() {
            "rising" => Some(TriggerPolarity::Rising),
            "falling" => Some(TriggerPolarity::Falling),
            "any" => Some(TriggerPolarity::Any),
            _ => None,
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            TriggerPolarity::Rising => "rising",
            TriggerPolarity::Falling => "falling",
            TriggerPolarity::Any => "any",
        }
    }

    fn accepts(self, t: &Trigger) -> bool {
        match self {
            TriggerPolarity::Rising => t.value == 1,
            TriggerPolarity::Falling => t.value == 0,
            TriggerPolarity::Any => true,
        }
    }
}

/// The trigger edges of a recording and its first event time.
#[derive(Debug, Clone, PartialEq)]
pub struct TriggerTimes {
    /// Times of the selected edges, µs, ascending, without repetitions.
    pub times_us: Vec<i64>,
    /// Time of the recording's first event, µs (`None` without events).
    pub first_event_us: Option<i64>,
    /// Edges of the recording on any channel and of either polarity.
    pub all_edges: usize,
}

impl TriggerTimes {
    /// Check that `series` can be matched to these triggers: camera times, measured from a
    /// recording that starts where this one does.
    pub fn check_time_base(&self, series: &FieldSeries) -> Result<()> {
        if !series.time_basis.is_camera_time() {
            return Err(Error::parameter(
                "triggers",
                "the fields of image pairs carry no times to place between triggers",
            ));
        }
        if let (Some(origin), Some(first)) = (series.time_origin_us, self.first_event_us) {
            if origin != 0 && origin != first {
                return Err(Error::parameter(
                    "triggers",
                    format!(
                        "the field series was measured from a recording whose first event is at \
                         {origin} us, this recording's first event is at {first} us: not the same \
                         recording, or read with another time shift (--metavision-time)"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Read every trigger edge of the recording `path` of `polarity` on `channel` (`None`: the
/// one channel the recording uses; an error when it uses several).
pub fn read_trigger_times(
    path: &Path,
    options: &ReadOptions,
    polarity: TriggerPolarity,
    channel: Option<u8>,
) -> Result<TriggerTimes> {
    let mut reader = crate::io::open(path, options)?;
    let mut batch = EventBuffer::new();
    let mut edges: Vec<Trigger> = Vec::new();
    let mut first_event_us = None;
    while reader.read_batch(&mut batch)? {
        if first_event_us.is_none() {
            first_event_us = batch.t.first().copied();
        }
        edges.extend_from_slice(&batch.triggers);
    }
    let mut channels: Vec<u8> = edges.iter().map(|t| t.channel).collect();
    channels.sort_unstable();
    channels.dedup();
    let channel = match (channel, channels.as_slice()) {
        (Some(c), _) => c,
        (None, []) => 0,
        (None, [one]) => *one,
        (None, many) => {
            return Err(Error::parameter(
                "trigger-channel",
                format!(
                    "{} has triggers on channels {many:?}; choose one",
                    path.display()
                ),
            ))
        }
    };
    let mut times_us: Vec<i64> = edges
        .iter()
        .filter(|t| t.channel == channel && polarity.accepts(t))
        .map(|t| t.t)
        .collect();
    times_us.sort_unstable();
    times_us.dedup();
    Ok(TriggerTimes {
        times_us,
        first_event_us,
        all_edges: edges.len(),
    })
}

/// [`read_trigger_times`] of the recording `path` that `series` was measured from, checked
/// against the series' time base ([`TriggerTimes::check_time_base`]).
pub fn triggers_for(
    series: &FieldSeries,
    path: &Path,
    options: &ReadOptions,
    polarity: TriggerPolarity,
    channel: Option<u8>,
) -> Result<TriggerTimes> {
    if !series.time_basis.is_camera_time() {
        return Err(Error::parameter(
            "triggers",
            "the fields of image pairs carry no times to place between triggers",
        ));
    }
    let times = read_trigger_times(path, options, polarity, channel)?;
    times.check_time_base(series)?;
    Ok(times)
}

/// What phase averaging by trigger used.
#[derive(Debug, Clone, PartialEq)]
pub struct TriggerSummary {
    /// Trigger times used.
    pub triggers: usize,
    /// The first and last trigger, µs.
    pub span_us: (i64, i64),
    /// Mean interval between consecutive triggers, µs.
    pub mean_interval_us: f64,
    /// Fields before the first or at or after the last trigger, left out.
    pub fields_outside: usize,
}

/// Trigger times and the fields outside their span.
pub(crate) struct TriggerPhases<'a> {
    times: &'a [i64],
    /// Fields outside the span.
    pub outside: usize,
}

impl<'a> TriggerPhases<'a> {
    /// For `times` (ascending) and the field times `field_times`; an error with fewer than
    /// two triggers or when no field lies between the first and the last.
    pub fn new(times: &'a [i64], field_times: &[i64]) -> Result<Self> {
        if times.windows(2).any(|w| w[1] <= w[0]) {
            return Err(Error::parameter(
                "triggers",
                "trigger times must be strictly ascending",
            ));
        }
        let (Some(&first), Some(&last)) = (times.first(), times.last()) else {
            return Err(Error::parameter(
                "triggers",
                "no trigger edge of the chosen polarity in the recording",
            ));
        };
        if times.len() < 2 {
            return Err(Error::parameter(
                "triggers",
                format!("one trigger edge (at {first} us): a phase needs two"),
            ));
        }
        let inside = |t: i64| t >= first && t < last;
        let outside = field_times.iter().filter(|&&t| !inside(t)).count();
        if outside == field_times.len() {
            let (lo, hi) = (
                field_times.iter().min().copied().unwrap_or(0),
                field_times.iter().max().copied().unwrap_or(0),
            );
            return Err(Error::parameter(
                "triggers",
                format!(
                    "no field time lies between the first and the last trigger: fields at \
                     {lo}..{hi} us, triggers at {first}..{last} us. The field times and the \
                     triggers are not on one clock (fields of another recording?)"
                ),
            ));
        }
        Ok(TriggerPhases { times, outside })
    }

    /// The phase bin of a field at `t` among `phases` bins, `None` outside the span.
    pub fn bin(&self, t: i64, phases: usize) -> Option<usize> {
        let k = self.times.partition_point(|&x| x <= t);
        if k == 0 || k >= self.times.len() {
            return None;
        }
        let (a, b) = (self.times[k - 1], self.times[k]);
        let fraction = (t - a) as f64 / (b - a) as f64;
        Some(((fraction * phases as f64) as usize).min(phases - 1))
    }

    /// What was used.
    pub fn summary(&self) -> TriggerSummary {
        let (first, last) = (self.times[0], self.times[self.times.len() - 1]);
        TriggerSummary {
            triggers: self.times.len(),
            span_us: (first, last),
            mean_interval_us: (last - first) as f64 / (self.times.len() - 1) as f64,
            fields_outside: self.outside,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_placed_between_the_triggers_around_them() {
        // Triggers at uneven intervals: the phase is a fraction of each one's own interval.
        let times = [1000, 2000, 4000];
        let fields = [500, 1000, 1499, 1500, 2999, 3000, 3999, 4000, 5000];
        let tp = TriggerPhases::new(&times, &fields).unwrap();
        let bins: Vec<Option<usize>> = fields.iter().map(|&t| tp.bin(t, 4)).collect();
        assert_eq!(
            bins,
            vec![
                None,
                Some(0),
                Some(1),
                Some(2),
                Some(1),
                Some(2),
                Some(3),
                None,
                None
            ]
        );
        assert_eq!(tp.outside, 3);
        let s = tp.summary();
        assert_eq!(
            (s.triggers, s.span_us, s.mean_interval_us),
            (3, (1000, 4000), 1500.0)
        );
    }

    #[test]
    fn unmatched_clocks_and_too_few_triggers_are_refused() {
        let e = TriggerPhases::new(&[1000, 2000], &[5_000_000, 6_000_000])
            .err()
            .unwrap();
        assert!(e.to_string().contains("one clock"), "{e}");
        assert!(TriggerPhases::new(&[1000], &[1500]).is_err());
        assert!(TriggerPhases::new(&[], &[1500]).is_err());
        assert!(TriggerPhases::new(&[2000, 1000], &[1500]).is_err());
        let times = TriggerTimes {
            times_us: vec![1000, 2000],
            first_event_us: Some(900),
            all_edges: 2,
        };
        let mut series = FieldSeries::new(vec![0.0], vec![0.0], vec![1500]);
        series.time_origin_us = Some(900);
        assert!(times.check_time_base(&series).is_ok());
        series.time_origin_us = Some(0); // --absolute-time: times given on the camera clock
        assert!(times.check_time_base(&series).is_ok());
        series.time_origin_us = Some(800);
        let e = times.check_time_base(&series).unwrap_err();
        assert!(e.to_string().contains("900"), "{e}");
        series.time_basis = crate::field::TimeBasis::PairIndex;
        assert!(times.check_time_base(&series).is_err());
    }
}
