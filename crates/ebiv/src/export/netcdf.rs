//! Vector fields as NetCDF-3 files (64-bit offset; Unidata NetCDF "Classic and 64-bit
//! Offset" format specification), following the CF conventions (CF-1.8) where they apply.
//!
//! Dimensions `(time, y, x)`. Coordinate variables `time`, `y`, `x` (px, or mm with a
//! calibration, then also `x_px`, `y_px`); data variables `u`, `v` (px/ms or m/s, NaN =
//! invalid), `u_unc`, `v_unc` (`float`, in the units of `u`, `v`: their standard uncertainty,
//! one standard deviation, NaN where unknown and for invalid and replaced vectors; scaled by a
//! calibration, never negated), `status` (`short`, CF flag variable: `flag_masks`,
//! `flag_meanings`), `peak`, `peak_ratio` (`float`), `event_count` (`int`), `slab_us` (`int`,
//! units `us`: the time slab each vector was measured over, see [`FieldSeries::slab_us`]). A
//! ground truth ([`FieldSeries::ground_truth`]) has only `u` and `v`: it has no uncertainty,
//! status, quality or slab.
//!
//! `time` is a CF time coordinate (`standard_name = "time"`, `calendar`, units
//! `microseconds since 1970-01-01 00:00:00`) on the recording's camera clock: CF needs a
//! reference date, and the date stands for the zero of that clock, which is a real date only
//! for recordings stamped in Unix time (AEDAT 4). Its `comment` says so and relates the times
//! to `ebiv process --time` (the global `time_origin_us`). xarray decodes such a coordinate to
//! dates; `decode_times=False` keeps the microseconds. For image pairs, which carry no time
//! stamps, `time` is the index of the field (units `1`, no `standard_name`).
//!
//! `x` and `y` carry no CF `positive` attribute (CF reserves it for vertical coordinates);
//! their `long_name` and the global `axis_convention` say which way they point. Global
//! attributes also state the software, the field time, the status legend, the calibration
//! and every attribute of the series; a series attribute identical to one the writer sets
//! is not repeated. NetCDF-3 is read natively by MATLAB `ncread`, xarray and ParaView.

use super::{axis_convention, check, partial_path, sanitize_name, time_comment, Written, SOFTWARE};
use crate::derived::DerivedQuantity;
use crate::error::{Error, Result};
use crate::field::{FieldSeries, Status, TimeBasis};
use netcdf3::{DataSet, FileWriter, Version};
use std::path::Path;

pub(crate) fn nc_err(path: &Path, e: impl std::fmt::Debug) -> Error {
    Error::Write {
        what: path.display().to_string(),
        message: format!("NetCDF: {e:?}"),
    }
}

/// Global attributes the writer may set itself; series attributes of the same (sanitised)
/// name are left out when their value is the writer's, else written with a `user_` prefix.
/// The reader ([`crate::io::field`]) does not copy them back into a series' attributes.
pub(crate) const OWN_GLOBALS: [&str; 10] = [
    "Conventions",
    "axis_convention",
    "software",
    "field_time",
    "status_flags",
    "mm_per_px",
    "origin_px",
    "y_positive",
    "time_origin_us",
    "title",
];

/// Units of a CF time coordinate on the camera clock: CF needs a reference date, which here
/// stands for the zero of the recording's clock (see the module documentation).
pub const TIME_UNITS: &str = "microseconds since 1970-01-01 00:00:00";

/// Write `field` to `path` as NetCDF-3 (64-bit offset), through a temporary file: the
/// variables and attributes of [`netcdf_dataset`].
pub fn write_field_netcdf(field: &FieldSeries, path: &Path) -> Result<()> {
    check(field)?;
    let dataset = netcdf_dataset(field).map_err(|message| Error::Write {
        what: path.display().to_string(),
        message: format!("NetCDF: {message}"),
    })?;
    write_dataset_netcdf(&dataset, path)
}

