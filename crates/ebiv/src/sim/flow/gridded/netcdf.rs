//! Gridded flows from NetCDF classic (CDF-1 and 64-bit-offset CDF-2) files, read with the
//! pure-Rust `netcdf3` crate. The layout is the one ebiv's own NetCDF export writes.

use super::GriddedFlow;
use crate::error::{Error, Result};
use netcdf3::{DataVector, FileReader, Variable};
use std::io::Read;
use std::path::Path;

/// Reads variables of one file, with errors naming the file (also used by the vector-field
/// reader, [`crate::io::field`]).
pub(crate) struct Reader {
    pub(crate) reader: FileReader,
    pub(crate) context: String,
    file_len: u64,
}

impl Reader {
    pub(crate) fn err(&self, message: impl Into<String>) -> Error {
        Error::unsupported(self.context.clone(), message)
    }

    pub(crate) fn var(&self, name: &str) -> Result<&Variable> {
        self.reader.data_set().get_var(name).ok_or_else(|| {
            self.err(format!(
                "no variable `{name}` (a gridded flow needs `u`, `v` over (time, y, x) or \
                 (y, x), and coordinate variables `x`, `y` and, with a time dimension, `time`)"
            ))
        })
    }

    pub(crate) fn dim_names(&self, name: &str) -> Result<Vec<String>> {
        Ok(self
            .var(name)?
            .get_dims()
            .iter()
            .map(|d| d.name())
            .collect())
    }

    /// A numeric attribute's first value.
    pub(crate) fn attr_number(&self, var: &str, attr: &str) -> Result<Option<f64>> {
        let Some(a) = self.var(var)?.get_attr(attr) else {
            return Ok(None);
        };
        let first = a
            .get_f64()
            .and_then(|d| d.first().copied())
            .or_else(|| a.get_f32().and_then(|d| d.first().map(|&v| v as f64)))
            .or_else(|| a.get_i32().and_then(|d| d.first().map(|&v| v as f64)))
            .or_else(|| a.get_i16().and_then(|d| d.first().map(|&v| v as f64)))
            .or_else(|| a.get_i8().and_then(|d| d.first().map(|&v| v as f64)));
        match first {
            Some(v) => Ok(Some(v)),
            None => Err(self.err(format!("attribute `{var}:{attr}` is not a number"))),
        }
    }

    /// All values of `name` as f64, after `_FillValue`/`missing_value` (→ NaN) and
    /// `scale_factor`/`add_offset` (CF conventions).
    pub(crate) fn read(&mut self, name: &str) -> Result<Vec<f64>> {
        let var = self.var(name)?;
        // Check the declared size against the file before the reader allocates it.
        let count = var
            .get_dims()
            .iter()
            .try_fold(1usize, |n, d| n.checked_mul(d.size()));
        let bytes = count.and_then(|n| n.checked_mul(var.data_type().size_of()));
        if bytes.is_none_or(|b| b as u64 > self.file_len) {
            return Err(self.err(format!(
                "variable `{name}` declares more data than the file's {} bytes hold",
                self.file_len
            )));
        }
        let data = self
            .reader
            .read_var(name)
            .map_err(|e| self.err(format!("cannot read variable `{name}`: {e:?}")))?;
        let mut values: Vec<f64> = match data {
            DataVector::I8(d) => d.into_iter().map(f64::from).collect(),
            DataVector::I16(d) => d.into_iter().map(f64::from).collect(),
            DataVector::I32(d) => d.into_iter().map(f64::from).collect(),
            DataVector::F32(d) => d.into_iter().map(f64::from).collect(),
            DataVector::F64(d) => d,
            DataVector::U8(_) => {
                return Err(self.err(format!("variable `{name}` is text, not numbers")));
            }
        };
        for attr in ["_FillValue", "missing_value"] {
            if let Some(fill) = self.attr_number(name, attr)? {
                values
                    .iter_mut()
                    .filter(|v| **v == fill)
                    .for_each(|v| *v = f64::NAN);
            }
        }
        let scale = self.attr_number(name, "scale_factor")?.unwrap_or(1.0);
        let offset = self.attr_number(name, "add_offset")?.unwrap_or(0.0);
        if scale != 1.0 || offset != 0.0 {
            values.iter_mut().for_each(|v| *v = *v * scale + offset);
        }
        Ok(values)
    }

