//! The ASCII header shared by Prophesee RAW and DAT files (`% key value` lines), and the
//! resolution of encoding and geometry from it with OpenEB's precedence
//! (formats.md §1.3: `format` > `evt` > `system_ID` table > user fallback).

use super::Format;
use crate::error::{Error, Result};
use crate::event::Geometry;
use std::io::Read;

/// Longest header accepted; a longer run of `% ` lines is treated as a hostile file.
const MAX_HEADER_BYTES: usize = 1 << 20;

/// Encodings of the RAW body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum RawEncoding {
    /// EVT 2.0: 32-bit words.
    Evt2,
    /// EVT 2.1: 64-bit vector words.
    Evt21,
    /// EVT 3.0: 16-bit stateful words.
    Evt3,
}

impl RawEncoding {
    /// The RAW encoding a [`Format`] stands for, if it is one.
    pub fn of_format(format: Format) -> Option<RawEncoding> {
        match format {
            Format::Evt2 => Some(RawEncoding::Evt2),
            Format::Evt21 => Some(RawEncoding::Evt21),
            Format::Evt3 => Some(RawEncoding::Evt3),
            _ => None,
        }
    }

    /// The [`Format`] of a RAW file with this encoding.
    pub fn format(self) -> Format {
        match self {
            RawEncoding::Evt2 => Format::Evt2,
            RawEncoding::Evt21 => Format::Evt21,
            RawEncoding::Evt3 => Format::Evt3,
        }
    }

    /// Parse a user's name for an encoding (`evt2`, `evt2.1`, `EVT21`, `3.0`, …).
    pub fn parse(name: &str) -> Option<RawEncoding> {
        let n: String = name
            .to_ascii_lowercase()
            .chars()
            .filter(|c| !matches!(c, '.' | ' ' | '_' | '-'))
            .collect();
        match n.trim_start_matches("evt") {
            "2" | "20" => Some(RawEncoding::Evt2),
            "21" => Some(RawEncoding::Evt21),
            "3" | "30" => Some(RawEncoding::Evt3),
            _ => None,
        }
    }
}

/// Byte order of EVT 2.1 words on disk (formats.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Evt21Order {
    /// High 32-bit half first, each half little-endian (IMX636).
    Legacy,
    /// One little-endian u64 (GenX320).
    Little,
}

/// A parsed `% key value` header.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PropheseeHeader {
    /// Key/value pairs in file order (`% end` excluded).
    pub entries: Vec<(String, String)>,
    /// Byte length of the header; the body starts here.
    pub length: u64,
}

impl PropheseeHeader {
    /// Read the header at the start of `source`. Up to two bytes past it are consumed, so
    /// callers seek to [`PropheseeHeader::length`] before reading the body.
    pub fn read(source: &mut dyn Read, context: &str) -> Result<PropheseeHeader> {
        let mut header = PropheseeHeader::default();
        let mut line = Vec::new();
        loop {
            let mut prefix = [0u8; 2];
            let got = read_up_to(source, &mut prefix)?;
            if got < 2 || prefix != *b"% " {
                // Up to two body bytes were consumed: callers seek back to `length`.
                return Ok(header);
            }
            line.clear();
            let mut byte = [0u8; 1];
            loop {
                if read_up_to(source, &mut byte)? == 0 {
                    break;
                }
                if byte[0] == b'\n' {
                    break;
                }
                line.push(byte[0]);
                if header.length as usize + line.len() > MAX_HEADER_BYTES {
                    return Err(Error::corrupt(
                        context,
                        header.length,
                        format!("header longer than {MAX_HEADER_BYTES} bytes; not an event file"),
                    ));
                }
            }
            let line_start = header.length;
            header.length += 2 + line.len() as u64 + 1;
            if header.add_line(&line, line_start) {
                return Ok(header);
            }
        }
    }

    /// Parse the header from bytes (for tests and detection). Returns the header and the
    /// body offset.
    pub fn parse(bytes: &[u8], context: &str) -> Result<PropheseeHeader> {
        let mut cursor = std::io::Cursor::new(bytes);
        let mut header = Self::read(&mut cursor, context)?;
        header.length = header.length.min(bytes.len() as u64);
        Ok(header)
    }

