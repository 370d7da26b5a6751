//! Round trips through ebiv's writers, tables of other tools, and clear errors.

use super::*;
use crate::export::{write_field_csv, write_field_netcdf};
use crate::field::{Calibration, Quantity, Status, TimeBasis};

fn series() -> FieldSeries {
    let mut f = FieldSeries::new(vec![8.0, 24.0, 40.0], vec![8.0, 24.0], vec![5000, 15_000]);
    for i in 0..f.u.len() {
        f.u[i] = 0.25 * i as f32 - 1.0;
        f.v[i] = 0.5 - 0.125 * i as f32;
        f.status[i] = Status::VALID;
        f.peak[i] = 0.5 + i as f32;
        f.peak_ratio[i] = 1.5 + i as f32;
        f.event_count[i] = 100 + i as u32;
        f.slab_us[i] = 10_000;
        f.u_unc[i] = 0.01 * (i + 1) as f32;
        f.v_unc[i] = 0.02 * (i + 1) as f32;
    }
    f.u_unc[3] = f32::NAN;
    f.v_unc[3] = f32::NAN;
    f.u[3] = f32::NAN;
    f.v[3] = f32::NAN;
    f.status[3] = Status::LOW_PEAK_RATIO;
    f.status[7] = Status::MEDIAN_TEST | Status::REPLACED;
    f.time_origin_us = Some(123);
    f
}

fn same_nan(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| (x.is_nan() && y.is_nan()) || (x - y).abs() <= 1e-6 * x.abs().max(1.0))
}

fn assert_same(a: &FieldSeries, b: &FieldSeries, quality: bool) {
    assert_eq!(a.x, b.x);
    assert_eq!(a.y, b.y);
    assert_eq!(a.t_us, b.t_us);
    assert!(same_nan(&a.u, &b.u), "{:?} {:?}", a.u, b.u);
    assert!(same_nan(&a.v, &b.v), "{:?} {:?}", a.v, b.v);
    if !a.ground_truth {
        assert!(same_nan(&a.u_unc, &b.u_unc), "{:?} {:?}", a.u_unc, b.u_unc);
        assert!(same_nan(&a.v_unc, &b.v_unc), "{:?} {:?}", a.v_unc, b.v_unc);
    }
    assert_eq!(a.quantity, b.quantity);
    if quality {
        assert_eq!(a.status, b.status);
        assert!(same_nan(&a.peak, &b.peak));
        assert!(same_nan(&a.peak_ratio, &b.peak_ratio));
        assert_eq!(a.event_count, b.event_count);
        assert_eq!(a.slab_us, b.slab_us);
    }
}

#[test]
fn netcdf_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.nc");
    let f = series();
    write_field_netcdf(&f, &path).unwrap();
    let back = read_field(&path, &FieldReadOptions::default()).unwrap();
    assert_same(&f, &back, true);
    assert_eq!(back.time_basis, TimeBasis::SlabCentre);
    assert_eq!(back.time_origin_us, Some(123));
    assert!(!back.ground_truth && back.calibration.is_none());
}

#[test]
fn calibrated_netcdf_and_csv_come_back_in_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let mut f = series();
    f.calibration = Some(Calibration {
        mm_per_px: 0.05,
        origin_px: [8.0, 40.0],
        y_up: true,
    });
    let nc = dir.path().join("f.nc");
    write_field_netcdf(&f, &nc).unwrap();
    let back = read_field(&nc, &FieldReadOptions::default()).unwrap();
    assert_same(&f, &back, true);
    assert_eq!(back.calibration, f.calibration);
    let csv = dir.path().join("f.csv");
    write_field_csv(&f, &csv).unwrap();
    let back = read_field(&csv, &FieldReadOptions::default()).unwrap();
    assert_same(&f, &back, true);
}

