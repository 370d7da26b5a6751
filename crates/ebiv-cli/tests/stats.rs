//! `ebiv stats`: statistics of a processed series, phase averaging, and errors.

mod common;
use common::{ebiv, simulated_uniform, stdout};

#[test]
fn stats_of_a_series_with_and_without_phases() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let rec = simulated_uniform(dir.path());
    let o = ebiv(&[
        "process",
        &rec,
        "--slab",
        "10ms",
        "--time",
        "::2ms",
        "-o",
        &p("flow.nc"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = ebiv(&["stats", &p("flow.nc"), "-o", &p("stats.csv")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout(&o).contains("field(s)"));
    let text = std::fs::read_to_string(p("stats.csv")).unwrap();
    let header = text.lines().next().unwrap();
    assert!(
        header.starts_with("x_px,y_px,u_mean_px_ms") && header.ends_with(",count"),
        "{header}"
    );
    // The uniform example moves at 2 px/ms to +x: the mean u of the nodes is near it.
    let u: Vec<f64> = text
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(2)?.parse().ok())
        .filter(|v: &f64| v.is_finite())
        .collect();
    let mean = u.iter().sum::<f64>() / u.len() as f64;
    assert!(u.len() > 10 && mean > 0.5, "{mean}");
    let o = ebiv(&[
        "stats",
        &p("flow.nc"),
        "-o",
        &p("phases.csv"),
        "--period",
        "8ms",
        "--phases",
        "4",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let phased = std::fs::read_to_string(p("phases.csv")).unwrap();
    assert!(phased.starts_with("phase_us,"));
    assert_eq!(phased.lines().count() - 1, 4 * (text.lines().count() - 1));
    for (args, expected) in [
        (vec!["stats", &p("flow.nc"), "--period", "0ms"], "period"),
        (
            vec!["stats", &p("flow.nc"), "-o", &p("s.vtk")],
            ".nc or .csv",
        ),
        (vec!["stats", &p("missing.nc")], "missing.nc"),
        (vec!["stats", &p("flow.nc"), "--phases", "4"], "--period"),
    ] {
        let o = ebiv(&args);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(expected), "{args:?}: {err}");
    }
}
