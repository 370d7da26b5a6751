//! Text and CSV event lists, one event per line (formats.md §11): the Event Camera Dataset's
//! `t x y p` with t in seconds (`0.003811000 96 133 0`), Metavision CSV `x,y,p,t` in µs after
//! a `%geometry:W,H` line, faery's `t,x,y,on` with a header row, and similar.
//!
//! What the reader works out by itself, each overridable through [`TextOptions`]:
//! * **columns**: from a header line naming them (`t`/`ts`/`timestamp`/`time`, `x`, `y`,
//!   `p`/`pol`/`polarity`/`on`; other names are ignored columns; a unit may be attached as in
//!   `t_us`, `t[s]` or `time (ms)`); without a header `t x y p`, or `x y p t` in a Metavision
//!   CSV (one with a `%geometry:` line);
//! * **delimiter**: `;`, else `,`, else runs of tabs/spaces, from the first line;
//! * **time unit**: seconds when the first data line's time has a decimal point, else µs;
//!   decimal times are converted exactly (the digits, not a binary float, rounded to the
//!   nearest µs), so `0.003811000` s is 3811 µs;
//! * **polarity**: 0/1, −1/1 or false/true (−1 and false are OFF);
//! * **geometry**: from a `%geometry:W,H` (or `# geometry: WxH`) comment line, else
//!   [`ReadOptions::geometry`](super::ReadOptions::geometry).
//!
//! Lines starting with `#` or `%` and blank lines are skipped; CRLF line ends and a UTF-8
//! byte-order mark are accepted. Events outside 0..=65535 or the geometry are dropped and
//! counted; malformed lines are skipped and counted with a warning naming the first few line
//! numbers — unless more than 1 % of the data lines are malformed, which is an error. The
//! file is streamed in batches of about `batch_bytes`.

mod parse;
mod reader;

use crate::error::{Error, Result};
use std::str::FromStr;

pub(crate) use reader::open;

/// What one column of a text file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TextColumn {
    /// Time stamp.
    T,
    /// Pixel column.
    X,
    /// Pixel row.
    Y,
    /// Polarity.
    P,
    /// A column ebiv ignores.
    Skip,
}

impl TextColumn {
    /// The column a header name stands for, with the time unit the name carries (`t_us`,
    /// `t[s]`, `time (ms)`). Unknown names are [`TextColumn::Skip`].
    pub fn from_name(name: &str) -> (TextColumn, Option<TimeUnit>) {
        let name = name.trim().trim_matches(|c| c == '"' || c == '\'').trim();
        let lower = name.to_lowercase();
        let (base, unit) = split_unit(&lower);
        let column = match base {
            "t" | "ts" | "timestamp" | "timestamps" | "time" => TextColumn::T,
            "x" => TextColumn::X,
            "y" => TextColumn::Y,
            "p" | "pol" | "polarity" | "polarities" | "on" => TextColumn::P,
            _ => TextColumn::Skip,
        };
        let unit = if column == TextColumn::T { unit } else { None };
        (column, unit)
    }

    fn letter(self) -> &'static str {
        match self {
            TextColumn::T => "t",
            TextColumn::X => "x",
            TextColumn::Y => "y",
            TextColumn::P => "p",
            TextColumn::Skip => "_",
        }
    }
}

/// Split `t_us`, `t[us]`, `t (us)` into the name and a recognised time unit.
fn split_unit(lower: &str) -> (&str, Option<TimeUnit>) {
    if let Some(open) = lower.find(['[', '(']) {
        let inner = lower[open + 1..].trim_end_matches([']', ')']).trim();
        if let Some(unit) = unit_word(inner) {
            return (lower[..open].trim(), Some(unit));
        }
    }
    if let Some(us) = lower.rfind('_') {
        if let Some(unit) = unit_word(&lower[us + 1..]) {
            return (&lower[..us], Some(unit));
        }
    }
    (lower, None)
}