#[test]
fn csv_round_trip_and_truth_files() {
    let dir = tempfile::tempdir().unwrap();
    let f = series();
    let path = dir.path().join("f.csv");
    write_field_csv(&f, &path).unwrap();
    let back = read_field(&path, &FieldReadOptions::default()).unwrap();
    assert_same(&f, &back, true);
    let mut truth = series();
    truth.ground_truth = true;
    truth.time_basis = TimeBasis::Instant;
    truth.u[3] = 1.0;
    truth.v[3] = 1.0;
    truth.status = vec![Status::VALID; truth.u.len()];
    for name in ["t.csv", "t.nc"] {
        let p = dir.path().join(name);
        crate::export::write_field(&truth, &p).unwrap();
        let back = read_field(&p, &FieldReadOptions::default()).unwrap();
        assert!(back.ground_truth, "{name}");
        assert_same(&truth, &back, false);
        assert_eq!(back.status, truth.status, "{name}");
    }
}

#[test]
fn openpiv_table_with_flags_and_mask() {
    let text = "# x\ty\tu\tv\tflags\tmask\n\
                16\t16\t1.5\t-0.5\t0\t0\n\
                32\t16\t2.5\t-0.5\t1\t0\n\
                16\t32\t1.0\t0.0\t0\t1\n\
                32\t32\tnan\tnan\t0\t0\n";
    let f = read_field_str(text, "openpiv.txt", &FieldReadOptions::default()).unwrap();
    assert_eq!(
        (f.x.clone(), f.y.clone()),
        (vec![16.0, 32.0], vec![16.0, 32.0])
    );
    assert_eq!(f.quantity, Quantity::Displacement);
    assert_eq!(f.time_basis, TimeBasis::PairIndex);
    assert_eq!(f.status[0], Status::VALID);
    assert_eq!(f.status[1], Status::MEDIAN_TEST | Status::REPLACED);
    assert_eq!(f.u[1], 2.5);
    assert!(f.status[2].contains(Status::MASKED) && f.u[2].is_nan());
    assert_eq!(f.status[3], Status::NO_EVENTS);
    let options = FieldReadOptions {
        frame_interval_us: Some(500.0),
        ..Default::default()
    };
    let f = read_field_str(text, "openpiv.txt", &options).unwrap();
    assert_eq!(
        (f.quantity, f.u[0], f.v[0]),
        (Quantity::Velocity, 3.0, -1.0)
    );
}

#[test]
fn pivlab_exports_plain_and_calibrated() {
    let plain = "PIVlab by W.Th. & E.J.S., ASCII chart output - 01-Jan-2024\n\
                 FRAME: 1, filenames: A: a.bmp & B: b.bmp, conversion factor xy (px -> m): 1, conversion factor uv (px/frame -> m/s): 1\n\
                 x [px],y [px],u [px/frame],v [px/frame],vorticity [1/frame]\n\
                 10,10,1.25,0.5,0\n20,10,NaN,NaN,NaN\n";
    let f = read_field_str(plain, "pivlab.txt", &FieldReadOptions::default()).unwrap();
    assert_eq!((f.x.clone(), f.u[0], f.v[0]), (vec![10.0, 20.0], 1.25, 0.5));
    assert_eq!(f.quantity, Quantity::Displacement);
    assert!(f.u[1].is_nan() && f.status[1] == Status::NO_EVENTS);
    // Calibrated: 2e-5 m per px = 0.02 mm per px; 0.02 m/s = 1 px/ms.
    let calibrated = "PIVlab by W.Th. & E.J.S., ASCII chart output - 01-Jan-2024\n\
                      FRAME: 1, filenames: A: a.bmp & B: b.bmp, conversion factor xy (px -> m): 2e-05, conversion factor uv (px/frame -> m/s): 0.02\n\
                      x [m],y [m],u [m/s],v [m/s]\n\
                      0.0002,0.0002,0.02,-0.04\n";
    let f = read_field_str(calibrated, "pivlab.txt", &FieldReadOptions::default()).unwrap();
    assert!((f.x[0] - 10.0).abs() < 1e-9 && (f.y[0] - 10.0).abs() < 1e-9);
    assert!((f.u[0] - 1.0).abs() < 1e-6 && (f.v[0] + 2.0).abs() < 1e-6);
    assert_eq!(f.quantity, Quantity::Velocity);
}

