//! Round trips through a small AEDAT 3.1 writer and damaged files.

use super::*;
use crate::io::{open_memory, Format, ReadOptions, Recording};
use proptest::prelude::*;
use std::sync::Arc;

fn header(source: &str) -> Vec<u8> {
    format!(
        "#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: {source}\r\n#-Source 0: OLDDEVICE\r\n#Start-Time: 2017-05-04 10:36:34 (TZ+0200)\r\n#!END-HEADER\r\n"
    )
    .into_bytes()
}

/// A packet of `capacity` slots holding `events` as (data word, time stamp) pairs.
fn packet(kind: i16, source: i16, overflow: i32, capacity: i32, events: &[(u32, i32)]) -> Vec<u8> {
    let number = events.len() as i32;
    let valid = events.iter().filter(|e| e.0 & 1 == 1).count() as i32;
    let mut out = Vec::new();
    out.extend(kind.to_le_bytes());
    out.extend(source.to_le_bytes());
    for v in [8, 4, overflow, capacity, number, valid] {
        out.extend(v.to_le_bytes());
    }
    for &(data, ts) in events {
        out.extend(data.to_le_bytes());
        out.extend(ts.to_le_bytes());
    }
    out.resize(28 + 8 * capacity as usize, 0);
    out
}

fn polarity(x: u32, y: u32, on: bool, valid: bool) -> u32 {
    (x << 17) | (y << 2) | ((on as u32) << 1) | valid as u32
}

fn special(kind: u32) -> u32 {
    (kind << 1) | 1
}

fn read_with(bytes: Vec<u8>, options: &ReadOptions) -> crate::Result<Recording> {
    open_memory(Arc::from(bytes), "test.aedat", options)?.read_all()
}

fn read(bytes: Vec<u8>) -> crate::Result<Recording> {
    read_with(bytes, &ReadOptions::default())
}

fn tuples(rec: &Recording) -> Vec<(i64, u16, u16, u8)> {
    rec.events.iter().map(|e| (e.t, e.x, e.y, e.p)).collect()
}

#[test]
fn round_trip_polarity_and_triggers() {
    let mut bytes = header("DVS128");
    bytes.extend(packet(
        1,
        1,
        0,
        4,
        &[
            (polarity(3, 4, true, true), 100),
            (polarity(5, 6, false, false), 101),
            (polarity(127, 127, false, true), 102),
        ],
    ));
    bytes.extend(packet(
        0,
        1,
        0,
        5,
        &[
            (special(2), 150),
            (special(3), 160),
            (special(4), 170),
            (special(0), 180),
            (special(5), 190),
        ],
    ));
    bytes.extend(packet(3, 1, 0, 2, &[(1, 200), (1, 201)]));
    bytes.extend(packet(
        1,
        1,
        2,
        2,
        &[
            (polarity(200, 1, true, true), 5),
            (polarity(1, 2, true, true), 7),
        ],
    ));
    let rec = read(bytes).unwrap();
    assert_eq!(rec.metadata.format, Format::Aedat31);
    assert_eq!(rec.metadata.geometry, Some(Geometry::new(128, 128)));
    assert_eq!(rec.metadata.sensor.as_deref(), Some("DVS128"));
    assert_eq!(rec.metadata.header_value("Format"), Some("RAW"));
    assert_eq!(rec.metadata.header_value("Source 1"), Some("DVS128"));
    assert_eq!(rec.metadata.header_value("-Source 0"), Some("OLDDEVICE"));
    assert_eq!(
        rec.metadata.header_value("Start-Time"),
        Some("2017-05-04 10:36:34 (TZ+0200)")
    );
    assert_eq!(
        tuples(&rec),
        vec![(100, 3, 4, 1), (102, 127, 127, 0), ((2 << 31) | 7, 1, 2, 1)]
    );
    let triggers: Vec<_> = rec
        .events
        .triggers
        .iter()
        .map(|t| (t.t, t.channel, t.value))
        .collect();
    assert_eq!(triggers, vec![(150, 0, 1), (160, 0, 0), (170, 0, 1)]);
    assert_eq!(rec.report.malformed, 1, "invalid polarity event");
    assert_eq!(rec.report.out_of_range, 1, "x = 200 on a DVS128");
    assert_eq!(rec.report.skipped_other, 4, "2 special + 2 IMU records");
}

#[test]
fn geometry_from_source_name_or_options() {
    let events = [
        (polarity(345, 259, true, true), 1),
        (polarity(346, 0, true, true), 2),
    ];
    let mut bytes = header("DAVIS346B");
    bytes.extend(packet(1, 1, 0, 2, &events));
    let rec = read(bytes).unwrap();
    assert_eq!(rec.metadata.geometry, Some(Geometry::new(346, 260)));
    assert_eq!((rec.events.len(), rec.report.out_of_range), (1, 1));

    let mut bytes = header("DAVIS240C");
    bytes.extend(packet(1, 1, 0, 2, &events));
    assert_eq!(
        read(bytes).unwrap().metadata.geometry,
        Some(Geometry::new(240, 180))
    );

    let mut bytes = header("SOMECAMERA");
    bytes.extend(packet(1, 1, 0, 2, &events));
    let rec = read(bytes.clone()).unwrap();
    assert_eq!((rec.metadata.geometry, rec.events.len()), (None, 2));
    let options = ReadOptions {
        geometry: Some(Geometry::new(100, 100)),
        ..Default::default()
    };
    let rec = read_with(bytes, &options).unwrap();
    assert_eq!(rec.metadata.geometry, Some(Geometry::new(100, 100)));
    assert_eq!(rec.events.len(), 0);
}

