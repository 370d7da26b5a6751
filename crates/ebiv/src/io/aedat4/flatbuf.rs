//! Bounds-checked reading of FlatBuffers, just enough for AEDAT 4.0 (formats.md §9).
//!
//! Layout as documented in the FlatBuffers internals guide (<https://flatbuffers.dev/internals/>):
//! a buffer starts with a `u32` offset to the root table (after an optional `u32` size prefix
//! and before an optional 4-byte file identifier); a table starts with an `i32` back-offset to
//! its vtable; the vtable holds `u16` vtable size, `u16` table size and one `u16` offset per
//! field (0 = absent, the default applies); offsets to tables, vectors and strings are `u32`
//! relative to where they are stored; vectors and strings start with a `u32` element count.
//!
//! Every read checks its bounds and returns [`FbError`] instead of panicking, so a hostile
//! file can only make decoding fail.

/// Why a flatbuffer could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct FbError(pub &'static str);

impl std::fmt::Display for FbError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

pub(super) type FbResult<T> = std::result::Result<T, FbError>;

fn bytes<const N: usize>(buf: &[u8], pos: usize) -> FbResult<[u8; N]> {
    pos.checked_add(N)
        .and_then(|end| buf.get(pos..end))
        .and_then(|s| s.try_into().ok())
        .ok_or(FbError("offset points outside the buffer"))
}

fn read_u16(buf: &[u8], pos: usize) -> FbResult<u16> {
    bytes::<2>(buf, pos).map(u16::from_le_bytes)
}

fn read_u32(buf: &[u8], pos: usize) -> FbResult<u32> {
    bytes::<4>(buf, pos).map(u32::from_le_bytes)
}

/// The 4-character file identifier of a buffer and where its root offset sits, accepting both
/// plain and size-prefixed buffers. Returns the buffer without its size prefix.
fn unprefixed<'a>(buf: &'a [u8], identifier: &[u8; 4]) -> FbResult<&'a [u8]> {
    if buf.get(4..8) == Some(identifier.as_slice()) {
        return Ok(buf);
    }
    if buf.get(8..12) == Some(identifier.as_slice()) {
        let size = read_u32(buf, 0)? as usize;
        return buf
            .get(4..)
            .and_then(|rest| rest.get(..size))
            .ok_or(FbError("size prefix is larger than the buffer"));
    }
    Err(FbError("file identifier not found"))
}

/// The identifier stored in a buffer (plain or size-prefixed), for messages.
pub(super) fn identifier_of(buf: &[u8]) -> String {
    let printable = |s: &[u8]| s.iter().all(|b| b.is_ascii_alphanumeric());
    for range in [8..12, 4..8] {
        if let Some(id) = buf.get(range) {
            if printable(id) {
                return String::from_utf8_lossy(id).into_owned();
            }
        }
    }
    "none".into()
}

/// The root table of `buf`, which must carry `identifier` (size prefix optional).
pub(super) fn root<'a>(buf: &'a [u8], identifier: &[u8; 4]) -> FbResult<Table<'a>> {
    let buf = unprefixed(buf, identifier)?;
    let offset = read_u32(buf, 0)? as usize;
    Table::at(buf, offset)
}

/// A table inside a buffer.
#[derive(Clone, Copy)]
pub(super) struct Table<'a> {
    buf: &'a [u8],
    pos: usize,
    vtable: usize,
    vtable_len: usize,
}

impl<'a> Table<'a> {
    /// The table starting at byte `pos` of `buf`.
    pub(super) fn at(buf: &'a [u8], pos: usize) -> FbResult<Self> {
        let back = i32::from_le_bytes(bytes::<4>(buf, pos)?);
        let vtable = (pos as i64)
            .checked_sub(back as i64)
            .filter(|&v| v >= 0)
            .ok_or(FbError("vtable offset points before the buffer"))?
            as usize;
        let vtable_len = read_u16(buf, vtable)? as usize;
        let table_len = read_u16(buf, vtable + 2)? as usize;
        if vtable_len < 4 || vtable_len % 2 != 0 || vtable + vtable_len > buf.len() {
            return Err(FbError("invalid vtable size"));
        }
        if table_len < 4 || pos + table_len > buf.len() {
            return Err(FbError("table extends past the buffer"));
        }
        Ok(Table {
            buf,
            pos,
            vtable,
            vtable_len,
        })
    }

    /// Absolute position of field `index`, or `None` when the field is absent.
    fn field(&self, index: usize) -> FbResult<Option<usize>> {
        let entry = 4 + 2 * index;
        if entry + 2 > self.vtable_len {
            return Ok(None);
        }
        match read_u16(self.buf, self.vtable + entry)? {
            0 => Ok(None),
            offset => Ok(Some(self.pos + offset as usize)),
        }
    }

