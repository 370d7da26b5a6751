use super::*;
use netcdf3::{DataSet, FileWriter, Version};

/// A field linear in x, y and t: bilinear-in-space, linear-in-time interpolation reproduces
/// it exactly.
fn linear(x: f64, y: f64, t: f64) -> (f64, f64) {
    (
        0.3 + 0.02 * x - 0.01 * y + 1e-4 * t,
        -0.5 + 0.005 * x + 0.03 * y - 2e-4 * t,
    )
}

/// Non-uniform axes, so that the test also covers rectilinear grids.
fn axes() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    (
        vec![0.0, 1_000.0, 3_000.0],
        vec![0.0, 16.0, 32.0, 56.0, 80.0, 100.0],
        vec![-10.0, 20.0, 40.0, 45.0, 90.0],
    )
}

fn sample(times: &[f64], xs: &[f64], ys: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (mut u, mut v) = (Vec::new(), Vec::new());
    for &t in times {
        for &y in ys {
            for &x in xs {
                let (a, b) = linear(x, y, t);
                u.push(a);
                v.push(b);
            }
        }
    }
    (u, v)
}

fn linear_grid() -> GriddedFlow {
    let (times, xs, ys) = axes();
    let (u, v) = sample(&times, &xs, &ys);
    GriddedFlow::new(times, xs, ys, u, v).unwrap()
}