fn unit_word(w: &str) -> Option<TimeUnit> {
    Some(match w {
        "s" | "sec" | "secs" | "second" | "seconds" => TimeUnit::Seconds,
        "ms" | "msec" | "millisecond" | "milliseconds" => TimeUnit::Milliseconds,
        "us" | "µs" | "μs" | "usec" | "microsecond" | "microseconds" => TimeUnit::Microseconds,
        "ns" | "nsec" | "nanosecond" | "nanoseconds" => TimeUnit::Nanoseconds,
        _ => return None,
    })
}

impl FromStr for TextColumn {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match TextColumn::from_name(s) {
            (TextColumn::Skip, _) if !matches!(s.trim(), "_" | "-" | "skip") => {
                Err(Error::parameter(
                    "columns",
                    format!("unknown column `{s}`; use t, x, y, p (or aliases ts, timestamp, pol, polarity, on) and `_` for a column to ignore"),
                ))
            }
            (c, _) => Ok(c),
        }
    }
}

/// Unit of the time column of a text file (and of `.npy`/`.npz` time fields when set).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum TimeUnit {
    /// Seconds when the first data line's time has a decimal point, else microseconds (for
    /// `.npy`/`.npz`: floats are seconds, integers µs).
    #[default]
    Auto,
    /// Seconds.
    Seconds,
    /// Milliseconds.
    Milliseconds,
    /// Microseconds (ebiv's own unit).
    Microseconds,
    /// Nanoseconds (rounded to the nearest µs).
    Nanoseconds,
    /// Microseconds per unit of the file's time column (`1000` for ms); converted through
    /// `f64`, so not exact beyond 15–16 significant digits.
    Scale(f64),
}

impl TimeUnit {
    /// Parse `auto`, `s`, `ms`, `us`/`µs`, `ns`, or a number of µs per unit.
    pub fn parse(s: &str) -> Result<TimeUnit> {
        let t = s.trim().to_lowercase();
        if t == "auto" {
            return Ok(TimeUnit::Auto);
        }
        if let Some(unit) = unit_word(&t) {
            return Ok(unit);
        }
        match t.parse::<f64>() {
            Ok(k) if k.is_finite() && k > 0.0 => Ok(TimeUnit::Scale(k)),
            _ => Err(Error::parameter(
                "time-unit",
                format!("`{s}` is not auto, s, ms, us, ns or a positive number of µs per unit"),
            )),
        }
    }

    /// The exact conversion to µs as `(numerator, denominator)`; `None` for a scale factor.
    /// `Auto` counts as µs.
    pub(crate) fn micros_ratio(self) -> Option<(i64, i64)> {
        match self {
            TimeUnit::Auto | TimeUnit::Microseconds => Some((1, 1)),
            TimeUnit::Seconds => Some((1_000_000, 1)),
            TimeUnit::Milliseconds => Some((1000, 1)),
            TimeUnit::Nanoseconds => Some((1, 1000)),
            TimeUnit::Scale(_) => None,
        }
    }

    /// Microseconds per unit as a float.
    pub(crate) fn micros_per_unit(self) -> f64 {
        match self {
            TimeUnit::Scale(k) => k,
            other => other
                .micros_ratio()
                .map_or(1.0, |(n, d)| n as f64 / d as f64),
        }
    }
}

impl FromStr for TimeUnit {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        TimeUnit::parse(s)
    }
}

/// How polarity is written in a text file. Every mapping gives 1 = ON, 0 = OFF.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PolarityEncoding {
    /// Any of `0`/`1`, `-1`/`1` and `false`/`true` (case-insensitive).
    #[default]
    Auto,
    /// Only `0` and `1`.
    ZeroOne,
    /// Only `-1` and `1` (`+1` accepted).
    MinusOneOne,
    /// Only `false` and `true` (case-insensitive).
    FalseTrue,
}

