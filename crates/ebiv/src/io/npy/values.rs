//! Numbers in `.npy` fields and their conversion to events (formats.md §12): raw bits of
//! any integer, bool, float or datetime type, time in µs, coordinate and polarity checks.

use super::header::{DateUnit, Kind, Scalar};
use crate::event::{EventBuffer, Geometry};
use crate::io::text::TimeUnit;

/// A number read from a field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Num {
    I(i64),
    U(u64),
    F(f64),
}

impl Scalar {
    /// The value stored in `b` (exactly `self.size` bytes).
    #[cfg(test)]
    pub fn read(&self, b: &[u8]) -> Num {
        let mut w = [0u8; 8];
        if let Some(dst) = w.get_mut(..b.len()) {
            dst.copy_from_slice(b);
        }
        let v = u64::from_le_bytes(w);
        let v = if self.big_endian {
            v.swap_bytes() >> (64 - 8 * self.size.clamp(1, 8) as u32)
        } else {
            v
        };
        self.num(v)
    }

    /// The value of raw bits `v` (already in native order, zero-extended).
    #[inline(always)]
    pub fn num(&self, v: u64) -> Num {
        let bits = 8 * self.size.clamp(1, 8) as u32;
        match self.kind {
            Kind::Bool => Num::U((v != 0) as u64),
            Kind::UInt => Num::U(v),
            Kind::Int | Kind::Date(_) => {
                let shift = 64 - bits;
                Num::I(((v << shift) as i64) >> shift)
            }
            Kind::Float => Num::F(match bits {
                16 => f16_to_f64(v as u16),
                32 => f32::from_bits(v as u32) as f64,
                _ => f64::from_bits(v),
            }),
        }
    }

    /// NumPy's spelling of this type, for messages.
    pub fn describe(&self) -> String {
        let order = if self.size == 1 {
            '|'
        } else if self.big_endian {
            '>'
        } else {
            '<'
        };
        let code = match self.kind {
            Kind::Bool => 'b',
            Kind::Int => 'i',
            Kind::UInt => 'u',
            Kind::Float => 'f',
            Kind::Date(_) => 'M',
        };
        format!("{order}{code}{}", self.size)
    }
}

/// IEEE 754 half precision to double.
fn f16_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1F) as i32;
    let frac = (h & 0x3FF) as f64;
    sign * match exp {
        0 => frac * 2f64.powi(-24),
        31 if frac == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        e => (1.0 + frac / 1024.0) * 2f64.powi(e - 15),
    }
}

/// How a time field turns into µs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum TimeConv {
    /// µs = value × num / den (exact for integers, rounded to nearest).
    Ratio(i64, i64),
    /// µs = value × factor, rounded.
    Factor(f64),
}

impl TimeConv {
    /// The conversion for a time field of type `scalar` under the user's `unit`
    /// (`Auto`: integers are µs, floats seconds).
    pub fn for_field(scalar: &Scalar, unit: TimeUnit) -> std::result::Result<TimeConv, String> {
        if let Kind::Date(d) = scalar.kind {
            return match d {
                DateUnit::Seconds => Ok(TimeConv::Ratio(1_000_000, 1)),
                DateUnit::Millis => Ok(TimeConv::Ratio(1000, 1)),
                DateUnit::Micros => Ok(TimeConv::Ratio(1, 1)),
                DateUnit::Nanos => Ok(TimeConv::Ratio(1, 1000)),
                DateUnit::Other => Err(
                    "the time field is a datetime64/timedelta64 in a unit other than s, ms, us or ns"
                        .into(),
                ),
            };
        }
        let unit = match (unit, scalar.kind) {
            (TimeUnit::Auto, Kind::Float) => TimeUnit::Seconds,
            (TimeUnit::Auto, _) => TimeUnit::Microseconds,
            (u, _) => u,
        };
        Ok(match unit.micros_ratio() {
            Some((num, den)) => TimeConv::Ratio(num, den),
            None => TimeConv::Factor(unit.micros_per_unit()),
        })
    }

    /// Time in µs, `None` when not representable.
    #[inline]
    pub fn micros(&self, v: Num) -> Option<i64> {
        match (*self, v) {
            (TimeConv::Ratio(1, 1), Num::I(i)) => Some(i),
            (TimeConv::Ratio(1, 1), Num::U(u)) => i64::try_from(u).ok(),
            (TimeConv::Ratio(num, den), Num::I(i)) => ratio(i as i128, num, den),
            (TimeConv::Ratio(num, den), Num::U(u)) => ratio(u as i128, num, den),
            (TimeConv::Ratio(num, den), Num::F(f)) => float_us(f * num as f64 / den as f64),
            (TimeConv::Factor(k), Num::I(i)) => float_us(i as f64 * k),
            (TimeConv::Factor(k), Num::U(u)) => float_us(u as f64 * k),
            (TimeConv::Factor(k), Num::F(f)) => float_us(f * k),
        }
    }

