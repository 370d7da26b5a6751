//! The EBIV authors' `.evt` files (formats.md §13; `cewdlr/ebiv` `EventData::save` and
//! `EBISaveEvents`/`EBILoadEvents`). Unrelated to Prophesee EVT 3.0 despite the `EVT3`
//! signature.
//!
//! Header, read by fixed little-endian offsets (§13.1): signature `EVT3`/`EVT2`, file size
//! (`u64` @8), event count N (`u64` @16), time stamp of the source's first event (`u64` µs
//! @24), duration (`u32` @32), header length (`u32` @36, ≥ 48; the data start there), width
//! (`u32` @40), height (`u32` @44). Records are `u64 = x | y << 16 | p << 32 | t << 33` with t
//! relative to the header time stamp; ebiv returns **absolute** time = time stamp + t.
//!
//! The Python writer on Linux/macOS packs the header with 8-byte `long`s (§13.3): duration,
//! header length, width and height become `u64` at 32/40/48/56, 16 zero bytes follow, and
//! the data start at byte 80 while the header still says 64. That variant is recognised
//! (header length 64 at byte 40, nothing sensible at byte 36) and read correctly with a
//! warning. A file size that disagrees with header length + 8·N is reported; all whole
//! records present are read.

use super::bytestream::{WordDecoder, WordStreamReader};
use super::prophesee_header::read_up_to;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use std::io::{Seek, SeekFrom};

/// Bytes of the portable header layout (`<4s4x3Q4I`).
const MIN_HEADER: u64 = 48;
/// Where the data start in files of the broken Linux writer.
const LINUX_DATA_START: u64 = 80;
/// Header lengths above this are not headers.
const MAX_HEADER: u64 = 1 << 20;

fn u32_at(h: &[u8], at: usize) -> u32 {
    let mut b = [0u8; 4];
    if let Some(s) = h.get(at..at + 4) {
        b.copy_from_slice(s);
    }
    u32::from_le_bytes(b)
}

fn u64_at(h: &[u8], at: usize) -> u64 {
    let mut b = [0u8; 8];
    if let Some(s) = h.get(at..at + 8) {
        b.copy_from_slice(s);
    }
    u64::from_le_bytes(b)
}

/// The header fields, whichever layout stored them.
#[derive(Debug, Clone, PartialEq, Eq)]
struct EvtHeader {
    signature: String,
    declared_size: u64,
    count: u64,
    time_stamp: u64,
    duration: u64,
    header_len: u64,
    data_start: u64,
    width: u64,
    height: u64,
    linux_variant: bool,
}

fn parse_header(h: &[u8], file_len: u64, context: &str) -> Result<EvtHeader> {
    if (h.len() as u64) < MIN_HEADER {
        return Err(Error::corrupt(
            context,
            0,
            format!(
                "an EBIV .evt header needs {MIN_HEADER} bytes; the file has {}",
                h.len()
            ),
        ));
    }
    let signature = match h.get(..4) {
        Some(b"EVT3") => "EVT3",
        Some(b"EVT2") => "EVT2",
        _ => {
            return Err(Error::corrupt(
                context,
                0,
                "not an EBIV .evt file (signature is not EVT3 or EVT2)",
            ))
        }
    };
    let declared_size = u64_at(h, 8);
    let count = u64_at(h, 16);
    let time_stamp = u64_at(h, 24);
    let portable_len = u32_at(h, 36) as u64;
    let linux_len = u64_at(h, 40);
    let linux_variant =
        portable_len < MIN_HEADER && linux_len == 64 && h.len() as u64 >= LINUX_DATA_START;
    let header = if linux_variant {
        EvtHeader {
            signature: signature.into(),
            declared_size,
            count,
            time_stamp,
            duration: u64_at(h, 32),
            header_len: linux_len,
            data_start: LINUX_DATA_START,
            width: u64_at(h, 48),
            height: u64_at(h, 56),
            linux_variant,
        }
    } else {
        if !(MIN_HEADER..=MAX_HEADER).contains(&portable_len) {
            return Err(Error::corrupt(
                context,
                36,
                format!("EBIV .evt header length {portable_len} is not between {MIN_HEADER} and {MAX_HEADER}"),
            ));
        }
        EvtHeader {
            signature: signature.into(),
            declared_size,
            count,
            time_stamp,
            duration: u32_at(h, 32) as u64,
            header_len: portable_len,
            data_start: portable_len,
            width: u32_at(h, 40) as u64,
            height: u32_at(h, 44) as u64,
            linux_variant,
        }
    };
    if header.data_start > file_len {
        return Err(Error::corrupt(
            context,
            0,
            format!(
                "EBIV .evt header length {} exceeds the file size {file_len}",
                header.data_start
            ),
        ));
    }
    Ok(header)
}

pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let file_len = source.seek(SeekFrom::End(0))?;
    source.seek(SeekFrom::Start(0))?;
    let mut head = [0u8; LINUX_DATA_START as usize];
    let n = read_up_to(&mut source, &mut head)?;
    let h = parse_header(head.get(..n).unwrap_or(&head), file_len, &context)?;
    let origin = i64::try_from(h.time_stamp)
        .ok()
        .filter(|&t| t <= i64::MAX - (1 << 31))
        .ok_or_else(|| {
            Error::corrupt(
                &context,
                24,
                format!(
                    "EBIV .evt time stamp {} µs is beyond the i64 range",
                    h.time_stamp
                ),
            )
        })?;
    let mut warnings = Vec::new();
    if h.linux_variant {
        warnings.push(format!(
            "{context}: written by the Linux/macOS Python writer (80-byte header declaring 64 bytes, formats.md §13.3); read from byte 80"
        ));
    }
    let body = file_len - h.data_start;
    let present = body / 8;
    let expected_size = h
        .count
        .checked_mul(8)
        .and_then(|b| b.checked_add(h.header_len));
    if present != h.count {
        warnings.push(format!(
            "{context}: the header declares {} events but the file holds {present} whole records; reading those",
            h.count
        ));
    } else if !h.linux_variant && expected_size != Some(h.declared_size) {
        warnings.push(format!(
            "{context}: the header's file size {} differs from header length + 8·N",
            h.declared_size
        ));
    }

    let mut metadata = Metadata::new(Format::EbivEvt);
    metadata.header = vec![
        ("signature".into(), h.signature.clone()),
        ("file_size".into(), h.declared_size.to_string()),
        ("event_count".into(), h.count.to_string()),
        ("time_stamp_us".into(), h.time_stamp.to_string()),
        ("duration_us".into(), h.duration.to_string()),
        ("header_length".into(), h.header_len.to_string()),
        ("width".into(), h.width.to_string()),
        ("height".into(), h.height.to_string()),
        (
            "layout".into(),
            if h.linux_variant {
                "80-byte (Linux Python writer)".into()
            } else {
                format!("{}-byte (portable)", h.header_len)
            },
        ),
    ];
    let header_geometry = match (u32::try_from(h.width), u32::try_from(h.height)) {
        (Ok(w), Ok(hh)) if w > 0 && hh > 0 => Some(Geometry::new(w, hh)),
        _ => None,
    };
    metadata.geometry = header_geometry.or(options.geometry);
    metadata.notes.push(format!(
        "times are absolute: the header time stamp {origin} µs plus the stored 31-bit relative time"
    ));
    let g = metadata
        .geometry
        .unwrap_or(Geometry::new(u32::MAX, u32::MAX));
    source.seek(SeekFrom::Start(h.data_start))?;
    Ok(Box::new(WordStreamReader::new(
        source,
        EvtDecoder {
            origin,
            width: g.width,
            height: g.height,
            warnings,
        },
        metadata,
        context,
        h.data_start,
        options.batch_bytes,
    )))
}

struct EvtDecoder {
    origin: i64,
    width: u32,
    height: u32,
    /// Header findings, moved into the report by the first call.
    warnings: Vec<String>,
}

impl EvtDecoder {
    fn flush_warnings(&mut self, report: &mut DecodeReport) {
        for w in self.warnings.drain(..) {
            report.warn(w);
        }
    }
}

impl WordDecoder for EvtDecoder {
    const WORD_BYTES: usize = 8;

    fn decode(
        &mut self,
        bytes: &[u8],
        _offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        self.flush_warnings(report);
        out.reserve(bytes.len() / 8);
        for rec in bytes.chunks_exact(8) {
            let mut b = [0u8; 8];
            b.copy_from_slice(rec);
            let w = u64::from_le_bytes(b);
            let x = (w & 0xFFFF) as u16;
            let y = ((w >> 16) & 0xFFFF) as u16;
            let p = ((w >> 32) & 1) as u8;
            let t = self.origin + (w >> 33) as i64;
            if x as u32 >= self.width || y as u32 >= self.height {
                report.out_of_range += 1;
                continue;
            }
            out.push(t, x, y, p);
        }
    }

