//! NumPy `.npy` files of events (formats.md §12): a structured array whose fields are mapped
//! case-insensitively — {t, ts, timestamp, time}, {x}, {y}, {p, pol, polarity, on} — in any of
//! the list (`[('t', '<i8'), …]`, padding fields included) or dict (`names`/`formats`/
//! `offsets`/`itemsize`) layouts of the producers in the §12 table, any byte order.
//!
//! Also read: a plain 2-D array of shape `(N, 4)` (C order) of one numeric type, whose
//! columns are taken as **`t, x, y, p`** in that order.
//!
//! Values: integer and bool fields of 1–8 bytes; `f2`/`f4`/`f8`; `datetime64`/`timedelta64`
//! in s, ms, µs or ns. Integer time is µs and float time is seconds, unless
//! [`ReadOptions::text`]`.time_unit` names a unit explicitly; a datetime's own unit always
//! wins. Float times are rounded to the nearest µs. Polarity is ON when the value is > 0
//! (so both {0, 1} and {−1, 1} work). Coordinates outside 0..=65535 or the geometry are
//! dropped and counted; non-integral or non-finite values are counted as malformed.
//!
//! The data are streamed in batches of about `batch_bytes`; the header is bounded to 1 MiB
//! and the declared record count is checked against the file size (a short file is decoded
//! as far as it goes, with a warning).
//!
//! [`ReadOptions::text`]: super::ReadOptions::text

mod header;
mod literal;
mod values;

pub(crate) use header::{read_header, Dtype, Kind, NpyHeader, Scalar};
pub(crate) use values::{gather, Converter, Num, Outcome, TimeConv};

use super::prophesee_header::read_up_to;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::EventBuffer;
use std::io::{Read, Seek, SeekFrom};

/// The four event quantities a reader maps fields or columns to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    T,
    X,
    Y,
    P,
}

impl Role {
    pub const ALL: [Role; 4] = [Role::T, Role::X, Role::Y, Role::P];

    /// The role a field or array name stands for (case-insensitive aliases of §12).
    pub fn of_name(name: &str) -> Option<Role> {
        match name.trim().to_ascii_lowercase().as_str() {
            "t" | "ts" | "timestamp" | "timestamps" | "time" => Some(Role::T),
            "x" => Some(Role::X),
            "y" => Some(Role::Y),
            "p" | "pol" | "polarity" | "polarities" | "on" => Some(Role::P),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Role::T => "t",
            Role::X => "x",
            Role::Y => "y",
            Role::P => "p",
        }
    }
}

/// The accepted names, for error messages.
pub(crate) const ALIASES: &str =
    "t/ts/timestamp/time, x, y and p/pol/polarity/on (case-insensitive)";

/// Byte offset and type of one mapped field inside a record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FieldAt {
    pub offset: usize,
    pub scalar: Scalar,
}

/// Where t, x, y and p sit in a record of `itemsize` bytes.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RecordLayout {
    pub itemsize: usize,
    /// In the order t, x, y, p.
    pub fields: [FieldAt; 4],
    /// Array elements per record: 1 for structured arrays, 4 for `(N, 4)` arrays.
    pub elements_per_record: u64,
    /// How the mapping was found, for the metadata notes.
    pub description: String,
}

impl RecordLayout {
    /// Number of records the header declares, `None` if it overflows.
    pub fn declared_records(&self, header: &NpyHeader) -> Option<u64> {
        header.count().map(|c| c / self.elements_per_record.max(1))
    }
}

