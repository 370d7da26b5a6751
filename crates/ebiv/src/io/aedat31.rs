//! iniVation AEDAT 3.1 files written by cAER / libcaer (formats.md §8; iniVation docs
//! `software/software-advanced-usage/file-formats/aedat-3.1`; libcaer
//! `include/libcaer/events/common.h`, `polarity.h`, `special.h`).
//!
//! Layout: `#` header lines ending with CRLF, from `#!AER-DAT3.1` to `#!END-HEADER`, then
//! packets. Each packet has a 28-byte little-endian header `i16 eventType, i16 eventSource,
//! i32 eventSize, i32 eventTSOffset, i32 eventTSOverflow, i32 eventCapacity, i32 eventNumber,
//! i32 eventValid` followed by `eventCapacity × eventSize` bytes of events. Polarity events
//! (type 1) become events, external-input special events (type 0) become triggers, every other
//! packet type is skipped and counted.

use super::prophesee_header::read_up_to;
use super::{DecodeReport, Format, FormatReader, Metadata, ReadOptions, ReadSeek};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry, Trigger};
use std::io::{Read, Seek, SeekFrom};

/// Largest header accepted; real ones are a few hundred bytes.
const MAX_HEADER_BYTES: usize = 1 << 20;
/// Size of a packet header.
const PACKET_HEADER_BYTES: u64 = 28;
/// Largest packet body accepted; larger ones are taken as corruption.
const MAX_PACKET_BYTES: u64 = 256 << 20;
/// Packet types of libcaer `common.h`.
const SPECIAL_EVENT: i16 = 0;
const POLARITY_EVENT: i16 = 1;
/// Special event types of libcaer `special.h` that carry external-input edges.
const EXTERNAL_INPUT_RISING_EDGE: u32 = 2;
const EXTERNAL_INPUT_FALLING_EDGE: u32 = 3;
const EXTERNAL_INPUT_PULSE: u32 = 4;
const TIMESTAMP_RESET: u32 = 1;

pub(crate) fn open(
    mut source: Box<dyn ReadSeek>,
    context: String,
    options: &ReadOptions,
) -> Result<Box<dyn FormatReader>> {
    let file_len = source.seek(SeekFrom::End(0))?;
    source.seek(SeekFrom::Start(0))?;
    let (lines, body_offset) = read_header(&mut source, &context)?;
    let mut metadata = Metadata::new(Format::Aedat31);
    for line in &lines {
        if line.starts_with("#!") {
            continue;
        }
        let text = line.trim_start_matches('#');
        let (key, value) = text.split_once(':').unwrap_or((text, ""));
        metadata
            .header
            .push((key.trim().to_string(), value.trim().to_string()));
    }
    if let Some(format) = metadata.header_value("Format") {
        if !format.eq_ignore_ascii_case("RAW") {
            return Err(Error::unsupported(
                &context,
                format!("AEDAT 3.1 `#Format: {format}` is not read; only RAW is"),
            ));
        }
    }
    // Current sources are `#Source <id>: <device>`; re-logged ones keep theirs as `#-Source`.
    let sources: Vec<(String, String)> = metadata
        .header
        .iter()
        .filter(|(k, _)| k.starts_with("Source "))
        .cloned()
        .collect();
    metadata.sensor = sources.first().map(|(_, v)| v.clone());
    let file_geometry = sources.iter().find_map(|(_, v)| geometry_of_device(v));
    metadata.geometry = file_geometry.or(options.geometry);
    if sources.len() > 1 {
        metadata.notes.push(
            "several event sources: only the polarity packets of the first source seen are decoded"
                .into(),
        );
    }
    metadata.notes.push(
        "time = eventTSOverflow << 31 | timestamp (µs since the device's time origin)".into(),
    );
    let limits = metadata
        .geometry
        .map_or((u32::MAX, u32::MAX), |g| (g.width, g.height));
    source.seek(SeekFrom::Start(body_offset))?;
    Ok(Box::new(Aedat31Reader {
        source,
        context,
        metadata,
        report: DecodeReport::default(),
        limits,
        pos: body_offset,
        file_len,
        primary_source: None,
        buf: Vec::new(),
        batch_bytes: options.batch_bytes.max(1) as u64,
        warned_other_source: false,
    }))
}

