//! `ebiv live`: a recording piped on standard input gives the fields of `ebiv process`, a
//! replay writes its summary, and bad arguments fail before any work.

mod common;
use common::{ebiv, simulated_uniform as recording, stdout};
use std::io::Write;
use std::process::{Command, Stdio};

const SETTINGS: [&str; 6] = ["--slab", "10ms", "--time", "::5ms", "--window", "48,32"];

#[test]
fn standard_input_gives_the_fields_of_process() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path());
    let live_csv = dir.path().join("live.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_ebiv"))
        .args([
            "live",
            "-",
            "--queue",
            "1000",
            "-o",
            live_csv.to_str().unwrap(),
        ])
        .args(SETTINGS)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let bytes = std::fs::read(&rec).unwrap();
    let mut stdin = child.stdin.take().unwrap();
    // Written in pieces that split words, as a camera tool's pipe delivers them.
    for piece in bytes.chunks(4093) {
        stdin.write_all(piece).unwrap();
    }
    drop(stdin);
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = stdout(&o);
    assert!(text.contains("standard input"), "{text}");
    assert!(text.contains(", 0 dropped"), "{text}");
    let process_csv = dir.path().join("process.csv");
    let o = ebiv(
        &[
            &["process", &rec, "-o", process_csv.to_str().unwrap()][..],
            &SETTINGS,
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let live = std::fs::read_to_string(&live_csv).unwrap();
    let expected = std::fs::read_to_string(&process_csv).unwrap();
    let without_last_column: Vec<&str> = live
        .lines()
        .map(|line| &line[..line.rfind(',').unwrap()])
        .collect();
    assert_eq!(without_last_column, expected.lines().collect::<Vec<_>>());
    assert!(live.lines().next().unwrap().ends_with(",fields_dropped"));
}

#[test]
fn a_replay_reports_its_latency_in_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path());
    let summary = dir.path().join("summary.json");
    let o = ebiv(
        &[
            &["live", &rec, "--replay", "--speed", "0.5", "--queue", "100"][..],
            &["--summary", summary.to_str().unwrap()],
            &SETTINGS,
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = stdout(&o);
    assert!(text.contains("99th percentile"), "{text}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert!(json["stats"]["fields"].as_u64().unwrap() >= 5, "{json}");
    assert!(json["latency_p99_ms"].as_f64().unwrap() > 0.0, "{json}");
}

#[test]
fn bad_arguments_fail_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path());
    let cases: [(&[&str], &str); 7] = [
        (
            &["live", &rec, "--every", "5ms", "--time", "::5ms"],
            "give the time between fields once",
        ),
        (
            &["live", "-", "--follow"],
            "--follow and --replay take a file",
        ),
        (&["live", &rec, "--serve=0.0.0.0:0"], "--allow-remote"),
        (&["live", &rec, "--serve=nonsense"], "is not an address"),
        (&["live", &rec, "--replay", "--speed", "0"], "speed"),
        (
            &["live", &rec, "--method", "piv"],
            "piv and pulsed are for ebiv process",
        ),
        (&["live", &rec, "-o", "out.vtk"], ".csv, .nc or .npz"),
    ];
    for (args, expected) in cases {
        let o = ebiv(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(err.contains(expected), "{args:?}: {err}");
    }
}

#[test]
fn an_input_shorter_than_one_field_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path());
    let out = dir.path().join("none.csv");
    let o = ebiv(&[
        "live",
        &rec,
        "--slab",
        "10ms",
        "--time",
        "500ms::5ms",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no field"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!out.exists());
    let o = ebiv(&["live", &rec, "--time", "30ms:10ms:5ms"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("before START"));
}

/// Derived quantities in every output format, the NPZ (written at the end) included: the
/// same values as `process --derive` on the finished recording.
#[test]
fn derived_quantities_reach_every_live_output() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path());
    for ext in ["npz", "nc", "csv"] {
        let out = dir.path().join(format!("live.{ext}"));
        let o = ebiv(
            &[
                &[
                    "live",
                    &rec,
                    "--derive",
                    "vorticity",
                    "-o",
                    out.to_str().unwrap(),
                ][..],
                &SETTINGS,
            ]
            .concat(),
        );
        assert!(
            o.status.success(),
            "{ext}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let bytes = std::fs::read(&out).unwrap();
        let needle: &[u8] = b"vorticity";
        assert!(
            bytes.windows(needle.len()).any(|w| w == needle),
            "{ext}: no vorticity in the output"
        );
    }
}
