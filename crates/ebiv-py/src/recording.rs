//! `ebiv.open`: a recording on disk, its metadata, and its events as NumPy arrays, read
//! whole between two times or in chunks by time or count.

use crate::convert::{apply_keywords, events_to_py};
use crate::errors::IntoPy;
use crate::observe::{watched, Watch};
use ebiv::io::{EventReader, ReadOptions};
use ebiv::settings::ProcessSettings;
use ebiv::EventBuffer;
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::PathBuf;
use std::sync::Mutex;

/// Open the event recording at `path` (any format `ebiv info` reads: RAW EVT 2.0/2.1/3.0,
/// DAT, AEDAT 2/3.1/4, Event Stream, CSV/text, NumPy, EBIV .evt). Reader options as
/// keywords: `geometry=(1280, 720)`, `format="evt3"`, `raw_encoding`, `metavision_time`,
/// `columns`, `time_unit`, `delimiter`, `polarity_values`.
#[pyfunction]
#[pyo3(signature = (path, **reader_options))]
pub fn open(path: PathBuf, reader_options: Option<&Bound<'_, PyDict>>) -> PyResult<Recording> {
    let options = read_options(reader_options)?;
    let reader = ebiv::io::open(&path, &options).py_err()?;
    Ok(Recording {
        metadata: reader.metadata().clone(),
        path,
        options,
        scan: Mutex::new(None),
    })
}

/// The index of the recording at `path` (RAW EVT 2.0, 2.1, 3.0): built and stored when
/// missing or stale (or with `force=True`), as `ebiv index` does. Returns where it is
/// stored, or `None` for formats without an index.
#[pyfunction]
#[pyo3(signature = (path, force=false, **reader_options))]
pub fn index(
    py: Python<'_>,
    path: PathBuf,
    force: bool,
    reader_options: Option<&Bound<'_, PyDict>>,
) -> PyResult<Option<PathBuf>> {
    let options = read_options(reader_options)?;
    watched(py, None, |_| {
        if !ebiv::io::index::indexable(&path, &options)? {
            return Ok(None);
        }
        Ok(Some(
            ebiv::io::index::ensure_index(&path, &options, force)?.file,
        ))
    })
}

/// Reader options from keywords, any other keyword a `ValueError`.
pub(crate) fn read_options(keywords: Option<&Bound<'_, PyDict>>) -> PyResult<ReadOptions> {
    let mut options = ReadOptions::default();
    if let Some(keywords) = keywords {
        for key in keywords.keys() {
            let key = crate::convert::kebab(&key.extract::<String>()?);
            if !ebiv::io::READ_OPTIONS.contains(&key.as_str()) {
                return Err(PyValueError::new_err(format!(
                    "invalid parameter `{key}`: not a reader option; they are {}",
                    ebiv::io::READ_OPTIONS.join(", ")
                )));
            }
        }
    }
    apply_keywords(keywords, &mut ProcessSettings::default(), &mut options)?;
    Ok(options)
}

/// What one pass over the whole recording finds.
#[derive(Clone)]
struct Scan {
    range: Option<(i64, i64)>,
    triggers: Vec<ebiv::Trigger>,
    report: ebiv::io::DecodeReport,
}

/// An event recording opened by `ebiv.open`.
#[pyclass(module = "ebiv", frozen)]
pub struct Recording {
    path: PathBuf,
    options: ReadOptions,
    metadata: ebiv::io::Metadata,
    scan: Mutex<Option<Scan>>,
}

impl Recording {
    fn reader(&self) -> ebiv::Result<EventReader> {
        ebiv::io::open(&self.path, &self.options)
    }

    /// The whole-file scan, made once (with the GIL released, interruptible).
    fn scanned(&self, py: Python<'_>) -> PyResult<Scan> {
        if let Some(scan) = self.scan.lock().expect("scan lock").clone() {
            return Ok(scan);
        }
        let scan = watched(py, None, |watch| {
            let mut reader = self.reader()?;
            let mut batch = EventBuffer::new();
            let (mut lo, mut hi) = (i64::MAX, i64::MIN);
            let mut triggers = Vec::new();
            while reader.read_batch(&mut batch)? {
                watch.check()?;
                for &t in &batch.t {
                    lo = lo.min(t);
                    hi = hi.max(t);
                }
                triggers.extend_from_slice(&batch.triggers);
            }
            Ok(Scan {
                range: (lo <= hi).then_some((lo, hi)),
                triggers,
                report: reader.report(),
            })
        })?;
        *self.scan.lock().expect("scan lock") = Some(scan.clone());
        Ok(scan)
    }
}

