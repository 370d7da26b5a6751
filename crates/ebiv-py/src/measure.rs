//! The measurements: `process`, `piv`, `simulate`, `assess` and `write`, each the library's
//! call with Python's arguments converted, run with the GIL released (see [`watched`]).

use crate::convert::{
    apply_keywords, dataset_from_py, dataset_to_py, events_from_arrays, events_to_py, is_path,
};
use crate::errors::IntoPy;
use crate::observe::{watched, FieldWatch};
use ebiv::assess::{AssessOptions, Truth};
use ebiv::export::netcdf_dataset;
use ebiv::field::FieldSeries;
use ebiv::frame::Frame;
use ebiv::io::field::{read_field, FieldReadOptions};
use ebiv::io::{EventSource, ReadOptions};
use ebiv::settings::{ProcessSettings, Source};
use ebiv::sim::scenario::{Scenario, EXAMPLES};
use numpy::{PyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Arc;

/// Settings of `ebiv process` that Python takes elsewhere, and where.
const NOT_KEYWORDS: [(&str, &str); 4] = [
    ("input", "the recording is the `source` argument"),
    ("images", "images are the arguments of `ebiv.piv(image_a, image_b, ...)`"),
    ("png", "figures are drawn by `ebiv process --png`; in Python, plot the dataset (see examples/wallflow.py)"),
    ("arrow_stride", "figures are drawn by `ebiv process --png`; in Python, plot the dataset (see examples/wallflow.py)"),
];

/// Settings from keywords: a `config` file first (as `--config`), then every other keyword
/// over it. Returns the settings, the reader options and whether to write `output` (given
/// as a keyword, or by the configuration file, as the command writes it).
pub(crate) fn settings_from(
    py: Python<'_>,
    keywords: Option<&Bound<'_, PyDict>>,
) -> PyResult<(ProcessSettings, ReadOptions, bool)> {
    let mut settings = ProcessSettings::default();
    let mut options = ReadOptions::default();
    let Some(keywords) = keywords else {
        return Ok((settings, options, false));
    };
    let keywords = keywords.copy()?;
    let mut write_output = false;
    if let Some(config) = keywords.get_item("config")? {
        keywords.del_item("config")?;
        let path: PathBuf = config.extract()?;
        for warning in settings.apply_file(&path).py_err()? {
            warn(py, &format!("{}: {warning}", path.display()))?;
        }
        write_output = settings.output != ProcessSettings::default().output;
        if let Some(png) = settings.png.take() {
            warn(
                py,
                &format!(
                    "{}: png = {} is left out: figures are drawn by `ebiv process --png`",
                    path.display(),
                    png.display()
                ),
            )?;
        }
    }
    for (key, instead) in NOT_KEYWORDS {
        if keywords.get_item(key)?.is_some_and(|v| !v.is_none()) {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `{key}`: {instead}"
            )));
        }
    }
    write_output |= keywords.get_item("output")?.is_some_and(|o| !o.is_none());
    apply_keywords(Some(&keywords), &mut settings, &mut options)?;
    Ok((settings, options, write_output))
}

/// Before any work: the field file `path` can be written (its folder exists: else
/// `OSError`) in a format its extension names (else `ValueError` naming `parameter`).
pub(crate) fn check_output(path: &std::path::Path, parameter: &str) -> PyResult<()> {
    ebiv::export::check_output_path(path).py_err()?;
    ebiv::export::field_extension(path)
        .map_err(|e| PyValueError::new_err(format!("invalid parameter `{parameter}`: {e}")))?;
    Ok(())
}

/// Set the method when given; else it stays the configuration file's, or the default.
pub(crate) fn set_method(settings: &mut ProcessSettings, method: Option<&str>) -> PyResult<()> {
    if let Some(method) = method {
        settings
            .set("method", &toml::Value::String(method.into()))
            .py_err()?;
    }
    Ok(())
}

/// Issue a Python `UserWarning`.
pub(crate) fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    py.import("warnings")?.call_method1("warn", (message,))?;
    Ok(())
}

