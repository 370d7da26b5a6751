//! Particle tracking: `track`, `bin_tracks` and `assess_tracks`, the library's
//! [`ebiv::track`] with Python's arguments converted, as `ebiv track` and
//! `ebiv assess --truth-tracks` run it: the same settings ([`TRACK_SETTINGS`], set by
//! [`TrackParams::set`]), the same run ([`track_source`]), the same files ([`TrackWriter`])
//! and the same datasets ([`tracks_dataset`], [`ebiv::export::netcdf_dataset`]).

use crate::convert::{dataset_to_py, is_path, kebab, reader_option_text};
use crate::errors::IntoPy;
use crate::measure::{input_of, scenario_of, series_to_py, Input};
use crate::observe::watched;
use ebiv::event::Geometry;
use ebiv::export::{
    read_tracks_csv, read_truth_tracks_csv, tracks_dataset, TrackFormat, TrackTable, TrackWriter,
    TRACK_COLUMNS,
};
use ebiv::io::{EventSource, ReadOptions, READ_OPTIONS};
use ebiv::sim::simulation::TrackPoint;
use ebiv::track::bin::BinParams;
use ebiv::track::run::{track_attributes, track_source, TrackInterval};
use ebiv::track::score::{score_tracks, ScoreOptions};
use ebiv::track::{TrackParams, TRACK_SETTINGS};
use numpy::PyReadonlyArray1;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::path::PathBuf;
use std::sync::Arc;

/// Flags of `ebiv track` that Python takes elsewhere, and where.
const NOT_KEYWORDS: [(&str, &str); 5] = [
    (
        "bin",
        "binning is `ebiv.bin_tracks(tracks, bin, interval=..., min_tracks=..., geometry=...)`",
    ),
    (
        "bin-interval",
        "binning is `ebiv.bin_tracks(tracks, bin, interval=...)`",
    ),
    (
        "bin-min-tracks",
        "binning is `ebiv.bin_tracks(tracks, bin, min_tracks=...)`",
    ),
    (
        "field",
        "the binned field is written by `ebiv.write(ebiv.bin_tracks(...), path)`",
    ),
    (
        "png",
        "figures are drawn by `ebiv track --png`; in Python, plot the dataset",
    ),
];

/// Tracking settings and reader options from keywords (`_` for `-`): reader options by
/// their names in [`READ_OPTIONS`], every other keyword a tracking setting set from its
/// `str()` as the command line's flag would be. `None` leaves a setting at its default.
fn track_settings(keywords: Option<&Bound<'_, PyDict>>) -> PyResult<(TrackParams, ReadOptions)> {
    let mut params = TrackParams::default();
    let mut options = ReadOptions::default();
    for (key, value) in keywords.into_iter().flat_map(|k| k.iter()) {
        let key = kebab(&key.extract::<String>()?);
        if value.is_none() {
            continue;
        }
        if let Some((_, instead)) = NOT_KEYWORDS.iter().find(|(k, _)| *k == key) {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `{}`: {instead}",
                key.replace('-', "_")
            )));
        }
        if READ_OPTIONS.contains(&key.as_str()) {
            options
                .set(&key, &reader_option_text(&key, &value)?)
                .py_err()?;
        } else {
            params.set(&key, &value.str()?.to_string()).py_err()?;
        }
    }
    Ok((params, options))
}

/// The interval tracked: `START:END` text (either end may be left out), or a pair
/// `(start, end)` of durations (µs, or text with units), `None` for an open end.
fn interval_of(time: Option<&Bound<'_, PyAny>>, absolute_time: bool) -> PyResult<TrackInterval> {
    let mut interval = TrackInterval {
        absolute_time,
        ..TrackInterval::default()
    };
    let Some(time) = time.filter(|t| !t.is_none()) else {
        return Ok(interval);
    };
    let bad = |m: String| PyValueError::new_err(format!("invalid parameter `time`: {m}"));
    let (start, end) = if time.is_instance_of::<PyString>() {
        ebiv::units::parse_range(&time.extract::<String>()?).map_err(bad)?
    } else {
        let (a, b): (Bound<'_, PyAny>, Bound<'_, PyAny>) = time.extract().map_err(|_| {
            bad(
                "give \"START:END\" (e.g. \"10ms:60ms\") or a pair (start, end) of durations"
                    .into(),
            )
        })?;
        let side = |v: Bound<'_, PyAny>| {
            (!v.is_none())
                .then(|| crate::recording::duration_us("time", &v))
                .transpose()
        };
        let (start, end) = (side(a)?, side(b)?);
        if let (Some(s), Some(e)) = (start, end) {
            if e <= s {
                return Err(bad(format!(
                    "the end ({e} µs) is not after the start ({s} µs)"
                )));
            }
        }
        (start, end)
    };
    interval.start = start;
    interval.end = end;
    Ok(interval)
}

