//! Vector fields as legacy VTK files ("VTK File Formats", VTK User's Guide, section "Simple
//! Legacy Formats"): `DATASET RECTILINEAR_GRID` with `DIMENSIONS nx ny 1`, `X_COORDINATES`,
//! `Y_COORDINATES` (`double`), `Z_COORDINATES` (0), and `POINT_DATA` with
//! `VECTORS velocity float` (u, v, 0), `SCALARS status unsigned_char` (0 = valid, else the
//! bits of [`Status`]) and a `FIELD` with `u_unc`, `v_unc` (`float`: the standard uncertainty
//! of u and v, one standard deviation, in their unit, NaN where unknown), `peak`,
//! `peak_ratio` (`float`), `event_count` and `slab_us` (`unsigned_int`; the time slab each
//! vector was measured over, µs, 0 where there is none): field arrays are loaded by every
//! legacy reader, where a second `SCALARS` section is skipped unless the reader is told to
//! read all of them.
//!
//! The files are `BINARY` (big-endian, as the legacy format prescribes): VTK's ASCII legacy
//! reader does not parse `nan`, and invalid vectors must stay NaN, never zero.
//!
//! **y points up in every VTK file.** ParaView draws y upwards, so image coordinates (y down)
//! written as they are would show the image upside down. Where the series is written with y
//! down (image coordinates, or a calibration without `y_up`), the y coordinates and the v
//! component are both negated: image row `r` is at `y = −r` (mm: `−y_mm`), `v` is positive
//! up, and ParaView shows the field as the camera saw it; `v_unc`, a spread, is not negated.
//! With a `y_up` calibration they are written as they are. The file's title line states
//! which. Coordinates ascend as VTK expects, so the rows are written bottom row first.
//!
//! One file per time step. A single field goes to `path`; a series of `nt > 1` fields goes
//! to `stem_0000.vtk`, `stem_0001.vtk`, … (see [`vtk_series_paths`]) plus a ParaView file
//! series description `path.series` (JSON, `file-series-version` 1.0) giving each file's time
//! in microseconds. ParaView also groups the numbered files by itself.
//!
//! [`Status`]: crate::field::Status

use super::{check, write_atomic, Written};
use crate::error::{Error, Result};
use crate::field::FieldSeries;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The files [`write_field_vtk`] writes for `nt` time steps to `path`: `path` itself for one
/// step, else `stem_0000.ext`, `stem_0001.ext`, … (at least four digits, more when needed so
/// that the names sort in time order).
pub fn vtk_series_paths(path: &Path, nt: usize) -> Vec<PathBuf> {
    if nt == 1 {
        return vec![path.to_path_buf()];
    }
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let ext = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    let digits = nt.saturating_sub(1).to_string().len().max(4);
    (0..nt)
        .map(|i| path.with_file_name(format!("{stem}_{i:0digits$}{ext}")))
        .collect()
}

/// Write `field` as legacy VTK, one binary file per time step (see the module
/// documentation for the names), each through a temporary file.
pub fn write_field_vtk(field: &FieldSeries, path: &Path) -> Result<()> {
    check(field)?;
    let nt = field.t_us.len();
    if nt == 0 {
        return Err(Error::parameter(
            "field",
            "a VTK file needs at least one time step",
        ));
    }
    let w = Written::new(field);
    let paths = vtk_series_paths(path, nt);
    for (ti, file) in paths.iter().enumerate() {
        write_atomic(file, |out| write_step(out, field, &w, ti))?;
    }
    if nt > 1 {
        let mut series = path.as_os_str().to_os_string();
        series.push(".series");
        let series = PathBuf::from(series);
        write_atomic(&series, |out| {
            writeln!(
                out,
                "{{\n  \"file-series-version\" : \"1.0\",\n  \"files\" : ["
            )?;
            for (ti, (file, t)) in paths.iter().zip(&field.t_us).enumerate() {
                let name = file.file_name().unwrap_or_default().to_string_lossy();
                let comma = if ti + 1 < nt { "," } else { "" };
                writeln!(
                    out,
                    "    {{ \"name\" : \"{}\", \"time\" : {t} }}{comma}",
                    json_escape(&name)
                )?;
            }
            writeln!(out, "  ]\n}}")
        })?;
    }
    Ok(())
}