    /// Add one line (without `% ` and newline). NUL bytes split a line into several, as seen
    /// in headers copied from GenX320 cameras. Returns true at `% end`.
    fn add_line(&mut self, line: &[u8], _offset: u64) -> bool {
        for (i, piece) in line.split(|&b| b == 0).enumerate() {
            let piece = if i == 0 {
                piece
            } else if let Some(rest) = piece.strip_prefix(b"% ") {
                rest
            } else {
                continue;
            };
            let text = String::from_utf8_lossy(piece);
            let text = text.trim_end_matches('\r');
            let mut tokens = text.split_whitespace();
            let Some(key) = tokens.next() else { continue };
            if key == "end" && i == 0 && tokens.clone().next().is_none() {
                return true;
            }
            let value = tokens.collect::<Vec<_>>().join(" ");
            self.entries.push((key.to_string(), value));
        }
        false
    }

    /// The value of the first entry named `key`.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.entries
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// The `format` entry split into its name and `option=value` pairs.
    fn format_field(&self) -> Option<(String, Vec<(String, String)>)> {
        let value = self.get("format")?;
        let mut parts = value.split(';');
        let name = parts.next()?.trim().to_string();
        let options = parts
            .filter_map(|p| {
                let (k, v) = p.split_once('=')?;
                Some((k.trim().to_ascii_lowercase(), v.trim().to_string()))
            })
            .collect();
        Some((name, options))
    }

    fn format_option(&self, key: &str) -> Option<String> {
        self.format_field()?
            .1
            .into_iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v)
    }

    fn system_id(&self) -> Option<u32> {
        self.get("system_ID")?.trim().parse().ok()
    }

    /// Whether the header names Prophesee as integrator (or names none, as very old files).
    fn integrator_is_prophesee(&self) -> bool {
        ["integrator_name", "camera_integrator_name"]
            .iter()
            .filter_map(|k| self.get(k))
            .all(|v| v.trim() == "Prophesee")
    }

    /// The body encoding by OpenEB's precedence; `Ok(None)` when the header does not say.
    pub fn encoding(&self, context: &str) -> Result<Option<RawEncoding>> {
        if let Some((name, _)) = self.format_field() {
            return match name.to_ascii_uppercase().as_str() {
                "EVT2" => Ok(Some(RawEncoding::Evt2)),
                "EVT21" | "EVT2.1" => Ok(Some(RawEncoding::Evt21)),
                "EVT3" => Ok(Some(RawEncoding::Evt3)),
                other => Err(Error::unsupported(
                    context,
                    format!(
                        "RAW encoding `{other}` is not supported (ebiv reads EVT2, EVT21, EVT3)"
                    ),
                )),
            };
        }
        if let Some(evt) = self.get("evt") {
            return match RawEncoding::parse(evt) {
                Some(e) => Ok(Some(e)),
                None => Err(Error::unsupported(
                    context,
                    format!("header key `evt {evt}` names an encoding ebiv does not read"),
                )),
            };
        }
        if self.integrator_is_prophesee() {
            if let Some(entry) = self.system_id().and_then(system_id_defaults) {
                return Ok(Some(entry.1));
            }
        }
        Ok(None)
    }

    /// The sensor geometry by OpenEB's precedence; `None` when the header does not say.
    /// A `geometry` entry that contradicts the `format` options is reported in `notes`.
    pub fn geometry(&self, notes: &mut Vec<String>) -> Option<Geometry> {
        let from_format = match (self.format_option("width"), self.format_option("height")) {
            (Some(w), Some(h)) => parse_size(&w, &h),
            _ => None,
        };
        let from_geometry = self.get("geometry").and_then(|g| {
            let (w, h) = g.trim().split_once('x')?;
            parse_size(w, h)
        });
        if let (Some(f), Some(g)) = (from_format, from_geometry) {
            if f != g {
                notes.push(format!(
                    "header `geometry {g}` contradicts `format` size {f}; using {f}"
                ));
            }
        }
        let from_dat = match (self.get("Width"), self.get("Height")) {
            (Some(w), Some(h)) => parse_size(w, h),
            _ => None,
        };
        let from_table = self
            .system_id()
            .and_then(system_id_defaults)
            .map(|(g, _)| g);
        from_format.or(from_geometry).or(from_dat).or(from_table)
    }

    /// The EVT 2.1 byte order (formats.md §3, OpenEB's selection rule).
    pub fn evt21_order(&self) -> Evt21Order {
        let explicit = self
            .format_option("endianness")
            .or_else(|| self.get("endianness").map(str::to_string));
        match explicit.as_deref().map(str::trim) {
            Some("legacy") => Evt21Order::Legacy,
            Some("little") => Evt21Order::Little,
            _ => {
                let old_board = self.system_id().is_some_and(|id| id < 0x37);
                if self.integrator_is_prophesee() && old_board {
                    Evt21Order::Legacy
                } else {
                    Evt21Order::Little
                }
            }
        }
    }
}