    /// Scalar field `index` of `N` bytes, if present.
    fn scalar<const N: usize>(&self, index: usize) -> FbResult<Option<[u8; N]>> {
        match self.field(index)? {
            None => Ok(None),
            Some(pos) => bytes::<N>(self.buf, pos).map(Some),
        }
    }

    /// `i64` field `index`, or `default` when absent.
    pub(super) fn i64(&self, index: usize, default: i64) -> FbResult<i64> {
        Ok(self.scalar::<8>(index)?.map_or(default, i64::from_le_bytes))
    }

    /// `i32` field `index`, or `default` when absent.
    pub(super) fn i32(&self, index: usize, default: i32) -> FbResult<i32> {
        Ok(self.scalar::<4>(index)?.map_or(default, i32::from_le_bytes))
    }

    /// `i8` field `index`, or `default` when absent.
    pub(super) fn i8(&self, index: usize, default: i8) -> FbResult<i8> {
        Ok(self.scalar::<1>(index)?.map_or(default, i8::from_le_bytes))
    }

    /// The `N` bytes of an inline struct field, if present.
    pub(super) fn inline_struct<const N: usize>(&self, index: usize) -> FbResult<Option<[u8; N]>> {
        self.scalar::<N>(index)
    }

    /// Follow the `u32` offset stored in field `index`.
    fn indirect(&self, index: usize) -> FbResult<Option<usize>> {
        match self.field(index)? {
            None => Ok(None),
            Some(pos) => {
                let offset = read_u32(self.buf, pos)? as usize;
                let target = pos
                    .checked_add(offset)
                    .filter(|&t| t < self.buf.len())
                    .ok_or(FbError("offset points outside the buffer"))?;
                Ok(Some(target))
            }
        }
    }

    /// Vector field `index` of elements `elem_size` bytes wide: its element count and bytes.
    pub(super) fn vector(
        &self,
        index: usize,
        elem_size: usize,
    ) -> FbResult<Option<(usize, &'a [u8])>> {
        let Some(pos) = self.indirect(index)? else {
            return Ok(None);
        };
        let count = read_u32(self.buf, pos)? as usize;
        let data = count
            .checked_mul(elem_size)
            .and_then(|len| (pos + 4).checked_add(len))
            .and_then(|end| self.buf.get(pos + 4..end))
            .ok_or(FbError("vector extends past the buffer"))?;
        Ok(Some((count, data)))
    }

    /// String field `index`, if present.
    pub(super) fn string(&self, index: usize) -> FbResult<Option<&'a str>> {
        match self.vector(index, 1)? {
            None => Ok(None),
            Some((_, data)) => std::str::from_utf8(data)
                .map(Some)
                .map_err(|_| FbError("string is not UTF-8")),
        }
    }

    /// Vector-of-tables field `index`, if present.
    pub(super) fn tables(&self, index: usize) -> FbResult<Option<TableVector<'a>>> {
        let Some(pos) = self.indirect(index)? else {
            return Ok(None);
        };
        let (count, _) = self
            .vector(index, 4)?
            .ok_or(FbError("vector extends past the buffer"))?;
        Ok(Some(TableVector {
            buf: self.buf,
            first: pos + 4,
            count,
        }))
    }
}

/// A vector of tables: `count` `u32` offsets starting at `first`.
#[derive(Clone, Copy)]
pub(super) struct TableVector<'a> {
    buf: &'a [u8],
    first: usize,
    count: usize,
}

impl<'a> TableVector<'a> {
    /// Number of tables.
    pub(super) fn len(&self) -> usize {
        self.count
    }

    /// Table `i` (`i < len()`).
    pub(super) fn get(&self, i: usize) -> FbResult<Table<'a>> {
        if i >= self.count {
            return Err(FbError("vector index out of range"));
        }
        let slot = self.first + 4 * i;
        let offset = read_u32(self.buf, slot)? as usize;
        let pos = slot
            .checked_add(offset)
            .ok_or(FbError("offset points outside the buffer"))?;
        Table::at(self.buf, pos)
    }
}

/// The root table of `buf`, with or without the identifier `identifier` (writers may omit
/// it); a size prefix is only recognised together with the identifier.
pub(super) fn root_lenient<'a>(buf: &'a [u8], identifier: &[u8; 4]) -> FbResult<Table<'a>> {
    match root(buf, identifier) {
        Err(FbError("file identifier not found")) => {
            let offset = read_u32(buf, 0)? as usize;
            Table::at(buf, offset)
        }
        other => other,
    }
}