/// The legacy VTK file of time step `ti`.
fn write_step(
    out: &mut impl Write,
    field: &FieldSeries,
    w: &Written<'_>,
    ti: usize,
) -> std::io::Result<()> {
    let (nx, ny) = (field.x.len(), field.y.len());
    let order = |axis: &[f64]| -> Vec<usize> {
        if axis.len() > 1 && axis[0] > axis[axis.len() - 1] {
            (0..axis.len()).rev().collect()
        } else {
            (0..axis.len()).collect()
        }
    };
    // y up in the file (see the module documentation): negate y and v of a y-down series.
    let flip = field.calibration.as_ref().is_none_or(|c| !c.y_up);
    let sign = if flip { -1.0 } else { 1.0 };
    let ys: Vec<f64> = w.y.iter().map(|&y| sign * y + 0.0).collect();
    let (rows, cols) = (order(&ys), order(&w.x));
    let points = || {
        rows.iter()
            .flat_map(|&r| cols.iter().map(move |&c| field.index(ti, r, c)))
    };
    let (image_unit, physical_unit) = field.quantity.units();
    let axes = match &field.calibration {
        None => format!("x right, y up (y = -image row, v positive up); px, {image_unit}"),
        Some(c) => format!(
            "x right, y up{}; mm, {physical_unit}; origin ({}, {}) px, {} mm/px",
            if c.y_up {
                ""
            } else {
                " (y = -y_mm, v positive up)"
            },
            c.origin_px[0],
            c.origin_px[1],
            c.mm_per_px
        ),
    };
    let mut title = format!(
        "ebiv vector field, t = {} us; {axes}; status 0 = valid",
        field.t_us[ti]
    );
    title.truncate(255);
    writeln!(out, "# vtk DataFile Version 3.0\n{title}\nBINARY")?;
    writeln!(out, "DATASET RECTILINEAR_GRID\nDIMENSIONS {nx} {ny} 1")?;
    let mut buf = Vec::new();
    writeln!(out, "X_COORDINATES {nx} double")?;
    buf.clear();
    for &c in &cols {
        buf.extend_from_slice(&w.x[c].to_be_bytes());
    }
    out.write_all(&buf)?;
    writeln!(out, "\nY_COORDINATES {ny} double")?;
    buf.clear();
    for &r in &rows {
        buf.extend_from_slice(&ys[r].to_be_bytes());
    }
    out.write_all(&buf)?;
    writeln!(out, "\nZ_COORDINATES 1 double")?;
    out.write_all(&0f64.to_be_bytes())?;
    writeln!(out, "\nPOINT_DATA {}", nx * ny)?;

    writeln!(out, "VECTORS velocity float")?;
    buf.clear();
    for i in points() {
        for c in [w.u[i], sign as f32 * w.v[i] + 0.0, 0.0] {
            buf.extend_from_slice(&c.to_be_bytes());
        }
    }
    out.write_all(&buf)?;
    writeln!(
        out,
        "\nSCALARS status unsigned_char 1\nLOOKUP_TABLE default"
    )?;
    buf.clear();
    buf.extend(points().map(|i| field.status[i].0));
    out.write_all(&buf)?;
    // Further arrays as field data, which every legacy reader loads (only the first
    // SCALARS is read unless the reader is told to read all).
    writeln!(out, "\nFIELD FieldData 6")?;
    let n = nx * ny;
    let floats: [(&str, &[f32]); 4] = [
        ("u_unc", &w.u_unc),
        ("v_unc", &w.v_unc),
        ("peak", &field.peak),
        ("peak_ratio", &field.peak_ratio),
    ];
    for (k, (name, data)) in floats.into_iter().enumerate() {
        if k > 0 {
            writeln!(out)?;
        }
        writeln!(out, "{name} 1 {n} float")?;
        buf.clear();
        for i in points() {
            buf.extend_from_slice(&data[i].to_be_bytes());
        }
        out.write_all(&buf)?;
    }
    for (name, data) in [
        ("event_count", &field.event_count),
        ("slab_us", &field.slab_us),
    ] {
        writeln!(out, "\n{name} 1 {n} unsigned_int")?;
        buf.clear();
        for i in points() {
            buf.extend_from_slice(&data[i].to_be_bytes());
        }
        out.write_all(&buf)?;
    }
    writeln!(out)
}

