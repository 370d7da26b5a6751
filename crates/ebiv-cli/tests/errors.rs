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
    // The wall slice does not state its sensor size, the RAW sample does: the same message.
    for name in [WALL, EVT2] {
        let Some(file) = data(name) else { return };
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.nc");
        let err = fails(&[
            "process",
            s(&file),
            "--slab",
            "1s",
            "--tau",
            "100ms",
            "-o",
            s(&out),
        ]);
        assert!(
            err.contains("is shorter than the time one field needs"),
            "{name}: {err}"
        );
        assert!(err.contains("--slab"), "{err}");
    }
}

#[test]
fn extreme_times_are_refused_not_wrapped() {
    let Some(wall) = data(WALL) else { return };
    let err = fails(&[
        "process",
        s(&wall),
        "--time=-9000000000000s:9000000000000s:1s",
        "-o",
        "x.nc",
    ]);
    assert!(err.contains("more than the limit"), "{err}");
    let err = fails(&[
        "render",
        s(&wall),
        "--t0",
        "9000000000000s",
        "--dt",
        "9000000000000s",
        "-o",
        "x.png",
    ]);
    assert!(err.contains("beyond the range of time stamps"), "{err}");
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
    assert!(err.contains("no event of polarity `neg`"), "{err}");
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

/// Run `ebiv args`, send SIGINT once `wait_for` exists, and return the exit status and
/// standard error (`None` if the run finished before `wait_for` appeared).
#[cfg(target_os = "linux")]
fn interrupt_when(args: &[&str], wait_for: &Path) -> Option<(std::process::ExitStatus, String)> {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_ebiv"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while !wait_for.exists() {
        if child.try_wait().unwrap().is_some() {
            return None;
        }
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            panic!("{} never appeared", wait_for.display());
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    // SAFETY: `kill` on our own child's pid with a valid signal.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
    let out = child.wait_with_output().unwrap();
    Some((out.status, stderr(&out)))
}

/// Every PNG in `dir` decodes (none is half-written), and how many there are.
fn whole_pngs(dir: &Path) -> usize {
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!name.ends_with(".partial"), "unfinished file {name}");
        if name.ends_with(".png") {
            image::open(&path).unwrap_or_else(|e| panic!("{name} is not a whole PNG: {e}"));
            n += 1;
        }
    }
    n
}

/// Ctrl-C during `process` stops it after a field: no field file, whole figures, and the
/// process ends by SIGINT.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_process_run_leaves_no_field_file_and_whole_figures() {
    use std::os::unix::process::ExitStatusExt;
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let (out, figures) = (dir.path().join("a.nc"), dir.path().join("fig"));
    let args = [
        "process",
        s(&wall),
        "--time",
        "5ms:15ms:20us",
        "-o",
        s(&out),
        "--png",
        s(&figures),
    ];
    let Some((status, err)) = interrupt_when(&args, &figures.join("field_0001.png")) else {
        panic!("500 fields with figures finished before an interrupt")
    };
    assert_eq!(status.signal(), Some(libc::SIGINT), "{status:?}: {err}");
    assert!(err.contains("interrupted"), "{err}");
    assert!(!out.exists());
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["fig"], "only the figures folder is left");
    let n = whole_pngs(&figures);
    assert!((2..500).contains(&n), "{n} figures");
}

/// Ctrl-C during `frames` stops after a whole frame, and frames.csv lists the frames written.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_frames_run_lists_its_whole_frames() {
    use std::os::unix::process::ExitStatusExt;
    let Some(raw) = data(EVT2) else { return };
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f");
    let args = ["frames", s(&raw), "--every", "10us", "-o", s(&frames)];
    let Some((status, err)) = interrupt_when(&args, &frames.join("frame_000001.png")) else {
        panic!("4900 frames finished before an interrupt")
    };
    assert_eq!(status.signal(), Some(libc::SIGINT), "{status:?}: {err}");
    assert!(err.contains("are complete"), "{err}");
    let n = whole_pngs(&frames);
    let listed = std::fs::read_to_string(frames.join("frames.csv")).unwrap();
    assert_eq!(
        listed.lines().count(),
        n + 1,
        "header and one line per frame"
    );
    assert!(n < 4900);
}

#[test]
fn render_refuses_to_draw_nothing() {
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let err = fails(&["render", s(&wall), "--t0", "10s", "-o", s(&out)]);
    assert!(err.contains("no event of polarity `both` within"), "{err}");
    let err = fails(&[
        "render",
        s(&wall),
        "--rate",
        "--polarity",
        "neg",
        "-o",
        s(&out),
    ]);
    assert!(
        err.contains("no event of polarity `neg` in the recording"),
        "{err}"
    );
    assert!(!out.exists());
    let missing = dir.path().join("nodir").join("r.png");
    let err = fails(&["render", s(&wall), "-o", s(&missing)]);
    assert!(err.contains("does not exist"), "{err}");
}

/// The summary says which flags the invalid vectors carry, so that the valid share and the
/// validation count add up (out-of-range vectors are not flagged by the validation).
#[test]
fn the_summary_counts_invalid_vectors_by_flag() {
    let Some(wall) = data(WALL) else { return };
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("f.csv");
    let o = ebiv(&["process", s(&wall), "-o", s(&csv)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = common::stdout(&o);
    let line = out
        .lines()
        .find_map(|l| l.strip_prefix("invalid vectors by flag: "))
        .unwrap_or_else(|| panic!("no flag line in {out}"));
    let counts: Vec<(usize, &str)> = line
        .split(", ")
        .map(|part| {
            let (n, name) = part.split_once(' ').unwrap();
            (n.parse().unwrap(), name)
        })
        .collect();
    let text = std::fs::read_to_string(&csv).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let status = header.iter().position(|&h| h == "status").unwrap();
    let invalid = text
        .lines()
        .skip(1)
        .filter(|l| l.split(',').nth(status) != Some("0"))
        .count();
    assert!(invalid > 0);
    let total: usize = counts.iter().map(|c| c.0).sum();
    assert!(total >= invalid, "{line}: {invalid} invalid");
    assert!(counts.iter().all(|c| c.0 <= invalid), "{line}");
    assert!(counts.iter().any(|c| c.1 == "median_test"), "{line}");
}