/// The NetCDF dataset of `series` as the Python structure of [`dataset_to_py`].
pub(crate) fn series_to_py<'py>(
    py: Python<'py>,
    series: &FieldSeries,
) -> PyResult<Bound<'py, PyDict>> {
    let dataset = netcdf_dataset(series)
        .map_err(|m| ebiv::Error::Write {
            what: "the dataset".into(),
            message: m,
        })
        .py_err()?;
    dataset_to_py(py, dataset)
}

/// Where the events of `process` come from: a path, or arrays `(t, x, y, p)` (a tuple, a
/// list, an object with those attributes, or a mapping with those keys).
pub(crate) enum Input {
    Path(PathBuf),
    Arrays(ebiv::EventBuffer),
}

pub(crate) fn input_of(source: &Bound<'_, PyAny>) -> PyResult<Input> {
    if is_path(source)? {
        return Ok(Input::Path(source.extract()?));
    }
    let field = |name: &str| -> PyResult<Bound<'_, PyAny>> {
        source
            .get_item(name)
            .or_else(|_| source.getattr(name))
            .map_err(|_| {
                PyTypeError::new_err(
                    "invalid parameter `source`: give a path, or event arrays (t, x, y, p) as a tuple, an object or a mapping",
                )
            })
    };
    let arrays = if source.hasattr("t")? || source.hasattr("keys")? {
        (field("t")?, field("x")?, field("y")?, field("p")?)
    } else {
        let items: Vec<Bound<'_, PyAny>> = source.extract().map_err(|_| {
            PyTypeError::new_err(
                "invalid parameter `source`: give a path, or event arrays (t, x, y, p)",
            )
        })?;
        let [t, x, y, p]: [Bound<'_, PyAny>; 4] = items.try_into().map_err(|_| {
            PyValueError::new_err("invalid parameter `source`: event arrays are four: t, x, y, p")
        })?;
        (t, x, y, p)
    };
    Ok(Input::Arrays(events_from_arrays(
        &arrays.0, &arrays.1, &arrays.2, &arrays.3,
    )?))
}

/// Velocity fields of a recording (a path, or event arrays with `geometry=(w, h)`) by any
/// event method, with the settings of `ebiv process` as keywords. Returns the NetCDF
/// dataset structure; `output=` also writes the file, as the command does.
#[pyfunction]
///
/// `shard=True` (for `ebiv.dask`): fields without events are gaps even when all are.
#[pyo3(signature = (source, method=None, progress=None, shard=false, **settings))]
pub fn process<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    method: Option<&str>,
    progress: Option<Py<PyAny>>,
    shard: bool,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (mut s, options, write_output) = settings_from(py, settings)?;
    set_method(&mut s, method)?;
    let input = input_of(source)?;
    s.input = Some(match &input {
        Input::Path(p) => p.clone(),
        Input::Arrays(_) => PathBuf::from("arrays"),
    });
    let run = s.resolve().py_err()?;
    if write_output {
        check_output(&run.output, "output")?;
    }
    if let Source::Images(_) = run.source {
        return Err(PyValueError::new_err(
            "invalid parameter `images`: PIV of image pairs is `ebiv.piv(image_a, image_b, ...)`",
        ));
    }
    let events = match input {
        Input::Path(path) => EventSource::file(path, &options),
        Input::Arrays(events) => EventSource::Memory {
            events: Arc::new(events),
            geometry: options.geometry,
            name: "arrays".into(),
            denoise: None,
        },
    };
    let measured = watched(py, progress.as_ref(), |watch| {
        let measured = if shard {
            run.measure_part(&events, &mut FieldWatch(watch))?
        } else {
            run.measure(&events, &mut FieldWatch(watch))?
        };
        if write_output {
            ebiv::export::write_field(&measured.series, &run.output)?;
        }
        Ok(measured)
    })?;
    for warning in &measured.warnings {
        warn(py, warning)?;
    }
    series_to_py(py, &measured.series)
}

