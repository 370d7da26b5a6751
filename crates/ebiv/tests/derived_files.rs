//! Derived quantities in field files (docs/derived.md, "Output"): the same series written as
//! CSV, NPZ and NetCDF holds the same values under unique names in every format, for
//! velocities and displacements, with and without a calibration, y down or up; and each
//! reader gives them back so that the file written again holds the same derived values.

use ebiv::derived::{add_derived, DerivedQuantity};
use ebiv::export::write_field;
use ebiv::field::{Calibration, FieldSeries, Quantity, Status, TimeBasis};
use ebiv::io::field::{read_field, FieldReadOptions};
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

/// Two fields on 5 × 4 nodes of a rotating, sheared and stretched flow with one invalid
/// vector, holding every derived quantity.
fn series(quantity: Quantity, calibration: Option<Calibration>) -> FieldSeries {
    let x: Vec<f64> = (0..5).map(|i| 8.0 + 16.0 * i as f64).collect();
    let y: Vec<f64> = (0..4).map(|i| 8.0 + 16.0 * i as f64).collect();
    let mut s = FieldSeries::new(x.clone(), y.clone(), vec![0, 1]);
    for t in 0..2 {
        for (r, &yy) in y.iter().enumerate() {
            for (c, &xx) in x.iter().enumerate() {
                let i = s.index(t, r, c);
                let k = 1.0 + 0.37 * t as f64;
                s.u[i] = (k * (-0.013 * yy + 0.0021 * xx * xx / 10.0)) as f32;
                s.v[i] = (k * (0.029 * xx - 0.0007 * yy * yy / 10.0 + 0.1)) as f32;
                s.status[i] = Status::VALID;
            }
        }
    }
    let bad = s.index(1, 2, 3);
    s.u[bad] = f32::NAN;
    s.v[bad] = f32::NAN;
    s.status[bad] = Status::NO_EVENTS;
    s.quantity = quantity;
    if quantity == Quantity::Displacement {
        s.time_basis = TimeBasis::PairIndex;
    }
    s.calibration = calibration;
    add_derived(&mut s, &DerivedQuantity::ALL).unwrap();
    s
}

/// Every kind of series: velocities and displacements; no calibration, y down, y up.
fn cases() -> Vec<(String, FieldSeries)> {
    let calibration = |y_up| Calibration {
        mm_per_px: 0.05,
        origin_px: [4.0, 60.0],
        y_up,
    };
    let mut out = Vec::new();
    for quantity in [Quantity::Velocity, Quantity::Displacement] {
        for (what, c) in [
            ("uncalibrated", None),
            ("y down", Some(calibration(false))),
            ("y up", Some(calibration(true))),
        ] {
            out.push((format!("{quantity:?}, {what}"), series(quantity, c)));
        }
    }
    out
}

/// The columns of a CSV file by name; panics on a repeated name.
fn csv_columns(path: &Path) -> HashMap<String, Vec<f32>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let names: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut columns: HashMap<String, Vec<f32>> = HashMap::new();
    for name in &names {
        assert!(
            columns.insert(name.clone(), Vec::new()).is_none(),
            "{}: column `{name}` twice in {names:?}",
            path.display()
        );
    }
    for line in lines {
        for (name, cell) in names.iter().zip(line.split(',')) {
            columns.get_mut(name).unwrap().push(cell.parse().unwrap());
        }
    }
    columns
}

/// The `<f4` arrays of an NPZ archive by name.
fn npz_arrays(path: &Path) -> HashMap<String, Vec<f32>> {
    let mut zip = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
    let mut out = HashMap::new();
    for k in 0..zip.len() {
        let mut member = zip.by_index(k).unwrap();
        let name = member.name().trim_end_matches(".npy").to_string();
        let mut bytes = Vec::new();
        member.read_to_end(&mut bytes).unwrap();
        let start = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = std::str::from_utf8(&bytes[10..start]).unwrap();
        if header.contains("'descr': '<f4'") {
            let values = bytes[start..]
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
                .collect();
            out.insert(name, values);
        }
    }
    out
}

fn netcdf_variable(path: &Path, name: &str) -> (Vec<f32>, String) {
    let mut r = netcdf3::FileReader::open(path).unwrap();
    let units = r
        .data_set()
        .get_var_attr_as_string(name, "units")
        .unwrap_or_default();
    (r.read_var_f32(name).unwrap(), units)
}

fn bits(values: &[f32]) -> Vec<u32> {
    values
        .iter()
        .map(|v| if v.is_nan() { u32::MAX } else { v.to_bits() })
        .collect()
}

