//! A small AEDAT 4.0 writer for the tests: IOHeader, EVTS/TRIG packet bodies and the data
//! table as FlatBuffers, whole files with any compression (formats.md §9).

use super::*;
use std::io::Write;

/// A forward FlatBuffers writer: objects are appended in order and offsets patched later.
struct Fb {
    buf: Vec<u8>,
}

impl Fb {
    fn new() -> Self {
        Fb { buf: Vec::new() }
    }

    fn pos(&self) -> usize {
        self.buf.len()
    }

    fn align(&mut self, n: usize) {
        while self.buf.len() % n != 0 {
            self.buf.push(0);
        }
    }

    /// A table of inline fields (scalars, structs, or 4-byte offset slots to patch). Returns
    /// the table position and the position of each present field.
    fn table(&mut self, fields: &[Option<Vec<u8>>]) -> (usize, Vec<Option<usize>>) {
        self.align(2);
        let vtable = self.pos();
        let vtable_len = 4 + 2 * fields.len();
        let mut offsets = Vec::new();
        let mut at = 4;
        for f in fields {
            match f {
                Some(bytes) => {
                    offsets.push(at as u16);
                    at += bytes.len();
                }
                None => offsets.push(0),
            }
        }
        self.buf.extend((vtable_len as u16).to_le_bytes());
        self.buf.extend((at as u16).to_le_bytes());
        for o in &offsets {
            self.buf.extend(o.to_le_bytes());
        }
        self.align(4);
        let table = self.pos();
        self.buf.extend(((table - vtable) as i32).to_le_bytes());
        let mut positions = Vec::new();
        for f in fields {
            match f {
                Some(bytes) => {
                    positions.push(Some(self.pos()));
                    self.buf.extend(bytes);
                }
                None => positions.push(None),
            }
        }
        (table, positions)
    }

    /// Point the 4-byte slot at `slot` to `target`.
    fn patch(&mut self, slot: usize, target: usize) {
        let off = (target - slot) as u32;
        self.buf[slot..slot + 4].copy_from_slice(&off.to_le_bytes());
    }

    /// A vector of `count` elements given as bytes; returns its position.
    fn vector(&mut self, count: usize, data: &[u8]) -> usize {
        self.align(4);
        if self.pos() % 8 == 0 {
            self.buf.extend([0; 4]);
        }
        let pos = self.pos();
        self.buf.extend((count as u32).to_le_bytes());
        self.buf.extend(data);
        pos
    }

    /// Finish with a root offset and identifier in front, optionally size-prefixed.
    fn finish(self, root: usize, identifier: &[u8; 4], size_prefixed: bool) -> Vec<u8> {
        let mut inner = Vec::new();
        inner.extend(((root + 8) as u32).to_le_bytes());
        inner.extend(identifier);
        inner.extend(self.buf);
        if !size_prefixed {
            return inner;
        }
        let mut out = (inner.len() as u32).to_le_bytes().to_vec();
        out.extend(inner);
        out
    }
}

const SLOT: Option<[u8; 4]> = Some([0; 4]);

fn slot() -> Option<Vec<u8>> {
    SLOT.map(|s| s.to_vec())
}

/// An `EventPacket` body.
pub(super) fn events_body(events: &[(i64, i16, i16, bool)]) -> Vec<u8> {
    let mut fb = Fb::new();
    let (root, fields) = fb.table(&[slot()]);
    let mut data = Vec::new();
    for &(t, x, y, p) in events {
        data.extend(t.to_le_bytes());
        data.extend(x.to_le_bytes());
        data.extend(y.to_le_bytes());
        data.extend([p as u8, 0, 0, 0]);
    }
    let v = fb.vector(events.len(), &data);
    fb.patch(fields[0].unwrap(), v);
    fb.finish(root, b"EVTS", true)
}