/// `s` as the inside of a JSON string.
fn json_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_names_are_numbered_and_sort_in_time_order() {
        let p = Path::new("/tmp/out/field.vtk");
        assert_eq!(vtk_series_paths(p, 1), vec![p.to_path_buf()]);
        let two = vtk_series_paths(p, 2);
        assert_eq!(two[1], Path::new("/tmp/out/field_0001.vtk"));
        let many = vtk_series_paths(p, 12_345);
        assert_eq!(many[12_344], Path::new("/tmp/out/field_12344.vtk"));
        assert_eq!(many[7], Path::new("/tmp/out/field_00007.vtk"));
        assert_eq!(json_escape("a\"b\\\n"), "a\\\"b\\\\\\u000a");
    }

    #[test]
    fn empty_series_is_an_error() {
        let f = FieldSeries::new(vec![0.0], vec![0.0], vec![]);
        let dir = tempfile::tempdir().unwrap();
        assert!(write_field_vtk(&f, &dir.path().join("f.vtk")).is_err());
    }

    #[test]
    fn header_is_legacy_binary_rectilinear() {
        let f = FieldSeries::new(vec![0.0, 1.0], vec![5.0], vec![9]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.vtk");
        write_field_vtk(&f, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.starts_with("# vtk DataFile Version 3.0\nebiv vector field, t = 9 us;"));
        assert!(text.contains("\nBINARY\nDATASET RECTILINEAR_GRID\nDIMENSIONS 2 1 1\n"));
        assert!(text.contains("\nPOINT_DATA 2\nVECTORS velocity float\n"));
        assert!(!dir.path().join("f.vtk.series").exists());
    }

    /// The doubles after `key` up to the next line: the coordinates of one axis.
    fn coordinates(bytes: &[u8], key: &str, n: usize) -> Vec<f64> {
        let at = bytes
            .windows(key.len())
            .position(|w| w == key.as_bytes())
            .unwrap();
        let start = at + bytes[at..].iter().position(|&b| b == b'\n').unwrap() + 1;
        (0..n)
            .map(|k| {
                let b = &bytes[start + 8 * k..start + 8 * k + 8];
                f64::from_be_bytes(b.try_into().unwrap())
            })
            .collect()
    }

    /// The (u, v) of each point, in file order.
    fn vectors(bytes: &[u8], n: usize) -> Vec<(f32, f32)> {
        let key = b"VECTORS velocity float\n";
        let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len();
        (0..n)
            .map(|k| {
                let f = |j: usize| {
                    let o = at + 12 * k + 4 * j;
                    f32::from_be_bytes(bytes[o..o + 4].try_into().unwrap())
                };
                (f(0), f(1))
            })
            .collect()
    }

    #[test]
    fn image_coordinates_are_written_y_up_so_the_image_is_not_mirrored() {
        // Two rows: row 10 (top of the image) moves down (+v), row 50 moves up (−v).
        let mut f = FieldSeries::new(vec![0.0], vec![10.0, 50.0], vec![0]);
        f.u = vec![1.0, 2.0];
        f.v = vec![3.0, -4.0];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.vtk");
        write_field_vtk(&f, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert!(
            text.contains("y up (y = -image row, v positive up)"),
            "{text}"
        );
        // Ascending y: the bottom row (50 → −50) first, the top row (10 → −10) last, so the
        // top of the image is drawn at the top.
        assert_eq!(coordinates(&bytes, "Y_COORDINATES", 2), vec![-50.0, -10.0]);
        // Row 50 moved up on the image: positive v in the y-up file.
        assert_eq!(vectors(&bytes, 2), vec![(2.0, 4.0), (1.0, -3.0)]);
    }

    /// The floats of the field array `name` of `n` points, in file order.
    fn field_array(bytes: &[u8], name: &str, n: usize) -> Vec<f32> {
        let key = format!("\n{name} 1 {n} float\n");
        let at = bytes
            .windows(key.len())
            .position(|w| w == key.as_bytes())
            .unwrap()
            + key.len();
        (0..n)
            .map(|k| f32::from_be_bytes(bytes[at + 4 * k..at + 4 * k + 4].try_into().unwrap()))
            .collect()
    }

    #[test]
    fn uncertainties_are_field_arrays_scaled_but_never_negated() {
        let mut f = FieldSeries::new(vec![0.0], vec![10.0, 50.0], vec![0]);
        f.u = vec![1.0, 2.0];
        f.v = vec![3.0, -4.0];
        f.u_unc = vec![0.25, f32::NAN];
        f.v_unc = vec![0.5, 0.75];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.vtk");
        write_field_vtk(&f, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(String::from_utf8_lossy(&bytes).contains("\nFIELD FieldData 6\n"));
        // Bottom row (50) first; v is negated for y up, v_unc is not.
        assert_eq!(vectors(&bytes, 2), vec![(2.0, 4.0), (1.0, -3.0)]);
        let u_unc = field_array(&bytes, "u_unc", 2);
        assert!(u_unc[0].is_nan() && u_unc[1] == 0.25);
        assert_eq!(field_array(&bytes, "v_unc", 2), vec![0.75, 0.5]);
        // A calibration without y up: scaled by 0.5 mm/px, still not negated.
        f.calibration = Some(crate::field::Calibration {
            mm_per_px: 0.5,
            origin_px: [0.0, 0.0],
            y_up: false,
        });
        write_field_vtk(&f, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(vectors(&bytes, 2), vec![(1.0, 2.0), (0.5, -1.5)]);
        assert_eq!(field_array(&bytes, "v_unc", 2), vec![0.375, 0.25]);
        assert_eq!(field_array(&bytes, "u_unc", 2)[1], 0.125);
    }

    #[test]
    fn y_up_calibration_is_written_as_it_is() {
        let mut f = FieldSeries::new(vec![0.0], vec![10.0, 50.0], vec![0]);
        f.u = vec![1.0, 2.0];
        f.v = vec![3.0, -4.0];
        f.calibration = Some(crate::field::Calibration {
            mm_per_px: 1.0,
            origin_px: [0.0, 0.0],
            y_up: true,
        });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.vtk");
        write_field_vtk(&f, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(coordinates(&bytes, "Y_COORDINATES", 2), vec![-50.0, -10.0]);
        assert_eq!(vectors(&bytes, 2), vec![(2.0, 4.0), (1.0, -3.0)]);
    }
}
