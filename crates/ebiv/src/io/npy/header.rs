//! The `.npy` header (formats.md §12): `\x93NUMPY`, a version byte pair, the header length
//! (`u16` for 1.0, `u32` for 2.0/3.0) and a Python dict literal with `descr`, `fortran_order`
//! and `shape`. The literal is parsed by hand (no `eval`); the `descr` may be a simple type
//! string, a list of `(name, type[, shape])` tuples (packed, with `('', '|Vn')` padding) or a
//! dict with `names`, `formats`, `offsets` and `itemsize`.

use super::literal::{parse_literal, Py};
use crate::error::{Error, Result};
use crate::io::prophesee_header::read_up_to;
use std::io::Read;

/// Headers longer than this are rejected before anything is allocated for them.
pub(crate) const MAX_HEADER_BYTES: usize = 1 << 20;
/// Records larger than this are not event records; rejected.
pub(crate) const MAX_ITEMSIZE: usize = 1 << 16;

/// Unit of a NumPy `datetime64`/`timedelta64` value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum DateUnit {
    Seconds,
    Millis,
    Micros,
    Nanos,
    /// Any other unit (days, picoseconds, …) or none: not usable as event time.
    Other,
}

/// The kind of a scalar field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Bool,
    Int,
    UInt,
    Float,
    /// `datetime64`/`timedelta64`: a signed 64-bit count of `DateUnit`.
    Date(DateUnit),
}

/// One numeric value type: kind, size in bytes and byte order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Scalar {
    pub kind: Kind,
    pub size: usize,
    pub big_endian: bool,
}

/// A NumPy dtype, reduced to what a reader needs.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Dtype {
    Scalar(Scalar),
    /// A value ebiv does not interpret (void padding, strings, sub-arrays, complex):
    /// only its size matters.
    Opaque {
        size: usize,
        what: String,
    },
    Record {
        fields: Vec<RecordField>,
        itemsize: usize,
    },
}

/// A named field of a structured dtype at a byte offset.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RecordField {
    pub name: String,
    pub offset: usize,
    pub dtype: Dtype,
}

impl Dtype {
    /// Bytes per element.
    pub fn size(&self) -> usize {
        match self {
            Dtype::Scalar(s) => s.size,
            Dtype::Opaque { size, .. } => *size,
            Dtype::Record { itemsize, .. } => *itemsize,
        }
    }
}

/// A parsed `.npy` header.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NpyHeader {
    pub version: (u8, u8),
    pub dtype: Dtype,
    pub fortran_order: bool,
    pub shape: Vec<u64>,
    /// Byte offset of the data from the start of the `.npy` stream.
    pub data_offset: u64,
    /// The dict exactly as stored (trimmed), for metadata.
    pub text: String,
}

impl NpyHeader {
    /// Number of elements (product of the shape), `None` if it overflows `u64`.
    pub fn count(&self) -> Option<u64> {
        self.shape
            .iter()
            .try_fold(1u64, |acc, &d| acc.checked_mul(d))
    }
}

