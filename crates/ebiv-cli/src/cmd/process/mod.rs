//! `ebiv process`: velocity fields from an event recording, by sum of correlation or motion
//! compensation, multi-pass, validated, written to disk and drawn; or by PIV of frames
//! rebuilt from the events, of one frame per light pulse, or of image pairs.
//!
//! The settings, their flags, defaults and checks are the library's
//! ([`ebiv::settings::ProcessSettings`]); this module reads them, reports progress and prints.

mod events;
mod figures;
pub(crate) mod flags;
mod piv;

pub use ebiv::grid::describe_passes;
pub use figures::series_histograms;

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

/// The settings of a configuration file (warnings printed), with the flags over them.
pub fn parse_settings(
    config: Option<&std::path::Path>,
    flags: &flags::SettingFlags,
) -> Result<ProcessSettings, ebiv::Error> {
    let mut settings = ProcessSettings::default();
    if let Some(path) = config {
        for warning in settings.apply_file(path)? {
            eprintln!("warning: {}: {warning}", path.display());
        }
    }
    flags.apply(&mut settings)?;
    Ok(settings)
}

pub fn run(args: &ProcessArgs) -> Result<(), ebiv::Error> {
    let settings = parse_settings(args.config.as_deref(), &args.settings)?;
    let run = settings.resolve()?;
    super::check_output_path(&run.output)?;
    ebiv::export::field_extension(&run.output)?;
    let options = args.input.read_options()?;
    // Ctrl-C stops the run after the field being evaluated: the field file is not written
    // (it is written whole at the end, or not at all), and every figure on disk is complete.
    let _catch = crate::interrupt::catch();
    match (run.method, &run.source) {
        (Method::Piv, Source::Images(_)) => piv::run_images(&run),
        _ => events::run(&run, &options),
    }
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
