//! FlatBuffers encoding of the AEDAT 4.0 structures (formats.md §9; iniVation docs
//! `aedat-4.0`; schemas `IOHeader`, `EventPacket`, `TriggerPacket`, `FileDataTable` of
//! dv-processing): the IOHeader, `EVTS` and `TRIG` packet bodies and the `FTAB` data table.
//!
//! The builder writes front to back, parents before children, and patches each `u32` offset
//! once its target exists (offsets in FlatBuffers point forward, so this order is always
//! valid; see <https://flatbuffers.dev/internals/>). Every scalar is aligned to its size
//! relative to the start of the buffer, size prefix included, as DV's own files are, so strict
//! verifiers (flatbuffers' `Verifier` with alignment checks) accept the result.

/// A forward FlatBuffers builder over a reusable byte vector.
pub(crate) struct Builder {
    buf: Vec<u8>,
    /// Where the root offset sits: 4 with a size prefix, else 0.
    root_slot: usize,
}

/// One inline field of a table.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Field {
    /// Not stored; readers use the schema default.
    Absent,
    /// A scalar or struct of `len` bytes (at most 8) aligned to `align`.
    Inline {
        bytes: [u8; 8],
        len: usize,
        align: usize,
    },
    /// A `u32` offset to an object added later and set with [`Builder::point`].
    Offset,
}

impl Field {
    pub(crate) fn i64(v: i64) -> Self {
        Field::Inline {
            bytes: v.to_le_bytes(),
            len: 8,
            align: 8,
        }
    }

    pub(crate) fn i32(v: i32) -> Self {
        let mut bytes = [0; 8];
        bytes[..4].copy_from_slice(&v.to_le_bytes());
        Field::Inline {
            bytes,
            len: 4,
            align: 4,
        }
    }

    pub(crate) fn i8(v: i8) -> Self {
        let mut bytes = [0; 8];
        bytes[0] = v as u8;
        Field::Inline {
            bytes,
            len: 1,
            align: 1,
        }
    }

    /// A struct of two `i32` (such as `PacketHeader { StreamID, Size }`).
    pub(crate) fn i32_pair(a: i32, b: i32) -> Self {
        let mut bytes = [0; 8];
        bytes[..4].copy_from_slice(&a.to_le_bytes());
        bytes[4..].copy_from_slice(&b.to_le_bytes());
        Field::Inline {
            bytes,
            len: 8,
            align: 4,
        }
    }

    /// Size and alignment in the table, when present.
    fn layout(&self) -> Option<(usize, usize)> {
        match *self {
            Field::Absent => None,
            Field::Inline { len, align, .. } => Some((len, align)),
            Field::Offset => Some((4, 4)),
        }
    }
}

impl Builder {
    /// Start a buffer with `identifier` in `buf` (cleared; its capacity is reused).
    pub(crate) fn new(mut buf: Vec<u8>, identifier: &[u8; 4], size_prefixed: bool) -> Self {
        buf.clear();
        let root_slot = if size_prefixed { 4 } else { 0 };
        buf.resize(root_slot + 4, 0);
        buf.extend_from_slice(identifier);
        Builder { buf, root_slot }
    }

    fn pad_until(&mut self, aligned: impl Fn(usize) -> bool) {
        while !aligned(self.buf.len()) {
            self.buf.push(0);
        }
    }

    /// Append a table (vtable first). Fields are laid out by decreasing alignment so that
    /// none needs padding. Returns the table's position and each field's position (0 for
    /// absent fields).
    pub(crate) fn table<const N: usize>(&mut self, fields: [Field; N]) -> (usize, [usize; N]) {
        let mut offsets = [0usize; N];
        let mut size = 4;
        let mut max_align = 4;
        for align in [8, 4, 2, 1] {
            for (i, field) in fields.iter().enumerate() {
                if let Some((len, a)) = field.layout() {
                    if a == align {
                        offsets[i] = size;
                        size += len;
                        max_align = max_align.max(a);
                    }
                }
            }
        }
        self.pad_until(|p| p % 2 == 0);
        let vtable = self.buf.len();
        self.buf
            .extend_from_slice(&((4 + 2 * N) as u16).to_le_bytes());
        self.buf.extend_from_slice(&(size as u16).to_le_bytes());
        for &o in &offsets {
            self.buf.extend_from_slice(&(o as u16).to_le_bytes());
        }
        // The first field (at table + 4) gets the largest alignment.
        self.pad_until(|p| p % 4 == 0 && (p + 4) % max_align == 0);
        let table = self.buf.len();
        self.buf
            .extend_from_slice(&((table - vtable) as i32).to_le_bytes());
        self.buf.resize(table + size, 0);
        let mut positions = [0usize; N];
        for (i, field) in fields.iter().enumerate() {
            if field.layout().is_none() {
                continue;
            }
            positions[i] = table + offsets[i];
            if let Field::Inline { bytes, len, .. } = field {
                self.buf[positions[i]..positions[i] + len].copy_from_slice(&bytes[..*len]);
            }
        }
        (table, positions)
    }