/// Particle tracks of a recording (a path, or event arrays with `geometry=(w, h)`), as
/// `ebiv track` follows them, with its tracking settings as keywords. Returns the NetCDF
/// dataset structure of the tracks; `output=` also writes the file (.csv, .npz or .nc).
#[pyfunction]
#[pyo3(signature = (source, time=None, absolute_time=false, output=None, progress=None, **settings))]
pub fn track<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    time: Option<&Bound<'py, PyAny>>,
    absolute_time: bool,
    output: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
    settings: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    // Everything that can be checked is checked before reading, as the command does.
    let (params, options) = track_settings(settings)?;
    let interval = interval_of(time, absolute_time)?;
    if let Some(path) = &output {
        TrackFormat::of(path).py_err()?;
        ebiv::export::check_output_path(path).py_err()?;
    }
    let (events, name, total) = match input_of(source)? {
        Input::Path(path) => {
            let total = std::fs::metadata(&path).ok().map(|m| m.len());
            let name = path.display().to_string();
            (EventSource::file(path, &options), name, total)
        }
        Input::Arrays(events) => {
            let source = EventSource::Memory {
                events: Arc::new(events),
                geometry: options.geometry,
                name: "arrays".into(),
                denoise: None,
            };
            (source, "arrays".to_string(), None)
        }
    };
    let (table, attributes) = watched(py, progress.as_ref(), |watch| {
        let mut writer = output.as_deref().map(TrackWriter::create).transpose()?;
        let mut table = TrackTable::default();
        let run = track_source(
            &events,
            &params,
            interval,
            &mut |track| {
                table.push(&track);
                match &mut writer {
                    Some(w) => w.write(&track),
                    None => Ok(()),
                }
            },
            &mut |position| {
                if let (Some(done), Some(total)) = (position, total) {
                    watch.progress(done.min(total), total);
                }
                watch.check()
            },
        )?;
        if let Some(total) = total {
            watch.progress(total, total);
        }
        let attributes = track_attributes(&name, &params, &run);
        if let Some(writer) = writer {
            writer.finish(&attributes)?;
        }
        Ok((table, attributes))
    })?;
    dataset_to_py(py, tracks_dataset(&table, &attributes).py_err()?)
}

/// One column of `columns` (a dict of 1-D arrays) as float64 values; `None` when absent.
fn column(columns: &Bound<'_, PyDict>, name: &str) -> PyResult<Option<Vec<f64>>> {
    let Some(array) = columns.get_item(name)? else {
        return Ok(None);
    };
    let np = columns.py().import("numpy")?;
    let array = np.call_method1("ascontiguousarray", (array, "float64"))?;
    let array: PyReadonlyArray1<'_, f64> = array.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "invalid parameter `tracks`: the column `{name}` is not a 1-D array of numbers"
        ))
    })?;
    Ok(Some(array.as_slice()?.to_vec()))
}

/// Integers stored as floats (identities, µs): each must be a whole number in `range`.
fn whole<T: TryFrom<i64>>(
    values: Vec<f64>,
    parameter: &str,
    name: &str,
    range: (f64, f64),
) -> PyResult<Vec<T>> {
    values
        .into_iter()
        .map(|v| {
            if v.fract() == 0.0 && v >= range.0 && v <= range.1 {
                T::try_from(v as i64).ok()
            } else {
                None
            }
        })
        .collect::<Option<Vec<T>>>()
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "invalid parameter `{parameter}`: the column `{name}` holds values that are not whole numbers in {}..{}",
                range.0, range.1
            ))
        })
}