#[pymethods]
impl Recording {
    /// The file's path.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// What the file says about itself: format, geometry, header entries (in file order),
    /// sensor, serial, the time shift applied (µs) and notes.
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.metadata;
        let d = PyDict::new(py);
        d.set_item("format", m.format.name())?;
        d.set_item("geometry", m.geometry.map(|g| (g.width, g.height)))?;
        d.set_item("header", m.header.clone())?;
        d.set_item("sensor", m.sensor.clone())?;
        d.set_item("serial", m.serial.clone())?;
        d.set_item("time_shift_us", m.time_shift_us)?;
        d.set_item("notes", m.notes.clone())?;
        Ok(d)
    }

    /// The sensor size `(width, height)` when the file states it, else `None`.
    #[getter]
    fn geometry(&self) -> Option<(u32, u32)> {
        self.metadata.geometry.map(|g| (g.width, g.height))
    }

    /// `(first, last)`: the earliest and latest event time stamps, µs of camera time;
    /// `None` without events. The first call reads the whole file.
    #[getter]
    fn time_range(&self, py: Python<'_>) -> PyResult<Option<(i64, i64)>> {
        Ok(self.scanned(py)?.range)
    }

    /// External trigger edges: a dict of arrays `t` (µs), `channel` and `value` (edge
    /// polarity). The first call reads the whole file.
    #[getter]
    fn triggers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let scan = self.scanned(py)?;
        let d = PyDict::new(py);
        let column =
            |f: fn(&ebiv::Trigger) -> i64| -> Vec<i64> { scan.triggers.iter().map(f).collect() };
        d.set_item("t", PyArray1::from_vec(py, column(|t| t.t)))?;
        let channel: Vec<u8> = scan.triggers.iter().map(|t| t.channel).collect();
        let value: Vec<u8> = scan.triggers.iter().map(|t| t.value).collect();
        d.set_item("channel", PyArray1::from_vec(py, channel))?;
        d.set_item("value", PyArray1::from_vec(py, value))?;
        Ok(d)
    }

    /// What the reader dropped or found odd over the whole file (counts and warnings), as
    /// `ebiv info` reports it. The first call reads the whole file.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let json = serde_json::to_string(&self.scanned(py)?.report)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        py.import("json")?.call_method1("loads", (json,))
    }

    /// The events with `t0 <= t < t1` (µs of camera time; `None`: from the start, to the
    /// end) as arrays `(t, x, y, p)`: int64 µs, uint16 px, uint16 px, uint8 0/1. Seeks by the
    /// file's index where the format has one. Reading stops at the first batch of events
    /// all at or after `t1`.
    #[pyo3(signature = (t0=None, t1=None))]
    fn read<'py>(
        &self,
        py: Python<'py>,
        t0: Option<&Bound<'py, PyAny>>,
        t1: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let t0 = t0.map(|t| duration_us("t0", t)).transpose()?;
        let t1 = t1.map(|t| duration_us("t1", t)).transpose()?;
        let events = watched(py, None, |watch| {
            let mut reader = self.reader()?;
            if let Some(t0) = t0 {
                reader.skip_to(t0)?;
            }
            if t0.is_none() && t1.is_none() {
                return read_rest(&mut reader, watch);
            }
            let (lo, hi) = (t0.unwrap_or(i64::MIN), t1.unwrap_or(i64::MAX));
            let mut out = EventBuffer::new();
            let mut batch = EventBuffer::new();
            while reader.read_batch(&mut batch)? {
                watch.check()?;
                let mut past = true;
                for i in 0..batch.len() {
                    let t = batch.t[i];
                    past &= t >= hi;
                    if t >= lo && t < hi {
                        out.push(t, batch.x[i], batch.y[i], batch.p[i]);
                    }
                }
                if past && !batch.is_empty() {
                    break;
                }
            }
            Ok(out)
        })?;
        Ok(events_to_py(py, events))
    }

    /// Iterate over the events in chunks of `duration` (µs, or a text such as "10ms"; windows
    /// aligned to the first event, those without events skipped) or of `count` events;
    /// neither: the reader's own batches. Each chunk is `(t, x, y, p)` as [`read`](Self::read) returns.
    #[pyo3(signature = (duration=None, count=None))]
    fn chunks(
        &self,
        duration: Option<&Bound<'_, PyAny>>,
        count: Option<usize>,
    ) -> PyResult<Chunks> {
        let split = match (duration, count) {
            (Some(_), Some(_)) => {
                return Err(PyValueError::new_err(
                    "invalid parameter `duration`: give a duration or a count, not both",
                ))
            }
            (Some(d), None) => {
                let d = duration_us("duration", d)?;
                if d <= 0 {
                    return Err(PyValueError::new_err(
                        "invalid parameter `duration`: must be positive",
                    ));
                }
                Split::Duration(d)
            }
            (None, Some(0)) => {
                return Err(PyValueError::new_err(
                    "invalid parameter `count`: must be at least 1",
                ))
            }
            (None, Some(n)) => Split::Count(n),
            (None, None) => Split::Batches,
        };
        Ok(Chunks {
            state: Mutex::new(ChunkState {
                reader: self.reader().py_err()?,
                split,
                pending: EventBuffer::new(),
                next_start: None,
                exhausted: false,
            }),
        })
    }

    fn __iter__(&self) -> PyResult<Chunks> {
        self.chunks(None, None)
    }

    fn __repr__(&self) -> String {
        let g = self
            .metadata
            .geometry
            .map_or("size unknown".to_string(), |g| g.to_string());
        format!(
            "<ebiv.Recording {} ({}, {g})>",
            self.path.display(),
            self.metadata.format.name()
        )
    }
}

