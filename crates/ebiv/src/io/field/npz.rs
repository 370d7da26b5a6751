//! Vector fields from NumPy `.npz` archives in the layout of ebiv's NPZ export
//! ([`crate::export::write_field_npz`]): `x`, `y` (px), `t_us` and, over `(time, y, x)`, `u`,
//! `v` in image units, optional `u_unc`, `v_unc`, `status`, `peak`, `peak_ratio`,
//! `event_count`, `slab_us` and the derived quantities in image units (`vorticity`, …;
//! [`crate::derived`]); the calibration, the units, what the times are and the series'
//! attributes from the `attributes` array of `key=value` strings. The arrays in physical
//! units (`u_m_s`, `x_mm`, `vorticity_1_s`, …) repeat these and are not read.

use super::FieldReadOptions;
use crate::derived::{DerivedField, DerivedQuantity};
use crate::error::{Error, Result};
use crate::field::{Calibration, FieldSeries, Quantity, Status, TimeBasis};
use crate::io::npy::{read_header, Dtype, Num, Scalar};
use std::io::Read;
use std::path::Path;

/// Largest member read, bytes (as for text tables).
const MAX_MEMBER_BYTES: u64 = super::MAX_TEXT_BYTES;

/// Attributes the writer sets itself, not copied into the series' attributes.
const OWN_ATTRIBUTES: [&str; 12] = [
    "software",
    "axis_convention",
    "field_time",
    "time_units",
    "length_units",
    "velocity_units",
    "time_origin_us",
    "status_flags",
    "slab_us",
    "mm_per_px",
    "origin_px",
    "y_positive",
];

/// One array of the archive: its shape and raw little- or big-endian elements.
struct Array {
    shape: Vec<usize>,
    dtype: Dtype,
    data: Vec<u8>,
}

type Reader = std::io::BufReader<std::fs::File>;

struct Archive {
    zip: zip::ZipArchive<Reader>,
    context: String,
}

impl Archive {
    fn err(&self, message: impl Into<String>) -> Error {
        Error::unsupported(self.context.clone(), message)
    }

    fn has(&self, name: &str) -> bool {
        self.zip.index_for_name(&format!("{name}.npy")).is_some()
    }

    /// The member of array `name` and its name for messages; `None` when the archive has
    /// none.
    fn member(&mut self, name: &str) -> Result<Option<(zip::read::ZipFile<'_, Reader>, String)>> {
        let member_name = format!("{name}.npy");
        let context = format!("{}: {member_name}", self.context);
        let Some(index) = self.zip.index_for_name(&member_name) else {
            return Ok(None);
        };
        let member = self
            .zip
            .by_index(index)
            .map_err(|e| Error::unsupported(context.clone(), e.to_string()))?;
        Ok(Some((member, context)))
    }

    /// The number of values of array `name` from its header alone, `None` when the archive
    /// has none.
    fn values_in(&mut self, name: &str) -> Result<Option<u64>> {
        let Some((mut member, context)) = self.member(name)? else {
            return Ok(None);
        };
        let header = read_header(&mut member, &context)?;
        header
            .count()
            .map(Some)
            .ok_or_else(|| Error::unsupported(context, "the array is too large"))
    }

    /// The array `name`, `None` when the archive has none.
    fn array(&mut self, name: &str) -> Result<Option<Array>> {
        let Some((mut member, context)) = self.member(name)? else {
            return Ok(None);
        };
        if member.size() > MAX_MEMBER_BYTES {
            return Err(Error::unsupported(
                context,
                format!(
                    "{} bytes, more than the {MAX_MEMBER_BYTES} read",
                    member.size()
                ),
            ));
        }
        let header = read_header(&mut member, &context)?;
        if header.fortran_order {
            return Err(Error::unsupported(
                context,
                "Fortran order; ebiv reads C-order arrays",
            ));
        }
        let shape: Vec<usize> = header
            .shape
            .iter()
            .map(|&d| usize::try_from(d).unwrap_or(usize::MAX))
            .collect();
        let bytes = header
            .count()
            .and_then(|c| c.checked_mul(header.dtype.size() as u64))
            .filter(|&b| b <= MAX_MEMBER_BYTES)
            .ok_or_else(|| Error::unsupported(context.clone(), "the array is too large"))?;
        let mut data = Vec::new();
        member
            .by_ref()
            .take(bytes)
            .read_to_end(&mut data)
            .map_err(|e| Error::unsupported(context.clone(), e.to_string()))?;
        if data.len() as u64 != bytes {
            return Err(Error::unsupported(
                context,
                format!("{} bytes of data, the shape needs {bytes}", data.len()),
            ));
        }
        Ok(Some(Array {
            shape,
            dtype: header.dtype,
            data,
        }))
    }

