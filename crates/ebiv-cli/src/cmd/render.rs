//! `ebiv render`: the first picture of a recording.

use crate::input::InputArgs;
use clap::Args;
use ebiv::render::{save_png, time_coded_image, upscale, EventRateMap};
use ebiv::units::format_us;
use ebiv::{EventBuffer, Geometry, PolaritySelection};
use std::path::{Path, PathBuf};

/// Draw the events of an interval colour-coded by time relative to T0 (past blue, present
/// white, future red, as in the EBIV paper's event images), or an event-rate map (--rate).
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The recording.
    pub file: PathBuf,
    /// The PNG to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Centre time of the image, from the first event (e.g. `25ms`); default: the first
    /// event plus DT/2.
    #[arg(long, value_parser = ebiv::units::parse_us)]
    pub t0: Option<i64>,
    /// Length of the interval drawn, centred on T0 (e.g. `10ms`, `500us`).
    #[arg(long, default_value = "10ms", value_parser = ebiv::units::parse_us)]
    pub dt: i64,
    /// Read --t0 as a camera time stamp in µs rather than from the first event.
    #[arg(long)]
    pub absolute_time: bool,
    /// Draw the event rate per pixel (events/s, square-root colour scale with a colour bar)
    /// instead; over the whole recording unless --t0 is given.
    #[arg(long)]
    pub rate: bool,
    /// Polarities drawn: pos, neg or both.
    #[arg(long, default_value = "both", value_parser = super::convert::parse_polarity)]
    pub polarity: PolaritySelection,
    /// Enlarge by this integer factor (default: so that the image is at least 640 px wide).
    #[arg(long)]
    pub scale: Option<u32>,
    #[command(flatten)]
    pub input: InputArgs,
}

pub fn run(args: &RenderArgs) -> Result<(), ebiv::Error> {
    if args.dt <= 0 {
        return Err(ebiv::Error::parameter(
            "dt",
            "the interval must be longer than 0 µs",
        ));
    }
    let options = args.input.read_options()?;
    let origin = if args.absolute_time {
        0
    } else {
        ebiv::process::first_event_time(&args.file, &options)?
            .ok_or_else(|| ebiv::Error::parameter("file", "the recording holds no events"))?
    };
    let whole_file = args.rate && args.t0.is_none();
    let t0 = origin + args.t0.unwrap_or(args.dt / 2);
    let (start, end) = if whole_file {
        (i64::MIN, i64::MAX)
    } else {
        (t0 - args.dt / 2, t0 + args.dt - args.dt / 2)
    };
    let scale = |g: Geometry| {
        args.scale
            .unwrap_or(640u32.div_ceil(g.width).clamp(1, 8))
            .clamp(1, 16)
    };
    if args.rate {
        let geometry = match ebiv::io::open(&args.file, &options)?.metadata().geometry {
            Some(g) => g,
            None => {
                let mut stats = ebiv::stats::RecordingStats::new();
                super::stream_file(&args.file, &options, |_, b| {
                    stats.add(b);
                    Ok(true)
                })?;
                data_geometry(stats.x_range.map(|r| r.1), stats.y_range.map(|r| r.1))
            }
        };
        let mut map = EventRateMap::new(geometry);
        super::stream_file(&args.file, &options, |_, batch| {
            map.add(batch, start, end, args.polarity);
            Ok(!batch.t.iter().all(|&t| t >= end) || batch.is_empty())
        })?;
        let duration = (!whole_file).then_some(args.dt);
        let img = map.render(duration);
        save_png(&upscale(&img.image, scale(geometry)), &args.output)?;
        eprintln!(
            "wrote {}: event rate of {} active pixels, colour bar 0 .. {:.0} events/s per pixel (mean {:.1})",
            args.output.display(),
            img.active_pixels,
            img.max_rate,
            img.mean_active_rate
        );
    } else {
        let (events, geometry) = collect(&args.file, &options, start, end)?;
        let img = time_coded_image(&events, geometry, t0, args.dt / 2, args.polarity);
        save_png(&upscale(&img.image, scale(geometry)), &args.output)?;
        eprintln!(
            "wrote {}: {} events within {} of t0 = {} µs{}; past blue, t0 white, future red",
            args.output.display(),
            img.events,
            format_us(args.dt / 2),
            t0,
            if args.absolute_time {
                String::new()
            } else {
                format!(" ({} after the first event)", format_us(t0 - origin))
            }
        );
    }
    Ok(())
}

/// The events of `[start, end)` and the sensor geometry (from the file, the options, or the
/// largest coordinates seen).
fn collect(
    path: &Path,
    options: &ebiv::io::ReadOptions,
    start: i64,
    end: i64,
) -> Result<(EventBuffer, Geometry), ebiv::Error> {
    let mut reader = ebiv::io::open(path, options)?;
    if start > i64::MIN {
        reader.skip_to(start)?;
    }
    let mut events = EventBuffer::new();
    let mut batch = EventBuffer::new();
    while reader.read_batch(&mut batch)? {
        let done = batch.t.iter().all(|&t| t >= end) && !batch.is_empty();
        batch.retain(|e| e.t >= start && e.t < end);
        events.extend_from(&batch);
        if done {
            break;
        }
    }
    let geometry = match reader.metadata().geometry {
        Some(g) => g,
        None => data_geometry(
            events.x.iter().max().copied(),
            events.y.iter().max().copied(),
        ),
    };
    Ok((events, geometry))
}

/// A sensor just large enough for the largest coordinates seen, with a note to the user.
fn data_geometry(x_max: Option<u16>, y_max: Option<u16>) -> Geometry {
    let w = x_max.map_or(1, |x| x as u32 + 1);
    let h = y_max.map_or(1, |y| y as u32 + 1);
    eprintln!("note: the file does not state its size; drawing {w}x{h} (pass --geometry)");
    Geometry::new(w, h)
}
