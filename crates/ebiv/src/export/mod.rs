//! Writers for vector fields ([`FieldSeries`]): NetCDF (MATLAB `ncread`, xarray, ParaView),
//! NumPy `.npz`, CSV, Tecplot ASCII and legacy VTK, chosen by [`write_field`] from the file
//! extension.
//!
//! Every writer states the axis convention, the units and what the field times are
//! ([`TimeBasis`](crate::field::TimeBasis)), writes invalid vectors as NaN (or, where the
//! format cannot carry NaN, as documented per format) next to the status flags, applies the
//! series' [`Calibration`](crate::field::Calibration) the same way (positions in mm,
//! velocities in m/s, `y` and `v` flipped together when `y_up`), and writes through a
//! temporary `<name>.partial` file that is renamed when complete. Every writer carries the
//! standard uncertainty of each vector (`u_unc`, `v_unc`: one standard deviation, in the unit
//! of `u` and `v`, NaN where unknown); a calibration scales it like the velocity but never
//! flips its sign. VTK files always have y up (a y-down series is written with y and v
//! negated, `v_unc` kept) so that ParaView does not show the image mirrored; see
//! [`write_field_vtk`]. A ground truth ([`FieldSeries::ground_truth`]) is written without
//! uncertainty, status and quality variables by the NetCDF and CSV writers.

mod csv;
mod live;
mod live_view;
pub(crate) mod netcdf;
pub(crate) mod npz;
mod statistics;
mod tecplot;
mod tracks;
mod vtk;

pub use self::csv::{csv_header, write_field_csv, CSV_HEADER};
pub use self::live::{LiveOutputs, LiveWriter};
pub use self::live_view::{LiveView, LIVE_VIEW_INTERVAL};
pub use self::netcdf::{
    netcdf_dataset, write_dataset_netcdf, write_field_netcdf, Attribute, Dataset, Values, Variable,
};
pub use self::npz::write_field_npz;
pub use self::statistics::{statistics_dataset, write_statistics};
pub use self::tecplot::{write_field_tecplot, TECPLOT_MISSING};
pub use self::tracks::{
    read_tracks_csv, read_truth_tracks_csv, track_csv_header, tracks_dataset, write_tracks_npz,
    TrackFormat, TrackTable, TrackWriter, TRACK_COLUMNS,
};
pub use self::vtk::{vtk_series_paths, write_field_vtk};

use crate::error::{Error, Result};
use crate::field::{Calibration, FieldSeries, Quantity, Status};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// File extensions [`write_field`] understands, with the format each selects.
pub const FIELD_EXTENSIONS: [(&str, &str); 6] = [
    ("nc", "NetCDF-3"),
    ("npz", "NumPy"),
    ("csv", "CSV"),
    ("dat", "Tecplot ASCII"),
    ("tec", "Tecplot ASCII"),
    ("vtk", "legacy VTK"),
];

/// Write `field` in the format given by the extension of `path` (case-insensitive): `.nc`
/// ([`write_field_netcdf`]), `.npz` ([`write_field_npz`]), `.csv` ([`write_field_csv`]),
/// `.dat` or `.tec` ([`write_field_tecplot`]), `.vtk` ([`write_field_vtk`]).
pub fn write_field(field: &FieldSeries, path: &Path) -> Result<()> {
    let extension = field_extension(path)?;
    if !field.derived.is_empty() {
        crate::derived::check_output(path)?;
    }
    match extension.as_str() {
        "nc" => write_field_netcdf(field, path),
        "npz" => write_field_npz(field, path),
        "csv" => write_field_csv(field, path),
        "dat" | "tec" => write_field_tecplot(field, path),
        _ => write_field_vtk(field, path), // "vtk", the last known extension
    }
}

/// Check, before any work, that `path` can be written: its folder exists and is a folder, and
/// the path itself is not a folder. A run that would fail only when it writes its result fails
/// here instead, before the processing.
pub fn check_output_path(path: &Path) -> Result<()> {
    let what = path.display().to_string();
    if path.is_dir() {
        return Err(crate::Error::Write {
            what,
            message: "it is a folder; give a file name".into(),
        });
    }
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !folder.is_dir() {
        return Err(crate::Error::Write {
            what,
            message: format!(
                "the folder `{}` does not exist (create it first, or choose another output)",
                folder.display()
            ),
        });
    }
    Ok(())
}

