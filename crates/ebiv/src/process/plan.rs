//! Planning a run over a recording: where it begins, how large its sensor is, and which
//! field times fit into it.

use super::stream::{scan_extent, RecordingExtent};
use super::times::{FieldTimes, TimeSteps};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry, PolaritySelection};
use crate::io::{EventReader, EventSource, ReadOptions};
use std::path::Path;

/// Most field times one run may ask for.
pub const MAX_FIELDS: usize = 1_000_000;

/// Time stamp of the first event of `path` in file order (the origin of every command's
/// relative times), decoding only as far as that event; `None` for a file without events.
pub fn first_event_time(path: &Path, options: &ReadOptions) -> Result<Option<i64>> {
    EventSource::file(path, options).first_event_time()
}

/// A recording opened for a run, with its sensor size and the field times to evaluate.
pub struct PlannedFields {
    /// The recording, positioned at its start.
    pub reader: EventReader,
    /// The sensor size (from the header, else the largest coordinates seen).
    pub geometry: Geometry,
    /// Field centre times, µs, ascending (camera time, as the recording stores it).
    pub times: Vec<i64>,
    /// The camera time, µs, that `time` counts from: the first event in file order, or 0
    /// with `absolute_time` (for [`FieldSeries::time_origin_us`](crate::field::FieldSeries)).
    pub time_origin_us: i64,
}

impl PlannedFields {
    /// "3 field(s) at 10.000 ms to 20.000 ms after the first event (camera time 1310000 µs
    /// to …)": the field times as `--time` counts them, and as the output files store them.
    pub fn describe_times(&self) -> String {
        let (first, last) = (self.times[0], self.times[self.times.len() - 1]);
        let relative = |t: i64| crate::units::format_us(t - self.time_origin_us);
        if self.time_origin_us == 0 {
            format!(
                "{} field(s) at camera times {first} to {last} µs",
                self.times.len()
            )
        } else {
            format!(
                "{} field(s) from {} to {} after the first event (camera time {first} to {last} µs)",
                self.times.len(),
                relative(first),
                relative(last)
            )
        }
    }
}

/// Open `source` and resolve its field times: `time` (relative to the first event unless
/// `absolute_time`), or every field that fits, given that a field needs `before` µs of
/// events before its centre and `after` µs after it, one every `default_step` µs. The whole
/// recording is read only for what its header does not say: the sensor size, or where the
/// fields that fit begin and end.
pub fn plan_fields(
    source: &EventSource,
    time: Option<FieldTimes>,
    absolute_time: bool,
    (before, after): (i64, i64),
    default_step: i64,
) -> Result<PlannedFields> {
    let reader = source.open()?;
    let header_geometry = reader.metadata().geometry;
    let no_events = || Error::empty(source.name(), "the file holds no events");
    let (start, end) = (time.and_then(|t| t.start), time.and_then(|t| t.end));
    let scanned = header_geometry.is_none() || start.is_none() || end.is_none();
    let extent = if scanned {
        let mut scan = source.open_raw()?;
        scan_extent(&mut scan)?.ok_or_else(no_events)?
    } else {
        let first_us = if absolute_time {
            0
        } else {
            source.first_event_time()?.ok_or_else(no_events)?
        };
        RecordingExtent {
            first_in_file_us: first_us,
            first_us,
            last_us: first_us,
            max_x: 0,
            max_y: 0,
            events: 0,
        }
    };
    let too_short = || {
        Error::empty(
            source.name(),
            format!(
                "the recording ({}) is shorter than the time one field needs ({}: the slab, and for corrsum the delay tau); use a shorter --slab (piv: --frame-step, --exposure, --pairs)",
                crate::units::format_us(extent.last_us + 1 - extent.first_us),
                crate::units::format_us(before + after)
            ),
        )
    };
    let geometry = header_geometry
        .unwrap_or_else(|| Geometry::new(extent.max_x as u32 + 1, extent.max_y as u32 + 1));
    let origin = if absolute_time {
        0
    } else {
        extent.first_in_file_us
    };
    let step = time.map_or(default_step, |t| t.step);
    let fitting = TimeSteps::fitting(extent.first_us, extent.last_us, before, after, step);
    let shift = |t: i64| {
        origin.checked_add(t).ok_or_else(|| {
            Error::parameter("time", format!("{t} µs is beyond the range of time stamps"))
        })
    };
    let (start, end) = (start.map(shift).transpose()?, end.map(shift).transpose()?);
    let steps = match (start, end, fitting) {
        (Some(a), Some(b), _) => TimeSteps {
            start: a,
            end: b,
            step,
        },
        (a, b, Some(f)) => TimeSteps {
            start: a.unwrap_or(f.start),
            end: b.unwrap_or(f.end),
            step,
        },
        _ => return Err(too_short()),
    };
    Ok(PlannedFields {
        reader,
        geometry,
        times: steps.times(MAX_FIELDS)?,
        time_origin_us: origin,
    })
}