/// A time in µs, from an integer or a text with units ("10ms", "1.5s"); the error names
/// the parameter `name`.
#[pyfunction]
#[pyo3(name = "duration_us")]
pub fn py_duration_us(name: &str, value: &Bound<'_, PyAny>) -> PyResult<i64> {
    duration_us(name, value)
}

/// A time in µs: an integer, or a text with units ("10ms", "1.5s").
pub fn duration_us(name: &str, value: &Bound<'_, PyAny>) -> PyResult<i64> {
    if let Ok(text) = value.extract::<String>() {
        return ebiv::units::parse_us(&text)
            .map_err(|m| PyValueError::new_err(format!("invalid parameter `{name}`: {m}")));
    }
    value.extract::<i64>().map_err(|_| {
        PyValueError::new_err(format!(
            "invalid parameter `{name}`: give µs as an integer or a text with units such as \"10ms\""
        ))
    })
}

/// Every event left in `reader`, batches gathered and joined once at the end (one copy of
/// each event, no regrowth).
fn read_rest(reader: &mut EventReader, watch: &Watch) -> ebiv::Result<EventBuffer> {
    let mut batches = Vec::new();
    loop {
        watch.check()?;
        let mut batch = EventBuffer::new();
        if !reader.read_batch(&mut batch)? {
            break;
        }
        batches.push(batch);
    }
    if batches.len() == 1 {
        return Ok(batches.pop().unwrap_or_default());
    }
    let mut out = EventBuffer::with_capacity(batches.iter().map(EventBuffer::len).sum());
    for batch in &batches {
        out.extend_from(batch);
    }
    out.triggers.clear();
    Ok(out)
}

#[derive(Clone, Copy)]
enum Split {
    Duration(i64),
    Count(usize),
    Batches,
}

struct ChunkState {
    reader: EventReader,
    split: Split,
    /// Events read but not yet handed out.
    pending: EventBuffer,
    /// Start of the next chunk by duration, µs.
    next_start: Option<i64>,
    exhausted: bool,
}

impl ChunkState {
    /// Read one more batch into `pending`; `false` at the end of the file.
    fn fill(&mut self, watch: &Watch) -> ebiv::Result<bool> {
        watch.check()?;
        let mut batch = EventBuffer::new();
        if self.exhausted || !self.reader.read_batch(&mut batch)? {
            self.exhausted = true;
            return Ok(false);
        }
        if self.pending.is_empty() {
            // Handed over as it is: no copy of the batch.
            self.pending = batch;
        } else {
            self.pending.extend_from(&batch);
        }
        Ok(true)
    }

    /// The next chunk, or `None` at the end.
    fn next_chunk(&mut self, watch: &Watch) -> ebiv::Result<Option<EventBuffer>> {
        loop {
            let n = self.pending.len();
            let cut = match self.split {
                Split::Batches => (n > 0).then_some(n),
                Split::Count(count) => (n >= count).then_some(count),
                Split::Duration(d) => match self.pending.t.first() {
                    None => None,
                    Some(&first) => {
                        let start = *self.next_start.get_or_insert(first);
                        let end = start.saturating_add(d);
                        match self.pending.t.iter().position(|&t| t >= end) {
                            Some(0) => {
                                // A gap: on to the window of the next event, not through
                                // every empty window before it.
                                let skip = first.saturating_sub(start) / d * d;
                                self.next_start = Some(start.saturating_add(skip));
                                continue;
                            }
                            Some(cut) => {
                                self.next_start = Some(end);
                                Some(cut)
                            }
                            None => None,
                        }
                    }
                },
            };
            if let Some(cut) = cut {
                return Ok(Some(self.split_off(cut)));
            }
            if !self.fill(watch)? {
                let rest = std::mem::take(&mut self.pending);
                return Ok((!rest.is_empty()).then_some(rest));
            }
        }
    }

    /// The first `n` pending events, the rest kept.
    fn split_off(&mut self, n: usize) -> EventBuffer {
        let p = &mut self.pending;
        let rest = EventBuffer {
            t: p.t.split_off(n),
            x: p.x.split_off(n),
            y: p.y.split_off(n),
            p: p.p.split_off(n),
            triggers: Vec::new(),
        };
        let mut head = std::mem::replace(p, rest);
        head.triggers.clear();
        head
    }
}

/// An iterator over a recording's events in chunks (`Recording.chunks`).
#[pyclass(module = "ebiv", frozen)]
pub struct Chunks {
    state: Mutex<ChunkState>,
}

#[pymethods]
impl Chunks {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyTuple>>> {
        let chunk = watched(py, None, |watch| {
            self.state.lock().expect("chunk lock").next_chunk(watch)
        })?;
        Ok(chunk.map(|events| events_to_py(py, events)))
    }
}