/// A `TriggerPacket` body.
pub(super) fn triggers_body(triggers: &[(i64, i8)]) -> Vec<u8> {
    let mut fb = Fb::new();
    let (root, fields) = fb.table(&[slot()]);
    let v = fb.vector(triggers.len(), &vec![0; 4 * triggers.len()]);
    for (i, &(t, kind)) in triggers.iter().enumerate() {
        let (table, _) = fb.table(&[Some(t.to_le_bytes().to_vec()), Some(vec![kind as u8])]);
        fb.patch(v + 4 + 4 * i, table);
    }
    fb.patch(fields[0].unwrap(), v);
    fb.finish(root, b"TRIG", true)
}

/// A `FileDataTable` body from (offset, stream id, size, count, t_start, t_end).
pub(super) fn table_body(entries: &[Entry]) -> Vec<u8> {
    let mut fb = Fb::new();
    let (root, fields) = fb.table(&[slot()]);
    let v = fb.vector(entries.len(), &vec![0; 4 * entries.len()]);
    for (i, &(offset, id, size, n, t0, t1)) in entries.iter().enumerate() {
        let mut header = id.to_le_bytes().to_vec();
        header.extend(size.to_le_bytes());
        let (table, _) = fb.table(&[
            Some(offset.to_le_bytes().to_vec()),
            Some(header),
            Some(n.to_le_bytes().to_vec()),
            Some(t0.to_le_bytes().to_vec()),
            Some(t1.to_le_bytes().to_vec()),
        ]);
        fb.patch(v + 4 + 4 * i, table);
    }
    fb.patch(fields[0].unwrap(), v);
    fb.finish(root, b"FTAB", true)
}

/// An IOHeader flatbuffer (not size-prefixed, as DV writes it).
pub(super) fn io_header(compression: i32, table_position: Option<i64>, info: &str) -> Vec<u8> {
    let mut fb = Fb::new();
    let (root, fields) = fb.table(&[
        Some(compression.to_le_bytes().to_vec()),
        table_position.map(|p| p.to_le_bytes().to_vec()),
        slot(),
    ]);
    let mut text = info.as_bytes().to_vec();
    text.push(0);
    let s = fb.vector(info.len(), &text);
    fb.patch(fields[2].unwrap(), s);
    fb.finish(root, b"IOHE", false)
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
    fn code(self) -> i32 {
        match self {
            Codec::None => 0,
            Codec::Lz4 | Codec::Lz4Linked => 1,
            Codec::Zstd => 3,
        }
    }

    pub(super) fn compress(self, data: &[u8]) -> Vec<u8> {
        match self {
            Codec::None => data.to_vec(),
            Codec::Lz4 | Codec::Lz4Linked => {
                let mut info = lz4_flex::frame::FrameInfo::new();
                if self == Codec::Lz4Linked {
                    info = info
                        .block_mode(lz4_flex::frame::BlockMode::Linked)
                        .content_checksum(true);
                }
                let mut enc = lz4_flex::frame::FrameEncoder::with_frame_info(info, Vec::new());
                enc.write_all(data).unwrap();
                enc.finish().unwrap()
            }
            Codec::Zstd => zstd::bulk::compress(data, 3).unwrap(),
        }
    }
}

/// A packet of the test file: stream id and uncompressed body.
pub(super) type Packet = (i32, Vec<u8>);

/// A data-table entry: (offset, stream id, size, count, t_start, t_end).
pub(super) type Entry = (i64, i32, i32, i64, i64, i64);

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
    let data_start = 18 + header_len;
    for (id, payload) in packets {
        let compressed = codec.compress(payload);
        let offset = (data_start + body.len()) as i64;
        body.extend(id.to_le_bytes());
        body.extend((compressed.len() as i32).to_le_bytes());
        body.extend(&compressed);
        let (t0, t1, n) = packet_times(*id, payload);
        // ByteOffset points at the packet body, after the 8-byte packet header.
        entries.push((offset + 8, *id, compressed.len() as i32, n, t0, t1));
    }
    let table_position = (data_start + body.len()) as i64;
    let header = io_header(
        codec.code(),
        Some(if table { table_position } else { -1 }),
        &info,
    );
    assert_eq!(header.len(), header_len);
    let mut out = MAGIC.to_vec();
    out.extend((header.len() as i32).to_le_bytes());
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