/// The camera-time interval of a recording to cover, and its sensor size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Coverage {
    /// Time of the first event in file order, µs.
    pub first_event_us: i64,
    /// Start of the interval, µs.
    pub start_us: i64,
    /// End of the interval (exclusive), µs: the requested end, or one past the last event
    /// when the recording ends earlier.
    pub end_us: i64,
    /// The requested end, when the recording ends before it (the interval was shortened to
    /// the recording).
    pub requested_end_us: Option<i64>,
    /// Events of the selected polarity in `[start_us, end_us)`.
    pub events: u64,
    /// The sensor size.
    pub geometry: Geometry,
    /// Whether the size came from the largest coordinates seen, the file not stating it.
    pub geometry_from_events: bool,
}

/// The interval `[start, end)` of `path` that `range` selects (relative to the first event
/// unless `absolute_time`; a missing end, or one beyond the recording, is one past the last
/// event), the sensor size, and how many events of `polarity` it holds. The file is read up
/// to the end of the interval, and to its own end only when the interval runs to the end or
/// the file does not state its sensor size.
///
/// An interval that starts after the recording, or that holds no event of `polarity`, is an
/// error ([`Error::Empty`]) naming the recording's span: whatever the caller would write
/// from it would be blank.
pub fn coverage(
    path: &Path,
    options: &ReadOptions,
    range: (Option<i64>, Option<i64>),
    absolute_time: bool,
    polarity: PolaritySelection,
) -> Result<Coverage> {
    let mut reader = crate::io::open(path, &options.without_denoise())?;
    let geometry = reader.metadata().geometry;
    let geometry_from_events = geometry.is_none();
    let mut batch = EventBuffer::new();
    let (mut first, mut last, mut max_x, mut max_y) = (None::<i64>, i64::MIN, 0u16, 0u16);
    let (mut start_us, mut end_us, mut events) = (None::<i64>, None::<i64>, 0u64);
    while reader.read_batch(&mut batch)? {
        let Some(&t_first) = batch.t.first() else {
            continue;
        };
        let first = *first.get_or_insert(t_first);
        let origin = if absolute_time { 0 } else { first };
        let start = *start_us.get_or_insert(range.0.map_or(first, |s| s.saturating_add(origin)));
        let end = *end_us.get_or_insert(range.1.map_or(i64::MAX, |e| e.saturating_add(origin)));
        for i in 0..batch.len() {
            let t = batch.t[i];
            last = last.max(t);
            max_x = max_x.max(batch.x[i]);
            max_y = max_y.max(batch.y[i]);
            events += u64::from(t >= start && t < end && polarity.accepts(batch.p[i]));
        }
        if geometry.is_some() && last >= end {
            break; // the recording reaches the end of the interval
        }
    }
    let no_events = || Error::empty(path.display().to_string(), "the file holds no events");
    let first_event_us = first.ok_or_else(no_events)?;
    let (start_us, requested) = (
        start_us.ok_or_else(no_events)?,
        end_us.ok_or_else(no_events)?,
    );
    let geometry = geometry.unwrap_or_else(|| Geometry::new(max_x as u32 + 1, max_y as u32 + 1));
    let recording_end = last.saturating_add(1);
    let end_us = requested.min(recording_end);
    let span = || {
        let origin = if absolute_time { 0 } else { first_event_us };
        format!(
            "the recording spans {} to {}{}",
            crate::units::format_us(first_event_us - origin),
            crate::units::format_us(recording_end - origin),
            if absolute_time {
                " in camera time"
            } else {
                " from its first event"
            }
        )
    };
    if requested <= start_us {
        return Err(Error::parameter(
            "time",
            format!(
                "nothing to do: the interval ends before it starts ({})",
                span()
            ),
        ));
    }
    if start_us >= recording_end {
        return Err(Error::empty(
            path.display().to_string(),
            format!("--time starts after the last event: {}", span()),
        ));
    }
    if events == 0 {
        return Err(Error::empty(
            path.display().to_string(),
            format!(
                "no event of polarity `{}` in the interval ({}); check --time and --polarity",
                polarity.name(),
                span()
            ),
        ));
    }
    Ok(Coverage {
        first_event_us,
        start_us,
        end_us,
        requested_end_us: (end_us < requested && range.1.is_some()).then_some(requested),
        events,
        geometry,
        geometry_from_events,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A CSV recording of ON events at 0, 1000, …, 9000 µs (one per ms, x = y = k), with or
    /// without a stated sensor size.
    fn recording(dir: &Path, geometry: bool) -> std::path::PathBuf {
        let mut text = String::from("t,x,y,p\n");
        if geometry {
            text.push_str("# geometry: 32x32\n");
        }
        for k in 0..10 {
            text.push_str(&format!("{},{k},{k},1\n", 1_000_000 + k * 1000));
        }
        let path = dir.join(if geometry { "g.csv" } else { "n.csv" });
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn coverage_ends_at_the_recording_and_refuses_empty_intervals() {
        let dir = tempfile::tempdir().unwrap();
        for geometry in [true, false] {
            let path = recording(dir.path(), geometry);
            let o = ReadOptions::default();
            let on = PolaritySelection::Positive;
            let c = coverage(&path, &o, (Some(2000), Some(50_000)), false, on).unwrap();
            assert_eq!((c.start_us, c.end_us), (1_002_000, 1_009_001));
            assert_eq!(c.requested_end_us, Some(1_050_000));
            assert_eq!(c.events, 8);
            let c = coverage(&path, &o, (None, Some(3000)), false, on).unwrap();
            assert_eq!(
                (c.end_us, c.requested_end_us, c.events),
                (1_003_000, None, 3)
            );
            let late = coverage(&path, &o, (Some(20_000), None), false, on).unwrap_err();
            assert!(matches!(late, Error::Empty { .. }), "{late}");
            assert!(
                late.to_string().contains("starts after the last event"),
                "{late}"
            );
            let off = coverage(&path, &o, (None, None), false, PolaritySelection::Negative);
            let off = off.unwrap_err().to_string();
            assert!(off.contains("no event of polarity `neg`"), "{off}");
        }
    }

    #[test]
    fn a_slab_longer_than_the_recording_is_refused_whether_or_not_the_size_is_stated() {
        let dir = tempfile::tempdir().unwrap();
        for geometry in [true, false] {
            let path = recording(dir.path(), geometry);
            let o = ReadOptions::default();
            let err = plan_fields(
                &EventSource::file(&path, &o),
                None,
                false,
                (6000, 6000),
                12_000,
            )
            .err()
            .unwrap()
            .to_string();
            assert!(
                err.contains("shorter than the time one field needs"),
                "{err}"
            );
            let planned = plan_fields(
                &EventSource::file(&path, &o),
                None,
                false,
                (2000, 2000),
                4000,
            )
            .unwrap();
            assert_eq!(planned.times, [1_002_000, 1_006_000]);
            assert_eq!(planned.time_origin_us, 1_000_000);
            let text = planned.describe_times();
            assert!(
                text.starts_with("2 field(s) from 2.000 ms to 6.000 ms"),
                "{text}"
            );
            assert!(text.contains("camera time 1002000 to 1006000 µs"), "{text}");
        }
    }
}
