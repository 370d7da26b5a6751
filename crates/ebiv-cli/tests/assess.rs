//! `ebiv assess`: a simulated recording with its truth, processed and assessed, with the
//! report files; two fields compared; clear errors for missing files and unreadable tables.

mod common;

use common::{ebiv, stderr, stdout};

#[test]
fn simulate_process_and_assess_against_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let o = ebiv(&[
        "simulate",
        "--example",
        "uniform",
        "--duration",
        "30ms",
        "--truth",
        &path("truth.nc"),
        "-o",
        &path("rec.raw"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = ebiv(&[
        "process",
        &path("rec.raw"),
        "--slab",
        "10ms",
        "-o",
        &path("field.nc"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));

    let o = ebiv(&[
        "assess",
        &path("field.nc"),
        "--truth",
        &path("truth.nc"),
        "-o",
        &path("report"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for text in [
        "compared with the truth",
        "RMS",
        "bias",
        "outliers",
        "dynamic velocity range",
        "peak locking",
        "wrote",
    ] {
        assert!(out.contains(text), "{text}: {out}");
    }
    let rms: f64 = out
        .split("RMS ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .expect("RMS in the summary");
    assert!(rms < 0.05, "uniform flow measured to {rms} px/ms");
    for name in [
        "assessment.json",
        "assessment.csv",
        "report.md",
        "error_map.png",
        "error_vs_speed.png",
        "error_vs_events.png",
        "fractional_displacement.png",
    ] {
        let p = dir.path().join("report").join(name);
        assert!(p.is_file(), "{name} missing");
    }
    let json = std::fs::read_to_string(dir.path().join("report/assessment.json")).unwrap();
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!(value["assessment"]["compared"].as_u64().unwrap() > 100);
    let csv = std::fs::read_to_string(dir.path().join("report/assessment.csv")).unwrap();
    assert!(csv.starts_with("group,metric,component,lo,hi,count,value,unit\n"));
    assert!(csv.contains("\nsummary,rms,"));
    let md = std::fs::read_to_string(dir.path().join("report/report.md")).unwrap();
    assert!(md.contains("![") && md.contains("peak-locking index"));
    let png = std::fs::read(dir.path().join("report/error_map.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"));

    // The scenario's exact flow gives the same numbers for a uniform flow.
    let o = ebiv(&["assess", &path("field.nc"), "--truth-example", "uniform"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains(&format!("RMS {rms:.4}")),
        "{}",
        stdout(&o)
    );

    // Two fields: a field agrees with itself; its CSV export agrees with the NetCDF.
    let o = ebiv(&[
        "process",
        &path("rec.raw"),
        "--slab",
        "10ms",
        "-o",
        &path("field.csv"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = ebiv(&[
        "assess",
        &path("field.nc"),
        &path("field.csv"),
        "-o",
        &path("cmp"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("median |Δv| 0.0000 px/ms") && out.contains("0.0 % differ"),
        "{out}"
    );
    for name in [
        "agreement.json",
        "agreement.csv",
        "report.md",
        "scatter.png",
        "differences.png",
    ] {
        assert!(
            dir.path().join("cmp").join(name).is_file(),
            "{name} missing"
        );
    }
}

#[test]
fn assess_errors_are_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let o = ebiv(&["assess", &path("missing.nc"), "--truth-example", "uniform"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("missing.nc"), "{}", stderr(&o));

    std::fs::write(path("cols.csv"), "a,b,c\n1,2,3\n").unwrap();
    let o = ebiv(&["assess", &path("cols.csv"), "--truth-example", "uniform"]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("cols.csv") && err.contains("x, y, u and v"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");

    std::fs::write(path("f.csv"), "x,y,u,v\n1,1,1,0\n").unwrap();
    let o = ebiv(&["assess", &path("f.csv")]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--truth"), "{}", stderr(&o));

    std::fs::write(path("phys.csv"), "x [mm],y [mm],u [m/s],v [m/s]\n1,1,1,0\n").unwrap();
    let o = ebiv(&["assess", &path("phys.csv"), "--truth-example", "uniform"]);
    assert!(stderr(&o).contains("--mm-per-px"), "{}", stderr(&o));
    let o = ebiv(&[
        "assess",
        &path("phys.csv"),
        "--truth-example",
        "uniform",
        "--mm-per-px",
        "0.5",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));

    let o = ebiv(&["assess", &path("f.csv"), "--truth", &path("nothing.nc")]);
    assert!(stderr(&o).contains("nothing.nc"), "{}", stderr(&o));
}
