//! Planning a run over a recording: where it begins, how large its sensor is, and which
//! field times fit into it.

use super::stream::{scan_extent, RecordingExtent};
use super::times::{FieldTimes, TimeSteps};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use crate::io::{EventReader, ReadOptions};
use std::path::Path;

/// Most field times one run may ask for.
pub const MAX_FIELDS: usize = 1_000_000;

/// Time stamp of the first event of `path` in file order (the origin of every command's
/// relative times), decoding only as far as that event; `None` for a file without events.
pub fn first_event_time(path: &Path, options: &ReadOptions) -> Result<Option<i64>> {
    let mut reader = crate::io::open(path, options)?;
    let mut batch = EventBuffer::new();
    while reader.read_batch(&mut batch)? {
        if let Some(&t) = batch.t.first() {
            return Ok(Some(t));
        }
    }
    Ok(None)
}

/// A recording opened for a run, with its sensor size and the field times to evaluate.
pub struct PlannedFields {
    /// The recording, positioned at its start.
    pub reader: EventReader,
    /// The sensor size (from the header, else the largest coordinates seen).
    pub geometry: Geometry,
    /// Field centre times, µs, ascending.
    pub times: Vec<i64>,
    /// The camera time, µs, that `time` counts from: the first event in file order, or 0
    /// with `absolute_time` (for [`FieldSeries::time_origin_us`](crate::field::FieldSeries)).
    pub time_origin_us: i64,
}

/// Open `path` and resolve its field times: `time` (relative to the first event unless
/// `absolute_time`), or every field that fits, given that a field needs `before` µs of
/// events before its centre and `after` µs after it, one every `default_step` µs. The whole
/// recording is read only for what its header does not say: the sensor size, or where the
/// fields that fit begin and end.
pub fn plan_fields(
    path: &Path,
    options: &ReadOptions,
    time: Option<FieldTimes>,
    absolute_time: bool,
    (before, after): (i64, i64),
    default_step: i64,
) -> Result<PlannedFields> {
    let reader = crate::io::open(path, options)?;
    let header_geometry = reader.metadata().geometry;
    let no_events = || Error::parameter("input", format!("{} holds no events", path.display()));
    let (start, end) = (time.and_then(|t| t.start), time.and_then(|t| t.end));
    let extent = if header_geometry.is_none() || start.is_none() || end.is_none() {
        let mut scan = crate::io::open(path, options)?;
        scan_extent(&mut scan)?.ok_or_else(no_events)?
    } else {
        let first_us = if absolute_time {
            0
        } else {
            first_event_time(path, options)?.ok_or_else(no_events)?
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
    let geometry = header_geometry
        .unwrap_or_else(|| Geometry::new(extent.max_x as u32 + 1, extent.max_y as u32 + 1));
    let origin = if absolute_time {
        0
    } else {
        extent.first_in_file_us
    };
    let step = time.map_or(default_step, |t| t.step);
    let fitting = TimeSteps::fitting(extent.first_us, extent.last_us, before, after, step);
    let (start, end) = (start.map(|t| origin + t), end.map(|t| origin + t));
    let steps = match (start, end, fitting) {
        (Some(a), Some(b), _) => TimeSteps { start: a, end: b, step },
        (a, b, Some(f)) => TimeSteps {
            start: a.unwrap_or(f.start),
            end: b.unwrap_or(f.end),
            step,
        },
        _ => {
            return Err(Error::parameter(
                "time",
                format!(
                    "the recording ({} ms) is shorter than one field needs ({} ms); use a shorter --slab (piv: --frame-step, --exposure, --pairs)",
                    (extent.last_us - extent.first_us) / 1000,
                    (before + after) / 1000
                ),
            ))
        }
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
    /// End of the interval (exclusive), µs.
    pub end_us: i64,
    /// The sensor size.
    pub geometry: Geometry,
    /// Whether the size came from the largest coordinates seen, the file not stating it.
    pub geometry_from_events: bool,
}

/// The interval `[start, end)` of `path` that `range` selects (relative to the first event
/// unless `absolute_time`; a missing end is the last event), and the sensor size. The whole
/// file is read only when the end or the size is not known otherwise.
pub fn coverage(
    path: &Path,
    options: &ReadOptions,
    range: (Option<i64>, Option<i64>),
    absolute_time: bool,
) -> Result<Coverage> {
    let first_event_us = first_event_time(path, options)?
        .ok_or_else(|| Error::parameter("input", format!("{} holds no events", path.display())))?;
    let origin = if absolute_time { 0 } else { first_event_us };
    let start_us = range.0.map_or(first_event_us, |s| s + origin);
    let mut end_us = range.1.map(|e| e + origin);
    let mut geometry = crate::io::open(path, options)?.metadata().geometry;
    let geometry_from_events = geometry.is_none();
    if end_us.is_none() || geometry.is_none() {
        let mut scan = crate::io::open(path, options)?;
        if let Some(extent) = scan_extent(&mut scan)? {
            end_us = end_us.or(Some(extent.last_us.saturating_add(1)));
            geometry = geometry.or(Some(Geometry::new(
                extent.max_x as u32 + 1,
                extent.max_y as u32 + 1,
            )));
        }
    }
    let end_us = end_us.unwrap_or(start_us);
    if end_us <= start_us {
        return Err(Error::parameter(
            "time",
            format!(
                "nothing to do: the interval ends ({end_us} µs) before it starts ({start_us} µs)"
            ),
        ));
    }
    Ok(Coverage {
        first_event_us,
        start_us,
        end_us,
        geometry: geometry.unwrap_or(Geometry::new(1, 1)),
        geometry_from_events,
    })
}
