//! `ebiv frames` end to end: frames rebuilt from a real recording, and pulse detection
//! refusing a recording made in continuous light.

mod common;

use common::{data, ebiv, stderr};

#[test]
fn wall_flow_frames_are_numbered_images_with_an_index() {
    let Some(file) = data("ebiv/wallflow_slice2.npz") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("frames");
    let out = ebiv(&[
        "frames",
        file.to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
        "--exposure",
        "2ms",
        "--every",
        "2.5ms",
        "--time",
        "1ms:11ms",
        "--geometry",
        "512x512",
        "--splat",
        "0.7",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    // Starts 1, 3.5, 6, 8.5 ms after the first event: the next (11 ms) would end past 11 ms.
    let csv = std::fs::read_to_string(out_dir.join("frames.csv")).unwrap();
    let rows: Vec<Vec<i64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(
        csv.lines().next(),
        Some("index,start_us,exposure_us,events")
    );
    assert_eq!(rows.len(), 4, "{csv}");
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[0], i as i64);
        assert_eq!(row[2], 2000);
        // ~89k positive events in 20 ms: ~9k per 2 ms frame.
        assert!(row[3] > 4000 && row[3] < 15_000, "{csv}");
        if i > 0 {
            assert_eq!(row[1] - rows[i - 1][1], 2500);
        }
        let png = out_dir.join(format!("frame_{i:06}.png"));
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (512, 512));
        let grey = img.into_luma16();
        assert_eq!(grey.pixels().map(|p| p.0[0]).max(), Some(65535));
        let lit = grey.pixels().filter(|p| p.0[0] > 0).count();
        assert!(lit > 4000, "{lit} lit pixels in frame {i}");
    }
    assert!(!out_dir.join("frame_000004.png").exists());

    // Time surfaces as TIFF; the wall flow was recorded in continuous light, so --pulsed
    // must refuse it rather than invent pulses.
    let out = ebiv(&[
        "frames",
        file.to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
        "--kind",
        "time-surface",
        "--image-format",
        "tiff",
        "--exposure",
        "5ms",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out_dir.join("frame_000002.tif").exists());
    let out = ebiv(&[
        "frames",
        file.to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
        "--pulsed",
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("no light pulses"), "{}", stderr(&out));
}

#[test]
fn pulsed_frames_follow_the_light_pulses_of_a_simulated_recording() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("pulsed.toml");
    std::fs::write(
        &scenario,
        r#"
seed = 3
duration = "60ms"

[sensor]
width = 64
height = 48
preset = "gen4"

[flow]
type = "uniform"
u = 2.0
v = 0.5

[particles]
density = 0.01

[illumination]
mode = "pulsed"
frequency_hz = 2000.0
duty = 0.1
phase_us = 130.0
edge_us = 2.0
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
    let frames = dir.path().join("frames");
    let out = ebiv(&[
        "frames",
        recording.to_str().unwrap(),
        "-o",
        frames.to_str().unwrap(),
        "--pulsed",
        "--kind",
        "binary",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let hz: f64 = text
        .split("pulses: ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no frequency in {text}"));
    assert!((hz / 2000.0 - 1.0).abs() < 1e-3, "{text}");
    let csv = std::fs::read_to_string(frames.join("frames.csv")).unwrap();
    let rows: Vec<Vec<i64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() >= 110, "{csv}");
    for row in &rows {
        assert_eq!(row[2], 500, "one period per frame");
        // Frames start in the dark: the light is on 130..180 µs (+2 µs edges) of each period.
        let phase = row[1].rem_euclid(500);
        assert!(
            !(110..=200).contains(&phase),
            "frame starts at phase {phase}"
        );
        assert!(row[3] > 0, "every pulse gives events: {row:?}");
    }
}
