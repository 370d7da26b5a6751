//! Field splitting and number parsing for text event lists (formats.md §11): hand-written,
//! allocation-free, exact for decimal times.

use super::{PolarityEncoding, TextColumn};
use crate::io::npy::{Num, TimeConv};

/// How fields are separated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delim {
    /// One character (`,`, `;`); blanks around fields are trimmed.
    Char(u8),
    /// Runs of spaces and tabs.
    Blank,
}

impl Delim {
    pub fn of_byte(b: u8) -> Delim {
        match b {
            b' ' | b'\t' => Delim::Blank,
            c => Delim::Char(c),
        }
    }

    /// The separator a line uses: `;`, else `,`, else blanks.
    pub fn detect(line: &[u8]) -> Delim {
        if line.contains(&b';') {
            Delim::Char(b';')
        } else if line.contains(&b',') {
            Delim::Char(b',')
        } else {
            Delim::Blank
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            Delim::Char(b',') => "commas",
            Delim::Char(b';') => "semicolons",
            Delim::Char(_) => "a custom delimiter",
            Delim::Blank => "spaces/tabs",
        }
    }
}

#[inline]
fn is_blank(b: u8) -> bool {
    b == b' ' || b == b'\t'
}

/// Strip blanks and one pair of surrounding double quotes.
#[inline]
fn trim(mut f: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = f {
        if !is_blank(*first) {
            break;
        }
        f = rest;
    }
    while let [rest @ .., last] = f {
        if !is_blank(*last) {
            break;
        }
        f = rest;
    }
    if let [b'"', inner @ .., b'"'] = f {
        return inner;
    }
    f
}

/// The fields of one line.
pub(crate) struct Fields<'a> {
    line: &'a [u8],
    pos: usize,
    done: bool,
    delim: Delim,
}

impl<'a> Fields<'a> {
    #[inline]
    pub fn new(line: &'a [u8], delim: Delim) -> Self {
        Fields {
            line,
            pos: 0,
            done: false,
            delim,
        }
    }
}

impl<'a> Iterator for Fields<'a> {
    type Item = &'a [u8];

    #[inline]
    fn next(&mut self) -> Option<&'a [u8]> {
        let rest = self.line.get(self.pos..)?;
        match self.delim {
            Delim::Blank => {
                let start = rest.iter().position(|&b| !is_blank(b))?;
                let len = rest[start..]
                    .iter()
                    .position(|&b| is_blank(b))
                    .unwrap_or(rest.len() - start);
                self.pos += start + len;
                rest.get(start..start + len)
            }
            Delim::Char(d) => {
                if self.done {
                    return None;
                }
                match rest.iter().position(|&b| b == d) {
                    Some(i) => {
                        self.pos += i + 1;
                        rest.get(..i).map(trim)
                    }
                    None => {
                        self.done = true;
                        Some(trim(rest))
                    }
                }
            }
        }
    }
}

/// A plain decimal integer with an optional sign.
#[inline]
pub(crate) fn parse_i64(f: &[u8]) -> Option<i64> {
    let (neg, digits) = match f {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, f),
    };
    if digits.is_empty() || digits.len() > 19 {
        return None;
    }
    let mut v: u64 = 0;
    for &b in digits {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        v = v.checked_mul(10)?.checked_add(d as u64)?;
    }
    if neg {
        if v <= i64::MAX as u64 + 1 {
            Some((v as i64).wrapping_neg())
        } else {
            None
        }
    } else {
        i64::try_from(v).ok()
    }
}

/// A decimal number `mantissa × 10^exponent`, parsed from its digits without rounding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Decimal {
    pub mantissa: i128,
    pub exponent: i32,
}

/// Significant digits kept; further fractional digits are dropped (they cannot change a
/// µs value of any realistic recording).
const MAX_DIGITS: u32 = 30;

