//! `ebiv index`: the index is written beside the recording, is used by `process --time`
//! without changing its result, and is rebuilt only when asked or when the file changed.

mod common;
use common::{ebiv, stdout};

#[test]
fn processing_from_a_time_gives_the_same_fields_with_and_without_the_index() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.raw");
    let rec_s = rec.to_str().unwrap();
    let o = ebiv(&[
        "simulate",
        "--example",
        "uniform",
        "--duration",
        "60ms",
        "--seed",
        "5",
        "-o",
        rec_s,
    ]);
    assert!(o.status.success());
    let run = |out: &str| {
        let path = dir.path().join(out);
        let o = ebiv(&[
            "process",
            rec_s,
            "--time",
            "40ms:50ms:5ms",
            "--window",
            "48,32",
            "--slab",
            "5ms",
            "-o",
            path.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(path).unwrap()
    };
    let without = run("without.nc");
    let o = ebiv(&["index", rec_s]);
    assert!(o.status.success());
    let text = stdout(&o);
    assert!(
        text.contains("points over") && text.contains("rec.raw.ebividx"),
        "{text}"
    );
    assert!(dir.path().join("rec.raw.ebividx").is_file());
    assert!(stdout(&ebiv(&["index", rec_s])).contains("up to date"));
    assert!(stdout(&ebiv(&["index", "--force", rec_s])).contains("points over"));
    assert_eq!(run("with.nc"), without);
}

#[test]
fn files_without_an_index_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("e.csv");
    std::fs::write(&csv, "t,x,y,p\n1,2,3,1\n").unwrap();
    let o = ebiv(&["index", csv.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(common::stderr(&o).contains("no index"));
}
