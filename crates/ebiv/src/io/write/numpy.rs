//! NumPy writers (formats.md §12).
//!
//! * [`NpyWriter`]: one structured array `[('t', '<i8'), ('x', '<u2'), ('y', '<u2'),
//!   ('p', '|u1')]`, packed 13-byte records (the expelliarmus layout). The header is written
//!   first with room for any count and patched with the final shape by `finish`.
//! * [`NpzWriter`]: an uncompressed `.npz` with the columns `t` (`<i8` µs), `x`, `y` (`<u2`)
//!   and `p` (`|u1`) as separate `.npy` members, the layout the EBIV community exchanges
//!   event slices in. Each column streams to a temporary file beside the target while
//!   writing; `finish` assembles the archive, so memory never holds the recording.
//!
//! Both load with `numpy.load` and read back exactly with ebiv. Triggers are not stored.

use super::{AtomicFile, EventWriter};
use crate::error::{Error, Result};
use crate::event::EventBuffer;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Bytes collected before they are handed to the file.
const FLUSH_BYTES: usize = 1 << 20;

/// A version 1.0 `.npy` header for `descr` and `count` elements, padded with spaces (and a
/// final newline) to `total` bytes, or to the next multiple of 64 when `total` is `None`.
pub(crate) fn npy_header(descr: &str, count: u64, total: Option<usize>) -> Vec<u8> {
    let dict = format!("{{'descr': {descr}, 'fortran_order': False, 'shape': ({count},), }}");
    let unpadded = 10 + dict.len() + 1;
    let total = total.unwrap_or(unpadded.div_ceil(64) * 64);
    let header_len = total - 10;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.resize(total - 1, b' ');
    out.push(b'\n');
    out
}

/// Size of a header that fits any count, so the real one can be patched in place.
fn reserved_header_len(descr: &str) -> usize {
    npy_header(descr, u64::MAX, None).len()
}

const RECORD_DESCR: &str = "[('t', '<i8'), ('x', '<u2'), ('y', '<u2'), ('p', '|u1')]";

/// Streaming `.npy` writer of packed 13-byte event records.
pub(crate) struct NpyWriter {
    file: AtomicFile,
    count: u64,
    header_len: usize,
    buf: Vec<u8>,
}

impl NpyWriter {
    /// Start writing `path` (through a temporary file renamed by `finish`).
    pub fn create(path: &Path) -> Result<Self> {
        let mut file = AtomicFile::create(path)?;
        let header_len = reserved_header_len(RECORD_DESCR);
        let header = npy_header(RECORD_DESCR, 0, Some(header_len));
        let io = file.writer().write_all(&header);
        io.map_err(|e| file.err(e))?;
        Ok(NpyWriter {
            file,
            count: 0,
            header_len,
            buf: Vec::with_capacity(FLUSH_BYTES + 13),
        })
    }

    fn flush_buf(&mut self) -> Result<()> {
        let io = self.file.writer().write_all(&self.buf);
        io.map_err(|e| self.file.err(e))?;
        self.buf.clear();
        Ok(())
    }
}

impl EventWriter for NpyWriter {
    fn write(&mut self, events: &EventBuffer) -> Result<()> {
        let columns = events.t.iter().zip(&events.x).zip(&events.y).zip(&events.p);
        for (((&t, &x), &y), &p) in columns {
            self.buf.extend_from_slice(&t.to_le_bytes());
            self.buf.extend_from_slice(&x.to_le_bytes());
            self.buf.extend_from_slice(&y.to_le_bytes());
            self.buf.push((p != 0) as u8);
            if self.buf.len() >= FLUSH_BYTES {
                self.flush_buf()?;
            }
        }
        self.count += events.len() as u64;
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        self.flush_buf()?;
        let header = npy_header(RECORD_DESCR, self.count, Some(self.header_len));
        let w = self.file.writer();
        let io = w
            .seek(SeekFrom::Start(0))
            .and_then(|_| w.write_all(&header));
        io.map_err(|e| self.file.err(e))?;
        self.file.commit()
    }
}