#[test]
fn unused_slots_and_second_sources_are_skipped() {
    let mut bytes = header("DVS128");
    bytes.extend(packet(1, 1, 0, 10, &[(polarity(1, 1, true, true), 1)]));
    bytes.extend(packet(1, 2, 0, 1, &[(polarity(2, 2, true, true), 2)]));
    bytes.extend(packet(1, 1, 0, 1, &[(polarity(3, 3, true, true), 3)]));
    let rec = read(bytes).unwrap();
    assert_eq!(tuples(&rec), vec![(1, 1, 1, 1), (3, 3, 3, 1)]);
    assert_eq!(rec.report.skipped_other, 1);
    assert_eq!(rec.report.warnings.len(), 1);
}

#[test]
fn truncated_packet_keeps_whole_events() {
    let events: Vec<(u32, i32)> = (0..10)
        .map(|i| (polarity(i, i, true, true), i as i32))
        .collect();
    let mut bytes = header("DVS128");
    let head = bytes.len();
    bytes.extend(packet(1, 1, 0, 10, &events));
    for (cut, kept, ignored) in [(28 + 8 * 4 + 3, 4, 3), (28 + 79, 9, 7), (10, 0, 10)] {
        let rec = read(bytes[..head + cut].to_vec()).unwrap();
        assert_eq!(rec.events.len(), kept, "cut {cut}");
        assert_eq!(rec.report.truncated_bytes, ignored, "cut {cut}");
        assert!(rec.report.warnings[0].contains(&format!("at byte {head}")));
    }
}

#[test]
fn bad_headers_and_packets_are_clear_errors() {
    let err = read(b"#!AER-DAT3.1\r\n#Format: RAW\r\n".to_vec()).unwrap_err();
    assert!(err.to_string().contains("END-HEADER"), "{err}");
    let mut huge = b"#!AER-DAT3.1\r\n".to_vec();
    huge.resize(3 << 20, b'#');
    let err = read(huge).unwrap_err();
    assert!(err.to_string().contains("1 MiB"), "{err}");
    let err =
        read(b"#!AER-DAT3.1\r\n#Format: SerializedTS\r\n#!END-HEADER\r\n".to_vec()).unwrap_err();
    assert!(err.to_string().contains("only RAW"), "{err}");

    let head = header("DVS128");
    let good = packet(1, 1, 0, 2, &[(polarity(1, 1, true, true), 1)]);
    let field = |at: usize, v: i32| {
        let mut b = head.clone();
        let mut p = good.clone();
        p[at..at + 4].copy_from_slice(&v.to_le_bytes());
        b.extend(p);
        b
    };
    for (bytes, needle) in [
        (field(4, 0), "eventSize"),
        (field(4, -8), "eventSize"),
        (field(8, 6), "eventTSOffset"),
        (field(16, -1), "negative"),
        (field(20, 5), "eventCapacity"),
        (field(16, i32::MAX), "256 MiB"),
    ] {
        let err = read(bytes).unwrap_err().to_string();
        assert!(err.contains(needle), "{needle}: {err}");
        assert!(err.contains(&format!("at byte {}", head.len())), "{err}");
    }
    let mut compressed = head.clone();
    let mut p = good.clone();
    p[1] |= 0x80;
    compressed.extend(p);
    assert!(read(compressed)
        .unwrap_err()
        .to_string()
        .contains("compressed"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// Arbitrary bytes after a valid header never panic the reader.
    #[test]
    fn random_bytes_never_panic(tail in proptest::collection::vec(any::<u8>(), 0..3000)) {
        let mut bytes = header("DVS128");
        bytes.extend(tail);
        if let Ok(mut reader) = open_memory(Arc::from(bytes), "x.aedat", &ReadOptions::default()) {
            let mut batch = EventBuffer::new();
            while let Ok(true) = reader.read_batch(&mut batch) {}
        }
    }

    /// Plausible packet headers with random fields never panic and never over-allocate.
    #[test]
    fn random_packet_headers_never_panic(
        fields in proptest::array::uniform8(any::<i32>()),
        body in proptest::collection::vec(any::<u8>(), 0..500),
    ) {
        let mut bytes = header("DAVIS346");
        bytes.extend(((fields[0] & 3) as i16).to_le_bytes());
        bytes.extend((fields[1] as i16).to_le_bytes());
        bytes.extend((fields[2] & 31).to_le_bytes());
        bytes.extend((fields[3] & 31).to_le_bytes());
        for v in &fields[4..8] {
            bytes.extend((v & 0xFFF).to_le_bytes());
        }
        bytes.extend(body);
        if let Ok(mut reader) = open_memory(Arc::from(bytes), "x.aedat", &ReadOptions::default()) {
            let mut batch = EventBuffer::new();
            while let Ok(true) = reader.read_batch(&mut batch) {}
        }
    }
}
