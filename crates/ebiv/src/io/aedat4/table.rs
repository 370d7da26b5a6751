//! The `FileDataTable` (`FTAB`) at the end of an AEDAT 4.0 file: one entry per packet with
//! its position, size, element count and time range (formats.md §9), used for seeking.

use super::flatbuf::{self, FbError};
use super::StreamKind;

/// One packet of the data table that matters for seeking.
#[derive(Debug, Clone, Copy)]
pub(super) struct TableEntry {
    /// Offset of the packet header.
    pub offset: u64,
    /// Stream id of the packet header, checked before jumping.
    pub stream_id: i32,
    /// Body size of the packet header, checked before jumping.
    pub size: i32,
    /// Last time stamp in the packet (µs).
    pub t_end: i64,
}

/// Why a data table is rejected.
#[derive(Debug)]
pub(super) enum TableError {
    Flatbuffer(FbError),
    Entry(usize, &'static str),
}

impl std::fmt::Display for TableError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TableError::Flatbuffer(e) => write!(f, "invalid flatbuffer: {e}"),
            TableError::Entry(i, what) => write!(f, "entry {i}: {what}"),
        }
    }
}

impl From<FbError> for TableError {
    fn from(e: FbError) -> Self {
        TableError::Flatbuffer(e)
    }
}

/// `FileDataTable` (identifier `FTAB`): field 0, a vector of `FileDataDefinition` tables with
/// fields 0 `ByteOffset` (i64, the file offset of the packet *body*, as DV writes it),
/// 1 `PacketInfo` (inline struct `i32 StreamID, i32 Size`), 2 `NumElements`,
/// 3 `TimestampStart`, 4 `TimestampEnd` (i64). Every entry must point at a whole packet inside
/// the packet area.
pub(super) fn parse_table(
    body: &[u8],
    data_start: u64,
    data_end: u64,
    kinds: &[(i32, StreamKind)],
) -> std::result::Result<Vec<TableEntry>, TableError> {
    let root = flatbuf::root(body, b"FTAB")?;
    let Some(definitions) = root.tables(0)? else {
        return Ok(Vec::new());
    };
    let mut entries = Vec::new();
    for i in 0..definitions.len() {
        let def = definitions.get(i)?;
        let offset = def.i64(0, -1)?;
        let header = def
            .inline_struct::<8>(1)?
            .ok_or(TableError::Entry(i, "no packet header"))?;
        let stream_id = i32::from_le_bytes([header[0], header[1], header[2], header[3]]);
        let size = i32::from_le_bytes([header[4], header[5], header[6], header[7]]);
        let t_end = def.i64(4, i64::MIN)?;
        // ByteOffset is where the packet body starts, after its 8-byte header.
        let packet = offset.checked_sub(8).filter(|&p| p >= 0).map(|p| p as u64);
        let fits = packet.is_some_and(|p| {
            size >= 0
                && p >= data_start
                && p.checked_add(8 + size as u64)
                    .is_some_and(|end| end <= data_end)
        });
        let Some(packet) = packet.filter(|_| fits) else {
            return Err(TableError::Entry(i, "packet lies outside the packet area"));
        };
        let decoded = kinds.iter().any(|&(id, k)| {
            id == stream_id && matches!(k, StreamKind::Events | StreamKind::Triggers)
        });
        if decoded && def.i64(2, 0)? > 0 {
            entries.push(TableEntry {
                offset: packet,
                stream_id,
                size,
                t_end,
            });
        }
    }
    entries.sort_by_key(|e| e.offset);
    Ok(entries)
}
