//! Truncated, corrupted, empty, mislabelled and hostile inputs give a clear error or a
//! warning with counts, never a panic or an unbounded allocation.

use ebiv::io::{self, ReadOptions};
use proptest::prelude::*;
use std::sync::Arc;

/// Decode `bytes` as the file `name`; returns the event count or the error message.
fn decode(bytes: &[u8], name: &str) -> Result<(usize, io::DecodeReport), String> {
    let reader = io::open_memory(Arc::from(bytes), name, &ReadOptions::default())
        .map_err(|e| e.to_string())?;
    let rec = reader.read_all().map_err(|e| e.to_string())?;
    Ok((rec.events.len(), rec.report))
}

const EVT3_HEADER: &[u8] = b"% evt 3.0\n% format EVT3;height=720;width=1280\n% end\n";
const EVT2_HEADER: &[u8] = b"% evt 2.0\n% geometry 640x480\n";
const EVT21_HEADER: &[u8] = b"% format EVT21;height=320;width=320;endianness=legacy\n% end\n";
const DAT_HEADER: &[u8] =
    b"% Data file containing Event2d events\n% Version 2\n% Width 640\n% Height 480\n\x00\x08";

#[test]
fn empty_file_is_an_unknown_format() {
    let err = decode(b"", "empty.raw").unwrap_err();
    assert!(err.contains("empty"), "{err}");
}

#[test]
fn header_only_files_hold_no_events() {
    for header in [EVT3_HEADER, EVT2_HEADER, EVT21_HEADER] {
        let (n, report) = decode(header, "h.raw").unwrap();
        assert_eq!(n, 0);
        assert!(!report.has_problems());
    }
    let err = decode(&DAT_HEADER[..DAT_HEADER.len() - 2], "h.dat").unwrap_err();
    assert!(err.contains("ends before its event type"), "{err}");
}

#[test]
fn truncated_word_is_reported_with_its_offset() {
    let mut bytes = EVT2_HEADER.to_vec();
    bytes.extend_from_slice(&(0x8000_0001u32).to_le_bytes()); // TIME_HIGH
    bytes.extend_from_slice(&(0x1000_0801u32).to_le_bytes()); // ON event x=1 y=1
    bytes.extend_from_slice(&[0x01, 0x02]); // half a word
    let (n, report) = decode(&bytes, "cut.raw").unwrap();
    assert_eq!(n, 1);
    assert_eq!(report.truncated_bytes, 2);
    let offset = EVT2_HEADER.len() + 8;
    assert!(
        report.warnings[0].contains(&format!("at byte {offset}")),
        "{:?}",
        report.warnings
    );
}

#[test]
fn headerless_raw_needs_an_encoding() {
    let err = decode(&[0x00, 0x80, 0x12, 0x34], "dump.raw").unwrap_err();
    assert!(err.contains("--raw-encoding"), "{err}");
    let opts = ReadOptions {
        raw_encoding: Some(io::RawEncoding::Evt3),
        geometry: Some(ebiv::Geometry::new(1280, 720)),
        ..Default::default()
    };
    let reader = io::open_memory(
        Arc::from(&[0x01u8, 0x80, 0x00, 0x00, 0x05, 0x20][..]),
        "dump.raw",
        &opts,
    )
    .unwrap();
    assert_eq!(reader.read_all().unwrap().events.len(), 1);
}

#[test]
fn unsupported_encodings_and_dat_types_are_named() {
    let err = decode(b"% format EVT4;width=10;height=10\n% end\n", "x.raw").unwrap_err();
    assert!(err.contains("EVT4"), "{err}");
    let err = decode(
        b"% Data file containing OpticalFlow events\n% Version 2\n\x28\x08",
        "x.dat",
    )
    .unwrap_err();
    assert!(err.contains("0x28"), "{err}");
    let err = decode(b"% Data file containing Event2d events\n\x00\x10", "x.dat").unwrap_err();
    assert!(err.contains("16 bytes"), "{err}");
}

#[test]
fn hostile_header_is_bounded() {
    let mut bytes = b"% ".to_vec();
    bytes.extend(std::iter::repeat_n(b'x', 3 << 20));
    let err = decode(&bytes, "big.raw").unwrap_err();
    assert!(err.contains("header longer than"), "{err}");
}

#[test]
fn mislabelled_file_is_detected_by_content() {
    let mut bytes = DAT_HEADER.to_vec();
    bytes.extend_from_slice(&5u32.to_le_bytes());
    bytes.extend_from_slice(&(1u32 << 28 | 3 << 14 | 2).to_le_bytes());
    let (n, _) = decode(&bytes, "actually_dat.raw").unwrap();
    assert_eq!(n, 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_bodies_never_panic(body in prop::collection::vec(any::<u8>(), 0..4096), which in 0usize..4) {
        let header = [EVT3_HEADER, EVT2_HEADER, EVT21_HEADER, DAT_HEADER][which];
        let mut bytes = header.to_vec();
        bytes.extend_from_slice(&body);
        let name = if which == 3 { "r.dat" } else { "r.raw" };
        if let Ok((n, report)) = decode(&bytes, name) {
            prop_assert_eq!(report.events as usize, n);
        }
    }

    #[test]
    fn random_files_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..2048), ext in prop::sample::select(vec!["raw", "dat", "csv", "npy", "npz", "es", "aedat4", "aedat", "evt", "bin"])) {
        let _ = decode(&bytes, &format!("f.{ext}"));
    }
}
