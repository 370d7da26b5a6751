//! Fields of a live run written as they arrive ([`crate::live`]).
//!
//! * CSV: the columns of [`write_field_csv`](super::write_field_csv) plus `fields_dropped`,
//!   the fields dropped just before this one; each field's lines are flushed as it arrives.
//! * NetCDF: the variables of [`write_field_netcdf`](super::write_field_netcdf) with `time`
//!   as the unlimited (record) dimension, plus `fields_dropped(time)`. Each field is
//!   appended as one record and the record count in the header is updated after its data
//!   (Unidata, "NetCDF Classic and 64-bit Offset Format", `numrecs`), so the file is valid
//!   after every field, whenever the run stops.
//! * NPZ: a zip archive cannot grow in place; the series is kept in memory and written
//!   (atomically) when the run ends, Ctrl-C included.
//!
//! The CSV and NetCDF files are written in place, not through a temporary file, so that
//! other programs can read them while they grow.

use super::csv::{csv_header, write_csv_row};
use super::netcdf::{
    define_dataset, nc_err, netcdf_dataset, write_variable, Attribute, Dataset, Values, Variable,
};
use super::{field_extension, write_field_npz, Physical};
use crate::error::{Error, Result};
use crate::field::{FieldSeries, VectorField};
use crate::live::LiveStart;
use netcdf3::{FileWriter, Version};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Name and meaning of the per-field count of dropped fields.
const DROPPED: &str = "fields_dropped";
const DROPPED_MEANING: &str =
    "fields dropped by the live run just before this one (it could not keep up)";

/// Appends a live run's fields to a file chosen by its extension (.csv, .nc, .npz).
pub struct LiveWriter {
    path: PathBuf,
    format: Format,
}

enum Format {
    /// Nothing written yet: the file is created at the first field.
    Pending,
    Csv(BufWriter<File>),
    NetCdf(Box<NetCdfAppender>),
    Npz(Box<NpzSeries>),
}

/// The fields of an NPZ output, kept until the run ends.
struct NpzSeries {
    /// The fields so far, without derived quantities (a series that holds them takes no
    /// more fields): they are derived over the whole series at the end.
    series: Option<FieldSeries>,
    derive: Vec<crate::derived::DerivedQuantity>,
    dropped: Vec<u64>,
}

impl LiveWriter {
    /// A writer for `path` (.csv, .nc or .npz); the file is created at the first field.
    pub fn create(path: &Path) -> Result<Self> {
        match field_extension(path)?.as_str() {
            "csv" | "nc" | "npz" => {}
            other => {
                return Err(Error::parameter(
                    "output",
                    format!(
                        "{}: a live run writes .csv, .nc or .npz (fields appended as they arrive), not .{other}",
                        path.display()
                    ),
                ))
            }
        }
        Ok(LiveWriter {
            path: path.to_path_buf(),
            format: Format::Pending,
        })
    }

    /// The output file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether a field was appended (the file exists, or an NPZ will be written).
    pub fn has_fields(&self) -> bool {
        !matches!(self.format, Format::Pending)
    }

    /// Append the field at `t0_us`, after `dropped_before` dropped ones.
    pub fn append(
        &mut self,
        start: &LiveStart,
        t0_us: i64,
        field: &VectorField,
        dropped_before: u64,
    ) -> Result<()> {
        let one = start.series_of(t0_us, field)?;
        let io = |e: std::io::Error| Error::io(&self.path, e);
        if let Format::Pending = self.format {
            self.format = match field_extension(&self.path)?.as_str() {
                "csv" => {
                    let mut w = BufWriter::new(File::create(&self.path).map_err(io)?);
                    writeln!(w, "{},{DROPPED}", csv_header(&one)).map_err(io)?;
                    Format::Csv(w)
                }
                "nc" => Format::NetCdf(Box::new(NetCdfAppender::create(&self.path, &one)?)),
                _ => Format::Npz(Box::new(NpzSeries {
                    series: None,
                    derive: Vec::new(),
                    dropped: Vec::new(),
                })),
            };
        }
        match &mut self.format {
            Format::Pending => Ok(()),
            Format::Csv(w) => {
                let physical = one.calibration.as_ref().map(|c| Physical::new(&one, c));
                for row in 0..one.y.len() {
                    for col in 0..one.x.len() {
                        write_csv_row(w, &one, physical.as_ref(), 0, row, col).map_err(io)?;
                        writeln!(w, ",{dropped_before}").map_err(io)?;
                    }
                }
                w.flush().map_err(io)
            }
            Format::NetCdf(nc) => nc.append(&one, dropped_before),
            Format::Npz(npz) => {
                match &mut npz.series {
                    Some(s) => s.push(t0_us, field)?,
                    None => {
                        let mut one = one;
                        npz.derive = std::mem::take(&mut one.derived)
                            .into_iter()
                            .map(|d| d.quantity)
                            .collect();
                        npz.series = Some(one);
                    }
                }
                npz.dropped.push(dropped_before);
                Ok(())
            }
        }
    }