/// Read and parse the header at the current position of `reader`; afterwards `reader` stands
/// at the first data byte.
pub(crate) fn read_header(reader: &mut dyn Read, context: &str) -> Result<NpyHeader> {
    let mut pre = [0u8; 8];
    let n = read_up_to(reader, &mut pre)?;
    if n < 8 || &pre[..6] != b"\x93NUMPY" {
        return Err(Error::corrupt(
            context,
            0,
            "not a NumPy .npy stream (no `\\x93NUMPY` magic)",
        ));
    }
    let version = (pre[6], pre[7]);
    let (len_bytes, utf8) = match version.0 {
        1 => (2usize, false),
        2 => (4, false),
        3 => (4, true),
        major => {
            return Err(Error::unsupported(
                context,
                format!(
                    ".npy format version {major}.{} is unknown (1.0, 2.0 and 3.0 exist)",
                    version.1
                ),
            ))
        }
    };
    let mut len = [0u8; 4];
    if read_up_to(reader, &mut len[..len_bytes])? < len_bytes {
        return Err(Error::corrupt(
            context,
            8,
            ".npy file ends inside its header length",
        ));
    }
    let header_len = u32::from_le_bytes(len) as usize;
    let prefix = 8 + len_bytes as u64;
    if header_len > MAX_HEADER_BYTES {
        return Err(Error::corrupt(
            context,
            8,
            format!(
                ".npy header claims {header_len} bytes; more than {MAX_HEADER_BYTES} is not a real header"
            ),
        ));
    }
    let mut raw = vec![0u8; header_len];
    if read_up_to(reader, &mut raw)? < header_len {
        return Err(Error::corrupt(
            context,
            prefix,
            format!(".npy file ends inside its {header_len}-byte header"),
        ));
    }
    let text: String = if utf8 {
        String::from_utf8_lossy(&raw).into_owned()
    } else {
        raw.iter().map(|&b| b as char).collect()
    };
    let data_offset = prefix + header_len as u64;
    parse_dict(&text, context, prefix).map(|(dtype, fortran_order, shape)| NpyHeader {
        version,
        dtype,
        fortran_order,
        shape,
        data_offset,
        text: text.trim().to_string(),
    })
}

fn parse_dict(text: &str, context: &str, offset: u64) -> Result<(Dtype, bool, Vec<u64>)> {
    let bad = |message: String| Error::corrupt(context, offset, message);
    let value =
        parse_literal(text).map_err(|e| bad(format!(".npy header is not a dict literal: {e}")))?;
    let Py::Dict(entries) = value else {
        return Err(bad(".npy header is not a dict".into()));
    };
    let get = |key: &str| {
        entries
            .iter()
            .find(|(k, _)| matches!(k, Py::Str(s) if s == key))
            .map(|(_, v)| v)
    };
    let descr = get("descr").ok_or_else(|| bad(".npy header has no `descr`".into()))?;
    let dtype = dtype_of(descr, 0).map_err(|e| bad(format!(".npy `descr`: {e}")))?;
    let fortran_order = match get("fortran_order") {
        None => false,
        Some(Py::Bool(b)) => *b,
        Some(Py::Int(i)) => *i != 0,
        Some(other) => {
            return Err(bad(format!(
                ".npy `fortran_order` is {other:?}, not a bool"
            )))
        }
    };
    let shape = match get("shape") {
        Some(Py::Tuple(items)) | Some(Py::List(items)) => items
            .iter()
            .map(|d| match d {
                Py::Int(v) => u64::try_from(*v).map_err(|_| ()),
                _ => Err(()),
            })
            .collect::<std::result::Result<Vec<u64>, ()>>()
            .map_err(|_| bad(".npy `shape` must hold non-negative integers".into()))?,
        Some(Py::Int(v)) => {
            vec![u64::try_from(*v).map_err(|_| bad(".npy `shape` must be non-negative".into()))?]
        }
        _ => return Err(bad(".npy header has no `shape` tuple".into())),
    };
    Ok((dtype, fortran_order, shape))
}

/// Nesting deeper than this in a `descr` is rejected.
const MAX_DTYPE_DEPTH: usize = 8;

/// The dtype a `descr` value describes.
pub(crate) fn dtype_of(descr: &Py, depth: usize) -> std::result::Result<Dtype, String> {
    if depth > MAX_DTYPE_DEPTH {
        return Err("nested too deeply".into());
    }
    match descr {
        Py::Str(s) => parse_type_str(s),
        Py::List(items) => record_from_list(items, depth),
        Py::Dict(entries) => record_from_dict(entries, depth),
        Py::Tuple(items) => match items.as_slice() {
            [base, shape] => {
                let base = dtype_of(base, depth + 1)?;
                let count = shape_count(shape)?;
                let size = checked_size(base.size(), count)?;
                Ok(Dtype::Opaque {
                    size,
                    what: "sub-array".into(),
                })
            }
            _ => Err(format!("unexpected tuple {descr:?}")),
        },
        other => Err(format!("unexpected value {other:?}")),
    }
}

