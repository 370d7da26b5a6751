//! `ebiv`: event-based imaging velocimetry from the command line.
//!
//! Times and durations are typed with units: `10ms`, `250us`, `1.5s` (a bare number is µs).
//! Coordinates are image pixels, x to the right, y down.

mod cmd;
mod input;
mod interrupt;
mod progress;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Event-based imaging velocimetry: measure fluid flows from event-camera recordings (velocity
/// fields by sum of correlation, motion compensation or PIV), and read, look at, convert and
/// simulate the recordings.
///
/// Times and durations take units (10ms, 250us, 1.5s; a bare number is µs). Pixel
/// coordinates are image coordinates: x to the right, y down, origin top-left.
#[derive(Debug, Parser)]
#[command(name = "ebiv", version, about, long_about)]
struct Cli {
    /// Worker threads for the parallel work (windows, simulator bands, figures). Default:
    /// one per core, or the RAYON_NUM_THREADS environment variable. Results are the same for
    /// any number of threads (1 to 1024).
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the built-in example: simulate, write, read back, draw.
    Demo(cmd::demo::DemoArgs),
    /// Describe a recording: format, sensor, counts, time range, rates, triggers, warnings.
    Info(cmd::info::InfoArgs),
    /// Build the index of RAW recordings, for fast seeking to a time.
    Index(cmd::index::IndexArgs),
    /// Convert a recording to EVT 3.0 RAW, CSV, NPY or NPZ, optionally cut and cropped.
    Convert(cmd::convert::ConvertArgs),
    /// Write a recording without its noise events (hot pixels, refractory, background
    /// activity), counting what each filter removed.
    Filter(cmd::denoise::FilterArgs),
    /// Draw a time-coded event image or an event-rate map as PNG.
    Render(cmd::render::RenderArgs),
    /// Rebuild image frames from events (for PIV or inspection), optionally one per light pulse.
    Frames(cmd::frames::FramesArgs),
    /// Measure velocity fields: sum of correlation, motion compensation, PIV of event frames or
    /// image pairs, pulsed EBIV.
    Process(Box<cmd::process::ProcessArgs>),
    /// Write a commented configuration file for `ebiv process --config`.
    Init(cmd::process::InitArgs),
    /// Simulate a recording of a known flow through an event-camera model, with ground truth.
    Simulate(cmd::simulate::SimulateArgs),
    /// Measure throughput on this machine, and the event estimators' operating envelope.
    Bench(cmd::bench::BenchArgs),
    /// Velocity fields while the camera records: follow a growing file, read a pipe or replay;
    /// a live view in the browser.
    Live(Box<cmd::live::LiveArgs>),
    /// Follow individual particles: tracks with velocity, acceleration and uncertainty.
    Track(Box<cmd::track::TrackArgs>),
    /// Errors of a vector field against the truth, or agreement of two fields, with a report.
    Assess(Box<cmd::assess::AssessArgs>),
    /// Flow statistics of a field series: mean, RMS, Reynolds stresses and valid samples per
    /// node, optionally phase-averaged.
    Stats(cmd::stats::StatsArgs),
    /// Vorticity, divergence, strain rates and swirling strength of a field series, with
    /// colour maps.
    Derive(cmd::derive::DeriveArgs),
    /// Monte-Carlo parameter study: simulate, process and measure a setup over swept
    /// parameters and seeds; tables, plots and a report.
    Study(cmd::study::StudyArgs),
}

/// End quietly when the reader of standard output goes away (`ebiv info REC | head -1`), as
/// Unix tools do: Rust ignores SIGPIPE, so `println!` would panic on the closed pipe instead.
fn die_quietly_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in `main`, before any other thread exists; SIG_DFL is a
    // valid disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    die_quietly_on_closed_pipe();
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(usize::from(n));
        if let Err(e) = pool.build_global() {
            eprintln!("error: --threads {n}: {e}");
            return ExitCode::FAILURE;
        }
    }
    let result = match &cli.command {
        Command::Demo(a) => cmd::demo::run(a),
        Command::Info(a) => cmd::info::run(a),
        Command::Index(a) => cmd::index::run(a),
        Command::Convert(a) => cmd::convert::run(a),
        Command::Filter(a) => cmd::denoise::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Frames(a) => cmd::frames::run(a),
        Command::Process(a) => cmd::process::run(a),
        Command::Init(a) => cmd::process::init(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Live(a) => cmd::live::run(a),
        Command::Track(a) => cmd::track::run(a),
        Command::Assess(a) => cmd::assess::run(a),
        Command::Stats(a) => cmd::stats::run(a),
        Command::Derive(a) => cmd::derive::run(a),
        Command::Study(a) => cmd::study::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            // Stopped by Ctrl-C or SIGTERM (after removing its unfinished output): end by that
            // signal, so that a shell loop running ebiv stops too.
            interrupt::resend_caught_signal();
            ExitCode::FAILURE
        }
    }
}