/// Write `dataset` to `path` as NetCDF-3 (64-bit offset), through a temporary file.
pub fn write_dataset_netcdf(dataset: &Dataset, path: &Path) -> Result<()> {
    let ds = define_dataset(dataset, None, path)?;
    let temp = partial_path(path);
    let werr = |e: netcdf3::error::WriteError| nc_err(path, e);
    let result = (|| {
        let mut w = FileWriter::open(&temp).map_err(werr)?;
        w.set_def(&ds, Version::Offset64Bit, 0).map_err(werr)?;
        for var in &dataset.variables {
            write_variable(&mut w, var).map_err(werr)?;
        }
        w.close().map_err(werr)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&temp);
        return Err(e);
    }
    std::fs::rename(&temp, path).map_err(|e| Error::io(path, e))
}

/// Write all the values of `var` (defined in `w`'s header).
pub(crate) fn write_variable(
    w: &mut FileWriter<'_>,
    var: &Variable,
) -> std::result::Result<(), netcdf3::error::WriteError> {
    match &var.values {
        Values::F64(v) => w.write_var_f64(&var.name, v),
        Values::F32(v) => w.write_var_f32(&var.name, v),
        Values::I16(v) => w.write_var_i16(&var.name, v),
        Values::I32(v) => w.write_var_i32(&var.name, v),
    }
}

/// The NetCDF-3 definition (dimensions, variables, attributes) of `dataset`; with
/// `records`, that dimension is the unlimited one, of length 0 (records are appended).
pub(crate) fn define_dataset(
    dataset: &Dataset,
    records: Option<&str>,
    path: &Path,
) -> Result<DataSet> {
    let err = |e: netcdf3::error::InvalidDataSet| nc_err(path, e);
    let mut ds = DataSet::new();
    for (name, len) in &dataset.dims {
        if records == Some(name.as_str()) {
            ds.set_unlimited_dim(name, 0).map_err(err)?;
        } else {
            ds.add_fixed_dim(name, *len).map_err(err)?;
        }
    }
    for var in &dataset.variables {
        let dims = &var.dims;
        match &var.values {
            Values::F64(_) => ds.add_var_f64(&var.name, dims),
            Values::F32(_) => ds.add_var_f32(&var.name, dims),
            Values::I16(_) => ds.add_var_i16(&var.name, dims),
            Values::I32(_) => ds.add_var_i32(&var.name, dims),
        }
        .map_err(err)?;
        for (key, value) in &var.attributes {
            match value {
                Attribute::Text(text) => ds.add_var_attr_string(&var.name, key, text),
                Attribute::F64(v) => ds.add_var_attr_f64(&var.name, key, v.clone()),
                Attribute::I16(v) => ds.add_var_attr_i16(&var.name, key, v.clone()),
            }
            .map_err(err)?;
        }
    }
    for (key, value) in &dataset.attributes {
        match value {
            Attribute::Text(text) => ds.add_global_attr_string(key, text),
            Attribute::F64(v) => ds.add_global_attr_f64(key, v.clone()),
            Attribute::I16(v) => ds.add_global_attr_i16(key, v.clone()),
        }
        .map_err(err)?;
    }
    Ok(ds)
}

/// The values of one variable, in the NetCDF type they are stored as.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    /// `double`.
    F64(Vec<f64>),
    /// `float`.
    F32(Vec<f32>),
    /// `short`.
    I16(Vec<i16>),
    /// `int`.
    I32(Vec<i32>),
}

/// The value of an attribute.
#[derive(Debug, Clone, PartialEq)]
pub enum Attribute {
    /// Text.
    Text(String),
    /// `double` values.
    F64(Vec<f64>),
    /// `short` values.
    I16(Vec<i16>),
}

/// One variable of a [`Dataset`]: its values in row-major order over `dims`.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// The variable's name.
    pub name: String,
    /// Its dimensions, slowest first.
    pub dims: Vec<String>,
    /// Its values.
    pub values: Values,
    /// Its attributes, in the file's order.
    pub attributes: Vec<(String, Attribute)>,
}