/// The plan of `process` over the recording at `source` without measuring: the field
/// times (µs of camera time), the time they count from, the events a field needs before
/// and after its time, µs, and the sensor size. `ebiv.dask` splits runs into shards by it.
#[pyfunction]
#[pyo3(signature = (source, method=None, **settings))]
pub fn plan<'py>(
    py: Python<'py>,
    source: PathBuf,
    method: Option<&str>,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (mut s, options, _) = settings_from(py, settings)?;
    set_method(&mut s, method)?;
    s.input = Some(source.clone());
    let run = s.resolve().py_err()?;
    let events = EventSource::file(source, &options);
    let (planned, extent) = py.detach(|| run.plan(&events)).py_err()?;
    let out = PyDict::new(py);
    out.set_item("times", PyArray1::from_vec(py, planned.times))?;
    out.set_item("time_origin_us", planned.time_origin_us)?;
    out.set_item("extent_us", extent)?;
    let g = planned.geometry;
    out.set_item("geometry", (g.width, g.height))?;
    Ok(out)
}

/// A grey image from a path or a 2-D array (any numeric type, converted to float32).
fn frame_of(image: &Bound<'_, PyAny>, index: usize) -> PyResult<(Frame, PathBuf)> {
    let py = image.py();
    if is_path(image)? {
        let path: PathBuf = image.extract()?;
        let frame = ebiv::frame::file::load(&path).py_err()?;
        return Ok((frame, path));
    }
    let np = py.import("numpy")?;
    let array = np.call_method1("ascontiguousarray", (image, "float32"))?;
    let array: PyReadonlyArray2<'_, f32> = array.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "invalid parameter `images`: image {index} is neither a path nor a 2-D array"
        ))
    })?;
    let (height, width) = (array.shape()[0], array.shape()[1]);
    let frame = Frame {
        width: u32::try_from(width).map_err(|_| PyValueError::new_err("image too wide"))?,
        height: u32::try_from(height).map_err(|_| PyValueError::new_err("image too tall"))?,
        data: array.as_slice()?.to_vec(),
    };
    Ok((frame, PathBuf::from(format!("image {index}"))))
}

/// Cross-correlation PIV of images (paths or 2-D arrays), pairs (1,2), (3,4), … or with
/// `sequence=True` (1,2), (2,3), …, with the PIV settings of `ebiv process --method piv`.
#[pyfunction]
#[pyo3(signature = (*images, progress=None, **settings))]
pub fn piv<'py>(
    py: Python<'py>,
    images: Vec<Bound<'py, PyAny>>,
    progress: Option<Py<PyAny>>,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (mut s, _, write_output) = settings_from(py, settings)?;
    let (frames, names): (Vec<Frame>, Vec<PathBuf>) = images
        .iter()
        .enumerate()
        .map(|(i, image)| frame_of(image, i))
        .collect::<PyResult<Vec<_>>>()?
        .into_iter()
        .unzip();
    if frames.len() < 2 {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `images`: PIV needs at least two images, got {}",
            frames.len()
        )));
    }
    let g = frames[0].geometry();
    if let Some((i, f)) = frames.iter().enumerate().find(|(_, f)| f.geometry() != g) {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `images`: image {i} is {}, image 0 is {g}",
            f.geometry()
        )));
    }
    s.set("method", &toml::Value::String("piv".into()))
        .py_err()?;
    let texts = names.iter().map(|n| n.display().to_string()).collect();
    s.images = Some(ebiv::settings::TextList(texts));
    let run = s.resolve().py_err()?;
    if write_output {
        check_output(&run.output, "output")?;
    }
    let series = watched(py, progress.as_ref(), |watch| {
        let params = run.image_series_params(g)?;
        let total = if params.ensemble {
            1
        } else {
            ebiv::piv::images::image_pairs(frames.len(), params.sequence)?.len()
        } as u64;
        let (mut series, _) =
            ebiv::piv::images::piv_image_series(&frames, &names, &params, &mut |done| {
                watch.progress(done.index as u64 + 1, total);
                watch.check()
            })?;
        run.finish_series(&mut series)?;
        if write_output {
            ebiv::export::write_field(&series, &run.output)?;
        }
        Ok(series)
    })?;
    series_to_py(py, &series)
}

