//! Shared body of the decoder fuzz targets: decoding may fail, but must never panic, hang or
//! allocate without bound. The first input byte sets the reader options (geometry given or
//! not, RAW encoding fallback or not), the rest is the file.

use ebiv::io::{self, Format, RawEncoding, ReadOptions};
use ebiv::{EventBuffer, Geometry};
use std::sync::Arc;

pub fn run(data: &[u8], format: Option<Format>) {
    let Some((&flags, file)) = data.split_first() else { return };
    let options = ReadOptions {
        format,
        geometry: (flags & 1 != 0).then_some(Geometry::new(1280, 720)),
        raw_encoding: (flags & 2 != 0).then_some(RawEncoding::Evt3),
        batch_bytes: 4096,
        ..ReadOptions::default()
    };
    let Ok(mut reader) = io::open_memory(Arc::from(file), "fuzz.bin", &options) else { return };
    let mut batch = EventBuffer::new();
    let mut batches = 0usize;
    while let Ok(true) = reader.read_batch(&mut batch) {
        assert!(batch.t.len() == batch.x.len() && batch.x.len() == batch.y.len() && batch.y.len() == batch.p.len());
        batches += 1;
        assert!(batches < 1 << 20, "a small input cannot give a million batches");
    }
    let _ = reader.report();
}
