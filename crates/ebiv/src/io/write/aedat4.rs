//! iniVation AEDAT 4.0 writer (formats.md §9; iniVation docs
//! `software/software-advanced-usage/file-formats/aedat-4.0`; flatbuffer schemas of
//! dv-processing), in the layout DV and dv-processing write and read:
//!
//! * the magic `#!AER-DAT4.0\r\n`, then the IOHeader as a size-prefixed flatbuffer whose prefix
//!   is the `i32` header length: `compression`, `dataTablePosition` and the `infoNode` XML with
//!   one `EVTS` stream `events` (id 0, `sizeX`/`sizeY` from the geometry) and, when triggers
//!   were written, one `TRIG` stream `triggers` (id 1), both with source `ebiv`;
//! * packets `i32 streamId, i32 size, body`, each body one LZ4 frame, one ZSTD frame or raw
//!   ([`Aedat4Compression`]) holding a size-prefixed `EVTS` or `TRIG` flatbuffer. Events are
//!   packed as they arrive, [`EVENTS_PER_PACKET`] to a packet; the partial packet is kept until
//!   it is full or the file is finished. Pending triggers follow each event packet;
//! * the `FTAB` data table (compressed like the packets) with one entry per packet, whose
//!   `ByteOffset` is the packet *body* (8 bytes after the header, as in DV's files) and whose
//!   time range is the smallest and largest time stamp of the packet. The IOHeader is rewritten
//!   at the end with the table's position, so readers can seek.
//!
//! Time stamps are stored as given (DV writes Unix-epoch µs); x and y must lie on the sensor
//! and fit `i16`. Polarity is stored as `p != 0`.
//!
//! **Limitation:** AEDAT 4.0 triggers (`TriggerPacket`) have a type but no channel. A trigger
//! with value 0 is written as type 2 (external input falling edge), any other value as type 1
//! (rising edge); the channel is dropped, and readers report every trigger on channel 0.

mod builder;

pub(crate) use builder::{
    event_record, events_body, io_header, table_body, triggers_body, PacketRecord, EVENT_BYTES,
};

use super::{AtomicFile, EventWriter};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use crate::io::aedat4::MAGIC;
use lz4_flex::frame::{BlockMode, BlockSize, FrameEncoder, FrameInfo};
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

/// Events per `EVTS` packet (as faery writes; DV's packets are of similar size).
pub const EVENTS_PER_PACKET: usize = 4096;
/// Triggers per `TRIG` packet at most.
const TRIGGERS_PER_PACKET: usize = 4096;
/// Stream id of the events.
const EVENTS_STREAM: i32 = 0;
/// Stream id of the triggers.
const TRIGGERS_STREAM: i32 = 1;
/// `TriggerType::EXTERNAL_SIGNAL_RISING_EDGE` of dv-processing.
const TRIGGER_RISING: i8 = 1;
/// `TriggerType::EXTERNAL_SIGNAL_FALLING_EDGE` of dv-processing.
const TRIGGER_FALLING: i8 = 2;
/// The ZSTD level DV uses by default.
const ZSTD_LEVEL: i32 = 3;
/// What the info node names as the source of both streams.
const SOURCE: &str = "ebiv";

/// How packet bodies and the data table are compressed (the IOHeader `compression` field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Aedat4Compression {
    /// Stored as is (`NONE`, code 0).
    None,
    /// One LZ4 frame per packet (`LZ4`, code 1), DV's default.
    #[default]
    Lz4,
    /// One ZSTD frame per packet (`ZSTD`, code 3), level 3.
    Zstd,
}

impl Aedat4Compression {
    /// The IOHeader `CompressionType` value.
    pub(crate) fn code(self) -> i32 {
        match self {
            Aedat4Compression::None => 0,
            Aedat4Compression::Lz4 => 1,
            Aedat4Compression::Zstd => 3,
        }
    }

