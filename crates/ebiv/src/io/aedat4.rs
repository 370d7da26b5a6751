//! iniVation AEDAT 4.0 files written by DV and dv-processing (formats.md §9; iniVation docs
//! `software/software-advanced-usage/file-formats/aedat-4.0`; flatbuffer schemas `IOHeader`,
//! `EventPacket`, `TriggerPacket`, `FileDataTable` of dv-processing).
//!
//! Layout: the magic `#!AER-DAT4.0\r\n`, an `i32` length, the IOHeader flatbuffer
//! (`compression`, `dataTablePosition`, `infoNode` XML), then packets `i32 streamId, i32 size,
//! body` up to the data table. Each body is compressed as the IOHeader says (one LZ4 or ZSTD
//! frame) and holds a size-prefixed flatbuffer with a 4-character identifier. The reader
//! decodes the first `EVTS` stream into events and every `TRIG` stream into triggers, counts
//! and skips everything else, and streams packet by packet. The `FTAB` data table at the end
//! is read only when [`FormatReader::seek_near`] needs it.

mod codec;
mod flatbuf;
mod info;
mod lz4_block;
mod lz4_direct;
mod packets;
mod table;
#[cfg(test)]
mod test_writer;
#[cfg(test)]
mod tests;

use super::prophesee_header::read_up_to;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use codec::{Compression, DecodeError, Decompressor};
use flatbuf::FbError;
use info::StreamInfo;
use packets::{decode_events, decode_triggers};
use std::io::{Read, Seek, SeekFrom};
use table::{parse_table, TableEntry};

/// The version line every AEDAT 4.0 file starts with.
pub(crate) const MAGIC: &[u8; 14] = b"#!AER-DAT4.0\r\n";
/// Largest IOHeader accepted (real ones are a few KiB of XML).
const MAX_HEADER_BYTES: u64 = 16 << 20;
/// Largest compressed packet accepted; larger sizes are taken as corruption.
const MAX_PACKET_BYTES: u64 = 256 << 20;
/// Decompress one LZ4 block with the AEDAT 4.0 reader's block decoder, after `dictionary`
/// (the content before it, as in a linked frame), into at most `limit` bytes; `None` when the
/// block is invalid. For the fuzz target `fuzz/fuzz_targets/lz4_block.rs`, which compares it
/// with lz4_flex; not part of the library's interface.
#[doc(hidden)]
pub fn lz4_block_for_fuzzing(block: &[u8], dictionary: &[u8], limit: usize) -> Option<Vec<u8>> {
    let start = dictionary.len();
    let mut out = vec![0u8; start + limit + lz4_block::SLACK];
    out[..start].copy_from_slice(dictionary);
    let end = lz4_block::decompress(block, &mut out, 0, start, start + limit).ok()?;
    out.truncate(end);
    Some(out.split_off(start))
}

/// Largest decompressed packet body accepted.
const MAX_BODY_BYTES: usize = 512 << 20;
/// Skipped packets up to this size are read and dropped instead of seeked over, which keeps
/// the buffered source's buffer (IMU packets are small and frequent).
const SKIP_BY_READING: u64 = 1 << 16;

/// How a stream's packets are handled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StreamKind {
    /// The event stream that is decoded (the first `EVTS` stream).
    Events,
    /// A `TRIG` stream, decoded into triggers.
    Triggers,
    /// Frames, IMU samples, further event streams: skipped and counted.
    Other,
}

/// The `FTAB` data table, loaded on the first seek.
enum DataTable {
    NotLoaded,
    Loaded(Vec<TableEntry>),
    Unavailable,
}

/// Streaming AEDAT 4.0 reader.
struct Aedat4Reader {
    source: Box<dyn ReadSeek>,
    context: String,
    metadata: Metadata,
    report: DecodeReport,
    decompressor: Decompressor,
    /// Largest decompressed body accepted.
    body_cap: usize,
    kinds: Vec<(i32, StreamKind)>,
    warned_unknown: Vec<i32>,
    /// Exclusive upper bounds for x and y.
    limits: (u32, u32),
    /// Offset of the next packet; the source is kept positioned here.
    pos: u64,
    data_start: u64,
    /// End of the packet area: the data table, or the end of the file.
    data_end: u64,
    file_len: u64,
    /// Where the data table starts, when the header gives a usable position.
    table_position: Option<u64>,
    table: DataTable,
    skip_buf: Vec<u8>,
    batch_bytes: u64,
}