/// One column of an [`NpzWriter`], streamed to a temporary file.
struct Column {
    name: &'static str,
    descr: &'static str,
    path: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl Drop for Column {
    fn drop(&mut self) {
        self.writer.take();
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Streaming `.npz` writer of the columns t, x, y, p.
pub(crate) struct NpzWriter {
    target: PathBuf,
    columns: [Column; 4],
    count: u64,
}

impl NpzWriter {
    /// Start writing `path`; the columns go to `<path>.<column>.partial` until `finish`.
    pub fn create(path: &Path) -> Result<Self> {
        let base = path.file_name().unwrap_or_default().to_os_string();
        let column = |name: &'static str, descr: &'static str| -> Result<Column> {
            let mut file_name = base.clone();
            file_name.push(format!(".{name}.partial"));
            let col_path = path.with_file_name(file_name);
            let file = File::create(&col_path).map_err(|e| Error::io(&col_path, e))?;
            Ok(Column {
                name,
                descr,
                path: col_path,
                writer: Some(BufWriter::with_capacity(1 << 18, file)),
            })
        };
        Ok(NpzWriter {
            target: path.to_path_buf(),
            columns: [
                column("t", "'<i8'")?,
                column("x", "'<u2'")?,
                column("y", "'<u2'")?,
                column("p", "'|u1'")?,
            ],
            count: 0,
        })
    }
}

fn zip_error(path: &Path, e: zip::result::ZipError) -> Error {
    match e {
        zip::result::ZipError::Io(io) => Error::io(path, io),
        other => Error::Write {
            what: path.display().to_string(),
            message: other.to_string(),
        },
    }
}

impl EventWriter for NpzWriter {
    fn write(&mut self, events: &EventBuffer) -> Result<()> {
        let [t, x, y, p] = &mut self.columns;
        let io = (|| -> std::io::Result<()> {
            let (Some(tw), Some(xw), Some(yw), Some(pw)) = (
                t.writer.as_mut(),
                x.writer.as_mut(),
                y.writer.as_mut(),
                p.writer.as_mut(),
            ) else {
                return Err(std::io::Error::other("column file already closed"));
            };
            for &v in &events.t {
                tw.write_all(&v.to_le_bytes())?;
            }
            for &v in &events.x {
                xw.write_all(&v.to_le_bytes())?;
            }
            for &v in &events.y {
                yw.write_all(&v.to_le_bytes())?;
            }
            for &v in &events.p {
                pw.write_all(&[(v != 0) as u8])?;
            }
            Ok(())
        })();
        io.map_err(|e| Error::io(&self.target, e))?;
        self.count += events.len() as u64;
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        use zip::write::SimpleFileOptions;
        for column in &mut self.columns {
            if let Some(w) = column.writer.take() {
                w.into_inner()
                    .map_err(|e| Error::io(&column.path, e.into_error()))?
                    .sync_all()
                    .map_err(|e| Error::io(&column.path, e))?;
            }
        }
        let mut file = AtomicFile::create(&self.target)?;
        let target = self.target.clone();
        {
            let mut zip = zip::ZipWriter::new(file.writer());
            for column in &self.columns {
                let header = npy_header(column.descr, self.count, None);
                let mut data = File::open(&column.path).map_err(|e| Error::io(&column.path, e))?;
                let size = header.len() as u64 + data.metadata().map_or(0, |m| m.len());
                let options = SimpleFileOptions::default()
                    .compression_method(zip::CompressionMethod::Stored)
                    .large_file(size >= u32::MAX as u64);
                zip.start_file(format!("{}.npy", column.name), options)
                    .map_err(|e| zip_error(&target, e))?;
                zip.write_all(&header).map_err(|e| Error::io(&target, e))?;
                std::io::copy(&mut data, &mut zip).map_err(|e| Error::io(&target, e))?;
            }
            zip.finish().map_err(|e| zip_error(&target, e))?;
        }
        file.commit()
    }
}

#[cfg(test)]
mod tests;
