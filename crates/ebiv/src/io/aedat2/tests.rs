//! Round trips through a small AEDAT 2.0 writer (DVS128 and DAVIS layouts) and damaged files.

use super::*;
use crate::io::{open_memory, Format, ReadOptions, Recording};
use proptest::prelude::*;
use std::sync::Arc;

fn header(chip: &str) -> Vec<u8> {
    format!(
        "#!AER-DAT2.0\r\n# This is a raw AE data file - do not edit\r\n# Data format is int32 address, int32 timestamp (8 bytes total), repeated for each event\r\n# Timestamps tick is 1 us\r\n# created Thu Dec 03 14:47:00 CET 2015\r\n# AEChip: {chip}\r\n#<?xml version=\"1.0\" encoding=\"UTF-8\"?>\r\n#<preferences EXTERNAL_XML_VERSION=\"1.0\">\r\n"
    )
    .into_bytes()
}

fn records(bytes: &mut Vec<u8>, recs: &[(u32, u32)]) {
    for &(addr, t) in recs {
        bytes.extend(addr.to_be_bytes());
        bytes.extend(t.to_be_bytes());
    }
}

fn dvs128(x: u32, y: u32, on: bool) -> u32 {
    (y << 8) | (x << 1) | on as u32
}

fn davis(x: u32, y: u32, on: bool) -> u32 {
    (y << 22) | (x << 12) | ((on as u32) << 11)
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
fn dvs128_round_trip() {
    let mut bytes = header("ch.unizh.ini.jaer.chip.retina.DVS128");
    records(
        &mut bytes,
        &[
            (dvs128(0, 0, true), 10),
            (dvs128(127, 127, false), 11),
            (0x8000, 12),
            (dvs128(5, 100, true), 13),
        ],
    );
    let rec = read(bytes).unwrap();
    assert_eq!(rec.metadata.format, Format::Aedat2);
    assert_eq!(rec.metadata.geometry, Some(Geometry::new(128, 128)));
    assert_eq!(
        rec.metadata.sensor.as_deref(),
        Some("ch.unizh.ini.jaer.chip.retina.DVS128")
    );
    assert_eq!(
        rec.metadata.header_value("Timestamps tick is 1 us"),
        Some("")
    );
    assert_eq!(
        rec.metadata
            .header_value("created Thu Dec 03 14:47:00 CET 2015"),
        Some("")
    );
    assert!(rec
        .metadata
        .notes
        .iter()
        .any(|n| n.contains("2 header lines of jAER XML")));
    assert_eq!(
        tuples(&rec),
        vec![(10, 0, 127, 1), (11, 127, 0, 0), (13, 5, 27, 1)]
    );
    assert_eq!(rec.report.skipped_other, 1, "external event");
    assert!(!rec.report.has_problems());
}

#[test]
fn davis_round_trip_skips_aps_and_imu() {
    for (chip, w, h) in [
        ("eu.seebetter.ini.chips.davis.Davis346red", 346, 260),
        ("eu.seebetter.ini.chips.davis.DAVIS240C", 240, 180),
    ] {
        let mut bytes = header(chip);
        records(
            &mut bytes,
            &[
                (davis(0, 0, true), 100),
                (0x8000_0000 | 12345, 101),
                (davis(3, 4, false) | 0x400, 102),
                (davis(w - 1, h - 1, false), 103),
                (davis(w, 0, true), 104),
                (davis(0, h, true), 105),
            ],
        );
        let rec = read(bytes).unwrap();
        assert_eq!(rec.metadata.geometry, Some(Geometry::new(w, h)));
        assert_eq!(
            tuples(&rec),
            vec![(100, 0, (h - 1) as u16, 1), (103, (w - 1) as u16, 0, 0)],
            "{chip}"
        );
        assert_eq!(rec.report.skipped_other, 2);
        assert_eq!(rec.report.out_of_range, 2);
    }
}

#[test]
fn time_wraps_are_unwrapped() {
    let mut bytes = header("Davis346blue");
    records(
        &mut bytes,
        &[
            (davis(1, 1, true), u32::MAX - 5),
            (davis(1, 1, true), 3),
            (davis(1, 1, true), 2),
            (davis(1, 1, true), 1 << 31),
            (davis(1, 1, true), 7),
            (davis(1, 1, true), (1 << 31) + 10),
            (davis(1, 1, true), 9),
        ],
    );
    let rec = read(bytes).unwrap();
    let base = 1i64 << 32;
    assert_eq!(
        rec.events.t,
        vec![
            (u32::MAX - 5) as i64,
            base + 3,
            base + 2,
            base + (1 << 31),
            base + 7,
            base + (1 << 31) + 10,
            2 * base + 9
        ]
    );
    assert_eq!(rec.report.time_regressions, 2, "3 → 2 and 2^31 → 7");
}

#[test]
fn unknown_chip_needs_a_geometry() {
    let mut bytes = header("some.other.Chip");
    records(
        &mut bytes,
        &[(davis(9, 1, true), 1), (davis(10, 1, true), 2)],
    );
    let err = read(bytes.clone()).unwrap_err().to_string();
    assert!(err.contains("--geometry"), "{err}");
    let options = ReadOptions {
        geometry: Some(Geometry::new(10, 5)),
        ..Default::default()
    };
    let rec = read_with(bytes, &options).unwrap();
    assert_eq!(tuples(&rec), vec![(1, 9, 3, 1)]);
    assert_eq!(rec.report.out_of_range, 1);
}

#[test]
fn header_only_truncated_and_version_1() {
    let rec = read(header("DVS128")).unwrap();
    assert_eq!(rec.events.len(), 0);
    let mut no_newline = header("DVS128");
    no_newline.extend(b"# last line without end");
    assert_eq!(read(no_newline).unwrap().events.len(), 0);

    let mut bytes = header("DVS128");
    records(
        &mut bytes,
        &[(dvs128(1, 1, true), 1), (dvs128(2, 2, true), 2)],
    );
    bytes.extend([0, 0, 1]);
    let rec = read(bytes).unwrap();
    assert_eq!(rec.events.len(), 2);
    assert_eq!(rec.report.truncated_bytes, 3);

    let forced = ReadOptions {
        format: Some(Format::Aedat2),
        ..Default::default()
    };
    let err = read_with(
        b"#!AER-DAT1.0\r\n\x00\x01\x00\x00\x00\x05".to_vec(),
        &forced,
    )
    .unwrap_err();
    assert!(err.to_string().contains("AEDAT 1.0"), "{err}");
    let mut huge = b"#!AER-DAT2.0\r\n#".to_vec();
    huge.resize(17 << 20, b'x');
    assert!(read(huge).unwrap_err().to_string().contains("16 MiB"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Any body decodes without panicking, and every event lies on the sensor.
    #[test]
    fn random_bodies_never_panic(body in proptest::collection::vec(any::<u8>(), 0..4000), davis_chip in any::<bool>()) {
        let mut bytes = header(if davis_chip { "Davis346" } else { "DVS128" });
        bytes.extend(body);
        let rec = read(bytes).unwrap();
        let g = rec.metadata.geometry.unwrap();
        prop_assert!(rec.events.iter().all(|e| g.contains(e.x as u32, e.y as u32)));
    }
}