    /// The name DV gives it in the info node.
    fn name(self) -> &'static str {
        match self {
            Aedat4Compression::None => "NONE",
            Aedat4Compression::Lz4 => "LZ4",
            Aedat4Compression::Zstd => "ZSTD",
        }
    }
}

/// Reusable compressor of packet bodies: each call yields one complete frame.
pub(crate) struct PacketCompressor {
    codec: Codec,
    out: Vec<u8>,
}

enum Codec {
    None,
    Lz4(Box<FrameEncoder<Vec<u8>>>),
    Zstd(Box<zstd::bulk::Compressor<'static>>),
}

impl PacketCompressor {
    pub(crate) fn new(compression: Aedat4Compression) -> std::io::Result<Self> {
        let codec = match compression {
            Aedat4Compression::None => Codec::None,
            // Independent 256 KiB blocks: a packet of 4096 events (64 KiB and a header) is one
            // block. The encoder is reused; each `try_finish` closes one frame.
            Aedat4Compression::Lz4 => {
                let info = FrameInfo::new()
                    .block_size(BlockSize::Max256KB)
                    .block_mode(BlockMode::Independent);
                Codec::Lz4(Box::new(FrameEncoder::with_frame_info(info, Vec::new())))
            }
            Aedat4Compression::Zstd => {
                Codec::Zstd(Box::new(zstd::bulk::Compressor::new(ZSTD_LEVEL)?))
            }
        };
        Ok(PacketCompressor {
            codec,
            out: Vec::new(),
        })
    }

