//! iniVation / jAER AEDAT 2.0 files (formats.md §7; iniVation docs
//! `software/software-advanced-usage/file-formats/aedat-2.0`).
//!
//! Layout: `#` header lines ending with CRLF (the first is `#!AER-DAT2.0`; jAER adds
//! `# AEChip: <java class>` and a long XML preferences dump), ended by the first line that
//! does not start with `#`; then 8-byte big-endian records `i32 address, i32 timestamp` (µs).
//! The address layout depends on the chip class:
//!
//! * DVS128 (iniVation doc): bit 15 external event, bits 14–8 y, bits 7–1 x, bit 0 polarity
//!   (1 = ON), origin bottom-left.
//! * DAVIS (jAER `DavisBaseCamera`): a DVS event iff bit 31 = 0 and bit 10 = 0; y bits 22–30,
//!   x bits 12–21, polarity bit 11; origin bottom-left.
//!
//! Rows are flipped to image coordinates (`y = height − 1 − y_raw`); x is kept as stored.

use super::bytestream::{WordDecoder, WordStreamReader};
use super::time32::Unwrap32;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use std::io::{Read, Seek, SeekFrom};

/// Largest header accepted (jAER's preferences dump is some hundred KiB).
const MAX_HEADER_BYTES: usize = 16 << 20;
/// Header lines kept in the metadata, besides the XML preferences (which are never kept).
const MAX_KEPT_LINES: usize = 200;

/// Address layout of the recording's chip class.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
    Dvs128,
    Davis,
}

pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    source.seek(SeekFrom::Start(0))?;
    let (lines, body_offset) = read_header(&mut source, &context)?;
    if lines.first().map(|l| l.trim_end()) != Some("#!AER-DAT2.0") {
        return Err(Error::unsupported(
            &context,
            "only AEDAT 2.0 is read (the first line must be `#!AER-DAT2.0`); AEDAT 1.0 files with 16-bit addresses are not supported",
        ));
    }
    let mut metadata = Metadata::new(Format::Aedat2);
    let mut xml_lines = 0usize;
    let mut dropped = 0usize;
    for line in lines.iter().skip(1) {
        let text = line.trim_start_matches('#').trim();
        if text.starts_with('<') {
            xml_lines += 1;
            continue;
        }
        if text.is_empty() {
            continue;
        }
        if metadata.header.len() >= MAX_KEPT_LINES {
            dropped += 1;
            continue;
        }
        let (key, value) = text.split_once(": ").unwrap_or((text, ""));
        metadata
            .header
            .push((key.trim().to_string(), value.trim().to_string()));
    }
    if xml_lines > 0 {
        metadata.notes.push(format!(
            "{xml_lines} header lines of jAER XML preferences are not kept"
        ));
    }
    if dropped > 0 {
        metadata
            .notes
            .push(format!("{dropped} further header lines are not kept"));
    }
    let chip = metadata.header_value("AEChip").map(str::to_string);
    let (layout, chip_geometry) = chip_layout(chip.as_deref());
    let geometry = chip_geometry.or(options.geometry).ok_or_else(|| {
        Error::unsupported(
            &context,
            format!(
                "the AEDAT 2.0 header names no chip ebiv knows (`# AEChip: {}`); pass --geometry WIDTHxHEIGHT",
                chip.as_deref().unwrap_or("none")
            ),
        )
    })?;
    if chip_geometry.is_none() {
        metadata.notes.push(
            "chip class unknown: addresses decoded with the DAVIS layout and the given geometry"
                .into(),
        );
    }
    metadata.geometry = Some(geometry);
    metadata.sensor = chip;
    metadata.notes.push(
        "jAER stores rows from the bottom (origin bottom-left); ebiv flips them (y = height − 1 − y_raw) and keeps x as stored. AEDAT 2 readers disagree on orientation (formats.md §7)".into(),
    );
    if layout == Layout::Dvs128 {
        metadata.notes.push(
            "DVS128 polarity read as bit 0 = 1 → ON (iniVation AEDAT 2.0 documentation); jAER's own DVS128 extractor reads bit 0 = 1 as OFF and mirrors x".into(),
        );
    }
    source.seek(SeekFrom::Start(body_offset))?;
    let decoder = Aedat2Decoder {
        layout,
        width: geometry.width,
        height: geometry.height,
        clock: Unwrap32::default(),
    };
    Ok(Box::new(WordStreamReader::new(
        source,
        decoder,
        metadata,
        context,
        body_offset,
        options.batch_bytes,
    )))
}