#[test]
fn physical_units_without_a_scale_ask_for_it() {
    let text = "x [mm],y [mm],u [m/s],v [m/s]\n1,1,0.1,0.1\n";
    let e = read_field_str(text, "tool.csv", &FieldReadOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("tool.csv") && msg.contains("mm-per-px"),
        "{msg}"
    );
    let options = FieldReadOptions {
        mm_per_px: Some(0.1),
        ..Default::default()
    };
    let f = read_field_str(text, "tool.csv", &options).unwrap();
    assert!((f.x[0] - 10.0).abs() < 1e-9 && (f.u[0] - 1.0).abs() < 1e-6);
}

#[test]
fn bad_tables_give_errors_naming_file_and_line() {
    let o = FieldReadOptions::default();
    let cases = [
        ("a,b,c\n1,2,3\n", "no header line"),
        ("x,y,u,v\n1,2,3\n", "line 2"),
        ("x,y,u,v\n1,2,oops,4\n", "`oops`"),
        ("x,y,u,v\n1,2,3,4\n1,2,3,4\n", "a second vector"),
        ("x,y,u,v\n", "no vectors"),
        (
            "x,y,u [furlong/fortnight],v [furlong/fortnight]\n1,1,1,1\n",
            "unknown unit",
        ),
        ("x,y,u,v,status\n1,1,1,1,300\n", "status"),
    ];
    for (text, expected) in cases {
        let e = read_field_str(text, "bad.csv", &o).unwrap_err().to_string();
        assert!(
            e.contains("bad.csv") && e.contains(expected),
            "{text:?}: {e}"
        );
    }
    // Scattered points that span a huge grid.
    let scattered: String = std::iter::once("x,y,u,v\n".to_string())
        .chain((0..100).map(|i| format!("{},{},0,0\n", i as f64 * 1.37, i as f64 * 2.11)))
        .collect();
    let e = read_field_str(&scattered, "s.csv", &o)
        .unwrap_err()
        .to_string();
    assert!(e.contains("regular grid"), "{e}");
}

#[test]
fn missing_and_unreadable_files() {
    let dir = tempfile::tempdir().unwrap();
    let o = FieldReadOptions::default();
    let missing = dir.path().join("none.nc");
    let e = read_field(&missing, &o).unwrap_err().to_string();
    assert!(e.contains("none.nc"), "{e}");
    let e = read_field(dir.path(), &o).unwrap_err().to_string();
    assert!(e.contains("folder"), "{e}");
    let broken = dir.path().join("broken.nc");
    std::fs::write(&broken, b"CDF\x01\xff\xff\xff\xff garbage").unwrap();
    let e = read_field(&broken, &o).unwrap_err().to_string();
    assert!(e.contains("broken.nc"), "{e}");
    let bad = FieldReadOptions {
        mm_per_px: Some(-1.0),
        ..Default::default()
    };
    assert!(read_field(&missing, &bad).is_err());
}

#[test]
fn an_npz_of_flattened_columns_is_refused_before_its_grid_is_made() {
    // 100 000 vectors as flat columns: read as ebiv's axes, x and y would make a grid of
    // 10¹⁰ nodes. The shape of `u` is checked first.
    use std::io::Write;
    use zip::write::SimpleFileOptions;
    let n = 100_000;
    let column: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flat.npz");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
    for name in ["x", "y", "u", "v"] {
        zip.start_file(format!("{name}.npy"), SimpleFileOptions::default())
            .unwrap();
        zip.write_all(&crate::export::npz::npy(&column, &[n]))
            .unwrap();
    }
    zip.finish().unwrap();
    let e = read_field(&path, &FieldReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("flat.npz") && e.contains("100000 values"), "{e}");
}
