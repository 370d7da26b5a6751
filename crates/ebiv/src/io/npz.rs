//! NumPy `.npz` archives of events (formats.md §12): a zip of `.npy` members, either
//! * one array per column — members named t, x, y, p or their aliases (ts, timestamp, time;
//!   pol, polarity, on), case-insensitive, with or without the `.npy` suffix — each 1-D of any
//!   integer, bool or float type (the EBIV slices: `x`, `y` `<u2`, `p` `<i2`, `t` `<i8` µs), or
//! * one structured array member (e.g. `events.npy`) read exactly like an `.npy` file.
//!
//! Members may be stored or deflate-compressed; both are **streamed** member by member in
//! batches (the columns are read side by side through one shared file handle), so memory
//! holds a batch, not the recording. Value conversion is the `.npy` reader's: integer time
//! in µs, float time in seconds, polarity ON when > 0, unless the text time unit is set.

use super::npy::{
    checked_count, count_outcome, event_layout, gather, npy_metadata, read_header, Converter,
    Dtype, NpyHeader, Outcome, RecordReader, Role, Scalar, TimeConv, ALIASES,
};
use super::prophesee_header::read_up_to;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::EventBuffer;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::sync::{Arc, Mutex};
use zip::CompressionMethod;

/// Members looked at; an event archive has a handful.
const MAX_MEMBERS: usize = 10_000;
/// Buffer between the archive and a member's decompressor.
const MEMBER_BUFFER: usize = 1 << 18;

type SharedSource = Arc<Mutex<Box<dyn ReadSeek>>>;

/// The bytes `pos..end` of the shared archive, read by seeking before every read so that
/// several members can be streamed side by side.
struct Window {
    source: SharedSource,
    pos: u64,
    end: u64,
}

impl Read for Window {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let left = self.end.saturating_sub(self.pos);
        let n = (buf.len() as u64).min(left) as usize;
        if n == 0 {
            return Ok(0);
        }
        let mut source = self
            .source
            .lock()
            .map_err(|_| std::io::Error::other("archive handle poisoned by an earlier panic"))?;
        source.seek(SeekFrom::Start(self.pos))?;
        let got = source.read(&mut buf[..n])?;
        self.pos += got as u64;
        Ok(got)
    }
}

/// A member of the archive.
#[derive(Debug, Clone)]
struct Member {
    name: String,
    /// File name without directories and `.npy`.
    stem: String,
    compression: CompressionMethod,
    data_start: u64,
    compressed_size: u64,
    size: u64,
}

impl Member {
    /// A reader of the member's uncompressed bytes.
    fn open(&self, source: &SharedSource, context: &str) -> Result<Box<dyn Read + Send>> {
        let window = Window {
            source: Arc::clone(source),
            pos: self.data_start,
            end: self.data_start.saturating_add(self.compressed_size),
        };
        let buffered = BufReader::with_capacity(MEMBER_BUFFER, window);
        match self.compression {
            CompressionMethod::Stored => Ok(Box::new(buffered)),
            CompressionMethod::Deflated => {
                Ok(Box::new(flate2::bufread::DeflateDecoder::new(buffered)))
            }
            other => Err(Error::unsupported(
                context,
                format!(
                    "member `{}` uses zip compression {other}; ebiv reads stored and deflate members (numpy.savez / savez_compressed)",
                    self.name
                ),
            )),
        }
    }

    /// Uncompressed bytes after a header of `header_bytes`.
    fn available(&self, header_bytes: u64) -> u64 {
        let size = match self.compression {
            CompressionMethod::Stored => self.compressed_size,
            _ => self.size,
        };
        size.saturating_sub(header_bytes)
    }
}

fn zip_error(context: &str, e: zip::result::ZipError) -> Error {
    match e {
        zip::result::ZipError::Io(io) => Error::Stream(io),
        other => Error::corrupt(
            context,
            0,
            format!("not a readable .npz (zip) archive: {other}"),
        ),
    }
}