    pub fn describe(&self) -> String {
        match *self {
            TimeConv::Ratio(1, 1) => "µs".into(),
            TimeConv::Ratio(1_000_000, 1) => "s".into(),
            TimeConv::Ratio(1000, 1) => "ms".into(),
            TimeConv::Ratio(1, 1000) => "ns".into(),
            TimeConv::Ratio(n, d) => format!("units of {n}/{d} µs"),
            TimeConv::Factor(k) => format!("units of {k} µs"),
        }
    }
}

/// `v × num / den` rounded half away from zero, if it fits in `i64`.
#[inline]
fn ratio(v: i128, num: i64, den: i64) -> Option<i64> {
    let n = v.checked_mul(num as i128)?;
    let d = den as i128;
    if d == 1 {
        return i64::try_from(n).ok();
    }
    let (q, r) = (n / d, n % d);
    let q = if 2 * r.abs() >= d { q + n.signum() } else { q };
    i64::try_from(q).ok()
}

#[inline]
fn float_us(us: f64) -> Option<i64> {
    (us.is_finite() && us.abs() < 9.2e18).then(|| us.round() as i64)
}

/// What became of one record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Outcome {
    Kept,
    OutOfRange,
    Malformed(&'static str),
}

/// Turns the four numbers of one record into an event: time conversion, coordinate and
/// geometry checks, polarity mapping.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Converter {
    pub time: TimeConv,
    pub width: u32,
    pub height: u32,
}

impl Converter {
    pub fn new(time: TimeConv, geometry: Option<Geometry>) -> Self {
        let g = geometry.unwrap_or(Geometry::new(u32::MAX, u32::MAX));
        Converter {
            time,
            width: g.width,
            height: g.height,
        }
    }

    #[inline(always)]
    pub fn push(&self, t: Num, x: Num, y: Num, p: Num, out: &mut EventBuffer) -> Outcome {
        let Some(t) = self.time.micros(t) else {
            return Outcome::Malformed("time not representable in i64 µs");
        };
        let (x, y) = match (coord(x), coord(y)) {
            (Coord::Bad, _) | (_, Coord::Bad) => {
                return Outcome::Malformed("coordinate is not an integer")
            }
            (Coord::Out, _) | (_, Coord::Out) => return Outcome::OutOfRange,
            (Coord::At(x), Coord::At(y)) => (x, y),
        };
        if x as u32 >= self.width || y as u32 >= self.height {
            return Outcome::OutOfRange;
        }
        let p = match p {
            Num::I(v) => (v > 0) as u8,
            Num::U(v) => (v > 0) as u8,
            Num::F(f) if f.is_nan() => return Outcome::Malformed("polarity is NaN"),
            Num::F(f) => (f > 0.0) as u8,
        };
        out.push(t, x, y, p);
        Outcome::Kept
    }
}

enum Coord {
    At(u16),
    Out,
    Bad,
}

#[inline]
fn coord(v: Num) -> Coord {
    match v {
        Num::I(i) => u16::try_from(i).map_or(Coord::Out, Coord::At),
        Num::U(u) => u16::try_from(u).map_or(Coord::Out, Coord::At),
        Num::F(f) if !f.is_finite() || f.fract() != 0.0 => Coord::Bad,
        Num::F(f) if (0.0..=65535.0).contains(&f) => Coord::At(f as u16),
        Num::F(_) => Coord::Out,
    }
}

/// The raw bits (native order, zero-extended) of the field at `offset` in every
/// `stride`-byte record of `bytes`, into `raw` (cleared first). The type dispatch happens
/// once per batch, not per value.
pub(crate) fn gather(
    bytes: &[u8],
    stride: usize,
    offset: usize,
    scalar: Scalar,
    raw: &mut Vec<u64>,
) {
    raw.clear();
    let records = bytes.chunks_exact(stride.max(1));
    raw.reserve(records.len());
    macro_rules! each {
        ($n:literal, $conv:expr) => {
            raw.extend(records.map(|rec| {
                let mut w = [0u8; $n];
                if let Some(src) = rec.get(offset..offset + $n) {
                    w.copy_from_slice(src);
                }
                $conv(w) as u64
            }))
        };
    }
    match (scalar.size, scalar.big_endian) {
        (1, _) => each!(1, |w: [u8; 1]| w[0]),
        (2, false) => each!(2, u16::from_le_bytes),
        (2, true) => each!(2, u16::from_be_bytes),
        (4, false) => each!(4, u32::from_le_bytes),
        (4, true) => each!(4, u32::from_be_bytes),
        (8, false) => each!(8, u64::from_le_bytes),
        (8, true) => each!(8, u64::from_be_bytes),
        _ => raw.extend(records.map(|_| 0)),
    }
}
