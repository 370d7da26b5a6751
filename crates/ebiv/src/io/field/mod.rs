//! Readers of vector fields ([`FieldSeries`]): the NetCDF, NPZ and CSV files ebiv writes, and
//! the CSV or whitespace-separated tables of other tools (OpenPIV, PIVlab and any table with
//! columns named x, y, u, v). [`read_field`] chooses the reader by content.
//!
//! Fields come back in image units, px and px/ms (or px for displacements), whatever the
//! file holds: positions in mm or m and velocities in m/s are converted with the file's own
//! calibration (ebiv's `mm_per_px`, `origin_px` and `y_positive` attributes, PIVlab's
//! "conversion factor xy") or with [`FieldReadOptions::mm_per_px`]; without either, a
//! calibrated file is an error that asks for the scale. Per-vector uncertainties (`u_unc`,
//! `v_unc`) and derived quantities ([`crate::derived`]) are read where present, back in image
//! coordinates and units, so that a series read and written again holds the same values. `docs/assess.md` lists the recognised columns.

mod columns;
mod grid;
mod netcdf;
mod npz;
mod table;

pub use columns::{Column, Role};

use crate::error::{Error, Result};
use crate::field::FieldSeries;
use std::path::Path;

/// What a field file does not say about itself.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FieldReadOptions {
    /// Millimetres per pixel, for files with physical positions or velocities (mm, m, m/s)
    /// that carry no calibration of their own.
    pub mm_per_px: Option<f64>,
    /// Time between the two frames of the pair, µs: turns displacements (px per frame,
    /// OpenPIV's and PIVlab's uncalibrated output) into velocities in px/ms.
    pub frame_interval_us: Option<f64>,
}

impl FieldReadOptions {
    /// Check the values: finite and positive where given.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("mm-per-px", self.mm_per_px),
            ("frame-interval", self.frame_interval_us),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return Err(Error::parameter(
                        name,
                        format!("must be a positive number, got {v}"),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Largest text file read, bytes (a field table of 10⁷ vectors is about 1 GB).
pub const MAX_TEXT_BYTES: u64 = 2 << 30;

/// Read the vector-field file `path`: NetCDF classic or NPZ (by their signatures) or a text
/// table.
pub fn read_field(path: &Path, options: &FieldReadOptions) -> Result<FieldSeries> {
    options.validate()?;
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::unsupported(
            path.display().to_string(),
            "is a folder, not a vector-field file",
        ));
    }
    let mut magic = [0u8; 4];
    {
        use std::io::Read;
        let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut got = 0;
        while got < 4 {
            match f.read(&mut magic[got..]) {
                Ok(0) => break,
                Ok(k) => got += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(Error::io(path, e)),
            }
        }
    }
    let context = path.display().to_string();
    if magic.starts_with(b"CDF") {
        return netcdf::read(path, options);
    }
    if magic == *b"\x89HDF" {
        return Err(Error::unsupported(
            context,
            "NetCDF-4/HDF5 files are not read; convert to NetCDF classic first \
             (`nccopy -k classic in.nc out.nc`, or xarray `to_netcdf(format=\"NETCDF3_64BIT\")`)",
        ));
    }
    if magic.starts_with(b"PK") {
        return npz::read(path, options);
    }
    if magic.starts_with(b"\x93NUM") {
        return Err(Error::unsupported(
            context,
            "a single NumPy array is not a vector field; write the field as .nc, .npz or .csv",
        ));
    }
    if meta.len() > MAX_TEXT_BYTES {
        return Err(Error::unsupported(
            context,
            format!(
                "a text table of {} bytes is larger than the {} bytes read; write NetCDF",
                meta.len(),
                MAX_TEXT_BYTES
            ),
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8_lossy(&bytes);
    table::read_str(&text, &context, options)
}

/// Read a vector-field table from text (see [`read_field`]); `context` names it in errors.
pub fn read_field_str(
    text: &str,
    context: &str,
    options: &FieldReadOptions,
) -> Result<FieldSeries> {
    options.validate()?;
    table::read_str(text, context, options)
}

/// The status of fields read without one (a ground truth, another tool's file): valid
/// where both components are finite, [`crate::field::Status::NO_EVENTS`] elsewhere.
fn status_from_values(u: &[f32], v: &[f32]) -> Vec<crate::field::Status> {
    use crate::field::Status;
    u.iter()
        .zip(v)
        .map(|(u, v)| {
            if u.is_finite() && v.is_finite() {
                Status::VALID
            } else {
                Status::NO_EVENTS
            }
        })
        .collect()
}

/// Event counts and slab lengths stored as numbers: non-negative whole counts, 0 for what
/// is not a finite positive number, at most `u32::MAX`.
fn counts_from_values(v: Vec<f64>) -> Vec<u32> {
    v.iter()
        .map(|&c| {
            if c.is_finite() && c > 0.0 {
                c.min(u32::MAX as f64) as u32
            } else {
                0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