    /// Finish the file: the NPZ is written now; CSV and NetCDF are already complete. A run
    /// without any field writes no file.
    pub fn finish(self) -> Result<()> {
        match self.format {
            Format::Pending => Ok(()),
            Format::Csv(mut w) => w.flush().map_err(|e| Error::io(&self.path, e)),
            Format::NetCdf(_) => Ok(()),
            Format::Npz(npz) => {
                let NpzSeries {
                    series,
                    derive,
                    dropped,
                } = *npz;
                let Some(mut series) = series else {
                    return Ok(());
                };
                if !derive.is_empty() {
                    crate::derived::add_derived(&mut series, &derive)?;
                }
                series.attributes.push((
                    DROPPED.into(),
                    dropped
                        .iter()
                        .map(u64::to_string)
                        .collect::<Vec<_>>()
                        .join(" "),
                ));
                write_field_npz(&series, &self.path)
            }
        }
    }
}

/// A NetCDF-3 file whose records (fields) are appended one at a time.
struct NetCdfAppender {
    file: File,
    path: PathBuf,
    /// Byte offset of the first record.
    records_start: u64,
    /// Bytes per record.
    record_size: u64,
    records: u32,
    /// Names of the record variables, in the file's order.
    record_variables: Vec<String>,
}

impl NetCdfAppender {
    /// Write the header and the fixed variables of `first`'s dataset (plus
    /// `fields_dropped`), with `time` unlimited and no record yet.
    fn create(path: &Path, first: &FieldSeries) -> Result<Self> {
        let dataset = with_dropped(netcdf_dataset(first).map_err(|m| nc_err(path, m))?, 0);
        let ds = define_dataset(&dataset, Some("time"), path)?;
        let werr = |e: netcdf3::error::WriteError| nc_err(path, e);
        let is_record = |v: &Variable| v.dims.first().map(String::as_str) == Some("time");
        {
            let mut w = FileWriter::open(path).map_err(werr)?;
            w.set_def(&ds, Version::Offset64Bit, 0).map_err(werr)?;
            for var in dataset.variables.iter().filter(|v| !is_record(v)) {
                write_variable(&mut w, var).map_err(werr)?;
            }
            w.close().map_err(werr)?;
        }
        let records: Vec<&Variable> = dataset.variables.iter().filter(|v| is_record(v)).collect();
        let padded = records.len() > 1;
        let record_size = records
            .iter()
            .map(|v| encoded_len(&v.values, padded) as u64)
            .sum();
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        let records_start = file
            .seek(SeekFrom::End(0))
            .map_err(|e| Error::io(path, e))?;
        Ok(NetCdfAppender {
            file,
            path: path.to_path_buf(),
            records_start,
            record_size,
            records: 0,
            record_variables: records.iter().map(|v| v.name.clone()).collect(),
        })
    }

