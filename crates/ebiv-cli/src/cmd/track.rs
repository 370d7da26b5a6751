//! `ebiv track`: particle tracks from events, with velocity and acceleration.

use crate::input::InputArgs;
use clap::{ArgMatches, Args, FromArgMatches};
use ebiv::export::{TrackTable, TrackWriter};
use ebiv::io::EventSource;
use ebiv::track::bin::{bin_tracks, BinParams};
use ebiv::track::run::{track_attributes, track_source, TrackInterval};
use ebiv::track::{TrackParams, TRACK_SETTINGS};
use std::path::PathBuf;
use std::time::Instant;

/// Follow individual particles through the events and write their tracks: position,
/// velocity, acceleration and path curvature at every sample, each with its standard
/// uncertainty, and the fit's quality.
///
/// Particles are found as clusters of touching pixels in short slabs, linked into tracks by
/// a constant-velocity predictor with one-to-one assignment (gaps up to --max-gap bridged),
/// and each track is fitted with a local cubic in time through its events. Tracks are
/// written as they end (CSV) or at the end (.npz, .nc). The method and its accuracy are
/// described in docs/tracking.md.
///
/// Examples:
///   ebiv simulate --example vortex -o vortex.raw --tracks truth.csv
///   ebiv track vortex.raw -o tracks.csv --png figures/
///   ebiv assess tracks.csv --truth-tracks truth.csv --truth-example vortex
///   ebiv track wallflow.raw -o tracks.nc --bin 8 --field mean.nc
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct TrackArgs {
    /// The recording.
    pub file: PathBuf,
    /// The tracks to write: .csv, .npz or .nc (columns track_id,t_us,x,y,u,v,ax,ay, their
    /// uncertainties, curvature, events, residual).
    #[arg(short, long, default_value = "tracks.csv")]
    pub output: PathBuf,
    /// Also draw the tracks over the events, and histograms of track length and fit
    /// residual, as PNG files in this folder.
    #[arg(long, value_name = "DIR")]
    pub png: Option<PathBuf>,
    /// Interval tracked, START:END from the first event (e.g. `10ms:60ms`; either end may be
    /// left out).
    #[arg(long, value_name = "START:END", value_parser = ebiv::units::parse_range)]
    pub time: Option<(Option<i64>, Option<i64>)>,
    /// Read --time as camera time stamps in µs rather than from the first event.
    #[arg(long)]
    pub absolute_time: bool,
    /// Average the track velocities in square bins of this size (px) into a vector field
    /// written to --field (the same files as `ebiv process`).
    #[arg(long, value_name = "PX")]
    pub bin: Option<f64>,
    /// The binned field's file (.nc, .csv, .npz, .dat, .vtk); default: the output's name
    /// with `_binned.nc`.
    #[arg(long, value_name = "FILE", requires = "bin")]
    pub field: Option<PathBuf>,
    /// One binned field per interval of this length (e.g. 100ms); default: one over all
    /// tracks.
    #[arg(long, value_name = "DUR", value_parser = ebiv::units::parse_us, requires = "bin")]
    pub bin_interval: Option<i64>,
    /// Fewest tracks through a bin for a valid vector.
    #[arg(long, value_name = "N", default_value_t = BinParams::default().min_tracks, requires = "bin")]
    pub bin_min_tracks: u32,
    #[command(flatten)]
    pub settings: TrackSettingArgs,
    #[command(flatten)]
    pub input: InputArgs,
}

/// The tracking settings as flags, one per entry of [`TRACK_SETTINGS`] (the library's one
/// definition), with its default.
#[derive(Debug, Clone, Default)]
pub struct TrackSettingArgs {
    /// (key, text) of the flags given.
    pub given: Vec<(String, String)>,
}

impl TrackSettingArgs {
    /// The settings: the defaults with the flags given applied.
    pub fn params(&self) -> Result<TrackParams, ebiv::Error> {
        let mut params = TrackParams::default();
        for (key, text) in &self.given {
            params.set(key, text)?;
        }
        Ok(params)
    }
}

