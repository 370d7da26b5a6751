//! Round trips through a small AEDAT 4.0 writer, damaged files, and the real sample.

use super::test_writer::*;
use super::*;
use crate::io::{open_memory, Format, ReadOptions, Recording};
use proptest::prelude::*;
use std::io::Write;
use std::sync::Arc;

fn open_bytes(bytes: Vec<u8>) -> crate::Result<crate::io::EventReader> {
    open_memory(Arc::from(bytes), "test.aedat4", &ReadOptions::default())
}

fn read(bytes: Vec<u8>) -> crate::Result<Recording> {
    open_bytes(bytes)?.read_all()
}

/// Events `i0..i1` of a deterministic pseudo-random recording on a `w`×`h` sensor.
fn synthetic(i0: usize, i1: usize, w: u32, h: u32) -> Vec<(i64, i16, i16, bool)> {
    (i0..i1)
        .map(|i| {
            let r = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 20;
            (
                1_600_000_000_000_000 + (i as i64) * 3 + (r % 3) as i64,
                (r % w as u64) as i16,
                ((r >> 16) % h as u64) as i16,
                (r >> 40) & 1 == 1,
            )
        })
        .collect()
}

fn packets_of(events: &[(i64, i16, i16, bool)], per_packet: usize) -> Vec<Packet> {
    let mut packets = Vec::new();
    for (k, chunk) in events.chunks(per_packet).enumerate() {
        packets.push((0, events_body(chunk)));
        if k % 2 == 0 {
            packets.push((2, vec![7; 100]));
        }
    }
    packets
}

/// `events` through the public writer (LZ4), as file bytes.
fn written(events: &[(i64, i16, i16, bool)], g: Geometry) -> Vec<u8> {
    use crate::io::write::{Aedat4Compression, Aedat4Writer, EventWriter};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.aedat4");
    let mut buffer = EventBuffer::new();
    for &(t, x, y, p) in events {
        buffer.push(t, x as u16, y as u16, p as u8);
    }
    let mut w = Box::new(Aedat4Writer::create(&path, Some(g), Aedat4Compression::Lz4).unwrap());
    w.write(&buffer).unwrap();
    w.finish().unwrap();
    std::fs::read(&path).unwrap()
}

fn assert_events(rec: &Recording, events: &[(i64, i16, i16, bool)]) {
    assert_eq!(rec.events.len(), events.len());
    for (i, &(t, x, y, p)) in events.iter().enumerate() {
        assert_eq!(
            rec.events.get(i),
            crate::Event {
                t,
                x: x as u16,
                y: y as u16,
                p: p as u8
            },
            "event {i}"
        );
    }
}

#[test]
fn round_trip_every_compression() {
    let events = synthetic(0, 25_000, 320, 240);
    let packets = packets_of(&events, 3000);
    for codec in [Codec::None, Codec::Lz4, Codec::Lz4Linked, Codec::Zstd] {
        for table in [false, true] {
            let rec = read(file(codec, &packets, table, 320, 240))
                .unwrap_or_else(|e| panic!("{codec:?}: {e}"));
            assert_eq!(rec.metadata.format, Format::Aedat4);
            assert_eq!(rec.metadata.geometry, Some(Geometry::new(320, 240)));
            assert_eq!(rec.metadata.sensor.as_deref(), Some("DVXplorer_TEST0001"));
            assert_eq!(rec.metadata.serial.as_deref(), Some("TEST0001"));
            assert_eq!(
                rec.metadata.header_value("stream 0"),
                Some("EVTS 320x240 DVXplorer_TEST0001")
            );
            assert_events(&rec, &events);
            assert_eq!(rec.report.skipped_other, 5, "{codec:?}: IMU packets");
            assert!(!rec.report.has_problems(), "{codec:?}: {:?}", rec.report);
        }
    }
}

#[test]
fn triggers_and_out_of_range_events() {
    let events = vec![
        (10, 5, 5, true),
        (11, 320, 5, false),
        (12, 5, 240, false),
        (13, -1, 0, true),
        (14, 0, -7, true),
        (15, 319, 239, false),
    ];
    let packets = vec![
        (0, events_body(&events)),
        (
            3,
            triggers_body(&[(20, 1), (21, 2), (22, 3), (23, 0), (24, 6)]),
        ),
        (0, events_body(&[])),
    ];
    let rec = read(file(Codec::Lz4, &packets, true, 320, 240)).unwrap();
    assert_events(&rec, &[(10, 5, 5, true), (15, 319, 239, false)]);
    assert_eq!(rec.report.out_of_range, 4);
    let triggers: Vec<_> = rec
        .events
        .triggers
        .iter()
        .map(|t| (t.t, t.channel, t.value))
        .collect();
    assert_eq!(triggers, vec![(20, 0, 1), (21, 0, 0), (22, 0, 1)]);
    assert_eq!(rec.report.triggers, 3);
    assert_eq!(
        rec.report.skipped_other, 2,
        "reset and frame-begin triggers"
    );
}

