//! `ebiv frames`: image frames rebuilt from events, for PIV software or for looking at, at a
//! fixed rate or one per light pulse (pulsed EBIV, Willert 2023).

use crate::input::InputArgs;
use crate::progress::count_bar;
use clap::Args;
use ebiv::frame::events::{frame_starts, stream_frames, FrameKind, FrameSpec};
use ebiv::frame::pulse::{detect_pulses, pulse_frame_starts, PulseTiming};
use ebiv::frame::{despeckle, save, splat, Scale};
use ebiv::units::format_us;
use ebiv::{EventBuffer, Geometry, PolaritySelection};
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

/// Default exposure, µs.
const DEFAULT_EXPOSURE_US: i64 = 1000;
/// Most frames one run writes.
const MAX_FRAMES: i64 = 1_000_000;
/// Stretch of the recording the pulse detection looks at, µs.
const DETECT_SPAN_US: i64 = 2_000_000;
/// Most events the pulse detection looks at.
const DETECT_MAX_EVENTS: usize = 2_000_000;

pub fn run(args: &FramesArgs) -> Result<(), ebiv::Error> {
    let mut spec = FrameSpec {
        kind: args.kind,
        exposure_us: args.exposure.unwrap_or(DEFAULT_EXPOSURE_US),
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
    let options = args.input.read_options()?;
    let extent = Extent::of(args, &options)?;
    let (start, end, geometry) = (extent.start, extent.end, extent.geometry);

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
    let summary = stream_frames(
        &mut reader,
        geometry,
        &build,
        &starts,
        |record, mut frame| {
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
            bar.inc(1);
            Ok(())
        },
    )?;
    bar.finish_and_clear();
    let csv_path = args.output.join("frames.csv");
    write_replacing(&csv_path, csv.as_bytes())?;

    eprintln!(
        "wrote {} {} frames of {geometry} px to {} (frame_000000.{extension} …), exposure {}, from {} after the first event; {} lists them",
        starts.len(),
        args.kind.name(),
        args.output.display(),
        format_us(spec.exposure_us),
        format_us(start - extent.first_event),
        csv_path.display()
    );
    if args.despeckle {
        eprintln!("despeckle cleared {cleared} isolated pixels");
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

/// The camera-time interval `[start, end)` to cover and the sensor size.
struct Extent {
    first_event: i64,
    start: i64,
    end: i64,
    geometry: Geometry,
}

impl Extent {
    /// From the options, the file's header, and where needed one pass over the file.
    fn of(args: &FramesArgs, options: &ebiv::io::ReadOptions) -> Result<Extent, ebiv::Error> {
        let first_event = super::first_event_time(&args.file, options)?
            .ok_or_else(|| ebiv::Error::parameter("file", "the recording holds no events"))?;
        let origin = if args.absolute_time { 0 } else { first_event };
        let (from, to) = args.time.unwrap_or((None, None));
        let start = from.map_or(first_event, |s| s + origin);
        let mut end = to.map(|e| e + origin);
        let mut geometry = ebiv::io::open(&args.file, options)?.metadata().geometry;
        if end.is_none() || geometry.is_none() {
            let (mut t_max, mut x_max, mut y_max) = (i64::MIN, 0u16, 0u16);
            super::stream_file(&args.file, options, |_, batch: &EventBuffer| {
                t_max = batch.t.iter().copied().fold(t_max, i64::max);
                x_max = batch.x.iter().copied().fold(x_max, u16::max);
                y_max = batch.y.iter().copied().fold(y_max, u16::max);
                Ok(true)
            })?;
            end = end.or(Some(t_max.saturating_add(1)));
            if geometry.is_none() {
                let g = Geometry::new(x_max as u32 + 1, y_max as u32 + 1);
                eprintln!(
                    "note: the file does not state the sensor size; frames are {g} px, the largest coordinates seen (set it with --geometry)"
                );
                geometry = Some(g);
            }
        }
        let end = end.unwrap_or(start);
        if end <= start {
            return Err(ebiv::Error::parameter(
                "time",
                format!(
                    "nothing to do: the interval ends ({end} µs) before it starts ({start} µs)"
                ),
            ));
        }
        Ok(Extent {
            first_event,
            start,
            end,
            geometry: geometry.expect("set above"),
        })
    }
}

/// Detect the pulse timing from up to the first two seconds of `[start, end)` and say what
/// was found.
fn find_pulses(
    args: &FramesArgs,
    options: &ebiv::io::ReadOptions,
    start: i64,
    end: i64,
) -> Result<PulseTiming, ebiv::Error> {
    let until = end.min(start.saturating_add(DETECT_SPAN_US));
    let mut reader = ebiv::io::open(&args.file, options)?;
    reader.skip_to(start)?;
    let mut times = Vec::new();
    let mut triggers = Vec::new();
    let mut batch = EventBuffer::new();
    'read: while reader.read_batch(&mut batch)? {
        triggers.extend(
            batch
                .triggers
                .iter()
                .filter(|tr| tr.t >= start && tr.t < until),
        );
        for i in 0..batch.len() {
            let t = batch.t[i];
            if t >= until || times.len() >= DETECT_MAX_EVENTS {
                break 'read;
            }
            if t >= start && args.polarity.accepts(batch.p[i]) {
                times.push(t);
            }
        }
    }
    let timing = detect_pulses(&times, &triggers, args.pulse_hz)?;
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