/// Everything the NetCDF file of a series holds, before it is encoded: what the writer
/// writes, and what the Python package turns into an `xarray.Dataset`, so that the two
/// have the same variables, attributes and units.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Dimensions and their lengths.
    pub dims: Vec<(String, usize)>,
    /// Coordinate variables first, then data variables.
    pub variables: Vec<Variable>,
    /// Global attributes.
    pub attributes: Vec<(String, Attribute)>,
}

/// The NetCDF dataset of `field` (see the module documentation); an error message when a
/// value does not fit the file's types.
pub fn netcdf_dataset(field: &FieldSeries) -> std::result::Result<Dataset, String> {
    check(field).map_err(|e| e.to_string())?;
    let (nt, ny, nx) = (field.t_us.len(), field.y.len(), field.x.len());
    let event_count: Vec<i32> = field
        .event_count
        .iter()
        .map(|&c| i32::try_from(c))
        .collect::<Result<_, _>>()
        .map_err(|_| "an event count exceeds the NetCDF int range")?;
    let slab_us: Vec<i32> = field
        .slab_us
        .iter()
        .map(|&c| i32::try_from(c))
        .collect::<Result<_, _>>()
        .map_err(|_| "a slab length (slab_us) exceeds the NetCDF int range")?;
    let written = Written::new(field);
    let calibrated = field.calibration.is_some();
    let quality = !field.ground_truth;
    let grid = || vec!["time", "y", "x"];
    let mut variables = vec![
        variable(
            "time",
            vec!["time"],
            Values::F64(field.t_us.iter().map(|&t| t as f64).collect()),
        ),
        variable("y", vec!["y"], Values::F64(written.y.to_vec())),
        variable("x", vec!["x"], Values::F64(written.x.to_vec())),
    ];
    if calibrated {
        variables.push(variable("y_px", vec!["y"], Values::F64(field.y.clone())));
        variables.push(variable("x_px", vec!["x"], Values::F64(field.x.clone())));
    }
    variables.push(variable("u", grid(), Values::F32(written.u.to_vec())));
    variables.push(variable("v", grid(), Values::F32(written.v.to_vec())));
    if quality {
        let status = field.status.iter().map(|s| s.0 as i16).collect();
        variables.extend([
            variable("u_unc", grid(), Values::F32(written.u_unc.to_vec())),
            variable("v_unc", grid(), Values::F32(written.v_unc.to_vec())),
            variable("status", grid(), Values::I16(status)),
            variable("peak", grid(), Values::F32(field.peak.clone())),
            variable("peak_ratio", grid(), Values::F32(field.peak_ratio.clone())),
            variable("event_count", grid(), Values::I32(event_count)),
            variable("slab_us", grid(), Values::I32(slab_us)),
        ]);
    }
    for (var, key, value) in variable_attributes(field) {
        let v = variables
            .iter_mut()
            .find(|v| v.name == var)
            .expect("attributes name variables of the dataset");
        v.attributes.push((key.into(), value));
    }
    variables.extend(derived_variables(field));
    Ok(Dataset {
        dims: vec![("time".into(), nt), ("y".into(), ny), ("x".into(), nx)],
        variables,
        attributes: global_attributes(field),
    })
}

/// The derived quantities of `field` ([`crate::derived`]) as written: in 1/s with a
/// calibration, 1/ms without (1 for displacements), odd quantities flipped with y.
fn derived_variables(field: &FieldSeries) -> Vec<Variable> {
    let unit = DerivedQuantity::unit(field.quantity, field.calibration.as_ref());
    let y_up = field.calibration.is_some_and(|c| c.y_up);
    field
        .derived
        .iter()
        .map(|d| {
            let mut v = variable(
                d.quantity.name(),
                vec!["time", "y", "x"],
                Values::F32(DerivedQuantity::written(d, field)),
            );
            v.attributes = vec![
                (
                    "long_name".into(),
                    Attribute::Text(d.quantity.long_name(y_up)),
                ),
                ("units".into(), Attribute::Text(unit.into())),
                (
                    "comment".into(),
                    Attribute::Text(crate::derived::SCHEME.into()),
                ),
            ];
            v
        })
        .collect()
}

