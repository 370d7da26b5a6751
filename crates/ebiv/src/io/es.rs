//! Event Stream (`.es`) files, version 2.x (formats.md §10; specification in the
//! `neuromorphic-paris/event_stream` README).
//!
//! Header: `"Event Stream"`, version major/minor/patch, a type byte, then for DVS and ATIS the
//! sensor width and height (`u16` LE). Bodies are byte state machines:
//! * **DVS** (type 1): `0xFF` adds 127 µs, `0xFE` is a reset (ignored), any other byte is
//!   `Δt << 1 | polarity` followed by x and y (`u16` LE each).
//! * **ATIS** (type 2): `0b111111nn` adds `63·nn` µs (`nn = 0` is the reset), any other byte
//!   is `Δt << 2 | polarity << 1 | is_threshold_crossing`, then x and y. Threshold crossings
//!   (exposure measurements) are skipped and counted in `skipped_other`; change detections
//!   become events.
//!
//! Generic, display and colour streams hold no change-detection events and are refused.
//!
//! **Rows are flipped to image coordinates**: Event Stream puts the y origin at the bottom of
//! the sensor, so ebiv returns `y = height − 1 − y_stored` (origin top-left, as every other
//! reader and as faery reports), and says so in the metadata. Events outside the header's
//! width × height are dropped and counted.

use super::bytestream::{WordDecoder, WordStreamReader};
use super::prophesee_header::read_up_to;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};

const MAGIC: &[u8; 12] = b"Event Stream";
/// Bytes before the body of a DVS or ATIS stream.
const HEADER_BYTES: usize = 20;
const TYPE_DVS: u8 = 1;
const TYPE_ATIS: u8 = 2;

pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let mut head = [0u8; HEADER_BYTES];
    let n = read_up_to(&mut source, &mut head)?;
    if n < 16 || &head[..12] != MAGIC {
        return Err(Error::corrupt(
            &context,
            0,
            "not an Event Stream file (no `Event Stream` signature and version)",
        ));
    }
    let [major, minor, patch, kind] = [head[12], head[13], head[14], head[15]];
    if major != 2 {
        return Err(Error::unsupported(
            &context,
            format!(
                "Event Stream version {major}.{minor}.{patch}; ebiv reads version 2.x (convert the file with the event_stream tools or faery)"
            ),
        ));
    }
    let kind_name = match kind {
        TYPE_DVS => "DVS",
        TYPE_ATIS => "ATIS",
        0 | 3 | 4 => {
            let what = ["generic", "", "", "asynchronous display", "colour"]
                .get(kind as usize)
                .copied()
                .unwrap_or("");
            return Err(Error::unsupported(
                &context,
                format!("Event Stream type {kind} ({what} events) holds no change-detection events; ebiv reads DVS and ATIS streams"),
            ));
        }
        other => {
            return Err(Error::corrupt(
                &context,
                15,
                format!("unknown Event Stream type {other} (0–4 exist)"),
            ))
        }
    };
    if n < HEADER_BYTES {
        return Err(Error::corrupt(
            &context,
            n as u64,
            "Event Stream file ends inside its width and height",
        ));
    }
    let width = u16::from_le_bytes([head[16], head[17]]);
    let height = u16::from_le_bytes([head[18], head[19]]);
    let mut metadata = Metadata::new(Format::EventStream);
    metadata.header = vec![
        ("version".into(), format!("{major}.{minor}.{patch}")),
        ("type".into(), kind_name.into()),
        ("width".into(), width.to_string()),
        ("height".into(), height.to_string()),
    ];
    metadata.geometry = if width > 0 && height > 0 {
        Some(Geometry::new(width.into(), height.into()))
    } else {
        options.geometry
    };
    metadata.notes.push(
        "Event Stream stores y with the origin at the bottom; ebiv flips it to image rows (y = height − 1 − y_stored)".into(),
    );
    if kind == TYPE_ATIS {
        metadata.notes.push(
            "ATIS stream: change detections are read, threshold crossings (exposure measurements) skipped and counted".into(),
        );
    }
    let g = metadata
        .geometry
        .unwrap_or(Geometry::new(u32::MAX, u32::MAX));
    let decoder = EsDecoder {
        atis: kind == TYPE_ATIS,
        t: 0,
        partial: [0; 5],
        have: 0,
        width: g.width,
        height: g.height,
    };
    Ok(Box::new(WordStreamReader::new(
        source,
        decoder,
        metadata,
        context,
        HEADER_BYTES as u64,
        options.batch_bytes,
    )))
}

