//! `ebiv.live`: velocity fields while the camera records, as `ebiv live` computes them,
//! each handed to a Python callback as it is ready (the run goes on in the library's
//! threads with the GIL released; the callback takes the GIL for its call).

use crate::errors::IntoPy;
use crate::measure::{check_output, series_to_py, set_method, settings_from, warn};
use crate::observe::watched;
use ebiv::export::{LiveOutputs, LiveView, LiveWriter};
use ebiv::live::{LiveField, LiveInput, LiveOptions, LiveSink, LiveStart, LiveSummary};
use ebiv::process::Method;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

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
    if matches!(run.method, Method::Piv | Method::Pulsed) {
        return Err(PyValueError::new_err(
            "invalid parameter `method`: live computes corrsum and motion fields; piv and pulsed are `ebiv.process`'s",
        ));
    }
    let input = live_input(source, follow, idle, replay, speed)?;
    let writer = if write_output {
        check_output(&run.output, "output")?;
        Some(LiveWriter::create(&run.output).py_err()?)
    } else {
        None
    };
    let mut options = LiveOptions::new(input);
    options.read = ebiv::io::ReadOptions {
        batch_bytes: options.read.batch_bytes,
        ..read
    };
    options.queue = queue.max(1);
    options.every_us = every
        .map(|text| {
            ebiv::units::parse_us(text)
                .map_err(|m| PyValueError::new_err(format!("invalid parameter `every`: {m}")))
        })
        .transpose()?;
    let view = match serve {
        Some(address) => {
            let address = address.parse().map_err(|_| {
                PyValueError::new_err(format!(
                    "invalid parameter `serve`: `{address}` is not an address such as 127.0.0.1:8080"
                ))
            })?;
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

fn live_input(
    source: PathBuf,
    follow: bool,
    idle: &str,
    replay: bool,
    speed: f64,
) -> PyResult<LiveInput> {
    let stdin = source.as_os_str() == "-";
    if follow && replay {
        return Err(PyValueError::new_err(
            "invalid parameter `follow`: give follow or replay, not both",
        ));
    }
    if stdin && (follow || replay) {
        return Err(PyValueError::new_err(
            "invalid parameter `source`: standard input (\"-\") is read as it comes; follow and replay take a file",
        ));
    }
    if !(speed.is_finite() && speed > 0.0) {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `speed`: must be positive, got {speed}"
        )));
    }
    let idle = ebiv::units::parse_us(idle)
        .ok()
        .and_then(|us| u64::try_from(us).ok())
        .filter(|&us| us > 0)
        .map(Duration::from_micros)
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "invalid parameter `idle`: a positive duration such as \"5s\", got `{idle}`"
            ))
        })?;
    Ok(if stdin {
        LiveInput::Stdin
    } else if follow {
        LiveInput::Follow { path: source, idle }
    } else if replay {
        LiveInput::Replay {
            path: source,
            speed,
        }
    } else {
        LiveInput::File(source)
    })
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
    d.set_item("stopped", s.stopped)?;
    d.set_item("warnings", s.report.warnings.clone())?;
    Ok(d)
}
