//! Running a study: the unfinished cells are grouped by recording, each recording is
//! simulated once in memory, and every cell of it is processed and measured against the
//! truth and stored. Recordings run in parallel (rayon: on the global pool, so `--threads`
//! applies); the estimators parallelise within each.

use super::cells::{cells, Cell, CellResult, CellStore};
use super::metrics::{measure, valid_vectors};
use super::spec::StudySpec;
use crate::error::Result;
use crate::sim::scenario::Scenario;
use rayon::prelude::*;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// What a run did.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    /// Every cell of the study, in order.
    pub cells: Vec<Cell>,
    /// Their results, in the same order.
    pub results: Vec<CellResult>,
    /// Cells computed by this run.
    pub computed: usize,
    /// Cells found finished in the output directory.
    pub reused: usize,
}

/// Progress of a run, for progress bars.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Cells finished by this run so far.
    pub done: usize,
    /// Cells this run has to compute.
    pub total: usize,
}

/// Run the unfinished cells of `spec` into the output directory `out` and return every
/// cell's result. `on_progress` hears of every finished cell (from worker threads);
/// `check` is asked before every recording and cell, and an error it returns (an interrupt)
/// stops the run after the cells in progress, which are stored: a rerun continues from
/// there.
pub fn run_study(
    spec: &StudySpec,
    out: &Path,
    on_progress: &(dyn Fn(Progress) + Sync),
    check: &(dyn Fn() -> Result<()> + Sync),
) -> Result<RunOutcome> {
    let all = cells(spec)?;
    let store = CellStore::open(out)?;
    let pending: Vec<&Cell> = all.iter().filter(|c| store.load(c).is_none()).collect();
    let total = pending.len();
    let mut groups: Vec<Vec<&Cell>> = Vec::new();
    for cell in pending {
        match groups.iter_mut().find(|g| g[0].recording == cell.recording) {
            Some(g) => g.push(cell),
            None => groups.push(vec![cell]),
        }
    }
    let done = AtomicUsize::new(0);
    on_progress(Progress { done: 0, total });
    groups.par_iter().try_for_each(|group| {
        check()?;
        run_recording(spec, &store, group, check, &|| {
            let d = done.fetch_add(1, Ordering::SeqCst) + 1;
            on_progress(Progress { done: d, total });
        })
    })?;
    let results: Vec<CellResult> = all
        .iter()
        .map(|c| {
            store.load(c).unwrap_or_else(|| CellResult {
                key: c.key.clone(),
                metrics: Vec::new(),
                error: Some("no result stored".into()),
            })
        })
        .collect();
    Ok(RunOutcome {
        computed: total,
        reused: all.len() - total,
        cells: all,
        results,
    })
}

/// Simulate the recording the cells of `group` share and run each of them.
fn run_recording(
    spec: &StudySpec,
    store: &CellStore,
    group: &[&Cell],
    check: &(dyn Fn() -> Result<()> + Sync),
    finished: &(dyn Fn() + Sync),
) -> Result<()> {
    let first = group[0];
    let values = spec.combination(first.combination);
    let simulated = spec.scenario(&values, first.seed).and_then(|scenario| {
        let sim = scenario.simulation()?;
        let events = sim.run(None, &|_| {})?.events;
        Ok((scenario, sim, events))
    });
    for &cell in group {
        check()?;
        let result = match &simulated {
            Err(e) => Err(e.to_string()),
            Ok((scenario, sim, events)) => {
                run_cell(spec, cell, scenario, sim, events).map_err(|e| e.to_string())
            }
        };
        let (result, vectors) = match result {
            Ok((metrics, vectors)) => (
                CellResult {
                    key: cell.key.clone(),
                    metrics,
                    error: None,
                },
                vectors,
            ),
            Err(error) => (
                CellResult {
                    key: cell.key.clone(),
                    metrics: Vec::new(),
                    error: Some(error),
                },
                Vec::new(),
            ),
        };
        store.save(spec, cell, &result, &vectors)?;
        finished();
    }
    Ok(())
}

