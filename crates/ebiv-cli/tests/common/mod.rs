//! Helpers shared by the CLI test files: run the binary, find the shared test data.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

/// Run `ebiv` with `args`.
pub fn ebiv(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ebiv"))
        .args(args)
        .output()
        .expect("run ebiv")
}

/// A file of the shared test data (`$EBIV_TEST_DATA` or `../shared/data`), or `None` with a
/// notice when it is absent.
pub fn data(name: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("EBIV_TEST_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let path = dir.join(name);
    if path.is_file() {
        Some(path)
    } else {
        eprintln!(
            "notice: {} not found (set EBIV_TEST_DATA); skipping",
            path.display()
        );
        None
    }
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Simulate 40 ms of the `uniform` example (seed 3) into `dir/rec.raw`; returns its path.
pub fn simulated_uniform(dir: &std::path::Path) -> String {
    let rec = dir.join("rec.raw");
    let rec = rec.to_str().expect("a UTF-8 path").to_string();
    let o = ebiv(&[
        "simulate",
        "--example",
        "uniform",
        "--duration",
        "40ms",
        "--seed",
        "3",
        "-o",
        &rec,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    rec
}