    /// The numbers of array `name`, which must hold `len` of them; `None` when absent.
    fn numbers(&mut self, name: &str, len: usize) -> Result<Option<Vec<Num>>> {
        let Some(a) = self.array(name)? else {
            return Ok(None);
        };
        let Dtype::Scalar(scalar) = a.dtype else {
            return Err(self.err(format!("`{name}` is not an array of numbers")));
        };
        let count: usize = a.shape.iter().product();
        if count != len {
            return Err(self.err(format!(
                "`{name}` has shape {:?} ({count} values), the grid needs {len}",
                a.shape
            )));
        }
        Ok(Some(
            a.data
                .chunks_exact(scalar.size)
                .map(|b| number(&scalar, b))
                .collect(),
        ))
    }

    fn f64s(&mut self, name: &str, len: usize) -> Result<Option<Vec<f64>>> {
        Ok(self
            .numbers(name, len)?
            .map(|v| v.into_iter().map(as_f64).collect()))
    }

    fn f32s(&mut self, name: &str, len: usize) -> Result<Option<Vec<f32>>> {
        Ok(self
            .numbers(name, len)?
            .map(|v| v.into_iter().map(|n| as_f64(n) as f32).collect()))
    }

    /// A 1-D array whose length gives an axis.
    fn axis(&mut self, name: &str) -> Result<Vec<Num>> {
        let a = self
            .array(name)?
            .ok_or_else(|| self.err(format!("no array `{name}`: not an ebiv vector field")))?;
        let Dtype::Scalar(scalar) = a.dtype else {
            return Err(self.err(format!("`{name}` is not an array of numbers")));
        };
        if a.shape.len() != 1 {
            return Err(self.err(format!("`{name}` has shape {:?}, not 1-D", a.shape)));
        }
        Ok(a.data
            .chunks_exact(scalar.size)
            .map(|b| number(&scalar, b))
            .collect())
    }

    /// The `key=value` strings of the `attributes` array.
    fn attributes(&mut self) -> Result<Vec<(String, String)>> {
        let Some(a) = self.array("attributes")? else {
            return Ok(Vec::new());
        };
        let size = a.dtype.size();
        let unicode = matches!(&a.dtype, Dtype::Opaque { what, .. } if what.contains('U'));
        if !unicode || size % 4 != 0 || size == 0 {
            return Err(self.err("`attributes` is not an array of strings"));
        }
        Ok(a.data
            .chunks_exact(size)
            .map(|b| {
                b.chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .take_while(|&c| c != 0)
                    .map(|c| char::from_u32(c).unwrap_or('\u{fffd}'))
                    .collect::<String>()
            })
            .filter_map(|s| {
                s.split_once('=')
                    .map(|(k, v)| (k.to_string(), v.to_string()))
            })
            .collect())
    }
}

/// The value of one element `b` of type `scalar`.
fn number(scalar: &Scalar, b: &[u8]) -> Num {
    let mut w = [0u8; 8];
    let n = b.len().min(8);
    w[..n].copy_from_slice(&b[..n]);
    let v = u64::from_le_bytes(w);
    let v = if scalar.big_endian && n > 1 {
        v.swap_bytes() >> (64 - 8 * n as u32)
    } else {
        v
    };
    scalar.num(v)
}

fn as_f64(n: Num) -> f64 {
    match n {
        Num::I(i) => i as f64,
        Num::U(u) => u as f64,
        Num::F(f) => f,
    }
}