#[test]
fn seek_near_uses_the_data_table() {
    let events = synthetic(0, 30_000, 640, 480);
    let packets = packets_of(&events, 1000);
    for codec in [Codec::Lz4, Codec::Zstd] {
        for table in [true, false] {
            let bytes = file(codec, &packets, table, 640, 480);
            let t = events[17_500].0;
            let mut reader = open_bytes(bytes.clone()).unwrap();
            reader.skip_to(t).unwrap();
            let rest = reader.read_all().unwrap();
            let expected: Vec<_> = events.iter().filter(|e| e.0 >= t).copied().collect();
            assert_events(&rest, &expected);

            let mut inner = open(
                Box::new(std::io::Cursor::new(bytes)),
                "test".into(),
                &ReadOptions::default(),
            )
            .unwrap();
            assert_eq!(inner.seek_near(t).unwrap(), table, "{codec:?}");
            let mut batch = EventBuffer::new();
            assert!(inner.next_batch(&mut batch).unwrap());
            if table {
                assert_eq!(
                    batch.t[0], events[17_000].0,
                    "starts at the packet holding t"
                );
                assert!(!inner.seek_near(events[100].0).unwrap(), "never backwards");
            }
        }
    }
}

#[test]
fn seek_past_the_end_and_before_the_start() {
    let events = synthetic(0, 5000, 320, 240);
    let bytes = written(&events, Geometry::new(320, 240));
    let mut reader = open_bytes(bytes.clone()).unwrap();
    reader.skip_to(i64::MAX).unwrap();
    assert_eq!(reader.read_all().unwrap().events.len(), 0);
    let mut reader = open_bytes(bytes).unwrap();
    reader.skip_to(0).unwrap();
    assert_events(&reader.read_all().unwrap(), &events);
}

#[test]
fn a_wrong_data_table_is_not_trusted() {
    let events = synthetic(0, 3000, 320, 240);
    let packets = packets_of(&events, 1000);
    let t = events[2500].0;
    type Tweak = fn(&mut [Entry]);
    let tweaks: [(&str, Tweak); 4] = [
        ("offset inside a packet", |e| {
            e.iter_mut().for_each(|e| e.offset += 1)
        }),
        ("wrong stream id", |e| {
            e.iter_mut().for_each(|e| e.stream_id = 3)
        }),
        ("offset past the packets", |e| {
            e.iter_mut().for_each(|e| e.offset += 1 << 20)
        }),
        ("negative size", |e| e.iter_mut().for_each(|e| e.size = -1)),
    ];
    for (what, tweak) in tweaks {
        let bytes = file_with(Codec::Zstd, &packets, true, 320, 240, tweak);
        let mut reader = open_bytes(bytes).unwrap();
        reader.skip_to(t).unwrap();
        let rest = reader.read_all().unwrap();
        assert_eq!(rest.events.t[0], t, "{what}");
        assert_eq!(rest.events.len(), 500, "{what}");
        assert!(
            rest.report
                .warnings
                .iter()
                .any(|w| w.contains("data table")),
            "{what}: {:?}",
            rest.report.warnings
        );
    }
}

#[test]
fn truncated_file_keeps_whole_packets() {
    let events = synthetic(0, 6000, 320, 240);
    let packets: Vec<Packet> = events.chunks(1000).map(|c| (0, events_body(c))).collect();
    let bytes = file(Codec::Lz4, &packets, false, 320, 240);
    let whole = read(bytes.clone()).unwrap();
    assert_events(&whole, &events);
    let mut ends = Vec::new();
    let mut pos = 18 + i32::from_le_bytes(bytes[14..18].try_into().unwrap()) as usize;
    while pos < bytes.len() {
        let size = i32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        pos += 8 + size;
        ends.push(pos);
    }
    for cut in [ends[2] + 3, ends[2] + 20, ends[4] - 1] {
        let rec = read(bytes[..cut].to_vec()).unwrap();
        let complete = ends.iter().filter(|&&e| e <= cut).count();
        assert_events(&rec, &events[..complete * 1000]);
        let last_end = ends[complete - 1];
        assert_eq!(rec.report.truncated_bytes, (cut - last_end) as u64);
        assert!(rec.report.warnings[0].contains(&format!("at byte {last_end}")));
    }
}