    fn finish(&mut self, _end_offset: u64, report: &mut DecodeReport) {
        self.flush_warnings(report);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{open_source, ReadOptions};
    use std::io::Cursor;

    fn record(t: u64, x: u16, y: u16, p: u8) -> [u8; 8] {
        (x as u64 | (y as u64) << 16 | (p as u64) << 32 | t << 33).to_le_bytes()
    }

    const EVENTS: [(u64, u16, u16, u8); 4] = [
        (0, 0, 0, 1),
        (17, 1279, 719, 0),
        ((1 << 31) - 1, 5, 6, 1),
        (40, 2000, 3, 1), // outside 1280 x 720
    ];

    /// A file as the C++ writer / the Python writer on Windows produce it.
    fn portable(signature: &[u8; 4], header_len: u32) -> Vec<u8> {
        let n = EVENTS.len() as u64;
        let mut v = signature.to_vec();
        v.extend([0xAB; 4]); // uninitialised padding
        v.extend((header_len as u64 + 8 * n).to_le_bytes());
        v.extend(n.to_le_bytes());
        v.extend(5_840_504u64.to_le_bytes());
        v.extend(40u32.to_le_bytes());
        v.extend(header_len.to_le_bytes());
        v.extend(1280u32.to_le_bytes());
        v.extend(720u32.to_le_bytes());
        v.resize(header_len as usize, 0xCD); // reserved garbage
        for (t, x, y, p) in EVENTS {
            v.extend(record(t, x, y, p));
        }
        v
    }

    /// `pack('4s3Q4L2Q', …)` with 8-byte longs: the broken Linux layout.
    fn linux() -> Vec<u8> {
        let n = EVENTS.len() as u64;
        let mut v = b"EVT3".to_vec();
        v.extend([0; 4]);
        v.extend((64 + 8 * n).to_le_bytes());
        v.extend(n.to_le_bytes());
        v.extend(5_840_504u64.to_le_bytes());
        for field in [40u64, 64, 1280, 720, 0, 0] {
            v.extend(field.to_le_bytes());
        }
        assert_eq!(v.len(), 80);
        for (t, x, y, p) in EVENTS {
            v.extend(record(t, x, y, p));
        }
        v
    }

    fn read(bytes: Vec<u8>) -> crate::Result<crate::io::Recording> {
        let options = ReadOptions {
            format: Some(Format::EbivEvt),
            ..Default::default()
        };
        open_source(Box::new(Cursor::new(bytes)), "test.evt", None, &options)?.read_all()
    }

    fn check(rec: &crate::io::Recording) {
        let t0 = 5_840_504;
        assert_eq!(rec.events.t, vec![t0, t0 + 17, t0 + (1 << 31) - 1]);
        assert_eq!(rec.events.x, vec![0, 1279, 5]);
        assert_eq!(rec.events.y, vec![0, 719, 6]);
        assert_eq!(rec.events.p, vec![1, 0, 1]);
        assert_eq!(rec.report.out_of_range, 1);
        assert_eq!(rec.metadata.geometry, Some(Geometry::new(1280, 720)));
        assert_eq!(rec.metadata.header_value("time_stamp_us"), Some("5840504"));
    }

    #[test]
    fn portable_header_variants() {
        for (sig, len) in [(b"EVT3", 64), (b"EVT2", 64), (b"EVT3", 48)] {
            let rec = read(portable(sig, len)).unwrap();
            check(&rec);
            assert!(rec.report.warnings.is_empty(), "{:?}", rec.report.warnings);
        }
        // Detection by content.
        let rec = open_source(
            Box::new(Cursor::new(portable(b"EVT3", 64))),
            "x",
            None,
            &ReadOptions::default(),
        )
        .unwrap()
        .read_all()
        .unwrap();
        assert_eq!(rec.metadata.format, Format::EbivEvt);
    }

    #[test]
    fn broken_linux_header_is_read_with_a_warning() {
        let rec = read(linux()).unwrap();
        check(&rec);
        assert!(rec.report.warnings.iter().any(|w| w.contains("Linux")));
        assert_eq!(rec.metadata.header_value("duration_us"), Some("40"));
    }

    #[test]
    fn inconsistent_sizes_are_reported() {
        let mut short = portable(b"EVT3", 64);
        short.truncate(short.len() - 12);
        let rec = read(short).unwrap();
        assert_eq!(rec.events.len(), 2);
        assert_eq!(rec.report.truncated_bytes, 4);
        assert!(rec
            .report
            .warnings
            .iter()
            .any(|w| w.contains("declares 4 events")));

        let mut huge_n = portable(b"EVT3", 64);
        huge_n[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        let rec = read(huge_n).unwrap();
        assert_eq!(rec.events.len(), 3);
        assert!(!rec.report.warnings.is_empty());
    }

    #[test]
    fn bad_headers_are_errors() {
        let mut bad_len = portable(b"EVT3", 64);
        bad_len[36..40].copy_from_slice(&20u32.to_le_bytes());
        assert!(read(bad_len).is_err());
        let mut absurd = portable(b"EVT3", 64);
        absurd[36..40].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(read(absurd).is_err());
        let mut beyond = portable(b"EVT3", 64);
        beyond[36..40].copy_from_slice(&4000u32.to_le_bytes());
        assert!(read(beyond).is_err());
        assert!(read(b"EVT3 too short".to_vec()).is_err());
        let mut sig = portable(b"EVT3", 64);
        sig[..4].copy_from_slice(b"EVIM");
        assert!(read(sig).is_err());
        let mut late = portable(b"EVT3", 64);
        late[24..32].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(read(late).is_err());
    }

    proptest::proptest! {
        #[test]
        fn random_bytes_after_a_valid_header_never_panic(body in proptest::collection::vec(proptest::num::u8::ANY, 0..600)) {
            let mut v = portable(b"EVT3", 64);
            v.truncate(64);
            v.extend(body);
            let _ = read(v);
            let mut h = linux();
            h.truncate(80);
            let _ = read(h);
        }
    }
}
