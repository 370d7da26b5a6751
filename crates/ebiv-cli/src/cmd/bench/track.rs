//! `ebiv bench track`: particle-tracking throughput at the EBIV paper's data rate (the
//! simulated `paper-rate` scene, 1280 × 720 px at about 20 M events/s), against the camera's
//! own rate.

use clap::Args;
use ebiv::track::{track_events, TrackParams};
use std::time::Instant;

#[derive(Debug, Args)]
pub struct TrackBenchArgs {
    /// Simulated recording length.
    #[arg(long, default_value = "200ms", value_parser = ebiv::units::parse_us)]
    pub duration: i64,
    /// Seeding density in particles per pixel, instead of the scene's 0.0092.
    #[arg(long)]
    pub density: Option<f64>,
    /// How many times the recording is tracked; the best run is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
}

pub fn run(args: &TrackBenchArgs) -> Result<(), ebiv::Error> {
    let (events, sim, _) = super::paper_rate(args.duration, args.density)?;
    let seconds_of_recording = args.duration as f64 * 1e-6;
    let camera_rate = events.len() as f64 / seconds_of_recording;
    println!(
        "simulated {} events on {}: {:.1} M events/s of recording over {} ms",
        events.len(),
        sim.geometry,
        camera_rate * 1e-6,
        args.duration / 1000
    );
    let threads = rayon::current_num_threads();
    let mut best = f64::INFINITY;
    let mut result = None;
    for _ in 0..args.repeat.max(1) {
        let started = Instant::now();
        let (tracks, summary) = track_events(&events, sim.geometry, &TrackParams::default())?;
        best = best.min(started.elapsed().as_secs_f64());
        result = Some((tracks.len(), summary));
    }
    let (tracks, summary) = result.expect("at least one run");
    let rate = events.len() as f64 / best;
    println!(
        "track ({threads} threads): {tracks} tracks, {} samples, {:.0} % of the events in tracks; \
         best {:.3} s = {:.2} s per s of recording, {:.1} M events/s ({:.2}× the camera's rate)",
        summary.samples,
        100.0 * summary.events_tracked as f64 / summary.events.max(1) as f64,
        best,
        best / seconds_of_recording,
        rate * 1e-6,
        rate / camera_rate
    );
    Ok(())
}