/// The record layout of a `.npy` array, or why it holds no events.
pub(crate) fn layout_of(header: &NpyHeader) -> std::result::Result<RecordLayout, String> {
    let dims_gt1 = header.shape.iter().filter(|&&d| d > 1).count();
    match &header.dtype {
        Dtype::Record { fields, itemsize } => {
            if header.fortran_order && dims_gt1 > 1 {
                return Err("a multi-dimensional structured array in Fortran order is not read; save it with fortran_order False".into());
            }
            let mut found: [Option<FieldAt>; 4] = [None; 4];
            let mut names = Vec::new();
            for f in fields {
                let Some(role) = Role::of_name(&f.name) else {
                    continue;
                };
                let slot = &mut found[role as usize];
                if slot.is_some() {
                    continue;
                }
                let Dtype::Scalar(scalar) = f.dtype else {
                    return Err(format!(
                        "field `{}` is not a plain number and cannot be the event {}",
                        f.name,
                        role.name()
                    ));
                };
                if f.offset + scalar.size > *itemsize {
                    return Err(format!("field `{}` lies beyond the record", f.name));
                }
                *slot = Some(FieldAt {
                    offset: f.offset,
                    scalar,
                });
                names.push(format!("{} = `{}` {}", role.name(), f.name, scalar.describe()));
            }
            match found {
                [Some(t), Some(x), Some(y), Some(p)] => Ok(RecordLayout {
                    itemsize: *itemsize,
                    fields: [t, x, y, p],
                    elements_per_record: 1,
                    description: format!(
                        "structured records of {itemsize} bytes: {}",
                        names.join(", ")
                    ),
                }),
                _ => {
                    let all: Vec<&str> = fields
                        .iter()
                        .map(|f| f.name.as_str())
                        .filter(|n| !n.is_empty())
                        .collect();
                    Err(format!(
                        "the structured array has fields ({}); ebiv needs {ALIASES}",
                        all.join(", ")
                    ))
                }
            }
        }
        Dtype::Scalar(scalar) => match header.shape.as_slice() {
            [_, 4] if !header.fortran_order || dims_gt1 <= 1 => {
                let at = |k: usize| FieldAt {
                    offset: k * scalar.size,
                    scalar: *scalar,
                };
                Ok(RecordLayout {
                    itemsize: 4 * scalar.size,
                    fields: [at(0), at(1), at(2), at(3)],
                    elements_per_record: 4,
                    description: format!(
                        "a 2-D {} array of shape (N, 4), columns taken as t, x, y, p",
                        scalar.describe()
                    ),
                })
            }
            [_, 4] => Err("an (N, 4) array in Fortran order is not read; save it in C order".into()),
            [_] => Err(format!(
                "a plain 1-D {} array holds one column; events need a structured array with {ALIASES}, an (N, 4) array, or an .npz with one array per column",
                scalar.describe()
            )),
            shape => Err(format!(
                "a plain array of shape {shape:?} holds no events; expected a structured array or shape (N, 4)"
            )),
        },
        Dtype::Opaque { what, .. } => Err(format!("arrays of {what} hold no events")),
    }
}

/// A `Read` over a seekable source, so that both files and zip members fit one reader.
pub(crate) struct ReadOnly(pub Box<dyn ReadSeek>);

impl Read for ReadOnly {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

/// At most this many value problems are described individually.
const MAX_VALUE_WARNINGS: u64 = 5;

/// Streams fixed-size records and converts them to events; used for `.npy` files and for
/// structured members of `.npz` archives.
pub(crate) struct RecordReader {
    reader: Box<dyn Read + Send>,
    layout: RecordLayout,
    conv: Converter,
    metadata: Metadata,
    report: DecodeReport,
    context: String,
    /// Records still expected.
    remaining: u64,
    /// Records decoded so far.
    index: u64,
    /// Byte offset of the next record in the file (or member).
    offset: u64,
    per_batch: usize,
    buf: Vec<u8>,
    /// Raw field values of the current batch, in the order t, x, y, p.
    raw: [Vec<u64>; 4],
}

impl RecordReader {
    /// A reader of `count` records (already checked against the bytes available) starting at
    /// the current position of `reader`, which is `data_offset` bytes into the stream.
    pub fn new(
        reader: Box<dyn Read + Send>,
        layout: RecordLayout,
        conv: Converter,
        count: u64,
        data_offset: u64,
        batch_bytes: usize,
    ) -> Self {
        let itemsize = layout.itemsize.max(1);
        let per_batch = (batch_bytes.max(4096) / itemsize).max(1);
        let first = per_batch.min(usize::try_from(count).unwrap_or(usize::MAX));
        RecordReader {
            reader,
            conv,
            metadata: Metadata::new(Format::Npy),
            report: DecodeReport::default(),
            context: String::new(),
            remaining: count,
            index: 0,
            offset: data_offset,
            per_batch,
            buf: vec![0; first * itemsize],
            raw: Default::default(),
            layout,
        }
    }