/// A scenario from an example name, a file, or TOML text.
pub(crate) fn scenario_of(scenario: &Bound<'_, PyAny>) -> PyResult<Scenario> {
    let text: String = match scenario.extract::<PathBuf>() {
        Ok(path) if path.is_file() => return Scenario::from_file(&path).py_err(),
        _ => scenario.extract().map_err(|_| {
            PyTypeError::new_err(
                "invalid parameter `scenario`: give an example name, a scenario file or TOML text",
            )
        })?,
    };
    if Scenario::example(&text).is_some() {
        return Scenario::from_example(&text).py_err();
    }
    if !text.contains('=') {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `scenario`: `{text}` is neither an example ({}), a file, nor TOML text",
            EXAMPLES.iter().map(|e| e.0).collect::<Vec<_>>().join(", ")
        )));
    }
    Scenario::from_toml(&text, "scenario text").py_err()
}

/// Simulate a recording with its ground truth (`ebiv simulate`): the events as arrays, the
/// sensor size, the true velocity field, and with `tracks=True` every particle's path.
#[pyfunction]
#[pyo3(signature = (scenario, seed=None, duration=None, tracks=false, progress=None))]
pub fn simulate<'py>(
    py: Python<'py>,
    scenario: &Bound<'py, PyAny>,
    seed: Option<u64>,
    duration: Option<&Bound<'py, PyAny>>,
    tracks: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut scenario = scenario_of(scenario)?;
    if let Some(seed) = seed {
        scenario.seed = seed;
    }
    if let Some(d) = duration {
        scenario.duration = crate::recording::duration_us("duration", d)?;
    }
    let sim = scenario.simulation().py_err()?;
    if tracks {
        scenario
            .truth
            .validate_tracks(sim.geometry, scenario.duration, scenario.particles.density)
            .py_err()?;
    }
    scenario
        .truth
        .validate_field(sim.geometry, scenario.duration)
        .py_err()?;
    let interval = tracks.then_some(scenario.truth.track_interval as f64);
    let (events, output) = watched(py, progress.as_ref(), |watch| {
        let mut events = ebiv::EventBuffer::new();
        let mut sink = |batch: &ebiv::EventBuffer| {
            watch.check()?;
            events.extend_from(batch);
            Ok(())
        };
        let progress = |f: f64| watch.progress((f * 1000.0) as u64, 1000);
        let output = sim.run_streaming(interval, &progress, &mut sink)?;
        Ok((events, output))
    })?;
    let out = PyDict::new(py);
    out.set_item("events", events_to_py(py, events))?;
    out.set_item("geometry", (sim.geometry.width, sim.geometry.height))?;
    out.set_item("truth", series_to_py(py, &scenario.truth_field(&sim))?)?;
    if tracks {
        let t = &output.tracks;
        let d = PyDict::new(py);
        d.set_item(
            "id",
            PyArray1::from_vec(py, t.iter().map(|p| p.id).collect()),
        )?;
        for (name, f) in [
            (
                "t_us",
                (|p| p.t_us) as fn(&ebiv::sim::simulation::TrackPoint) -> f64,
            ),
            ("x", |p| p.x),
            ("y", |p| p.y),
            ("z", |p| p.z),
            ("u", |p| p.u),
            ("v", |p| p.v),
        ] {
            d.set_item(name, PyArray1::from_vec(py, t.iter().map(f).collect()))?;
        }
        out.set_item("tracks", d)?;
    }
    Ok(out)
}

/// A field series from a path or a dataset structure ([`dataset_from_py`]), read as
/// `ebiv assess` and `ebiv convert` read field files.
pub(crate) fn series_of(
    field: &Bound<'_, PyAny>,
    options: &FieldReadOptions,
) -> PyResult<FieldSeries> {
    if let Ok(path) = field.extract::<PathBuf>() {
        return read_field(&path, options).py_err();
    }
    let dataset = dataset_from_py(field)?;
    let temp = TempFile::new("nc");
    ebiv::export::write_dataset_netcdf(&dataset, &temp.0).py_err()?;
    // The reader takes the derived quantities the dataset holds as they are.
    read_field(&temp.0, options).py_err()
}