fn checked_size(size: usize, count: u64) -> std::result::Result<usize, String> {
    usize::try_from(count)
        .ok()
        .and_then(|c| size.checked_mul(c))
        .filter(|&s| s <= MAX_ITEMSIZE)
        .ok_or_else(|| format!("element larger than {MAX_ITEMSIZE} bytes"))
}

fn shape_count(shape: &Py) -> std::result::Result<u64, String> {
    match shape {
        Py::Int(v) => u64::try_from(*v).map_err(|_| "negative sub-array shape".to_string()),
        Py::Tuple(items) | Py::List(items) => items.iter().try_fold(1u64, |acc, d| match d {
            Py::Int(v) => u64::try_from(*v)
                .ok()
                .and_then(|v| acc.checked_mul(v))
                .ok_or_else(|| "bad sub-array shape".to_string()),
            _ => Err("bad sub-array shape".to_string()),
        }),
        _ => Err("bad sub-array shape".into()),
    }
}

fn field_name(name: &Py) -> std::result::Result<String, String> {
    match name {
        Py::Str(s) => Ok(s.clone()),
        // (title, name)
        Py::Tuple(items) => match items.as_slice() {
            [_, Py::Str(s)] => Ok(s.clone()),
            _ => Err("field name is not a string".into()),
        },
        _ => Err(format!("field name {name:?} is not a string")),
    }
}

fn record_from_list(items: &[Py], depth: usize) -> std::result::Result<Dtype, String> {
    let mut fields = Vec::with_capacity(items.len());
    let mut offset = 0usize;
    for item in items {
        let (Py::Tuple(parts) | Py::List(parts)) = item else {
            return Err(format!("field {item:?} is not a (name, type) tuple"));
        };
        let (name, dtype) = match parts.as_slice() {
            [name, ty] => (field_name(name)?, dtype_of(ty, depth + 1)?),
            [name, ty, shape] => {
                let base = dtype_of(ty, depth + 1)?;
                let size = checked_size(base.size(), shape_count(shape)?)?;
                (
                    field_name(name)?,
                    Dtype::Opaque {
                        size,
                        what: "sub-array".into(),
                    },
                )
            }
            _ => return Err(format!("field {item:?} is not a (name, type) tuple")),
        };
        let size = dtype.size();
        fields.push(RecordField {
            name,
            offset,
            dtype,
        });
        offset = offset
            .checked_add(size)
            .filter(|&o| o <= MAX_ITEMSIZE)
            .ok_or_else(|| format!("record larger than {MAX_ITEMSIZE} bytes"))?;
    }
    Ok(Dtype::Record {
        fields,
        itemsize: offset,
    })
}

fn record_from_dict(entries: &[(Py, Py)], depth: usize) -> std::result::Result<Dtype, String> {
    let get = |key: &str| {
        entries
            .iter()
            .find(|(k, _)| matches!(k, Py::Str(s) if s == key))
            .map(|(_, v)| v)
    };
    let list = |key: &str| match get(key) {
        Some(Py::List(v)) | Some(Py::Tuple(v)) => Ok(Some(v.as_slice())),
        None => Ok(None),
        Some(_) => Err(format!("`{key}` is not a list")),
    };
    let names = list("names")?.ok_or("dict descr has no `names`")?;
    let formats = list("formats")?.ok_or("dict descr has no `formats`")?;
    if names.len() != formats.len() {
        return Err("`names` and `formats` differ in length".into());
    }
    let offsets = list("offsets")?;
    if offsets.is_some_and(|o| o.len() != names.len()) {
        return Err("`offsets` and `names` differ in length".into());
    }
    let mut fields = Vec::with_capacity(names.len());
    let mut packed = 0usize;
    let mut end = 0usize;
    for (i, (name, format)) in names.iter().zip(formats).enumerate() {
        let dtype = dtype_of(format, depth + 1)?;
        let offset = match offsets.and_then(|o| o.get(i)) {
            Some(Py::Int(v)) => usize::try_from(*v)
                .ok()
                .filter(|&o| o <= MAX_ITEMSIZE)
                .ok_or_else(|| format!("bad offset {v}"))?,
            Some(other) => return Err(format!("offset {other:?} is not an integer")),
            None => packed,
        };
        let size = dtype.size();
        packed = offset + size;
        end = end.max(packed);
        fields.push(RecordField {
            name: field_name(name)?,
            offset,
            dtype,
        });
    }
    let itemsize = match get("itemsize") {
        Some(Py::Int(v)) => usize::try_from(*v)
            .ok()
            .filter(|&s| s <= MAX_ITEMSIZE)
            .ok_or_else(|| format!("bad itemsize {v}"))?,
        Some(other) => return Err(format!("itemsize {other:?} is not an integer")),
        None => end,
    };
    if end > itemsize {
        return Err(format!(
            "fields end at byte {end}, beyond the itemsize {itemsize}"
        ));
    }
    Ok(Dtype::Record { fields, itemsize })
}