/// Address layout and sensor size of a jAER chip class such as
/// `eu.seebetter.ini.chips.davis.Davis346red` or `ch.unizh.ini.jaer.chip.retina.DVS128`.
fn chip_layout(chip: Option<&str>) -> (Layout, Option<Geometry>) {
    let name = chip.unwrap_or("").to_ascii_lowercase();
    if name.contains("dvs128") || name.contains("tmpdiff128") {
        (Layout::Dvs128, Some(Geometry::new(128, 128)))
    } else if name.contains("davis346") {
        (Layout::Davis, Some(Geometry::new(346, 260)))
    } else if name.contains("davis240") {
        (Layout::Davis, Some(Geometry::new(240, 180)))
    } else {
        (Layout::Davis, None)
    }
}

/// The header lines (including `#`, without line ends) and the offset of the first record:
/// the first line that does not start with `#`.
fn read_header(source: &mut dyn Read, context: &str) -> Result<(Vec<String>, u64)> {
    let mut buf = Vec::new();
    let mut chunk = [0u8; 8192];
    let mut lines = Vec::new();
    let mut pos = 0usize;
    let mut eof = false;
    loop {
        match buf.get(pos) {
            Some(b'#') => match buf
                .get(pos..)
                .and_then(|r| r.iter().position(|&b| b == b'\n'))
            {
                Some(nl) => {
                    let line = String::from_utf8_lossy(&buf[pos..pos + nl]);
                    lines.push(line.trim_end_matches('\r').to_string());
                    pos += nl + 1;
                    continue;
                }
                None if eof => {
                    let line = String::from_utf8_lossy(&buf[pos..]);
                    lines.push(line.trim_end_matches('\r').to_string());
                    pos = buf.len();
                    break;
                }
                None => {}
            },
            Some(_) => break,
            None if eof => break,
            None => {}
        }
        if buf.len() > MAX_HEADER_BYTES {
            return Err(Error::corrupt(
                context,
                pos as u64,
                "the AEDAT 2.0 header is longer than 16 MiB",
            ));
        }
        match source.read(&mut chunk) {
            Ok(0) => eof = true,
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.into()),
        }
    }
    Ok((lines, pos as u64))
}

/// Decoder of the 8-byte big-endian records.
struct Aedat2Decoder {
    layout: Layout,
    width: u32,
    height: u32,
    /// The 32-bit clock, unwrapped.
    clock: Unwrap32,
}

impl WordDecoder for Aedat2Decoder {
    const WORD_BYTES: usize = 8;

    fn decode(
        &mut self,
        bytes: &[u8],
        _offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        out.reserve(bytes.len() / 8);
        for rec in bytes.chunks_exact(8) {
            let addr = u32::from_be_bytes([rec[0], rec[1], rec[2], rec[3]]);
            let raw_t = u32::from_be_bytes([rec[4], rec[5], rec[6], rec[7]]);
            let t = self.clock.unwrap(raw_t);
            let (x, y_raw, p) = match self.layout {
                Layout::Dvs128 => {
                    if addr & 0xFFFF_8000 != 0 {
                        report.skipped_other += 1;
                        continue;
                    }
                    ((addr >> 1) & 0x7F, (addr >> 8) & 0x7F, addr & 1)
                }
                Layout::Davis => {
                    if addr & 0x8000_0000 != 0 || addr & 0x400 != 0 {
                        report.skipped_other += 1;
                        continue;
                    }
                    ((addr >> 12) & 0x3FF, (addr >> 22) & 0x1FF, (addr >> 11) & 1)
                }
            };
            if x >= self.width || y_raw >= self.height {
                report.out_of_range += 1;
                continue;
            }
            out.push(t, x as u16, (self.height - 1 - y_raw) as u16, p as u8);
        }
    }
}

#[cfg(test)]
mod tests;