fn close(a: (f64, f64), b: (f64, f64)) -> bool {
    (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12
}

#[test]
fn gridded_flow_reproduces_a_linear_field_exactly() {
    let flow = linear_grid();
    for i in 0..50 {
        let x = 0.0 + 1.79 * i as f64;
        let y = -9.0 + 2.0 * i as f64;
        let t = 61.0 * i as f64;
        assert!(
            close(flow.velocity(x, y, t), linear(x, y, t)),
            "at ({x}, {y}, {t})"
        );
    }
}

#[test]
fn gridded_flow_interpolates_linearly_in_time() {
    let flow = GriddedFlow::new(
        vec![0.0, 1_000.0],
        vec![0.0, 10.0],
        vec![0.0, 10.0],
        vec![1.0, 1.0, 1.0, 1.0, 3.0, 3.0, 3.0, 3.0],
        vec![0.0, 0.0, 0.0, 0.0, -2.0, -2.0, -2.0, -2.0],
    )
    .unwrap();
    assert_eq!(flow.velocity(5.0, 5.0, 250.0), (1.5, -0.5));
    assert_eq!(flow.velocity(5.0, 5.0, 1_000.0), (3.0, -2.0));
    // u = 1 + 2t (t in ms) from x = 0: x(1 ms) = 1 + 1 = 2.
    let p = flow.advect((0.0, 0.0), 0.0, 1_000.0);
    assert!(
        (p.0 - 2.0).abs() < 1e-9 && (p.1 + 1.0).abs() < 1e-9,
        "{p:?}"
    );
}

#[test]
fn gridded_flow_clamps_outside_the_grid_in_space_and_time() {
    let flow = linear_grid();
    assert!(close(
        flow.velocity(-50.0, 20.0, 500.0),
        linear(0.0, 20.0, 500.0)
    ));
    assert!(close(
        flow.velocity(30.0, 500.0, 500.0),
        linear(30.0, 90.0, 500.0)
    ));
    assert!(close(
        flow.velocity(500.0, -500.0, -7.0),
        linear(100.0, -10.0, 0.0)
    ));
    assert!(close(
        flow.velocity(5.0, 5.0, 1e9),
        linear(5.0, 5.0, 3_000.0)
    ));
    let (u, v) = flow.velocity(f64::NAN, 5.0, 0.0);
    assert!(u.is_nan() && v.is_nan());
}

#[test]
fn gridded_flow_advects_a_steady_uniform_field_exactly() {
    let flow = GriddedFlow::new(
        vec![0.0],
        vec![0.0, 100.0],
        vec![0.0, 50.0],
        vec![2.0; 4],
        vec![-0.5; 4],
    )
    .unwrap();
    let p = flow.advect((10.0, 20.0), 0.0, 20_000.0);
    assert!(
        (p.0 - 50.0).abs() < 1e-9 && (p.1 - 10.0).abs() < 1e-9,
        "{p:?}"
    );
    // Beyond the grid the edge velocity carries on.
    let p = flow.advect((90.0, 20.0), 0.0, 20_000.0);
    assert!((p.0 - 130.0).abs() < 1e-9, "{p:?}");
    assert_eq!(flow.max_speed(320.0, 240.0, 0.0), 2f64.hypot(0.5));
}

#[test]
fn gridded_flow_nan_nodes_stop_particles_and_are_ignored_by_max_speed() {
    let mut u = vec![1.0; 9];
    u[5] = f64::NAN; // node (x = 20, y = 10)
    let flow = GriddedFlow::new(
        vec![0.0],
        vec![0.0, 10.0, 20.0],
        vec![0.0, 10.0, 20.0],
        u,
        vec![0.0; 9],
    )
    .unwrap();
    assert_eq!(flow.velocity(5.0, 10.0, 0.0), (1.0, 0.0));
    let p = flow.advect((0.0, 10.0), 0.0, 50_000.0);
    assert!(p.0 <= 10.0 && p.0 > 9.0, "{p:?}");
    assert_eq!(flow.max_speed(100.0, 100.0, 0.0), 1.0);
}

#[test]
fn gridded_flow_reverses_decreasing_axes() {
    let (times, xs, mut ys) = axes();
    ys.reverse();
    let (u, v) = sample(&times, &xs, &ys);
    let flow = GriddedFlow::new(times, xs, ys, u, v).unwrap();
    assert!(flow.y().windows(2).all(|w| w[1] > w[0]));
    assert!(close(
        flow.velocity(33.0, 44.0, 1_500.0),
        linear(33.0, 44.0, 1_500.0)
    ));
}

#[test]
fn gridded_flow_rejects_bad_grids_by_name() {
    let name = |r: Result<GriddedFlow>| match r {
        Err(Error::Parameter { name, .. }) => name,
        other => panic!("expected a parameter error, got {other:?}"),
    };
    let grid = |xs: Vec<f64>, n: usize| {
        GriddedFlow::new(vec![0.0], xs, vec![0.0], vec![0.0; n], vec![0.0; n])
    };
    assert_eq!(name(grid(vec![0.0, 1.0, 1.0], 3)), "x");
    assert_eq!(name(grid(vec![0.0, 2.0, 1.0], 3)), "x");
    assert_eq!(name(grid(vec![0.0, f64::NAN], 2)), "x");
    assert_eq!(name(grid(vec![], 0)), "x");
    assert_eq!(name(grid(vec![0.0, 1.0], 3)), "u");
}

fn to_csv(rows: &[(f64, f64, f64, f64, f64)]) -> String {
    let mut text = String::from("t_us,x,y,u,v\n");
    for r in rows {
        text += &format!("{},{},{},{},{}\n", r.0, r.1, r.2, r.3, r.4);
    }
    text
}

fn linear_rows() -> Vec<(f64, f64, f64, f64, f64)> {
    let (times, xs, ys) = axes();
    let mut rows = Vec::new();
    for &t in &times {
        for &y in &ys {
            for &x in &xs {
                let (u, v) = linear(x, y, t);
                rows.push((t, x, y, u, v));
            }
        }
    }
    rows
}

#[test]
fn csv_rows_in_any_order_give_the_same_field() {
    let mut rows = linear_rows();
    // A fixed shuffle: reverse, then interleave halves.
    rows.reverse();
    let (a, b) = rows.split_at(rows.len() / 2);
    let shuffled: Vec<_> = a.iter().zip(b).flat_map(|(p, q)| [*q, *p]).collect();
    let from_csv = GriddedFlow::from_csv_str(&to_csv(&shuffled), "field.csv").unwrap();
    assert_eq!(from_csv, linear_grid());
    // Columns in another order, extra columns, comments and blank lines.
    let mut text = String::from("# exported by hand\nu, y, extra, x, v, t_us\n\n");
    for r in linear_rows() {
        text += &format!("{},{},7,{},{},{}\n", r.3, r.2, r.1, r.4, r.0);
    }
    assert_eq!(
        GriddedFlow::from_csv_str(&text, "f.csv").unwrap(),
        linear_grid()
    );
}

#[test]
fn csv_incomplete_grid_names_the_missing_point() {
    let mut rows = linear_rows();
    let gone = rows.remove(37);
    let err = GriddedFlow::from_csv_str(&to_csv(&rows), "field.csv").unwrap_err();
    let message = err.to_string();
    let want = format!(
        "no row for t_us = {}, x = {}, y = {}",
        gone.0, gone.1, gone.2
    );
    assert!(message.starts_with("field.csv: "), "{message}");
    assert!(message.contains(&want), "{message}");
    // Scattered points (every row a new x and y) cannot form a grid.
    let scattered = to_csv(&[(0.0, 1.0, 2.0, 0.0, 0.0), (0.0, 3.0, 4.0, 0.0, 0.0)]);
    let message = GriddedFlow::from_csv_str(&scattered, "s.csv")
        .unwrap_err()
        .to_string();
    assert!(message.contains("incomplete"), "{message}");
}

#[test]
fn csv_errors_name_the_line_and_the_problem() {
    let parse = |text: &str| GriddedFlow::from_csv_str(text, "f.csv").unwrap_err();
    let line_of = |e: Error| match e {
        Error::Parse { line, message, .. } => (line, message),
        other => panic!("expected a parse error, got {other}"),
    };
    let (line, message) = line_of(parse(
        "t_us,x,y,u,v\n0,0,0,1,1\n0,1,0,1,1\n0,0,0,2,2\n0,1,0,1,1\n",
    ));
    assert_eq!(line, 4);
    assert!(
        message.contains("duplicate") && message.contains("line 2"),
        "{message}"
    );
    let (line, message) = line_of(parse("t_us,x,y,u,v\n0,0,0,1,1\n0,1,zero,1,1\n"));
    assert_eq!(line, 3);
    assert!(
        message.contains("`y`") && message.contains("zero"),
        "{message}"
    );
    let (line, message) = line_of(parse("t_us,x,y,u,v\n0,0,0,1\n"));
    assert_eq!(line, 2);
    assert!(message.contains("`v`"), "{message}");
    let (line, message) = line_of(parse("t,x,y,u,v\n0,0,0,1,1\n"));
    assert_eq!(line, 1);
    assert!(message.contains("t_us"), "{message}");
    let (_, message) = line_of(parse("t_us,x,y,u,v\n0,inf,0,1,1\n"));
    assert!(message.contains("finite"), "{message}");
    assert!(parse("").to_string().contains("empty"));
    assert!(parse("t_us,x,y,u,v\n").to_string().contains("no data rows"));
    // NaN velocities are allowed (invalid vectors), NaN coordinates are not.
    GriddedFlow::from_csv_str("t_us,x,y,u,v\n5,1,2,NaN,NaN\n", "f.csv").unwrap();
    assert!(GriddedFlow::from_csv_str("t_us,x,y,u,v\n5,NaN,2,0,0\n", "f.csv").is_err());
}

/// Write a NetCDF classic file like ebiv's export: f32 `u`, `v` over (time, y, x).
fn write_netcdf(
    path: &Path,
    times: Option<(&[f64], &str)>,
    xs: &[f64],
    ys: &[f64],
    u: &[f32],
    v: &[f32],
) {
    let mut ds = DataSet::new();
    let mut dims = Vec::new();
    if let Some((t, units)) = times {
        ds.add_fixed_dim("time", t.len()).unwrap();
        ds.add_var_f64("time", &["time"]).unwrap();
        ds.add_var_attr_string("time", "units", units).unwrap();
        dims.push("time");
    }
    ds.add_fixed_dim("y", ys.len()).unwrap();
    ds.add_fixed_dim("x", xs.len()).unwrap();
    dims.extend(["y", "x"]);
    ds.add_var_f64("y", &["y"]).unwrap();
    ds.add_var_f64("x", &["x"]).unwrap();
    ds.add_var_f32("u", &dims).unwrap();
    ds.add_var_f32("v", &dims).unwrap();
    ds.add_var_attr_f32("u", "_FillValue", vec![-999.0])
        .unwrap();
    let mut w = FileWriter::open(path).unwrap();
    w.set_def(&ds, Version::Offset64Bit, 0).unwrap();
    if let Some((t, _)) = times {
        w.write_var_f64("time", t).unwrap();
    }
    w.write_var_f64("y", ys).unwrap();
    w.write_var_f64("x", xs).unwrap();
    w.write_var_f32("u", u).unwrap();
    w.write_var_f32("v", v).unwrap();
    w.close().unwrap();
}

#[test]
fn netcdf_time_y_x_field_is_read_with_units_and_fill_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("field.nc");
    // Values exactly representable in f32.
    let xs = [0.0, 10.0, 20.0];
    let ys = [0.0, 8.0];
    let n = 2 * ys.len() * xs.len();
    let u: Vec<f32> = (0..n)
        .map(|i| if i == 4 { -999.0 } else { i as f32 * 0.5 })
        .collect();
    let v: Vec<f32> = (0..n).map(|i| -(i as f32)).collect();
    write_netcdf(&path, Some((&[0.0, 2.0], "milliseconds")), &xs, &ys, &u, &v);
    let flow = GriddedFlow::open(&path).unwrap();
    assert_eq!(flow.times_us(), &[0.0, 2_000.0]);
    assert_eq!(flow.x(), &xs);
    assert_eq!(flow.y(), &ys);
    // Node (t = 1, y = 0, x = 0) is flat index 6.
    assert_eq!(flow.velocity(0.0, 0.0, 2_000.0), (3.0, -6.0));
    assert_eq!(flow.velocity(0.0, 0.0, 1_000.0), (1.5, -3.0));
    // The fill value became NaN: node (t = 0, y = 8, x = 10).
    assert!(flow.velocity(10.0, 8.0, 0.0).0.is_nan());
}