    /// Attach the metadata, the report so far (header warnings) and the context for messages.
    pub fn described(mut self, metadata: Metadata, report: DecodeReport, context: String) -> Self {
        self.metadata = metadata;
        self.report = report;
        self.context = context;
        self
    }
}

/// Count a record that did not become an event.
pub(crate) fn count_outcome(
    outcome: Outcome,
    report: &mut DecodeReport,
    context: &str,
    index: u64,
) {
    match outcome {
        Outcome::Kept => {}
        Outcome::OutOfRange => report.out_of_range += 1,
        Outcome::Malformed(why) => {
            report.malformed += 1;
            if report.malformed <= MAX_VALUE_WARNINGS {
                report.warn(format!("{context}: record {index} skipped: {why}"));
            }
        }
    }
}

impl FormatReader for RecordReader {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        if self.remaining == 0 {
            return Ok(false);
        }
        let itemsize = self.layout.itemsize;
        let n = self
            .per_batch
            .min(usize::try_from(self.remaining).unwrap_or(usize::MAX));
        let want = n * itemsize;
        if self.buf.len() < want {
            self.buf.resize(want, 0);
        }
        let got = read_up_to(&mut *self.reader, &mut self.buf[..want])?;
        let whole = got / itemsize;
        out.reserve(whole);
        let bytes = self.buf.get(..whole * itemsize).unwrap_or(&[]);
        for (field, raw) in self.layout.fields.iter().zip(&mut self.raw) {
            gather(bytes, itemsize, field.offset, field.scalar, raw);
        }
        let [st, sx, sy, sp] = self.layout.fields.map(|f| f.scalar);
        let [rt, rx, ry, rp] = &self.raw;
        let rows = rt.iter().zip(rx).zip(ry).zip(rp);
        for (((&t, &x), &y), &p) in rows {
            let outcome = self
                .conv
                .push(st.num(t), sx.num(x), sy.num(y), sp.num(p), out);
            if outcome != Outcome::Kept {
                count_outcome(outcome, &mut self.report, &self.context, self.index);
            }
            self.index += 1;
        }
        if got < want {
            let partial = (got % itemsize) as u64;
            self.report.truncated_bytes += partial;
            self.report.warn(format!(
                "{}: data end after {} of the {} records the header declares (byte {}); {partial} trailing bytes ignored",
                self.context,
                self.index,
                self.index + self.remaining - whole as u64,
                self.offset + got as u64,
            ));
            self.remaining = 0;
        } else {
            self.remaining -= n as u64;
        }
        self.offset += got as u64;
        Ok(whole > 0 || self.remaining > 0)
    }

    fn report(&self) -> &DecodeReport {
        &self.report
    }

    fn position(&self) -> Option<u64> {
        Some(self.offset)
    }
}

/// How many whole records of `itemsize` bytes to read when the header declares `declared`
/// and `available` bytes follow it; warns about a short or over-long data section.
pub(crate) fn checked_count(
    declared: Option<u64>,
    itemsize: usize,
    available: u64,
    context: &str,
    report: &mut DecodeReport,
) -> u64 {
    let itemsize = itemsize as u64;
    let present = available / itemsize.max(1);
    let need = declared.and_then(|n| n.checked_mul(itemsize));
    match (declared, need) {
        (Some(n), Some(need)) if need <= available => {
            if need < available {
                report.warn(format!(
                    "{context}: {} bytes after the {n} declared records are ignored",
                    available - need
                ));
            }
            n
        }
        _ => {
            let declared = declared.map_or("more than 2^64".to_string(), |n| n.to_string());
            report.truncated_bytes += available % itemsize.max(1);
            report.warn(format!(
                "{context}: the header declares {declared} records but the data hold only {present} (file truncated?); reading those"
            ));
            present
        }
    }
}

pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let file_len = source.seek(SeekFrom::End(0))?;
    source.seek(SeekFrom::Start(0))?;
    let header = read_header(&mut source, &context)?;
    let mut report = DecodeReport::default();
    let available = file_len.saturating_sub(header.data_offset);
    let (layout, conv) = event_layout(&header, &context, options)?;
    let count = checked_count(
        layout.declared_records(&header),
        layout.itemsize,
        available,
        &context,
        &mut report,
    );
    let metadata = npy_metadata(Format::Npy, &header, &layout, &conv, options);
    Ok(Box::new(
        RecordReader::new(
            Box::new(ReadOnly(source)),
            layout,
            Converter::new(conv, options.geometry),
            count,
            header.data_offset,
            options.batch_bytes,
        )
        .described(metadata, report, context),
    ))
}

/// The record layout and time conversion of an event array, or an error saying why the
/// array holds no events.
pub(crate) fn event_layout(
    header: &NpyHeader,
    context: &str,
    options: &ReadOptions,
) -> Result<(RecordLayout, TimeConv)> {
    let layout = layout_of(header).map_err(|m| Error::unsupported(context, m))?;
    if layout.itemsize == 0 {
        return Err(Error::corrupt(
            context,
            header.data_offset,
            "records of 0 bytes",
        ));
    }
    let conv = TimeConv::for_field(&layout.fields[0].scalar, options.text.time_unit)
        .map_err(|m| Error::unsupported(context, m))?;
    Ok((layout, conv))
}

/// Metadata of an `.npy` array (also a structured `.npz` member).
pub(crate) fn npy_metadata(
    format: Format,
    header: &NpyHeader,
    layout: &RecordLayout,
    conv: &TimeConv,
    options: &ReadOptions,
) -> Metadata {
    let mut metadata = Metadata::new(format);
    metadata.geometry = options.geometry;
    metadata.header.push((
        "npy_version".into(),
        format!("{}.{}", header.version.0, header.version.1),
    ));
    metadata
        .header
        .push(("npy_header".into(), header.text.clone()));
    metadata.notes.push(layout.description.clone());
    metadata
        .notes
        .push(format!("time field read as {}", conv.describe()));
    if options.geometry.is_none() {
        metadata
            .notes
            .push(".npy files do not store the sensor size; pass --geometry to set it".into());
    }
    metadata
}

#[cfg(test)]
pub(crate) mod tests;