/// Read an ebiv NPZ field file.
pub(super) fn read(path: &Path, options: &FieldReadOptions) -> Result<FieldSeries> {
    let context = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let zip = zip::ZipArchive::new(std::io::BufReader::new(file))
        .map_err(|e| Error::unsupported(context.clone(), format!("not a readable .npz: {e}")))?;
    let mut a = Archive { zip, context };
    for name in ["x", "y", "u", "v"] {
        if !a.has(name) {
            return Err(a.err(format!(
                "no array `{name}`: a vector field needs `x`, `y`, `u`, `v` (ebiv's NPZ \
                 layout); NumPy files of events are read by the event commands"
            )));
        }
    }
    let attributes = a.attributes()?;
    let attribute = |key: &str| {
        attributes
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.trim())
    };
    let xs: Vec<f64> = a.axis("x")?.into_iter().map(as_f64).collect();
    let ys: Vec<f64> = a.axis("y")?.into_iter().map(as_f64).collect();
    let times: Vec<i64> = if a.has("t_us") {
        a.axis("t_us")?
            .into_iter()
            .map(|n| match n {
                Num::I(i) => Ok(i),
                Num::U(u) => i64::try_from(u).map_err(|_| a.err("`t_us` exceeds i64")),
                Num::F(f) if f.is_finite() && f.abs() < 9e18 => Ok(f.round() as i64),
                Num::F(_) => Err(a.err("`t_us` holds values that are not times")),
            })
            .collect::<Result<_>>()?
    } else {
        vec![0]
    };
    // The grid must match `u` before arrays of its size are made: a foreign layout of
    // flattened columns would otherwise ask for len(x)·len(y) nodes per time.
    let nodes = (xs.len() as u64)
        .checked_mul(ys.len() as u64)
        .and_then(|n| n.checked_mul(times.len() as u64));
    let in_u = a.values_in("u")?.unwrap_or(0);
    if nodes != Some(in_u) {
        return Err(a.err(format!(
            "`u` holds {in_u} values, but `x`, `y` and `t_us` make a grid of {} × {} × {} \
             nodes: ebiv's NPZ layout stores `u`, `v` as (time, row, column) arrays on the \
             axes `x`, `y`",
            xs.len(),
            ys.len(),
            times.len()
        )));
    }
    let mut s = FieldSeries::new(xs, ys, times);
    let n = s.u.len();
    let quantity = match attribute("velocity_units") {
        None | Some("px/ms") | Some("m/s") => Quantity::Velocity,
        Some("px") | Some("mm") => Quantity::Displacement,
        Some(other) => {
            return Err(a.err(format!(
                "`velocity_units` is `{other}`; expected px/ms, px, m/s or mm"
            )))
        }
    };
    s.quantity = quantity;
    s.time_basis = [
        TimeBasis::SlabCentre,
        TimeBasis::FrameCentre,
        TimeBasis::Instant,
        TimeBasis::PairIndex,
    ]
    .into_iter()
    .find(|b| attribute("field_time") == Some(b.describe()))
    .unwrap_or(if attribute("time_units") == Some("1 (index)") {
        TimeBasis::PairIndex
    } else {
        TimeBasis::SlabCentre
    });
    s.u = a.f32s("u", n)?.unwrap_or_default();
    s.v = a.f32s("v", n)?.unwrap_or_default();
    if let Some(v) = a.f32s("u_unc", n)? {
        s.u_unc = v;
    }
    if let Some(v) = a.f32s("v_unc", n)? {
        s.v_unc = v;
    }
    s.ground_truth = attribute("status_flags").is_none();
    match a.numbers("status", n)? {
        Some(st) => {
            s.status = st
                .iter()
                .enumerate()
                .map(|(i, &v)| match v {
                    Num::U(b) if b <= 255 => Ok(Status(b as u8)),
                    Num::I(b) if (0..=255).contains(&b) => Ok(Status(b as u8)),
                    other => Err(a.err(format!(
                        "`status` holds {} (vector {i}), not 0 to 255",
                        as_f64(other)
                    ))),
                })
                .collect::<Result<_>>()?;
        }
        None => s.status = super::status_from_values(&s.u, &s.v),
    }
    if let Some(v) = a.f32s("peak", n)? {
        s.peak = v;
    }
    if let Some(v) = a.f32s("peak_ratio", n)? {
        s.peak_ratio = v;
    }
    let counts = super::counts_from_values;
    if let Some(v) = a.f64s("event_count", n)? {
        s.event_count = counts(v);
    }
    if let Some(v) = a.f64s("slab_us", n)? {
        s.slab_us = counts(v);
    }
    let mut derived_names = Vec::new();
    for q in DerivedQuantity::ALL {
        if let Some(values) = a.f32s(q.name(), n)? {
            s.derived.push(DerivedField {
                quantity: q,
                values,
            });
        }
        derived_names.push(q.name().to_string());
        derived_names.extend(
            [Quantity::Velocity, Quantity::Displacement]
                .into_iter()
                .filter_map(|quantity| {
                    let c = Calibration {
                        mm_per_px: 1.0,
                        origin_px: [0.0, 0.0],
                        y_up: true,
                    };
                    q.physical_name(quantity, Some(&c))
                }),
        );
    }
    if let (Quantity::Displacement, Some(dt)) = (s.quantity, options.frame_interval_us) {
        let k = 1000.0 / dt;
        s.u.iter_mut()
            .chain(s.v.iter_mut())
            .chain(s.u_unc.iter_mut())
            .chain(s.v_unc.iter_mut())
            .chain(s.derived.iter_mut().flat_map(|d| d.values.iter_mut()))
            .for_each(|w| *w = (*w as f64 * k) as f32);
        s.quantity = Quantity::Velocity;
    }
    if let Some(mm) = attribute("mm_per_px").and_then(|v| v.parse::<f64>().ok()) {
        let origin: Vec<f64> = attribute("origin_px")
            .unwrap_or("0 0")
            .split_whitespace()
            .filter_map(|v| v.parse().ok())
            .collect();
        let c = Calibration {
            mm_per_px: mm,
            origin_px: [
                origin.first().copied().unwrap_or(0.0),
                origin.get(1).copied().unwrap_or(0.0),
            ],
            y_up: attribute("y_positive") == Some("up"),
        };
        c.validate()?;
        s.calibration = Some(c);
    }
    s.time_origin_us = attribute("time_origin_us").and_then(|v| v.parse().ok());
    s.attributes = attributes
        .iter()
        .filter(|(k, _)| !OWN_ATTRIBUTES.contains(&k.as_str()) && !derived_names.contains(k))
        .cloned()
        .collect();
    Ok(s)
}
