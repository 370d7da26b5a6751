//! `ebiv bench process`: how long both estimators take per second of a recording at the
//! EBIV paper's data rate and settings (Willert & Klinner 2022: 1280 × 720 px, ≈ 20 M
//! events/s, 40 × 40 px windows on a 20 px step, T = 10 ms, 100 fields per second).

use crate::cmd::process::describe_passes;
use clap::Args;
use ebiv::estimate::corrsum::{CorrSumParams, SumOfCorrelation};
use ebiv::estimate::motion::{ContrastMaximization, MotionParams};
use ebiv::estimate::Estimator;
use ebiv::grid::GridSpec;
use ebiv::process::{process_recording, MemorySource, ProcessParams, TimeSteps};
use ebiv::EventBuffer;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct ProcessBenchArgs {
    /// Simulated recording length (fields every 10 ms over it).
    #[arg(long, default_value = "200ms", value_parser = ebiv::units::parse_us)]
    pub duration: i64,
    /// Seeding density in particles per pixel, instead of the `paper-rate` scene's 0.0092
    /// (19.9 M events/s over one second, the paper's rate).
    #[arg(long)]
    pub density: Option<f64>,
    /// Window size in px (square windows, one pass).
    #[arg(long, default_value_t = 40)]
    pub window: u32,
    /// Grid step in px: the distance between neighbouring windows' centres.
    #[arg(long, default_value_t = 20)]
    pub step: u32,
    /// Only this method: corrsum or motion (default both).
    #[arg(long)]
    pub method: Option<String>,
    /// How many times each method processes the recording (at least once); the best run is
    /// reported (the recording is simulated once).
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
    /// Without the per-vector uncertainty (as `ebiv process --no-uncertainty`).
    #[arg(long)]
    pub no_uncertainty: bool,
}

pub fn run(args: &ProcessBenchArgs) -> Result<(), ebiv::Error> {
    let (events, sim, seconds) = super::paper_rate(args.duration, args.density)?;
    let seconds_of_recording = args.duration as f64 * 1e-6;
    println!(
        "simulated {} events on {} in {seconds:.1} s: {:.1} M events/s of recording, {} ms",
        events.len(),
        sim.geometry,
        events.len() as f64 / seconds_of_recording * 1e-6,
        args.duration / 1000
    );
    let params = ProcessParams {
        passes: vec![GridSpec::square(args.window, args.step)],
        uncertainty: !args.no_uncertainty,
        ..ProcessParams::default()
    };
    let which = args.method.as_deref();
    if which.is_none_or(|m| m == "corrsum") {
        let e = SumOfCorrelation::new(CorrSumParams::default())?;
        time_method(&e, &events, &sim, &params, args.repeat)?;
    }
    if which.is_none_or(|m| m == "motion") {
        let e = ContrastMaximization::new(MotionParams::default())?;
        time_method(&e, &events, &sim, &params, args.repeat)?;
    }
    Ok(())
}

/// Process every 10 ms field that fits, `repeat` times, and print the best time per second
/// of recording.
fn time_method<E: Estimator>(
    estimator: &E,
    events: &EventBuffer,
    sim: &ebiv::sim::simulation::Simulation,
    params: &ProcessParams,
    repeat: u32,
) -> Result<(), ebiv::Error> {
    let (before, after) = estimator.time_extent_us();
    let last = events.t.last().copied().unwrap_or(0);
    let times = TimeSteps::fitting(0, last, before, after, 10_000)
        .ok_or_else(|| ebiv::Error::parameter("duration", "too short for one field"))?
        .times(100_000)?;
    let run_once = || {
        let started = Instant::now();
        let mut source = MemorySource::new(events);
        let run = process_recording(
            &mut source,
            sim.geometry,
            estimator,
            params,
            &times,
            &mut |_| Ok(()),
        )?;
        Ok::<_, ebiv::Error>((started.elapsed().as_secs_f64(), run))
    };
    let (mut best, (series, summary)) = run_once()?;
    for _ in 1..repeat {
        best = best.min(run_once()?.0);
    }
    let per_recording_second = best / (times.len() as f64 / 100.0);
    println!(
        "{:8} {}: {} fields × {} windows in {best:.2} s (best of {}) = {:.0} windows/s; {:.2} s per second of recording at 100 fields/s ({:.1} % valid) on {}",
        estimator.name(),
        describe_passes(&params.passes),
        summary.fields,
        series.field_len(),
        repeat.max(1),
        summary.vectors as f64 / best,
        per_recording_second,
        100.0 * summary.valid as f64 / summary.vectors.max(1) as f64,
        super::worker_threads()
    );
    Ok(())
}