    /// Compress `body` (non-empty, as every flatbuffer is) into one frame.
    pub(crate) fn compress<'a>(&'a mut self, body: &'a [u8]) -> std::io::Result<&'a [u8]> {
        match &mut self.codec {
            Codec::None => Ok(body),
            Codec::Lz4(encoder) => {
                encoder.get_mut().clear();
                encoder.write_all(body)?;
                encoder.try_finish()?;
                Ok(encoder.get_ref())
            }
            Codec::Zstd(compressor) => {
                self.out.clear();
                self.out
                    .reserve(zstd::zstd_safe::compress_bound(body.len()));
                compressor.compress_to_buffer(body, &mut self.out)?;
                Ok(&self.out)
            }
        }
    }
}

/// The IOHeader `infoNode`: the XML tree DV writes (`<dv version="2.0">`, one node per stream
/// below `outInfo` with `compression`, `originalModuleName`, `originalOutputName`,
/// `typeDescription`, `typeIdentifier` and an `info` node with `sizeX`/`sizeY` and `source`).
fn info_xml(geometry: Geometry, compression: Aedat4Compression, triggers: bool) -> String {
    let stream = |id: i32, name: &str, kind: &str, description: &str, info: &str| {
        format!(
            r#"        <node name="{id}" path="/outInfo/{id}/">
            <attr key="compression" type="string">{compression}</attr>
            <attr key="originalModuleName" type="string">{SOURCE}</attr>
            <attr key="originalOutputName" type="string">{name}</attr>
            <attr key="typeDescription" type="string">{description}</attr>
            <attr key="typeIdentifier" type="string">{kind}</attr>
            <node name="info" path="/outInfo/{id}/info/">
{info}                <attr key="source" type="string">{SOURCE}</attr>
            </node>
        </node>
"#,
            compression = compression.name()
        )
    };
    let size = format!(
        "                <attr key=\"sizeX\" type=\"int\">{}</attr>\n                <attr key=\"sizeY\" type=\"int\">{}</attr>\n",
        geometry.width, geometry.height
    );
    let mut xml =
        String::from("<dv version=\"2.0\">\n    <node name=\"outInfo\" path=\"/outInfo/\">\n");
    xml.push_str(&stream(
        EVENTS_STREAM,
        "events",
        "EVTS",
        "Array of events (polarity ON/OFF).",
        &size,
    ));
    if triggers {
        xml.push_str(&stream(
            TRIGGERS_STREAM,
            "triggers",
            "TRIG",
            "Array of triggers.",
            "",
        ));
    }
    xml.push_str("    </node>\n</dv>\n");
    xml
}

/// Streaming AEDAT 4.0 writer; see the module documentation.
pub struct Aedat4Writer {
    file: AtomicFile,
    geometry: Geometry,
    compression: Aedat4Compression,
    compressor: PacketCompressor,
    /// Length of the IOHeader (size prefix included), fixed when the file is created.
    header_len: usize,
    /// File offset of the next packet.
    pos: u64,
    /// Packed `Event` structs of the partial packet.
    records: Vec<u8>,
    /// Smallest and largest time of the partial packet.
    records_range: (i64, i64),
    triggers: Vec<(i64, i8)>,
    triggers_written: bool,
    events_seen: u64,
    body: Vec<u8>,
    table: Vec<PacketRecord>,
}

impl Aedat4Writer {
    /// Start writing `path`. The sensor size is required (it goes into the info node; at
    /// most 32768×32768, as coordinates are `i16`).
    pub fn create(
        path: &Path,
        geometry: Option<Geometry>,
        compression: Aedat4Compression,
    ) -> Result<Self> {
        let geometry = geometry.ok_or_else(|| {
            Error::parameter(
                "geometry",
                "AEDAT 4.0 output needs the sensor size; the input does not state it, pass --geometry WIDTHxHEIGHT",
            )
        })?;
        let limit = 1u32 << 15;
        if geometry.width == 0
            || geometry.height == 0
            || geometry.width > limit
            || geometry.height > limit
        {
            return Err(Error::parameter(
                "geometry",
                format!("AEDAT 4.0 stores 16-bit signed coordinates; the sensor size {geometry} must lie within 1x1 and 32768x32768"),
            ));
        }
        let mut file = AtomicFile::create(path)?;
        let compressor = PacketCompressor::new(compression).map_err(|e| file.err(e))?;
        // The header is written now with room for the trigger stream and rewritten by
        // `finish`, which knows the table position and whether triggers came.
        let header = io_header(
            compression.code(),
            Some(-1),
            &info_xml(geometry, compression, true),
        );
        let io = file
            .writer()
            .write_all(MAGIC)
            .and_then(|()| file.writer().write_all(&header));
        io.map_err(|e| file.err(e))?;
        Ok(Aedat4Writer {
            file,
            geometry,
            compression,
            compressor,
            header_len: header.len(),
            pos: (MAGIC.len() + header.len()) as u64,
            records: Vec::with_capacity(EVENTS_PER_PACKET * EVENT_BYTES),
            records_range: (i64::MAX, i64::MIN),
            triggers: Vec::new(),
            triggers_written: false,
            events_seen: 0,
            body: Vec::new(),
            table: Vec::new(),
        })
    }

    /// Compress `self.body` and append it as a packet of `stream_id` holding `elements`
    /// elements with times in `range`.
    fn write_packet(&mut self, stream_id: i32, elements: usize, range: (i64, i64)) -> Result<()> {
        let compressed = self
            .compressor
            .compress(&self.body)
            .map_err(|e| self.file.err(e))?;
        let size = i32::try_from(compressed.len()).map_err(|_| Error::Write {
            what: "AEDAT 4.0 packet".into(),
            message: format!("a packet body of {} bytes exceeds 2 GiB", compressed.len()),
        })?;
        let writer = self.file.writer();
        let io = writer
            .write_all(&stream_id.to_le_bytes())
            .and_then(|()| writer.write_all(&size.to_le_bytes()))
            .and_then(|()| writer.write_all(compressed));
        io.map_err(|e| self.file.err(e))?;
        self.table.push(PacketRecord {
            offset: self.pos as i64 + 8,
            stream_id,
            size,
            elements: elements as i64,
            t_start: range.0,
            t_end: range.1,
        });
        self.pos += 8 + size as u64;
        Ok(())
    }

