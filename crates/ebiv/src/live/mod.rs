//! Live EBIV: velocity fields computed while the camera records.
//!
//! A live run reads a recording that is still being written ([`input::GrowingFile`]), a
//! stream on standard input ([`input::PipeInput`]), or a finished recording replayed at its
//! own rate; it computes a field every `step` exactly as `ebiv process` does (the same
//! settings, field times and slabs), and hands each field to a [`LiveSink`] as soon as it is
//! ready.
//!
//! Two threads form the pipeline: one decodes, paces a replay and cuts the stream into
//! slabs ([`crate::volume::Slab`]); the other evaluates them (its windows in parallel) and
//! passes the fields on. Between them a queue of at most `queue` slabs bounds memory and
//! latency. When the estimator falls behind a live input, the oldest waiting slab is dropped
//! whole to make room for the newest (never some of a slab's events), and the next field
//! delivered says how many were dropped before it; a finished recording read as fast as
//! possible waits for room instead.
//!
//! Latency is the time from a slab's end (replay: the moment the replay clock passes it;
//! otherwise: when its last event was read) to its field being ready.

pub mod input;
mod pipeline;
mod queue;

pub use input::{GrowingFile, PipeInput, StopCheck};
pub use pipeline::run_live;

use crate::event::{EventBuffer, Geometry};
use crate::field::{Calibration, FieldSeries, VectorField};
use crate::io::{DecodeReport, ReadOptions};
use std::path::PathBuf;
use std::time::Duration;

/// Where a live run's events come from.
#[derive(Debug, Clone, PartialEq)]
pub enum LiveInput {
    /// A finished recording, read as fast as the fields are computed (no field dropped).
    File(PathBuf),
    /// A recording still being written: read as it grows, until it has not grown for `idle`.
    Follow {
        /// The recording.
        path: PathBuf,
        /// How long the file may stay the same size before the run ends.
        idle: Duration,
    },
    /// A stream on standard input (a RAW file, or any format that needs no seeking).
    Stdin,
    /// A finished recording played at `speed` times its own rate.
    Replay {
        /// The recording.
        path: PathBuf,
        /// Replay speed (1: as recorded).
        speed: f64,
    },
}

impl LiveInput {
    /// The input's name in messages and the output's `source` attribute.
    pub fn name(&self) -> String {
        match self {
            LiveInput::File(path)
            | LiveInput::Follow { path, .. }
            | LiveInput::Replay { path, .. } => path.display().to_string(),
            LiveInput::Stdin => "standard input".into(),
        }
    }

    /// The input a command asks for: `source` (`-` for standard input), followed as it
    /// grows (`follow`, ending after `idle`, e.g. `5s`, without growth), replayed at `speed`
    /// (`replay`), or else read as fast as the fields are computed. Errors name the option.
    pub fn choose(
        source: &std::path::Path,
        follow: bool,
        replay: bool,
        speed: f64,
        idle: &str,
    ) -> crate::Result<LiveInput> {
        use crate::Error;
        let stdin = source.as_os_str() == "-";
        if follow && replay {
            return Err(Error::parameter(
                "follow",
                "follow or replay: give one, not both (--follow, --replay)",
            ));
        }
        if stdin && (follow || replay) {
            return Err(Error::parameter(
                "input",
                "standard input (-) is read as it comes; --follow and --replay take a file",
            ));
        }
        if !(speed.is_finite() && speed > 0.0) {
            return Err(Error::parameter(
                "speed",
                format!("must be a positive number, got {speed}"),
            ));
        }
        let idle = crate::units::parse_us(idle)
            .ok()
            .and_then(|us| u64::try_from(us).ok())
            .filter(|&us| us > 0)
            .map(Duration::from_micros)
            .ok_or_else(|| {
                Error::parameter(
                    "idle",
                    format!("a positive duration such as 5s, got `{idle}`"),
                )
            })?;
        let path = source.to_path_buf();
        Ok(if stdin {
            LiveInput::Stdin
        } else if follow {
            LiveInput::Follow { path, idle }
        } else if replay {
            LiveInput::Replay { path, speed }
        } else {
            LiveInput::File(path)
        })
    }

    /// Whether fields are dropped when the estimator falls behind (a live input cannot wait).
    pub fn drops_when_behind(&self) -> bool {
        !matches!(self, LiveInput::File(_))
    }
}

/// Default number of slabs that may wait for the estimator.
pub const DEFAULT_QUEUE: usize = 2;

/// How a live run reads and queues.
#[derive(Clone)]
pub struct LiveOptions {
    /// The input.
    pub input: LiveInput,
    /// How to read it (format, sensor size; small batches keep latency low).
    pub read: ReadOptions,
    /// Slabs that may wait for the estimator (at least 1).
    pub queue: usize,
    /// Time between fields, µs; `None`: the STEP of the run's `time`, else one per slab.
    pub every_us: Option<i64>,
    /// Least wall-clock time between two fields that carry their slab's events (for a live
    /// view); `None`: no field carries them.
    pub events_every: Option<Duration>,
}