/// The lower-case extension of `path` if [`write_field`] knows it (one of
/// [`FIELD_EXTENSIONS`]), else an error listing the known ones: a caller checks its output
/// with it before the work that produces the field.
pub fn field_extension(path: &Path) -> Result<String> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if FIELD_EXTENSIONS.iter().any(|(e, _)| *e == ext) {
        return Ok(ext);
    }
    let known = FIELD_EXTENSIONS
        .iter()
        .map(|(e, f)| format!(".{e} ({f})"))
        .collect::<Vec<_>>()
        .join(", ");
    let seen = if ext.is_empty() {
        "no extension".to_string()
    } else {
        format!("the extension `.{ext}`")
    };
    Err(Error::unsupported(
        path.display().to_string(),
        format!("cannot tell the field format from {seen}; use one of {known}"),
    ))
}

/// Ground-truth particle tracks as CSV: header `id,t_us,x,y,z,u,v` (px, µs, px/ms).
pub fn write_tracks_csv(tracks: &[crate::sim::simulation::TrackPoint], path: &Path) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "id,t_us,x,y,z,u,v")?;
        for p in tracks {
            writeln!(
                w,
                "{},{},{},{},{},{},{}",
                p.id, p.t_us, p.x, p.y, p.z, p.u, p.v
            )?;
        }
        Ok(())
    })
}

/// Write `text` to `path` through a temporary file renamed when complete, as the field
/// writers do (for reports such as the envelope study's CSV).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// `path` with `.partial` appended: outputs are written there and renamed when complete.
pub(crate) fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    path.with_file_name(name)
}

/// Write `path` through `<path>.partial` with a buffered writer; the partial file is synced
/// and renamed on success and removed on failure. I/O errors name `path`.
pub(crate) fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let temp = partial_path(path);
    let result = (|| {
        let file = std::fs::File::create(&temp)?;
        let mut w = BufWriter::with_capacity(1 << 18, file);
        body(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&temp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&temp);
        Error::io(path, e)
    })
}

/// Reject a series whose arrays do not match its grid and times (they would index out of
/// bounds) or whose calibration is unusable.
pub(crate) fn check(field: &FieldSeries) -> Result<()> {
    let n = field
        .x
        .len()
        .checked_mul(field.y.len())
        .and_then(|n| n.checked_mul(field.t_us.len()))
        .ok_or_else(|| Error::parameter("field", "grid size overflows"))?;
    let lengths = [
        ("u", field.u.len()),
        ("v", field.v.len()),
        ("u_unc", field.u_unc.len()),
        ("v_unc", field.v_unc.len()),
        ("status", field.status.len()),
        ("peak", field.peak.len()),
        ("peak_ratio", field.peak_ratio.len()),
        ("event_count", field.event_count.len()),
        ("slab_us", field.slab_us.len()),
    ];
    let derived = field
        .derived
        .iter()
        .map(|d| (d.quantity.name(), d.values.len()));
    for (name, len) in lengths.into_iter().chain(derived) {
        if len != n {
            return Err(Error::parameter(
                "field",
                format!(
                    "`{name}` holds {len} values, the grid {} × {} × {} times needs {n}",
                    field.x.len(),
                    field.y.len(),
                    field.t_us.len()
                ),
            ));
        }
    }
    if let Some(c) = &field.calibration {
        c.validate()?;
    }
    Ok(())
}

/// Positions and velocities of a series in physical units (mm, m/s), `y` and `v` flipped
/// together when the calibration says `y_up`; uncertainties scaled, never flipped.
pub(crate) struct Physical {
    /// Grid column positions, mm.
    pub x_mm: Vec<f64>,
    /// Grid row positions, mm.
    pub y_mm: Vec<f64>,
    /// x velocity, m/s, indexed like the series.
    pub u: Vec<f32>,
    /// y velocity, m/s (positive up when `y_up`).
    pub v: Vec<f32>,
    /// Standard uncertainty of `u`, m/s.
    pub u_unc: Vec<f32>,
    /// Standard uncertainty of `v`, m/s (not flipped: a spread has no direction).
    pub v_unc: Vec<f32>,
}

impl Physical {
    /// Apply `c` to `field`.
    pub fn new(field: &FieldSeries, c: &Calibration) -> Self {
        let (u, v) = field
            .u
            .iter()
            .zip(&field.v)
            .map(|(&u, &v)| {
                let (u, v) = c.velocity_m_per_s(u, v);
                (u + 0.0, v + 0.0)
            })
            .unzip();
        let (u_unc, v_unc) = field
            .u_unc
            .iter()
            .zip(&field.v_unc)
            .map(|(&u, &v)| c.uncertainty_m_per_s(u, v))
            .unzip();
        // `+ 0.0` turns the -0 of a flipped zero into 0, so text files do not show `-0`.
        Physical {
            x_mm: field.x.iter().map(|&x| c.x_mm(x) + 0.0).collect(),
            y_mm: field.y.iter().map(|&y| c.y_mm(y) + 0.0).collect(),
            u,
            v,
            u_unc,
            v_unc,
        }
    }
}

