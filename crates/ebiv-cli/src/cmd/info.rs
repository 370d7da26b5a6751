//! `ebiv info`: what a recording holds.

use crate::input::InputArgs;
use clap::Args;
use ebiv::stats::RecordingStats;
use ebiv::units::format_us;
use std::path::PathBuf;

/// Print format, sensor, event counts, time range, rates, triggers and every warning.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The recording.
    pub file: PathBuf,
    /// Print one JSON object instead of text (for scripts).
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub activity: super::activity::ActivityArgs,
    #[command(flatten)]
    pub input: InputArgs,
}

pub fn run(args: &InfoArgs) -> Result<(), ebiv::Error> {
    let options = args.input.read_options()?;
    let mut stats = RecordingStats::new();
    let mut activity = None;
    let reader = super::stream_file(&args.file, &options, |reader, batch| {
        stats.add(batch);
        if args.activity.activity {
            if activity.is_none() {
                let geometry = reader.metadata().geometry;
                activity = Some(args.activity.start(&args.file, &options, geometry)?);
            }
            if let Some(run) = activity.as_mut() {
                run.add(batch)?;
            }
        }
        Ok(true)
    })?;
    if args.activity.activity && activity.is_none() {
        let geometry = reader.metadata().geometry;
        activity = Some(args.activity.start(&args.file, &options, geometry)?);
    }
    let activity = activity.map(|run| run.finish());
    let meta = reader.metadata();
    let report = reader.report();
    let file_bytes = std::fs::metadata(&args.file).map(|m| m.len()).unwrap_or(0);
    if args.json {
        let value = serde_json::json!({
            "file": args.file.display().to_string(),
            "bytes": file_bytes,
            "metadata": meta,
            "stats": stats,
            "duration_us": stats.duration_us(),
            "mean_rate_ev_per_s": stats.mean_rate(),
            "peak_rate_ev_per_s": stats.peak_rate(),
            "report": report,
            "activity": activity.as_ref().map(|(r, _)| r),
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&value).expect("serialisable")
        );
        return Ok(());
    }
    println!("file        {} ({} bytes)", args.file.display(), file_bytes);
    println!("format      {}", meta.format);
    match meta.geometry {
        Some(g) => println!("geometry    {g}"),
        None => println!("geometry    not stated by the file (pass --geometry WxH)"),
    }
    if let Some(s) = &meta.sensor {
        println!("sensor      {s}");
    }
    if let Some(s) = &meta.serial {
        println!("serial      {s}");
    }
    let off = stats.events - stats.on;
    println!(
        "events      {} (ON {}, OFF {})",
        stats.events, stats.on, off
    );
    if let (Some(t0), Some(t1)) = (stats.t_min, stats.t_max) {
        println!(
            "time        {t0} .. {t1} µs (duration {})",
            format_us(t1 - t0)
        );
    }
    if meta.time_shift_us != 0 {
        println!(
            "time shift  {} µs subtracted (Metavision view)",
            meta.time_shift_us
        );
    }
    if let (Some(first), Some(last)) = (stats.first, stats.last) {
        println!(
            "first event t={} x={} y={} p={}",
            first.0, first.1, first.2, first.3
        );
        println!(
            "last event  t={} x={} y={} p={}",
            last.0, last.1, last.2, last.3
        );
    }
    if let (Some(x), Some(y)) = (stats.x_range, stats.y_range) {
        println!("pixels      x {}..{}, y {}..{}", x.0, x.1, y.0, y.1);
    }
    println!(
        "rate        mean {:.3} Mev/s, peak {:.3} Mev/s (1 ms bins)",
        stats.mean_rate() * 1e-6,
        stats.peak_rate() * 1e-6
    );
    if stats.triggers.is_empty() {
        println!("triggers    none");
    }
    for (ch, (n, a, b)) in &stats.triggers {
        println!("triggers    channel {ch}: {n} edges, t {a} .. {b} µs");
    }
    if !meta.header.is_empty() {
        println!("header");
        for (k, v) in &meta.header {
            println!("  {k} {v}");
        }
    }
    for note in &meta.notes {
        println!("note        {note}");
    }
    let counters = [
        ("dropped, pixel outside the sensor", report.out_of_range),
        (
            "dropped, before the first time base",
            report.before_time_base,
        ),
        ("time steps backwards (kept)", report.time_regressions),
        ("unknown words skipped", report.unknown_words),
        ("malformed records skipped", report.malformed),
        (
            "non-event records skipped (IMU, monitoring, frames)",
            report.skipped_other,
        ),
        (
            "trailing bytes of an incomplete record",
            report.truncated_bytes,
        ),
    ];
    for (what, n) in counters {
        if n > 0 {
            println!("warning     {n} {what}");
        }
    }
    for w in &report.warnings {
        println!("warning     {w}");
    }
    if let Some((r, selection)) = &activity {
        super::activity::print(r, selection);
    }
    Ok(())
}
