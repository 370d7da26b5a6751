//! One module per subcommand.

pub mod activity;
pub mod assess;
pub mod bench;
pub mod convert;
pub mod demo;
pub mod denoise;
pub mod derive;
pub mod frames;
pub mod index;
pub mod info;
pub mod live;
pub mod process;
pub mod render;
pub mod simulate;
pub mod stats;
pub mod study;
pub mod track;

use crate::progress::bytes_bar;
use ebiv::io::{EventReader, ReadOptions};
use ebiv::EventBuffer;
use std::path::Path;

/// Open `path` and hand every batch to `each`, with a progress bar over the file's bytes.
/// `each` returns `false` to stop early.
pub fn stream_file(
    path: &Path,
    options: &ReadOptions,
    mut each: impl FnMut(&EventReader, &EventBuffer) -> Result<bool, ebiv::Error>,
) -> Result<EventReader, ebiv::Error> {
    let mut reader = ebiv::io::open(path, options)?;
    let total = std::fs::metadata(path).ok().map(|m| m.len());
    let bar = bytes_bar(total.filter(|_| reader.position().is_some()), "reading");
    let mut batch = EventBuffer::new();
    while reader.read_batch(&mut batch)? {
        if let Some(pos) = reader.position() {
            bar.set_position(pos);
        } else {
            bar.tick();
        }
        if !each(&reader, &batch)? {
            break;
        }
    }
    bar.finish_and_clear();
    Ok(reader)
}

/// One line on standard error for each kind of dropped or skipped data.
pub fn print_report_summary(report: &ebiv::io::DecodeReport) {
    let lost =
        report.out_of_range + report.before_time_base + report.malformed + report.unknown_words;
    if lost > 0 {
        eprintln!(
            "warning: {lost} records of the input were not events ebiv could use (run `ebiv info` for details)"
        );
    }
    for w in report.warnings.iter().take(5) {
        eprintln!("warning: {w}");
    }
    print_denoise_report(report.denoise.as_ref());
}

/// One line per denoising filter: how many events it removed.
pub fn print_denoise_report(report: Option<&ebiv::denoise::DenoiseReport>) {
    for line in report.map(|r| r.lines()).unwrap_or_default() {
        eprintln!("denoise: {line}");
    }
}

pub use ebiv::export::check_output_path;