#[test]
fn damaged_sizes_are_clear_errors() {
    let events = synthetic(0, 2000, 320, 240);
    let packets: Vec<Packet> = events.chunks(1000).map(|c| (0, events_body(c))).collect();
    let bytes = file(Codec::Lz4, &packets, true, 320, 240);
    let first = 18 + i32::from_le_bytes(bytes[14..18].try_into().unwrap()) as usize;
    for (size, needle) in [
        (-5i32, "negative size"),
        (i32::MAX, "256 MiB"),
        (1 << 20, "packet area ends"),
    ] {
        let mut b = bytes.clone();
        b[first + 4..first + 8].copy_from_slice(&size.to_le_bytes());
        let err = read(b).unwrap_err().to_string();
        assert!(err.contains(needle), "{err}");
        assert!(err.contains(&format!("at byte {}", first + 4)), "{err}");
    }
    for header_len in [-1i32, i32::MAX, 1 << 30] {
        let mut b = bytes.clone();
        b[14..18].copy_from_slice(&header_len.to_le_bytes());
        let err = read(b).unwrap_err().to_string();
        assert!(err.contains("IOHeader length"), "{err}");
    }
}

#[test]
fn corrupt_bodies_are_skipped_and_counted() {
    let events = synthetic(0, 3000, 320, 240);
    let mut packets: Vec<Packet> = events.chunks(1000).map(|c| (0, events_body(c))).collect();
    packets.insert(1, (0, b"not a flatbuffer at all".to_vec()));
    packets.insert(2, (7, vec![1, 2, 3]));
    for codec in [Codec::Lz4, Codec::Zstd, Codec::None] {
        let rec = read(file(codec, &packets, false, 320, 240)).unwrap();
        assert_events(&rec, &events);
        assert_eq!(rec.report.malformed, 1, "{codec:?}");
        assert_eq!(rec.report.unknown_words, 1, "{codec:?}");
    }
    // A body that is not a valid compressed frame at all.
    let mut bytes = file(Codec::Lz4, &packets[..1], false, 320, 240);
    let first = 18 + i32::from_le_bytes(bytes[14..18].try_into().unwrap()) as usize;
    bytes[first + 8] ^= 0xFF;
    let rec = read(bytes).unwrap();
    assert_eq!((rec.events.len(), rec.report.malformed), (0, 1));
}

#[test]
fn decompression_bombs_are_refused() {
    // 3 MiB of zeros compress to a few hundred bytes; with a 1 MiB cap the packet is refused,
    // with or without the content size in the frame header.
    let zeros = vec![0u8; 3 << 20];
    let mut streamed = Vec::new();
    {
        let mut enc = zstd::stream::write::Encoder::new(&mut streamed, 1).unwrap();
        enc.include_contentsize(false).unwrap();
        enc.write_all(&zeros).unwrap();
        enc.finish().unwrap();
    }
    for (code, frame) in [
        (3, zstd::bulk::compress(&zeros, 1).unwrap()),
        (3, streamed),
        (1, Codec::Lz4.compress(&zeros)),
    ] {
        let info = info_xml(320, 240);
        let header = io_header(code, None, &info);
        let mut bytes = MAGIC.to_vec();
        bytes.extend(header);
        bytes.extend(0i32.to_le_bytes());
        bytes.extend((frame.len() as i32).to_le_bytes());
        bytes.extend(frame);
        let source = Box::new(std::io::Cursor::new(bytes));
        let mut reader =
            open_reader(source, "bomb".into(), &ReadOptions::default(), 1 << 20).unwrap();
        let err = reader
            .next_batch(&mut EventBuffer::new())
            .unwrap_err()
            .to_string();
        assert!(err.contains("decompresses to more than 1 MiB"), "{err}");
    }
}

#[test]
fn headers_without_table_field_or_streams() {
    let events = synthetic(0, 100, 320, 240);
    let info = info_xml(320, 240);
    let header = io_header(0, None, &info);
    let mut bytes = MAGIC.to_vec();
    bytes.extend(header);
    let body = events_body(&events);
    bytes.extend(0i32.to_le_bytes());
    bytes.extend((body.len() as i32).to_le_bytes());
    bytes.extend(body);
    let rec = read(bytes).unwrap();
    assert_events(&rec, &events);
    assert_eq!(rec.metadata.header_value("dataTablePosition"), Some("-1"));

    let header = io_header(1, Some(-1), "<dv></dv>");
    let mut bytes = MAGIC.to_vec();
    bytes.extend(header);
    assert!(read(bytes).unwrap_err().to_string().contains("no streams"));

    let header = io_header(9, Some(-1), &info);
    let mut bytes = MAGIC.to_vec();
    bytes.extend(header);
    assert!(read(bytes)
        .unwrap_err()
        .to_string()
        .contains("compression code 9"));
}