/// Sensor size of a libcaer device name (`DVS128`, `DAVIS346B`, `DAVIS240C`, …).
fn geometry_of_device(name: &str) -> Option<Geometry> {
    let n = name.to_ascii_uppercase();
    if n.contains("DVS128") {
        Some(Geometry::new(128, 128))
    } else if n.contains("DAVIS346") {
        Some(Geometry::new(346, 260))
    } else if n.contains("DAVIS240") {
        Some(Geometry::new(240, 180))
    } else {
        None
    }
}

/// The header lines (without CRLF) and the offset of the first packet.
fn read_header(source: &mut dyn Read, context: &str) -> Result<(Vec<String>, u64)> {
    let mut head = Vec::new();
    let mut chunk = [0u8; 4096];
    let marker = b"#!END-HEADER\r\n";
    let mut searched = 0;
    let end = loop {
        if let Some(end) = find(head.get(searched..).unwrap_or(&[]), marker) {
            break searched + end + marker.len();
        }
        searched = head.len().saturating_sub(marker.len() - 1);
        if head.len() > MAX_HEADER_BYTES {
            return Err(Error::corrupt(
                context,
                0,
                "no `#!END-HEADER` line in the first 1 MiB of the AEDAT 3.1 file",
            ));
        }
        let n = match source.read(&mut chunk) {
            Ok(0) => {
                return Err(Error::corrupt(
                    context,
                    head.len() as u64,
                    "the AEDAT 3.1 header has no `#!END-HEADER` line",
                ))
            }
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e.into()),
        };
        head.extend_from_slice(&chunk[..n]);
    };
    let text = String::from_utf8_lossy(head.get(..end).unwrap_or(&[]));
    if !text.starts_with("#!AER-DAT3.1") {
        return Err(Error::corrupt(
            context,
            0,
            "not an AEDAT 3.1 file (the first line is not `#!AER-DAT3.1`)",
        ));
    }
    let lines = text
        .split("\r\n")
        .filter(|l| !l.is_empty())
        .map(str::to_string)
        .collect();
    Ok((lines, end as u64))
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// The 28-byte header of one packet.
#[derive(Debug, Clone, Copy)]
struct PacketHeader {
    event_type: i16,
    event_source: i16,
    event_size: i32,
    ts_offset: i32,
    ts_overflow: i32,
    capacity: i32,
    number: i32,
    valid: i32,
}

impl PacketHeader {
    fn parse(b: &[u8; 28]) -> Self {
        let i32_at = |i: usize| i32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        PacketHeader {
            event_type: i16::from_le_bytes([b[0], b[1]]),
            event_source: i16::from_le_bytes([b[2], b[3]]),
            event_size: i32_at(4),
            ts_offset: i32_at(8),
            ts_overflow: i32_at(12),
            capacity: i32_at(16),
            number: i32_at(20),
            valid: i32_at(24),
        }
    }

    /// What is inconsistent in the header, if anything.
    fn problem(&self) -> Option<&'static str> {
        if self.event_type < 0 {
            // libcaer marks compressed (serialized) packets with the type's top bit.
            return Some("its type has the top bit set (a compressed packet, not supported)");
        }
        if self.event_size <= 0 {
            return Some("eventSize is not positive");
        }
        if self.ts_offset < 0 || self.ts_offset as i64 + 4 > self.event_size as i64 {
            return Some("eventTSOffset does not lie inside the event");
        }
        if self.ts_overflow < 0 {
            return Some("eventTSOverflow is negative");
        }
        if self.capacity < 0 || self.number < 0 || self.valid < 0 {
            return Some("eventCapacity, eventNumber or eventValid is negative");
        }
        if self.number > self.capacity || self.valid > self.number {
            return Some("eventValid ≤ eventNumber ≤ eventCapacity does not hold");
        }
        None
    }
}

