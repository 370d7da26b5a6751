//! `ebiv track`: tracks of a simulated vortex in each file format, the binned field, the
//! figures, scoring by `ebiv assess --truth-tracks`, and errors before any work.

mod common;
use common::{ebiv, stdout};

/// A small vortex recording with its particle paths, in `dir`.
fn small_vortex(dir: &std::path::Path) -> (String, String, String) {
    let text = std::process::Command::new(env!("CARGO_BIN_EXE_ebiv"))
        .args(["simulate", "--print-example", "vortex"])
        .output()
        .unwrap()
        .stdout;
    let text = String::from_utf8(text)
        .unwrap()
        .replace("width = 640", "width = 192")
        .replace("height = 480", "height = 160")
        .replace("centre = [319.5, 239.5]", "centre = [95.5, 79.5]")
        .replace("circulation = 2500.0", "circulation = 900.0")
        .replace("core_radius = 40.0", "core_radius = 20.0")
        .replace("density = 0.005", "density = 0.004");
    let scenario = dir.join("vortex.toml");
    std::fs::write(&scenario, text).unwrap();
    let rec = dir.join("vortex.raw");
    let truth = dir.join("truth.csv");
    let o = ebiv(&[
        "simulate",
        scenario.to_str().unwrap(),
        "-o",
        rec.to_str().unwrap(),
        "--tracks",
        truth.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = |p: std::path::PathBuf| p.to_str().unwrap().to_string();
    (s(scenario), s(rec), s(truth))
}

#[test]
fn tracks_are_written_binned_drawn_and_scored() {
    let dir = tempfile::tempdir().unwrap();
    let (scenario, rec, truth) = small_vortex(dir.path());
    let csv = dir.path().join("tracks.csv");
    let figures = dir.path().join("figures");
    let field = dir.path().join("mean.nc");
    let out = stdout(&ebiv(&[
        "track",
        &rec,
        "-o",
        csv.to_str().unwrap(),
        "--png",
        figures.to_str().unwrap(),
        "--bin",
        "16",
        "--field",
        field.to_str().unwrap(),
    ]));
    assert!(out.contains(" tracks ("), "{out}");
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with(
        "track_id,t_us,x,y,u,v,ax,ay,x_unc,y_unc,u_unc,v_unc,ax_unc,ay_unc,curvature,events,residual\n"
    ));
    assert!(text.lines().count() > 100, "{} lines", text.lines().count());
    assert!(field.exists());
    for png in ["tracks.png", "histograms.png"] {
        assert!(figures.join(png).exists(), "{png}");
    }
    // The same tracks in the other formats.
    let counts = |out: &str| {
        out.lines()
            .find(|l| l.contains(" tracks ("))
            .map(|l| l.split(" from ").next().unwrap().to_string())
    };
    for ext in ["npz", "nc"] {
        let path = dir.path().join(format!("tracks.{ext}"));
        let other = stdout(&ebiv(&["track", &rec, "-o", path.to_str().unwrap()]));
        assert_eq!(counts(&other), counts(&out), "{other}");
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
    }
    // The binned field may not replace the tracks.
    let o = ebiv(&[
        "track",
        &rec,
        "-o",
        csv.to_str().unwrap(),
        "--bin",
        "16",
        "--field",
        csv.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("also the tracks' output"));
    assert!(
        std::fs::read_to_string(&csv).unwrap() == text,
        "the tracks are left as they were"
    );
    let report = dir.path().join("report");
    let out = stdout(&ebiv(&[
        "assess",
        csv.to_str().unwrap(),
        "--truth-tracks",
        &truth,
        "--truth",
        &scenario,
        "-o",
        report.to_str().unwrap(),
    ]));
    println!("{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("tracks.json")).unwrap())
            .unwrap();
    assert!(json["particles"].as_u64().unwrap() >= 10, "{json}");
    assert!(json["yield_fraction"].as_f64().unwrap() >= 0.7, "{json}");
    assert!(json["velocity_rms"].as_f64().unwrap() <= 0.2, "{json}");
}

#[test]
fn bad_settings_and_outputs_fail_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("none.raw");
    let missing = missing.to_str().unwrap();
    for (args, expected) in [
        (
            vec!["-o", "t.txt"],
            "tracks are written as .csv, .npz or .nc",
        ),
        (vec!["--degree", "5"], "degree"),
        (vec!["--gate=-2"], "gate"),
        (vec!["--slab", "fast"], "slab"),
        (vec!["--bin", "0.5"], "bin"),
        (vec!["--time", "5ms"], "START:END"),
    ] {
        let mut all = vec!["track", missing];
        all.extend(args.iter().copied());
        let o = ebiv(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success());
        assert!(err.contains(expected), "{args:?}: {err}");
    }
    let o = ebiv(&["track", missing]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("none.raw"));
}