/// Positions and velocities as written: physical when the series is calibrated, image
/// coordinates (px, px/ms) otherwise, with the unit names.
pub(crate) struct Written<'a> {
    /// Column positions.
    pub x: std::borrow::Cow<'a, [f64]>,
    /// Row positions.
    pub y: std::borrow::Cow<'a, [f64]>,
    /// x velocity.
    pub u: std::borrow::Cow<'a, [f32]>,
    /// y velocity.
    pub v: std::borrow::Cow<'a, [f32]>,
    /// Standard uncertainty of `u`, in its unit.
    pub u_unc: std::borrow::Cow<'a, [f32]>,
    /// Standard uncertainty of `v`, in its unit (never flipped).
    pub v_unc: std::borrow::Cow<'a, [f32]>,
    /// Unit of x and y.
    pub length_unit: &'static str,
    /// Unit of u and v.
    pub velocity_unit: &'static str,
}

impl<'a> Written<'a> {
    /// The written view of `field`.
    pub fn new(field: &'a FieldSeries) -> Self {
        use std::borrow::Cow;
        let (image_unit, physical_unit) = field.quantity.units();
        match &field.calibration {
            Some(c) => {
                let p = Physical::new(field, c);
                Written {
                    x: Cow::Owned(p.x_mm),
                    y: Cow::Owned(p.y_mm),
                    u: Cow::Owned(p.u),
                    v: Cow::Owned(p.v),
                    u_unc: Cow::Owned(p.u_unc),
                    v_unc: Cow::Owned(p.v_unc),
                    length_unit: "mm",
                    velocity_unit: physical_unit,
                }
            }
            None => Written {
                x: Cow::Borrowed(&field.x),
                y: Cow::Borrowed(&field.y),
                u: Cow::Borrowed(&field.u),
                v: Cow::Borrowed(&field.v),
                u_unc: Cow::Borrowed(&field.u_unc),
                v_unc: Cow::Borrowed(&field.v_unc),
                length_unit: "px",
                velocity_unit: image_unit,
            },
        }
    }
}

/// One sentence stating the axis convention of what is written for `field`.
pub(crate) fn axis_convention(field: &FieldSeries) -> String {
    axis_convention_of(field.quantity, field.calibration.as_ref())
}

/// [`axis_convention`] of what holds `quantity`, with `calibration`.
pub(crate) fn axis_convention_of(quantity: Quantity, calibration: Option<&Calibration>) -> String {
    let (image_unit, physical_unit) = quantity.units();
    let noun = quantity.noun();
    match calibration {
        None => format!(
            "image coordinates: x to the right, y down, pixel centres at integers; \
             positions in px, {noun} in {image_unit}"
        ),
        Some(c) => format!(
            "physical coordinates: x to the right, y {}, origin at image point ({}, {}) px, \
             {} mm per px; positions in mm, {noun} in {physical_unit} (v positive {})",
            if c.y_up { "up" } else { "down" },
            c.origin_px[0],
            c.origin_px[1],
            c.mm_per_px,
            if c.y_up { "up" } else { "down" },
        ),
    }
}

/// The software that wrote a file.
pub(crate) const SOFTWARE: &str = concat!("ebiv ", env!("CARGO_PKG_VERSION"));

/// The sentence that relates the times of `field` to the camera clock and to `ebiv process
/// --time`, for file metadata.
pub(crate) fn time_comment(field: &FieldSeries) -> String {
    if !field.time_basis.is_camera_time() {
        return field.time_basis.describe().to_string();
    }
    let clock = "microseconds of the recording's camera clock, as its time stamps are stored \
                 (the clock's zero is the camera's own, e.g. the start of a Prophesee RAW \
                 recording or the Unix epoch for AEDAT 4)";
    match field.time_origin_us {
        Some(0) => format!(
            "{clock}; the requested field times (ebiv process --time) were given on this clock"
        ),
        Some(origin) => format!(
            "{clock}; ebiv process --time counts from the recording's first event, at \
             {origin} us on this clock: time = {origin} us + the --time value"
        ),
        None => clock.to_string(),
    }
}

