//! `ebiv index`: build and store the index of recordings, so that reading from a time in the
//! middle of a RAW file (`process --time`, Python's `Recording.read`, `ebiv.dask` shards)
//! starts close to it instead of decoding everything before.

use crate::input::InputArgs;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

/// Build the index of event recordings (RAW EVT 2.0, 2.1 and 3.0): points where decoding
/// can resume, with the decoder's state there. It is written beside the recording as
/// REC.ebividx, or where that folder is not writable into $EBIV_INDEX_DIR (default
/// ~/.cache/ebiv/index). Every command uses it while the file's size and modification time
/// match; `ebiv.dask` builds it itself when missing.
#[derive(Debug, Args)]
pub struct IndexArgs {
    /// The recordings.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Rebuild indexes that exist and still match.
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

pub fn run(args: &IndexArgs) -> Result<(), ebiv::Error> {
    let options = args.input.read_options()?;
    for path in &args.files {
        let started = Instant::now();
        let ensured = ebiv::io::index::ensure_index(path, &options, args.force)?;
        if !ensured.built {
            println!("{}: index up to date", path.display());
            continue;
        }
        let index = &ensured.index;
        let seconds = started.elapsed().as_secs_f64();
        println!(
            "{}: {} points over {:.1} MB, {} events, built in {seconds:.2} s ({:.0} M events/s); wrote {}",
            path.display(),
            index.points.len(),
            index.file_size as f64 / 1e6,
            index.events,
            index.events as f64 / seconds / 1e6,
            ensured.file.display()
        );
    }
    Ok(())
}
