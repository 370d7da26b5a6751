//! `ebiv filter`: a recording rewritten without its noise events.

use super::process::flags::DenoiseFlags;
use crate::input::InputArgs;
use clap::Args;
use ebiv::io::RawEncoding;
use ebiv::PolaritySelection;
use std::path::PathBuf;

/// Write the recording without the events the denoising filters remove (docs/denoise.md):
/// hot pixels, events within a pixel's refractory period, and events without a recent
/// neighbour (background activity), and print how many each filter removed. The output
/// format follows OUT's extension, as for `ebiv convert`: .raw (EVT 3.0, or
/// --output-encoding), .aedat4, .csv, .npy or .npz.
#[derive(Debug, Args)]
pub struct FilterArgs {
    /// The recording to read.
    pub input: PathBuf,
    /// The file to write (.raw, .aedat4, .csv, .npy, .npz).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// RAW output encoding: evt3 (default), evt2 or evt21 (little-endian words).
    #[arg(long, value_name = "ENC", default_value = "evt3", value_parser = super::convert::parse_raw_encoding)]
    pub output_encoding: RawEncoding,
    #[command(flatten)]
    pub denoise: DenoiseFlags,
    #[command(flatten)]
    pub input_args: InputArgs,
}

pub fn run(args: &FilterArgs) -> Result<(), ebiv::Error> {
    let mut options = args.input_args.read_options()?;
    options.denoise = args.denoise.settings()?;
    if options.denoise.is_none() {
        return Err(ebiv::Error::parameter(
            "denoise",
            "no filter chosen; give --denoise hot-pixels,refractory,correlation (any of them) or --denoise all",
        ));
    }
    super::convert::rewrite(&super::convert::Rewrite {
        input: &args.input,
        output: &args.output,
        options: &options,
        time_range: (None, None),
        absolute_time: false,
        roi: None,
        polarity: PolaritySelection::Both,
        output_encoding: args.output_encoding,
    })
}
