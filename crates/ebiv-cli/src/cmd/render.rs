//! `ebiv render`: the first picture of a recording.

use crate::input::InputArgs;
use clap::Args;
use ebiv::render::{
    event_figure, figure_format, save_figure, time_coded_image, EventRateMap, ImageFigureStyle,
    MAX_PIXEL_SCALE,
};
use ebiv::units::format_us;
use ebiv::{EventBuffer, Geometry, PolaritySelection};
use std::path::{Path, PathBuf};

/// Draw the events of an interval colour-coded by time relative to T0 (past blue, present
/// white, future red, as in the EBIV paper's event images), or an event-rate map (--rate),
/// as a figure with axes in sensor pixels, a colour bar and a caption giving the time.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The recording.
    pub file: PathBuf,
    /// The figure to write: .png, .jpg (.jpeg), .tif (.tiff) or .bmp, by extension.
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
    /// Enlarge the sensor image by this whole factor, 1 to 16 (default: so that it is at
    /// least 640 px wide).
    #[arg(long, value_name = "N", allow_hyphen_values = true, value_parser = parse_scale)]
    pub scale: Option<u32>,
    #[command(flatten)]
    pub denoise: super::process::flags::DenoiseFlags,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Parse `--scale`: a whole number from 1 to [`MAX_PIXEL_SCALE`].
fn parse_scale(text: &str) -> Result<u32, String> {
    let bad = || format!("--scale must be a whole number from 1 to {MAX_PIXEL_SCALE}, got {text}");
    match text.trim().parse::<i64>() {
        Ok(k) if (1..=MAX_PIXEL_SCALE as i64).contains(&k) => Ok(k as u32),
        _ => Err(bad()),
    }
}

