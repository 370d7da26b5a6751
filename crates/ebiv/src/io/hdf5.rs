//! HDF5 event files, read with the pure-Rust `hdf5-reader` (no libhdf5, no plugin):
//! - **Metavision** (`metavision_file_to_hdf5`, Metavision Studio; formats.md §6): the compound
//!   dataset `/CD/events` (`x u16, y u16, p i16, t i64`), its chunks compressed with Prophesee's
//!   ECF codec (HDF5 filter 0x8ECF, decoded by [`super::ecf`]) or stored plain; `/CD/indexes`
//!   to seek by time; external triggers in `/EXT_TRIGGER/events` (`p i16, t i64, id i16`); the
//!   camera's header as root attributes, with `time_shift` when the writer shifted nothing
//!   but recorded the Metavision time origin.
//! - **Column layouts** (DSEC and similar): the 1-D datasets `events/x`, `events/y`,
//!   `events/t`, `events/p` (or the same names at the root), of any integer or float type, with
//!   the DSEC `t_offset` (µs added to every `t`) and `ms_to_idx` (the first event of every
//!   millisecond, used to seek).
//!
//! Events are read a few chunks at a time, so memory holds a batch, not the recording; one
//! read returns at most [`MAX_READ_BYTES`], so a damaged size field cannot make the reader
//! allocate without bound.
//!
//! Time: ebiv keeps the time stamps as stored (formats.md §14). A Metavision file's
//! `time_shift` attribute is what the Metavision reader subtracts; `--metavision-time` does
//! the same.

mod storage;
mod tables;

use super::npy::{count_outcome, gather, Converter, Kind, Outcome, Scalar, TimeConv};
use super::prophesee_header::PropheseeHeader;
use super::raw::metadata_from_header;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek, TimeUnit};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Trigger};
use hdf5_reader::{
    dtype_element_size, ByteOrder, Dataset, Datatype, FilterRegistry, H5Type, Hdf5File,
    OpenOptions, SliceInfo, SliceInfoElem,
};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use storage::SourceStorage;
use tables::{dsec_index, metavision_index, read_triggers, root_attributes, scalar_i64, SeekTable};

/// Largest element (record) of an event dataset read, bytes.
const MAX_RECORD_BYTES: usize = 64;
/// Most trigger edges read from `/EXT_TRIGGER/events` (they are held in memory).
const MAX_TRIGGERS: u64 = 50_000_000;
/// Most bytes one read of a dataset may return (a batch, an index, the triggers).
const MAX_READ_BYTES: usize = 1 << 30;
/// Most entries of a seek index read (`/CD/indexes`, `ms_to_idx`).
const MAX_INDEX_ENTRIES: u64 = 100_000_000;

/// Open an HDF5 event file.
pub(super) fn open(
    source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    Ok(Box::new(open_reader(source, context, options)?))
}

