//! `ebiv bench`: measured throughput on this machine.

mod envelope;
mod piv;
mod process;
mod track;

use crate::input::InputArgs;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// Benchmarks, each printing the best of several runs, and the estimators' operating envelope.
#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub what: BenchWhat,
}

#[derive(Debug, Subcommand)]
pub enum BenchWhat {
    /// Single-thread decode throughput of FILE (read into memory first, so the disk is not
    /// measured): events per second and bytes per second.
    Decode(DecodeBenchArgs),
    /// Event generation rate of the simulator on a scenario (default: the `paper-rate`
    /// example, 1280x720 at about 20 M events/s) with the full `imx636` sensor model.
    Simulate(SimulateBenchArgs),
    /// Time per second of recording of both estimators at the EBIV paper's data rate and
    /// settings (simulated 1280x720 at about 20 M events/s, 40x40 px windows, 20 px step,
    /// T = 10 ms, 100 fields per second).
    Process(process::ProcessBenchArgs),
    /// Multi-pass PIV of a synthetic 1024x1024 image pair, windows 64/32/16 px at 50 %
    /// overlap (the case timed for OpenPIV in the docs).
    Piv(piv::PivBenchArgs),
    /// Particle-tracking throughput at the EBIV paper's data rate (simulated 1280x720 at
    /// about 20 M events/s, default tracking settings) against the camera's rate.
    Track(track::TrackBenchArgs),
    /// Operating envelope of both event estimators: simulated uniform flows over a range of
    /// speeds and seeding densities, processed with each window size, slab T and pass
    /// schedule; prints per cell the RMS error, the valid share and the share of valid vectors
    /// that are grossly wrong, as Markdown tables (runs for many minutes with the defaults).
    Envelope(envelope::EnvelopeBenchArgs),
}