#[test]
fn csv_npz_and_netcdf_hold_the_same_derived_values_under_unique_names() {
    let dir = tempfile::tempdir().unwrap();
    for (case, s) in cases() {
        let (csv, npz, nc) = (
            dir.path().join("f.csv"),
            dir.path().join("f.npz"),
            dir.path().join("f.nc"),
        );
        for path in [&csv, &npz, &nc] {
            write_field(&s, path).unwrap();
        }
        let csv = csv_columns(&csv);
        let npz = npz_arrays(&npz);
        let calibration = s.calibration.as_ref();
        for d in &s.derived {
            let q = d.quantity;
            let image_csv = &csv[&q.image_column(s.quantity)];
            assert_eq!(bits(image_csv), bits(&d.values), "{case}: {}", q.name());
            assert_eq!(
                bits(&npz[q.name()]),
                bits(&d.values),
                "{case}: {}",
                q.name()
            );
            // NetCDF: the values in the frame of its u and v, which NPZ and CSV hold as
            // their second copy where the calibration changes them.
            let (netcdf, units) = netcdf_variable(&nc, q.name());
            assert_eq!(units, DerivedQuantity::unit(s.quantity, calibration));
            let (in_csv, in_npz) = match q.physical_name(s.quantity, calibration) {
                Some(name) => (&csv[&name], &npz[&name]),
                None => (image_csv, &npz[q.name()]),
            };
            assert_eq!(bits(in_csv), bits(&netcdf), "{case}: {} CSV", q.name());
            assert_eq!(bits(in_npz), bits(&netcdf), "{case}: {} NPZ", q.name());
            // The sign the file states: with y up, the odd quantities turn.
            let k = q.written_factor(s.quantity, calibration);
            let y_up = calibration.is_some_and(|c| c.y_up);
            assert_eq!(k < 0.0, y_up && q.odd_in_y(), "{case}: {}", q.name());
            for (w, v) in netcdf.iter().zip(&d.values) {
                assert!(w.is_nan() == v.is_nan());
                if v.is_finite() && *v != 0.0 {
                    assert_eq!(w.signum() as f64, v.signum() as f64 * k.signum());
                }
            }
        }
    }
}

#[test]
fn every_reader_gives_the_derived_values_back_and_writing_again_changes_none() {
    let dir = tempfile::tempdir().unwrap();
    let options = FieldReadOptions::default();
    for (case, s) in cases() {
        for ext in ["csv", "npz", "nc"] {
            let (first, second) = (
                dir.path().join(format!("a.{ext}")),
                dir.path().join(format!("b.{ext}")),
            );
            write_field(&s, &first).unwrap();
            let read = read_field(&first, &options).unwrap();
            let quantities: Vec<_> = read.derived.iter().map(|d| d.quantity).collect();
            assert_eq!(quantities, DerivedQuantity::ALL, "{case}, .{ext}");
            assert_eq!(read.quantity, s.quantity, "{case}, .{ext}");
            for (back, d) in read.derived.iter().zip(&s.derived) {
                // As the file holds them: NetCDF the calibration's values, NPZ and CSV the
                // image values.
                let (got, want) = if ext == "nc" {
                    (
                        DerivedQuantity::written(back, &read),
                        DerivedQuantity::written(d, &s),
                    )
                } else {
                    (back.values.clone(), d.values.clone())
                };
                assert_eq!(bits(&got), bits(&want), "{case}, .{ext}: {:?}", d.quantity);
            }
            write_field(&read, &second).unwrap();
            match ext {
                "csv" => {
                    // The CSV reader takes the image columns (and no calibration).
                    let (a, b) = (csv_columns(&first), csv_columns(&second));
                    for q in DerivedQuantity::ALL {
                        let name = q.image_column(s.quantity);
                        assert_eq!(bits(&a[&name]), bits(&b[&name]), "{case}: {name}");
                    }
                }
                "npz" => {
                    assert_eq!(read.calibration, s.calibration, "{case}");
                    assert_eq!(bits(&read.u), bits(&s.u), "{case}");
                    assert_eq!(read.status, s.status, "{case}");
                    let (a, b) = (npz_arrays(&first), npz_arrays(&second));
                    let mut names: Vec<&String> = a.keys().collect();
                    names.sort();
                    let mut again: Vec<&String> = b.keys().collect();
                    again.sort();
                    assert_eq!(names, again, "{case}");
                    for name in names {
                        assert_eq!(bits(&a[name]), bits(&b[name]), "{case}: {name}");
                    }
                }
                _ => {
                    for q in DerivedQuantity::ALL {
                        let (a, ua) = netcdf_variable(&first, q.name());
                        let (b, ub) = netcdf_variable(&second, q.name());
                        assert_eq!((bits(&a), ua), (bits(&b), ub), "{case}: {}", q.name());
                    }
                }
            }
        }
    }
}

#[test]
fn a_frame_interval_turns_derived_displacements_into_rates() {
    let dir = tempfile::tempdir().unwrap();
    let s = series(Quantity::Displacement, None);
    let options = FieldReadOptions {
        frame_interval_us: Some(250.0),
        ..FieldReadOptions::default()
    };
    for ext in ["csv", "npz", "nc"] {
        let path = dir.path().join(format!("d.{ext}"));
        write_field(&s, &path).unwrap();
        let read = read_field(&path, &options).unwrap();
        assert_eq!(read.quantity, Quantity::Velocity);
        for (back, d) in read.derived.iter().zip(&s.derived) {
            for (b, v) in back.values.iter().zip(&d.values) {
                // Per frame interval of 0.25 ms: ×4 per ms.
                assert!(
                    b.is_nan() && v.is_nan() || *b == *v * 4.0,
                    ".{ext}: {b} {v}"
                );
            }
        }
    }
}