#[test]
fn netcdf_steady_y_x_field_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("steady.nc");
    let xs = [0.0, 4.0];
    let ys = [10.0, 0.0]; // stored bottom-up
    write_netcdf(&path, None, &xs, &ys, &[1.0, 2.0, 3.0, 4.0], &[0.0; 4]);
    let flow = GriddedFlow::from_netcdf(&path).unwrap();
    assert_eq!(flow.times_us(), &[0.0]);
    assert_eq!(flow.y(), &[0.0, 10.0]);
    assert_eq!(flow.velocity(0.0, 0.0, 5e6), (3.0, 0.0));
    assert_eq!(flow.velocity(2.0, 5.0, 0.0), (2.5, 0.0));
}

#[test]
fn netcdf_errors_name_the_file_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    // No `v` variable.
    let path = dir.path().join("no_v.nc");
    let mut ds = DataSet::new();
    ds.add_fixed_dim("y", 1).unwrap();
    ds.add_fixed_dim("x", 1).unwrap();
    ds.add_var_f64("y", &["y"]).unwrap();
    ds.add_var_f64("x", &["x"]).unwrap();
    ds.add_var_f64("u", &["y", "x"]).unwrap();
    let mut w = FileWriter::open(&path).unwrap();
    w.set_def(&ds, Version::Classic, 0).unwrap();
    for name in ["y", "x", "u"] {
        w.write_var_f64(name, &[0.0]).unwrap();
    }
    w.close().unwrap();
    let message = GriddedFlow::open(&path).unwrap_err().to_string();
    assert!(
        message.contains("no_v.nc") && message.contains("no variable `v`"),
        "{message}"
    );

    let path = dir.path().join("whole.nc");
    write_netcdf(
        &path,
        None,
        &[0.0, 1.0],
        &[0.0, 1.0, 2.0],
        &[0.0; 6],
        &[0.0; 6],
    );
    let bytes = std::fs::read(&path).unwrap();
    // Truncated: the header promises data that is not there.
    let cut = dir.path().join("cut.nc");
    std::fs::write(&cut, &bytes[..bytes.len() - 20]).unwrap();
    let message = GriddedFlow::open(&cut).unwrap_err().to_string();
    assert!(message.contains("cut.nc"), "{message}");
    // Garbage after the signature.
    let junk = dir.path().join("junk.nc");
    std::fs::write(&junk, b"CDF\x01\xff\xff\xff\xff\x00\x00").unwrap();
    let message = GriddedFlow::open(&junk).unwrap_err().to_string();
    assert!(message.contains("junk.nc"), "{message}");
    // NetCDF-4 is recognised and explained.
    let hdf = dir.path().join("four.nc");
    std::fs::write(&hdf, b"\x89HDF\r\n\x1a\n....").unwrap();
    let message = GriddedFlow::open(&hdf).unwrap_err().to_string();
    assert!(
        message.contains("four.nc") && message.contains("classic"),
        "{message}"
    );
}

