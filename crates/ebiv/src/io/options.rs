//! The reader options by name, as `ebiv` takes them on the command line (`--geometry
//! 1280x720`) and Python as keywords (`geometry="1280x720"`): one parser for both.

use super::{Format, RawEncoding, ReadOptions, TextOptions};
use crate::error::{Error, Result};
use crate::event::Geometry;

/// The names of the reader options, in the order of `ebiv --help`.
pub const READ_OPTIONS: [&str; 8] = [
    "geometry",
    "raw-encoding",
    "format",
    "metavision-time",
    "columns",
    "time-unit",
    "delimiter",
    "polarity-values",
];

impl ReadOptions {
    /// Set the option `key` (one of [`READ_OPTIONS`]) from its text; the error names the
    /// option.
    pub fn set(&mut self, key: &str, text: &str) -> Result<()> {
        let bad = |m: String| Error::parameter(key, m);
        match key {
            "geometry" => self.geometry = Some(parse_geometry(text).map_err(bad)?),
            "raw-encoding" => {
                self.raw_encoding = Some(RawEncoding::parse(text).ok_or_else(|| {
                    bad(format!(
                        "`{text}` is not a RAW encoding; use evt2, evt21 or evt3"
                    ))
                })?)
            }
            "format" => {
                self.format = Some(
                    Format::parse(text)
                        .ok_or_else(|| bad(format!("`{text}` is not a format ebiv reads")))?,
                )
            }
            "metavision-time" => {
                self.metavision_time_shift = match text {
                    "true" => true,
                    "false" => false,
                    _ => return Err(bad(format!("`{text}` is not true or false"))),
                }
            }
            "columns" => self.text.columns = Some(TextOptions::parse_columns(text)?),
            "time-unit" => self.text.time_unit = TextOptions::parse_time_unit(text)?,
            "delimiter" => self.text.delimiter = TextOptions::parse_delimiter(text)?,
            "polarity-values" => self.text.polarity = TextOptions::parse_polarity(text)?,
            _ => {
                return Err(Error::parameter(
                    key,
                    format!("not a reader option; they are {}", READ_OPTIONS.join(", ")),
                ))
            }
        }
        Ok(())
    }
}

/// Parse a sensor size `1280x720`.
pub fn parse_geometry(s: &str) -> std::result::Result<Geometry, String> {
    let err = || format!("`{s}` is not a size; write WIDTHxHEIGHT, e.g. 1280x720");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let w: u32 = w.trim().parse().map_err(|_| err())?;
    let h: u32 = h.trim().parse().map_err(|_| err())?;
    if w == 0 || h == 0 || w > 65536 || h > 65536 {
        return Err(format!("`{s}`: width and height must be 1..=65536"));
    }
    Ok(Geometry::new(w, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_option_is_set_by_its_name_and_bad_values_name_it() {
        let mut o = ReadOptions::default();
        o.set("geometry", "640x480").unwrap();
        o.set("format", "evt3").unwrap();
        o.set("raw-encoding", "evt21").unwrap();
        o.set("metavision-time", "true").unwrap();
        o.set("columns", "x,y,p,t").unwrap();
        o.set("time-unit", "ms").unwrap();
        assert_eq!(o.geometry, Some(Geometry::new(640, 480)));
        assert_eq!(o.format, Some(Format::Evt3));
        assert!(o.metavision_time_shift);
        for (key, text) in [("geometry", "640"), ("format", "mp4"), ("speed", "1")] {
            let e = o.set(key, text).unwrap_err().to_string();
            assert!(e.contains(key), "{e}");
        }
        assert!(parse_geometry("0x5").is_err());
    }
}