fn list_members(source: Box<dyn ReadSeek>, context: &str) -> Result<(Vec<Member>, SharedSource)> {
    let mut archive = zip::ZipArchive::new(source).map_err(|e| zip_error(context, e))?;
    let mut members = Vec::new();
    for i in 0..archive.len().min(MAX_MEMBERS) {
        let f = archive.by_index_raw(i).map_err(|e| zip_error(context, e))?;
        if f.is_dir() || f.encrypted() {
            continue;
        }
        let name = f.name().to_string();
        let base = name.rsplit('/').next().unwrap_or(&name);
        let stem = match base.len().checked_sub(4) {
            Some(cut) if base.is_char_boundary(cut) && base[cut..].eq_ignore_ascii_case(".npy") => {
                &base[..cut]
            }
            _ => base,
        };
        members.push(Member {
            stem: stem.to_string(),
            compression: f.compression(),
            data_start: f.data_start(),
            compressed_size: f.compressed_size(),
            size: f.size(),
            name,
        });
    }
    Ok((members, Arc::new(Mutex::new(archive.into_inner()))))
}

pub(crate) fn open(
    source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let (members, shared) = list_members(source, &context)?;
    let names: Vec<&str> = members.iter().map(|m| m.name.as_str()).collect();
    let member_list = names.join(", ");

    let mut columns: [Option<&Member>; 4] = [None; 4];
    for m in &members {
        if let Some(role) = Role::of_name(&m.stem) {
            columns[role as usize].get_or_insert(m);
        }
    }
    if let [Some(t), Some(x), Some(y), Some(p)] = columns {
        return open_columns([t, x, y, p], &shared, context, &member_list, options);
    }
    // One structured array holding all four fields.
    let mut reasons = Vec::new();
    for m in &members {
        let mut reader = match m.open(&shared, &context) {
            Ok(r) => r,
            Err(e) => {
                reasons.push(e.to_string());
                continue;
            }
        };
        let header = match read_header(&mut reader, &format!("{context}: {}", m.name)) {
            Ok(h) => h,
            Err(e) => {
                reasons.push(format!("`{}`: {e}", m.name));
                continue;
            }
        };
        if !matches!(header.dtype, Dtype::Record { .. }) {
            continue;
        }
        let member_context = format!("{context}: {}", m.name);
        let (layout, conv) = match event_layout(&header, &member_context, options) {
            Ok(l) => l,
            Err(e) => {
                reasons.push(e.to_string());
                continue;
            }
        };
        let mut report = DecodeReport::default();
        let available = m.available(header.data_offset);
        let count = checked_count(
            layout.declared_records(&header),
            layout.itemsize,
            available,
            &member_context,
            &mut report,
        );
        let mut metadata = npy_metadata(Format::Npz, &header, &layout, &conv, options);
        metadata
            .header
            .insert(0, ("members".into(), member_list.clone()));
        metadata
            .notes
            .insert(0, format!("events from the structured member `{}`", m.name));
        return Ok(Box::new(
            RecordReader::new(
                reader,
                layout,
                Converter::new(conv, options.geometry),
                count,
                header.data_offset,
                options.batch_bytes,
            )
            .described(metadata, report, member_context),
        ));
    }
    let missing: Vec<&str> = Role::ALL
        .iter()
        .zip(columns)
        .filter(|(_, c)| c.is_none())
        .map(|(r, _)| r.name())
        .collect();
    Err(Error::unsupported(
        &context,
        format!(
            "the archive holds [{member_list}]: no column array for {} and no structured array with all fields; ebiv needs arrays or fields named {ALIASES}{}",
            missing.join(", "),
            if reasons.is_empty() {
                String::new()
            } else {
                format!(" ({})", reasons.join("; "))
            }
        ),
    ))
}

/// One column: its member's stream and element type.
struct Column {
    reader: Box<dyn Read + Send>,
    scalar: Scalar,
    buf: Vec<u8>,
    /// Raw values of the current batch.
    raw: Vec<u64>,
}