    /// Append `one` (a series of one field) as the next record, then count it in the header.
    fn append(&mut self, one: &FieldSeries, dropped_before: u64) -> Result<()> {
        let dataset = with_dropped(
            netcdf_dataset(one).map_err(|m| nc_err(&self.path, m))?,
            dropped_before,
        );
        let padded = self.record_variables.len() > 1;
        let mut bytes = Vec::with_capacity(self.record_size as usize);
        for name in &self.record_variables {
            let var = dataset
                .variables
                .iter()
                .find(|v| &v.name == name)
                .ok_or_else(|| nc_err(&self.path, format!("variable {name} missing")))?;
            encode(&var.values, padded, &mut bytes);
        }
        if bytes.len() as u64 != self.record_size {
            return Err(nc_err(
                &self.path,
                "a field's record does not match the file's",
            ));
        }
        let io = |e: std::io::Error| Error::io(&self.path, e);
        let offset = self.records_start + u64::from(self.records) * self.record_size;
        self.file.seek(SeekFrom::Start(offset)).map_err(io)?;
        self.file.write_all(&bytes).map_err(io)?;
        // `numrecs` is a non-negative 32-bit integer (all ones means "streaming").
        self.records = self
            .records
            .checked_add(1)
            .filter(|&n| n <= i32::MAX as u32)
            .ok_or_else(|| nc_err(&self.path, "more records than NetCDF-3 counts"))?;
        // `numrecs` follows the 4-byte magic number.
        self.file.seek(SeekFrom::Start(4)).map_err(io)?;
        self.file
            .write_all(&self.records.to_be_bytes())
            .map_err(io)?;
        self.file.flush().map_err(io)
    }
}

/// `dataset` with the record variable `fields_dropped` (one value).
fn with_dropped(mut dataset: Dataset, dropped: u64) -> Dataset {
    dataset.variables.push(Variable {
        name: DROPPED.into(),
        dims: vec!["time".into()],
        values: Values::I32(vec![i32::try_from(dropped).unwrap_or(i32::MAX)]),
        attributes: vec![("long_name".into(), Attribute::Text(DROPPED_MEANING.into()))],
    });
    dataset
}

/// Bytes of `values` in a record: big-endian, padded to 4 bytes when the file has more than
/// one record variable.
fn encoded_len(values: &Values, padded: bool) -> usize {
    let raw = match values {
        Values::F64(v) => 8 * v.len(),
        Values::F32(v) => 4 * v.len(),
        Values::I16(v) => 2 * v.len(),
        Values::I32(v) => 4 * v.len(),
    };
    if padded {
        raw.div_ceil(4) * 4
    } else {
        raw
    }
}

fn encode(values: &Values, padded: bool, out: &mut Vec<u8>) {
    let start = out.len();
    match values {
        Values::F64(v) => v
            .iter()
            .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
        Values::F32(v) => v
            .iter()
            .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
        Values::I16(v) => v
            .iter()
            .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
        Values::I32(v) => v
            .iter()
            .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
    }
    out.resize(start + encoded_len(values, padded), 0);
}

/// The outputs of a live run, as one sink: the file of a [`LiveWriter`] and the page of a
/// [`LiveView`](super::LiveView), either optional. The command line and Python wrap it.
pub struct LiveOutputs {
    writer: Option<LiveWriter>,
    view: Option<super::LiveView>,
    start: Option<LiveStart>,
}

impl LiveOutputs {
    /// Outputs to `writer` and `view`.
    pub fn new(writer: Option<LiveWriter>, view: Option<super::LiveView>) -> Self {
        LiveOutputs {
            writer,
            view,
            start: None,
        }
    }

    /// The run's start, once told.
    pub fn start(&self) -> Option<&LiveStart> {
        self.start.as_ref()
    }

    /// Finish the file (an NPZ is written now); the page stops being served. Whether a file
    /// was written (not without a field).
    pub fn finish(self) -> Result<bool> {
        let wrote = self.writer.as_ref().is_some_and(LiveWriter::has_fields);
        self.writer.map(LiveWriter::finish).transpose()?;
        Ok(wrote)
    }
}

impl crate::live::LiveSink for LiveOutputs {
    fn started(&mut self, start: &LiveStart) -> Result<()> {
        if let Some(view) = &self.view {
            view.started(start);
        }
        self.start = Some(start.clone());
        Ok(())
    }

    fn field(&mut self, f: &crate::live::LiveField) -> Result<()> {
        let start = self
            .start
            .as_ref()
            .ok_or_else(|| Error::parameter("live", "a field before the run started"))?;
        if let Some(writer) = &mut self.writer {
            writer.append(start, f.t0_us, f.field, f.dropped_before)?;
        }
        if let Some(view) = &self.view {
            view.publish(start, f);
        }
        Ok(())
    }
}