type Measured = (Vec<(String, f64)>, Vec<super::metrics::VectorRecord>);

/// Process one cell's recording with its settings and measure it against the truth.
fn run_cell(
    spec: &StudySpec,
    cell: &Cell,
    scenario: &Scenario,
    sim: &crate::sim::simulation::Simulation,
    events: &crate::EventBuffer,
) -> Result<Measured> {
    let values = spec.combination(cell.combination);
    let run = spec.settings(&values, &cell.method)?.resolve()?;
    let (start, end) = (scenario.start, scenario.start + scenario.duration);
    let times = |extent| {
        crate::settings::spread_field_times(
            extent,
            start + spec.margin_us,
            end - spec.margin_us,
            spec.fields,
        )
    };
    let started = Instant::now();
    let (series, delay_ms) = run.process_in_memory(events, sim.geometry, &times)?;
    let seconds = started.elapsed().as_secs_f64();
    let truth = |x: f64, y: f64, t: f64| sim.velocity(x, y, t);
    let vectors = valid_vectors(&series, &truth);
    let metrics = measure(
        &series,
        &vectors,
        &truth,
        &scenario.flow,
        delay_ms,
        events.len(),
        seconds,
    );
    Ok((
        metrics
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
        vectors,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A study small enough for a debug build: 64 × 64 px, two slabs, one seed.
    pub(crate) const TINY: &str = "title = \"tiny\"\nseeds = 1\nfields = 1\n\
        [scenario]\nexample = \"uniform\"\nduration = \"30ms\"\n\
        sensor = { width = 64, height = 64, preset = \"ideal\" }\n\
        particles = { density = 0.02, diameter = 1.5 }\nflow = { u = 1.0, v = 0.5 }\n\
        [process]\nwindow = [32]\n\
        [sweep]\n\"process.slab\" = [\"5ms\", \"10ms\"]\n";

    #[test]
    fn a_rerun_computes_nothing_and_a_changed_study_only_its_new_cells() {
        let spec = StudySpec::from_toml(TINY, "tiny", Path::new(".")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let seen = std::sync::Mutex::new(Vec::new());
        let first = run_study(
            &spec,
            dir.path(),
            &|p| seen.lock().unwrap().push(p),
            &|| Ok(()),
        )
        .unwrap();
        assert_eq!((first.computed, first.reused), (2, 0));
        assert_eq!(
            seen.lock().unwrap().last(),
            Some(&Progress { done: 2, total: 2 })
        );
        for r in &first.results {
            assert!(r.error.is_none(), "{r:?}");
            assert!(r.get("rms") < 0.2 && r.get("valid_share") > 0.5, "{r:?}");
        }
        let again = run_study(&spec, dir.path(), &|_| {}, &|| Ok(())).unwrap();
        assert_eq!((again.computed, again.reused), (0, 2));
        let rms = |o: &RunOutcome| -> Vec<(String, f64)> {
            o.results
                .iter()
                .map(|r| (r.key.clone(), r.get("rms")))
                .collect()
        };
        assert_eq!(rms(&again), rms(&first));
        let grown = TINY.replace("\"10ms\"]", "\"10ms\", \"20ms\"]");
        let grown = StudySpec::from_toml(&grown, "tiny", Path::new(".")).unwrap();
        let third = run_study(&grown, dir.path(), &|_| {}, &|| Ok(())).unwrap();
        assert_eq!((third.computed, third.reused), (1, 2));
        // An interrupt before the first cell stores nothing and says so.
        let other = tempfile::tempdir().unwrap();
        let stopped = run_study(&spec, other.path(), &|_| {}, &|| {
            Err(crate::Error::parameter("interrupt", "stopped"))
        });
        assert!(stopped.is_err());
        let again = run_study(&spec, other.path(), &|_| {}, &|| Ok(())).unwrap();
        assert_eq!(again.computed, 2);
    }
}
