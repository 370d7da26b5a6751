//! `ebiv convert`: rewrite a recording in another format, optionally cut and cropped.

use super::process::flags::DenoiseFlags;
use crate::input::InputArgs;
use clap::Args;
use ebiv::filter::{EventFilter, Roi};
use ebiv::io::{write, Format, RawEncoding};
use ebiv::PolaritySelection;
use std::path::PathBuf;

/// Convert IN to OUT; the output format follows OUT's extension: .raw (EVT 3.0, or
/// --output-encoding), .aedat4 (LZ4), .csv (header `t,x,y,p`, t in µs, p 0/1), .npy
/// (structured array) or .npz (column arrays).
#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// The recording to read.
    pub input: PathBuf,
    /// The file to write (.raw, .aedat4, .csv, .npy, .npz).
    pub output: PathBuf,
    /// Keep only START:END (e.g. `10ms:20ms`, either side may be empty), measured from the
    /// first event of the recording (or in camera time with --absolute-time).
    #[arg(long, visible_alias = "time", value_name = "START:END", value_parser = ebiv::units::parse_range)]
    pub time_range: Option<(Option<i64>, Option<i64>)>,
    /// Read --time-range as camera time stamps in µs rather than from the first event.
    #[arg(long)]
    pub absolute_time: bool,
    /// Keep only the region x,y,width,height; output coordinates start at its corner.
    #[arg(long, value_name = "X,Y,W,H", value_parser = parse_roi)]
    pub roi: Option<Roi>,
    /// Keep positive (ON), negative (OFF) or both polarities.
    #[arg(long, default_value = "both", value_parser = parse_polarity)]
    pub polarity: PolaritySelection,
    /// RAW output encoding: evt3 (default), evt2 or evt21 (little-endian words).
    #[arg(long, value_name = "ENC", default_value = "evt3", value_parser = parse_raw_encoding)]
    pub output_encoding: RawEncoding,
    #[command(flatten)]
    pub denoise: DenoiseFlags,
    #[command(flatten)]
    pub input_args: InputArgs,
}

pub fn parse_raw_encoding(s: &str) -> Result<RawEncoding, String> {
    RawEncoding::parse(s).ok_or_else(|| format!("`{s}` is not evt2, evt21 or evt3"))
}

fn parse_roi(s: &str) -> Result<Roi, String> {
    Roi::parse(s).map_err(|e| e.to_string())
}

/// Parse a polarity selection for clap.
pub fn parse_polarity(s: &str) -> Result<PolaritySelection, String> {
    PolaritySelection::parse(s).ok_or_else(|| format!("`{s}` is not pos, neg or both"))
}

/// Stop reading once a whole batch lies this far past the end of the requested interval;
/// the margin tolerates small time regressions of real sensors.
const STOP_MARGIN_US: i64 = 1_000_000;

pub fn run(args: &ConvertArgs) -> Result<(), ebiv::Error> {
    let mut options = args.input_args.read_options()?;
    options.denoise = args.denoise.settings()?;
    rewrite(&Rewrite {
        input: &args.input,
        output: &args.output,
        options: &options,
        time_range: args.time_range.unwrap_or((None, None)),
        absolute_time: args.absolute_time,
        roi: args.roi,
        polarity: args.polarity,
        output_encoding: args.output_encoding,
    })
}

/// A recording rewritten: `ebiv convert`, and `ebiv filter` (denoising, nothing selected).
pub struct Rewrite<'a> {
    pub input: &'a std::path::Path,
    pub output: &'a std::path::Path,
    /// How to read the input, denoising included.
    pub options: &'a ebiv::io::ReadOptions,
    pub time_range: (Option<i64>, Option<i64>),
    pub absolute_time: bool,
    pub roi: Option<Roi>,
    pub polarity: PolaritySelection,
    pub output_encoding: RawEncoding,
}

/// Read, denoise, select and write; print what was written and removed.
pub fn rewrite(args: &Rewrite) -> Result<(), ebiv::Error> {
    let options = args.options;
    let out_format = match write::format_for_path(args.output)? {
        Format::Evt3 => args.output_encoding.format(),
        other => other,
    };
    super::check_output_path(args.output)?;
    let origin = if args.absolute_time {
        0
    } else {
        ebiv::process::first_event_time(args.input, options)?.unwrap_or(0)
    };
    let (start, end) = args.time_range;
    let filter = EventFilter {
        t_start: start.map(|s| s + origin),
        t_end: end.map(|e| e + origin),
        roi: args.roi,
        polarity: args.polarity,
    };
    let mut reader = ebiv::io::open(args.input, options)?;
    let mut geometry = reader.metadata().geometry;
    if let Some(roi) = args.roi {
        if let Some(g) = geometry {
            roi.check_within(g)?;
        }
        geometry = Some(roi.geometry());
    }
    if let Some(t) = filter.t_start {
        reader.skip_to(t)?;
    }
    // Ctrl-C stops the conversion at its next batch, and the unfinished file is removed; the
    // guard is declared before the writer, so that it is still in place while the writer
    // removes its file, and lives until the file is complete.
    let catch = crate::interrupt::catch();
    let mut writer = write::create(args.output, out_format, geometry)?;
    let total = std::fs::metadata(args.input).ok().map(|m| m.len());
    let bar =
        crate::progress::bytes_bar(total.filter(|_| reader.position().is_some()), "converting");
    let mut batch = ebiv::EventBuffer::new();
    let mut written = 0u64;
    while reader.read_batch(&mut batch)? {
        crate::interrupt::check(args.output)?;
        let past_end = filter
            .t_end
            .is_some_and(|e| batch.t.iter().all(|&t| t >= e + STOP_MARGIN_US) && !batch.is_empty());
        filter.apply(&mut batch);
        written += batch.len() as u64;
        writer.write(&batch)?;
        if let Some(p) = reader.position() {
            bar.set_position(p);
        }
        if past_end {
            break;
        }
    }
    crate::interrupt::check(args.output)?;
    if written == 0 {
        // (The writer, dropped unfinished, removes its file.)
        return Err(ebiv::Error::empty(
            args.input.display().to_string(),
            if options.denoise.is_some() {
                "no event passes the denoising and the selection (--denoise, --time-range, --roi, --polarity), so nothing is written; `ebiv info` shows the recording's span, size and polarities"
            } else {
                "no event passes the selection (--time-range, --roi, --polarity), so nothing is written; `ebiv info` shows the recording's span, size and polarities"
            },
        ));
    }
    writer.finish()?;
    drop(catch);
    bar.finish_and_clear();
    let report = reader.report();
    eprintln!(
        "wrote {written} events to {} ({})",
        args.output.display(),
        out_format
    );
    crate::cmd::print_report_summary(&report);
    Ok(())
}