pub(crate) fn open(
    source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    Ok(Box::new(open_reader(
        source,
        context,
        options,
        MAX_BODY_BYTES,
    )?))
}

/// Read the header and position the reader at the first packet; bodies decompressing to more
/// than `body_cap` bytes are refused.
fn open_reader(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
    body_cap: usize,
) -> Result<Aedat4Reader> {
    let file_len = source.seek(SeekFrom::End(0))?;
    source.seek(SeekFrom::Start(0))?;
    let mut head = [0u8; 18];
    if read_up_to(&mut source, &mut head)? < head.len() || &head[..14] != MAGIC {
        return Err(Error::corrupt(
            &context,
            0,
            "not an AEDAT 4.0 file (expected `#!AER-DAT4.0\\r\\n` and a header length)",
        ));
    }
    let header_len = i32::from_le_bytes([head[14], head[15], head[16], head[17]]);
    if header_len < 0 || header_len as u64 > MAX_HEADER_BYTES || 18 + header_len as u64 > file_len {
        return Err(Error::corrupt(
            &context,
            14,
            format!(
                "IOHeader length {header_len} is negative, above 16 MiB or beyond the end of the {file_len}-byte file"
            ),
        ));
    }
    let mut header = vec![0u8; header_len as usize];
    source.read_exact(&mut header)?;
    let io_header = parse_io_header(&header).map_err(|e| {
        Error::corrupt(&context, 18, format!("IOHeader flatbuffer is invalid: {e}"))
    })?;
    let compression = Compression::from_code(io_header.compression).ok_or_else(|| {
        Error::unsupported(
            &context,
            format!(
                "unknown AEDAT 4.0 compression code {} (known: 0 none, 1 LZ4, 2 LZ4_HIGH, 3 ZSTD, 4 ZSTD_HIGH)",
                io_header.compression
            ),
        )
    })?;
    let streams = info::parse_streams(&io_header.info);
    if streams.is_empty() {
        return Err(Error::corrupt(
            &context,
            18,
            "the IOHeader info node describes no streams (no `outInfo/<id>` nodes)",
        ));
    }
    let data_start = 18 + header_len as u64;
    let mut report = DecodeReport::default();
    let mut metadata = Metadata::new(Format::Aedat4);
    metadata
        .header
        .push(("compression".into(), compression.name().into()));
    metadata.header.push((
        "dataTablePosition".into(),
        io_header.data_table_position.to_string(),
    ));
    let (data_end, table_position) = match io_header.data_table_position {
        p if p < 0 => {
            metadata.notes.push(
                "no data table (dataTablePosition = -1, e.g. an interrupted recording): seeking decodes from the start".into(),
            );
            (file_len, None)
        }
        p if (p as u64) < data_start => {
            report.warn(format!(
                "{context}: dataTablePosition {p} lies inside the header; ignored, packets are read to the end of the file"
            ));
            (file_len, None)
        }
        p if p as u64 > file_len => {
            report.warn(format!(
                "{context}: dataTablePosition {p} lies beyond the end of the {file_len}-byte file (truncated copy?); packets are read to the end of the file"
            ));
            (file_len, None)
        }
        p => (p as u64, Some(p as u64)),
    };
    let kinds = stream_kinds(&streams, &mut metadata);
    describe_streams(&streams, &mut metadata);
    let primary = streams.iter().find(|s| s.type_identifier == "EVTS");
    let file_geometry = primary.and_then(|s| match (s.size_x, s.size_y) {
        (Some(w), Some(h)) if w > 0 && h > 0 => Some(Geometry::new(w, h)),
        _ => None,
    });
    metadata.geometry = file_geometry.or(options.geometry);
    if let Some(source_name) = primary.and_then(|s| s.source.clone()) {
        metadata.serial = source_name
            .rsplit_once('_')
            .map(|(_, serial)| serial.to_string())
            .filter(|s| !s.is_empty());
        metadata.sensor = Some(source_name);
    }
    metadata.notes.push(
        "time stamps are Unix-epoch microseconds as written by DV (the streams' tsOffset is already included)".into(),
    );
    let limits = metadata.geometry.map_or((1 << 15, 1 << 15), |g| {
        (g.width.min(1 << 15), g.height.min(1 << 15))
    });
    Ok(Aedat4Reader {
        source,
        context,
        metadata,
        report,
        decompressor: Decompressor::new(compression, body_cap),
        body_cap,
        kinds,
        warned_unknown: Vec::new(),
        limits,
        pos: data_start,
        data_start,
        data_end,
        file_len,
        table_position,
        table: DataTable::NotLoaded,
        skip_buf: Vec::new(),
        batch_bytes: options.batch_bytes.max(1) as u64,
    })
}

