//! Monte-Carlo parameter studies (`ebiv study`): a base scenario simulated with repeated
//! seeds, swept over any scenario, sensor or processing parameter, processed by one or more
//! methods, and measured against the simulator's truth.
//!
//! The EBIV paper (Willert & Klinner 2022, Exp. Fluids 63:101) asks for Monte-Carlo
//! simulations of the imaging process to say how accurate event-based velocimetry is; a
//! study answers that for a given setup before the experiment is built. It sits above every
//! other layer: it simulates ([`crate::sim`]), processes ([`crate::settings`]), measures
//! ([`crate::assess`]) and draws ([`crate::render`]).
//!
//! * [`spec`]: the study file, its schema and checks;
//! * [`cells`]: one cell per combination × method × seed, keyed by a hash of its settings,
//!   and the store of finished cells that makes a study resumable;
//! * [`run`]: simulating each recording once and running its cells in parallel;
//! * [`metrics`]: what a cell measures;
//! * [`summary`]: `results.csv` and `summary.csv` (means with 95 % confidence intervals);
//! * [`report`]: the figures and `report.md`.
//!
//! [`EXAMPLES`] are the ready studies of `ebiv study --example NAME`.

pub mod cells;
pub mod metrics;
pub mod report;
pub mod run;
pub mod spec;
pub mod summary;

pub use cells::{Cell, CellResult, CellStore};
pub use run::{run_study, Progress, RunOutcome};
pub use spec::StudySpec;

use crate::error::{Error, Result};
use std::path::Path;

/// The ready studies: name, one-line description, TOML.
pub const EXAMPLES: [(&str, &str, &str); 4] = [
    (
        "turntable",
        "the EBIV paper's turntable test: solid-body rotation at T = 5, 10, 20 ms",
        include_str!("examples/turntable.toml"),
    ),
    (
        "histograms",
        "random vortices by every method: (u, v) histograms that show peak locking",
        include_str!("examples/histograms.toml"),
    ),
    (
        "envelope",
        "uniform flow: speed × seeding density × window × slab, two estimators",
        include_str!("examples/envelope.toml"),
    ),
    (
        "density",
        "seeding density from 0.001 to 0.05 particles/px, two estimators",
        include_str!("examples/density.toml"),
    ),
];

/// The TOML of a ready study, or an error listing them.
pub fn example_text(name: &str) -> Result<&'static str> {
    EXAMPLES
        .iter()
        .find(|e| e.0 == name)
        .map(|e| e.2)
        .ok_or_else(|| {
            let names: Vec<&str> = EXAMPLES.iter().map(|e| e.0).collect();
            Error::parameter(
                "example",
                format!("`{name}` is not one of {}", names.join(", ")),
            )
        })
}

/// The ready study `name`, parsed.
pub fn example(name: &str) -> Result<StudySpec> {
    StudySpec::from_toml(
        example_text(name)?,
        &format!("example `{name}`"),
        Path::new("."),
    )
}

/// A study file, parsed (its `scenario.file` taken relative to the file's folder).
pub fn open(path: &Path) -> Result<StudySpec> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    StudySpec::from_toml(&text, &path.display().to_string(), dir)
}

/// Write the tables and the report of a finished run into `out`: `results.csv`,
/// `summary.csv`, `plots/*.png` and `report.md`.
pub fn write_outputs(spec: &StudySpec, outcome: &RunOutcome, out: &Path) -> Result<()> {
    let groups = summary::summarise(&outcome.cells, &outcome.results);
    crate::export::write_text(
        &out.join("results.csv"),
        &summary::results_csv(spec, &outcome.cells, &outcome.results),
    )?;
    crate::export::write_text(
        &out.join("summary.csv"),
        &summary::summary_csv(spec, &groups),
    )?;
    let store = CellStore::open(out)?;
    let md = report::write_report(
        &report::ReportInput {
            spec,
            cells: &outcome.cells,
            groups: &groups,
            store: &store,
        },
        out,
    )?;
    crate::export::write_text(&out.join("report.md"), &md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_example_parses() {
        for (name, ..) in EXAMPLES {
            example(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        let e = example("tornado").unwrap_err().to_string();
        assert!(e.contains("turntable"), "{e}");
    }
}