/// A file in the temporary folder, removed when dropped.
struct TempFile(PathBuf);

impl TempFile {
    fn new(extension: &str) -> Self {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        TempFile(
            std::env::temp_dir().join(format!("ebiv-py-{}-{n}.{extension}", std::process::id())),
        )
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// Errors of a field (a path or a dataset) against the truth (`ebiv assess`): a truth field
/// or scenario file, or a ready scenario's flow by `truth_example`. Returns the metrics.
#[pyfunction]
#[pyo3(signature = (field, truth=None, truth_example=None, outlier_px=None, outlier_floor=None, outlier_fixed=None, mm_per_px=None, frame_interval=None))]
#[allow(clippy::too_many_arguments)]
pub fn assess<'py>(
    py: Python<'py>,
    field: &Bound<'py, PyAny>,
    truth: Option<PathBuf>,
    truth_example: Option<String>,
    outlier_px: Option<f64>,
    outlier_floor: Option<f64>,
    outlier_fixed: Option<f64>,
    mm_per_px: Option<f64>,
    frame_interval: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let read_options = FieldReadOptions {
        mm_per_px,
        frame_interval_us: frame_interval
            .map(|d| crate::recording::duration_us("frame_interval", d))
            .transpose()?
            .map(|t| t as f64),
    };
    read_options.validate().py_err()?;
    let defaults = AssessOptions::default();
    let options = AssessOptions {
        outlier_px: outlier_px.unwrap_or(defaults.outlier_px),
        outlier_floor: outlier_floor.unwrap_or(defaults.outlier_floor),
        outlier_fixed,
        ..defaults
    };
    options.validate().py_err()?;
    let truth = match (truth, truth_example) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "invalid parameter `truth`: give truth or truth_example, not both",
            ))
        }
        (Some(path), None) => Truth::from_path(&path),
        (None, Some(name)) => Truth::from_example(&name),
        (None, None) => {
            return Err(PyValueError::new_err(
                "invalid parameter `truth`: give the truth (a file) or truth_example (a ready scenario)",
            ))
        }
    }
    .py_err()?;
    let series = series_of(field, &read_options)?;
    let assessment =
        py.detach(|| ebiv::assess::assess(&series, &|x, y, t| truth.velocity(x, y, t), &options));
    let json =
        serde_json::to_string(&assessment).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (json,))
}

/// Write a field (a dataset structure, or a field file to convert) to `path`: NetCDF, CSV,
/// NPZ, Tecplot or VTK by its extension, as `ebiv process -o` writes.
#[pyfunction]
pub fn write(field: &Bound<'_, PyAny>, path: PathBuf) -> PyResult<()> {
    check_output(&path, "path")?;
    let series = series_of(field, &FieldReadOptions::default())?;
    field
        .py()
        .detach(|| ebiv::export::write_field(&series, &path))
        .py_err()
}

/// Every setting of `ebiv process`: `(keyword, group, default or None, summary)`.
#[pyfunction]
pub fn setting_names() -> Vec<(String, &'static str, Option<String>, String)> {
    ebiv::settings::settings()
        .iter()
        .map(|s| {
            (
                s.key.replace('-', "_"),
                s.group,
                s.default_text(),
                s.summary().to_string(),
            )
        })
        .collect()
}

/// The ready scenarios of `ebiv simulate --example`: `(name, description)`.
#[pyfunction]
pub fn examples() -> Vec<(&'static str, &'static str)> {
    EXAMPLES.iter().map(|e| (e.0, e.1)).collect()
}

