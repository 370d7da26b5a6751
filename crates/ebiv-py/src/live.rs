//! `ebiv.live`: velocity fields while the camera records, as `ebiv live` computes them,
//! each handed to a Python callback as it is ready (the run goes on in the library's
//! threads with the GIL released; the callback takes the GIL for its call).

use crate::errors::IntoPy;
use crate::measure::{check_output, series_to_py, set_method, settings_from, warn};
use crate::observe::watched;
use ebiv::export::{LiveOutputs, LiveView, LiveWriter};
use ebiv::live::{LiveField, LiveInput, LiveOptions, LiveSink, LiveStart, LiveSummary};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// Run `ebiv live` on `source` (a path, or `"-"` for standard input): `follow` a growing
/// file (ending after `idle` without growth), `replay` a finished one at `speed`, or read it
/// as fast as the fields are computed. `on_field(dataset, stats)` is called with every field
/// (the dict structure of `process`, one time) and the run's counts; a false return value
/// (not `None`) stops the run. `output=` appends the fields to a file, `serve=` serves the live view. Returns
/// the summary as a dict.
#[pyfunction]
#[pyo3(signature = (source, method=None, *, follow=false, idle="5s", replay=false, speed=1.0, every=None, queue=ebiv::live::DEFAULT_QUEUE, serve=None, allow_remote=false, on_field=None, **settings))]
#[allow(clippy::too_many_arguments)]
pub fn live<'py>(
    py: Python<'py>,
    source: PathBuf,
    method: Option<&str>,
    follow: bool,
    idle: &str,
    replay: bool,
    speed: f64,
    every: Option<&str>,
    queue: usize,
    serve: Option<&str>,
    allow_remote: bool,
    on_field: Option<Py<PyAny>>,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (mut s, read, write_output) = settings_from(py, settings)?;
    set_method(&mut s, method)?;
    s.input = Some(source.clone());
    let run = s.resolve().py_err()?;
    let input = LiveInput::choose(&source, follow, replay, speed, idle).py_err()?;
    let writer = if write_output {
        check_output(&run.output, "output")?;
        Some(LiveWriter::create(&run.output).py_err()?)
    } else {
        None
    };
    let mut options = LiveOptions::new(input);
    options.set_read_options(read);
    options.queue = queue;
    options.every_us = every
        .map(|text| {
            ebiv::units::parse_us(text)
                .map_err(|m| PyValueError::new_err(format!("invalid parameter `every`: {m}")))
        })
        .transpose()?;
    let view = match serve {
        Some(address) => {
            let view = LiveView::start(address, allow_remote).py_err()?;
            options.events_every = Some(ebiv::export::LIVE_VIEW_INTERVAL);
            Some(view)
        }
        None => None,
    };
    let raised: Mutex<Option<PyErr>> = Mutex::new(None);
    let outcome = watched(py, None, |watch| {
        let stop_flag = watch.stop_flag();
        let stopped_by_callback = Arc::new(AtomicBool::new(false));
        let stop = {
            let by_callback = stopped_by_callback.clone();
            Arc::new(move || {
                stop_flag.load(Ordering::Relaxed) || by_callback.load(Ordering::Relaxed)
            })
        };
        let mut sink = Callback {
            outputs: LiveOutputs::new(writer, view),
            on_field: on_field.as_ref(),
            stop: stopped_by_callback,
            raised: &raised,
        };
        let summary = ebiv::live::run_live(&run, &options, stop, &mut sink);
        let finished = sink.outputs.finish();
        let summary = summary?;
        finished?;
        Ok(summary)
    });
    // The callback's own exception comes first: it stopped the run.
    if let Some(e) = raised.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(e);
    }
    let summary = outcome?;
    for warning in &summary.report.warnings {
        warn(py, warning)?;
    }
    summary_to_py(py, &summary)
}

/// The outputs, plus the Python callback.
struct Callback<'a> {
    outputs: LiveOutputs,
    on_field: Option<&'a Py<PyAny>>,
    /// Set when the callback returns `False` or raises.
    stop: Arc<AtomicBool>,
    raised: &'a Mutex<Option<PyErr>>,
}

impl LiveSink for Callback<'_> {
    fn started(&mut self, start: &LiveStart) -> ebiv::Result<()> {
        self.outputs.started(start)
    }

    fn field(&mut self, f: &LiveField) -> ebiv::Result<()> {
        self.outputs.field(f)?;
        let (Some(callback), Some(start)) = (self.on_field, self.outputs.start()) else {
            return Ok(());
        };
        if self.stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        let series = start.series_of(f.t0_us, f.field)?;
        let outcome = Python::attach(|py| -> PyResult<bool> {
            let dataset = series_to_py(py, &series)?;
            let stats = pythonize_stats(py, &f.stats, f.dropped_before)?;
            let answer = callback.call1(py, (dataset, stats))?;
            let answer = answer.bind(py);
            // A false value stops (`False`, NumPy's `False_`, 0); `None` goes on.
            Ok(answer.is_none() || answer.is_truthy()?)
        });
        match outcome {
            Ok(true) => {}
            Ok(false) => self.stop.store(true, Ordering::Relaxed),
            Err(e) => {
                self.stop.store(true, Ordering::Relaxed);
                self.raised
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .get_or_insert(e);
            }
        }
        Ok(())
    }
}

fn pythonize_stats<'py>(
    py: Python<'py>,
    s: &ebiv::live::LiveStats,
    dropped_before: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("events", s.events)?;
    d.set_item("fields", s.fields)?;
    d.set_item("dropped", s.dropped)?;
    d.set_item("dropped_before", dropped_before)?;
    d.set_item("event_rate", s.event_rate)?;
    d.set_item("field_rate", s.field_rate)?;
    d.set_item("latency_ms", s.latency_ms)?;
    d.set_item("latency_p99_ms", s.latency_p99_ms)?;
    d.set_item("elapsed_s", s.elapsed_s)?;
    Ok(d)
}

fn summary_to_py<'py>(py: Python<'py>, s: &LiveSummary) -> PyResult<Bound<'py, PyDict>> {
    let d = pythonize_stats(py, &s.stats, 0)?;
    d.del_item("dropped_before")?;
    d.del_item("latency_ms")?;
    d.del_item("latency_p99_ms")?;
    d.set_item("latency_p50_ms", s.latency_p50_ms)?;
    d.set_item("latency_p99_ms", s.latency_p99_ms)?;
    d.set_item("latency_max_ms", s.latency_max_ms)?;
    d.set_item("empty_fields", s.empty_fields)?;
    d.set_item("lone_pixel_events", s.lone_pixel_events)?;
    d.set_item("stopped", s.stopped)?;
    d.set_item("warnings", s.report.warnings.clone())?;
    Ok(d)
}
