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

/// A recording of `events` (at 1 ms steps from `first_us`) with rising trigger edges at
/// `triggers` and falling ones 100 µs after each, as EVT 3.0.
fn recording_with_triggers(path: &std::path::Path, first_us: i64, triggers: &[i64]) {
    let mut events = ebiv::EventBuffer::new();
    for k in 0..60 {
        events.push(first_us + 1000 * k, (k % 30) as u16, 3, 1);
    }
    for &t in triggers {
        for (dt, value) in [(0, 1), (100, 0)] {
            events.triggers.push(ebiv::Trigger {
                t: t + dt,
                channel: 0,
                value,
            });
        }
    }
    events.triggers.sort_by_key(|tr| tr.t);
    let geometry = Some(ebiv::Geometry::new(32, 8));
    let mut w = ebiv::io::write::create(path, ebiv::io::Format::Evt3, geometry).unwrap();
    w.write(&events).unwrap();
    w.finish().unwrap();
}

#[test]
fn phase_averaging_by_trigger_places_fields_between_the_edges() {
    use ebiv::field::{FieldSeries, Status, VectorField};
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    // Triggers every 10 ms from 5 ms; fields every 1 ms from 1 ms, u = their phase bin of 4
    // (the interval's quarter they fall in), so each phase's mean u is its index exactly.
    let first = 1_000_000;
    let triggers: Vec<i64> = (0..5).map(|k| first + 5_000 + 10_000 * k).collect();
    recording_with_triggers(dir.path().join("rec.raw").as_path(), first, &triggers);
    let mut series = FieldSeries::on_grid(vec![8.0, 24.0], vec![8.0]);
    let mut outside = 0;
    for k in 1..58 {
        let t = first + 1000 * k;
        let mut f = VectorField::new(series.x.clone(), series.y.clone());
        let bin = match triggers.iter().rposition(|&tr| tr <= t) {
            Some(i) if i + 1 < triggers.len() => ((t - triggers[i]) / 2500) as f32,
            _ => {
                outside += 1;
                -100.0
            }
        };
        f.u = vec![bin; 2];
        f.v = vec![0.0; 2];
        f.status = vec![Status::VALID; 2];
        series.push(t, &f).unwrap();
    }
    series.time_origin_us = Some(first);
    ebiv::export::write_field(&series, &dir.path().join("flow.nc")).unwrap();
    let o = ebiv(&[
        "stats",
        &p("flow.nc"),
        "--triggers",
        &p("rec.raw"),
        "--phases",
        "4",
        "-o",
        &p("phases.csv"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = stdout(&o);
    assert!(out.contains("5 rising trigger edge(s)"), "{out}");
    assert!(
        out.contains(&format!("{outside} field(s) outside the triggers left out")),
        "{out}"
    );
    let text = std::fs::read_to_string(p("phases.csv")).unwrap();
    assert!(text.starts_with("phase,x_px,y_px,u_mean_px_ms"), "{text}");
    for line in text.lines().skip(1) {
        let cols: Vec<f64> = line.split(',').map(|c| c.parse().unwrap()).collect();
        let bin = (cols[0] * 4.0 - 0.5).round();
        assert_eq!(cols[3], bin, "{line}");
        // Fields 0, 1, 2 ms into an interval are in its first quarter, 3, 4 ms in the second…
        let per_interval = if bin as i64 % 2 == 0 { 3.0 } else { 2.0 };
        assert_eq!(cols.last().copied(), Some(4.0 * per_interval), "{line}");
    }
    // Falling edges 100 µs later: other phases, the same number of intervals.
    let o = ebiv(&[
        "stats",
        &p("flow.nc"),
        "--triggers",
        &p("rec.raw"),
        "--trigger-polarity",
        "falling",
        "-o",
        &p("falling.nc"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout(&o).contains("5 falling trigger edge(s)"));
    // Another recording (first event elsewhere): refused, naming both times.
    recording_with_triggers(dir.path().join("other.raw").as_path(), 7_000_000, &triggers);
    for (args, expected) in [
        (
            vec!["stats", &p("flow.nc"), "--triggers", &p("other.raw")],
            "7000000",
        ),
        (
            vec![
                "stats",
                &p("flow.nc"),
                "--triggers",
                &p("rec.raw"),
                "--period",
                "1ms",
            ],
            "--period",
        ),
        (
            vec![
                "stats",
                &p("flow.nc"),
                "--triggers",
                &p("rec.raw"),
                "--trigger-polarity",
                "up",
            ],
            "rising, falling or any",
        ),
    ] {
        let o = ebiv(&args);
        assert!(!o.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(expected), "{args:?}: {err}");
    }
}
