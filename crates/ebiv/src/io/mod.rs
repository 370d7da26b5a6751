//! Reading and writing event-camera files.
//!
//! [`open`] detects the format from the file's content (the extension only breaks ties) and
//! returns a streaming [`EventReader`]; [`read_all`] decodes a whole (small) file. Writers live
//! in [`write`]. Format facts follow `docs/formats.md` of the project's shared notes.

mod aedat2;
mod aedat31;
mod aedat4;
mod bytestream;
mod dat;
mod denoise;
mod detect;
mod ebiv_evt;
pub mod ecf;
mod es;
mod evt2;
mod evt21;
mod evt3;
pub mod field;
mod hdf5;
pub mod index;
mod memory;
mod npy;
mod npz;
mod options;
mod prophesee_header;
mod raw;
mod reader;
mod report;
mod sink;
mod source;
mod text;
mod time32;
pub mod write;

#[doc(hidden)]
pub use aedat4::lz4_block_for_fuzzing;
pub use detect::{detect_format, Format};
pub use memory::open_events;
pub use options::{parse_geometry, READ_OPTIONS};
pub use prophesee_header::{Evt21Order, PropheseeHeader, RawEncoding};
pub use reader::{EventReader, Recording};
pub use report::DecodeReport;
pub use source::EventSource;
pub use text::{PolarityEncoding, TextColumn, TextOptions, TimeUnit};

use crate::error::{Error, Result};
use crate::event::Geometry;
use std::io::{Read, Seek};
use std::path::Path;

/// A byte source a reader can also seek in (a file, or bytes in memory for tests and fuzzing).
pub trait ReadSeek: Read + Seek + Send {}
impl<T: Read + Seek + Send> ReadSeek for T {}

/// What a reader needs to know beyond the file itself. The defaults suit almost every file.
#[derive(Debug, Clone)]
pub struct ReadOptions {
    /// Sensor size to use when the file does not state it (old RAW headers, DAT, text).
    pub geometry: Option<Geometry>,
    /// RAW encoding to use when the header does not state it (header-less dumps).
    pub raw_encoding: Option<RawEncoding>,
    /// Subtract the Metavision SDK's time shift (first time base) from every time stamp, so
    /// that times match what Metavision tools print. Off by default: ebiv keeps camera time.
    pub metavision_time_shift: bool,
    /// Roughly how many bytes of the file to decode per batch; bounds batch memory.
    pub batch_bytes: usize,
    /// Column layout and units of text files.
    pub text: TextOptions,
    /// Force a format instead of detecting it.
    pub format: Option<Format>,
    /// Filters that remove noise events as they are read ([`crate::denoise`]); applied by
    /// [`open`] and [`EventSource::open`], not by the lower-level openers.
    pub denoise: Option<crate::denoise::DenoiseSettings>,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            geometry: None,
            raw_encoding: None,
            metavision_time_shift: false,
            batch_bytes: 1 << 20,
            text: TextOptions::default(),
            format: None,
            denoise: None,
        }
    }
}

impl ReadOptions {
    /// The same options without denoising: what planning reads (the first event, the span
    /// and the size of a recording are the recording's, not the filters').
    pub fn without_denoise(&self) -> ReadOptions {
        ReadOptions {
            denoise: None,
            ..self.clone()
        }
    }
}

/// Everything a reader knows about a recording besides its events.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Metadata {
    /// The file format.
    pub format: Format,
    /// Sensor size, when known from the file or the options.
    pub geometry: Option<Geometry>,
    /// Header key/value pairs in file order, exactly as stored.
    pub header: Vec<(String, String)>,
    /// Camera or sensor name when the file says it.
    pub sensor: Option<String>,
    /// Camera serial number when the file says it.
    pub serial: Option<String>,
    /// Microseconds subtracted from every time stamp by the reader (0 = camera time).
    pub time_shift_us: i64,
    /// Facts about the file a user should know (e.g. "time already shifted by the writer").
    pub notes: Vec<String>,
}

impl Metadata {
    /// Metadata of `format` with nothing else known.
    pub fn new(format: Format) -> Self {
        Metadata {
            format,
            geometry: None,
            header: Vec::new(),
            sensor: None,
            serial: None,
            time_shift_us: 0,
            notes: Vec::new(),
        }
    }

