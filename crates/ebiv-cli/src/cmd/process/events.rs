//! `ebiv process --method corrsum|motion`: the event estimators over a recording.

use super::figures::{describe_passes, finish_recording_run, write_series_figures, FieldProgress};
use ebiv::estimate::Estimator;
use ebiv::io::ReadOptions;
use ebiv::process::{process_recording, PlannedFields};
use ebiv::settings::{EstimatorTask, Resolved};
use ebiv::Error;
use std::time::Instant;

/// A run of an event estimator over a recording ([`Resolved::with_event_estimator`]).
pub struct Run<'a> {
    pub run: &'a Resolved,
    pub options: &'a ReadOptions,
}

impl EstimatorTask for Run<'_> {
    type Output = Result<(), Error>;
    fn run<E: Estimator>(self, estimator: &E) -> Self::Output {
        run_estimator(self.run, self.options, estimator)
    }
}

/// Stream the recording through `estimator`, write the series and the figures.
fn run_estimator<E: Estimator>(
    run: &Resolved,
    options: &ReadOptions,
    estimator: &E,
) -> Result<(), Error> {
    let input = run.input_path();
    let planned = run.plan_fields(options, estimator.planning_extent_us(), run.slab_us())?;
    crate::interrupt::check(&run.output)?;
    let described = planned.describe_times();
    let PlannedFields {
        mut reader,
        geometry: g,
        times,
        time_origin_us,
    } = planned;
    let mut params = run.process.clone();
    params.mask = run.mask_for(g)?;
    params.grids(g)?; // report a window that does not fit before anything else
    println!(
        "{}: {described}, {} on {g}, passes {}",
        input.display(),
        estimator.name(),
        describe_passes(&params.passes)
    );
    if let Some(dir) = &run.png {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let started = Instant::now();
    let mut progress = FieldProgress::new(run, g, times.len(), estimator.planning_extent_us());
    let (mut series, summary) =
        process_recording(&mut reader, g, estimator, &params, &times, &mut |d| {
            progress.on_field(d)?;
            if d.done < d.total {
                crate::interrupt::check(&run.output)?;
            }
            Ok(())
        })?;
    let frames = progress.finish();
    super::check_run_found_events(run, &summary, &described, params.polarity)?;
    series.time_origin_us = Some(time_origin_us);
    finish_recording_run(run, &mut series, &summary, started, &reader.report())?;
    if let Some(dir) = &run.png {
        write_series_figures(&series, dir, run, frames)?;
    }
    Ok(())
}
