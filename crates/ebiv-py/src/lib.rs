//! The Python package `ebiv` (module `ebiv._ebiv`): reading recordings into NumPy arrays,
//! and every measurement of the library (`process`, `piv`, `simulate`, `assess`, `write`)
//! with the settings of the command line and the configuration file as keywords, and
//! particle tracking (`track`, `bin_tracks`, `assess_tracks`) with the settings of
//! `ebiv track`.
//!
//! This crate only converts between Python and the library: settings are the library's
//! ([`ebiv::settings`]), runs are the library's ([`ebiv::settings::Resolved::measure`]),
//! datasets are the NetCDF writer's ([`ebiv::export::netcdf_dataset`]). The pure-Python part
//! of the package (`python/ebiv`) turns datasets into `xarray.Dataset`s and adds `ebiv.dask`.

mod convert;
mod denoise;
mod errors;
mod live;
mod measure;
mod observe;
mod recording;
mod track;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _ebiv(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("EbivError", m.py().get_type::<errors::EbivError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    let reader_options: Vec<String> = ebiv::io::READ_OPTIONS
        .iter()
        .map(|k| k.replace('-', "_"))
        .collect();
    m.add("READER_OPTIONS", reader_options)?;
    m.add_class::<recording::Recording>()?;
    m.add_class::<recording::Chunks>()?;
    m.add_function(wrap_pyfunction!(recording::open, m)?)?;
    m.add_function(wrap_pyfunction!(recording::index, m)?)?;
    m.add_function(wrap_pyfunction!(recording::py_duration_us, m)?)?;
    m.add_function(wrap_pyfunction!(measure::process, m)?)?;
    m.add_function(wrap_pyfunction!(denoise::filter, m)?)?;
    m.add_function(wrap_pyfunction!(measure::plan, m)?)?;
    m.add_function(wrap_pyfunction!(measure::piv, m)?)?;
    m.add_function(wrap_pyfunction!(measure::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(measure::assess, m)?)?;
    m.add_function(wrap_pyfunction!(measure::write, m)?)?;
    m.add_function(wrap_pyfunction!(measure::stats, m)?)?;
    m.add_function(wrap_pyfunction!(measure::derive, m)?)?;
    m.add_function(wrap_pyfunction!(measure::setting_names, m)?)?;
    m.add_function(wrap_pyfunction!(measure::examples, m)?)?;
    m.add_function(wrap_pyfunction!(live::live, m)?)?;
    m.add_function(wrap_pyfunction!(track::track, m)?)?;
    m.add_function(wrap_pyfunction!(track::bin_tracks, m)?)?;
    m.add_function(wrap_pyfunction!(track::assess_tracks, m)?)?;
    m.add_function(wrap_pyfunction!(track::track_setting_names, m)?)?;
    Ok(())
}