fn variable(name: &str, dims: Vec<&str>, values: Values) -> Variable {
    Variable {
        name: name.into(),
        dims: dims.into_iter().map(String::from).collect(),
        values,
        attributes: Vec::new(),
    }
}

/// `(variable, key, value)` of every variable attribute, in the file's order.
fn variable_attributes(field: &FieldSeries) -> Vec<(&'static str, &'static str, Attribute)> {
    let calibrated = field.calibration.is_some();
    let quality = !field.ground_truth;
    let displacement = field.quantity == crate::field::Quantity::Displacement;
    let (length, velocity) = match (calibrated, displacement) {
        (true, false) => ("mm", "m/s"),
        (true, true) => ("mm", "mm"),
        (false, false) => ("pixel", "pixel/millisecond"),
        (false, true) => ("pixel", "pixel"),
    };
    let noun = if displacement {
        "displacement"
    } else {
        "velocity"
    };
    let y_positive = match &field.calibration {
        Some(c) if c.y_up => "up",
        _ => "down",
    };
    let y_direction = match &field.calibration {
        Some(c) if c.y_up => "up",
        Some(_) => "down",
        None => "down: image rows",
    };
    let position = if field.ground_truth {
        "grid node"
    } else {
        "window centre"
    };
    let mut text_attrs: Vec<(&str, &str, String)> = Vec::new();
    if field.time_basis.is_camera_time() {
        text_attrs.extend([
            ("time", "standard_name", "time".into()),
            ("time", "units", TIME_UNITS.into()),
            ("time", "calendar", "proleptic_gregorian".into()),
            ("time", "axis", "T".into()),
        ]);
    } else {
        text_attrs.push(("time", "units", "1".into()));
    }
    text_attrs.extend([
        (
            "time",
            "long_name",
            match field.time_basis {
                TimeBasis::SlabCentre => "time of the field: centre of its time slab",
                TimeBasis::FrameCentre => "time of the field: centre of its frames' time span",
                TimeBasis::Instant => "time of the field",
                TimeBasis::PairIndex => "index of the field (one per image pair)",
            }
            .into(),
        ),
        ("time", "comment", time_comment(field)),
        ("y", "units", length.into()),
        ("y", "axis", "Y".into()),
        ("y", "long_name", format!("{position}, y ({y_direction})")),
        ("x", "units", length.into()),
        ("x", "axis", "X".into()),
        ("x", "long_name", format!("{position}, x (to the right)")),
        ("u", "units", velocity.into()),
        ("u", "long_name", format!("{noun} along x (to the right)")),
        ("v", "units", velocity.into()),
        (
            "v",
            "long_name",
            format!("{noun} along y (positive {y_positive})"),
        ),
    ]);
    if quality {
        text_attrs.extend([
            ("u_unc", "units", velocity.into()),
            (
                "u_unc",
                "long_name",
                "standard uncertainty of u (one standard deviation)".into(),
            ),
            ("v_unc", "units", velocity.into()),
            (
                "v_unc",
                "long_name",
                "standard uncertainty of v (one standard deviation)".into(),
            ),
            ("status", "long_name", "vector status flags".into()),
            (
                "status",
                "flag_meanings",
                Status::NAMES
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(" "),
            ),
            (
                "status",
                "comment",
                format!("0 valid; bits: {}", Status::legend()),
            ),
            (
                "peak",
                "long_name",
                "peak of the correlation plane or objective".into(),
            ),
            (
                "peak_ratio",
                "long_name",
                "first-to-second peak ratio".into(),
            ),
            ("peak_ratio", "units", "1".into()),
            (
                "peak_ratio",
                "comment",
                "NaN where not defined; below 1: valid vector re-evaluated on a lower peak \
                 (multiple-peak validation), its height over the highest peak"
                    .into(),
            ),
            (
                "event_count",
                "long_name",
                "events used in the window".into(),
            ),
            ("event_count", "units", "1".into()),
            (
                "slab_us",
                "long_name",
                "time span the vector was measured over".into(),
            ),
            ("slab_us", "units", "us".into()),
            (
                "slab_us",
                "comment",
                field.time_basis.describe_slab().into(),
            ),
        ]);
    }
    if calibrated {
        text_attrs.extend([
            ("y_px", "units", "pixel".into()),
            (
                "y_px",
                "long_name",
                "window centre, image row (down)".into(),
            ),
            ("x_px", "units", "pixel".into()),
            ("x_px", "long_name", "window centre, image column".into()),
        ]);
    }
    // No NaN `_FillValue` attribute: netcdf3 compares variables by value, and NaN never
    // equals itself. NaN data are read as NaN by MATLAB, xarray and ParaView anyway.
    if quality {
        for var in ["u", "v"] {
            text_attrs.push((var, "comment", "NaN where no valid vector".into()));
        }
        for var in ["u_unc", "v_unc"] {
            text_attrs.push((
                var,
                "comment",
                "NaN where unknown, and for invalid and replaced vectors".into(),
            ));
        }
    }
    let mut attributes: Vec<(&str, &str, Attribute)> = text_attrs
        .into_iter()
        .map(|(var, key, value)| (var, key, Attribute::Text(value)))
        .collect();
    if quality {
        let masks: Vec<i16> = Status::NAMES.iter().map(|(_, s)| s.0 as i16).collect();
        attributes.push(("status", "flag_masks", Attribute::I16(masks)));
        attributes.push(("status", "valid_range", Attribute::I16(vec![0, 255])));
    }
    attributes
}

