//! `ebiv process --method piv|pulsed` end to end: a real image pair, the real wall flow
//! through frames rebuilt from events, and a simulated pulsed recording.

mod common;

use common::{data, ebiv, stderr, stdout};
use std::path::Path;

/// The first columns of a field CSV of image pairs (displacements, indexed fields).
const IMAGE_PAIR_COLUMNS: &str = "field,x_px,y_px,u_px,v_px,u_unc_px,v_unc_px,status";
/// The first columns of a field CSV of velocities in camera time.
const EVENT_COLUMNS: &str = "t_us,x_px,y_px,u_px_ms,v_px_ms,u_unc_px_ms,v_unc_px_ms,status";

/// Rows of a field CSV as (x, y, u, v, status), after checking that the header starts with
/// `columns`.
fn read_csv(path: &Path, columns: &str) -> Vec<(f64, f64, f64, f64, u32)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    assert!(header.starts_with(columns), "{header}");
    lines
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (
                c[1].parse().unwrap(),
                c[2].parse().unwrap(),
                c[3].parse().unwrap(),
                c[4].parse().unwrap(),
                c[7].parse().unwrap(),
            )
        })
        .collect()
}

/// The values of the column `name` of a field CSV.
fn column(path: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let k = header
        .split(',')
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header}"));
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse().unwrap())
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn image_pair_gives_displacements_in_px() {
    let (Some(a), Some(b)) = (
        data("piv/PIVlab_Karman_01.bmp"),
        data("piv/PIVlab_Karman_02.bmp"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("karman.csv");
    let nc = dir.path().join("karman.nc");
    let figures = dir.path().join("fig");
    let out = ebiv(&[
        "process",
        "--method",
        "piv",
        "--images",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--passes",
        "64,32",
        "--overlap",
        "0.5",
        "-o",
        csv.to_str().unwrap(),
        "--png",
        figures.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("displacements in px"),
        "{}",
        stdout(&out)
    );
    let rows = read_csv(&csv, IMAGE_PAIR_COLUMNS);
    let valid: Vec<_> = rows.iter().filter(|r| r.4 == 0).collect();
    assert!(valid.len() as f64 >= 0.95 * rows.len() as f64);
    // The Kármán street's free stream runs right to left at about 1.8 px per frame pair.
    let u = median(valid.iter().map(|r| r.2).collect());
    assert!((-2.2..-1.4).contains(&u), "median u {u}");
    assert!(figures.join("field_0000.png").is_file() && figures.join("histograms.png").is_file());
    // NetCDF states displacement units.
    let out = ebiv(&[
        "process",
        "--method",
        "piv",
        "--images",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--passes",
        "64,32",
        "-o",
        nc.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let bytes = std::fs::read(&nc).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    assert!(text.contains("displacement along x"));
    // The time axis is the index of the pair, not a slab centre in camera time; the
    // settings are plain text. Without `--dt` a pair has no time span: `slab_us` says so.
    assert!(text.contains("index of the field (one per image pair)"));
    assert!(text.contains("0 when it is not given"));
    for absent in ["time slab", "microseconds since", "ValidationParams"] {
        assert!(
            !text.contains(absent),
            "`{absent}` in the NetCDF of an image pair"
        );
    }
    assert!(text.contains("normalised median test threshold"));

    // Mistakes are explained.
    let out = ebiv(&[
        "process",
        "--method",
        "piv",
        "--images",
        a.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("at least two images"),
        "{}",
        stderr(&out)
    );
    let out = ebiv(&[
        "process",
        "--method",
        "corrsum",
        "--images",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
    ]);
    assert!(
        stderr(&out).contains("needs --method piv"),
        "{}",
        stderr(&out)
    );
    let out = ebiv(&[
        "process",
        "--method",
        "piv",
        "--images",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--passes",
        "2048",
    ]);
    assert!(stderr(&out).contains("does not fit"), "{}", stderr(&out));
}

/// The real wall flow through frames rebuilt from its events (three pairs of 1 ms count
/// frames 2 ms apart, 64 → 40 px): the same median velocity as the event estimators report
/// in docs/process.md, (1.47, 0.27) px/ms by sum of correlation.
#[test]
fn wall_flow_through_event_frames_matches_the_event_estimators() {
    let Some(file) = data("ebiv/wallflow_slice2.npz") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("wall.csv");
    let out = ebiv(&[
        "process",
        file.to_str().unwrap(),
        "--method",
        "piv",
        "--time",
        "10ms:10ms:1ms",
        "--window",
        "64,40",
        "--step",
        "32,20",
        "--pairs",
        "3",
        "--exposure",
        "1ms",
        "--frame-step",
        "2ms",
        "-o",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let rows = read_csv(&csv, EVENT_COLUMNS);
    let valid: Vec<_> = rows.iter().filter(|r| r.4 == 0).collect();
    let (u, v) = (
        median(valid.iter().map(|r| r.2).collect()),
        median(valid.iter().map(|r| r.3).collect()),
    );
    eprintln!(
        "wall flow, piv of event frames: {} of {} valid, median ({u:.3}, {v:.3}) px/ms",
        valid.len(),
        rows.len()
    );
    assert!(valid.len() as f64 >= 0.9 * rows.len() as f64);
    assert!(
        (1.3..1.7).contains(&u) && (0.1..0.45).contains(&v),
        "({u}, {v})"
    );
    // Every vector was measured over the span of its four frames: 3 × 2 ms + 1 ms.
    assert!(column(&csv, "slab_us").iter().all(|&s| s == 7000.0));
}

/// A pulsed light sheet (1 kHz, 5 % duty) on a uniform 1.5 px/ms flow: `--method pulsed`
/// finds the pulses by itself and measures the flow from one frame per pulse.
#[test]
fn pulsed_recording_is_measured_from_one_frame_per_pulse() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("pulsed.toml");
    std::fs::write(
        &scenario,
        r#"
seed = 5
duration = "40ms"

[sensor]
width = 192
height = 128
preset = "gen4"

[flow]
type = "uniform"
u = 1.5
v = -0.5

[particles]
density = 0.006
diameter = 2.5
brightness = 20.0

[illumination]
mode = "pulsed"
frequency_hz = 1000.0
duty = 0.05
phase_us = 300.0
"#,
    )
    .unwrap();
    let recording = dir.path().join("pulsed.raw");
    let out = ebiv(&[
        "simulate",
        scenario.to_str().unwrap(),
        "-o",
        recording.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let csv = dir.path().join("pulsed.csv");
    let out = ebiv(&[
        "process",
        recording.to_str().unwrap(),
        "--method",
        "pulsed",
        "--window",
        "64,32",
        "--pairs",
        "3",
        "-o",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    let hz: f64 = text
        .split("pulses: ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no pulse frequency in {text}"));
    assert!((hz - 1000.0).abs() < 1.0, "{hz} Hz");
    let rows = read_csv(&csv, EVENT_COLUMNS);
    let valid: Vec<_> = rows.iter().filter(|r| r.4 == 0).collect();
    let (u, v) = (
        median(valid.iter().map(|r| r.2).collect()),
        median(valid.iter().map(|r| r.3).collect()),
    );
    eprintln!(
        "pulsed: {} of {} valid, median ({u:.4}, {v:.4}) px/ms",
        valid.len(),
        rows.len()
    );
    assert!(valid.len() as f64 >= 0.9 * rows.len() as f64);
    assert!(
        (u - 1.5).abs() < 0.03 && (v + 0.5).abs() < 0.03,
        "({u}, {v})"
    );
    // Four frames of one 1 ms period each (starts and exposure rounded to whole µs).
    let slabs = column(&csv, "slab_us");
    assert!(
        slabs.iter().all(|&s| (s - 4000.0).abs() <= 2.0),
        "{slabs:?}"
    );

    // With --time, the pulses are found from the requested start on.
    let out = ebiv(&[
        "process",
        recording.to_str().unwrap(),
        "--method",
        "pulsed",
        "--window",
        "64,32",
        "--time",
        "20ms:30ms:5ms",
        "-o",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let rows = read_csv(&csv, EVENT_COLUMNS);
    assert!(!rows.is_empty());
    assert!(rows.iter().filter(|r| r.4 == 0).count() as f64 >= 0.9 * rows.len() as f64);
}
