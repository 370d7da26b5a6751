//! `ebiv filter` and `--denoise` of the reading commands: the events written are those the
//! filters keep, and every command prints what each filter removed.

mod common;
use common::{ebiv, simulated_uniform, stderr};

/// `(removed, reaching)` of the line `denoise: NAME: removed R of N events`, and the kept
/// count of `denoising kept K of N events`.
fn counts(err: &str, name: &str) -> ((u64, u64), u64) {
    let number = |s: &str| {
        s.parse::<u64>()
            .unwrap_or_else(|_| panic!("`{s}` in {err}"))
    };
    let line = err
        .lines()
        .find(|l| l.starts_with(&format!("denoise: {name}: removed ")))
        .unwrap_or_else(|| panic!("no {name} line in {err}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let kept = err
        .lines()
        .find(|l| l.starts_with("denoise: denoising kept "))
        .unwrap_or_else(|| panic!("no kept line in {err}"));
    let kept_words: Vec<&str> = kept.split_whitespace().collect();
    ((number(words[3]), number(words[5])), number(kept_words[3]))
}

#[test]
fn filter_writes_the_kept_events_and_counts_each_filter() {
    let dir = tempfile::tempdir().unwrap();
    let rec = simulated_uniform(dir.path());
    let out = dir.path().join("clean.csv");
    let o = ebiv(&[
        "filter",
        &rec,
        "-o",
        out.to_str().unwrap(),
        "--denoise",
        "correlation,refractory",
        "--denoise-dt",
        "500us",
        "--denoise-refractory",
        "20us",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let ((refr, reaching), kept) = counts(&err, "refractory");
    let ((corr, reaching_corr), _) = counts(&err, "correlation");
    assert_eq!(reaching_corr, reaching - refr, "{err}");
    assert_eq!(kept, reaching - refr - corr, "{err}");
    assert!(corr > 0 && kept > reaching / 2, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let events = text
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .count();
    assert_eq!(events as u64, kept);
    assert!(err.contains(&format!("wrote {kept} events")), "{err}");

    // The same filters in convert: the same events.
    let converted = dir.path().join("converted.csv");
    let o = ebiv(&[
        "convert",
        &rec,
        converted.to_str().unwrap(),
        "--denoise",
        "refractory,correlation",
        "--denoise-dt",
        "500us",
        "--denoise-refractory",
        "20us",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&converted).unwrap(), text);

    // render and process print their counts too.
    let png = dir.path().join("r.png");
    let o = ebiv(&[
        "render",
        &rec,
        "-o",
        png.to_str().unwrap(),
        "--denoise",
        "correlation",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    counts(&stderr(&o), "correlation");
    let nc = dir.path().join("f.csv");
    let o = ebiv(&[
        "process",
        &rec,
        "-o",
        nc.to_str().unwrap(),
        "--time",
        "20ms:20ms:1ms",
        "--denoise",
        "all",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    counts(&err, "hot-pixels");
    counts(&err, "correlation");
}

#[test]
fn filter_needs_a_filter_and_bad_values_name_the_setting() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("r.csv");
    std::fs::write(&rec, "t,x,y,p\n# geometry: 8x8\n0,1,1,1\n5,2,2,1\n").unwrap();
    let rec = rec.to_str().unwrap();
    let out = dir.path().join("o.csv");
    let out = out.to_str().unwrap();
    let o = ebiv(&["filter", rec, "-o", out]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--denoise"), "{}", stderr(&o));
    let o = ebiv(&["filter", rec, "-o", out, "--denoise", "median"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("`median` is not a denoising filter"),
        "{}",
        stderr(&o)
    );
    let o = ebiv(&[
        "filter",
        rec,
        "-o",
        out,
        "--denoise",
        "correlation",
        "--denoise-dt",
        "0us",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("denoise-dt"), "{}", stderr(&o));
    let o = ebiv(&[
        "filter",
        rec,
        "-o",
        out,
        "--denoise",
        "hot-pixels",
        "--denoise-hot-factor",
        "1",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("denoise-hot-factor"), "{}", stderr(&o));
    // Two isolated events: the correlation filter keeps (2,2), supported by (1,1) 5 µs before,
    // and removes (1,1).
    let o = ebiv(&["filter", rec, "-o", out, "--denoise", "correlation"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(out).unwrap();
    assert!(
        text.contains("5,2,2,1") && !text.contains("0,1,1,1"),
        "{text}"
    );
    assert!(
        stderr(&o).contains("correlation: removed 1 of 2 events"),
        "{}",
        stderr(&o)
    );
}