/// The DVS/ATIS byte state machine; an event cut by a chunk boundary waits in `partial`.
struct EsDecoder {
    atis: bool,
    t: i64,
    partial: [u8; 5],
    /// Bytes of `partial` filled; 0 when idle.
    have: usize,
    width: u32,
    height: u32,
}

impl EsDecoder {
    #[inline]
    fn event(
        &mut self,
        [b0, x0, x1, y0, y1]: [u8; 5],
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        let p = if self.atis {
            self.t += (b0 >> 2) as i64;
            if b0 & 1 == 1 {
                report.skipped_other += 1;
                return;
            }
            (b0 >> 1) & 1
        } else {
            self.t += (b0 >> 1) as i64;
            b0 & 1
        };
        let x = u16::from_le_bytes([x0, x1]);
        let y = u16::from_le_bytes([y0, y1]);
        if x as u32 >= self.width || y as u32 >= self.height {
            report.out_of_range += 1;
            return;
        }
        // Stored rows count from the bottom; image rows from the top.
        out.push(self.t, x, (self.height - 1 - y as u32) as u16, p);
    }
}

impl WordDecoder for EsDecoder {
    const WORD_BYTES: usize = 1;

    fn decode(
        &mut self,
        bytes: &[u8],
        _offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        let mut rest = bytes;
        // Complete an event started in the previous chunk.
        while self.have > 0 {
            let [b, tail @ ..] = rest else { return };
            if let Some(slot) = self.partial.get_mut(self.have) {
                *slot = *b;
            }
            self.have += 1;
            rest = tail;
            if self.have == 5 {
                self.have = 0;
                let ev = self.partial;
                self.event(ev, out, report);
            }
        }
        out.reserve(rest.len() / 5);
        loop {
            match *rest {
                [] => break,
                [b, ref tail @ ..] if (!self.atis && b >= 0xFE) || (self.atis && b >= 0xFC) => {
                    if self.atis {
                        self.t += 63 * (b & 3) as i64;
                    } else if b == 0xFF {
                        self.t += 127;
                    }
                    rest = tail;
                }
                [b0, x0, x1, y0, y1, ref tail @ ..] => {
                    self.event([b0, x0, x1, y0, y1], out, report);
                    rest = tail;
                }
                ref short => {
                    self.have = short.len();
                    if let Some(dst) = self.partial.get_mut(..short.len()) {
                        dst.copy_from_slice(short);
                    }
                    break;
                }
            }
        }
    }

