//! `ebiv live`: velocity fields while the camera records, from a growing file, a pipe, or a
//! replayed recording; appended to a file as they arrive and shown in a browser.
//!
//! The library runs the pipeline ([`ebiv::live::run_live`]), writes ([`ebiv::export::LiveWriter`])
//! and serves the page ([`ebiv::export::LiveView`]); this module reads the flags and prints.

use super::process::{flags::SettingFlags, parse_settings};
use crate::input::InputArgs;
use clap::Args;
use ebiv::export::{LiveOutputs, LiveView, LiveWriter};
use ebiv::live::{LiveField, LiveInput, LiveOptions, LiveSink, LiveStart, LiveSummary};
use ebiv::Error;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Compute velocity fields while the camera records, and show them live.
///
/// INPUT is a recording still being written (`--follow`), `-` for standard input (RAW and
/// other formats that need no seeking), or a finished recording (`--replay` plays it at its
/// own rate; without it, it is read as fast as the fields are computed). The method and every
/// setting are those of `ebiv process` (flags and `--config`); a field is computed every slab,
/// or every `--every`. When the machine cannot keep up with a live input, whole
/// fields are dropped, never events of a field, and the output says so (`fields_dropped`).
/// Ctrl-C stops the run after the field being evaluated; the output file is then complete
/// up to that field.
#[derive(Debug, Args)]
pub struct LiveArgs {
    /// Settings file (TOML, see `ebiv init`); flags override its keys.
    #[arg(long, value_name = "TOML")]
    pub config: Option<PathBuf>,
    /// Follow a recording that is still being written: wait for new data at its end.
    #[arg(long, conflicts_with = "replay")]
    pub follow: bool,
    /// With --follow: end when the file has not grown for this long.
    #[arg(long, value_name = "DUR", default_value = "5s")]
    pub idle: String,
    /// Play a finished recording at its own rate (for demonstrations and tests).
    #[arg(long)]
    pub replay: bool,
    /// With --replay: speed relative to the recording's own rate.
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub speed: f64,
    /// Time between fields (default: one per slab; or the STEP of --time).
    #[arg(long, value_name = "DUR")]
    pub every: Option<String>,
    /// Slabs that may wait for the estimator; when one more arrives from a live input, the
    /// oldest is dropped.
    #[arg(long, value_name = "N", default_value_t = ebiv::live::DEFAULT_QUEUE)]
    pub queue: usize,
    /// Serve the live view, a web page updated as fields arrive, at 127.0.0.1:8080, or at
    /// ADDR with --serve=ADDR (port 0 picks a free one).
    #[arg(
        long,
        value_name = "ADDR",
        num_args = 0..=1,
        require_equals = true,
        default_missing_value = "127.0.0.1:8080"
    )]
    pub serve: Option<String>,
    /// Allow --serve on an address other than loopback: anyone who can reach it sees the
    /// page, without a password.
    #[arg(long)]
    pub allow_remote: bool,
    /// Write a summary of the run (counts, rates, latency percentiles) as JSON.
    #[arg(long, value_name = "FILE")]
    pub summary: Option<PathBuf>,
    #[command(flatten)]
    pub settings: SettingFlags,
    #[command(flatten)]
    pub input: InputArgs,
}

