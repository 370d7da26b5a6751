//! AEDAT 4.0 files the public writer cannot produce, for the reader's tests: several streams
//! (IMU, unknown ids), packets of any content, DV's linked LZ4 blocks, missing or tampered
//! data tables (formats.md §9). The flatbuffers come from the production writer's encoders
//! ([`crate::io::write::aedat4`]).

use super::*;
use crate::io::write::aedat4::{self as writer, Aedat4Compression, PacketCompressor};
use std::io::Write;

pub(super) use writer::{io_header, table_body, PacketRecord as Entry};

/// An `EventPacket` body of `(t, x, y, p)`; coordinates may be negative, to test the reader.
pub(super) fn events_body(events: &[(i64, i16, i16, bool)]) -> Vec<u8> {
    let records: Vec<u8> = events
        .iter()
        .flat_map(|&(t, x, y, p)| writer::event_record(t, x, y, p))
        .collect();
    writer::events_body(&records, Vec::new())
}

/// A `TriggerPacket` body of `(t, type)`, any type.
pub(super) fn triggers_body(triggers: &[(i64, i8)]) -> Vec<u8> {
    writer::triggers_body(triggers, Vec::new())
}

pub(super) fn info_xml(width: u32, height: u32) -> String {
    format!(
        r#"<dv version="2.0">
    <node name="outInfo" path="/mainloop/Recorder/outInfo/">
        <node name="0" path="/mainloop/Recorder/outInfo/0/">
            <attr key="compression" type="string">LZ4</attr>
            <attr key="typeIdentifier" type="string">EVTS</attr>
            <node name="info" path="/mainloop/Recorder/outInfo/0/info/">
                <attr key="sizeX" type="int">{width}</attr>
                <attr key="sizeY" type="int">{height}</attr>
                <attr key="source" type="string">DVXplorer_TEST0001</attr>
                <attr key="tsOffset" type="long">1000</attr>
            </node>
        </node>
        <node name="2" path="/mainloop/Recorder/outInfo/2/">
            <attr key="typeIdentifier" type="string">IMUS</attr>
        </node>
        <node name="3" path="/mainloop/Recorder/outInfo/3/">
            <attr key="typeIdentifier" type="string">TRIG</attr>
        </node>
    </node>
</dv>"#
    )
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Codec {
    None,
    Lz4,
    Lz4Linked,
    Zstd,
}

impl Codec {
    fn production(self) -> Option<Aedat4Compression> {
        match self {
            Codec::None => Some(Aedat4Compression::None),
            Codec::Lz4 => Some(Aedat4Compression::Lz4),
            Codec::Zstd => Some(Aedat4Compression::Zstd),
            Codec::Lz4Linked => None,
        }
    }

    fn code(self) -> i32 {
        self.production().map_or(1, Aedat4Compression::code)
    }

    /// One frame, as the writer makes it; `Lz4Linked` makes DV's linked blocks with a content
    /// checksum instead.
    pub(super) fn compress(self, data: &[u8]) -> Vec<u8> {
        match self.production() {
            Some(c) => PacketCompressor::new(c)
                .unwrap()
                .compress(data)
                .unwrap()
                .to_vec(),
            None => {
                let info = lz4_flex::frame::FrameInfo::new()
                    .block_mode(lz4_flex::frame::BlockMode::Linked)
                    .content_checksum(true);
                let mut enc = lz4_flex::frame::FrameEncoder::with_frame_info(info, Vec::new());
                enc.write_all(data).unwrap();
                enc.finish().unwrap()
            }
        }
    }
}

/// A packet of the test file: stream id and uncompressed body.
pub(super) type Packet = (i32, Vec<u8>);

/// A whole AEDAT 4.0 file; with `table`, a data table indexing every packet.
pub(super) fn file(
    codec: Codec,
    packets: &[Packet],
    table: bool,
    width: u32,
    height: u32,
) -> Vec<u8> {
    file_with(codec, packets, table, width, height, |_| {})
}

/// [`file`] with the data table entries changed by `tweak` before they are written.
pub(super) fn file_with(
    codec: Codec,
    packets: &[Packet],
    table: bool,
    width: u32,
    height: u32,
    tweak: impl Fn(&mut [Entry]),
) -> Vec<u8> {
    let info = info_xml(width, height);
    let header_len = io_header(codec.code(), Some(0), &info).len();
    let mut body = Vec::new();
    let mut entries = Vec::new();
    let data_start = MAGIC.len() + header_len;
    for (id, payload) in packets {
        let compressed = codec.compress(payload);
        let offset = (data_start + body.len()) as i64;
        body.extend(id.to_le_bytes());
        body.extend((compressed.len() as i32).to_le_bytes());
        body.extend(&compressed);
        let (t0, t1, n) = packet_times(*id, payload);
        // ByteOffset points at the packet body, after the 8-byte packet header.
        entries.push(Entry {
            offset: offset + 8,
            stream_id: *id,
            size: compressed.len() as i32,
            elements: n,
            t_start: t0,
            t_end: t1,
        });
    }
    let table_position = (data_start + body.len()) as i64;
    let header = io_header(
        codec.code(),
        Some(if table { table_position } else { -1 }),
        &info,
    );
    assert_eq!(header.len(), header_len);
    let mut out = MAGIC.to_vec();
    out.extend(header);
    out.extend(body);
    if table {
        tweak(&mut entries);
        out.extend(codec.compress(&table_body(&entries)));
    }
    out
}

/// First and last time stamp and element count of a test packet body.
fn packet_times(id: i32, payload: &[u8]) -> (i64, i64, i64) {
    let mut b = EventBuffer::new();
    let mut r = DecodeReport::default();
    let ok = match id {
        0 => decode_events(payload, (1 << 15, 1 << 15), &mut b, &mut r).is_ok(),
        3 => {
            let ok = decode_triggers(payload, &mut b, &mut r).is_ok();
            b.t = b.triggers.iter().map(|t| t.t).collect();
            ok
        }
        _ => false,
    };
    if !ok {
        return (0, 0, 1);
    }
    let (t0, t1) = b.time_range().unwrap_or((0, 0));
    (t0, t1, b.t.len() as i64)
}