    /// Start a vector of `count` elements aligned to `elem_align`; the caller appends the
    /// elements with [`Builder::extend`]. Returns the vector's position.
    pub(crate) fn begin_vector(&mut self, count: usize, elem_align: usize) -> usize {
        let align = elem_align.max(4);
        self.pad_until(|p| p % 4 == 0 && (p + 4) % align == 0);
        let pos = self.buf.len();
        self.buf.extend_from_slice(&(count as u32).to_le_bytes());
        pos
    }

    /// Append raw element bytes to the vector just begun.
    pub(crate) fn extend(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// A vector of `count` offsets to tables added later; slot `i` is at `pos + 4 + 4 i`.
    pub(crate) fn offset_vector(&mut self, count: usize) -> usize {
        let pos = self.begin_vector(count, 4);
        self.buf.resize(pos + 4 + 4 * count, 0);
        pos
    }

    /// A NUL-terminated string; returns its position.
    pub(crate) fn string(&mut self, text: &str) -> usize {
        let pos = self.begin_vector(text.len(), 1);
        self.buf.extend_from_slice(text.as_bytes());
        self.buf.push(0);
        pos
    }

    /// Point the `u32` offset slot at `slot` to the object at `target` (added after it).
    pub(crate) fn point(&mut self, slot: usize, target: usize) {
        let offset = (target - slot) as u32;
        self.buf[slot..slot + 4].copy_from_slice(&offset.to_le_bytes());
    }

    /// Set the root table and the size prefix; returns the finished buffer.
    pub(crate) fn finish(mut self, root: usize) -> Vec<u8> {
        self.point(self.root_slot, root);
        if self.root_slot == 4 {
            let size = (self.buf.len() - 4) as u32;
            self.buf[..4].copy_from_slice(&size.to_le_bytes());
        }
        self.buf
    }
}

/// Size of one `dv::Event` struct: `i64 timestamp, i16 x, i16 y, bool polarity`, padded to 8.
pub(crate) const EVENT_BYTES: usize = 16;

/// One `dv::Event` struct as stored in an `EVTS` packet.
#[inline]
pub(crate) fn event_record(t: i64, x: i16, y: i16, polarity: bool) -> [u8; EVENT_BYTES] {
    let mut r = [0u8; EVENT_BYTES];
    r[..8].copy_from_slice(&t.to_le_bytes());
    r[8..10].copy_from_slice(&x.to_le_bytes());
    r[10..12].copy_from_slice(&y.to_le_bytes());
    r[12] = polarity as u8;
    r
}

/// An `EventPacket` body (identifier `EVTS`, size-prefixed): field 0 is the vector of
/// `Event` structs given as packed records (see [`event_record`]). Built in `buf`.
pub(crate) fn events_body(records: &[u8], buf: Vec<u8>) -> Vec<u8> {
    let mut fb = Builder::new(buf, b"EVTS", true);
    let (root, [elements]) = fb.table([Field::Offset]);
    let v = fb.begin_vector(records.len() / EVENT_BYTES, 8);
    fb.extend(records);
    fb.point(elements, v);
    fb.finish(root)
}

/// A `TriggerPacket` body (identifier `TRIG`, size-prefixed): field 0 is a vector of
/// `Trigger` tables `{timestamp: i64, type: i8}`. Built in `buf`.
pub(crate) fn triggers_body(triggers: &[(i64, i8)], buf: Vec<u8>) -> Vec<u8> {
    let mut fb = Builder::new(buf, b"TRIG", true);
    let (root, [elements]) = fb.table([Field::Offset]);
    let v = fb.offset_vector(triggers.len());
    for (i, &(t, kind)) in triggers.iter().enumerate() {
        let (table, _) = fb.table([Field::i64(t), Field::i8(kind)]);
        fb.point(v + 4 + 4 * i, table);
    }
    fb.point(elements, v);
    fb.finish(root)
}

/// One `FileDataDefinition` of the data table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PacketRecord {
    /// `ByteOffset`: file offset of the packet body, 8 bytes after the packet header (as DV
    /// writes it and the reader expects).
    pub offset: i64,
    /// `PacketInfo.StreamID`.
    pub stream_id: i32,
    /// `PacketInfo.Size`: compressed body size.
    pub size: i32,
    /// `NumElements`.
    pub elements: i64,
    /// `TimestampStart`.
    pub t_start: i64,
    /// `TimestampEnd`.
    pub t_end: i64,
}