/// The fields of the IOHeader table.
struct IoHeader {
    compression: i32,
    data_table_position: i64,
    info: String,
}

/// IOHeader: field 0 `compression` (i32 enum, default NONE), field 1 `dataTablePosition`
/// (i64, default −1), field 2 `infoNode` (string); file identifier `IOHE`, not size-prefixed.
fn parse_io_header(buf: &[u8]) -> std::result::Result<IoHeader, FbError> {
    let table = flatbuf::root_lenient(buf, b"IOHE")?;
    Ok(IoHeader {
        compression: table.i32(0, 0)?,
        data_table_position: table.i64(1, -1)?,
        info: table.string(2)?.unwrap_or_default().to_string(),
    })
}

/// Which streams are decoded: the first `EVTS` stream, every `TRIG` stream.
fn stream_kinds(streams: &[StreamInfo], metadata: &mut Metadata) -> Vec<(i32, StreamKind)> {
    let mut have_events = false;
    let mut kinds = Vec::with_capacity(streams.len());
    for s in streams {
        let kind = match s.type_identifier.as_str() {
            "EVTS" if !have_events => {
                have_events = true;
                StreamKind::Events
            }
            "EVTS" => {
                metadata.notes.push(format!(
                    "stream {} is a further event stream; only the first one is decoded, its packets are counted as skipped",
                    s.id
                ));
                StreamKind::Other
            }
            "TRIG" => StreamKind::Triggers,
            _ => StreamKind::Other,
        };
        kinds.push((s.id, kind));
    }
    if !have_events {
        metadata
            .notes
            .push("the file has no event (EVTS) stream".into());
    }
    kinds
}

/// One header entry per stream: `("stream 0", "EVTS 320x240 DVXplorer_DXB00010")`.
fn describe_streams(streams: &[StreamInfo], metadata: &mut Metadata) {
    for s in streams {
        let mut text = s.type_identifier.clone();
        if let (Some(w), Some(h)) = (s.size_x, s.size_y) {
            text.push_str(&format!(" {w}x{h}"));
        }
        if let Some(source) = &s.source {
            text.push(' ');
            text.push_str(source);
        }
        metadata.header.push((format!("stream {}", s.id), text));
        if let Some(offset) = s.ts_offset {
            metadata
                .header
                .push((format!("stream {} tsOffset", s.id), offset.to_string()));
        }
    }
}

impl Aedat4Reader {
    fn kind(&self, stream_id: i32) -> Option<StreamKind> {
        self.kinds
            .iter()
            .find(|(id, _)| *id == stream_id)
            .map(|&(_, k)| k)
    }