pub fn run(args: &RenderArgs) -> Result<(), ebiv::Error> {
    if args.dt <= 0 {
        return Err(ebiv::Error::parameter(
            "dt",
            "the interval must be longer than 0 µs",
        ));
    }
    // Before reading anything: the output format and the enlargement.
    figure_format(&args.output, "output")?;
    super::check_output_path(&args.output)?;
    // Ctrl-C stops the reading at its next batch; the figure, written through a temporary
    // file once everything is read, is then not written at all.
    let _catch = crate::interrupt::catch();
    let mut options = args.input.read_options()?;
    options.denoise = args.denoise.settings()?;
    let origin = if args.absolute_time {
        0
    } else {
        ebiv::process::first_event_time(&args.file, &options)?
            .ok_or_else(|| ebiv::Error::parameter("file", "the recording holds no events"))?
    };
    let whole_file = args.rate && args.t0.is_none();
    let beyond =
        || ebiv::Error::parameter("t0", "--t0 and --dt reach beyond the range of time stamps");
    let t0 = origin
        .checked_add(args.t0.unwrap_or(args.dt / 2))
        .ok_or_else(beyond)?;
    let (start, end) = if whole_file {
        (i64::MIN, i64::MAX)
    } else {
        (
            t0.checked_sub(args.dt / 2).ok_or_else(beyond)?,
            t0.checked_add(args.dt - args.dt / 2).ok_or_else(beyond)?,
        )
    };
    let name = args.file.file_name().unwrap_or_default().to_string_lossy();
    let polarity = args.polarity.name();
    let style = |what: &str| ImageFigureStyle {
        title: Some(format!("{name}: {what}, polarity {polarity}")),
        pixel_scale: args.scale,
        time_origin_us: origin,
    };
    if args.rate {
        let raw = options.without_denoise();
        let geometry = match ebiv::io::open(&args.file, &raw)?.metadata().geometry {
            Some(g) => g,
            None => {
                let mut stats = ebiv::stats::RecordingStats::new();
                super::stream_file(&args.file, &raw, |_, b| {
                    crate::interrupt::check(&args.output)?;
                    stats.add(b);
                    Ok(true)
                })?;
                data_geometry(stats.x_range.map(|r| r.1), stats.y_range.map(|r| r.1))
            }
        };
        let style = style("event rate");
        style.scale_for(geometry.width, geometry.height)?;
        let mut map = EventRateMap::new(geometry);
        let reader = super::stream_file(&args.file, &options, |_, batch| {
            crate::interrupt::check(&args.output)?;
            map.add(batch, start, end, args.polarity);
            Ok(!batch.t.iter().all(|&t| t >= end) || batch.is_empty())
        })?;
        super::print_denoise_report(reader.denoise_report().as_ref());
        let interval = (!whole_file).then_some((start, end));
        let img = map.render(interval, &style)?;
        if img.active_pixels == 0 {
            return Err(nothing_to_draw(args, t0 - origin));
        }
        save_figure(&img.image, &args.output)?;
        eprintln!(
            "wrote {}: event rate of {} active pixels, colour bar 0 .. {:.0} events/s per pixel (mean {:.1})",
            args.output.display(),
            img.active_pixels,
            img.max_rate,
            img.mean_active_rate
        );
    } else {
        let (events, geometry) = collect(&args.file, &options, (start, end), &args.output)?;
        let img = time_coded_image(&events, geometry, t0, args.dt / 2, args.polarity);
        if img.events == 0 {
            return Err(nothing_to_draw(args, t0 - origin));
        }
        save_figure(&event_figure(&img, &style("events"))?, &args.output)?;
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

/// The error for an interval without events of the selected polarity: a blank figure is not
/// written.
fn nothing_to_draw(args: &RenderArgs, t0_from_origin: i64) -> ebiv::Error {
    let when = if args.rate && args.t0.is_none() {
        "in the recording".to_string()
    } else {
        format!(
            "within {} of t0 = {}{}",
            format_us(args.dt / 2),
            format_us(t0_from_origin),
            if args.absolute_time {
                " (camera time)"
            } else {
                " after the first event"
            }
        )
    };
    ebiv::Error::empty(
        args.file.display().to_string(),
        format!(
            "no event of polarity `{}` {when}, so no figure is written; `ebiv info` gives the recording's span and polarities (check --t0, --dt and --polarity)",
            args.polarity.name()
        ),
    )
}

/// The events of `[start, end)` and the sensor geometry (from the file, the options, or the
/// largest coordinates seen).
fn collect(
    path: &Path,
    options: &ebiv::io::ReadOptions,
    (start, end): (i64, i64),
    output: &Path,
) -> Result<(EventBuffer, Geometry), ebiv::Error> {
    let mut reader = ebiv::io::open(path, options)?;
    if start > i64::MIN {
        reader.skip_to(start)?;
    }
    let mut events = EventBuffer::new();
    let mut batch = EventBuffer::new();
    while reader.read_batch(&mut batch)? {
        crate::interrupt::check(output)?;
        let done = batch.t.iter().all(|&t| t >= end) && !batch.is_empty();
        batch.retain(|e| e.t >= start && e.t < end);
        events.extend_from(&batch);
        if done {
            break;
        }
    }
    super::print_denoise_report(reader.denoise_report().as_ref());
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

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        render: RenderArgs,
    }

    fn parse(args: &[&str]) -> Result<RenderArgs, String> {
        Cli::try_parse_from(std::iter::once("render").chain(args.iter().copied()))
            .map(|c| c.render)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn scale_must_be_a_whole_number_from_1_to_16() {
        for bad in ["0", "-1", "17", "1000000", "2.5", "x"] {
            let e = parse(&["rec.raw", "-o", "a.png", "--scale", bad])
                .err()
                .unwrap_or_else(|| panic!("--scale {bad} accepted"));
            assert!(e.contains("--scale") && e.contains("1 to 16"), "{e}");
        }
        for (text, k) in [("1", 1), ("16", 16)] {
            let args = parse(&["rec.raw", "-o", "a.png", "--scale", text]).unwrap();
            assert_eq!(args.scale, Some(k));
        }
        assert_eq!(parse(&["rec.raw", "-o", "a.png"]).unwrap().scale, None);
    }

    /// A 64 × 48 recording of a particle moving right, 1 px per 100 µs.
    fn recording(dir: &Path) -> PathBuf {
        let path = dir.join("rec.csv");
        let mut text = String::from("%geometry:64,48\n");
        for i in 0..40 {
            text.push_str(&format!("{},20,1,{}\n", 10 + i, 1000 + 100 * i));
        }
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn figures_are_written_in_the_format_the_output_names() {
        let dir = tempfile::tempdir().unwrap();
        let rec = recording(dir.path());
        for (name, rate, magic) in [
            ("events.jpg", false, &[0xFF, 0xD8, 0xFF][..]),
            ("rate.jpeg", true, &[0xFF, 0xD8, 0xFF][..]),
            ("events.png", false, &b"\x89PNG"[..]),
        ] {
            let out = dir.path().join(name);
            let mut args = vec![rec.to_str().unwrap(), "-o", out.to_str().unwrap()];
            args.extend(["--dt", "2ms", "--scale", "10"]);
            if rate {
                args.push("--rate");
            }
            run(&parse(&args).unwrap()).unwrap();
            let bytes = std::fs::read(&out).unwrap();
            assert!(bytes.starts_with(magic), "{name}: {:02x?}", &bytes[..4]);
            // The figure: the 640 × 480 plot with axes, colour bar and caption around it.
            let (w, h) = image::image_dimensions(&out).unwrap();
            assert!(w > 640 + 100 && h > 480 + 80, "{name}: {w}x{h}");
        }
        let out = dir.path().join("events.gif");
        let args = [rec.to_str().unwrap(), "-o", out.to_str().unwrap()];
        let e = run(&parse(&args).unwrap()).unwrap_err().to_string();
        assert!(e.contains(".png") && e.contains(".jpg"), "{e}");
        assert!(!out.exists());
        // An enlargement that makes the figure too large is refused naming the flag.
        let out = dir.path().join("big.png");
        let args = [rec.to_str().unwrap(), "-o", out.to_str().unwrap()];
        let mut big = parse(&args).unwrap();
        big.scale = Some(400);
        let e = run(&big).unwrap_err().to_string();
        assert!(e.contains("scale"), "{e}");
    }
}
