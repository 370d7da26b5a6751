//! `ebiv demo`: the whole foundation on a built-in example, with no input files.

use clap::Args;
use ebiv::io::{write, Format, ReadOptions};
use ebiv::render::{save_png, time_coded_image, upscale, EventRateMap};

use ebiv::stats::RecordingStats;
use ebiv::PolaritySelection;
use std::path::PathBuf;
use std::time::Instant;

/// The demo scene: particles on a turntable seen by the `gen4` sensor model.
const DEMO_SCENARIO: &str = r#"
seed = 1
duration = "50ms"

[sensor]
width = 320
height = 240
preset = "gen4"

[flow]
type = "solid_body"
centre = [159.5, 119.5]
omega = 0.01

[particles]
density = 0.006
diameter = 2.5
brightness = 10.0
"#;

/// Simulate seeded particles on a turntable, write the recording as a Prophesee EVT 3.0 RAW
/// file, read it back, check that nothing changed, and draw the event images.
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
    let mut scenario = super::simulate::parse_scenario(DEMO_SCENARIO, "demo")?;
    scenario.seed = args.seed;
    let sim = scenario.simulation()?;
    let g = sim.geometry;
    let started = Instant::now();
    let events = sim.run(None, &|_| {})?.events;
    let (u_corner, v_corner) = sim.flow.velocity(0.0, 0.0, 0.0);
    println!(
        "simulated {} events: particles on a turntable, {g} sensor (gen4 model), {} ms, corner speed {:.2} px/ms, in {:.2} s",
        events.len(),
        scenario.duration / 1000,
        u_corner.hypot(v_corner),
        started.elapsed().as_secs_f64()
    );

    let raw = args.output.join("turntable.raw");
    let mut writer = write::create(&raw, Format::Evt3, Some(g))?;
    writer.write(&events)?;
    writer.finish()?;
    let size = std::fs::metadata(&raw).map(|m| m.len()).unwrap_or(0);
    println!(
        "wrote {} (Prophesee RAW EVT 3.0, {size} bytes)",
        raw.display()
    );

    let started = Instant::now();
    let back = ebiv::io::read_all(&raw, &ReadOptions::default())?;
    let seconds = started.elapsed().as_secs_f64();
    if back.events != events {
        return Err(ebiv::Error::Write {
            what: raw.display().to_string(),
            message: "the file read back differs from the events written".into(),
        });
    }
    println!(
        "read it back: {} events, identical to what was written ({:.1} Mev/s)",
        back.events.len(),
        back.events.len() as f64 / seconds * 1e-6
    );
    let mut stats = RecordingStats::new();
    stats.add(&back.events);
    println!(
        "  ON {} / OFF {}, mean rate {:.2} Mev/s, peak {:.2} Mev/s",
        stats.on,
        stats.events - stats.on,
        stats.mean_rate() * 1e-6,
        stats.peak_rate() * 1e-6
    );

    let image = time_coded_image(
        &events,
        g,
        scenario.duration / 2,
        2_500,
        PolaritySelection::Positive,
    );
    let events_png = args.output.join("events.png");
    save_png(&upscale(&image.image, 2), &events_png)?;
    println!(
        "wrote {}: {} ON events within ±2.5 ms of t = 25 ms, past blue, present white, future red",
        events_png.display(),
        image.events
    );
    let mut map = EventRateMap::new(g);
    map.add(&events, i64::MIN, i64::MAX, PolaritySelection::Both);
    let rate = map.render(Some(scenario.duration));
    let rate_png = args.output.join("rate.png");
    save_png(&upscale(&rate.image, 2), &rate_png)?;
    println!(
        "wrote {}: events per pixel per second (colour bar up to {:.0}/s)",
        rate_png.display(),
        rate.max_rate
    );
    println!(
        "next: ebiv info {}    ebiv render {} -o my.png --t0 10ms --dt 4ms",
        raw.display(),
        raw.display()
    );
    Ok(())
}