    /// A 1-D coordinate variable and the name of its dimension.
    fn coordinate(&mut self, name: &str) -> Result<(Vec<f64>, String)> {
        let dims = self.dim_names(name)?;
        let [dim] = dims.as_slice() else {
            return Err(self.err(format!(
                "coordinate variable `{name}` must have one dimension, it has {}",
                dims.len()
            )));
        };
        let dim = dim.clone();
        Ok((self.read(name)?, dim))
    }

    /// µs per unit of the `time` variable, from its `units` attribute (µs if absent).
    pub(crate) fn time_scale(&self) -> Result<f64> {
        let Some(units) = self.var("time")?.get_attr_as_string("units") else {
            return Ok(1.0);
        };
        let word = units
            .split_whitespace()
            .next()
            .unwrap_or("")
            .to_ascii_lowercase();
        Ok(match word.as_str() {
            "us" | "µs" | "μs" | "usec" | "microsecond" | "microseconds" => 1.0,
            "ms" | "msec" | "millisecond" | "milliseconds" => 1e3,
            "s" | "sec" | "second" | "seconds" => 1e6,
            "ns" | "nanosecond" | "nanoseconds" => 1e-3,
            _ => {
                return Err(self.err(format!(
                    "`time:units` is \"{units}\"; expected microseconds, milliseconds or seconds"
                )))
            }
        })
    }
}

/// Walks the header of a classic NetCDF file and checks that every count and every
/// variable's size fits in the file. The `netcdf3` parser allocates from these counts before
/// checking them, so a corrupt header could otherwise exhaust memory (no header value may make
/// ebiv allocate without bound).
struct HeaderCheck<R> {
    input: R,
    pos: u64,
    file_len: u64,
}

type Check<T> = std::result::Result<T, String>;

impl<R: Read> HeaderCheck<R> {
    fn early(&self) -> String {
        format!("the header ends early (at byte {})", self.pos)
    }

    fn u32(&mut self) -> Check<u64> {
        let mut b = [0u8; 4];
        self.input.read_exact(&mut b).map_err(|_| self.early())?;
        self.pos += 4;
        Ok(u64::from(u32::from_be_bytes(b)))
    }

    fn skip(&mut self, n: u64) -> Check<()> {
        if n > self.file_len.saturating_sub(self.pos) {
            return Err(self.early());
        }
        let copied = std::io::copy(&mut self.input.by_ref().take(n), &mut std::io::sink())
            .map_err(|e| e.to_string())?;
        if copied != n {
            return Err(self.early());
        }
        self.pos += n;
        Ok(())
    }

    /// A count of items of at least `min_bytes` each that must fit in the rest of the file.
    fn count(&mut self, min_bytes: u64, what: &str) -> Check<u64> {
        let at = self.pos;
        let n = self.u32()?;
        if n.saturating_mul(min_bytes) > self.file_len.saturating_sub(self.pos) {
            return Err(format!(
                "the header declares {n} {what} at byte {at}, more than the file holds"
            ));
        }
        Ok(n)
    }

    fn name(&mut self) -> Check<()> {
        let n = self.count(1, "name bytes")?;
        self.skip(n.div_ceil(4) * 4)
    }

    /// A list tag (or ABSENT: two zero words) and the list's length.
    fn list(&mut self, tag: u64, min_bytes: u64, what: &str) -> Check<u64> {
        let at = self.pos;
        let found = self.u32()?;
        let n = self.count(min_bytes, what)?;
        if found != tag && !(found == 0 && n == 0) {
            return Err(format!("unexpected list tag {found:#x} at byte {at}"));
        }
        Ok(n)
    }

    fn type_size(&mut self) -> Check<u64> {
        let at = self.pos;
        match self.u32()? {
            1 | 2 => Ok(1),
            3 => Ok(2),
            4 | 5 => Ok(4),
            6 => Ok(8),
            t => Err(format!("unknown data type {t} at byte {at}")),
        }
    }

    fn attributes(&mut self) -> Check<()> {
        for _ in 0..self.list(0x0C, 12, "attributes")? {
            self.name()?;
            let size = self.type_size()?;
            let n = self.count(size, "attribute values")?;
            self.skip((n * size).div_ceil(4) * 4)?;
        }
        Ok(())
    }

