//! `ebiv frames`: image frames rebuilt from events, for PIV software or for looking at, at a
//! fixed rate or one per light pulse (pulsed EBIV, Willert 2023).

use crate::input::InputArgs;
use crate::progress::count_bar;
use clap::Args;
use ebiv::frame::events::{frame_starts, stream_frames, FrameKind, FrameSpec};
use ebiv::frame::pulse::{pulse_frame_starts, PulseTiming};
use ebiv::frame::scan_pulse_timing;
use ebiv::frame::{despeckle, save, splat, Scale};
use ebiv::process::coverage;
use ebiv::units::format_us;
use ebiv::PolaritySelection;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Rebuild image frames from the events of a recording (Willert & Klinner 2022), written as
/// numbered 16-bit grey images `frame_000000.png`, … plus `frames.csv` with each frame's
/// start, exposure and event count.
///
/// Each frame holds the events of [start, start + exposure). With --pulsed the frames follow
/// the light pulses instead: one frame per pulse period, starting in the dark gap before
/// each pulse, the period taken from the trigger input or from the events themselves.
#[derive(Debug, Args)]
pub struct FramesArgs {
    /// The recording (any format `ebiv info` reads).
    pub file: PathBuf,
    /// Folder for the frames (created if missing; existing frames are overwritten).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Time collected into one frame (e.g. `1.5ms`, `500us`). Default 1ms.
    #[arg(long, value_name = "DUR", value_parser = ebiv::units::parse_us, conflicts_with = "pulsed")]
    pub exposure: Option<i64>,
    /// Time between frame starts (default: the exposure, frames back to back; shorter
    /// overlaps them, longer leaves gaps).
    #[arg(long, value_name = "DUR", value_parser = ebiv::units::parse_us, conflicts_with = "pulsed")]
    pub every: Option<i64>,
    /// Only START:END (e.g. `10ms:20ms`, either side may be empty), from the first event of
    /// the recording (or in camera time with --absolute-time). Only whole frames are written.
    #[arg(long, value_name = "START:END", value_parser = ebiv::units::parse_range)]
    pub time: Option<(Option<i64>, Option<i64>)>,
    /// Read --time as camera time stamps rather than from the first event.
    #[arg(long)]
    pub absolute_time: bool,
    /// Pixel values: count (events per pixel), binary (1 where any event) or time-surface
    /// (time of the last event, (t − start + 1)/exposure, 0 where none).
    #[arg(long, default_value = "count", value_parser = parse_kind)]
    pub kind: FrameKind,
    /// Spread each event over a Gaussian of this σ in px (0 = none), for particle-like
    /// images that correlate better.
    #[arg(long, value_name = "SIGMA", default_value_t = 0.0)]
    pub splat: f64,
    /// Events used: pos, neg or both (default pos, as in the EBIV papers).
    #[arg(long, default_value = "pos", value_parser = super::convert::parse_polarity)]
    pub polarity: PolaritySelection,
    /// Image format: png or tiff (16-bit grey). (`--format` is the input format.)
    #[arg(long, value_name = "FMT", default_value = "png", value_parser = ["png", "tiff", "tif"])]
    pub image_format: String,
    /// Grey-value scale: a factor (e.g. `1` keeps counts as they are) or `stretch` (each
    /// frame's maximum becomes 65535). Default: stretch for count frames, 65535 for binary
    /// and time-surface frames.
    #[arg(long, value_parser = parse_scale)]
    pub scale: Option<Scale>,
    /// Clear isolated pixels (no lit 8-neighbour) before writing, as the reference code's
    /// `despeckle`.
    #[arg(long)]
    pub despeckle: bool,
    /// One frame per light pulse: detect the pulse period and phase (trigger input, else the
    /// event rate) and print them.
    #[arg(long)]
    pub pulsed: bool,
    /// With --pulsed: the nominal pulse frequency in Hz, to narrow the search.
    #[arg(long, value_name = "HZ", requires = "pulsed")]
    pub pulse_hz: Option<f64>,
    #[command(flatten)]
    pub denoise: super::process::flags::DenoiseFlags,
    #[command(flatten)]
    pub input: InputArgs,
}

