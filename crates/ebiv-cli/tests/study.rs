//! `ebiv study` end to end: a tiny study runs, writes its tables, plots and report, and a
//! rerun computes nothing.

mod common;

use common::{ebiv, stderr, stdout};

/// Two cells on a 64 × 64 px recording: fast in a debug build.
const TINY: &str = r#"title = "tiny"
seeds = 1
fields = 1
figures = ["metrics", "uv-histogram"]

[scenario]
example = "uniform"
duration = "30ms"
sensor = { width = 64, height = 64, preset = "ideal" }
particles = { density = 0.02, diameter = 1.5 }
flow = { u = 1.0, v = 0.5 }

[process]
window = [32]

[sweep]
"process.slab" = ["5ms", "10ms"]

[[compare]]
metric = "rms"
where = { "process.slab" = "10ms" }
paper = 0.02
source = "a test"
"#;

#[test]
fn a_tiny_study_writes_its_report_and_a_rerun_computes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tiny.toml");
    std::fs::write(&file, TINY).unwrap();
    let out = dir.path().join("out");
    let args = ["study", file.to_str().unwrap(), "-o", out.to_str().unwrap()];
    let run = ebiv(&args);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("2 cells computed, 0 found finished"),
        "{}",
        stderr(&run)
    );
    let results = std::fs::read_to_string(out.join("results.csv")).unwrap();
    let lines: Vec<&str> = results.lines().collect();
    assert_eq!(lines.len(), 3, "{results}");
    assert!(lines[0].starts_with("key,method,process.slab,seed,vectors,valid_share"));
    assert!(lines[1].contains(",corrsum,5ms,1,"), "{results}");
    let summary = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    assert_eq!(summary.lines().count(), 3, "{summary}");
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains("# tiny") && report.contains("## Beside the paper"),
        "{report}"
    );
    for figure in [
        "rms-vs-process-slab.png",
        "uv-truth.png",
        "uv-corrsum-slab-5ms.png",
    ] {
        assert!(
            report.contains(&format!("plots/{figure}")),
            "{figure}: {report}"
        );
        assert!(out.join("plots").join(figure).is_file(), "{figure}");
    }
    let again = ebiv(&args);
    assert!(again.status.success(), "{}", stderr(&again));
    assert!(
        stderr(&again).contains("0 cells computed, 2 found finished"),
        "{}",
        stderr(&again)
    );
    assert_eq!(
        std::fs::read_to_string(out.join("results.csv")).unwrap(),
        results
    );
}

#[test]
fn examples_print_and_a_bad_study_names_its_key() {
    let list = ebiv(&["study", "--list-examples"]);
    assert!(stdout(&list).contains("turntable") && stdout(&list).contains("histograms"));
    let printed = ebiv(&["study", "--print-example", "turntable"]);
    assert!(printed.status.success());
    assert!(stdout(&printed).contains("\"process.slab\" = [\"5ms\", \"10ms\", \"20ms\"]"));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.toml");
    std::fs::write(&file, TINY.replace("process.slab", "process.slabb")).unwrap();
    let bad = ebiv(&[
        "study",
        file.to_str().unwrap(),
        "-o",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    let e = stderr(&bad);
    assert!(
        e.contains("process.slabb") && e.contains("not an `ebiv process` setting"),
        "{e}"
    );
    let unknown = ebiv(&["study", "--example", "tornado"]);
    assert!(
        stderr(&unknown).contains("turntable"),
        "{}",
        stderr(&unknown)
    );
}