/// Columns `names` of `columns`, each as long as the first: the required ones present,
/// the others NaN when absent.
fn columns_of(
    columns: &Bound<'_, PyDict>,
    parameter: &str,
    names: &[&str],
    required: &[&str],
) -> PyResult<Vec<Vec<f64>>> {
    let mut out: Vec<Option<Vec<f64>>> = Vec::new();
    for name in names {
        let values = column(columns, name)?;
        if values.is_none() && required.contains(name) {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `{parameter}`: no column `{name}` (needed: {})",
                required.join(", ")
            )));
        }
        out.push(values);
    }
    let n = out.iter().flatten().map(Vec::len).next().unwrap_or(0);
    if let Some((name, values)) = names
        .iter()
        .zip(&out)
        .find_map(|(name, v)| v.as_ref().filter(|v| v.len() != n).map(|v| (name, v)))
    {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `{parameter}`: the column `{name}` has {} values, `{}` {n}",
            values.len(),
            names[0]
        )));
    }
    Ok(out
        .into_iter()
        .map(|v| v.unwrap_or_else(|| vec![f64::NAN; n]))
        .collect())
}

/// Samples of tracks: a track CSV file of `ebiv track` (read as `ebiv assess` reads it), or
/// a dict of the columns of [`TRACK_COLUMNS`] (`track_id`, `t_us`, `x`, `y`, `u`, `v`
/// needed; others NaN when absent).
fn table_of(tracks: &Bound<'_, PyAny>) -> PyResult<TrackTable> {
    if is_path(tracks)? {
        let path: PathBuf = tracks.extract()?;
        let mut table = TrackTable::default();
        for track in read_tracks_csv(&path).py_err()? {
            table.push(&track);
        }
        return Ok(table);
    }
    let columns: Bound<'_, PyDict> = tracks.extract().map_err(|_| {
        PyTypeError::new_err(
            "invalid parameter `tracks`: give a track file (CSV) or the columns as a dict of arrays",
        )
    })?;
    let names: Vec<&str> = TRACK_COLUMNS.iter().map(|c| c.0).collect();
    let mut values = columns_of(
        &columns,
        "tracks",
        &names,
        &["track_id", "t_us", "x", "y", "u", "v"],
    )?
    .into_iter();
    let max_exact = 2f64.powi(53);
    let track_id = whole(
        values.next().unwrap_or_default(),
        "tracks",
        "track_id",
        (0.0, max_exact),
    )?;
    let t_us = whole(
        values.next().unwrap_or_default(),
        "tracks",
        "t_us",
        (-max_exact, max_exact),
    )?;
    let mut table = TrackTable {
        track_id,
        t_us,
        ..TrackTable::default()
    };
    for (slot, column) in table.values.iter_mut().zip(values) {
        *slot = column;
    }
    Ok(table)
}

/// A parameter error of [`BinParams`] named by its Python keyword.
fn bin_error(e: ebiv::Error) -> PyErr {
    match e {
        ebiv::Error::Parameter { name, message } => {
            let name = match name.as_str() {
                "bin-interval" => "interval",
                "bin-min-tracks" => "min_tracks",
                other => other,
            };
            PyValueError::new_err(format!("invalid parameter `{name}`: {message}"))
        }
        other => crate::errors::to_py(other),
    }
}

/// The mean velocity field of tracks binned on a grid (`ebiv track --bin`), on a sensor of
/// `geometry`; `attributes` (the tracks' own) are added to the field's, as the command
/// adds them. Returns the NetCDF dataset structure of `process`.
#[pyfunction]
#[pyo3(signature = (tracks, geometry, bin=16.0, interval=None, min_tracks=3, attributes=Vec::new()))]
pub fn bin_tracks<'py>(
    py: Python<'py>,
    tracks: &Bound<'py, PyAny>,
    geometry: (u32, u32),
    bin: f64,
    interval: Option<&Bound<'py, PyAny>>,
    min_tracks: u32,
    attributes: Vec<(String, String)>,
) -> PyResult<Bound<'py, PyDict>> {
    let params = BinParams {
        bin_px: bin,
        interval_us: interval
            .filter(|i| !i.is_none())
            .map(|i| crate::recording::duration_us("interval", i))
            .transpose()?,
        min_tracks,
    };
    params.validate().map_err(bin_error)?;
    if geometry.0 == 0 || geometry.1 == 0 {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `geometry`: {}x{} px has no pixels",
            geometry.0, geometry.1
        )));
    }
    let geometry = Geometry {
        width: geometry.0,
        height: geometry.1,
    };
    let table = table_of(tracks)?;
    let mut field = py
        .detach(|| ebiv::track::bin::bin_tracks(&table, geometry, &params))
        .map_err(bin_error)?;
    ebiv::track::bin::add_track_attributes(&mut field, &attributes);
    series_to_py(py, &field)
}

