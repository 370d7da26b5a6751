//! Helpers shared by the integration tests: where the real recordings are, and the canonical
//! digest of `EXPECTED.json`.

#![allow(dead_code)]

use ebiv::EventBuffer;
use sha2::{Digest, Sha256};
use std::path::PathBuf;

/// The shared data directory: `$EBIV_TEST_DATA`, else `../shared/data` beside the workspace.
/// `None` (with a printed notice) when neither exists, so a fresh clone still passes.
pub fn data_dir() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("EBIV_TEST_DATA").map(PathBuf::from),
        Some(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data")),
    ];
    for dir in candidates.into_iter().flatten() {
        if dir.join("EXPECTED.json").is_file() {
            return Some(dir);
        }
    }
    eprintln!("notice: shared test data not found (set EBIV_TEST_DATA); skipping");
    None
}

/// The expected values for `name` (a path relative to the data directory).
pub fn expected(dir: &std::path::Path, name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("EXPECTED.json")).expect("EXPECTED.json");
    let all: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    all[name].clone()
}

/// SHA-256 of all events sorted by (t, x, y, p), each packed little-endian as
/// `x u16, y u16, p u8, t i64` (formats.md §16.1).
pub fn canonical_sha256(events: &EventBuffer) -> String {
    let mut all: Vec<(i64, u16, u16, u8)> = events.iter().map(|e| (e.t, e.x, e.y, e.p)).collect();
    all.sort_unstable();
    let mut hasher = Sha256::new();
    for (t, x, y, p) in all {
        hasher.update(x.to_le_bytes());
        hasher.update(y.to_le_bytes());
        hasher.update([p]);
        hasher.update(t.to_le_bytes());
    }
    hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Check a decoded recording against every value `EXPECTED.json` gives for it.
pub fn assert_matches_expected(events: &EventBuffer, exp: &serde_json::Value) {
    let n = exp["n_events"].as_u64().unwrap() as usize;
    assert_eq!(events.len(), n, "event count");
    assert_eq!(
        events.count_on() as u64,
        exp["n_on"].as_u64().unwrap(),
        "ON count"
    );
    let tuple = |i: usize| {
        let e = events.get(i);
        vec![e.t, e.x as i64, e.y as i64, e.p as i64]
    };
    let first: Vec<Vec<i64>> =
        serde_json::from_value(exp["first_events_file_order_t_x_y_p"].clone()).unwrap();
    for (i, want) in first.iter().enumerate() {
        assert_eq!(&tuple(i), want, "event {i} in file order");
    }
    let last: Vec<Vec<i64>> =
        serde_json::from_value(exp["last_events_file_order_t_x_y_p"].clone()).unwrap();
    for (k, want) in last.iter().enumerate() {
        let i = n - last.len() + k;
        assert_eq!(&tuple(i), want, "event {i} in file order");
    }
    let (t_min, t_max) = events.time_range().unwrap();
    assert_eq!(t_min, exp["t_min"].as_i64().unwrap(), "t_min");
    assert_eq!(t_max, exp["t_max"].as_i64().unwrap(), "t_max");
    assert_eq!(
        *events.x.iter().max().unwrap() as u64,
        exp["x_max"].as_u64().unwrap(),
        "x_max"
    );
    assert_eq!(
        *events.y.iter().max().unwrap() as u64,
        exp["y_max"].as_u64().unwrap(),
        "y_max"
    );
    // Not every entry states it (the HDF5 samples do not).
    if let Some(want) = exp["n_decreasing_t_steps"].as_u64() {
        let decreasing = events.t.windows(2).filter(|w| w[1] < w[0]).count() as u64;
        assert_eq!(decreasing, want, "decreasing steps");
    }
    assert_eq!(
        canonical_sha256(events),
        exp["canonical_sha256"].as_str().unwrap(),
        "canonical digest"
    );
}

/// Simulate a 256 × 256 `gen4` scene of `duration` (e.g. `"40ms"`) with the given `[flow]`
/// table, seeding 0.006 particles/px of 2.5 px diameter, plus `extra` TOML (e.g. an
/// `[illumination]` table); returns the simulation (for its truth) and the events.
pub fn simulate_scene(
    flow: &str,
    duration: &str,
    extra: &str,
    seed: u64,
) -> (ebiv::sim::simulation::Simulation, EventBuffer) {
    let text = format!(
        r#"
seed = {seed}
duration = "{duration}"
[sensor]
width = 256
height = 256
preset = "gen4"
[flow]
{flow}
[particles]
density = 0.006
diameter = 2.5
brightness = 20.0
{extra}
"#
    );
    let scenario: ebiv::sim::scenario::Scenario = toml::from_str(&text).unwrap();
    let sim = scenario.simulation().unwrap();
    let events = sim.run(None, &|_| {}).unwrap().events;
    (sim, events)
}
