//! Options shared by every command that reads an event file.

use clap::Args;
use ebiv::io::{Format, RawEncoding, ReadOptions};
use ebiv::Geometry;

/// How to read the input file; the defaults suit almost every file.
#[derive(Debug, Clone, Args)]
pub struct InputArgs {
    /// Sensor size WIDTHxHEIGHT, for files that do not state it (old RAW, DAT, text).
    #[arg(long, value_name = "WxH", value_parser = parse_geometry)]
    pub geometry: Option<Geometry>,
    /// RAW encoding for header-less RAW dumps: evt2, evt21 or evt3.
    #[arg(long, value_name = "ENC", value_parser = parse_encoding)]
    pub raw_encoding: Option<RawEncoding>,
    /// Force the input format instead of detecting it: raw, evt2, evt21, evt3, dat, aedat4,
    /// aedat2, aedat31, es, csv, npy, npz, evt, hdf5.
    #[arg(long, value_name = "FMT", value_parser = parse_format)]
    pub format: Option<Format>,
    /// Subtract the Metavision SDK time shift, so times match what Metavision tools print.
    #[arg(long)]
    pub metavision_time: bool,
    /// Text input: column order, e.g. `t,x,y,p` or `x,y,p,t` (default: from the header line).
    #[arg(long, value_name = "COLS")]
    pub columns: Option<String>,
    /// Text and NumPy input: unit of the time column: us, ms, s or ns (default: from the
    /// header name, else integers are µs and decimals are seconds).
    #[arg(long, value_name = "UNIT")]
    pub time_unit: Option<String>,
    /// Text input: field delimiter (`,`, `;`, `tab`, `space`; default: detected).
    #[arg(long, value_name = "D")]
    pub delimiter: Option<String>,
    /// Text input: how polarity is written: 01, pm1 (-1/1), bool (default: any of them).
    #[arg(long, value_name = "ENC")]
    pub polarity_values: Option<String>,
}

impl InputArgs {
    /// The library's read options.
    pub fn read_options(&self) -> Result<ReadOptions, ebiv::Error> {
        let mut options = ReadOptions {
            geometry: self.geometry,
            raw_encoding: self.raw_encoding,
            metavision_time_shift: self.metavision_time,
            format: self.format,
            ..ReadOptions::default()
        };
        let texts = [
            ("columns", &self.columns),
            ("time-unit", &self.time_unit),
            ("delimiter", &self.delimiter),
            ("polarity-values", &self.polarity_values),
        ];
        for (key, text) in texts {
            if let Some(text) = text {
                options.set(key, text)?;
            }
        }
        Ok(options)
    }
}

fn parse_geometry(s: &str) -> Result<Geometry, String> {
    ebiv::io::parse_geometry(s)
}

fn parse_encoding(s: &str) -> Result<RawEncoding, String> {
    RawEncoding::parse(s)
        .ok_or_else(|| format!("`{s}` is not a RAW encoding; use evt2, evt21 or evt3"))
}

fn parse_format(s: &str) -> Result<Format, String> {
    Format::parse(s).ok_or_else(|| format!("`{s}` is not a format ebiv reads"))
}