    /// The value of the first header entry named `key`.
    pub fn header_value(&self, key: &str) -> Option<&str> {
        self.header
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

/// One format's decoder behind [`EventReader`]: it fills batches in file order and counts
/// what it could not decode.
pub(crate) trait FormatReader: Send {
    /// What the file says about itself.
    fn metadata(&self) -> &Metadata;
    /// Decode the next stretch of the file into `out` (already cleared). Returns `false` at
    /// the end of the file, when `out` holds nothing more.
    fn next_batch(&mut self, out: &mut crate::EventBuffer) -> Result<bool>;
    /// Counters of what was dropped or skipped so far.
    fn report(&self) -> &DecodeReport;
    /// The Metavision SDK time shift for this file once known (RAW only).
    fn metavision_time_shift(&self) -> Option<i64> {
        None
    }
    /// Jump close to (never past) the first event at or after `t_us` without decoding what
    /// lies before, when the format has an index. Returns whether it jumped.
    fn seek_near(&mut self, _t_us: i64) -> Result<bool> {
        Ok(false)
    }
    /// Bytes of the file consumed so far, for progress bars, where the reader knows it.
    fn position(&self) -> Option<u64> {
        None
    }
    /// Where decoding could resume now, with the decoder's state: a point of the
    /// recording's index ([`index`]). `None` for formats that do not support it.
    fn resume_point(&self) -> Option<ResumePoint> {
        None
    }
    /// Continue decoding at `point`, recorded by [`FormatReader::resume_point`] from the
    /// same file.
    fn resume(&mut self, _point: &ResumePoint) -> Result<()> {
        Err(Error::Unsupported {
            context: self.metadata().format.name().into(),
            message: "this format cannot resume at an index point".into(),
        })
    }
}

/// A place in a file where decoding can resume: the byte offset of a word boundary and the
/// state the decoder carries there.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ResumePoint {
    /// Byte offset in the file.
    pub offset: u64,
    /// The decoder's state (format-specific numbers).
    pub state: Vec<i64>,
}

/// Open the event file at `path` for streaming; seeking uses the recording's index where one
/// is stored ([`index`]). With `options.denoise`, the reader hands out the events its
/// filters keep ([`EventReader::denoise_report`] counts what they removed).
pub fn open(path: impl AsRef<Path>, options: &ReadOptions) -> Result<EventReader> {
    let path = path.as_ref();
    let mut reader = open_without_index(path, options)?;
    if reader.inner().resume_point().is_some() {
        let m = reader.metadata();
        reader.index = index::load_index(path, m.format.name(), m.geometry).map(Into::into);
    }
    if let Some(settings) = &options.denoise {
        let raw = options.without_denoise();
        denoise::attach(&mut reader, settings, || open_without_index(path, &raw))?;
    }
    Ok(reader)
}

/// [`open`] without looking for an index.
fn open_without_index(path: &Path, options: &ReadOptions) -> Result<EventReader> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    open_source(
        Box::new(std::io::BufReader::with_capacity(1 << 16, file)),
        &path.display().to_string(),
        ext.as_deref(),
        options,
    )
    .map_err(|e| match e {
        Error::Stream(source) => Error::io(path, source),
        other => other,
    })
}

/// Decode the whole event file at `path` into memory.
pub fn read_all(path: impl AsRef<Path>, options: &ReadOptions) -> Result<Recording> {
    open(path, options)?.read_all()
}

/// Open an event stream held in memory (benchmarks, fuzzing, data received over a network).
/// `name` is used in messages and its extension breaks ties in format detection.
pub fn open_memory(
    bytes: std::sync::Arc<[u8]>,
    name: &str,
    options: &ReadOptions,
) -> Result<EventReader> {
    let ext = Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    open_source(
        Box::new(std::io::Cursor::new(bytes)),
        name,
        ext.as_deref(),
        options,
    )
}

/// Open an event stream from any seekable source. `context` names it in messages and
/// `extension` (lower case, no dot) breaks ties in format detection.
pub fn open_source(
    mut source: Box<dyn ReadSeek>,
    context: &str,
    extension: Option<&str>,
    options: &ReadOptions,
) -> Result<EventReader> {
    let format = match options.format {
        Some(f) => f,
        None => detect::detect_source(&mut *source, context, extension)?,
    };
    let ctx = context.to_string();
    let inner: Box<dyn FormatReader> = match format {
        Format::Raw => raw::open(source, ctx, None, options)?,
        Format::Evt2 | Format::Evt21 | Format::Evt3 => {
            raw::open(source, ctx, RawEncoding::of_format(format), options)?
        }
        Format::Dat => dat::open(source, ctx, options)?,
        Format::Aedat4 => aedat4::open(source, ctx, options)?,
        Format::Aedat2 => aedat2::open(source, ctx, options)?,
        Format::Aedat31 => aedat31::open(source, ctx, options)?,
        Format::EventStream => es::open(source, ctx, options)?,
        Format::Text => text::open(source, ctx, options)?,
        Format::Npy => npy::open(source, ctx, options)?,
        Format::Npz => npz::open(source, ctx, options)?,
        Format::EbivEvt => ebiv_evt::open(source, ctx, options)?,
        Format::Hdf5 => hdf5::open(source, ctx, options)?,
        Format::Memory => {
            return Err(Error::parameter(
                "format",
                format!(
                "{ctx}: events in memory are opened with `io::open_events`, not read from bytes"
            ),
            ))
        }
    };
    Ok(EventReader::new(inner, options.metavision_time_shift))
}