    /// Write the partial event packet (if any), then the pending triggers.
    fn flush_events(&mut self) -> Result<()> {
        if !self.records.is_empty() {
            self.body = events_body(&self.records, std::mem::take(&mut self.body));
            let n = self.records.len() / EVENT_BYTES;
            self.write_packet(EVENTS_STREAM, n, self.records_range)?;
            self.records.clear();
            self.records_range = (i64::MAX, i64::MIN);
        }
        self.flush_triggers()
    }

    fn flush_triggers(&mut self) -> Result<()> {
        if self.triggers.is_empty() {
            return Ok(());
        }
        self.body = triggers_body(&self.triggers, std::mem::take(&mut self.body));
        let range = self
            .triggers
            .iter()
            .fold((i64::MAX, i64::MIN), |(lo, hi), &(t, _)| {
                (lo.min(t), hi.max(t))
            });
        self.write_packet(TRIGGERS_STREAM, self.triggers.len(), range)?;
        self.triggers.clear();
        self.triggers_written = true;
        Ok(())
    }
}

impl EventWriter for Aedat4Writer {
    fn write(&mut self, events: &EventBuffer) -> Result<()> {
        let g = self.geometry;
        let mut start = 0;
        while start < events.len() {
            let room = EVENTS_PER_PACKET - self.records.len() / EVENT_BYTES;
            let end = events.len().min(start + room);
            for i in start..end {
                let (x, y) = (events.x[i], events.y[i]);
                // The geometry is at most 32768 wide and high, so x and y fit i16.
                if !g.contains(x as u32, y as u32) {
                    return Err(Error::parameter(
                        "events",
                        format!(
                            "event {} at ({x}, {y}) lies outside the {g} sensor",
                            self.events_seen + i as u64
                        ),
                    ));
                }
                let t = events.t[i];
                let (lo, hi) = self.records_range;
                self.records_range = (lo.min(t), hi.max(t));
                self.records.extend_from_slice(&event_record(
                    t,
                    x as i16,
                    y as i16,
                    events.p[i] != 0,
                ));
            }
            start = end;
            if self.records.len() == EVENTS_PER_PACKET * EVENT_BYTES {
                self.flush_events()?;
            }
        }
        self.events_seen += events.len() as u64;
        for tr in &events.triggers {
            let kind = if tr.value == 0 {
                TRIGGER_FALLING
            } else {
                TRIGGER_RISING
            };
            self.triggers.push((tr.t, kind));
            if self.triggers.len() == TRIGGERS_PER_PACKET {
                self.flush_triggers()?;
            }
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        self.flush_events()?;
        let table_position = self.pos as i64;
        let table = table_body(&self.table);
        let compressed = self
            .compressor
            .compress(&table)
            .map_err(|e| self.file.err(e))?;
        let io = self.file.writer().write_all(compressed);
        io.map_err(|e| self.file.err(e))?;
        let info = info_xml(self.geometry, self.compression, self.triggers_written);
        let mut header = io_header(self.compression.code(), Some(table_position), &info);
        if header.len() > self.header_len {
            return Err(Error::Write {
                what: "AEDAT 4.0 header".into(),
                message: "the final IOHeader is larger than the space reserved for it".into(),
            });
        }
        // Zero bytes after the flatbuffer's last object keep the header length unchanged.
        header.resize(self.header_len, 0);
        let inner = (self.header_len - 4) as u32;
        header[..4].copy_from_slice(&inner.to_le_bytes());
        let writer = self.file.writer();
        let io = writer
            .seek(SeekFrom::Start(MAGIC.len() as u64))
            .and_then(|_| writer.write_all(&header))
            .and_then(|()| writer.seek(SeekFrom::End(0)).map(|_| ()));
        io.map_err(|e| self.file.err(e))?;
        self.file.commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{read_all, ReadOptions};
    use crate::Trigger;

    #[test]
    fn geometry_is_required_and_bounded() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.aedat4");
        for g in [
            None,
            Some(Geometry::new(0, 10)),
            Some(Geometry::new(40_000, 10)),
        ] {
            let err = Aedat4Writer::create(&path, g, Aedat4Compression::Lz4)
                .err()
                .unwrap();
            assert!(err.to_string().contains("geometry"), "{err}");
        }
        assert!(!path.exists());
        assert!(!dir.path().join("g.aedat4.partial").exists());
    }

    #[test]
    fn events_off_the_sensor_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("o.aedat4");
        let mut w = Box::new(
            Aedat4Writer::create(&path, Some(Geometry::new(32, 16)), Aedat4Compression::Lz4)
                .unwrap(),
        );
        let mut b = EventBuffer::new();
        b.push(0, 31, 15, 1);
        w.write(&b).unwrap();
        for (x, y) in [(32, 0), (0, 16), (u16::MAX, 0)] {
            let mut bad = EventBuffer::new();
            bad.push(1, 0, 0, 0);
            bad.push(2, x, y, 0);
            let err = w.write(&bad).unwrap_err().to_string();
            assert!(err.contains(&format!("event 2 at ({x}, {y})")), "{err}");
        }
        drop(w);
        assert!(!path.exists());
    }