/// The global attributes, in the file's order: the writer's own, then the series'.
fn global_attributes(field: &FieldSeries) -> Vec<(String, Attribute)> {
    let quality = !field.ground_truth;
    let title = if field.ground_truth {
        "ebiv ground-truth velocity field series"
    } else {
        "ebiv vector field series"
    };
    let mut own: Vec<(&str, String)> = vec![
        ("Conventions", "CF-1.8".into()),
        ("title", title.into()),
        ("axis_convention", axis_convention(field)),
        ("software", SOFTWARE.into()),
        ("field_time", field.time_basis.describe().into()),
    ];
    if quality {
        own.push(("status_flags", Status::legend()));
    }
    let mut attributes: Vec<(String, Attribute)> = own
        .iter()
        .map(|(key, value)| (key.to_string(), Attribute::Text(value.clone())))
        .collect();
    if let Some(origin) = field.time_origin_us {
        attributes.push(("time_origin_us".into(), Attribute::F64(vec![origin as f64])));
    }
    if let Some(c) = &field.calibration {
        let y_positive = if c.y_up { "up" } else { "down" };
        attributes.extend([
            ("mm_per_px".into(), Attribute::F64(vec![c.mm_per_px])),
            ("origin_px".into(), Attribute::F64(c.origin_px.to_vec())),
            ("y_positive".into(), Attribute::Text(y_positive.into())),
        ]);
    }
    for (k, v) in &field.attributes {
        let mut key = sanitize_name(k);
        if own.iter().any(|(ok, ov)| *ok == key && ov == v) {
            continue;
        }
        if OWN_GLOBALS.contains(&key.as_str()) {
            key = format!("user_{key}");
        }
        let base = key.clone();
        let mut i = 2;
        while attributes.iter().any(|(k, _)| *k == key) {
            key = format!("{base}_{i}");
            i += 1;
        }
        attributes.push((key, Attribute::Text(v.clone())));
    }
    attributes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Calibration;

    fn series() -> FieldSeries {
        let mut f = FieldSeries::new(vec![0.0, 20.0, 40.0], vec![10.0, 30.0], vec![0, 10_000]);
        for i in 0..f.u.len() {
            f.u[i] = i as f32;
            f.v[i] = -(i as f32);
            f.u_unc[i] = 0.01 * i as f32;
            f.v_unc[i] = 0.02 * i as f32;
            f.status[i] = Status::VALID;
            f.peak[i] = 0.5 + i as f32;
            f.peak_ratio[i] = 1.5;
            f.event_count[i] = 100 + i as u32;
            f.slab_us[i] = 10_000;
        }
        f.slab_us[3] = 0;
        f.u[3] = f32::NAN;
        f.v[3] = f32::NAN;
        f.u_unc[3] = f32::NAN;
        f.v_unc[3] = f32::NAN;
        f.status[3] = Status::NO_EVENTS | Status::MASKED;
        f.peak_ratio[3] = f32::NAN;
        f.status[7] = Status::MEDIAN_TEST | Status::REPLACED;
        f.attributes.push(("source file".into(), "a.raw".into()));
        f.attributes
            .push(("software".into(), "something else".into()));
        f
    }

    #[test]
    fn netcdf_round_trip_through_the_reader() {
        let f = series();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nc");
        write_field_netcdf(&f, &path).unwrap();
        let (ds, _) = netcdf3::FileReader::open(&path).unwrap().close();
        let mut r = netcdf3::FileReader::open(&path).unwrap();
        assert_eq!(ds.dim_size("time"), Some(2));
        assert_eq!(ds.dim_size("y"), Some(2));
        assert_eq!(ds.dim_size("x"), Some(3));
        assert_eq!(
            ds.get_global_attr_as_string("source_file").as_deref(),
            Some("a.raw")
        );
        assert_eq!(
            ds.get_global_attr_as_string("software").as_deref(),
            Some(SOFTWARE)
        );
        assert_eq!(
            ds.get_global_attr_as_string("user_software").as_deref(),
            Some("something else")
        );
        assert!(!ds.has_var("x_px"));
        assert_eq!(
            ds.get_var_attr_as_string("u", "units").as_deref(),
            Some("pixel/millisecond")
        );
        assert_eq!(
            ds.get_var_attr_i16("status", "flag_masks"),
            Some(&[1i16, 2, 4, 8, 16, 32, 64, 128][..])
        );
        assert_eq!(
            ds.get_var_attr_as_string("status", "flag_meanings")
                .unwrap()
                .split(' ')
                .count(),
            8
        );
        let u = r.read_var_f32("u").unwrap();
        assert_eq!(u.len(), 12);
        assert!(u[3].is_nan());
        assert_eq!(u[5], 5.0);
        assert_eq!(r.read_var_f32("v").unwrap()[5], -5.0);
        let (u_unc, v_unc) = (
            r.read_var_f32("u_unc").unwrap(),
            r.read_var_f32("v_unc").unwrap(),
        );
        assert_eq!((u_unc[5], v_unc[5]), (f.u_unc[5], f.v_unc[5]));
        assert!(u_unc[3].is_nan() && v_unc[3].is_nan());
        for var in ["u_unc", "v_unc"] {
            assert_eq!(
                ds.get_var_attr_as_string(var, "units").as_deref(),
                Some("pixel/millisecond")
            );
            let long_name = ds.get_var_attr_as_string(var, "long_name").unwrap();
            assert!(
                long_name.starts_with("standard uncertainty of"),
                "{long_name}"
            );
            assert_eq!(ds.get_var(var).unwrap().dim_names(), ["time", "y", "x"]);
        }
        assert_eq!(r.read_var_f64("time").unwrap(), vec![0.0, 10_000.0]);
        assert_eq!(r.read_var_f64("x").unwrap(), f.x);
        let status = r.read_var_i16("status").unwrap();
        assert_eq!(status[3], 129);
        assert_eq!(status[7], 72);
        assert_eq!(status[0], 0);
        assert_eq!(r.read_var_f32("peak").unwrap(), f.peak);
        let ratio = r.read_var_f32("peak_ratio").unwrap();
        assert!(ratio[3].is_nan() && ratio[4] == 1.5);
        let counts = r.read_var_i32("event_count").unwrap();
        assert_eq!(counts[11], 111);
        let slabs = r.read_var_i32("slab_us").unwrap();
        assert_eq!((slabs[3], slabs[11]), (0, 10_000));
        assert_eq!(
            ds.get_var_attr_as_string("slab_us", "units").as_deref(),
            Some("us")
        );
        let comment = ds.get_var_attr_as_string("slab_us", "comment").unwrap();
        assert!(comment.contains("sub-volumes"), "{comment}");
        assert!(!dir.path().join("f.nc.partial").exists());
    }

    #[test]
    fn calibrated_netcdf_is_in_mm_and_m_per_s_with_pixel_coordinates_kept() {
        let mut f = series();
        f.calibration = Some(Calibration {
            mm_per_px: 0.1,
            origin_px: [20.0, 10.0],
            y_up: true,
        });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nc");
        write_field_netcdf(&f, &path).unwrap();
        let (ds, _) = netcdf3::FileReader::open(&path).unwrap().close();
        let mut r = netcdf3::FileReader::open(&path).unwrap();
        assert_eq!(
            ds.get_var_attr_as_string("u", "units").as_deref(),
            Some("m/s")
        );
        assert_eq!(
            ds.get_var_attr_as_string("x", "units").as_deref(),
            Some("mm")
        );
        assert_eq!(
            ds.get_var_attr_as_string("y", "long_name").as_deref(),
            Some("window centre, y (up)")
        );
        assert_eq!(
            ds.get_global_attr_as_string("y_positive").as_deref(),
            Some("up")
        );
        assert_eq!(ds.get_global_attr_f64("mm_per_px"), Some(&[0.1][..]));
        assert_eq!(ds.get_global_attr_f64("origin_px"), Some(&[20.0, 10.0][..]));
        let x = r.read_var_f64("x").unwrap();
        let y = r.read_var_f64("y").unwrap();
        assert!((x[0] + 2.0).abs() < 1e-12 && (x[2] - 2.0).abs() < 1e-12);
        // Row 30 px lies 20 px below the origin: 2 mm down, i.e. y = -2 mm with y up.
        assert!(y[0].abs() < 1e-12 && (y[1] + 2.0).abs() < 1e-12);
        assert_eq!(r.read_var_f64("x_px").unwrap(), f.x);
        assert_eq!(r.read_var_f64("y_px").unwrap(), f.y);
        let u = r.read_var_f32("u").unwrap();
        let v = r.read_var_f32("v").unwrap();
        assert!((u[5] - 0.5).abs() < 1e-6);
        // Image v = -5 px/ms (upwards) becomes +0.5 m/s with y up.
        assert!((v[5] - 0.5).abs() < 1e-6);
        assert!(u[3].is_nan() && v[3].is_nan());
        // The uncertainties are scaled (0.05 and 0.1 px/ms → 0.005 and 0.01 m/s), not flipped.
        let (u_unc, v_unc) = (
            r.read_var_f32("u_unc").unwrap(),
            r.read_var_f32("v_unc").unwrap(),
        );
        assert!((u_unc[5] - 0.005).abs() < 1e-7 && (v_unc[5] - 0.01).abs() < 1e-7);
        assert!(u_unc[3].is_nan() && v_unc[3].is_nan());
        assert_eq!(
            ds.get_var_attr_as_string("v_unc", "units").as_deref(),
            Some("m/s")
        );
        assert_eq!(r.read_var_i16("status").unwrap()[3], 129);
    }

    #[test]
    fn time_is_a_cf_time_coordinate_and_x_y_carry_no_positive() {
        let mut f = series();
        f.time_origin_us = Some(1_000_000);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nc");
        write_field_netcdf(&f, &path).unwrap();
        let (ds, _) = netcdf3::FileReader::open(&path).unwrap().close();
        let attr = |var: &str, key: &str| ds.get_var_attr_as_string(var, key);
        assert_eq!(
            attr("time", "units").as_deref(),
            Some("microseconds since 1970-01-01 00:00:00")
        );
        assert_eq!(attr("time", "standard_name").as_deref(), Some("time"));
        assert_eq!(
            attr("time", "calendar").as_deref(),
            Some("proleptic_gregorian")
        );
        let comment = attr("time", "comment").unwrap();
        assert!(
            comment.contains("camera clock") && comment.contains("1000000 us"),
            "{comment}"
        );
        assert_eq!(ds.get_global_attr_f64("time_origin_us"), Some(&[1e6][..]));
        for var in ["x", "y"] {
            assert_eq!(attr(var, "positive"), None, "{var}");
        }
        assert_eq!(
            attr("y", "long_name").as_deref(),
            Some("window centre, y (down: image rows)")
        );
    }

    #[test]
    fn series_attributes_equal_to_the_writers_are_not_repeated() {
        let mut f = series();
        f.attributes.retain(|(k, _)| k != "software");
        f.attributes.push(("software".into(), SOFTWARE.into()));
        f.attributes.push(("status_flags".into(), Status::legend()));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nc");
        write_field_netcdf(&f, &path).unwrap();
        let (ds, _) = netcdf3::FileReader::open(&path).unwrap().close();
        assert!(ds.has_global_attr("software") && ds.has_global_attr("status_flags"));
        assert!(!ds.has_global_attr("user_software"));
        assert!(!ds.has_global_attr("user_status_flags"));
    }

    #[test]
    fn image_pair_series_has_an_index_not_a_camera_time() {
        let mut f = series();
        f.time_basis = TimeBasis::PairIndex;
        f.quantity = crate::field::Quantity::Displacement;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nc");
        write_field_netcdf(&f, &path).unwrap();
        let (ds, _) = netcdf3::FileReader::open(&path).unwrap().close();
        let attr = |var: &str, key: &str| ds.get_var_attr_as_string(var, key);
        assert_eq!(attr("time", "units").as_deref(), Some("1"));
        assert_eq!(attr("time", "standard_name"), None);
        assert_eq!(attr("time", "calendar"), None);
        let long_name = attr("time", "long_name").unwrap();
        assert!(long_name.contains("image pair"), "{long_name}");
        assert!(!long_name.contains("slab"), "{long_name}");
        let field_time = ds.get_global_attr_as_string("field_time").unwrap();
        assert!(field_time.contains("index") && !field_time.contains("slab"));
        assert_eq!(attr("u", "units").as_deref(), Some("pixel"));
    }

    #[test]
    fn ground_truth_has_no_status_or_quality_variables() {
        let mut f = series();
        f.ground_truth = true;
        f.time_basis = TimeBasis::Instant;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("truth.nc");
        write_field_netcdf(&f, &path).unwrap();
        let (ds, _) = netcdf3::FileReader::open(&path).unwrap().close();
        for var in [
            "u_unc",
            "v_unc",
            "status",
            "peak",
            "peak_ratio",
            "event_count",
            "slab_us",
        ] {
            assert!(!ds.has_var(var), "{var}");
        }
        assert!(!ds.has_global_attr("status_flags"));
        assert!(ds.has_var("u") && ds.has_var("v"));
        let mut r = netcdf3::FileReader::open(&path).unwrap();
        assert_eq!(r.read_var_f32("u").unwrap()[5], 5.0);
    }

    #[test]
    fn event_counts_and_slabs_beyond_int_are_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nc");
        let mut f = series();
        f.event_count[0] = u32::MAX;
        assert!(write_field_netcdf(&f, &path).is_err());
        assert!(!path.exists());
        let mut f = series();
        f.slab_us[0] = i32::MAX as u32 + 1;
        let e = write_field_netcdf(&f, &path).unwrap_err();
        assert!(e.to_string().contains("slab_us"), "{e}");
        assert!(!path.exists());
    }
}
