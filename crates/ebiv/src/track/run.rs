//! Tracking a whole recording: read the events of an interval, track them, and hand each
//! track to the caller as it ends — the one run shared by `ebiv track` and Python's
//! `ebiv.track`.

use super::{Track, TrackParams, TrackSummary, Tracker};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use crate::io::EventSource;

/// The interval tracked: `[start, end)` µs from the first event (or camera time with
/// `absolute_time`); `None` ends are the recording's.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrackInterval {
    /// Start, µs.
    pub start: Option<i64>,
    /// End, µs.
    pub end: Option<i64>,
    /// The ends are camera time stamps rather than times from the first event.
    pub absolute_time: bool,
}

/// What a run did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackRun {
    /// Counts.
    pub summary: TrackSummary,
    /// Sensor size.
    pub geometry: Geometry,
    /// Camera time of the first event of the recording, µs.
    pub first_event_us: i64,
    /// Camera time of the first and last event tracked, µs.
    pub span_us: (i64, i64),
}

/// The attributes of a track file: the source, the method, the sensor size and every
/// setting of `params` as `run` used them (the slab it chose, when automatic, with
/// `slab_choice = auto`).
pub fn track_attributes(
    source: &str,
    params: &TrackParams,
    run: &TrackRun,
) -> Vec<(String, String)> {
    let geometry = run.geometry;
    let mut attributes = vec![
        ("source".to_string(), source.to_string()),
        ("method".to_string(), "particle tracking".to_string()),
        ("sensor_width".to_string(), geometry.width.to_string()),
        ("sensor_height".to_string(), geometry.height.to_string()),
    ];
    let mut used = params.clone();
    if params.slab_us == 0 && run.summary.slab_us > 0 {
        used.slab_us = run.summary.slab_us;
        attributes.push(("slab_choice".to_string(), "auto".to_string()));
    }
    attributes.extend(used.describe());
    attributes
}

/// The sensor size of `source`: stated by it, else from the largest coordinates (one pass).
pub fn source_geometry(source: &EventSource) -> Result<Geometry> {
    let mut reader = source.open()?;
    if let Some(g) = reader.metadata().geometry {
        return Ok(g);
    }
    let mut batch = EventBuffer::new();
    let (mut w, mut h, mut any) = (0u32, 0u32, false);
    while reader.read_batch(&mut batch)? {
        for i in 0..batch.len() {
            w = w.max(batch.x[i] as u32 + 1);
            h = h.max(batch.y[i] as u32 + 1);
            any = true;
        }
    }
    if !any {
        return Err(Error::empty(source.name(), "the recording holds no events"));
    }
    Ok(Geometry {
        width: w,
        height: h,
    })
}

/// Track the events of `interval` in `source`. `sink` receives every track as it ends (an
/// error from it stops the run); `progress` is called after every batch with the bytes of
/// the file read so far (`None` for events in memory) and may stop the run by an error.
pub fn track_source(
    source: &EventSource,
    params: &TrackParams,
    interval: TrackInterval,
    sink: &mut dyn FnMut(Track) -> Result<()>,
    progress: &mut dyn FnMut(Option<u64>) -> Result<()>,
) -> Result<TrackRun> {
    params.validate()?;
    let geometry = source_geometry(source)?;
    let first_event_us = source
        .first_event_time()?
        .ok_or_else(|| Error::empty(source.name(), "the recording holds no events"))?;
    let origin = if interval.absolute_time {
        0
    } else {
        first_event_us
    };
    let start = interval
        .start
        .map_or(i64::MIN, |s| s.saturating_add(origin));
    let end = interval.end.map_or(i64::MAX, |e| e.saturating_add(origin));
    if start >= end {
        return Err(Error::parameter(
            "time",
            "the interval's end is not after its start",
        ));
    }
    let mut reader = source.open()?;
    if start > first_event_us {
        reader.skip_to(start)?;
    }
    let mut tracker = Tracker::new(geometry, params.clone())?;
    let mut failure: Option<Error> = None;
    let mut pass_on = |track: Track, failure: &mut Option<Error>| {
        if failure.is_none() {
            if let Err(e) = sink(track) {
                *failure = Some(e);
            }
        }
    };
    let mut batch = EventBuffer::new();
    let mut selected = EventBuffer::new();
    let mut span: Option<(i64, i64)> = None;
    while reader.read_batch(&mut batch)? {
        // Time stamps run forward: a batch that starts at the end is beyond the interval.
        if batch.t.first().is_some_and(|&t| t >= end) {
            break;
        }
        selected.clear();
        for i in 0..batch.len() {
            let t = batch.t[i];
            if t >= start && t < end {
                selected.push(t, batch.x[i], batch.y[i], batch.p[i]);
                span = Some(span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            }
        }
        tracker.push(&selected, &mut |t| pass_on(t, &mut failure));
        if let Some(e) = failure.take() {
            return Err(e);
        }
        progress(reader.position())?;
    }
    let summary = tracker.finish(&mut |t| pass_on(t, &mut failure));
    if let Some(e) = failure {
        return Err(e);
    }
    let span_us =
        span.ok_or_else(|| Error::empty(source.name(), "no events in the interval tracked"))?;
    Ok(TrackRun {
        summary,
        geometry,
        first_event_us,
        span_us,
    })
}