#[test]
fn netcdf_wrong_dimension_order_is_explained() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("xy.nc");
    let mut ds = DataSet::new();
    ds.add_fixed_dim("y", 2).unwrap();
    ds.add_fixed_dim("x", 3).unwrap();
    ds.add_var_f64("y", &["y"]).unwrap();
    ds.add_var_f64("x", &["x"]).unwrap();
    ds.add_var_f64("u", &["x", "y"]).unwrap();
    ds.add_var_f64("v", &["x", "y"]).unwrap();
    let mut w = FileWriter::open(&path).unwrap();
    w.set_def(&ds, Version::Classic, 0).unwrap();
    w.write_var_f64("y", &[0.0, 1.0]).unwrap();
    w.write_var_f64("x", &[0.0, 1.0, 2.0]).unwrap();
    w.write_var_f64("u", &[0.0; 6]).unwrap();
    w.write_var_f64("v", &[0.0; 6]).unwrap();
    w.close().unwrap();
    let message = GriddedFlow::open(&path).unwrap_err().to_string();
    assert!(
        message.contains("xy.nc") && message.contains("(x, y)"),
        "{message}"
    );
}

#[test]
fn csv_file_is_detected_and_read_from_disk() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("truth.csv");
    std::fs::write(&path, to_csv(&linear_rows())).unwrap();
    assert_eq!(GriddedFlow::open(&path).unwrap(), linear_grid());
    let message = GriddedFlow::open(dir.path().join("absent.csv"))
        .unwrap_err()
        .to_string();
    assert!(message.contains("absent.csv"), "{message}");
}