fn open_columns(
    members: [&Member; 4],
    shared: &SharedSource,
    context: String,
    member_list: &str,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let mut report = DecodeReport::default();
    let mut metadata = Metadata::new(Format::Npz);
    metadata.geometry = options.geometry;
    metadata
        .header
        .push(("members".into(), member_list.to_string()));
    let mut declared: Vec<(String, Option<u64>)> = Vec::new();
    let mut count = u64::MAX;
    let mut opened = Vec::with_capacity(4);
    let mut described = Vec::new();
    for (role, m) in Role::ALL.iter().zip(members) {
        let member_context = format!("{context}: {}", m.name);
        let mut reader = m.open(shared, &context)?;
        let header: NpyHeader = read_header(&mut reader, &member_context)?;
        let Dtype::Scalar(scalar) = header.dtype else {
            return Err(Error::unsupported(
                &member_context,
                format!(
                    "the {} column must be a plain numeric array, not {}",
                    role.name(),
                    header.text
                ),
            ));
        };
        if header.shape.iter().filter(|&&d| d > 1).count() > 1 {
            return Err(Error::unsupported(
                &member_context,
                format!(
                    "the {} column has shape {:?}; a 1-D array is needed",
                    role.name(),
                    header.shape
                ),
            ));
        }
        let n = header.count();
        declared.push((m.name.clone(), n));
        let here = checked_count(
            n,
            scalar.size,
            m.available(header.data_offset),
            &member_context,
            &mut report,
        );
        count = count.min(here);
        described.push(format!(
            "{} = `{}` {}",
            role.name(),
            m.name,
            scalar.describe()
        ));
        opened.push(Column {
            reader,
            scalar,
            buf: Vec::new(),
            raw: Vec::new(),
        });
    }
    if declared.windows(2).any(|w| w[0].1 != w[1].1) {
        let lengths: Vec<String> = declared
            .iter()
            .map(|(name, n)| format!("{name} {}", n.map_or("?".into(), |n| n.to_string())))
            .collect();
        return Err(Error::corrupt(
            &context,
            0,
            format!(
                "the column arrays differ in length ({}); they must describe the same events",
                lengths.join(", ")
            ),
        ));
    }
    let Ok::<[Column; 4], _>(cols) = opened.try_into() else {
        return Err(Error::corrupt(&context, 0, "expected four columns"));
    };
    let conv = TimeConv::for_field(&cols[0].scalar, options.text.time_unit)
        .map_err(|m| Error::unsupported(&context, m))?;
    metadata
        .notes
        .push(format!("column arrays: {}", described.join(", ")));
    metadata
        .notes
        .push(format!("time column read as {}", conv.describe()));
    if options.geometry.is_none() {
        metadata
            .notes
            .push(".npz files do not store the sensor size; pass --geometry to set it".into());
    }
    let per_batch = (options.batch_bytes.max(4096) / 16).max(1);
    Ok(Box::new(ColumnsReader {
        cols,
        conv: Converter::new(conv, options.geometry),
        remaining: count,
        index: 0,
        per_batch,
        metadata,
        report,
        context,
    }))
}

/// Streams four column arrays side by side.
struct ColumnsReader {
    /// In the order t, x, y, p.
    cols: [Column; 4],
    conv: Converter,
    remaining: u64,
    index: u64,
    per_batch: usize,
    metadata: Metadata,
    report: DecodeReport,
    context: String,
}

impl FormatReader for ColumnsReader {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        if self.remaining == 0 {
            return Ok(false);
        }
        let n = self
            .per_batch
            .min(usize::try_from(self.remaining).unwrap_or(usize::MAX));
        let mut whole = n;
        for col in &mut self.cols {
            let want = n * col.scalar.size;
            if col.buf.len() < want {
                col.buf.resize(want, 0);
            }
            let got = read_up_to(&mut *col.reader, &mut col.buf[..want])?;
            whole = whole.min(got / col.scalar.size.max(1));
        }
        for col in &mut self.cols {
            let size = col.scalar.size;
            let bytes = col.buf.get(..whole * size).unwrap_or(&[]);
            gather(bytes, size, 0, col.scalar, &mut col.raw);
        }
        let [ct, cx, cy, cp] = &self.cols;
        let rows = ct.raw.iter().zip(&cx.raw).zip(&cy.raw).zip(&cp.raw);
        out.reserve(whole);
        for (((&t, &x), &y), &p) in rows {
            let outcome = self.conv.push(
                ct.scalar.num(t),
                cx.scalar.num(x),
                cy.scalar.num(y),
                cp.scalar.num(p),
                out,
            );
            if outcome != Outcome::Kept {
                count_outcome(outcome, &mut self.report, &self.context, self.index);
            }
            self.index += 1;
        }
        if whole < n {
            self.report.warn(format!(
                "{}: the column data end after {} of {} values; the rest is ignored",
                self.context,
                self.index,
                self.index + self.remaining - whole as u64
            ));
            self.remaining = 0;
        } else {
            self.remaining -= n as u64;
        }
        Ok(whole > 0 || self.remaining > 0)
    }

    fn report(&self) -> &DecodeReport {
        &self.report
    }
}

#[cfg(test)]
mod tests;