impl PolarityEncoding {
    /// Parse `auto`, `01`/`0,1`, `-11`/`-1,1`/`pm1`, `bool`/`false,true`.
    pub fn parse(s: &str) -> Result<PolarityEncoding> {
        let t: String = s
            .trim()
            .to_lowercase()
            .chars()
            .filter(|c| !c.is_whitespace() && !matches!(c, '{' | '}'))
            .collect();
        Ok(match t.as_str() {
            "auto" => PolarityEncoding::Auto,
            "01" | "0,1" | "0/1" => PolarityEncoding::ZeroOne,
            "-11" | "-1,1" | "-1/1" | "pm1" | "±1" | "-1,+1" => PolarityEncoding::MinusOneOne,
            "bool" | "false,true" | "false/true" | "truefalse" | "true,false" => {
                PolarityEncoding::FalseTrue
            }
            _ => {
                return Err(Error::parameter(
                    "polarity",
                    format!("`{s}` is not auto, 0,1, -1,1 or false,true"),
                ))
            }
        })
    }
}

impl FromStr for PolarityEncoding {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        PolarityEncoding::parse(s)
    }
}

/// Column layout and units of text event files (formats.md §11). The defaults detect
/// everything from the file; set a field to override what detection would decide.
#[derive(Debug, Clone, Default)]
pub struct TextOptions {
    /// Role of each column in file order; columns after the last listed one are ignored.
    /// `None`: from a header line, else `t x y p` (`x y p t` after a Metavision `%geometry:`
    /// line). A header line, if present, is skipped either way.
    pub columns: Option<Vec<TextColumn>>,
    /// Field separator. `None` detects `;`, `,` or blanks from the first line. `b' '` and
    /// `b'\t'` both split on runs of spaces and tabs.
    pub delimiter: Option<u8>,
    /// Unit of the time column (also of `.npy`/`.npz` time fields when not `Auto`).
    pub time_unit: TimeUnit,
    /// How polarity values are written.
    pub polarity: PolarityEncoding,
}

impl TextOptions {
    /// Parse a column order such as `t,x,y,p`, `x y p t` or `t,_,x,y,p` (`_` skips a column).
    /// Each of t, x, y and p must appear exactly once.
    pub fn parse_columns(spec: &str) -> Result<Vec<TextColumn>> {
        let columns = spec
            .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(TextColumn::from_str)
            .collect::<Result<Vec<_>>>()?;
        check_columns(&columns).map_err(|m| Error::parameter("columns", m))?;
        Ok(columns)
    }

    /// Parse a time unit for [`TextOptions::time_unit`]: `auto`, `s`, `ms`, `us`/`µs`, `ns`,
    /// or a number of µs per unit.
    pub fn parse_time_unit(spec: &str) -> Result<TimeUnit> {
        TimeUnit::parse(spec)
    }

    /// Parse a polarity encoding for [`TextOptions::polarity`]: `auto`, `0,1`, `-1,1` or
    /// `false,true`.
    pub fn parse_polarity(spec: &str) -> Result<PolarityEncoding> {
        PolarityEncoding::parse(spec)
    }

    /// Parse a delimiter name: `auto`, `,`/`comma`, `;`/`semicolon`, `tab`/`\t`,
    /// `space`/`whitespace`/` `.
    pub fn parse_delimiter(spec: &str) -> Result<Option<u8>> {
        Ok(Some(match spec.to_lowercase().as_str() {
            "auto" | "" => return Ok(None),
            "," | "comma" => b',',
            ";" | "semicolon" => b';',
            "\t" | "\\t" | "tab" => b'\t',
            " " | "space" | "spaces" | "whitespace" | "blank" => b' ',
            _ => {
                return Err(Error::parameter(
                    "delimiter",
                    format!("`{spec}` is not auto, comma, semicolon, tab or space"),
                ))
            }
        }))
    }
}

/// Each of t, x, y and p present exactly once.
pub(crate) fn check_columns(columns: &[TextColumn]) -> std::result::Result<(), String> {
    for needed in [TextColumn::T, TextColumn::X, TextColumn::Y, TextColumn::P] {
        let n = columns.iter().filter(|&&c| c == needed).count();
        if n != 1 {
            return Err(format!(
                "the columns {} must name {} exactly once (found {n} times)",
                describe_columns(columns),
                needed.letter()
            ));
        }
    }
    Ok(())
}

pub(crate) fn describe_columns(columns: &[TextColumn]) -> String {
    columns
        .iter()
        .map(|c| c.letter())
        .collect::<Vec<_>>()
        .join(",")
}

#[cfg(test)]
mod tests;