#[test]
fn netcdf_header_counts_beyond_the_file_are_rejected_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.nc");
    // CDF-1, 0 records, a dimension list claiming 2^31 − 1 entries.
    let mut bytes = b"CDF\x01".to_vec();
    bytes.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 0x0A, 0x7F, 0xFF, 0xFF, 0xFF]);
    bytes.extend_from_slice(&[0; 64]);
    std::fs::write(&path, &bytes).unwrap();
    let message = GriddedFlow::open(&path).unwrap_err().to_string();
    assert!(
        message.contains("huge.nc") && message.contains("more than the file holds"),
        "{message}"
    );
    // CDF-5 is recognised and explained.
    std::fs::write(&path, b"CDF\x05\0\0\0\0\0\0\0\0").unwrap();
    let message = GriddedFlow::open(&path).unwrap_err().to_string();
    assert!(message.contains("CDF-5"), "{message}");
}

#[test]
fn truth_csv_written_by_ebiv_reads_back_with_its_unit_named_columns() {
    let flow = crate::sim::flow::Uniform { u: 1.5, v: -0.5 };
    let geometry = crate::event::Geometry::new(64, 32);
    let truth = crate::sim::truth::velocity_field(&flow, geometry, 16.0, 0, 2000, 1000);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("truth.csv");
    crate::export::write_field_csv(&truth, &path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.starts_with("t_us,x_px,y_px,u_px_ms,v_px_ms\n"),
        "{text}"
    );
    let read = GriddedFlow::open(&path).unwrap();
    assert_eq!(read.velocity(20.0, 10.0, 500.0), (1.5, -0.5));
}
