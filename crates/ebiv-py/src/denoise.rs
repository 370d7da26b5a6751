//! `ebiv.filter`: a recording (or event arrays) read through the denoising filters, as
//! `ebiv filter` does; the settings are the library's (`denoise`, `denoise_dt`, …).

use crate::convert::events_to_py;
use crate::errors::IntoPy;
use crate::measure::{input_of, settings_from, Input};
use crate::observe::watched;
use ebiv::io::{write, EventSource};
use ebiv::EventBuffer;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Arc;

/// Denoise `source` (a path, or event arrays with `geometry=(w, h)`) with the denoising
/// settings as keywords (`denoise="all"`, `denoise_dt="2ms"`, …) and reader options. With
/// `output`, writes the kept events in the format of its extension; without, returns them.
/// Returns the counts of each filter (and `events` without `output`).
#[pyfunction]
#[pyo3(signature = (source, output=None, **settings))]
pub fn filter<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    output: Option<PathBuf>,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    if let Some(keywords) = settings {
        for key in keywords.keys() {
            let key = crate::convert::kebab(&key.extract::<String>()?);
            let denoising = ebiv::settings::find(&key)
                .is_some_and(|s| s.group == ebiv::settings::DENOISE_GROUP);
            if !denoising && !ebiv::io::READ_OPTIONS.contains(&key.as_str()) {
                return Err(PyValueError::new_err(format!(
                    "invalid parameter `{key}`: filter takes the denoising settings (denoise, denoise_dt, denoise_refractory, denoise_hot_factor, denoise_hot_learn) and reader options"
                )));
            }
        }
    }
    let (s, options, _) = settings_from(py, settings)?;
    let denoise = s.denoise_settings().ok_or_else(|| {
        PyValueError::new_err(
            "invalid parameter `denoise`: no filter chosen; give denoise=\"hot-pixels,refractory,correlation\" (any of them) or \"all\"",
        )
    })?;
    denoise.check().py_err()?;
    let events = match input_of(source)? {
        Input::Path(path) => EventSource::file(path, &options),
        Input::Arrays(events) => EventSource::memory(Arc::new(events), options.geometry, "arrays"),
    }
    .denoised(Some(denoise));
    let format = output
        .as_deref()
        .map(|o| {
            ebiv::export::check_output_path(o)?;
            write::format_for_path(o)
        })
        .transpose()
        .py_err()?;
    let (kept, report) = watched(py, None, |watch| {
        let mut reader = events.open()?;
        let mut writer = match (&output, format) {
            (Some(o), Some(f)) => Some(write::create(o, f, reader.metadata().geometry)?),
            _ => None,
        };
        let mut kept = EventBuffer::new();
        let mut batch = EventBuffer::new();
        while reader.read_batch(&mut batch)? {
            watch.check()?;
            match writer.as_mut() {
                Some(w) => w.write(&batch)?,
                None => kept.extend_from(&batch),
            }
        }
        if let Some(w) = writer {
            w.finish()?;
        }
        Ok((kept, reader.denoise_report().unwrap_or_default()))
    })?;
    let out = PyDict::new(py);
    out.set_item("filters", denoise.filters.names())?;
    out.set_item("events_in", report.events_in)?;
    out.set_item("events_out", report.events_out)?;
    out.set_item("hot_pixels", report.hot_pixels)?;
    out.set_item("removed_hot_pixels", report.removed_hot_pixels)?;
    out.set_item("removed_refractory", report.removed_refractory)?;
    out.set_item("removed_correlation", report.removed_correlation)?;
    if output.is_none() {
        out.set_item("events", events_to_py(py, kept))?;
    }
    Ok(out)
}
