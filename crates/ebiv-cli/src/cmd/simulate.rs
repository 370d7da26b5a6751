//! `ebiv simulate`: a synthetic recording of a known flow, with its ground truth.

use clap::Args;
use ebiv::io::write;
use ebiv::sim::scenario::{Scenario, EXAMPLES};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Simulate seeded particles carried by a known flow, imaged onto an event-camera pixel model,
/// and write the events (EVT 3.0 RAW by default; any writer format by extension) with the
/// true velocity field and particle tracks.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Scenario file (TOML). See `--print-example uniform` for a commented one.
    #[arg(required_unless_present_any = ["example", "print_example", "list_examples"])]
    pub scenario: Option<PathBuf>,
    /// Run a ready scenario instead: uniform, turntable, vortex, shear-layer, mixing-layer,
    /// paper-rate, wallflow (see --list-examples).
    #[arg(long, value_name = "NAME", conflicts_with = "scenario")]
    pub example: Option<String>,
    /// Print a ready scenario's TOML (to edit and pass back) and exit.
    #[arg(long, value_name = "NAME")]
    pub print_example: Option<String>,
    /// List the ready scenarios and exit.
    #[arg(long)]
    pub list_examples: bool,
    /// The recording to write (.raw EVT 3.0, .csv, .npy, .npz, .aedat4).
    #[arg(short, long, default_value = "simulated.raw")]
    pub output: PathBuf,
    /// Also write the true velocity field: .nc (NetCDF, dims time/y/x) or .csv
    /// (t_us,x_px,y_px,u_px_ms,v_px_ms).
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Also write every particle's path in view: CSV id,t_us,x,y,z,u,v.
    #[arg(long, value_name = "FILE")]
    pub tracks: Option<PathBuf>,
    /// Override the scenario's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override the scenario's duration (e.g. 20ms).
    #[arg(long, value_parser = ebiv::units::parse_us)]
    pub duration: Option<i64>,
}