    fn finish(&mut self, end_offset: u64, report: &mut DecodeReport) {
        if self.have > 0 {
            report.truncated_bytes += self.have as u64;
            report.warn(format!(
                "Event Stream ends inside an event at byte {}; {} bytes ignored",
                end_offset - self.have as u64,
                self.have
            ));
            self.have = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{open_source, ReadOptions};
    use std::io::Cursor;

    fn header(kind: u8, w: u16, h: u16) -> Vec<u8> {
        let mut v = b"Event Stream".to_vec();
        v.extend_from_slice(&[2, 0, 0, kind]);
        v.extend_from_slice(&w.to_le_bytes());
        v.extend_from_slice(&h.to_le_bytes());
        v
    }

    fn dvs_event(dt: u8, p: u8, x: u16, y: u16) -> Vec<u8> {
        let mut v = vec![dt << 1 | p];
        v.extend_from_slice(&x.to_le_bytes());
        v.extend_from_slice(&y.to_le_bytes());
        v
    }

    fn read(bytes: Vec<u8>, batch_bytes: usize) -> crate::Result<crate::io::Recording> {
        let options = ReadOptions {
            batch_bytes,
            ..Default::default()
        };
        open_source(Box::new(Cursor::new(bytes)), "test.es", None, &options)?.read_all()
    }

    fn sample() -> Vec<u8> {
        let mut v = header(TYPE_DVS, 320, 240);
        v.extend(dvs_event(0, 1, 0, 239));
        v.extend([0xFF, 0xFF, 0xFE]);
        v.extend(dvs_event(5, 0, 319, 0));
        v.extend(dvs_event(126, 1, 320, 3)); // out of range
        v.extend(dvs_event(1, 1, 7, 8));
        v
    }

    #[test]
    fn dvs_overflow_reset_and_range() {
        let rec = read(sample(), 1 << 20).unwrap();
        let e = &rec.events;
        assert_eq!(e.t, vec![0, 259, 386]);
        assert_eq!(e.x, vec![0, 319, 7]);
        assert_eq!(e.y, vec![0, 239, 231]);
        assert_eq!(e.p, vec![1, 0, 1]);
        assert_eq!(rec.report.out_of_range, 1);
        assert_eq!(rec.metadata.geometry, Some(Geometry::new(320, 240)));
        assert!(rec.metadata.notes.iter().any(|n| n.contains("flips")));
    }

    #[test]
    fn events_straddling_chunks_decode_identically() {
        let whole = read(sample(), 1 << 20).unwrap();
        // Chunks are at least 4096 bytes; pad the body so events cross every boundary offset.
        let mut bytes = header(TYPE_DVS, 640, 480);
        for i in 0..3000u16 {
            if i % 7 == 0 {
                bytes.push(0xFF);
            }
            bytes.extend(dvs_event((i % 100) as u8, (i % 2) as u8, i % 640, i % 480));
        }
        let a = read(bytes.clone(), 4096).unwrap();
        let b = read(bytes, 1 << 20).unwrap();
        assert_eq!(a.events, b.events);
        assert_eq!(a.events.len(), 3000);
        assert_eq!(whole.events.len(), 3);
    }

    #[test]
    fn truncated_event_is_counted() {
        let mut bytes = sample();
        bytes.extend([0x02, 0x01, 0x00]);
        let rec = read(bytes, 1 << 20).unwrap();
        assert_eq!(rec.events.len(), 3);
        assert_eq!(rec.report.truncated_bytes, 3);
    }

    #[test]
    fn atis_skips_threshold_crossings() {
        let mut v = header(TYPE_ATIS, 304, 240);
        let ev = |dt: u8, pol: u8, tc: u8, x: u16, y: u16| {
            let mut e = vec![dt << 2 | pol << 1 | tc];
            e.extend_from_slice(&x.to_le_bytes());
            e.extend_from_slice(&y.to_le_bytes());
            e
        };
        v.extend(ev(3, 1, 0, 1, 2));
        v.extend([0xFD, 0xFC]); // +63, reset
        v.extend(ev(10, 0, 1, 5, 5)); // exposure: skipped
        v.extend([0xFF]); // +189
        v.extend(ev(2, 0, 0, 3, 4));
        let rec = read(v, 1 << 20).unwrap();
        assert_eq!(rec.events.t, vec![3, 3 + 63 + 10 + 189 + 2]);
        assert_eq!(rec.events.p, vec![1, 0]);
        assert_eq!(rec.report.skipped_other, 1);
    }

    #[test]
    fn bad_headers_are_clear_errors() {
        let mut v1 = header(TYPE_DVS, 10, 10);
        v1[12] = 1;
        let msg = read(v1, 4096).unwrap_err().to_string();
        assert!(msg.contains("version 1.0.0"), "{msg}");
        let generic = header(0, 0, 0);
        assert!(read(generic, 4096)
            .unwrap_err()
            .to_string()
            .contains("generic"));
        let colour = header(4, 10, 10);
        assert!(read(colour, 4096).is_err());
        let mut short = header(TYPE_DVS, 10, 10);
        short.truncate(17);
        assert!(read(short, 4096).is_err());
        let empty = header(TYPE_DVS, 10, 10);
        assert_eq!(read(empty, 4096).unwrap().events.len(), 0);
    }

    proptest::proptest! {
        #[test]
        fn random_bodies_never_panic(body in proptest::collection::vec(proptest::num::u8::ANY, 0..2000), atis in proptest::bool::ANY) {
            let mut v = header(if atis { TYPE_ATIS } else { TYPE_DVS }, 64, 64);
            v.extend(body);
            let rec = read(v, 4096).unwrap();
            proptest::prop_assert!(rec.events.x.iter().all(|&x| x < 64));
        }
    }
}
