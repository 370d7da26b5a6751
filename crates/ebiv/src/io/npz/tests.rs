use super::*;
use crate::io::npy::tests::{encode, npy_bytes};
use crate::io::{open_source, Recording};
use std::io::{Cursor, Write};
use zip::write::SimpleFileOptions;

/// A 1-D `.npy` array of `ty` holding `values`.
fn column(ty: &str, values: &[f64]) -> Vec<u8> {
    let dict = format!(
        "{{'descr': '{ty}', 'fortran_order': False, 'shape': ({},), }}",
        values.len()
    );
    let data: Vec<u8> = values.iter().flat_map(|&v| encode(ty, v)).collect();
    npy_bytes(1, &dict, &data)
}

fn archive(members: &[(&str, Vec<u8>)], method: CompressionMethod) -> Vec<u8> {
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
    for (name, bytes) in members {
        zip.start_file(
            *name,
            SimpleFileOptions::default().compression_method(method),
        )
        .unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

fn read_with(bytes: Vec<u8>, options: &ReadOptions) -> Result<Recording> {
    open_source(
        Box::new(Cursor::new(bytes)),
        "test.npz",
        Some("npz"),
        options,
    )?
    .read_all()
}

fn read(bytes: Vec<u8>) -> Result<Recording> {
    read_with(bytes, &ReadOptions::default())
}

fn tuples(rec: &Recording) -> Vec<(i64, u16, u16, u8)> {
    rec.events.iter().map(|e| (e.t, e.x, e.y, e.p)).collect()
}

/// The EBIV slice layout: x, y `<u2`, p `<i2`, t `<i8`.
fn ebiv_slice(n: usize) -> Vec<(&'static str, Vec<u8>)> {
    let t: Vec<f64> = (0..n).map(|i| 300_000.0 + i as f64).collect();
    let x: Vec<f64> = (0..n).map(|i| (i % 512) as f64).collect();
    let y: Vec<f64> = (0..n).map(|i| (i * 7 % 512) as f64).collect();
    let p: Vec<f64> = (0..n)
        .map(|i| if i % 3 == 0 { -1.0 } else { 1.0 })
        .collect();
    vec![
        ("x.npy", column("<u2", &x)),
        ("y.npy", column("<u2", &y)),
        ("p.npy", column("<i2", &p)),
        ("t.npy", column("<i8", &t)),
    ]
}

#[test]
fn column_archives_stored_and_deflated() {
    for method in [CompressionMethod::Stored, CompressionMethod::Deflated] {
        let n = 20_000;
        let bytes = archive(&ebiv_slice(n), method);
        let small = ReadOptions {
            batch_bytes: 1,
            ..Default::default()
        };
        let rec = read_with(bytes.clone(), &small).unwrap();
        assert_eq!(rec.metadata.format, Format::Npz);
        assert_eq!(rec.events.len(), n);
        assert_eq!(
            rec.events.get(3),
            crate::Event {
                t: 300_003,
                x: 3,
                y: 21,
                p: 0
            }
        );
        assert_eq!(rec.events.get(4).p, 1);
        assert!(!rec.report.has_problems(), "{:?}", rec.report);
        assert_eq!(read(bytes).unwrap().events, rec.events, "{method:?}");
    }
}

#[test]
fn aliases_case_directories_and_float_seconds() {
    let members = vec![
        ("data/Timestamp.NPY", column("<f8", &[0.5, 1.25])),
        ("data/X", column(">i4", &[1.0, 70000.0])),
        ("data/y.npy", column("|u1", &[2.0, 3.0])),
        ("data/Polarity.npy", column("|b1", &[1.0, 0.0])),
        ("data/notes.npy", column("<f4", &[9.0])),
    ];
    let rec = read(archive(&members, CompressionMethod::Deflated)).unwrap();
    assert_eq!(tuples(&rec), vec![(500_000, 1, 2, 1)]);
    assert_eq!(rec.report.out_of_range, 1);
    assert!(rec.metadata.notes.iter().any(|n| n.contains("Timestamp")));
}

#[test]
fn structured_member_is_read_like_npy() {
    let dict = "{'descr': [('t', '<i8'), ('x', '<u2'), ('y', '<u2'), ('p', '|u1')], 'fortran_order': False, 'shape': (2,), }";
    let mut data = Vec::new();
    for (t, x, y, p) in [(5i64, 1u16, 2u16, 1u8), (6, 3, 4, 0)] {
        data.extend(t.to_le_bytes());
        data.extend(x.to_le_bytes());
        data.extend(y.to_le_bytes());
        data.push(p);
    }
    for method in [CompressionMethod::Stored, CompressionMethod::Deflated] {
        let members = vec![
            ("readme.npy", column("<u2", &[1.0])),
            ("events.npy", npy_bytes(2, dict, &data)),
        ];
        let rec = read(archive(&members, method)).unwrap();
        assert_eq!(tuples(&rec), vec![(5, 1, 2, 1), (6, 3, 4, 0)]);
        assert_eq!(rec.metadata.format, Format::Npz);
    }
}

#[test]
fn missing_columns_name_what_is_there() {
    let mut members = ebiv_slice(3);
    members.retain(|(n, _)| *n != "p.npy");
    members.push(("weights.npy", column("<f4", &[1.0, 2.0, 3.0])));
    let msg = read(archive(&members, CompressionMethod::Stored))
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("x.npy, y.npy, t.npy, weights.npy") && msg.contains("no column array for p"),
        "{msg}"
    );
    let empty = archive(&[], CompressionMethod::Stored);
    assert!(read(empty).is_err());
}

#[test]
fn inconsistent_or_damaged_columns() {
    let mut members = ebiv_slice(4);
    members[0].1 = column("<u2", &[1.0, 2.0, 3.0]);
    let msg = read(archive(&members, CompressionMethod::Stored))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("differ in length"), "{msg}");

    let mut members = ebiv_slice(4);
    members[3].1 = column("<M8[D]", &[1.0; 4]);
    assert!(read(archive(&members, CompressionMethod::Stored)).is_err());

    let mut members = ebiv_slice(4);
    members[2].1 = b"not an npy".to_vec();
    assert!(read(archive(&members, CompressionMethod::Stored)).is_err());

    // A column whose data were cut: declared 4, 2.5 present.
    let mut members = ebiv_slice(4);
    let t = column("<i8", &[1.0, 2.0, 3.0, 4.0]);
    members[3].1 = t[..t.len() - 12].to_vec();
    let rec = read(archive(&members, CompressionMethod::Deflated)).unwrap();
    assert_eq!(rec.events.len(), 2);
    assert!(!rec.report.warnings.is_empty());
}