fn parse_size(w: &str, h: &str) -> Option<Geometry> {
    let w: u32 = w.trim().parse().ok()?;
    let h: u32 = h.trim().parse().ok()?;
    (w > 0 && h > 0 && w <= 1 << 16 && h <= 1 << 16).then_some(Geometry::new(w, h))
}

/// OpenEB's default size and encoding per `system_ID` (formats.md §1.4).
fn system_id_defaults(id: u32) -> Option<(Geometry, RawEncoding)> {
    let vga = Geometry::new(640, 480);
    let hd = Geometry::new(1280, 720);
    Some(match id {
        21 | 23 | 25 | 28 | 33 | 34 | 35 | 41 => (vga, RawEncoding::Evt2),
        26 | 31 | 39 => (hd, RawEncoding::Evt2),
        30 | 46 | 48 | 49 | 50 => (hd, RawEncoding::Evt3),
        40 => (vga, RawEncoding::Evt3),
        _ => return None,
    })
}

/// Read into `buf` until it is full or the source ends; returns the bytes read.
pub(crate) fn read_up_to(source: &mut dyn Read, buf: &mut [u8]) -> Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match source.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.into()),
        }
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_header_resolves_from_system_id() {
        let bytes =
            b"% Date 2020-09-14 09:03:25\n% integrator_name Prophesee\n% system_ID 21\n\x01\x02";
        let h = PropheseeHeader::parse(bytes, "t").unwrap();
        assert_eq!(h.get("Date"), Some("2020-09-14 09:03:25"));
        assert_eq!(h.length, bytes.len() as u64 - 2);
        assert_eq!(h.encoding("t").unwrap(), Some(RawEncoding::Evt2));
        assert_eq!(h.geometry(&mut vec![]), Some(Geometry::new(640, 480)));
    }

    #[test]
    fn evt_key_beats_system_id_and_format_beats_geometry() {
        let bytes = b"% evt 3.0\n% system_ID 39\n% format EVT3;height=720;width=1280\n% geometry 640x480\n% end\n";
        let h = PropheseeHeader::parse(bytes, "t").unwrap();
        assert_eq!(h.length, bytes.len() as u64);
        assert_eq!(h.encoding("t").unwrap(), Some(RawEncoding::Evt3));
        let mut notes = vec![];
        assert_eq!(h.geometry(&mut notes), Some(Geometry::new(1280, 720)));
        assert_eq!(notes.len(), 1);
        let h = PropheseeHeader::parse(b"% evt 3.0\n% system_ID 39\n", "t").unwrap();
        assert_eq!(h.encoding("t").unwrap(), Some(RawEncoding::Evt3));
        assert_eq!(h.geometry(&mut vec![]), Some(Geometry::new(1280, 720)));
    }

    #[test]
    fn percent_without_space_is_body() {
        let h = PropheseeHeader::parse(b"% evt 2.0\n%\x01\x02\x03", "t").unwrap();
        assert_eq!(h.length, 10);
    }

    #[test]
    fn nul_splits_lines_and_evt21_order() {
        let bytes = b"% format EVT21;height=320;width=320\x00% generation 4.2\n% end\n";
        let h = PropheseeHeader::parse(bytes, "t").unwrap();
        assert_eq!(h.get("generation"), Some("4.2"));
        assert_eq!(h.encoding("t").unwrap(), Some(RawEncoding::Evt21));
        assert_eq!(h.evt21_order(), Evt21Order::Little);
        let h = PropheseeHeader::parse(b"% format EVT21;endianness=legacy\n", "t").unwrap();
        assert_eq!(h.evt21_order(), Evt21Order::Legacy);
        let h = PropheseeHeader::parse(
            b"% evt 2.1\n% integrator_name Prophesee\n% system_ID 49\n",
            "t",
        )
        .unwrap();
        assert_eq!(h.evt21_order(), Evt21Order::Legacy);
    }

    #[test]
    fn unknown_encoding_is_an_error_and_endless_header_is_bounded() {
        let h = PropheseeHeader::parse(b"% format EVT4\n", "t").unwrap();
        assert!(h.encoding("t").is_err());
        let mut endless = b"% ".to_vec();
        endless.extend(std::iter::repeat_n(b'a', MAX_HEADER_BYTES + 10));
        assert!(PropheseeHeader::parse(&endless, "t").is_err());
    }

    #[test]
    fn encoding_names_parse() {
        assert_eq!(RawEncoding::parse("evt2.1"), Some(RawEncoding::Evt21));
        assert_eq!(RawEncoding::parse("EVT3"), Some(RawEncoding::Evt3));
        assert_eq!(RawEncoding::parse("2.0"), Some(RawEncoding::Evt2));
        assert_eq!(RawEncoding::parse("evt4"), None);
    }
}