/// A `FileDataTable` body (identifier `FTAB`, size-prefixed): field 0 is a vector of
/// `FileDataDefinition` tables `{ByteOffset, PacketInfo, NumElements, TimestampStart,
/// TimestampEnd}`.
pub(crate) fn table_body(entries: &[PacketRecord]) -> Vec<u8> {
    let mut fb = Builder::new(Vec::new(), b"FTAB", true);
    let (root, [definitions]) = fb.table([Field::Offset]);
    let v = fb.offset_vector(entries.len());
    for (i, e) in entries.iter().enumerate() {
        let (table, _) = fb.table([
            Field::i64(e.offset),
            Field::i32_pair(e.stream_id, e.size),
            Field::i64(e.elements),
            Field::i64(e.t_start),
            Field::i64(e.t_end),
        ]);
        fb.point(v + 4 + 4 * i, table);
    }
    fb.point(definitions, v);
    fb.finish(root)
}

/// The IOHeader as it follows the magic line: a size-prefixed flatbuffer (identifier `IOHE`)
/// whose prefix is the file's `i32` header length, as DV writes it. Fields: 0 `compression`
/// (i32), 1 `dataTablePosition` (i64, omitted when `None`), 2 `infoNode` (string).
pub(crate) fn io_header(compression: i32, table_position: Option<i64>, info: &str) -> Vec<u8> {
    let mut fb = Builder::new(Vec::new(), b"IOHE", true);
    let (root, [_, _, info_slot]) = fb.table([
        Field::i32(compression),
        table_position.map_or(Field::Absent, Field::i64),
        Field::Offset,
    ]);
    let s = fb.string(info);
    fb.point(info_slot, s);
    fb.finish(root)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalars_are_aligned_from_the_size_prefix() {
        let body = table_body(&[PacketRecord {
            offset: 100,
            stream_id: 3,
            size: 40,
            elements: 2,
            t_start: -5,
            t_end: 7,
        }]);
        // Root offset, identifier, then the root table and the vector.
        assert_eq!(&body[8..12], b"FTAB");
        let size = u32::from_le_bytes(body[..4].try_into().unwrap()) as usize;
        assert_eq!(size, body.len() - 4);
        for (value, len) in [(100i64, 8usize), (-5, 8), (7, 8)] {
            let bytes = &value.to_le_bytes()[..len];
            let at = body.windows(len).position(|w| w == bytes).unwrap();
            assert_eq!(at % 8, 0, "i64 {value} at {at}");
        }
        let records: Vec<u8> = [event_record(1, 2, 3, true), event_record(4, 5, 6, false)].concat();
        let body = events_body(&records, Vec::new());
        let at = body
            .windows(records.len())
            .position(|w| w == records)
            .unwrap();
        assert_eq!(at % 8, 0);
        assert_eq!(u32::from_le_bytes(body[at - 4..at].try_into().unwrap()), 2);
        let header = io_header(1, Some(0x0102_0304_0506_0708), "<dv/>");
        let at = header
            .windows(8)
            .position(|w| w == 0x0102_0304_0506_0708i64.to_le_bytes())
            .unwrap();
        assert_eq!(at % 8, 0);
    }
}
