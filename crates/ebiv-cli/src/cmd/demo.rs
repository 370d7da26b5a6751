//! `ebiv demo`: the whole chain on a built-in example, with no input files: simulate a
//! Lamb–Oseen vortex in a uniform stream through the gen4 sensor model, write and re-read
//! the recording, measure its velocity field with both estimators, compare with the truth.

use crate::cmd::process::{describe_passes, series_histograms};
use crate::progress::count_bar;
use clap::Args;
use ebiv::assess::{field_errors, ErrorStats};
use ebiv::estimate::corrsum::{CorrSumParams, SumOfCorrelation};
use ebiv::estimate::motion::{ContrastMaximization, MotionParams};
use ebiv::estimate::Estimator;
use ebiv::field::FieldSeries;
use ebiv::frame::events::{FrameKind, FrameSpec};
use ebiv::grid::GridSpec;
use ebiv::io::{write, Format, ReadOptions};
use ebiv::piv::{piv_events, EventPivParams, FrameClock, PivParams};
use ebiv::process::{process_recording, FieldDone, MemorySource, ProcessParams, RunSummary};
use ebiv::render::{
    event_figure, save_png, time_coded_image, vector_map, ImageFigureStyle, VectorMapStyle,
};
use ebiv::sim::simulation::Simulation;
use ebiv::{EventBuffer, PolaritySelection};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The demo scene: a Lamb–Oseen vortex carried by a uniform stream, seen by the gen4 model.
const DEMO_SCENARIO: &str = r#"
seed = 1
duration = "60ms"

[sensor]
width = 384
height = 256
preset = "gen4"

[flow]
type = "superposition"

[[flow.flows]]
type = "uniform"
u = 1.0
v = 0.0

[[flow.flows]]
type = "lamb_oseen"
centre = [191.5, 127.5]
circulation = 800.0
core_radius = 30.0

[particles]
density = 0.006
diameter = 2.5
brightness = 20.0
"#;

/// Field times of the demo, µs: one field every 10 ms once the scene has settled.
const FIELD_TIMES: [i64; 4] = [20_000, 30_000, 40_000, 50_000];

/// Simulate a Lamb–Oseen vortex in a uniform stream, write it as a Prophesee EVT 3.0 RAW
/// file, read it back, measure its velocity by sum of correlation and by motion
/// compensation, and print both fields' errors against the known flow.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder for the outputs (created if missing).
    #[arg(short, long, default_value = "ebiv-demo")]
    pub output: PathBuf,
    /// Random seed of the particle positions.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(args: &DemoArgs) -> Result<(), ebiv::Error> {
    std::fs::create_dir_all(&args.output).map_err(|e| ebiv::Error::io(&args.output, e))?;
    let mut scenario = ebiv::sim::scenario::Scenario::from_toml(DEMO_SCENARIO, "demo")?;
    scenario.seed = args.seed;
    let sim = scenario.simulation()?;
    let g = sim.geometry;
    let started = Instant::now();
    let events = sim.run(None, &|_| {})?.events;
    println!(
        "simulated {} events: a Lamb–Oseen vortex (peak {:.1} px/ms) in a 1 px/ms stream, {g} sensor (gen4 model), {} ms, in {:.2} s",
        events.len(),
        peak_speed(&sim),
        scenario.duration / 1000,
        started.elapsed().as_secs_f64()
    );
    let events = write_and_read_back(&events, &sim, &args.output)?;

    let image = time_coded_image(&events, g, 30_000, 2_500, PolaritySelection::Positive);
    let events_png = args.output.join("events.png");
    let style = ImageFigureStyle {
        title: Some("ebiv demo: events, polarity positive".into()),
        pixel_scale: Some(2),
        time_origin_us: 0,
    };
    save_png(&event_figure(&image, &style)?, &events_png)?;
    println!(
        "wrote {}: ON events within ±2.5 ms of t = 30 ms, past blue, present white, future red",
        events_png.display()
    );

    let params = ProcessParams {
        passes: vec![GridSpec::square(64, 32), GridSpec::square(32, 16)],
        ..ProcessParams::default()
    };
    println!(
        "measuring {} fields ({}), positive events, T = 10 ms:",
        FIELD_TIMES.len(),
        describe_passes(&params.passes)
    );
    let corrsum = SumOfCorrelation::new(CorrSumParams::default())?;
    let motion = ContrastMaximization::new(MotionParams::default())?;
    measure(&corrsum, "corrsum", &sim, &events, &params, &args.output)?;
    measure(&motion, "motion", &sim, &events, &params, &args.output)?;
    let piv = EventPivParams {
        frames: FrameSpec {
            kind: FrameKind::Count,
            exposure_us: 1000,
            polarity: PolaritySelection::Positive,
            splat_sigma: 0.0,
        },
        clock: FrameClock::Regular { step_us: 2000 },
        pairs: 3,
        piv: PivParams {
            passes: params.passes.clone(),
            ..PivParams::default()
        },
    };
    println!("  piv of four 1 ms count frames 2 ms apart per field, same windows:");
    measure_with("piv", &sim, &events, &args.output, |source, on_field| {
        piv_events(source, sim.geometry, &piv, &FIELD_TIMES, on_field)
    })?;
    println!(
        "next: ebiv process {} --method motion --png figures    (ebiv process --help)",
        args.output.join("vortex.raw").display()
    );
    Ok(())
}