pub fn run(args: &LiveArgs) -> Result<(), Error> {
    let settings = parse_settings(args.config.as_deref(), &args.settings)?;
    if settings.png.is_some() {
        return Err(Error::parameter(
            "png",
            "live shows its fields in the browser (--serve); figures per field are ebiv process's",
        ));
    }
    let run = settings.resolve()?;
    let given_output = args
        .settings
        .given
        .iter()
        .any(|(flag, _)| *flag == "output")
        || args.config.as_deref().is_some_and(config_sets_output);
    let output = given_output.then(|| run.output.clone());
    if let Some(path) = &output {
        super::check_output_path(path)?;
    }
    let writer = output.as_deref().map(LiveWriter::create).transpose()?;
    let input = LiveInput::choose(
        &run.input_path(),
        args.follow,
        args.replay,
        args.speed,
        &args.idle,
    )?;
    let mut options = LiveOptions::new(input);
    options.set_read_options(args.input.read_options()?);
    options.queue = args.queue;
    options.every_us = args
        .every
        .as_deref()
        .map(|text| ebiv::units::parse_us(text).map_err(|m| Error::parameter("every", m)))
        .transpose()?;
    let view = match &args.serve {
        Some(addr) => {
            let view = LiveView::start(addr, args.allow_remote)?;
            println!("live view: http://{}/", view.address());
            options.events_every = Some(ebiv::export::LIVE_VIEW_INTERVAL);
            Some(view)
        }
        None => None,
    };
    let _catch = crate::interrupt::catch();
    let mut sink = Printer {
        outputs: LiveOutputs::new(writer, view),
        last_line: Instant::now(),
        first_line: true,
    };
    let summary = ebiv::live::run_live(
        &run,
        &options,
        Arc::new(crate::interrupt::received),
        &mut sink,
    );
    let finished = sink.outputs.finish();
    eprintln!();
    let summary = summary?;
    let wrote = finished?;
    report(&summary, output.as_deref().filter(|_| wrote));
    if let Some(path) = &args.summary {
        let text = serde_json::to_string_pretty(&summary).expect("a summary serialises");
        std::fs::write(path, text + "\n").map_err(|e| Error::io(path, e))?;
    }
    // Ended by Ctrl-C or SIGTERM: the outputs are complete; end by that signal, as shells
    // expect of an interrupted command.
    crate::interrupt::resend_caught_signal();
    Ok(())
}

/// Whether the configuration file at `path` sets `output`.
fn config_sets_output(path: &std::path::Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|text| text.parse::<toml::Table>().ok())
        .is_some_and(|table| table.contains_key("output"))
}

/// Writes, serves and prints a status line about twice a second.
struct Printer {
    outputs: LiveOutputs,
    last_line: Instant,
    first_line: bool,
}

impl LiveSink for Printer {
    fn started(&mut self, start: &LiveStart) -> Result<(), Error> {
        println!("{}", start.description);
        self.outputs.started(start)
    }

    fn field(&mut self, f: &LiveField) -> Result<(), Error> {
        self.outputs.field(f)?;
        if self.first_line || self.last_line.elapsed() >= Duration::from_millis(500) {
            self.first_line = false;
            self.last_line = Instant::now();
            let s = &f.stats;
            let mut err = std::io::stderr();
            let _ = write!(
                err,
                "\r{:>7.1} s  fields {} ({:.1}/s)  dropped {}  events {:.2} M/s  latency {:.1} ms (p99 {:.1} ms)   ",
                s.elapsed_s,
                s.fields,
                s.field_rate,
                s.dropped,
                s.event_rate / 1e6,
                s.latency_ms,
                s.latency_p99_ms
            );
            let _ = err.flush();
        }
        Ok(())
    }
}

fn report(s: &LiveSummary, output: Option<&std::path::Path>) {
    let t = &s.stats;
    println!(
        "{} field(s) in {:.2} s ({:.1} fields/s), {} dropped, {} events ({:.2} M events/s){}",
        t.fields,
        t.elapsed_s,
        t.field_rate,
        t.dropped,
        t.events,
        t.event_rate / 1e6,
        if s.stopped { "; stopped" } else { "" }
    );
    println!(
        "latency from a slab's end to its field: median {:.1} ms, 99th percentile {:.1} ms, largest {:.1} ms",
        s.latency_p50_ms, s.latency_p99_ms, s.latency_max_ms
    );
    if t.dropped > 0 {
        println!(
            "warning: {} field(s) dropped: the machine did not keep up (fewer passes, larger windows, a longer --time step or --threads help)",
            t.dropped
        );
    }
    if s.empty_fields > 0 {
        println!(
            "warning: {} field(s) held no event of the selected polarity",
            s.empty_fields
        );
    }
    if s.lone_pixel_events > 0 {
        println!(
            "{}",
            ebiv::process::lone_pixel_line(s.lone_pixel_events as usize)
        );
    }
    for w in &s.report.warnings {
        println!("warning: {w}");
    }
    crate::cmd::print_denoise_report(s.report.denoise.as_ref());
    if let Some(path) = output {
        println!("wrote {}", path.display());
    }
}