    fn run(&mut self) -> Check<()> {
        let mut magic = [0u8; 4];
        self.input
            .read_exact(&mut magic)
            .map_err(|_| self.early())?;
        self.pos = 4;
        let offset_bytes = match magic {
            [b'C', b'D', b'F', 1] => 4,
            [b'C', b'D', b'F', 2] => 8,
            [b'C', b'D', b'F', 5] => {
                return Err(
                    "CDF-5 files are not read; write NetCDF classic or 64-bit offset".into(),
                )
            }
            _ => return Err("no NetCDF classic signature".into()),
        };
        let records = match self.u32()? {
            0xFFFF_FFFF => 0,
            n => n,
        };
        let mut dims = Vec::new();
        for _ in 0..self.list(0x0A, 8, "dimensions")? {
            self.name()?;
            let size = self.u32()?;
            dims.push(if size == 0 { records } else { size });
        }
        self.attributes()?;
        for _ in 0..self.list(0x0B, 24, "variables")? {
            self.name()?;
            let mut len = 1u64;
            for _ in 0..self.count(4, "dimension ids")? {
                let id = self.u32()?;
                let size = usize::try_from(id)
                    .ok()
                    .and_then(|i| dims.get(i))
                    .ok_or_else(|| {
                        format!("a variable uses dimension {id}, which does not exist")
                    })?;
                len = len.saturating_mul(*size);
            }
            self.attributes()?;
            let bytes = len.saturating_mul(self.type_size()?);
            if bytes > self.file_len {
                return Err(format!(
                    "a variable declares {bytes} bytes of data, more than the file holds"
                ));
            }
            self.skip(4 + offset_bytes)?;
        }
        Ok(())
    }
}

impl Reader {
    /// Open a NetCDF classic file after checking that its header cannot make the reader
    /// allocate more than the file holds.
    pub(crate) fn open(path: &Path) -> Result<Reader> {
        let context = path.display().to_string();
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        HeaderCheck {
            input: std::io::BufReader::new(file),
            pos: 0,
            file_len,
        }
        .run()
        .map_err(|m| {
            Error::unsupported(
                context.clone(),
                format!("not a readable NetCDF classic file: {m}"),
            )
        })?;
        let reader = FileReader::open(path).map_err(|e| {
            Error::unsupported(
                context.clone(),
                format!("not a readable NetCDF classic file ({e:?})"),
            )
        })?;
        Ok(Reader {
            reader,
            context,
            file_len,
        })
    }
}

impl GriddedFlow {
    /// Load a field from a NetCDF classic file: variables `u`, `v` (px/ms) with dimensions
    /// (time, y, x) or (y, x); 1-D coordinate variables `x`, `y` (px, image coordinates) and,
    /// for three dimensions, `time` (µs, or the unit its `units` attribute names: ms, s).
    /// `_FillValue`/`missing_value` become NaN; `scale_factor`/`add_offset` are applied.
    /// This is the layout of ebiv's NetCDF export.
    pub fn from_netcdf(path: impl AsRef<Path>) -> Result<Self> {
        let mut r = Reader::open(path.as_ref())?;
        let (xs, x_dim) = r.coordinate("x")?;
        let (ys, y_dim) = r.coordinate("y")?;
        let u_dims = r.dim_names("u")?;
        if r.dim_names("v")? != u_dims {
            return Err(r.err(format!(
                "`u` has dimensions ({}) but `v` has ({})",
                u_dims.join(", "),
                r.dim_names("v")?.join(", ")
            )));
        }
        let spatial_ok =
            u_dims.len() >= 2 && u_dims[u_dims.len() - 2..] == [y_dim.clone(), x_dim.clone()];
        let times_us = match u_dims.len() {
            2 if spatial_ok => vec![0.0],
            3 if spatial_ok => {
                let (times, t_dim) = r.coordinate("time")?;
                if t_dim != u_dims[0] {
                    return Err(r.err(format!(
                        "`u` has dimensions ({}) but `time` runs along `{t_dim}`",
                        u_dims.join(", ")
                    )));
                }
                let scale = r.time_scale()?;
                times.into_iter().map(|t| t * scale).collect()
            }
            _ => {
                let found = u_dims.join(", ");
                let expected = format!("(time, {y_dim}, {x_dim}) or ({y_dim}, {x_dim})");
                return Err(r.err(format!("`u` has dimensions ({found}); expected {expected}")));
            }
        };
        let u = r.read("u")?;
        let v = r.read("v")?;
        GriddedFlow::build(times_us, xs, ys, u, v).map_err(|(key, m)| r.err(format!("`{key}` {m}")))
    }
}