fn parse_kind(s: &str) -> Result<FrameKind, String> {
    FrameKind::parse(s).map_err(|e| e.to_string())
}

fn parse_scale(s: &str) -> Result<Scale, String> {
    if s.trim().eq_ignore_ascii_case("stretch") {
        return Ok(Scale::Stretch);
    }
    match s.trim().parse::<f32>() {
        Ok(f) if f.is_finite() && f >= 0.0 => Ok(Scale::Fixed(f)),
        _ => Err(format!("`{s}` is not `stretch` or a factor ≥ 0")),
    }
}

/// Most frames one run writes.
const MAX_FRAMES: i64 = 1_000_000;

pub fn run(args: &FramesArgs) -> Result<(), ebiv::Error> {
    let mut spec = FrameSpec {
        kind: args.kind,
        exposure_us: args.exposure.unwrap_or(FrameSpec::default().exposure_us),
        polarity: args.polarity,
        splat_sigma: args.splat,
    };
    spec.check()?;
    if let Some(every) = args.every {
        if every <= 0 {
            return Err(ebiv::Error::parameter(
                "every",
                format!("{every} µs: frames must be spaced by more than 0"),
            ));
        }
    }
    let mut options = args.input.read_options()?;
    options.denoise = args.denoise.settings()?;
    let extent = coverage(
        &args.file,
        &options,
        args.time.unwrap_or((None, None)),
        args.absolute_time,
        args.polarity,
    )?;
    if let Some(requested) = extent.requested_end_us {
        eprintln!(
            "note: the recording ends {} before the end of --time; frames stop at its last event",
            format_us(requested - extent.end_us)
        );
    }
    if extent.geometry_from_events {
        eprintln!(
            "note: the file does not state the sensor size; frames are {} px, the largest coordinates seen (set it with --geometry)",
            extent.geometry
        );
    }
    let (start, end, geometry) = (extent.start_us, extent.end_us, extent.geometry);

    let starts = if args.pulsed {
        let timing = find_pulses(args, &options, start, end)?;
        spec.exposure_us = timing.exposure_us();
        if (end - start) as f64 / timing.period_us >= MAX_FRAMES as f64 {
            return Err(ebiv::Error::parameter(
                "time",
                format!(
                    "{:.0} pulses lie in the interval (at most {MAX_FRAMES} frames); use --time",
                    (end - start) as f64 / timing.period_us
                ),
            ));
        }
        pulse_frame_starts(&timing, start, end)
    } else {
        let every = args.every.unwrap_or(spec.exposure_us);
        if end - start < spec.exposure_us {
            return Err(ebiv::Error::parameter(
                "time",
                format!(
                    "the interval ({}) is shorter than one exposure ({})",
                    format_us(end - start),
                    format_us(spec.exposure_us)
                ),
            ));
        }
        let last = end - spec.exposure_us;
        if (last - start) / every >= MAX_FRAMES {
            return Err(ebiv::Error::parameter(
                "every",
                format!(
                    "{} frames would be written (at most {MAX_FRAMES}); use --time or a longer --every",
                    (last - start) / every + 1
                ),
            ));
        }
        frame_starts(start, last + 1, every)
    };
    if starts.is_empty() {
        return Err(ebiv::Error::parameter(
            "time",
            "no whole frame fits into the interval",
        ));
    }

    std::fs::create_dir_all(&args.output).map_err(|e| ebiv::Error::io(&args.output, e))?;
    let extension = if args.image_format == "png" {
        "png"
    } else {
        "tif"
    };
    let scale = args.scale.unwrap_or(match args.kind {
        FrameKind::Count => Scale::Stretch,
        FrameKind::Binary | FrameKind::TimeSurface => Scale::Fixed(65535.0),
    });
    let mut reader = ebiv::io::open(&args.file, &options)?;
    let bar = count_bar(starts.len() as u64, "frames");
    bar.set_message("writing");
    let mut csv = String::from("index,start_us,exposure_us,events\n");
    let mut cleared = 0usize;
    // Despeckling looks for isolated events, so it comes before any splatting.
    let build = FrameSpec {
        splat_sigma: if args.despeckle {
            0.0
        } else {
            spec.splat_sigma
        },
        ..spec
    };
    // Ctrl-C stops after the frame being written (every frame on disk is whole), and
    // frames.csv then lists the frames that were written.
    let catch = crate::interrupt::catch();
    let (mut written, mut blank) = (0usize, 0usize);
    let streamed = stream_frames(
        &mut reader,
        geometry,
        &build,
        &starts,
        |record, mut frame| {
            crate::interrupt::check(&args.output)?;
            if args.despeckle {
                cleared += despeckle(&mut frame);
                splat(&mut frame, spec.splat_sigma);
            }
            let path = frame_path(&args.output, record.index, extension);
            save(&frame, &path, scale)?;
            let _ = writeln!(
                csv,
                "{},{},{},{}",
                record.index, record.start_us, record.exposure_us, record.events
            );
            written += 1;
            blank += usize::from(record.events == 0);
            bar.inc(1);
            Ok(())
        },
    );
    let summary = match streamed {
        Ok(summary) => summary,
        Err(e) => {
            bar.finish_and_clear();
            if written > 0 {
                write_replacing(&args.output.join("frames.csv"), csv.as_bytes())?;
                eprintln!(
                    "stopped after {written} of {} frames: the frames listed in {} are complete",
                    starts.len(),
                    args.output.join("frames.csv").display()
                );
            }
            return Err(e);
        }
    };
    drop(catch);
    bar.finish_and_clear();
    let csv_path = args.output.join("frames.csv");
    write_replacing(&csv_path, csv.as_bytes())?;

    eprintln!(
        "wrote {} {} frames of {geometry} px to {} (frame_000000.{extension} …), exposure {}, from {} after the first event; {} lists them",
        starts.len(),
        args.kind.name(),
        args.output.display(),
        format_us(spec.exposure_us),
        format_us(start - extent.first_event_us),
        csv_path.display()
    );
    if args.despeckle {
        eprintln!("despeckle cleared {cleared} isolated pixels");
    }
    if blank > 0 {
        eprintln!(
            "warning: {blank} of {written} frames hold no event (frames.csv lists them with 0 events; check --time against `ebiv info`)"
        );
    }
    if summary.late_events > 0 {
        eprintln!(
            "warning: {} events came after their frame was complete (time stamps out of order) and are missing from it",
            summary.late_events
        );
    }
    if summary.off_sensor > 0 {
        eprintln!(
            "warning: {} events lie outside the {geometry} sensor and are not in any frame",
            summary.off_sensor
        );
    }
    super::print_report_summary(&reader.report());
    Ok(())
}

