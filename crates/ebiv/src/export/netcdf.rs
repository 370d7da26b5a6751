//! Vector fields as NetCDF-3 classic files: dimensions (time, y, x); coordinate variables
//! `time` (µs), `y`, `x` (px); data variables `u`, `v` (px/ms, NaN = invalid); attributes
//! stating units, the axis convention and how the field was made (CF conventions where they
//! apply). NetCDF-3 is read natively by MATLAB `ncread`, xarray and ParaView.

use crate::error::{Error, Result};
use crate::field::FieldSeries;
use netcdf3::{DataSet, FileWriter, Version};
use std::path::{Path, PathBuf};

/// `path` with `.partial` appended: outputs are written there and renamed when complete.
pub(crate) fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    path.with_file_name(name)
}

fn nc_err(path: &Path, e: impl std::fmt::Debug) -> Error {
    Error::Write {
        what: path.display().to_string(),
        message: format!("NetCDF: {e:?}"),
    }
}

/// Write `field` to `path` as NetCDF-3 (64-bit offset), through a temporary file.
pub fn write_field_netcdf(field: &FieldSeries, path: &Path) -> Result<()> {
    let (nt, ny, nx) = (field.t_us.len(), field.y.len(), field.x.len());
    let err = |e: netcdf3::error::InvalidDataSet| nc_err(path, e);
    let mut ds = DataSet::new();
    ds.add_fixed_dim("time", nt).map_err(err)?;
    ds.add_fixed_dim("y", ny).map_err(err)?;
    ds.add_fixed_dim("x", nx).map_err(err)?;
    ds.add_var_f64("time", &["time"]).map_err(err)?;
    ds.add_var_f64("y", &["y"]).map_err(err)?;
    ds.add_var_f64("x", &["x"]).map_err(err)?;
    ds.add_var_f32("u", &["time", "y", "x"]).map_err(err)?;
    ds.add_var_f32("v", &["time", "y", "x"]).map_err(err)?;
    let var_attrs: [(&str, &str, &str); 5] = [
        ("time", "units", "microseconds"),
        ("y", "units", "pixel"),
        ("x", "units", "pixel"),
        ("u", "units", "pixel/millisecond"),
        ("v", "units", "pixel/millisecond"),
    ];
    for (var, key, value) in var_attrs {
        ds.add_var_attr_string(var, key, value).map_err(err)?;
    }
    ds.add_var_attr_string("y", "positive", "down")
        .map_err(err)?;
    ds.add_var_attr_string("u", "long_name", "velocity along x (to the right)")
        .map_err(err)?;
    ds.add_var_attr_string("v", "long_name", "velocity along y (downwards, image rows)")
        .map_err(err)?;
    // No NaN `_FillValue` attribute: netcdf3 compares variables by value, and NaN never
    // equals itself. NaN data are read as NaN by MATLAB, xarray and ParaView anyway.
    for var in ["u", "v"] {
        ds.add_var_attr_string(var, "comment", "NaN where no valid vector")
            .map_err(err)?;
    }
    ds.add_global_attr_string("Conventions", "CF-1.8")
        .map_err(err)?;
    ds.add_global_attr_string(
        "axis_convention",
        "image coordinates: x to the right, y down, pixel centres at integers",
    )
    .map_err(err)?;
    ds.add_global_attr_string("software", concat!("ebiv ", env!("CARGO_PKG_VERSION")))
        .map_err(err)?;
    for (k, v) in &field.attributes {
        let key: String = k
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        ds.add_global_attr_string(&key, v).map_err(err)?;
    }
    let temp = partial_path(path);
    let times: Vec<f64> = field.t_us.iter().map(|&t| t as f64).collect();
    let werr = |e: netcdf3::error::WriteError| nc_err(path, e);
    let result = (|| {
        let mut w = FileWriter::open(&temp).map_err(werr)?;
        w.set_def(&ds, Version::Offset64Bit, 0).map_err(werr)?;
        w.write_var_f64("time", &times).map_err(werr)?;
        w.write_var_f64("y", &field.y).map_err(werr)?;
        w.write_var_f64("x", &field.x).map_err(werr)?;
        w.write_var_f32("u", &field.u).map_err(werr)?;
        w.write_var_f32("v", &field.v).map_err(werr)?;
        w.close().map_err(werr)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&temp);
        return Err(e);
    }
    std::fs::rename(&temp, path).map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn netcdf_round_trip_through_the_reader() {
        let mut f = FieldSeries::new(vec![0.0, 20.0, 40.0], vec![10.0, 30.0], vec![0, 10_000]);
        for i in 0..f.u.len() {
            f.u[i] = i as f32;
            f.v[i] = -(i as f32);
        }
        f.u[3] = f32::NAN;
        f.attributes.push(("source file".into(), "a.raw".into()));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nc");
        write_field_netcdf(&f, &path).unwrap();
        let mut r = netcdf3::FileReader::open(&path).unwrap();
        let ds = r.data_set();
        assert_eq!(ds.dim_size("time"), Some(2));
        assert_eq!(ds.dim_size("y"), Some(2));
        assert_eq!(ds.dim_size("x"), Some(3));
        assert_eq!(
            ds.get_global_attr_as_string("source_file").as_deref(),
            Some("a.raw")
        );
        let u = r.read_var_f32("u").unwrap();
        assert_eq!(u.len(), 12);
        assert!(u[3].is_nan());
        assert_eq!(u[5], 5.0);
        assert_eq!(r.read_var_f64("time").unwrap(), vec![0.0, 10_000.0]);
        assert!(!dir.path().join("f.nc.partial").exists());
    }

    #[test]
    fn csv_has_the_documented_header() {
        let f = FieldSeries::new(vec![1.0], vec![2.0], vec![5]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.csv");
        crate::export::write_field_csv(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "t_us,x,y,u,v\n5,1,2,NaN,NaN\n");
    }
}