impl LiveOptions {
    /// Options for `input` with batches of 64 KiB (about a millisecond of a fast camera).
    pub fn new(input: LiveInput) -> Self {
        LiveOptions {
            input,
            read: ReadOptions {
                batch_bytes: 1 << 16,
                ..ReadOptions::default()
            },
            queue: DEFAULT_QUEUE,
            every_us: None,
            events_every: None,
        }
    }
}

impl LiveOptions {
    /// Read with `read` (format, sensor size, text columns), in the live run's small batches.
    pub fn set_read_options(&mut self, read: ReadOptions) {
        self.read = ReadOptions {
            batch_bytes: self.read.batch_bytes,
            ..read
        };
    }
}

/// What a live run tells its sink before the first field.
#[derive(Debug, Clone)]
pub struct LiveStart {
    /// The input's name.
    pub source: String,
    /// Sensor size.
    pub geometry: Geometry,
    /// Window centres of the output grid, px.
    pub x: Vec<f64>,
    /// Window centres of the output grid, px.
    pub y: Vec<f64>,
    /// The run's settings as output attributes (as `ebiv process` writes them).
    pub attributes: Vec<(String, String)>,
    /// The camera time that relative times count from (the first event, or 0).
    pub time_origin_us: i64,
    /// Positions in mm and velocities in m/s in the outputs.
    pub calibration: Option<Calibration>,
    /// Quantities derived from the velocity gradient of each field.
    pub derive: Vec<crate::derived::DerivedQuantity>,
    /// Time between fields, µs.
    pub step_us: i64,
    /// One line: input, field times, method, sensor, passes.
    pub description: String,
}

impl LiveStart {
    /// A series of `field` alone (at `t0_us`) on the run's grid, with the run's attributes,
    /// time origin and calibration: what the writers and figures take.
    pub fn series_of(&self, t0_us: i64, field: &VectorField) -> crate::Result<FieldSeries> {
        let mut series = FieldSeries::on_grid(self.x.clone(), self.y.clone());
        series.attributes = self.attributes.clone();
        series.time_origin_us = Some(self.time_origin_us);
        series.calibration = self.calibration;
        series.push(t0_us, field)?;
        crate::derived::add_derived(&mut series, &self.derive)?;
        Ok(series)
    }
}

/// Counts and rates of a live run so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LiveStats {
    /// Events read.
    pub events: u64,
    /// Fields computed.
    pub fields: u64,
    /// Fields dropped because the estimator was behind.
    pub dropped: u64,
    /// Events read per second of wall-clock time, over about the last second.
    pub event_rate: f64,
    /// Fields computed per second of wall-clock time, over about the last second.
    pub field_rate: f64,
    /// This field's latency, ms.
    pub latency_ms: f64,
    /// 99th percentile of the latency over the last 1000 fields, ms.
    pub latency_p99_ms: f64,
    /// Wall-clock time since the first event, s.
    pub elapsed_s: f64,
}

/// A field as it becomes ready.
pub struct LiveField<'a> {
    /// Centre time of the field's slab, µs of camera time.
    pub t0_us: i64,
    /// The field (last pass, validated).
    pub field: &'a VectorField,
    /// Fields dropped since the previous field delivered (or since the start).
    pub dropped_before: u64,
    /// The slab's events, when the run was asked for them and this field's turn has come
    /// ([`LiveOptions::events_every`]).
    pub events: Option<&'a EventBuffer>,
    /// The slab's interval, µs: `[t0 − before, t0 + after)`.
    pub interval_us: (i64, i64),
    /// The run so far, this field included.
    pub stats: LiveStats,
}

/// Receives a live run's fields. An error ends the run (and is returned by [`run_live`]).
pub trait LiveSink {
    /// Before the first field.
    fn started(&mut self, start: &LiveStart) -> crate::Result<()>;
    /// A field is ready.
    fn field(&mut self, field: &LiveField) -> crate::Result<()>;
}

/// What a live run did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct LiveSummary {
    /// Final counts and rates; `event_rate` and `field_rate` over the whole run.
    pub stats: LiveStats,
    /// Median latency, ms.
    pub latency_p50_ms: f64,
    /// 99th percentile of the latency, ms.
    pub latency_p99_ms: f64,
    /// Largest latency, ms.
    pub latency_max_ms: f64,
    /// Fields whose slab held no event of the selected polarity.
    pub empty_fields: u64,
    /// Events of lone hot pixels left out of the fields' slabs, summed over fields
    /// ([`crate::volume::Slab::drop_lone_pixels`]).
    pub lone_pixel_events: u64,
    /// What the reader dropped or skipped.
    #[serde(skip)]
    pub report: DecodeReport,
    /// Whether the run ended on a stop request (Ctrl-C) rather than at the end of its input.
    pub stopped: bool,
}