    #[test]
    fn the_header_names_the_streams_and_is_patched_in_place() {
        let dir = tempfile::tempdir().unwrap();
        for (with_triggers, compression) in [
            (false, Aedat4Compression::Lz4),
            (true, Aedat4Compression::Zstd),
            (true, Aedat4Compression::None),
        ] {
            let path = dir.path().join(format!("h{with_triggers}.aedat4"));
            let g = Some(Geometry::new(346, 260));
            let mut w: Box<dyn EventWriter> =
                Box::new(Aedat4Writer::create(&path, g, compression).unwrap());
            let mut b = EventBuffer::new();
            for i in 0..10_000 {
                b.push(
                    1_700_000_000_000_000 + i,
                    (i % 346) as u16,
                    (i % 260) as u16,
                    1,
                );
            }
            if with_triggers {
                b.triggers.push(Trigger {
                    t: 5,
                    channel: 0,
                    value: 1,
                });
            }
            w.write(&b).unwrap();
            w.finish().unwrap();
            let rec = read_all(&path, &ReadOptions::default()).unwrap();
            assert_eq!(rec.events, b);
            assert_eq!(rec.metadata.geometry, g);
            assert_eq!(rec.metadata.sensor.as_deref(), Some("ebiv"));
            assert_eq!(
                rec.metadata.header_value("compression"),
                Some(compression.name())
            );
            assert_eq!(
                rec.metadata.header_value("stream 0"),
                Some("EVTS 346x260 ebiv")
            );
            let trig = rec.metadata.header_value("stream 1");
            assert_eq!(trig, with_triggers.then_some("TRIG ebiv"));
            let position: u64 = rec
                .metadata
                .header_value("dataTablePosition")
                .unwrap()
                .parse()
                .unwrap();
            let len = std::fs::metadata(&path).unwrap().len();
            assert!(position > 0 && position < len);
            assert!(!rec.report.has_problems(), "{:?}", rec.report);
        }
    }

    #[test]
    fn lz4_frames_are_independent_and_complete() {
        let mut c = PacketCompressor::new(Aedat4Compression::Lz4).unwrap();
        for n in [1usize, 70_000, 300_000, 5] {
            let data: Vec<u8> = (0..n).map(|i| (i * 7 % 13) as u8).collect();
            let frame = c.compress(&data).unwrap().to_vec();
            let mut back = Vec::new();
            std::io::Read::read_to_end(
                &mut lz4_flex::frame::FrameDecoder::new(frame.as_slice()),
                &mut back,
            )
            .unwrap();
            assert_eq!(back, data, "{n} bytes");
        }
        let mut z = PacketCompressor::new(Aedat4Compression::Zstd).unwrap();
        let data = vec![3u8; 100_000];
        let frame = z.compress(&data).unwrap().to_vec();
        assert_eq!(zstd::bulk::decompress(&frame, 200_000).unwrap(), data);
    }
}
