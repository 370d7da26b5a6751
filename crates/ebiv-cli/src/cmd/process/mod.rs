//! `ebiv process`: velocity fields from an event recording, by sum of correlation or motion
//! compensation, multi-pass, validated, written to disk and drawn; or by PIV of frames
//! rebuilt from the events, of one frame per light pulse, or of image pairs.
//!
//! The settings, their flags, defaults and checks are the library's
//! ([`ebiv::settings::ProcessSettings`]); this module reads them, reports progress and prints.

mod events;
mod figures;
mod flags;
mod piv;

pub use figures::{describe_passes, series_histograms};

use crate::input::InputArgs;
use clap::Args;
use ebiv::process::Method;
use ebiv::settings::{ProcessSettings, Source};
use std::path::PathBuf;

/// Measure velocity fields from an event recording (Willert & Klinner 2022), or by PIV from
/// image pairs (`--method piv --images A B`).
///
/// Every flag is also a key of the configuration file (`ebiv init` writes one with all of
/// them, commented); flags override the file. Durations take units (10ms, 250us, 1.5s),
/// lengths are pixels, velocities px/ms (m/s with --mm-per-px). A field's time t0 is the
/// centre of its time slab.
#[derive(Debug, Args)]
pub struct ProcessArgs {
    /// Settings file (TOML, see `ebiv init`); flags override its keys.
    #[arg(long, value_name = "TOML")]
    pub config: Option<PathBuf>,
    #[command(flatten)]
    pub settings: flags::SettingFlags,
    #[command(flatten)]
    pub input: InputArgs,
}

pub fn run(args: &ProcessArgs) -> Result<(), ebiv::Error> {
    let mut settings = ProcessSettings::default();
    if let Some(path) = &args.config {
        for warning in settings.apply_file(path)? {
            eprintln!("warning: {}: {warning}", path.display());
        }
    }
    args.settings.apply(&mut settings)?;
    let run = settings.resolve()?;
    super::check_output_path(&run.output)?;
    ebiv::export::field_extension(&run.output)?;
    let options = args.input.read_options()?;
    // Ctrl-C stops the run after the field being evaluated: the field file is not written
    // (it is written whole at the end, or not at all), and every figure on disk is complete.
    let _catch = crate::interrupt::catch();
    match (run.method, &run.source) {
        (Method::CorrSum | Method::Motion, _) => run.with_event_estimator(events::Run {
            run: &run,
            options: &options,
        })?,
        (Method::Piv, Source::Images(_)) => piv::run_images(&run),
        (Method::Piv | Method::Pulsed, _) => piv::run_events(&run, &options),
    }
}

/// After a run over a recording, before anything is written: an error when no field held an
/// event of the selected polarity (a `--time` beyond the recording, or a polarity the camera
/// did not record), a warning when some fields were empty or no vector is valid.
fn check_run_found_events(
    run: &ebiv::settings::Resolved,
    summary: &ebiv::process::RunSummary,
    described_times: &str,
    polarity: ebiv::PolaritySelection,
) -> Result<(), ebiv::Error> {
    let input = run.input_path();
    let polarity = match polarity {
        ebiv::PolaritySelection::Both => "either polarity".to_string(),
        p => format!("{} polarity", format!("{p:?}").to_lowercase()),
    };
    if summary.fields > 0 && summary.empty_fields == summary.fields {
        return Err(ebiv::Error::empty(
            input.display().to_string(),
            format!(
                "no event of {polarity} in any field's time interval ({described_times}), so no field file is written. `ebiv info {}` shows the recording's span and polarities: check --time and --polarity",
                input.display()
            ),
        ));
    }
    if summary.empty_fields > 0 {
        eprintln!(
            "warning: {} of {} field(s) had no event of {polarity} in their time interval; their vectors are gaps (check --time against the recording's span from `ebiv info`)",
            summary.empty_fields, summary.fields
        );
    }
    if summary.vectors > 0 && summary.valid == 0 {
        eprintln!(
            "warning: no vector is valid. Look at the events (`ebiv render`) and see Troubleshooting in the README: too few particles per window (larger --window), a --slab too short for the particles to move a pixel or so long they leave the window, or --max-velocity too low"
        );
    }
    Ok(())
}

/// Write a commented configuration file for `ebiv process --config`.
#[derive(Debug, Args)]
pub struct InitArgs {
    /// File to write.
    #[arg(default_value = "ebiv.toml")]
    pub output: PathBuf,
    /// Overwrite an existing file.
    #[arg(long)]
    pub force: bool,
}

pub fn init(args: &InitArgs) -> Result<(), ebiv::Error> {
    if args.output.exists() && !args.force {
        return Err(ebiv::Error::parameter(
            "output",
            format!(
                "{} exists; use --force to overwrite it",
                args.output.display()
            ),
        ));
    }
    std::fs::write(&args.output, ebiv::settings::template())
        .map_err(|e| ebiv::Error::io(&args.output, e))?;
    println!(
        "wrote {}: edit it, then run `ebiv process --config {}`",
        args.output.display(),
        args.output.display()
    );
    Ok(())
}