fn open_reader(
    source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Hdf5Reader> {
    let storage = SourceStorage::new(source)?;
    // The ECF filter pads a chunk's events to the chunk's length; it learns the chunk length
    // and the length of the dataset's last, partial chunk once the dataset is found, and
    // refuses a chunk that declares any other number of events (a damaged count).
    let chunk_rows = Arc::new(AtomicUsize::new(0));
    let last_rows = Arc::new(AtomicUsize::new(0));
    let mut filters = FilterRegistry::new();
    let (rows, last) = (Arc::clone(&chunk_rows), Arc::clone(&last_rows));
    filters.register(
        super::ecf::FILTER_ID,
        Box::new(move |_, data, _| {
            let filter_error = hdf5_reader::error::Error::FilterError;
            let (rows, last) = (rows.load(Ordering::Relaxed), last.load(Ordering::Relaxed));
            let declared = super::ecf::declared_events(data).unwrap_or(0);
            if rows > 0 && declared != rows && declared != last {
                return Err(filter_error(format!(
                    "ECF: a chunk declares {declared} events; chunks of this dataset hold {rows} (the last {last})"
                )));
            }
            let rows = Some(rows).filter(|&r| r > 0);
            super::ecf::decode_records(data, rows).map_err(|e| filter_error(format!("ECF: {e}")))
        }),
    );
    let file = Hdf5File::from_storage_with_options(
        Arc::new(storage),
        // Batches are whole chunks read once, in order: a chunk cache would only copy them.
        // Reads of a whole dataset (indexes, triggers) are capped: a damaged size field must
        // not make the reader allocate without bound.
        OpenOptions::default()
            .with_filter_registry(filters)
            .with_chunk_cache_bytes(0)
            .with_max_read_bytes(MAX_READ_BYTES),
    )
    .map_err(|e| hdf5_error(&context, "not a readable HDF5 file", e))?;
    let layout = Layout::find(&file, &context)?;
    if let Some(rows) = layout.datasets[0].chunks().and_then(|c| c.first().copied()) {
        let rows = rows as usize;
        let left = (layout.rows % rows.max(1) as u64) as usize;
        chunk_rows.store(rows, Ordering::Relaxed);
        last_rows.store(if left == 0 { rows } else { left }, Ordering::Relaxed);
    }
    Hdf5Reader::new(file, layout, context, options)
}

fn hdf5_error(context: &str, what: &str, e: hdf5_reader::error::Error) -> Error {
    Error::corrupt(context, 0, format!("{what}: {e}"))
}

/// Where a file keeps its events.
struct Layout {
    kind: LayoutKind,
    /// The datasets the fields are read from (one for `/CD/events`, four for columns).
    datasets: Vec<Dataset>,
    /// t, x, y, p: the dataset (index into `datasets`), byte offset in its record, type.
    fields: [Field; 4],
    /// Events stored.
    rows: u64,
    /// Metavision's own 16-byte record (`x u16 @0, y u16 @2, p i16 @4, t i64 @8`,
    /// little-endian), converted without the general field machinery.
    standard_cd: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LayoutKind {
    Metavision,
    Columns,
}

#[derive(Debug, Clone, Copy)]
struct Field {
    dataset: usize,
    offset: usize,
    scalar: Scalar,
}

impl Layout {
    fn find(file: &Hdf5File, context: &str) -> Result<Layout> {
        if let Ok(cd) = file.dataset("/CD/events") {
            return Layout::metavision(cd, context);
        }
        for group in ["/events", ""] {
            let names = ["t", "x", "y", "p"].map(|n| format!("{group}/{n}"));
            if let Ok(found) = names
                .iter()
                .map(|n| file.dataset(n))
                .collect::<std::result::Result<Vec<_>, _>>()
            {
                return Layout::columns(found, &names, context);
            }
        }
        let (groups, datasets) = file
            .root_group()
            .and_then(|g| g.member_names())
            .unwrap_or_default();
        Err(Error::unsupported(
            context,
            format!(
                "no events found: expected /CD/events (Metavision) or the datasets events/x, events/y, events/t and events/p; the file holds groups [{}] and datasets [{}]",
                groups.join(", "),
                datasets.join(", ")
            ),
        ))
    }

    fn metavision(cd: Dataset, context: &str) -> Result<Layout> {
        let Datatype::Compound { fields, .. } = cd.dtype() else {
            return Err(Error::unsupported(
                context,
                "/CD/events is not a compound dataset of x, y, p and t",
            ));
        };
        let find = |name: &str| -> Result<Field> {
            let f = fields.iter().find(|f| f.name == name).ok_or_else(|| {
                Error::unsupported(context, format!("/CD/events has no field `{name}`"))
            })?;
            Ok(Field {
                dataset: 0,
                offset: f.byte_offset as usize,
                scalar: scalar_of(&f.datatype).ok_or_else(|| {
                    Error::unsupported(
                        context,
                        format!("/CD/events field `{name}` is not an integer or float"),
                    )
                })?,
            })
        };
        let fields = [find("t")?, find("x")?, find("y")?, find("p")?];
        let rows = one_dimensional(&cd, "/CD/events", context)?;
        check_record(&cd, "/CD/events", context)?;
        let little = |kind, size| Scalar {
            kind,
            size,
            big_endian: false,
        };
        let standard_cd = dtype_element_size(cd.dtype()).is_ok_and(|s| s == 16)
            && [
                (8, little(Kind::Int, 8)),
                (0, little(Kind::UInt, 2)),
                (2, little(Kind::UInt, 2)),
                (4, little(Kind::Int, 2)),
            ]
            .iter()
            .zip(&fields)
            .all(|(&(offset, scalar), f)| f.offset == offset && f.scalar == scalar);
        Ok(Layout {
            kind: LayoutKind::Metavision,
            datasets: vec![cd],
            fields,
            rows,
            standard_cd,
        })
    }

    fn columns(datasets: Vec<Dataset>, names: &[String; 4], context: &str) -> Result<Layout> {
        let mut rows = None;
        let mut fields = Vec::new();
        for (k, (d, name)) in datasets.iter().zip(names).enumerate() {
            let n = one_dimensional(d, name, context)?;
            check_record(d, name, context)?;
            if rows.is_some_and(|r| r != n) {
                return Err(Error::corrupt(
                    context,
                    0,
                    format!("the event columns differ in length ({name} has {n} values)"),
                ));
            }
            rows = Some(n);
            let scalar = scalar_of(d.dtype()).ok_or_else(|| {
                Error::unsupported(context, format!("{name} is not an integer or float column"))
            })?;
            fields.push(Field {
                dataset: k,
                offset: 0,
                scalar,
            });
        }
        let fields: [Field; 4] = fields
            .try_into()
            .map_err(|_| Error::corrupt(context, 0, "expected four event columns"))?;
        Ok(Layout {
            kind: LayoutKind::Columns,
            datasets,
            fields,
            rows: rows.unwrap_or(0),
            standard_cd: false,
        })
    }
}

/// The length of a 1-D dataset.
fn one_dimensional(d: &Dataset, name: &str, context: &str) -> Result<u64> {
    match d.shape() {
        [n] => Ok(*n),
        shape => Err(Error::unsupported(
            context,
            format!("{name} has shape {shape:?}; events are read from 1-D datasets"),
        )),
    }
}

/// Refuse records larger than [`MAX_RECORD_BYTES`].
fn check_record(d: &Dataset, name: &str, context: &str) -> Result<()> {
    match dtype_element_size(d.dtype()) {
        Ok(size) if (1..=MAX_RECORD_BYTES).contains(&size) => Ok(()),
        _ => Err(Error::unsupported(
            context,
            format!("{name} has records of an unsupported size or type"),
        )),
    }
}

/// The scalar type of an HDF5 integer, float or enumeration (h5py's bool) field.
fn scalar_of(dtype: &Datatype) -> Option<Scalar> {
    match dtype {
        Datatype::FixedPoint {
            size,
            signed,
            byte_order,
        } if matches!(size, 1 | 2 | 4 | 8) => Some(Scalar {
            kind: if *signed { Kind::Int } else { Kind::UInt },
            size: *size as usize,
            big_endian: *byte_order == ByteOrder::BigEndian,
        }),
        Datatype::FloatingPoint { size, byte_order } if matches!(size, 4 | 8) => Some(Scalar {
            kind: Kind::Float,
            size: *size as usize,
            big_endian: *byte_order == ByteOrder::BigEndian,
        }),
        Datatype::Enum { base, .. } => scalar_of(base),
        _ => None,
    }
}

/// One record of a dataset as stored, `N` bytes, so that any compound or scalar type is
/// read as bytes and its fields taken out by offset. The HDF5 reader copies the stored bytes
/// straight into a vector of them.
#[derive(Clone, Copy)]
#[repr(transparent)]
struct Record<const N: usize>([u8; N]);

impl<const N: usize> H5Type for Record<N> {
    fn hdf5_type() -> Datatype {
        Datatype::Opaque {
            size: N as u32,
            tag: "ebiv record".into(),
        }
    }

    fn from_bytes(bytes: &[u8], _dtype: &Datatype) -> hdf5_reader::error::Result<Self> {
        let mut r = [0u8; N];
        let n = bytes.len().min(N);
        r[..n].copy_from_slice(&bytes[..n]);
        Ok(Record(r))
    }

    fn element_size(_dtype: &Datatype) -> usize {
        N
    }

    fn native_copy_compatible(dtype: &Datatype) -> bool {
        dtype_element_size(dtype).is_ok_and(|size| size == N)
    }
}

/// The rows `first..end` of a 1-D dataset.
fn rows(first: u64, end: u64) -> SliceInfo {
    SliceInfo {
        selections: vec![SliceInfoElem::Slice {
            start: first,
            end,
            step: 1,
        }],
    }
}

/// The records `selection` of `dataset` as bytes, `N` per record, appended to `bytes`.
fn read_records<const N: usize>(
    dataset: &Dataset,
    selection: &SliceInfo,
    bytes: &mut Vec<u8>,
) -> hdf5_reader::error::Result<()> {
    let records = dataset.read_slice::<Record<N>>(selection)?;
    bytes.reserve(records.len() * N);
    for r in records.iter() {
        bytes.extend_from_slice(&r.0);
    }
    Ok(())
}

/// The records `selection` of `dataset` as bytes, appended to `bytes`, for records of
/// 1 to [`MAX_RECORD_BYTES`] bytes.
fn read_any_records(
    dataset: &Dataset,
    selection: &SliceInfo,
    size: usize,
    bytes: &mut Vec<u8>,
) -> hdf5_reader::error::Result<()> {
    match size {
        1 => read_records::<1>(dataset, selection, bytes),
        2 => read_records::<2>(dataset, selection, bytes),
        4 => read_records::<4>(dataset, selection, bytes),
        8 => read_records::<8>(dataset, selection, bytes),
        16 => read_records::<16>(dataset, selection, bytes),
        24 => read_records::<24>(dataset, selection, bytes),
        _ => {
            // Other sizes: one padded record each, cut to size.
            let records = dataset.read_slice::<Record<MAX_RECORD_BYTES>>(selection)?;
            for r in records.iter() {
                bytes.extend_from_slice(&r.0[..size.min(MAX_RECORD_BYTES)]);
            }
            Ok(())
        }
    }
}

struct Hdf5Reader {
    layout: Layout,
    metadata: Metadata,
    report: DecodeReport,
    context: String,
    conv: Converter,
    /// Added to every time stamp (DSEC `t_offset`).
    t_offset: i64,
    /// The next event to read.
    next: u64,
    /// Events per batch: whole chunks of the first dataset.
    per_batch: u64,
    triggers: Vec<Trigger>,
    next_trigger: usize,
    seek: SeekTable,
    metavision_shift: Option<i64>,
    /// Raw field values of the current batch (t, x, y, p).
    raw: [Vec<u64>; 4],
    bytes: Vec<u8>,
}

impl Hdf5Reader {
    fn new(file: Hdf5File, layout: Layout, context: String, options: &ReadOptions) -> Result<Self> {
        let mut report = DecodeReport::default();
        let header = root_attributes(&file);
        let format = Format::Hdf5;
        let mut metadata = if layout.kind == LayoutKind::Metavision {
            metadata_from_header(
                &PropheseeHeader {
                    entries: header,
                    length: 0,
                },
                format,
                options,
            )
        } else {
            let mut m = Metadata::new(format);
            m.header = header;
            m.geometry = options.geometry;
            m
        };
        if metadata.geometry.is_none() {
            metadata
                .notes
                .push("the file does not state the sensor size; pass --geometry to set it".into());
        }
        // Metavision's `t` is µs by definition (and its index is in µs); columns follow the
        // user's time unit.
        let unit = match layout.kind {
            LayoutKind::Metavision => TimeUnit::Auto,
            LayoutKind::Columns => options.text.time_unit,
        };
        let conv = TimeConv::for_field(&layout.fields[0].scalar, unit)
            .map_err(|m| Error::unsupported(&context, m))?;
        let mut layout = layout;
        layout.standard_cd &= conv == TimeConv::Ratio(1, 1);
        let (t_offset, seek, triggers, metavision_shift) = match layout.kind {
            LayoutKind::Metavision => {
                // A plausible time origin only (so subtracting it cannot overflow).
                let shift = metadata
                    .header_value("time_shift")
                    .and_then(|v| v.trim().parse::<i64>().ok())
                    .filter(|s| s.unsigned_abs() < 1 << 62);
                if let Some(s) = shift {
                    metadata.notes.push(format!(
                        "the file records a Metavision time shift of {s} µs (its time origin); times are as stored, --metavision-time subtracts it"
                    ));
                }
                let seek = metavision_index(&file, &context, &mut report);
                let mut triggers = read_triggers(&file, &context, &mut report)?;
                triggers.sort_by_key(|tr| tr.t);
                (0, seek, triggers, shift)
            }
            LayoutKind::Columns => {
                let offset = scalar_i64(&file, "t_offset")
                    .or_else(|| scalar_i64(&file, "events/t_offset"))
                    .unwrap_or(0);
                if offset != 0 {
                    metadata.notes.push(format!(
                        "t_offset = {offset} µs is added to every time stamp"
                    ));
                }
                (offset, dsec_index(&file, offset), Vec::new(), None)
            }
        };
        let chunk = layout.datasets[0]
            .chunks()
            .and_then(|c| c.first().copied())
            .map_or(16_384, u64::from)
            .max(1);
        let record = dtype_element_size(layout.datasets[0].dtype())
            .unwrap_or(16)
            .max(1) as u64;
        let per_batch = (options.batch_bytes as u64 / record / chunk).max(1) * chunk;
        Ok(Hdf5Reader {
            conv: Converter::new(conv, metadata.geometry),
            layout,
            metadata,
            report,
            context,
            t_offset,
            next: 0,
            per_batch,
            triggers,
            next_trigger: 0,
            seek,
            metavision_shift,
            raw: Default::default(),
            bytes: Vec::new(),
        })
    }

    /// The raw values of the fields of events `first..end` into `self.raw`.
    fn read_fields(&mut self, first: u64, end: u64) -> Result<()> {
        let selection = rows(first, end);
        for (k, dataset) in self.layout.datasets.iter().enumerate() {
            let size = dtype_element_size(dataset.dtype()).unwrap_or(MAX_RECORD_BYTES);
            self.bytes.clear();
            read_any_records(dataset, &selection, size, &mut self.bytes).map_err(|e| {
                hdf5_error(
                    &self.context,
                    &format!("reading events {first}..{end} of {}", dataset.name()),
                    e,
                )
            })?;
            for (field, raw) in self.layout.fields.iter().zip(&mut self.raw) {
                if field.dataset == k {
                    gather(&self.bytes, size, field.offset, field.scalar, raw);
                }
            }
        }
        Ok(())
    }

    /// Hand out the triggers up to `until` (all that are left when `None`).
    fn deliver_triggers(&mut self, until: Option<i64>, out: &mut EventBuffer) {
        let rest = &self.triggers[self.next_trigger..];
        let n = until.map_or(rest.len(), |t| rest.partition_point(|tr| tr.t <= t));
        out.triggers.extend_from_slice(&rest[..n]);
        self.next_trigger += n;
    }
}

impl FormatReader for Hdf5Reader {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        if self.next >= self.layout.rows {
            if self.next_trigger < self.triggers.len() {
                self.deliver_triggers(None, out);
                return Ok(true);
            }
            return Ok(false);
        }
        let first = self.next;
        // Whole chunks per batch, also after a seek lands inside one (each chunk is decoded
        // once: there is no chunk cache).
        let end = ((first / self.per_batch + 1) * self.per_batch).min(self.layout.rows);
        if self.layout.standard_cd {
            let records = self.layout.datasets[0]
                .read_slice::<Record<16>>(&rows(first, end))
                .map_err(|e| {
                    hdf5_error(
                        &self.context,
                        &format!("reading events {first}..{end} of /CD/events"),
                        e,
                    )
                })?;
            match records.as_slice() {
                Some(contiguous) => self.convert_standard(contiguous.iter(), out),
                None => self.convert_standard(records.iter(), out),
            }
        } else {
            self.read_fields(first, end)?;
            self.convert_fields(first, out);
        }
        if self.t_offset != 0 {
            let offset = self.t_offset;
            out.t.iter_mut().for_each(|t| *t = t.saturating_add(offset));
        }
        self.next = end;
        let last = out.t.last().copied();
        if last.is_some() {
            self.deliver_triggers(last, out);
        }
        Ok(true)
    }

    fn report(&self) -> &DecodeReport {
        &self.report
    }

    fn metavision_time_shift(&self) -> Option<i64> {
        self.metavision_shift
    }

    fn seek_near(&mut self, t_us: i64) -> Result<bool> {
        let Some(start) = self.seek.start_for(t_us) else {
            return Ok(false);
        };
        if start <= self.next || start >= self.layout.rows {
            return Ok(false);
        }
        self.next = start;
        let skipped = self.triggers[self.next_trigger..].partition_point(|tr| tr.t < t_us);
        self.next_trigger += skipped;
        Ok(true)
    }
}

impl Hdf5Reader {
    /// Events from the raw field values of the batch starting at event `first`.
    fn convert_fields(&mut self, first: u64, out: &mut EventBuffer) {
        let [st, sx, sy, sp] = self.layout.fields.map(|f| f.scalar);
        let [rt, rx, ry, rp] = &self.raw;
        out.reserve(rt.len());
        for (i, (((&t, &x), &y), &p)) in rt.iter().zip(rx).zip(ry).zip(rp).enumerate() {
            let outcome = self
                .conv
                .push(st.num(t), sx.num(x), sy.num(y), sp.num(p), out);
            if outcome != Outcome::Kept {
                count_outcome(outcome, &mut self.report, &self.context, first + i as u64);
            }
        }
    }

    /// Events from Metavision's 16-byte records: pixels outside the sensor are counted and
    /// dropped, polarity is ON when `p > 0` (as [`Converter`] does).
    fn convert_standard<'a>(
        &mut self,
        records: impl ExactSizeIterator<Item = &'a Record<16>>,
        out: &mut EventBuffer,
    ) {
        let (width, height) = (self.conv.width, self.conv.height);
        out.reserve(records.len());
        let mut outside = 0u64;
        for Record(r) in records {
            let x = u16::from_le_bytes([r[0], r[1]]);
            let y = u16::from_le_bytes([r[2], r[3]]);
            let p = i16::from_le_bytes([r[4], r[5]]);
            let t = i64::from_le_bytes([r[8], r[9], r[10], r[11], r[12], r[13], r[14], r[15]]);
            if u32::from(x) < width && u32::from(y) < height {
                out.push(t, x, y, u8::from(p > 0));
            } else {
                outside += 1;
            }
        }
        self.report.out_of_range += outside;
    }
}

#[cfg(test)]
mod tests;