#[test]
fn garbage_is_an_error() {
    assert!(read(b"PK\x03\x04 garbage".to_vec()).is_err());
    let mut bytes = archive(&ebiv_slice(100), CompressionMethod::Deflated);
    let mid = bytes.len() / 3;
    for b in &mut bytes[mid..mid + 50] {
        *b ^= 0x5A;
    }
    let _ = read(bytes);
}

#[test]
fn real_wallflow_slice_when_present() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let path = std::env::var_os("EBIV_TEST_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or(dir)
        .join("ebiv/wallflow_slice2.npz");
    if !path.is_file() {
        eprintln!("notice: {} not found; skipping", path.display());
        return;
    }
    let rec = crate::io::read_all(&path, &ReadOptions::default()).unwrap();
    assert_eq!(rec.events.len(), 89_239);
    assert!(!rec.report.has_problems(), "{:?}", rec.report);
}

proptest::proptest! {
    #[test]
    fn random_member_bytes_never_panic(body in proptest::collection::vec(proptest::num::u8::ANY, 0..300), stored in proptest::bool::ANY) {
        let mut members = ebiv_slice(5);
        let mut t = column("<i8", &[1.0; 5]);
        t.truncate(64);
        t.extend(body);
        members[3].1 = t;
        let method = if stored { CompressionMethod::Stored } else { CompressionMethod::Deflated };
        let _ = read(archive(&members, method));
    }
}