/// Streaming AEDAT 3.1 reader.
struct Aedat31Reader {
    source: Box<dyn ReadSeek>,
    context: String,
    metadata: Metadata,
    report: DecodeReport,
    /// Exclusive upper bounds for x and y.
    limits: (u32, u32),
    /// Offset of the next packet; the source is kept positioned here.
    pos: u64,
    file_len: u64,
    /// The event source whose polarity packets are decoded.
    primary_source: Option<i16>,
    buf: Vec<u8>,
    batch_bytes: u64,
    warned_other_source: bool,
}

impl Aedat31Reader {
    /// Decode the packet at `self.pos`. Returns its size in bytes, or `None` at the end.
    fn next_packet(&mut self, out: &mut EventBuffer) -> Result<Option<u64>> {
        let start = self.pos;
        let left = self.file_len.saturating_sub(start);
        if left == 0 {
            return Ok(None);
        }
        let mut raw = [0u8; 28];
        let got = read_up_to(&mut self.source, &mut raw)?;
        if got < raw.len() {
            self.truncated(start, got as u64, got as u64, "a packet header");
            return Ok(None);
        }
        let header = PacketHeader::parse(&raw);
        if let Some(problem) = header.problem() {
            return Err(Error::corrupt(
                &self.context,
                start,
                format!("invalid packet header: {problem} ({header:?})"),
            ));
        }
        let size = header.event_size as u64;
        let body = size * header.capacity as u64;
        if body > MAX_PACKET_BYTES {
            return Err(Error::corrupt(
                &self.context,
                start,
                format!(
                    "packet of {} × {size}-byte events is larger than 256 MiB",
                    header.capacity
                ),
            ));
        }
        let body_start = start + PACKET_HEADER_BYTES;
        let available = self.file_len.saturating_sub(body_start);
        self.pos = body_start + body;
        let decoded_type = match header.event_type {
            POLARITY_EVENT | SPECIAL_EVENT if size < 8 => {
                return Err(Error::corrupt(
                    &self.context,
                    start,
                    format!(
                        "eventSize {size} is too small for event type {} (8 bytes)",
                        header.event_type
                    ),
                ));
            }
            POLARITY_EVENT => {
                let primary = *self.primary_source.get_or_insert(header.event_source);
                primary == header.event_source
            }
            SPECIAL_EVENT => true,
            _ => false,
        };
        if !decoded_type {
            if body > available {
                self.truncated(start, left, left, "a packet");
                return Ok(None);
            }
            self.report.skipped_other += header.number as u64;
            if header.event_type == POLARITY_EVENT && !self.warned_other_source {
                self.warned_other_source = true;
                self.report.warn(format!(
                    "{}: polarity packet at byte {start} comes from source {}, not the first source; such packets are skipped",
                    self.context, header.event_source
                ));
            }
            self.skip(body)?;
            return Ok(Some(PACKET_HEADER_BYTES + body));
        }
        // The whole events present in the file; only the first eventNumber slots hold events.
        let n = body.min(available / size * size) as usize;
        if self.buf.len() < n {
            self.buf.resize(n, 0);
        }
        let got = read_up_to(&mut self.source, &mut self.buf[..n])?;
        let whole = got - got % size as usize;
        let used = whole.min((size * header.number as u64) as usize);
        let events = self.buf.get(..used).unwrap_or(&[]);
        let layout = Layout {
            size: size as usize,
            ts_offset: header.ts_offset as usize,
            overflow: (header.ts_overflow as i64) << 31,
        };
        if header.event_type == POLARITY_EVENT {
            decode_polarity(events, layout, self.limits, out, &mut self.report);
        } else {
            decode_special(events, layout, out, &mut self.report);
        }
        if body > available || got < n {
            let ignored = left.saturating_sub(PACKET_HEADER_BYTES + whole as u64);
            self.truncated(start, left, ignored, "a packet");
            return Ok(None);
        }
        Ok(Some(PACKET_HEADER_BYTES + body))
    }

    /// Move past the `body` bytes of a skipped packet: small ones are read and dropped, which
    /// keeps the buffered source's buffer; large ones are seeked over.
    fn skip(&mut self, body: u64) -> Result<()> {
        if body <= 1 << 16 {
            let n = body as usize;
            if self.buf.len() < n {
                self.buf.resize(n, 0);
            }
            if read_up_to(&mut self.source, &mut self.buf[..n])? == n {
                return Ok(());
            }
        }
        self.source.seek(SeekFrom::Start(self.pos))?;
        Ok(())
    }