/// Parse a NumPy type string such as `<i8`, `|u1`, `|b1`, `?`, `>f4`, `<M8[us]`, `|V3`,
/// `uint16` or `float64`. `=` (native) is read as little-endian.
pub(crate) fn parse_type_str(s: &str) -> std::result::Result<Dtype, String> {
    let s = s.trim();
    let (big_endian, body) = match s.as_bytes().first() {
        Some(b'<') | Some(b'|') | Some(b'=') => (false, &s[1..]),
        Some(b'>') | Some(b'!') => (true, &s[1..]),
        _ => (false, s),
    };
    let scalar = |kind: Kind, size: usize| {
        Ok(Dtype::Scalar(Scalar {
            kind,
            size,
            big_endian,
        }))
    };
    // Single-character codes and NumPy names.
    match body {
        "?" | "bool" | "bool_" | "b1" => return scalar(Kind::Bool, 1),
        "b" | "int8" => return scalar(Kind::Int, 1),
        "B" | "uint8" => return scalar(Kind::UInt, 1),
        "h" | "int16" => return scalar(Kind::Int, 2),
        "H" | "uint16" => return scalar(Kind::UInt, 2),
        "i" | "int32" => return scalar(Kind::Int, 4),
        "I" | "uint32" => return scalar(Kind::UInt, 4),
        "l" | "q" | "int64" | "int" => return scalar(Kind::Int, 8),
        "L" | "Q" | "uint64" => return scalar(Kind::UInt, 8),
        "e" | "float16" => return scalar(Kind::Float, 2),
        "f" | "float32" => return scalar(Kind::Float, 4),
        "d" | "float64" | "float" => return scalar(Kind::Float, 8),
        _ => {}
    }
    if let Some(rest) = body.strip_prefix("M8").or_else(|| body.strip_prefix("m8")) {
        let unit = match rest.trim_start_matches('[').trim_end_matches(']') {
            "s" => DateUnit::Seconds,
            "ms" => DateUnit::Millis,
            "us" | "μs" | "µs" => DateUnit::Micros,
            "ns" => DateUnit::Nanos,
            _ => DateUnit::Other,
        };
        return scalar(Kind::Date(unit), 8);
    }
    let Some(code) = body.chars().next() else {
        return Err("empty type string".into());
    };
    let digits = &body[code.len_utf8()..];
    let n: usize = digits.parse().map_err(|_| format!("unknown type `{s}`"))?;
    match (code, n) {
        ('b', 1) => scalar(Kind::Bool, 1),
        ('i', 1 | 2 | 4 | 8) => scalar(Kind::Int, n),
        ('u', 1 | 2 | 4 | 8) => scalar(Kind::UInt, n),
        ('f', 2 | 4 | 8) => scalar(Kind::Float, n),
        ('O', _) => Err("object arrays (pickled Python objects) cannot be read".into()),
        ('V' | 'S' | 'a' | 'c' | 'f' | 'U', _) => {
            let size = if code == 'U' {
                n.checked_mul(4)
            } else {
                Some(n)
            }
            .filter(|&b| b <= MAX_ITEMSIZE)
            .ok_or_else(|| format!("type `{s}` is too large"))?;
            Ok(Dtype::Opaque {
                size,
                what: format!("`{s}`"),
            })
        }
        _ => Err(format!("unknown type `{s}`")),
    }
}