impl FromArgMatches for TrackSettingArgs {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let mut given = Vec::new();
        for (key, _, _) in TRACK_SETTINGS {
            if let Some(text) = matches.get_one::<String>(key) {
                given.push((key.to_string(), text.clone()));
            }
        }
        Ok(TrackSettingArgs { given })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

impl Args for TrackSettingArgs {
    fn augment_args(mut cmd: clap::Command) -> clap::Command {
        let defaults = TrackParams::default();
        for (key, value_name, help) in TRACK_SETTINGS {
            let default = defaults.get(key).unwrap_or_default();
            cmd = cmd.arg(
                clap::Arg::new(*key)
                    .long(*key)
                    .value_name(*value_name)
                    .help_heading("Tracking")
                    .help(format!("{help} [default: {default}]")),
            );
        }
        cmd
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

pub fn run(args: &TrackArgs) -> Result<(), ebiv::Error> {
    // Everything that can be checked is checked before reading.
    let params = args.settings.params()?;
    ebiv::export::TrackFormat::of(&args.output)?;
    super::check_output_path(&args.output)?;
    let bin = args
        .bin
        .map(|bin_px| {
            let p = BinParams {
                bin_px,
                interval_us: args.bin_interval,
                min_tracks: args.bin_min_tracks,
            };
            p.validate().map(|_| p)
        })
        .transpose()?;
    let field_path = args.field.clone().unwrap_or_else(|| {
        let stem = args
            .output
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy();
        args.output.with_file_name(format!("{stem}_binned.nc"))
    });
    if bin.is_some() {
        ebiv::export::field_extension(&field_path)?;
        super::check_output_path(&field_path)?;
        if same_file(&field_path, &args.output) {
            return Err(ebiv::Error::parameter(
                "field",
                format!(
                    "{} is also the tracks' output: give the binned field another file",
                    field_path.display()
                ),
            ));
        }
    }
    if let Some(dir) = &args.png {
        std::fs::create_dir_all(dir).map_err(|e| ebiv::Error::io(dir, e))?;
    }
    let _catch = crate::interrupt::catch();
    let options = args.input.read_options()?;
    let source = EventSource::file(&args.file, &options);
    let interval = TrackInterval {
        start: args.time.and_then(|t| t.0),
        end: args.time.and_then(|t| t.1),
        absolute_time: args.absolute_time,
    };
    let total = std::fs::metadata(&args.file).ok().map(|m| m.len());
    let bar = crate::progress::bytes_bar(total, "tracking");
    let mut writer = TrackWriter::create(&args.output)?;
    let keep_table = bin.is_some() || args.png.is_some();
    let mut table = TrackTable::default();
    let started = Instant::now();
    let run = track_source(
        &source,
        &params,
        interval,
        &mut |track| {
            if keep_table {
                table.push(&track);
            }
            writer.write(&track)
        },
        &mut |position| {
            if let Some(p) = position {
                bar.set_position(p);
            }
            crate::interrupt::check(&args.output)
        },
    )?;
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let attributes = track_attributes(&args.file.display().to_string(), &params, &run);
    writer.finish(&attributes)?;
    let s = run.summary;
    if params.slab_us == 0 {
        println!(
            "detection slab: {} (chosen from the first events)",
            ebiv::units::format_us(s.slab_us)
        );
    }
    println!(
        "{} tracks ({} samples) from {} events in {:.2} s ({:.1} M events/s): {} detections, {} short tracks dropped, {} events in tracks ({:.0} %), {} outliers left out; wrote {}",
        s.tracks,
        s.samples,
        s.events,
        seconds,
        s.events as f64 / seconds.max(1e-9) / 1e6,
        s.detections,
        s.dropped,
        s.events_tracked,
        100.0 * s.events_tracked as f64 / s.events.max(1) as f64,
        s.outliers,
        args.output.display()
    );
    if let Some(dir) = &args.png {
        write_figures(dir, &table, &source, &run, params.polarity)?;
    }
    if let Some(bin) = &bin {
        if table.is_empty() {
            println!(
                "binned field: no tracks to bin, {} not written",
                field_path.display()
            );
            return Ok(());
        }
        let mut field = bin_tracks(&table, run.geometry, bin)?;
        ebiv::track::bin::add_track_attributes(&mut field, &attributes);
        ebiv::export::write_field(&field, &field_path)?;
        let valid = field.status.iter().filter(|s| s.is_valid()).count();
        println!(
            "binned field: {} × {} bins of {} px, {} fields, {valid} valid vectors; wrote {}",
            field.x.len(),
            field.y.len(),
            bin.bin_px,
            field.t_us.len(),
            field_path.display()
        );
    }
    Ok(())
}

/// Whether two output paths name one file (the same path, or one that exists under both).
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    if a == b {
        return true;
    }
    let canonical = |p: &std::path::Path| {
        let parent = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(std::path::Path::new("."));
        parent
            .canonicalize()
            .ok()
            .map(|d| d.join(p.file_name().unwrap_or_default()))
    };
    matches!((canonical(a), canonical(b)), (Some(x), Some(y)) if x == y)
}

/// Longest interval drawn in the track map: beyond it the tracks would cover each other.
const FIGURE_SPAN_US: i64 = 50_000;

/// The track map (tracks of the first [`FIGURE_SPAN_US`] of the interval tracked over its
/// events) and the histograms of all tracks, as PNG files in `dir`.
fn write_figures(
    dir: &std::path::Path,
    table: &TrackTable,
    source: &EventSource,
    run: &ebiv::track::run::TrackRun,
    polarity: ebiv::PolaritySelection,
) -> Result<(), ebiv::Error> {
    use ebiv::render::tracks::{track_histograms, track_map, TrackMapStyle};
    use ebiv::render::EventRateMap;
    let (start, end) = (
        run.span_us.0,
        run.span_us
            .0
            .saturating_add(FIGURE_SPAN_US)
            .min(run.span_us.1 + 1),
    );
    let mut shown = TrackTable::default();
    for k in 0..table.len() {
        if (start..end).contains(&table.t_us[k]) {
            shown.track_id.push(table.track_id[k]);
            shown.t_us.push(table.t_us[k]);
            for (column, values) in shown.values.iter_mut().zip(&table.values) {
                column.push(values[k]);
            }
        }
    }
    let mut events = EventRateMap::new(run.geometry);
    let mut reader = source.open()?;
    reader.skip_to(start)?;
    let mut batch = ebiv::EventBuffer::new();
    while reader.read_batch(&mut batch)? {
        events.add(&batch, start, end, polarity);
        if batch.t.first().is_some_and(|&t| t >= end) {
            break;
        }
    }
    let style = TrackMapStyle {
        time_origin_us: run.first_event_us,
        ..TrackMapStyle::default()
    };
    let map = track_map(Some(&events), &shown, run.geometry, &style)?;
    let paths = [dir.join("tracks.png"), dir.join("histograms.png")];
    ebiv::render::save_png(&map, &paths[0])?;
    ebiv::render::save_png(&track_histograms(table)?, &paths[1])?;
    println!("wrote {} and {}", paths[0].display(), paths[1].display());
    Ok(())
}