/// Parse `[-+]digits[.digits][(e|E)[-+]digits]`; `comma` also accepts `,` as the decimal
/// point.
pub(crate) fn parse_decimal(f: &[u8], comma: bool) -> Option<Decimal> {
    let (neg, body) = match f {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, f),
    };
    let mut mantissa: i128 = 0;
    let mut exponent: i32 = 0;
    let mut significant = 0u32;
    let mut any_digit = false;
    let mut after_point = false;
    let mut i = 0;
    while let Some(&b) = body.get(i) {
        match b {
            b'0'..=b'9' => {
                any_digit = true;
                if significant < MAX_DIGITS {
                    mantissa = mantissa * 10 + (b - b'0') as i128;
                    if mantissa != 0 {
                        significant += 1;
                    }
                    if after_point {
                        exponent = exponent.saturating_sub(1);
                    }
                } else if !after_point {
                    exponent = exponent.saturating_add(1);
                }
            }
            b'.' if !after_point => after_point = true,
            b',' if comma && !after_point => after_point = true,
            _ => break,
        }
        i += 1;
    }
    if !any_digit {
        return None;
    }
    if let Some(&(b'e' | b'E')) = body.get(i) {
        i += 1;
        let (eneg, start) = match body.get(i) {
            Some(b'-') => (true, i + 1),
            Some(b'+') => (false, i + 1),
            _ => (false, i),
        };
        let digits = body.get(start..)?;
        if digits.is_empty() || !digits.iter().all(u8::is_ascii_digit) {
            return None;
        }
        let mut e: i32 = 0;
        for &d in digits {
            e = (e * 10 + (d - b'0') as i32).min(100_000);
        }
        exponent = exponent.checked_add(if eneg { -e } else { e })?;
        i = body.len();
    }
    if i != body.len() {
        return None;
    }
    Some(Decimal {
        mantissa: if neg { -mantissa } else { mantissa },
        exponent,
    })
}

impl Decimal {
    /// `self × num / den` rounded half away from zero, if it fits in `i64`.
    pub fn scaled(self, num: i64, den: i64) -> Option<i64> {
        if self.mantissa == 0 {
            return Some(0);
        }
        let mut n = self.mantissa.checked_mul(num as i128)?;
        let mut d = den as i128;
        if self.exponent >= 0 {
            for _ in 0..self.exponent {
                n = n.checked_mul(10)?;
            }
        } else {
            for _ in 0..self.exponent.unsigned_abs() {
                match d.checked_mul(10) {
                    Some(v) => d = v,
                    // |value| < 10^38 / 10^38: rounds to zero.
                    None => return Some(0),
                }
            }
        }
        let (q, r) = (n / d, n % d);
        let q = if r.abs() >= d - r.abs() {
            q + n.signum()
        } else {
            q
        };
        i64::try_from(q).ok()
    }

    /// The value if it is a whole number that fits in `i64`.
    pub fn integral(self) -> Option<i64> {
        if self.exponent >= 0 || self.mantissa == 0 {
            return self.scaled(1, 1);
        }
        let mut p: i128 = 1;
        for _ in 0..self.exponent.unsigned_abs() {
            p = p.checked_mul(10)?;
        }
        if self.mantissa % p != 0 {
            return None;
        }
        i64::try_from(self.mantissa / p).ok()
    }

    pub fn to_f64(self) -> f64 {
        self.mantissa as f64 * 10f64.powi(self.exponent)
    }
}

/// Why a line is malformed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Bad {
    Missing { found: usize, need: usize },
    Time,
    Coordinate(TextColumn),
    Polarity,
}

impl std::fmt::Display for Bad {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Bad::Missing { found, need } => {
                write!(f, "{found} fields where {need} are needed")
            }
            Bad::Time => write!(f, "the time is not a number"),
            Bad::Coordinate(c) => write!(f, "{} is not an integer", c.letter()),
            Bad::Polarity => write!(f, "the polarity is not one the polarity setting accepts"),
        }
    }
}

/// What became of one data line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Line {
    Event(i64, u16, u16, u8),
    OutOfRange,
    Malformed(Bad),
}

/// Parses the data lines of one file.
#[derive(Debug, Clone)]
pub(crate) struct LineParser {
    /// Column roles up to the last needed one.
    pub roles: Vec<TextColumn>,
    pub delim: Delim,
    pub time: TimeConv,
    pub polarity: PolarityEncoding,
    /// Whether `,` may be a decimal point (when it is not the delimiter).
    pub comma_decimal: bool,
    pub width: u32,
    pub height: u32,
}