    /// Decode the packet at `self.pos`. Returns its size in bytes, or `None` at the end.
    fn next_packet(&mut self, out: &mut EventBuffer) -> Result<Option<u64>> {
        let start = self.pos;
        if start >= self.data_end {
            return Ok(None);
        }
        let left = self.data_end - start;
        if left < 8 {
            self.truncated(start, left, "a packet header");
            return Ok(None);
        }
        let mut head = [0u8; 8];
        if read_up_to(&mut self.source, &mut head)? < head.len() {
            self.truncated(start, left, "a packet header");
            return Ok(None);
        }
        let stream_id = i32::from_le_bytes([head[0], head[1], head[2], head[3]]);
        let size = i32::from_le_bytes([head[4], head[5], head[6], head[7]]);
        if size < 0 {
            return Err(Error::corrupt(
                &self.context,
                start + 4,
                format!("packet of stream {stream_id} has a negative size ({size})"),
            ));
        }
        let size = size as u64;
        if size > MAX_PACKET_BYTES {
            return Err(Error::corrupt(
                &self.context,
                start + 4,
                format!(
                    "packet of stream {stream_id} claims {size} bytes, above the 256 MiB limit"
                ),
            ));
        }
        if size > left - 8 {
            if self.table_position.is_some() {
                return Err(Error::corrupt(
                    &self.context,
                    start + 4,
                    format!(
                        "packet of stream {stream_id} claims {size} bytes but the packet area ends {} bytes later, at the data table (byte {})",
                        left - 8,
                        self.data_end
                    ),
                ));
            }
            self.truncated(start, left, &format!("a {size}-byte packet"));
            return Ok(None);
        }
        self.pos = start + 8 + size;
        match self.kind(stream_id) {
            Some(StreamKind::Events) => self.decode_body(start, stream_id, size, out, true)?,
            Some(StreamKind::Triggers) => self.decode_body(start, stream_id, size, out, false)?,
            Some(StreamKind::Other) => {
                self.skip(size)?;
                self.report.skipped_other += 1;
            }
            None => {
                self.skip(size)?;
                self.report.unknown_words += 1;
                if !self.warned_unknown.contains(&stream_id) && self.warned_unknown.len() < 16 {
                    self.warned_unknown.push(stream_id);
                    self.report.warn(format!(
                        "{}: packet at byte {start} belongs to stream {stream_id}, which the header does not describe; its packets are skipped",
                        self.context
                    ));
                }
            }
        }
        Ok(Some(8 + size))
    }

    /// Read, decompress and decode one packet body of an event or trigger stream.
    fn decode_body(
        &mut self,
        start: u64,
        stream_id: i32,
        size: u64,
        out: &mut EventBuffer,
        events: bool,
    ) -> Result<()> {
        let size = size as usize;
        let input = self.decompressor.input_buffer(size);
        if read_up_to(&mut self.source, input)? < size {
            self.truncated(start, self.data_end - start, "a packet body");
            return Ok(());
        }
        let (body, trailing) = match self.decompressor.decompress(size) {
            Ok(done) => done,
            Err(DecodeError::TooLarge(n)) => {
                return Err(Error::corrupt(
                    &self.context,
                    start + 8,
                    format!(
                        "packet body of stream {stream_id} decompresses to more than {} MiB ({n}+ bytes)",
                        self.body_cap >> 20
                    ),
                ))
            }
            Err(DecodeError::Invalid(message)) => {
                self.report.malformed += 1;
                self.report.warn(format!(
                    "{}: packet at byte {start} (stream {stream_id}) skipped: {message}",
                    self.context
                ));
                return Ok(());
            }
        };
        if trailing > 0 {
            self.report.warn(format!(
                "{}: packet at byte {start} (stream {stream_id}) has {trailing} bytes after its compressed frame; ignored",
                self.context
            ));
        }
        let decoded = if events {
            decode_events(body, self.limits, out, &mut self.report)
        } else {
            decode_triggers(body, out, &mut self.report)
        };
        if let Err(e) = decoded {
            self.report.malformed += 1;
            self.report.warn(format!(
                "{}: packet at byte {start} (stream {stream_id}, {}) skipped: invalid flatbuffer ({e}; identifier {})",
                self.context,
                if events { "EVTS" } else { "TRIG" },
                flatbuf::identifier_of(body)
            ));
        }
        Ok(())
    }

    /// Move past `size` bytes of a skipped packet body.
    fn skip(&mut self, size: u64) -> Result<()> {
        if size <= SKIP_BY_READING {
            let n = size as usize;
            if self.skip_buf.len() < n {
                self.skip_buf.resize(n, 0);
            }
            let got = read_up_to(&mut self.source, &mut self.skip_buf[..n])?;
            if got < n {
                self.source.seek(SeekFrom::Start(self.pos))?;
            }
        } else {
            self.source.seek(SeekFrom::Start(self.pos))?;
        }
        Ok(())
    }