#[derive(Debug, Args)]
pub struct SimulateBenchArgs {
    /// Ready scenario to run (see `ebiv simulate --list-examples`).
    #[arg(long, default_value = "paper-rate", conflicts_with = "scenario")]
    pub example: String,
    /// A scenario file (TOML, as `ebiv simulate` takes) to run instead of an example; its
    /// duration is replaced by --duration.
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Simulated time per run.
    #[arg(long, default_value = "100ms", value_parser = ebiv::units::parse_us)]
    pub duration: i64,
    /// How many runs; the best is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
    /// Also time the run as `ebiv simulate` does it: the events streamed to FILE (any
    /// writer format by extension; EVT 3.0 for .raw) as they are read out, instead of kept
    /// in memory. The file is left in place.
    #[arg(long, value_name = "FILE")]
    pub output: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct DecodeBenchArgs {
    /// The recording to decode.
    pub file: PathBuf,
    /// How many times to decode it; the best run is reported.
    #[arg(long, default_value_t = 5)]
    pub repeat: u32,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Simulate `duration_us` of the `paper-rate` scene (at `density` particles/px instead of
/// its own, if given): the events, the simulation and the seconds it took.
fn paper_rate(
    duration_us: i64,
    density: Option<f64>,
) -> Result<(ebiv::EventBuffer, ebiv::sim::simulation::Simulation, f64), ebiv::Error> {
    let text = ebiv::sim::scenario::Scenario::example("paper-rate").expect("built-in example");
    let mut scenario = ebiv::sim::scenario::Scenario::from_toml(text, "paper-rate")?;
    scenario.duration = duration_us;
    if let Some(density) = density {
        scenario.particles.density = density;
    }
    let sim = scenario.simulation()?;
    let started = Instant::now();
    let events = sim.run(None, &|_| {})?.events;
    Ok((events, sim, started.elapsed().as_secs_f64()))
}

pub fn run(args: &BenchArgs) -> Result<(), ebiv::Error> {
    match &args.what {
        BenchWhat::Decode(a) => decode(a),
        BenchWhat::Simulate(a) => simulate(a),
        BenchWhat::Process(a) => process::run(a),
        BenchWhat::Piv(a) => piv::run(a),
        BenchWhat::Track(a) => track::run(a),
        BenchWhat::Envelope(a) => envelope::run(a),
    }
}

fn simulate(args: &SimulateBenchArgs) -> Result<(), ebiv::Error> {
    let example = args.scenario.is_none().then_some(args.example.as_str());
    let (mut scenario, _) = crate::cmd::simulate::load_scenario(example, args.scenario.as_deref())?;
    scenario.duration = args.duration;
    let name = match &args.scenario {
        Some(path) => path.display().to_string(),
        None => args.example.clone(),
    };
    let sim = scenario.simulation()?;
    let label = format!("simulate {name}");
    let kept = time_best(args.repeat, || Ok(sim.run(None, &|_| {})?.events.len()))?;
    report_simulate(&label, &sim, args, kept);
    if let Some(path) = &args.output {
        let format = ebiv::io::write::format_for_path(path)?;
        let streamed = time_best(args.repeat, || {
            let mut writer = ebiv::io::write::create(path, format, Some(sim.geometry))?;
            let mut events = 0;
            let mut sink = |batch: &ebiv::EventBuffer| {
                events += batch.len();
                writer.write(batch)
            };
            sim.run_streaming(None, &|_| {}, &mut sink)?;
            writer.finish()?;
            Ok(events)
        })?;
        let label = format!(
            "{label}, streamed to {} as `ebiv simulate` writes it",
            path.display()
        );
        report_simulate(&label, &sim, args, streamed);
    }
    Ok(())
}

/// The best of `repeat` runs of `run` (which returns how many events it made): `(events,
/// wall seconds, CPU seconds)` of the fastest.
fn time_best(
    repeat: u32,
    mut run: impl FnMut() -> Result<usize, ebiv::Error>,
) -> Result<(usize, f64, Option<f64>), ebiv::Error> {
    let mut best = (0, f64::INFINITY, None);
    for _ in 0..repeat.max(1) {
        let (start, cpu_start) = (Instant::now(), process_cpu_seconds());
        let events = run()?;
        let elapsed = start.elapsed().as_secs_f64();
        if elapsed < best.1 {
            let cpu = cpu_start.zip(process_cpu_seconds()).map(|(a, b)| b - a);
            best = (events, elapsed, cpu);
        }
    }
    Ok(best)
}

/// Print one `bench simulate` line, `label` first: the best run `(events, wall, cpu)` of
/// `sim`.
fn report_simulate(
    label: &str,
    sim: &ebiv::sim::simulation::Simulation,
    args: &SimulateBenchArgs,
    (events, best, best_cpu): (usize, f64, Option<f64>),
) {
    let simulated_s = args.duration as f64 * 1e-6;
    let cpu = best_cpu
        .map(|c| format!(" ({c:.3} s of CPU time, {:.2} CPUs busy)", c / best))
        .unwrap_or_default();
    println!(
        "{label}: {} for {}, {events} events ({:.1} M events/s of recording); best of {}: {:.3} s{cpu} = {:.2} M events/s generated on {}",
        sim.geometry,
        ebiv::units::format_us(args.duration),
        events as f64 / simulated_s * 1e-6,
        args.repeat.max(1),
        best,
        events as f64 / best * 1e-6,
        worker_threads()
    );
}

/// The CPU time (user and system) this process has used so far, in seconds, where the
/// platform tells it.
fn process_cpu_seconds() -> Option<f64> {
    #[cfg(unix)]
    {
        let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
        // SAFETY: `getrusage` writes a `rusage` into the pointer it is given.
        let ok = unsafe { libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr()) } == 0;
        if !ok {
            return None;
        }
        // SAFETY: initialised by the successful call above.
        let usage = unsafe { usage.assume_init() };
        let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
        Some(seconds(usage.ru_utime) + seconds(usage.ru_stime))
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// "1 thread" or "N threads": the size of the worker pool the bench ran on.
pub(crate) fn worker_threads() -> String {
    match rayon::current_num_threads() {
        1 => "1 thread".to_string(),
        n => format!("{n} threads"),
    }
}

fn decode(args: &DecodeBenchArgs) -> Result<(), ebiv::Error> {
    let options = args.input.read_options()?;
    let bytes: Arc<[u8]> = std::fs::read(&args.file)
        .map_err(|e| ebiv::Error::io(&args.file, e))?
        .into();
    let name = args.file.display().to_string();
    let mut best = f64::INFINITY;
    let mut events = 0u64;
    let mut format = None;
    for _ in 0..args.repeat.max(1) {
        let start = Instant::now();
        let mut reader = ebiv::io::open_memory(bytes.clone(), &name, &options)?;
        let mut batch = ebiv::EventBuffer::new();
        let mut n = 0u64;
        while reader.read_batch(&mut batch)? {
            n += batch.len() as u64;
        }
        best = best.min(start.elapsed().as_secs_f64());
        events = n;
        format = Some(reader.metadata().format);
    }
    let format = format.map(|f| f.to_string()).unwrap_or_default();
    println!(
        "decode {name}: {format}, {events} events, {} bytes; best of {}: {:.4} s = {:.1} Mev/s, {:.0} MB/s (single thread)",
        bytes.len(),
        args.repeat.max(1),
        best,
        events as f64 / best * 1e-6,
        bytes.len() as f64 / best * 1e-6
    );
    Ok(())
}