    /// The file ends inside the packet at `start`, `left` bytes later: count the `ignored`
    /// bytes that formed no complete event and report them.
    fn truncated(&mut self, start: u64, left: u64, ignored: u64, what: &str) {
        self.report.truncated_bytes += ignored;
        self.report.warn(format!(
            "{}: file ends inside {what} at byte {start} ({left} bytes left); {ignored} bytes that form no complete event are ignored",
            self.context
        ));
        self.pos = self.file_len;
    }
}

/// Polarity events (libcaer `polarity.h`): `u32 data` with bit 0 valid, bit 1 polarity
/// (1 = ON), bits 2–16 y, bits 17–31 x (origin top-left), then the `i32` time stamp.
/// Invalid events are counted as malformed.
fn decode_polarity(
    events: &[u8],
    layout: Layout,
    (width, height): (u32, u32),
    out: &mut EventBuffer,
    report: &mut DecodeReport,
) {
    out.reserve(events.len() / layout.size);
    for e in events.chunks_exact(layout.size) {
        let (data, t) = layout.data_and_time(e);
        if data & 1 == 0 {
            report.malformed += 1;
            continue;
        }
        let y = (data >> 2) & 0x7FFF;
        let x = data >> 17;
        if x >= width || y >= height {
            report.out_of_range += 1;
            continue;
        }
        out.push(t, x as u16, y as u16, ((data >> 1) & 1) as u8);
    }
}

/// Special events (libcaer `special.h`): `u32 data` with bit 0 valid, bits 1–7 type,
/// bits 8–31 payload, then the `i32` time stamp. External-input edges become triggers on
/// channel 0; time-stamp wraps, resets and other types are counted as skipped.
fn decode_special(events: &[u8], layout: Layout, out: &mut EventBuffer, report: &mut DecodeReport) {
    for e in events.chunks_exact(layout.size) {
        let (data, t) = layout.data_and_time(e);
        if data & 1 == 0 {
            report.malformed += 1;
            continue;
        }
        let value = match (data >> 1) & 0x7F {
            EXTERNAL_INPUT_RISING_EDGE | EXTERNAL_INPUT_PULSE => 1,
            EXTERNAL_INPUT_FALLING_EDGE => 0,
            kind => {
                if kind == TIMESTAMP_RESET {
                    report.warn(format!(
                        "time stamp reset at t = {t}: later time stamps restart from 0"
                    ));
                }
                report.skipped_other += 1;
                continue;
            }
        };
        out.triggers.push(Trigger {
            t,
            channel: 0,
            value,
        });
    }
}

/// Where the fields of one packet's events are.
#[derive(Debug, Clone, Copy)]
struct Layout {
    /// eventSize (at least 8 for the decoded types).
    size: usize,
    /// eventTSOffset: byte offset of the `i32` time stamp (4 for polarity and special events).
    ts_offset: usize,
    /// eventTSOverflow << 31.
    overflow: i64,
}

impl Layout {
    /// The `u32 data` word at byte 0 and the full time stamp of event `e`; the time stamp's
    /// sign bit, never set by libcaer, is ignored.
    #[inline]
    fn data_and_time(&self, e: &[u8]) -> (u32, i64) {
        let word = |i: usize| {
            e.get(i..i + 4)
                .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        };
        (
            word(0),
            self.overflow | (word(self.ts_offset) & 0x7FFF_FFFF) as i64,
        )
    }
}

impl FormatReader for Aedat31Reader {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        let mut consumed = 0u64;
        let mut any = false;
        while consumed < self.batch_bytes {
            match self.next_packet(out)? {
                Some(n) => {
                    consumed += n;
                    any = true;
                }
                None => break,
            }
        }
        Ok(any || !out.is_empty() || !out.triggers.is_empty())
    }

    fn report(&self) -> &DecodeReport {
        &self.report
    }

    fn position(&self) -> Option<u64> {
        Some(self.pos)
    }
}

#[cfg(test)]
mod tests;
