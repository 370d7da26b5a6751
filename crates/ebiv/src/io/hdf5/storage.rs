//! The byte source of a reader as the random-access storage the pure-Rust HDF5 reader
//! (`hdf5-reader`) parses: every range is read by seeking, so a file is never loaded whole.

use super::super::ReadSeek;
use hdf5_reader::{Storage, StorageBuffer};
use std::io::{Read, Seek, SeekFrom};
use std::sync::Mutex;

/// A seekable source shared behind a lock (the HDF5 reader asks for ranges from any thread).
pub(super) struct SourceStorage {
    source: Mutex<Box<dyn ReadSeek>>,
    len: u64,
}

impl SourceStorage {
    /// Storage over `source`, whose length is found by seeking to its end.
    pub fn new(mut source: Box<dyn ReadSeek>) -> std::io::Result<Self> {
        let len = source.seek(SeekFrom::End(0))?;
        Ok(SourceStorage {
            source: Mutex::new(source),
            len,
        })
    }
}

fn storage_error(message: String) -> hdf5_reader::error::Error {
    hdf5_reader::error::Error::InvalidData(message)
}

impl Storage for SourceStorage {
    fn len(&self) -> u64 {
        self.len
    }

    /// The bytes `offset..offset + len`; a range past the end of the file is an error (so a
    /// damaged size field cannot make the reader allocate more than the file holds).
    fn read_range(&self, offset: u64, len: usize) -> hdf5_reader::error::Result<StorageBuffer> {
        let end = offset.checked_add(len as u64);
        if end.is_none_or(|end| end > self.len) {
            return Err(hdf5_reader::error::Error::UnexpectedEof {
                offset,
                needed: len as u64,
                available: self.len.saturating_sub(offset),
            });
        }
        let mut source = self
            .source
            .lock()
            .map_err(|_| storage_error("file handle poisoned by an earlier panic".into()))?;
        let mut bytes = vec![0u8; len];
        source
            .seek(SeekFrom::Start(offset))
            .and_then(|_| source.read_exact(&mut bytes))
            .map_err(|e| storage_error(format!("reading {len} bytes at byte {offset}: {e}")))?;
        Ok(StorageBuffer::from_vec(bytes))
    }
}