    /// The file ends inside the packet starting at `start`: count and report the rest.
    fn truncated(&mut self, start: u64, left: u64, what: &str) {
        self.report.truncated_bytes += left;
        self.report.warn(format!(
            "{}: file ends inside {what} at byte {start} ({left} bytes left); the recording was probably interrupted, those bytes are ignored",
            self.context
        ));
        self.pos = self.data_end;
    }

    /// Read and check the data table. Entries of decoded streams are kept, in file order.
    fn load_table(&mut self) -> Result<DataTable> {
        let Some(position) = self.table_position else {
            return Ok(DataTable::Unavailable);
        };
        let size = self.file_len - position;
        if size == 0 || size > MAX_PACKET_BYTES {
            self.report.warn(format!(
                "{}: data table at byte {position} is {size} bytes long; not used for seeking",
                self.context
            ));
            return Ok(DataTable::Unavailable);
        }
        self.source.seek(SeekFrom::Start(position))?;
        let size = size as usize;
        let input = self.decompressor.input_buffer(size);
        let got = read_up_to(&mut self.source, input)?;
        self.source.seek(SeekFrom::Start(self.pos))?;
        if got < size {
            return Ok(DataTable::Unavailable);
        }
        let parsed = match self.decompressor.decompress(size) {
            Ok((body, _)) => parse_table(body, self.data_start, self.data_end, &self.kinds)
                .map_err(|e| e.to_string()),
            Err(DecodeError::Invalid(message)) => Err(message),
            Err(DecodeError::TooLarge(n)) => Err(format!("decompresses to {n}+ bytes")),
        };
        match parsed {
            Ok(entries) => Ok(DataTable::Loaded(entries)),
            Err(message) => {
                self.report.warn(format!(
                    "{}: data table at byte {position} is unusable ({message}); seeking decodes instead",
                    self.context
                ));
                Ok(DataTable::Unavailable)
            }
        }
    }
}

impl FormatReader for Aedat4Reader {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        let mut consumed = 0u64;
        let mut any = false;
        while consumed < self.batch_bytes {
            match self.next_packet(out)? {
                Some(n) => {
                    consumed += n;
                    any = true;
                }
                None => break,
            }
        }
        Ok(any || !out.is_empty() || !out.triggers.is_empty())
    }

    fn report(&self) -> &DecodeReport {
        &self.report
    }

    /// Jump to the first event or trigger packet whose last time stamp is at or after `t_us`,
    /// using the file's data table.
    fn seek_near(&mut self, t_us: i64) -> Result<bool> {
        if matches!(self.table, DataTable::NotLoaded) {
            self.table = self.load_table()?;
        }
        let DataTable::Loaded(entries) = &self.table else {
            return Ok(false);
        };
        let Some(entry) = entries
            .iter()
            .find(|e| e.t_end >= t_us)
            .or_else(|| entries.last())
            .copied()
        else {
            return Ok(false);
        };
        if entry.offset <= self.pos {
            return Ok(false);
        }
        self.source.seek(SeekFrom::Start(entry.offset))?;
        let mut head = [0u8; 8];
        let got = read_up_to(&mut self.source, &mut head)?;
        let matches = got == 8
            && i32::from_le_bytes([head[0], head[1], head[2], head[3]]) == entry.stream_id
            && i32::from_le_bytes([head[4], head[5], head[6], head[7]]) == entry.size;
        if matches {
            self.source.seek(SeekFrom::Start(entry.offset))?;
            self.pos = entry.offset;
            return Ok(true);
        }
        self.source.seek(SeekFrom::Start(self.pos))?;
        self.report.warn(format!(
            "{}: the data table points at byte {} but no matching packet header is there; seeking decodes instead",
            self.context, entry.offset
        ));
        self.table = DataTable::Unavailable;
        Ok(false)
    }

    fn position(&self) -> Option<u64> {
        Some(self.pos)
    }
}