/// A coordinate: `Ok(Some(v))` in 0..=65535, `Ok(None)` out of range, `Err` not a number.
#[inline]
fn parse_coord(f: &[u8], comma: bool) -> Result<Option<u16>, ()> {
    let v = match parse_i64(f) {
        Some(v) => v,
        // Only integral values such as `12.0`.
        None => parse_decimal(f, comma)
            .and_then(Decimal::integral)
            .ok_or(())?,
    };
    Ok(u16::try_from(v).ok())
}

impl LineParser {
    #[inline]
    fn time(&self, f: &[u8]) -> Option<i64> {
        if let Some(v) = parse_i64(f) {
            return self.time.micros(Num::I(v));
        }
        let d = parse_decimal(f, self.comma_decimal)?;
        match self.time {
            TimeConv::Ratio(num, den) => d.scaled(num, den),
            TimeConv::Factor(k) => {
                let us = d.to_f64() * k;
                (us.is_finite() && us.abs() < 9.2e18).then(|| us.round() as i64)
            }
        }
    }

    #[inline]
    fn polarity(&self, f: &[u8]) -> Option<u8> {
        let word = |f: &[u8]| {
            if f.eq_ignore_ascii_case(b"true") {
                Some(1)
            } else if f.eq_ignore_ascii_case(b"false") {
                Some(0)
            } else {
                None
            }
        };
        match self.polarity {
            PolarityEncoding::Auto => match f {
                b"1" | b"+1" => Some(1),
                b"0" | b"-1" => Some(0),
                _ => word(f),
            },
            PolarityEncoding::ZeroOne => match f {
                b"1" => Some(1),
                b"0" => Some(0),
                _ => None,
            },
            PolarityEncoding::MinusOneOne => match f {
                b"1" | b"+1" => Some(1),
                b"-1" => Some(0),
                _ => None,
            },
            PolarityEncoding::FalseTrue => word(f),
        }
    }

    /// Parse one data line (no line end, not a comment).
    #[inline]
    pub fn parse(&self, line: &[u8]) -> Line {
        let mut fields = Fields::new(line, self.delim);
        let (mut t, mut x, mut y, mut p) = (None, None, None, None);
        let mut out_of_range = false;
        let mut bad = None;
        for (i, &role) in self.roles.iter().enumerate() {
            let Some(f) = fields.next() else {
                return Line::Malformed(Bad::Missing {
                    found: i,
                    need: self.roles.len(),
                });
            };
            match role {
                TextColumn::T => match self.time(f) {
                    Some(v) => t = Some(v),
                    None => bad = bad.or(Some(Bad::Time)),
                },
                TextColumn::X | TextColumn::Y => match parse_coord(f, self.comma_decimal) {
                    Ok(Some(v)) => {
                        if role == TextColumn::X {
                            x = Some(v);
                        } else {
                            y = Some(v);
                        }
                    }
                    Ok(None) => out_of_range = true,
                    Err(()) => bad = bad.or(Some(Bad::Coordinate(role))),
                },
                TextColumn::P => match self.polarity(f) {
                    Some(v) => p = Some(v),
                    None => bad = bad.or(Some(Bad::Polarity)),
                },
                TextColumn::Skip => {}
            }
        }
        if let Some(b) = bad {
            return Line::Malformed(b);
        }
        match (t, x, y, p) {
            (Some(t), Some(x), Some(y), Some(p)) if !out_of_range => {
                if (x as u32) < self.width && (y as u32) < self.height {
                    Line::Event(t, x, y, p)
                } else {
                    Line::OutOfRange
                }
            }
            _ => Line::OutOfRange,
        }
    }
}

