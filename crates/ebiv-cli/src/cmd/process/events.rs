//! `ebiv process` over an event recording, by any method: the library measures
//! ([`Resolved::measure`]); this module shows progress, draws figures, writes and prints.

use super::figures::{finish_recording_run, write_series_figures, FieldProgress};
use ebiv::io::ReadOptions;
use ebiv::process::FieldDone;
use ebiv::settings::{Resolved, RunObserver, RunPlan};
use ebiv::Error;
use std::time::Instant;

/// Measure the recording's fields, write the series and the figures.
pub fn run(run: &Resolved, options: &ReadOptions) -> Result<(), Error> {
    let mut observer = Observer {
        run,
        progress: None,
        started: Instant::now(),
    };
    let mut measured = run.measure(&run.event_source(options), &mut observer)?;
    let frames = observer
        .progress
        .map(FieldProgress::finish)
        .unwrap_or_default();
    for warning in &measured.warnings {
        eprintln!("warning: {warning}");
    }
    finish_recording_run(
        run,
        &mut measured.series,
        &measured.summary,
        observer.started,
        &measured.report,
    )?;
    if let Some(dir) = &run.png {
        write_series_figures(&measured.series, dir, run, frames)?;
    }
    Ok(())
}

/// Prints the plan, then a progress bar and the figures of each field; Ctrl-C stops the run
/// after the field being evaluated.
struct Observer<'a> {
    run: &'a Resolved,
    progress: Option<FieldProgress<'a>>,
    /// When the fields began (after planning): the run's time and rates count from here.
    started: Instant,
}

impl RunObserver for Observer<'_> {
    fn planned(&mut self, plan: &RunPlan) -> Result<(), Error> {
        crate::interrupt::check(&self.run.output)?;
        println!("{}", plan.description);
        if let Some(dir) = &self.run.png {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        self.started = Instant::now();
        self.progress = Some(FieldProgress::new(
            self.run,
            plan.geometry,
            plan.times.len(),
            plan.extent_us,
        ));
        Ok(())
    }

    fn note(&mut self, line: &str) {
        println!("{line}");
    }

    fn field(&mut self, d: &FieldDone) -> Result<(), Error> {
        if let Some(progress) = &mut self.progress {
            progress.on_field(d)?;
        }
        if d.done < d.total {
            crate::interrupt::check(&self.run.output)?;
        }
        Ok(())
    }
}