/// Descriptive metadata for formats with free-form key/value attributes: the writer's own
/// entries (software, axis convention, time basis, units, status legend, calibration), then
/// the series' `attributes`. Keys are sanitised to `[A-Za-z_][A-Za-z0-9_]*` and made unique; a
/// series attribute identical to one of the writer's is left out, one whose key the writer
/// uses with another value is kept with a `user_` prefix.
pub(crate) fn metadata(field: &FieldSeries) -> Vec<(String, String)> {
    let w = Written::new(field);
    let mut own = vec![
        ("software".to_string(), SOFTWARE.to_string()),
        ("axis_convention".to_string(), axis_convention(field)),
        (
            "field_time".to_string(),
            field.time_basis.describe().to_string(),
        ),
        (
            "time_units".to_string(),
            if field.time_basis.is_camera_time() {
                "us"
            } else {
                "1 (index)"
            }
            .to_string(),
        ),
        ("length_units".to_string(), w.length_unit.to_string()),
        ("velocity_units".to_string(), w.velocity_unit.to_string()),
    ];
    if let Some(origin) = field.time_origin_us {
        own.push(("time_origin_us".to_string(), origin.to_string()));
    }
    if !field.ground_truth {
        own.push((
            "status_flags".to_string(),
            format!("0 valid; bits: {}", Status::legend()),
        ));
        own.push((
            "slab_us".to_string(),
            field.time_basis.describe_slab().to_string(),
        ));
    }
    if let Some(c) = &field.calibration {
        own.push(("mm_per_px".into(), c.mm_per_px.to_string()));
        own.push((
            "origin_px".into(),
            format!("{} {}", c.origin_px[0], c.origin_px[1]),
        ));
        own.push((
            "y_positive".into(),
            if c.y_up { "up" } else { "down" }.into(),
        ));
    }
    let reserved: Vec<String> = own.iter().map(|(k, _)| k.clone()).collect();
    let mut out = own;
    for (k, v) in &field.attributes {
        let mut key = sanitize_name(k);
        if out.iter().any(|(ok, ov)| *ok == key && ov == v) {
            continue;
        }
        if reserved.contains(&key) {
            key = format!("user_{key}");
        }
        out.push((unique_key(&out, key), v.clone()));
    }
    out
}

/// `name` with every character outside `[A-Za-z0-9_]` replaced by `_`, prefixed with `a_` if
/// it is empty or does not start with a letter or `_` (NetCDF, Tecplot AUXDATA names).
pub(crate) fn sanitize_name(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if !s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
        s.insert_str(0, "a_");
    }
    s
}

/// `key`, or `key_2`, `key_3`, … if `key` is taken in `existing`.
fn unique_key(existing: &[(String, String)], key: String) -> String {
    let taken = |k: &str| existing.iter().any(|(e, _)| e == k);
    if !taken(&key) {
        return key;
    }
    (2..)
        .map(|i| format!("{key}_{i}"))
        .find(|k| !taken(k))
        .unwrap_or(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_extension_names_the_supported_ones() {
        let f = FieldSeries::new(vec![0.0], vec![0.0], vec![0]);
        let dir = tempfile::tempdir().unwrap();
        let e = write_field(&f, &dir.path().join("f.xyz")).unwrap_err();
        let text = e.to_string();
        assert!(text.contains(".xyz") && text.contains(".nc") && text.contains(".vtk"));
        assert!(write_field(&f, &dir.path().join("noext")).is_err());
        assert!(!dir.path().join("f.xyz").exists());
    }

    #[test]
    fn metadata_keys_are_sanitised_and_unique() {
        let mut f = FieldSeries::new(vec![0.0], vec![0.0], vec![0]);
        f.attributes.push(("source file".into(), "a".into()));
        f.attributes.push(("source-file".into(), "b".into()));
        f.attributes.push(("software".into(), "other".into()));
        f.attributes.push(("software".into(), SOFTWARE.into()));
        f.attributes.push(("3d".into(), "no".into()));
        let m = metadata(&f);
        let get = |k: &str| m.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
        assert_eq!(get("source_file"), Some("a"));
        assert_eq!(get("source_file_2"), Some("b"));
        assert_eq!(get("software"), Some(SOFTWARE));
        assert_eq!(get("user_software"), Some("other"));
        // An attribute identical to the writer's own is not repeated.
        assert_eq!(get("user_software_2"), None);
        assert_eq!(m.iter().filter(|(_, v)| v == SOFTWARE).count(), 1);
        assert_eq!(get("a_3d"), Some("no"));
    }

    #[test]
    fn inconsistent_arrays_are_an_error_not_a_panic() {
        let mut f = FieldSeries::new(vec![0.0, 1.0], vec![0.0], vec![0]);
        f.peak.pop();
        let dir = tempfile::tempdir().unwrap();
        for ext in ["nc", "npz", "csv", "dat", "vtk"] {
            let path = dir.path().join(format!("f.{ext}"));
            let e = write_field(&f, &path).unwrap_err();
            assert!(e.to_string().contains("peak"), "{ext}: {e}");
            assert!(!path.exists());
        }
    }
}