/// Largest speed of the demo flow on a 1 px grid at t = 0.
fn peak_speed(sim: &Simulation) -> f64 {
    let g = sim.geometry;
    (0..g.height)
        .flat_map(|y| (0..g.width).map(move |x| (x as f64, y as f64)))
        .map(|(x, y)| {
            let (u, v) = sim.flow.velocity(x, y, 0.0);
            u.hypot(v)
        })
        .fold(0.0, f64::max)
}

/// Write `events` as EVT 3.0 RAW, read the file back and check that nothing changed.
fn write_and_read_back(
    events: &EventBuffer,
    sim: &Simulation,
    dir: &Path,
) -> Result<EventBuffer, ebiv::Error> {
    let raw = dir.join("vortex.raw");
    let mut writer = write::create(&raw, Format::Evt3, Some(sim.geometry))?;
    writer.write(events)?;
    writer.finish()?;
    let back = ebiv::io::read_all(&raw, &ReadOptions::default())?;
    if back.events != *events {
        return Err(ebiv::Error::Write {
            what: raw.display().to_string(),
            message: "the file read back differs from the events written".into(),
        });
    }
    let size = std::fs::metadata(&raw).map(|m| m.len()).unwrap_or(0);
    println!(
        "wrote {} (Prophesee RAW EVT 3.0, {size} bytes) and read it back identical",
        raw.display()
    );
    Ok(back.events)
}

/// Process the demo events with one estimator, write its field and figures, print errors.
fn measure<E: Estimator>(
    estimator: &E,
    name: &str,
    sim: &Simulation,
    events: &EventBuffer,
    params: &ProcessParams,
    dir: &Path,
) -> Result<ErrorStats, ebiv::Error> {
    measure_with(name, sim, events, dir, |source, on_field| {
        process_recording(
            source,
            sim.geometry,
            estimator,
            params,
            &FIELD_TIMES,
            on_field,
        )
    })
}

/// Run one method over the demo events (`run` gets the event source and the progress
/// callback), write its field and figures, print its errors against the truth.
fn measure_with(
    name: &str,
    sim: &Simulation,
    events: &EventBuffer,
    dir: &Path,
    run: impl FnOnce(
        &mut MemorySource,
        &mut dyn FnMut(&FieldDone) -> Result<(), ebiv::Error>,
    ) -> Result<(FieldSeries, RunSummary), ebiv::Error>,
) -> Result<ErrorStats, ebiv::Error> {
    let started = Instant::now();
    let bar = count_bar(FIELD_TIMES.len() as u64, name);
    let mut source = MemorySource::new(events);
    let (mut series, _) = run(&mut source, &mut |d| {
        bar.set_position(d.done as u64);
        Ok(())
    })?;
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    series.attributes.push((
        "source".into(),
        "ebiv demo: simulated Lamb-Oseen vortex".into(),
    ));
    let errors = field_errors(&series, |x, y, t| sim.flow.velocity(x, y, t));
    println!("  {name:8} {errors}  ({seconds:.2} s)");
    let nc = dir.join(format!("flow_{name}.nc"));
    ebiv::export::write_field(&series, &nc)?;
    ebiv::export::write_field(&series, &dir.join(format!("flow_{name}.csv")))?;
    write_figures(&series, name, sim, events, dir)?;
    println!(
        "           wrote {}, flow_{name}.csv, vectors_{name}.png, histograms_{name}.png",
        nc.display()
    );
    Ok(errors)
}

/// Vector map of the middle field over its events, and the velocity histograms.
fn write_figures(
    series: &FieldSeries,
    name: &str,
    sim: &Simulation,
    events: &EventBuffer,
    dir: &Path,
) -> Result<(), ebiv::Error> {
    let k = series.t_us.len() / 2;
    let t0 = series.t_us[k];
    let background = time_coded_image(events, sim.geometry, t0, 5_000, PolaritySelection::Positive);
    let style = VectorMapStyle {
        title: Some(format!("{name}, t = {} ms", t0 / 1000)),
        ..VectorMapStyle::default()
    };
    let map = vector_map(
        &series.field(k),
        sim.geometry,
        Some(&background.image),
        &style,
    );
    save_png(&map, &dir.join(format!("vectors_{name}.png")))?;
    let hist = series_histograms(series, &format!("{name}: "), None);
    save_png(&hist, &dir.join(format!("histograms_{name}.png")))
}