/// The simulator's particle paths: its CSV file (`ebiv simulate --tracks`), or the dict of
/// arrays `id`, `t_us`, `x`, `y`, `z`, `u`, `v` of `ebiv.simulate(..., tracks=True)`.
fn truth_of(truth: &Bound<'_, PyAny>) -> PyResult<Vec<TrackPoint>> {
    if is_path(truth)? {
        return read_truth_tracks_csv(&truth.extract::<PathBuf>()?).py_err();
    }
    let columns: Bound<'_, PyDict> = truth.extract().map_err(|_| {
        PyTypeError::new_err(
            "invalid parameter `truth_tracks`: give the simulator's track file (CSV) or the tracks of ebiv.simulate(..., tracks=True)",
        )
    })?;
    let names = ["id", "t_us", "x", "y", "z", "u", "v"];
    let mut c = columns_of(&columns, "truth_tracks", &names, &names)?.into_iter();
    let ids: Vec<u64> = whole(
        c.next().unwrap_or_default(),
        "truth_tracks",
        "id",
        (0.0, 2f64.powi(53)),
    )?;
    let mut next = || c.next().unwrap_or_default();
    let (t, x, y, z, u, v) = (next(), next(), next(), next(), next(), next());
    Ok((0..ids.len())
        .map(|k| TrackPoint {
            id: ids[k],
            t_us: t[k],
            x: x[k],
            y: y[k],
            z: z[k],
            u: u[k],
            v: v[k],
        })
        .collect())
}

/// Tracks (a track CSV file or the columns) scored against the simulator's particle paths,
/// as `ebiv assess TRACKS --truth-tracks TRUTH` scores them: the particles in view are
/// decided by the scenario (`scenario`: an example name, a file or TOML text; or
/// `truth_example`), else by the paths' extent and the default light sheet. Returns the
/// scores of `tracks.json`.
#[pyfunction]
#[pyo3(signature = (tracks, truth_tracks, scenario=None, truth_example=None))]
pub fn assess_tracks<'py>(
    py: Python<'py>,
    tracks: &Bound<'py, PyAny>,
    truth_tracks: &Bound<'py, PyAny>,
    scenario: Option<&Bound<'py, PyAny>>,
    truth_example: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let scenario = match (scenario.filter(|s| !s.is_none()), truth_example) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "invalid parameter `scenario`: give scenario or truth_example, not both",
            ))
        }
        (Some(s), None) => Some(scenario_of(s)?),
        (None, Some(name)) => Some(ebiv::sim::scenario::Scenario::from_example(&name).py_err()?),
        (None, None) => None,
    };
    let measured = if is_path(tracks)? {
        read_tracks_csv(&tracks.extract::<PathBuf>()?).py_err()?
    } else {
        table_of(tracks)?.tracks()
    };
    let truth = truth_of(truth_tracks)?;
    // As `ebiv assess --truth-tracks` (crates/ebiv-cli/src/cmd/assess.rs) decides them.
    let options = match &scenario {
        Some(s) => ScoreOptions::for_scenario(s),
        None => ScoreOptions::from_truth(&truth),
    };
    let score = py.detach(|| score_tracks(&measured, &truth, &options));
    let json = serde_json::to_string(&score).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (json,))
}

/// Every tracking setting: `(keyword, value placeholder, default, summary)`.
#[pyfunction]
pub fn track_setting_names() -> Vec<(String, &'static str, String, &'static str)> {
    let defaults = TrackParams::default();
    TRACK_SETTINGS
        .iter()
        .map(|(key, placeholder, help)| {
            (
                key.replace('-', "_"),
                *placeholder,
                defaults.get(key).unwrap_or_default(),
                *help,
            )
        })
        .collect()
}
