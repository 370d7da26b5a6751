//! `ebiv derive` and `ebiv process --derive`: derived quantities of a field file, the maps.

mod common;
use common::{ebiv, simulated_uniform, stdout};
use ebiv::field::{FieldSeries, Status, VectorField};

/// A solid-body rotation of `omega` per ms about (40, 24) on a 6 × 4 grid of step 16 px,
/// one node invalid.
fn rotation(omega: f32) -> FieldSeries {
    let x: Vec<f64> = (0..6).map(|i| 8.0 + 16.0 * i as f64).collect();
    let y: Vec<f64> = (0..4).map(|i| 8.0 + 16.0 * i as f64).collect();
    let mut f = VectorField::new(x.clone(), y.clone());
    for (r, &yy) in y.iter().enumerate() {
        for (c, &xx) in x.iter().enumerate() {
            let i = f.index(r, c);
            f.u[i] = -omega * (yy - 24.0) as f32;
            f.v[i] = omega * (xx - 40.0) as f32;
            f.status[i] = Status::VALID;
        }
    }
    f.invalidate(f.index(1, 2), Status::MEDIAN_TEST);
    let mut s = FieldSeries::on_grid(x, y);
    s.push(5000, &f).unwrap();
    s
}

#[test]
fn derive_writes_the_quantities_with_units_and_draws_them() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    ebiv::export::write_field(&rotation(0.05), &dir.path().join("rot.nc")).unwrap();
    let o = ebiv(&[
        "derive",
        &p("rot.nc"),
        "-o",
        &p("d.csv"),
        "--quantities",
        "vorticity,swirling_strength",
        "--png",
        &p("figs"),
        "--vectors",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout(&o).contains("in 1/ms"), "{}", stdout(&o));
    let text = std::fs::read_to_string(p("d.csv")).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (w, l) = (col("vorticity_1_ms"), col("swirling_strength_1_ms"));
    let mut nan = Vec::new();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|c| c.parse().unwrap()).collect();
        if v[w].is_nan() {
            assert!(v[l].is_nan(), "{line}");
            nan.push((v[1], v[2]));
            continue;
        }
        assert!((v[w] - 0.1).abs() < 1e-6, "vorticity 2ω: {line}");
        assert!((v[l] - 0.05).abs() < 1e-6, "swirling strength ω: {line}");
    }
    // The invalid node, and the one above it on the grid's edge, which has no other
    // neighbour along y: NaN, not a difference with a zero.
    assert_eq!(nan, vec![(40.0, 8.0), (40.0, 24.0)]);
    assert!(dir.path().join("figs/vorticity_0000.png").exists());

    // Calibrated: 1/s, and the sign of the vorticity flips with y up (NetCDF).
    let mut s = rotation(0.05);
    s.calibration = Some(ebiv::field::Calibration {
        mm_per_px: 0.1,
        origin_px: [0.0, 0.0],
        y_up: true,
    });
    ebiv::export::write_field(&s, &dir.path().join("cal.nc")).unwrap();
    let o = ebiv(&[
        "derive",
        &p("cal.nc"),
        "-o",
        &p("cal_d.nc"),
        "--quantities",
        "vorticity",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout(&o).contains("in 1/s"), "{}", stdout(&o));
    let back = ebiv::io::field::read_field(
        &dir.path().join("cal_d.nc"),
        &ebiv::io::field::FieldReadOptions::default(),
    )
    .unwrap();
    assert_eq!(back.calibration, s.calibration);
    let (ds, _) = netcdf3::FileReader::open(dir.path().join("cal_d.nc"))
        .unwrap()
        .close();
    let units = ds.get_var_attr_as_string("vorticity", "units").unwrap();
    assert_eq!(units, "1/s");
    let long = ds.get_var_attr_as_string("vorticity", "long_name").unwrap();
    assert!(long.contains("counter-clockwise"), "{long}");
    let mut file = netcdf3::FileReader::open(dir.path().join("cal_d.nc")).unwrap();
    let values = file.read_var_f32("vorticity").unwrap();
    let finite: Vec<f32> = values.into_iter().filter(|v| v.is_finite()).collect();
    assert_eq!(finite.len(), 22);
    assert!(
        finite.iter().all(|v| (v + 100.0).abs() < 1e-3),
        "{finite:?}"
    );

    for (args, expected) in [
        (
            vec!["derive", &p("rot.nc"), "-o", &p("d.vtk")],
            ".nc, .csv or .npz",
        ),
        (vec!["derive", &p("rot.nc"), "--quantities", "curl"], "curl"),
        (
            vec![
                "derive",
                &p("rot.nc"),
                "--quantities",
                "divergence",
                "--png",
                &p("f"),
                "--quantity",
                "vorticity",
            ],
            "--quantities",
        ),
        (vec!["derive", &p("missing.nc")], "missing.nc"),
    ] {
        let o = ebiv(&args);
        assert!(!o.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(expected), "{args:?}: {err}");
    }
}

#[test]
fn process_derive_adds_the_quantities_and_their_maps() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let rec = simulated_uniform(dir.path());
    let o = ebiv(&[
        "process",
        &rec,
        "--time",
        "10ms:20ms:10ms",
        "--derive",
        "divergence,vorticity",
        "-o",
        &p("flow.npz"),
        "--png",
        &p("figs"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout(&o).contains("2 map(s) of vorticity"),
        "{}",
        stdout(&o)
    );
    assert!(dir.path().join("figs/vorticity_0001.png").exists());
    let zip = std::fs::read(p("flow.npz")).unwrap();
    let has = |name: &str| zip.windows(name.len()).any(|w| w == name.as_bytes());
    assert!(has("vorticity.npy") && has("divergence.npy") && !has("e_xx.npy"));
    let o = ebiv(&["process", &rec, "--derive", "all", "-o", &p("flow.vtk")]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains(".nc, .csv or .npz"));
}
