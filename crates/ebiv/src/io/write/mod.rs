//! Event file writers: Prophesee RAW (EVT 3.0, 2.0, 2.1), iniVation AEDAT 4.0 (LZ4, ZSTD or
//! uncompressed), CSV, NumPy `.npy` and `.npz`.
//!
//! Every writer streams: batches go to a temporary file next to the target, which is renamed
//! into place by [`EventWriter::finish`], so an interrupted run never leaves a half-written
//! file under the requested name.

pub(crate) mod aedat4;
mod csv;
mod evt2;
mod evt3;
mod numpy;

pub use aedat4::{Aedat4Compression, Aedat4Writer};
pub use evt2::{Evt2Variant, Evt2Writer};
pub use evt3::Evt3Writer;

use super::Format;
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// A streaming event writer. Call [`EventWriter::write`] with batches in order, then
/// [`EventWriter::finish`]; dropping a writer without finishing leaves no output file.
pub trait EventWriter {
    /// Append a batch of events (and its triggers, where the format stores them).
    fn write(&mut self, events: &EventBuffer) -> Result<()>;
    /// Complete the file and move it into place.
    fn finish(self: Box<Self>) -> Result<()>;
}

/// Formats ebiv writes, chosen from the output file's extension.
pub fn format_for_path(path: &Path) -> Result<Format> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "raw" => Ok(Format::Evt3),
        "aedat4" => Ok(Format::Aedat4),
        "csv" | "txt" => Ok(Format::Text),
        "npy" => Ok(Format::Npy),
        "npz" => Ok(Format::Npz),
        _ => Err(Error::parameter(
            "output",
            format!(
                "cannot tell the output format from `{}`; use .raw (EVT 3.0), .aedat4 (AEDAT 4.0), .csv, .npy or .npz",
                path.display()
            ),
        )),
    }
}

/// Create a writer for `path` in `format` (see [`format_for_path`]; `.raw` means EVT 3.0,
/// and [`Format::Evt2`]/[`Format::Evt21`] select the other RAW encodings; AEDAT 4.0 is written
/// with LZ4, use [`Aedat4Writer::create`] for another compression). `geometry` is stored where
/// the format has a place for it (in CSV as a `# geometry: WxH` comment) and is required by
/// EVT 2.x, EVT 3.0 and AEDAT 4.0. The
/// writer may be moved to another thread (`ebiv simulate` writes beside the simulation).
pub fn create(
    path: &Path,
    format: Format,
    geometry: Option<Geometry>,
) -> Result<Box<dyn EventWriter + Send>> {
    match format {
        Format::Evt3 => Ok(Box::new(Evt3Writer::create(path, geometry)?)),
        Format::Evt2 => Ok(Box::new(Evt2Writer::create(
            path,
            geometry,
            Evt2Variant::Evt2,
        )?)),
        Format::Evt21 => Ok(Box::new(Evt2Writer::create(
            path,
            geometry,
            Evt2Variant::Evt21(crate::io::Evt21Order::Little),
        )?)),
        Format::Aedat4 => Ok(Box::new(Aedat4Writer::create(
            path,
            geometry,
            Aedat4Compression::Lz4,
        )?)),
        Format::Text => Ok(Box::new(csv::CsvWriter::create(path, geometry)?)),
        Format::Npy => Ok(Box::new(numpy::NpyWriter::create(path)?)),
        Format::Npz => Ok(Box::new(numpy::NpzWriter::create(path)?)),
        other => Err(Error::parameter(
            "output",
            format!("ebiv does not write {other}; use .raw (EVT 3.0), .aedat4 (AEDAT 4.0), .csv, .npy or .npz"),
        )),
    }
}

/// A file written under a temporary name and renamed into place when complete.
pub(crate) struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Start writing `target` (through `target.partial`).
    pub fn create(target: &Path) -> Result<Self> {
        let mut name = target.file_name().unwrap_or_default().to_os_string();
        name.push(".partial");
        let temp = target.with_file_name(name);
        let file = File::create(&temp).map_err(|e| Error::io(target, e))?;
        Ok(AtomicFile {
            target: target.to_path_buf(),
            temp,
            writer: Some(BufWriter::with_capacity(1 << 20, file)),
        })
    }

    /// The buffered writer.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        self.writer.as_mut().expect("writer present until commit")
    }

    /// Map an I/O error to one naming the target file.
    pub fn err(&self, e: std::io::Error) -> Error {
        Error::io(&self.target, e)
    }

    /// Flush, sync and rename into place.
    pub fn commit(mut self) -> Result<()> {
        let writer = self.writer.take().expect("commit once");
        let file = writer
            .into_inner()
            .map_err(|e| Error::io(&self.target, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(&self.target, e))?;
        drop(file);
        std::fs::rename(&self.temp, &self.target).map_err(|e| Error::io(&self.target, e))
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}