/// Index of the first `needle` in `hay`, eight bytes at a time.
#[inline]
pub(crate) fn find_byte(hay: &[u8], needle: u8) -> Option<usize> {
    const LO: u64 = 0x0101_0101_0101_0101;
    const HI: u64 = 0x8080_8080_8080_8080;
    let pattern = LO * needle as u64;
    let mut chunks = hay.chunks_exact(8);
    let mut base = 0;
    for chunk in &mut chunks {
        let mut w = [0u8; 8];
        w.copy_from_slice(chunk);
        let x = u64::from_le_bytes(w) ^ pattern;
        let found = x.wrapping_sub(LO) & !x & HI;
        if found != 0 {
            return Some(base + (found.trailing_zeros() / 8) as usize);
        }
        base += 8;
    }
    chunks
        .remainder()
        .iter()
        .position(|&b| b == needle)
        .map(|i| base + i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_cover_the_i64_range() {
        assert_eq!(parse_i64(b"0"), Some(0));
        assert_eq!(parse_i64(b"-17"), Some(-17));
        assert_eq!(parse_i64(b"+17"), Some(17));
        assert_eq!(parse_i64(b"9223372036854775807"), Some(i64::MAX));
        assert_eq!(parse_i64(b"-9223372036854775808"), Some(i64::MIN));
        assert_eq!(parse_i64(b"9223372036854775808"), None);
        assert_eq!(parse_i64(b"99999999999999999999"), None);
        for bad in [&b""[..], b"-", b"1.0", b"1e3", b"12a", b" 1"] {
            assert_eq!(parse_i64(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn decimal_seconds_convert_exactly() {
        let us = |s: &str| parse_decimal(s.as_bytes(), false).and_then(|d| d.scaled(1_000_000, 1));
        assert_eq!(us("0.003811000"), Some(3811));
        assert_eq!(us("0.003820001"), Some(3820));
        assert_eq!(
            us("1.0000005"),
            Some(1_000_001),
            "half rounds away from zero"
        );
        assert_eq!(us("-1.0000005"), Some(-1_000_001));
        assert_eq!(us("1.0000004999"), Some(1_000_000));
        assert_eq!(us("1e-6"), Some(1));
        assert_eq!(us("2.5E3"), Some(2_500_000_000));
        assert_eq!(us(".5"), Some(500_000));
        assert_eq!(us("5."), Some(5_000_000));
        assert_eq!(us("1e-400"), Some(0));
        assert_eq!(us("1e400"), None);
        assert_eq!(us("9223372036854.775807"), Some(i64::MAX));
        assert_eq!(us("9223372036854.775808"), None);
        assert_eq!(us("1.2.3"), None);
        assert_eq!(us("e5"), None);
        assert_eq!(us("1e"), None);
        let int = |s: &str| parse_decimal(s.as_bytes(), false).and_then(Decimal::integral);
        assert_eq!(int("12.000"), Some(12));
        assert_eq!(int("12.04"), None);
        assert_eq!(int("1.2e1"), Some(12));
        assert_eq!(int("-3e0"), Some(-3));
        let ns = parse_decimal(b"1500", false).unwrap();
        assert_eq!(ns.scaled(1, 1000), Some(2));
        let comma = parse_decimal(b"0,5", true).unwrap();
        assert_eq!(comma.scaled(1_000_000, 1), Some(500_000));
        // 40 digits: the extra fractional ones are dropped.
        let long = parse_decimal(b"1.000000000000000000000000000000000000009", false).unwrap();
        assert_eq!(long.scaled(1_000_000, 1), Some(1_000_000));
    }

    #[test]
    fn fields_split_on_any_delimiter() {
        let f: Vec<&[u8]> = Fields::new(b" 1\t 2  3 ", Delim::Blank).collect();
        assert_eq!(f, vec![&b"1"[..], b"2", b"3"]);
        let f: Vec<&[u8]> = Fields::new(b"1, 2 ,\"3\",", Delim::Char(b',')).collect();
        assert_eq!(f, vec![&b"1"[..], b"2", b"3", b""]);
    }

    #[test]
    fn find_byte_matches_position() {
        let hay = b"0123456789abcdef\n0123\n";
        for start in 0..hay.len() {
            assert_eq!(
                find_byte(&hay[start..], b'\n'),
                hay[start..].iter().position(|&b| b == b'\n')
            );
        }
        assert_eq!(find_byte(b"\xff\xfe\x0a", b'\n'), Some(2));
        assert_eq!(find_byte(b"\x8a\x0a", b'\n'), Some(1));
    }
}
