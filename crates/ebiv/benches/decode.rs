//! Single-thread decode throughput per format (`cargo bench -p ebiv --bench decode`).
//!
//! Synthetic streams of 4 M events at the paper's rate (20 events per µs, 1280×720, rows and
//! columns spread like a seeded flow) are written with ebiv's own writers (RAW EVT 3.0, 2.0,
//! 2.1; AEDAT 4.0 with LZ4 and with ZSTD) and decoded from memory; the real samples of the
//! shared data are added when present.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use ebiv::io::{self, write, Evt21Order, Format, ReadOptions};
use ebiv::{EventBuffer, Geometry};
use std::path::{Path, PathBuf};
use std::sync::Arc;

const EVENTS: usize = 4_000_000;

fn synthetic_stream() -> EventBuffer {
    let mut b = EventBuffer::with_capacity(EVENTS);
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for k in 0..EVENTS {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        // Particles light short runs of neighbouring pixels on a row.
        let y = (state % 720) as u16;
        let x = ((state >> 20) % 1270) as u16;
        b.push(1_000_000 + (k / 20) as i64, x, y, ((state >> 40) & 1) as u8);
    }
    b
}

/// How a synthetic stream is written: a writer for a path and the sensor size.
type MakeWriter = fn(&Path, Option<Geometry>) -> ebiv::Result<Box<dyn write::EventWriter + Send>>;

fn encode(make: MakeWriter, file_name: &str, events: &EventBuffer) -> Arc<[u8]> {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join(file_name);
    let mut w = make(&path, Some(Geometry::new(1280, 720))).expect("writer");
    w.write(events).expect("write");
    w.finish().expect("finish");
    std::fs::read(&path).expect("read").into()
}

fn decode_all(bytes: &Arc<[u8]>, name: &str) -> usize {
    let mut reader = io::open_memory(bytes.clone(), name, &ReadOptions::default()).expect("open");
    let mut batch = EventBuffer::new();
    let mut n = 0;
    while reader.read_batch(&mut batch).expect("decode") {
        n += batch.len();
    }
    n
}

fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("EBIV_TEST_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    dir.is_dir().then_some(dir)
}

fn bench_decode(c: &mut Criterion) {
    let events = synthetic_stream();
    let mut group = c.benchmark_group("decode");
    group.sample_size(10);
    let synthetic: [(&str, &str, MakeWriter); 5] = [
        ("evt3", "bench.raw", |p, g| {
            write::create(p, Format::Evt3, g)
        }),
        ("evt2", "bench.raw", |p, g| {
            write::create(p, Format::Evt2, g)
        }),
        ("evt21", "bench.raw", |p, g| {
            let variant = write::Evt2Variant::Evt21(Evt21Order::Legacy);
            Ok(Box::new(write::Evt2Writer::create(p, g, variant)?))
        }),
        ("aedat4-lz4", "bench.aedat4", |p, g| {
            write::create(p, Format::Aedat4, g)
        }),
        ("aedat4-zstd", "bench.aedat4", |p, g| {
            let zstd = write::Aedat4Compression::Zstd;
            Ok(Box::new(write::Aedat4Writer::create(p, g, zstd)?))
        }),
    ];
    for (name, file_name, make) in synthetic {
        let bytes = encode(make, file_name, &events);
        group.throughput(Throughput::Elements(EVENTS as u64));
        group.bench_with_input(BenchmarkId::new("synthetic", name), &bytes, |b, bytes| {
            b.iter(|| decode_all(bytes, file_name))
        });
    }
    if let Some(dir) = shared_data() {
        for file in [
            "prophesee/evt2_sample.raw",
            "prophesee/evt3_test_pedestrians.raw",
            "prophesee/sample_ncars.dat",
            "inivation/sample.aedat4",
            "es/dvs.es",
        ] {
            let Ok(bytes) = std::fs::read(dir.join(file)) else {
                continue;
            };
            let bytes: Arc<[u8]> = bytes.into();
            let n = decode_all(&bytes, file);
            group.throughput(Throughput::Elements(n as u64));
            group.bench_with_input(BenchmarkId::new("sample", file), &bytes, |b, bytes| {
                b.iter(|| decode_all(bytes, file))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_decode);
criterion_main!(benches);