/// `DIR/frame_000042.png`.
fn frame_path(dir: &Path, index: usize, extension: &str) -> PathBuf {
    dir.join(format!("frame_{index:06}.{extension}"))
}

/// Write `path` through `<path>.partial`, renamed when complete.
fn write_replacing(path: &Path, bytes: &[u8]) -> Result<(), ebiv::Error> {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let temp = path.with_file_name(name);
    std::fs::write(&temp, bytes)
        .and_then(|()| std::fs::rename(&temp, path))
        .map_err(|e| {
            let _ = std::fs::remove_file(&temp);
            ebiv::Error::io(path, e)
        })
}

/// Detect the pulse timing from up to the first two seconds of `[start, end)` and say what
/// was found.
fn find_pulses(
    args: &FramesArgs,
    options: &ebiv::io::ReadOptions,
    start: i64,
    end: i64,
) -> Result<PulseTiming, ebiv::Error> {
    let mut reader = ebiv::io::open(&args.file, options)?;
    let timing = scan_pulse_timing(
        &mut reader,
        args.polarity,
        Some(start),
        Some(end),
        args.pulse_hz,
    )?;
    let source = match timing.source {
        ebiv::frame::PulseSource::Triggers => "trigger input",
        ebiv::frame::PulseSource::EventHistogram => "event rate",
    };
    println!(
        "pulses: {:.4} Hz (period {:.4} µs) from the {source}, over {} periods; frames start at phase {:.1} µs (camera time {:.1} µs + k·period); contrast {:.1}",
        timing.frequency_hz,
        timing.period_us,
        timing.periods,
        timing.phase_us(),
        timing.offset_us,
        timing.contrast
    );
    Ok(timing)
}