#[test]
fn geometry_from_options_when_the_header_has_none() {
    let info = info_xml(320, 240)
        .replace("sizeX", "sX")
        .replace("sizeY", "sY");
    let header = io_header(0, None, &info);
    let mut bytes = MAGIC.to_vec();
    bytes.extend(header);
    let body = events_body(&[(1, 5, 5, true), (2, 50, 5, true)]);
    bytes.extend(0i32.to_le_bytes());
    bytes.extend((body.len() as i32).to_le_bytes());
    bytes.extend(body);
    let rec = read(bytes.clone()).unwrap();
    assert_eq!((rec.metadata.geometry, rec.events.len()), (None, 2));
    let options = ReadOptions {
        geometry: Some(Geometry::new(10, 10)),
        ..Default::default()
    };
    let rec = open_memory(Arc::from(bytes), "x.aedat4", &options)
        .unwrap()
        .read_all()
        .unwrap();
    assert_eq!(rec.metadata.geometry, Some(Geometry::new(10, 10)));
    assert_eq!((rec.events.len(), rec.report.out_of_range), (1, 1));
}

#[test]
fn the_real_sample_file() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let path = std::env::var_os("EBIV_TEST_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or(dir)
        .join("inivation/sample.aedat4");
    if !path.is_file() {
        eprintln!("notice: {} not found; skipping", path.display());
        return;
    }
    let rec = crate::io::read_all(&path, &ReadOptions::default()).unwrap();
    assert_eq!(rec.events.len(), 111_954);
    assert_eq!(rec.metadata.geometry, Some(Geometry::new(320, 240)));
    assert_eq!(rec.metadata.header_value("compression"), Some("LZ4"));
    assert_eq!(
        rec.metadata.header_value("stream 0"),
        Some("EVTS 320x240 DVXplorer_DXB00010")
    );
    assert_eq!(rec.report.skipped_other, 59, "IMU packets");
    assert!(!rec.report.has_problems(), "{:?}", rec.report);

    // The file has a data table: seeking lands on a packet boundary close before t.
    let t = 1_605_537_494_000_000;
    let mut reader = crate::io::open(&path, &ReadOptions::default()).unwrap();
    reader.skip_to(t).unwrap();
    let rest = reader.read_all().unwrap();
    let expected = rec.events.t.iter().filter(|&&x| x >= t).count();
    assert_eq!(rest.events.len(), expected);
    assert!(!rest.report.has_problems(), "{:?}", rest.report);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Arbitrary bytes after a valid header never panic the reader.
    #[test]
    fn random_packets_never_panic(tail in proptest::collection::vec(any::<u8>(), 0..2000), codec in 0usize..3) {
        let codec = [Codec::None, Codec::Lz4, Codec::Zstd][codec];
        let mut bytes = file(codec, &[], false, 320, 240);
        bytes.extend(tail);
        if let Ok(mut reader) = open_bytes(bytes) {
            let _ = reader.skip_to(5);
            let mut batch = EventBuffer::new();
            while let Ok(true) = reader.read_batch(&mut batch) {}
        }
    }

    /// Flipping bytes of a valid file (header, packets, table) never panics.
    #[test]
    fn flipped_bytes_never_panic(flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8), table in any::<bool>()) {
        let events = synthetic(0, 300, 320, 240);
        let mut packets = packets_of(&events, 100);
        packets.push((3, triggers_body(&[(5, 1), (6, 2)])));
        let mut bytes = file(Codec::Lz4, &packets, table, 320, 240);
        let n = bytes.len();
        for (at, value) in flips {
            bytes[at % n] ^= value | 1;
        }
        if let Ok(mut reader) = open_bytes(bytes) {
            let _ = reader.skip_to(events[150].0);
            let mut batch = EventBuffer::new();
            while let Ok(true) = reader.read_batch(&mut batch) {}
        }
    }

    /// Random bytes inside an uncompressed packet body never panic the flatbuffer parser.
    #[test]
    fn random_bodies_never_panic(body in proptest::collection::vec(any::<u8>(), 0..400)) {
        let mut out = EventBuffer::new();
        let mut report = DecodeReport::default();
        let _ = decode_events(&body, (320, 240), &mut out, &mut report);
        let _ = decode_triggers(&body, &mut out, &mut report);
        let _ = parse_table(&body, 0, 1 << 20, &[(0, StreamKind::Events)]);
        let _ = parse_io_header(&body);
    }
}