pub fn run(args: &SimulateArgs) -> Result<(), ebiv::Error> {
    if args.list_examples {
        for (name, about, _) in EXAMPLES {
            println!("{name:12} {about}");
        }
        return Ok(());
    }
    if let Some(name) = &args.print_example {
        print!("{}", Scenario::example_text(name)?);
        return Ok(());
    }
    let (mut scenario, origin) = load_scenario(args.example.as_deref(), args.scenario.as_deref())?;
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    if let Some(d) = args.duration {
        scenario.duration = d;
    }
    let sim = scenario.simulation()?;
    // Everything that can be checked before the simulation is checked first.
    let out_format = write::format_for_path(&args.output)?;
    let truth_format = args.truth.as_deref().map(TruthFormat::of).transpose()?;
    if args.truth.is_some() {
        scenario
            .truth
            .validate_field(sim.geometry, scenario.duration)?;
    }
    if args.tracks.is_some() {
        scenario.truth.validate_tracks(
            sim.geometry,
            scenario.duration,
            scenario.particles.density,
        )?;
    }
    for path in [
        Some(&args.output),
        args.truth.as_ref(),
        args.tracks.as_ref(),
    ]
    .into_iter()
    .flatten()
    {
        check_directory(path)?;
    }
    let bar = crate::progress::fraction_bar("simulating");
    let started = Instant::now();
    let track_interval = args
        .tracks
        .as_ref()
        .map(|_| scenario.truth.track_interval as f64);
    // The events are written as they are read out, beside the simulation, so that memory
    // holds a window of them rather than the recording (the file appears only once
    // complete); Ctrl-C stops the run at its next batch or before the next output, and the
    // unfinished file is removed. The guard lives to the end of the command and is declared
    // before the writer, so that it is still in place while the writer removes its file.
    let _catch = crate::interrupt::catch();
    let mut writer = write::create(&args.output, out_format, Some(sim.geometry))?;
    let (mut n, mut on) = (0usize, 0usize);
    let mut sink = |events: &ebiv::EventBuffer| {
        crate::interrupt::check(&args.output)?;
        writer.write(events)?;
        n += events.len();
        on += events.count_on();
        Ok(())
    };
    let output = sim.run_streaming(
        track_interval,
        &|f| bar.set_position((f * 1000.0) as u64),
        &mut sink,
    );
    bar.finish_and_clear();
    let output = output?;
    crate::interrupt::check(&args.output)?;
    writer.finish()?;
    let seconds = started.elapsed().as_secs_f64();
    println!(
        "simulated {} of {} ({}) in {:.2} s, writing included: {n} events ({on} ON), {:.2} M events/s, {} samples (sampling: {})",
        ebiv::units::format_us(scenario.duration),
        sim.geometry,
        origin,
        seconds,
        n as f64 / seconds * 1e-6,
        output.samples,
        scenario.sampling.resolve(&scenario.illumination)
    );
    println!("wrote {}", args.output.display());
    let r = &output.readout;
    println!(
        "sensor: {} crossings hidden by the refractory period, {} noise events (leak {}, shot {}, hot pixels {}), {} dropped by the readout bandwidth limit",
        r.dropped_refractory,
        r.pixels.leak + r.pixels.shot + r.pixels.hot,
        r.pixels.leak,
        r.pixels.shot,
        r.pixels.hot,
        r.dropped_bandwidth
    );
    if let (Some(path), Some(format)) = (&args.truth, truth_format) {
        crate::interrupt::check(path)?;
        let field = scenario.truth_field(&sim);
        match format {
            TruthFormat::Csv => ebiv::export::write_field_csv(&field, path)?,
            TruthFormat::NetCdf => ebiv::export::write_field_netcdf(&field, path)?,
        }
        println!(
            "wrote {} (true velocity, {} fields of {}x{} vectors)",
            path.display(),
            field.t_us.len(),
            field.x.len(),
            field.y.len()
        );
    }
    if let Some(path) = &args.tracks {
        crate::interrupt::check(path)?;
        ebiv::export::write_tracks_csv(&output.tracks, path)?;
        println!(
            "wrote {} ({} track points)",
            path.display(),
            output.tracks.len()
        );
    }
    Ok(())
}

/// The file format of the velocity truth, from its file name.
#[derive(Debug, Clone, Copy)]
enum TruthFormat {
    Csv,
    NetCdf,
}

impl TruthFormat {
    fn of(path: &Path) -> Result<TruthFormat, ebiv::Error> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("csv") => Ok(TruthFormat::Csv),
            Some("nc") => Ok(TruthFormat::NetCdf),
            _ => Err(ebiv::Error::parameter(
                "truth",
                format!("{}: use a .nc or .csv file name", path.display()),
            )),
        }
    }
}

/// An error unless the directory `path` is to be written in exists.
fn check_directory(path: &Path) -> Result<(), ebiv::Error> {
    let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) else {
        return Ok(());
    };
    let problem = if dir.is_dir() {
        return Ok(());
    } else if dir.exists() {
        "is not a directory"
    } else {
        "does not exist"
    };
    Err(ebiv::Error::io(
        path,
        std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("the directory {} {problem}", dir.display()),
        ),
    ))
}

/// The ready scenario `example` or else the scenario file `path` (its gridded flow files
/// named relative to the file), with a name for it in messages.
pub fn load_scenario(
    example: Option<&str>,
    path: Option<&Path>,
) -> Result<(Scenario, String), ebiv::Error> {
    match (example, path) {
        (Some(name), _) => Ok((Scenario::from_example(name)?, format!("example `{name}`"))),
        (None, Some(path)) => Ok((Scenario::from_file(path)?, path.display().to_string())),
        (None, None) => Err(ebiv::Error::parameter(
            "scenario",
            "give a scenario file or --example NAME",
        )),
    }
}
