//! Runs whose result would be empty, outputs that cannot be written, and bad values: each is
//! an error that says what was wrong (or a warning), checked before the work where it can be,
//! and leaves no file behind.

mod common;
use common::{data, ebiv, stderr};
use std::path::Path;

const WALL: &str = "ebiv/wallflow_slice2.npz";
const EVT2: &str = "prophesee/evt2_sample.raw";

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Run `ebiv args`, expect failure, and return standard error.
fn fails(args: &[&str]) -> String {
    let out = ebiv(args);
    assert!(
        !out.status.success(),
        "ebiv {args:?} succeeded; stderr: {}",
        stderr(&out)
    );
    stderr(&out)
}

#[test]
fn process_refuses_a_time_beyond_the_recording_and_writes_nothing() {
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.nc");
    let err = fails(&["process", s(&wall), "--time", "100s:101s:1s", "-o", s(&out)]);
    assert!(err.contains("no event of positive polarity"), "{err}");
    assert!(err.contains("--time"), "{err}");
    assert!(!out.exists());
}

#[test]
fn process_refuses_a_polarity_without_events() {
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.nc");
    for method in ["corrsum", "piv"] {
        let err = fails(&[
            "process",
            s(&wall),
            "--method",
            method,
            "--polarity",
            "neg",
            "-o",
            s(&out),
        ]);
        assert!(
            err.contains("no event of negative polarity"),
            "{method}: {err}"
        );
        assert!(!out.exists());
    }
}

#[test]
fn process_warns_about_fields_past_the_end() {
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.nc");
    let o = ebiv(&[
        "process",
        s(&wall),
        "--time",
        "10ms:310ms:100ms",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("3 of 4 field(s) had no event"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn process_checks_the_output_before_the_work() {
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nodir").join("a.nc");
    let err = fails(&["process", s(&wall), "-o", s(&missing)]);
    assert!(err.contains("does not exist"), "{err}");
    // No processing line was printed: the check came first.
    let o = ebiv(&["process", s(&wall), "-o", s(&missing)]);
    assert!(String::from_utf8_lossy(&o.stdout).is_empty());
    let err = fails(&["process", s(&wall), "-o", s(&dir.path().join("a.txt"))]);
    assert!(
        err.contains(".txt") && err.contains(".nc (NetCDF-3)"),
        "{err}"
    );
    let err = fails(&["process", s(&wall), "-o", s(dir.path())]);
    assert!(err.contains("folder"), "{err}");
}

#[test]
fn a_slab_longer_than_the_recording_is_reported_as_that() {
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.nc");
    // With and without explicit field times.
    for time in [None, Some("5ms:5ms:1ms")] {
        let mut args = vec!["process", s(&wall), "--slab", "1s", "--tau", "100ms"];
        args.extend(time.map(|t| ["--time", t]).into_iter().flatten());
        args.extend(["-o", s(&out)]);
        let err = fails(&args);
        assert!(
            err.contains("is shorter than the time one field needs"),
            "{err}"
        );
        assert!(err.contains("--slab"), "{err}");
    }
}

#[test]
fn pixel_settings_explain_zero_and_negative_values() {
    let Some(wall) = data(WALL) else { return };
    let err = fails(&["process", s(&wall), "--window", "-40", "-o", "x.nc"]);
    assert!(err.contains("cannot be negative"), "{err}");
    let err = fails(&["process", s(&wall), "--window", "64,-40", "-o", "x.nc"]);
    assert!(err.contains("cannot be negative"), "{err}");
    let err = fails(&["process", s(&wall), "--step", "0", "-o", "x.nc"]);
    assert!(
        err.contains("`step`") && err.contains("0 px is not a size"),
        "{err}"
    );
}

#[test]
fn frames_stop_at_the_end_of_the_recording() {
    let Some(raw) = data(EVT2) else { return };
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f");
    // The sample holds 50 ms: 50 frames of 1 ms, not 100.
    let o = ebiv(&["frames", s(&raw), "--time", "0:100ms", "-o", s(&frames)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("frames stop at its last event"));
    let pngs = std::fs::read_dir(&frames)
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension() == Some("png".as_ref()))
        .count();
    assert_eq!(pngs, 50);
}

#[test]
fn frames_refuse_empty_ranges_and_polarities() {
    let (Some(raw), Some(wall)) = (data(EVT2), data(WALL)) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f");
    let err = fails(&["frames", s(&raw), "--time", "10s:11s", "-o", s(&frames)]);
    assert!(err.contains("starts after the last event"), "{err}");
    assert!(err.contains("50.001 ms"), "{err}");
    let err = fails(&["frames", s(&wall), "--polarity", "neg", "-o", s(&frames)]);
    assert!(err.contains("no event of polarity `negative`"), "{err}");
    assert!(
        !frames.exists(),
        "no folder for frames that were not written"
    );
}

#[test]
fn convert_refuses_an_empty_selection_and_a_missing_folder() {
    let Some(raw) = data(EVT2) else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    let err = fails(&["convert", s(&raw), "--time", "10s:11s", s(&out)]);
    assert!(err.contains("no event passes the selection"), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
    let missing = dir.path().join("nodir").join("x.raw");
    let err = fails(&["convert", s(&raw), s(&missing)]);
    assert!(
        err.contains("the folder") && err.contains("does not exist"),
        "{err}"
    );
    assert!(!err.contains(".partial"), "{err}");
}

#[test]
fn files_named_raw_that_are_not_recordings_say_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.raw");
    std::fs::write(&empty, b"").unwrap();
    let err = fails(&["info", s(&empty)]);
    assert!(err.contains("the file is empty"), "{err}");
    let text = dir.path().join("notes.raw");
    std::fs::write(&text, b"recorded on Monday\nsecond line\n").unwrap();
    let err = fails(&["info", s(&text)]);
    assert!(
        err.contains("this is a text file") && err.contains("recorded on Monday"),
        "{err}"
    );
    let binary = dir.path().join("bin.raw");
    std::fs::write(&binary, [0u8, 1, 2, 255, 128, 7, 9, 200]).unwrap();
    let err = fails(&["info", s(&binary)]);
    assert!(err.contains("--raw-encoding"), "{err}");
}