/// Quantities derived from the velocity gradient of a field series (a dataset structure or
/// a field file), as `ebiv derive` computes them; `output=` also writes the file (.nc, .csv
/// or .npz). Returns the dataset structure of the field with the quantities.
#[pyfunction]
#[pyo3(signature = (field, quantities="all", mm_per_px=None, output=None))]
pub fn derive<'py>(
    py: Python<'py>,
    field: &Bound<'py, PyAny>,
    quantities: &str,
    mm_per_px: Option<f64>,
    output: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let quantities = ebiv::derived::parse_quantities(quantities)
        .map_err(|m| PyValueError::new_err(format!("invalid parameter `quantities`: {m}")))?;
    if let Some(path) = &output {
        check_output(path, "output")?;
        ebiv::derived::check_output(path).py_err()?;
    }
    let read_options = FieldReadOptions {
        mm_per_px,
        ..FieldReadOptions::default()
    };
    let mut series = series_of(field, &read_options)?;
    series.scale_if_uncalibrated(mm_per_px);
    let series = py
        .detach(|| -> ebiv::Result<_> {
            ebiv::derived::add_derived(&mut series, &quantities)?;
            if let Some(path) = &output {
                ebiv::export::write_field(&series, path)?;
            }
            Ok(series)
        })
        .py_err()?;
    series_to_py(py, &series)
}

/// Flow statistics of a field series (a dataset structure or a field file), as `ebiv stats`
/// computes them; `output=` also writes the file (.nc or .csv). Returns the dataset
/// structure of the statistics' NetCDF file.
#[pyfunction]
#[pyo3(signature = (field, period=None, phases=8, phase_origin=None, include_replaced=false, mm_per_px=None, output=None, triggers=None, trigger_polarity="rising", trigger_channel=None, reader_options=None))]
#[allow(clippy::too_many_arguments)]
pub fn stats<'py>(
    py: Python<'py>,
    field: &Bound<'py, PyAny>,
    period: Option<&Bound<'py, PyAny>>,
    phases: i64,
    phase_origin: Option<&Bound<'py, PyAny>>,
    include_replaced: bool,
    mm_per_px: Option<f64>,
    output: Option<PathBuf>,
    triggers: Option<PathBuf>,
    trigger_polarity: &str,
    trigger_channel: Option<u8>,
    reader_options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let duration = |name: &str, value: Option<&Bound<'py, PyAny>>| -> PyResult<Option<i64>> {
        value
            .filter(|v| !v.is_none())
            .map(|v| crate::recording::duration_us(name, v))
            .transpose()
    };
    let phases = usize::try_from(phases).map_err(|_| {
        PyValueError::new_err(format!(
            "invalid parameter `phases`: must be 1 to 10000, got {phases}"
        ))
    })?;
    let polarity = ebiv::statistics::TriggerPolarity::parse(trigger_polarity).ok_or_else(|| {
        PyValueError::new_err(format!(
            "invalid parameter `trigger_polarity`: `{trigger_polarity}` is not rising, falling or any"
        ))
    })?;
    let reader_options = crate::recording::read_options(reader_options)?;
    let mut options = ebiv::statistics::StatsOptions {
        period_us: duration("period", period)?,
        triggers_us: None,
        phases,
        phase_origin_us: duration("phase_origin", phase_origin)?,
        include_replaced,
    };
    if let Some(path) = &output {
        ebiv::export::check_output_path(path).py_err()?;
    }
    let read_options = FieldReadOptions {
        mm_per_px,
        ..FieldReadOptions::default()
    };
    let mut series = series_of(field, &read_options)?;
    // A scale given for a field without one: the statistics in m/s, y down (as `ebiv stats`).
    series.scale_if_uncalibrated(mm_per_px);
    let statistics = py
        .detach(|| -> ebiv::Result<_> {
            if let Some(recording) = &triggers {
                let times = ebiv::statistics::triggers_for(
                    &series,
                    recording,
                    &reader_options,
                    polarity,
                    trigger_channel,
                )?;
                options.triggers_us = Some(times.times_us);
            }
            let st = ebiv::statistics::flow_statistics(&series, &options)?;
            if let Some(path) = &output {
                ebiv::export::write_statistics(&st, &series.attributes, path)?;
            }
            Ok(st)
        })
        .py_err()?;
    dataset_to_py(
        py,
        ebiv::export::statistics_dataset(&statistics, &series.attributes),
    )
}
