use super::header::{DateUnit, Kind};
use super::*;
use crate::io::text::TimeUnit;
use crate::io::{open_source, Recording};
use std::io::Cursor;

/// A `.npy` stream of the given version with `dict` as header and `data` after it.
pub(crate) fn npy_bytes(version: u8, dict: &str, data: &[u8]) -> Vec<u8> {
    let prefix = if version == 1 { 10 } else { 12 };
    let unpadded = prefix + dict.len() + 1;
    let total = unpadded.div_ceil(64) * 64;
    let header_len = total - prefix;
    let mut v = b"\x93NUMPY".to_vec();
    v.extend([version, 0]);
    if version == 1 {
        v.extend((header_len as u16).to_le_bytes());
    } else {
        v.extend((header_len as u32).to_le_bytes());
    }
    v.extend(dict.as_bytes());
    v.resize(total - 1, b' ');
    v.push(b'\n');
    v.extend(data);
    v
}

/// Encode `value` as NumPy type `ty` (`<i8`, `>u2`, `|b1`, `<f8`, …).
pub(crate) fn encode(ty: &str, value: f64) -> Vec<u8> {
    let big = ty.starts_with('>');
    let code = ty.trim_start_matches(['<', '>', '|', '=']);
    let mut le: Vec<u8> = match code {
        "i1" => (value as i8).to_le_bytes().to_vec(),
        "u1" | "b1" | "?" => (value as u8).to_le_bytes().to_vec(),
        "i2" => (value as i16).to_le_bytes().to_vec(),
        "u2" => (value as u16).to_le_bytes().to_vec(),
        "i4" => (value as i32).to_le_bytes().to_vec(),
        "u4" => (value as u32).to_le_bytes().to_vec(),
        "i8" | "M8[us]" | "M8[ns]" | "m8[ms]" | "M8[D]" => (value as i64).to_le_bytes().to_vec(),
        "u8" => (value as u64).to_le_bytes().to_vec(),
        "f4" => (value as f32).to_le_bytes().to_vec(),
        "f8" => value.to_le_bytes().to_vec(),
        other => panic!("test encoder lacks {other}"),
    };
    if big {
        le.reverse();
    }
    le
}

/// Records of `itemsize` bytes with fields `(offset, type)` for t, x, y, p.
fn records(fields: [(usize, &str); 4], itemsize: usize, events: &[[f64; 4]]) -> Vec<u8> {
    let mut out = Vec::new();
    for ev in events {
        let mut rec = vec![0xEEu8; itemsize];
        for ((offset, ty), v) in fields.iter().zip(ev) {
            let b = encode(ty, *v);
            rec[*offset..*offset + b.len()].copy_from_slice(&b);
        }
        out.extend(rec);
    }
    out
}

fn read_bytes(bytes: Vec<u8>, options: &ReadOptions) -> Result<Recording> {
    open_source(
        Box::new(Cursor::new(bytes)),
        "test.npy",
        Some("npy"),
        options,
    )?
    .read_all()
}

fn read(bytes: Vec<u8>) -> Result<Recording> {
    read_bytes(bytes, &ReadOptions::default())
}

fn tuples(rec: &Recording) -> Vec<(i64, u16, u16, u8)> {
    rec.events.iter().map(|e| (e.t, e.x, e.y, e.p)).collect()
}

const EVENTS: [[f64; 4]; 3] = [
    [0.0, 0.0, 0.0, 1.0],
    [123.0, 65535.0, 1.0, 0.0],
    [1_000_000.0, 3.0, 65535.0, 1.0],
];
const EXPECTED: [(i64, u16, u16, u8); 3] =
    [(0, 0, 0, 1), (123, 65535, 1, 0), (1_000_000, 3, 65535, 1)];

/// The producers of formats.md §12, as (name, descr, field offsets and types, itemsize).
type Producer = (&'static str, String, [(usize, &'static str); 4], usize);

fn producers() -> Vec<Producer> {
    vec![
        (
            "expelliarmus",
            "[('t', '<i8'), ('x', '<i2'), ('y', '<i2'), ('p', 'u1')]".into(),
            [(0, "<i8"), (8, "<i2"), (10, "<i2"), (12, "|u1")],
            13,
        ),
        (
            "expelliarmus padded",
            "[('t', '<i8'), ('x', '<i2'), ('y', '<i2'), ('p', 'u1'), ('', '|V3')]".into(),
            [(0, "<i8"), (8, "<i2"), (10, "<i2"), (12, "|u1")],
            16,
        ),
        (
            "Metavision EventCD",
            "{'names': ['x', 'y', 'p', 't'], 'formats': ['<u2', '<u2', '<i2', '<i8'], 'offsets': [0, 2, 4, 8], 'itemsize': 16}".into(),
            [(8, "<i8"), (0, "<u2"), (2, "<u2"), (4, "<i2")],
            16,
        ),
        (
            "dv-processing",
            "{'names': ['timestamp', 'x', 'y', 'polarity'], 'formats': ['<i8', '<i2', '<i2', 'i1'], 'offsets': [0, 8, 10, 12], 'itemsize': 16}".into(),
            [(0, "<i8"), (8, "<i2"), (10, "<i2"), (12, "|i1")],
            16,
        ),
        (
            "faery",
            "[('t', '<u8'), ('x', '<u2'), ('y', '<u2'), ('on', '?')]".into(),
            [(0, "<u8"), (8, "<u2"), (10, "<u2"), (12, "|b1")],
            13,
        ),
        (
            "tonic",
            "[('x', '<i2'), ('y', '<i2'), ('t', '<i8'), ('p', '|b1')]".into(),
            [(4, "<i8"), (0, "<i2"), (2, "<i2"), (12, "|b1")],
            13,
        ),
        (
            "big-endian, upper-case names",
            "[('T', '>i8'), ('X', '>u2'), ('Y', '>u4'), ('Pol', '>i2')]".into(),
            [(0, ">i8"), (8, ">u2"), (10, ">u4"), (14, ">i2")],
            16,
        ),
        (
            "native order, uint64 name",
            "{'names': ['ts', 'x', 'y', 'polarity'], 'formats': ['=u8', 'uint16', 'H', 'B']}".into(),
            [(0, "<u8"), (8, "<u2"), (10, "<u2"), (12, "|u1")],
            13,
        ),
    ]
}

#[test]
fn every_producer_layout_of_section_12() {
    for version in [1u8, 2, 3] {
        for (name, descr, fields, itemsize) in producers() {
            // x = 65535 does not fit `<i2`: producers with signed x store -1, dropped as out of range.
            let signed = fields[1].1.contains('i') || fields[2].1.contains('i');
            let events: Vec<[f64; 4]> = if signed {
                vec![EVENTS[0], [5.0, 300.0, 2.0, 0.0]]
            } else {
                EVENTS.to_vec()
            };
            let dict = format!(
                "{{'descr': {descr}, 'fortran_order': False, 'shape': ({},), }}",
                events.len()
            );
            let bytes = npy_bytes(version, &dict, &records(fields, itemsize, &events));
            let rec = read(bytes).unwrap_or_else(|e| panic!("{name} v{version}: {e}"));
            let want: Vec<_> = if signed {
                vec![EXPECTED[0], (5, 300, 2, 0)]
            } else {
                EXPECTED.to_vec()
            };
            assert_eq!(tuples(&rec), want, "{name} v{version}");
            assert_eq!(rec.metadata.format, Format::Npy);
            assert!(!rec.report.has_problems(), "{name}: {:?}", rec.report);
        }
    }
}

#[test]
fn signed_polarity_and_negative_coordinates() {
    let fields = [(0, "<i8"), (8, "<i2"), (10, "<i2"), (12, "|i1")];
    let events = [
        [-5.0, -1.0, 0.0, 1.0],
        [7.0, 1.0, 2.0, -1.0],
        [8.0, 3.0, 4.0, 0.0],
    ];
    let dict = "{'descr': [('t', '<i8'), ('x', '<i2'), ('y', '<i2'), ('p', '|i1')], 'fortran_order': False, 'shape': (3,), }";
    let rec = read(npy_bytes(1, dict, &records(fields, 13, &events))).unwrap();
    assert_eq!(tuples(&rec), vec![(7, 1, 2, 0), (8, 3, 4, 0)]);
    assert_eq!(rec.report.out_of_range, 1);
}

#[test]
fn float_and_datetime_times() {
    let dict = |t: &str| {
        format!("{{'descr': [('t', '{t}'), ('x', '<u2'), ('y', '<u2'), ('p', '|u1')], 'fortran_order': False, 'shape': (2,), }}")
    };
    let size = |t: &str| if t.ends_with('4') { 4 } else { 8 };
    let cases: [(&str, [f64; 2], [i64; 2]); 5] = [
        ("<f8", [0.003811, 1.25], [3811, 1_250_000]),
        (">f8", [-0.5, 2.0], [-500_000, 2_000_000]),
        ("<f4", [0.25, 1.5], [250_000, 1_500_000]),
        ("<M8[ns]", [1500.0, 2499.0], [2, 2]),
        ("<m8[ms]", [3.0, -1.0], [3000, -1000]),
    ];
    for (ty, values, want) in cases {
        let s = size(ty);
        let fields = [(0, ty), (s, "<u2"), (s + 2, "<u2"), (s + 4, "|u1")];
        let events = [[values[0], 1.0, 2.0, 1.0], [values[1], 3.0, 4.0, 0.0]];
        let rec = read(npy_bytes(1, &dict(ty), &records(fields, s + 5, &events))).unwrap();
        assert_eq!(rec.events.t, want.to_vec(), "{ty}");
    }
    // An explicit unit applies to integer time.
    let options = ReadOptions {
        text: crate::io::TextOptions {
            time_unit: TimeUnit::Milliseconds,
            ..Default::default()
        },
        ..Default::default()
    };
    let fields = [(0, "<i8"), (8, "<u2"), (10, "<u2"), (12, "|u1")];
    let bytes = npy_bytes(
        1,
        &dict("<i8"),
        &records(fields, 13, &[[7.0, 0.0, 0.0, 1.0]; 2]),
    );
    assert_eq!(
        read_bytes(bytes, &options).unwrap().events.t,
        vec![7000, 7000]
    );
}

#[test]
fn two_dimensional_arrays_are_t_x_y_p() {
    let mut data = Vec::new();
    for v in [1.5f64, 10.0, 20.0, 1.0, 2.0, 11.0, 21.0, -1.0] {
        data.extend(v.to_le_bytes());
    }
    let dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 4), }";
    let rec = read(npy_bytes(1, dict, &data)).unwrap();
    assert_eq!(
        tuples(&rec),
        vec![(1_500_000, 10, 20, 1), (2_000_000, 11, 21, 0)]
    );
    let mut ints = Vec::new();
    for v in [5i64, 1, 2, 1] {
        ints.extend(v.to_le_bytes());
    }
    let dict = "{'descr': '<i8', 'fortran_order': False, 'shape': (1, 4), }";
    assert_eq!(
        tuples(&read(npy_bytes(1, dict, &ints)).unwrap()),
        vec![(5, 1, 2, 1)]
    );
    let fortran = "{'descr': '<i8', 'fortran_order': True, 'shape': (3, 4), }";
    assert!(read(npy_bytes(1, fortran, &[0; 96])).is_err());
}

#[test]
fn float_coordinates_must_be_integral() {
    let mut data = Vec::new();
    for v in [
        1.0f64,
        10.5,
        20.0,
        1.0,
        2.0,
        f64::NAN,
        21.0,
        1.0,
        3.0,
        4.0,
        5.0,
        f64::NAN,
    ] {
        data.extend(v.to_le_bytes());
    }
    let dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4), }";
    let rec = read(npy_bytes(1, dict, &data)).unwrap();
    assert!(rec.events.is_empty());
    assert_eq!(rec.report.malformed, 3);
    assert_eq!(rec.report.warnings.len(), 3, "{:?}", rec.report.warnings);
}

#[test]
fn arrays_without_events_are_clear_errors() {
    let column = "{'descr': '<u2', 'fortran_order': False, 'shape': (3,), }";
    let msg = read(npy_bytes(1, column, &[0; 6])).unwrap_err().to_string();
    assert!(msg.contains("1-D") && msg.contains(".npz"), "{msg}");
    let missing = "{'descr': [('t', '<i8'), ('x', '<u2'), ('q', '<u2')], 'fortran_order': False, 'shape': (0,), }";
    let msg = read(npy_bytes(1, missing, &[])).unwrap_err().to_string();
    assert!(msg.contains("(t, x, q)"), "{msg}");
    let object = "{'descr': '|O', 'fortran_order': False, 'shape': (1,), }";
    assert!(read(npy_bytes(1, object, &[0; 8])).is_err());
    let strings = "{'descr': [('t', '<U4'), ('x', '<u2'), ('y', '<u2'), ('p', '|u1')], 'fortran_order': False, 'shape': (1,), }";
    assert!(read(npy_bytes(1, strings, &[0; 21])).is_err());
    let days = "{'descr': [('t', '<M8[D]'), ('x', '<u2'), ('y', '<u2'), ('p', '|u1')], 'fortran_order': False, 'shape': (1,), }";
    assert!(read(npy_bytes(1, days, &[0; 13])).is_err());
}

#[test]
fn truncated_data_and_absurd_counts() {
    let descr = "[('t', '<i8'), ('x', '<u2'), ('y', '<u2'), ('p', '|u1')]";
    let fields = [(0, "<i8"), (8, "<u2"), (10, "<u2"), (12, "|u1")];
    let data = records(fields, 13, &EVENTS);
    let dict = format!("{{'descr': {descr}, 'fortran_order': False, 'shape': (10,), }}");
    let rec = read(npy_bytes(1, &dict, &data[..32])).unwrap();
    assert_eq!(tuples(&rec), EXPECTED[..2].to_vec());
    assert_eq!(rec.report.truncated_bytes, 6);
    assert!(!rec.report.warnings.is_empty());
    // A shape that would need exabytes: read what is there, allocate nothing for it.
    for shape in ["(1152921504606846976,)", "(4294967296, 4294967296)"] {
        let dict = format!("{{'descr': {descr}, 'fortran_order': False, 'shape': {shape}, }}");
        let rec = read(npy_bytes(1, &dict, &data)).unwrap();
        assert_eq!(rec.events.len(), 3, "{shape}");
    }
    // Extra bytes after the declared records are ignored with a warning.
    let dict = format!("{{'descr': {descr}, 'fortran_order': False, 'shape': (2,), }}");
    let rec = read(npy_bytes(1, &dict, &data)).unwrap();
    assert_eq!(rec.events.len(), 2);
    assert!(!rec.report.warnings.is_empty());
}

#[test]
fn malformed_headers_are_errors() {
    let mut absurd = b"\x93NUMPY\x02\x00".to_vec();
    absurd.extend(u32::MAX.to_le_bytes());
    absurd.extend([b' '; 100]);
    assert!(read(absurd)
        .unwrap_err()
        .to_string()
        .contains("header claims"));
    let mut v4 = npy_bytes(1, "{}", &[]);
    v4[6] = 4;
    assert!(read(v4).unwrap_err().to_string().contains("version 4"));
    for dict in [
        "not a dict",
        "{'descr': '<i8'}",
        "{'descr': [('t', '<i8'), ('x'", 
        "{'shape': (1,), 'fortran_order': False}",
        "{'descr': [('t', '<i8')], 'fortran_order': False, 'shape': (-1,), }",
        "{'descr': {'names': ['t'], 'formats': ['<i8', '<i8']}, 'fortran_order': False, 'shape': (1,), }",
        "{'descr': {'names': ['t'], 'formats': ['<i8'], 'offsets': [4], 'itemsize': 8}, 'fortran_order': False, 'shape': (1,), }",
        "{'descr': [('t', '|V99999999')], 'fortran_order': False, 'shape': (1,), }",
    ] {
        assert!(read(npy_bytes(1, dict, &[0; 64])).is_err(), "{dict}");
    }
    let mut short = npy_bytes(
        1,
        "{'descr': '<i8', 'fortran_order': False, 'shape': (1,), }",
        &[],
    );
    short.truncate(40);
    assert!(read(short).is_err());
    assert!(read(b"\x93NUMPY".to_vec()).is_err());
}

#[test]
fn streaming_in_small_batches_matches_one_batch() {
    let descr = "[('t', '<i8'), ('x', '<u2'), ('y', '<u2'), ('p', '|u1')]";
    let fields = [(0, "<i8"), (8, "<u2"), (10, "<u2"), (12, "|u1")];
    let events: Vec<[f64; 4]> = (0..5000)
        .map(|i| {
            [
                i as f64 * 3.0,
                (i % 640) as f64,
                (i % 480) as f64,
                (i % 2) as f64,
            ]
        })
        .collect();
    let dict = format!(
        "{{'descr': {descr}, 'fortran_order': False, 'shape': ({},), }}",
        events.len()
    );
    let bytes = npy_bytes(1, &dict, &records(fields, 13, &events));
    let small = ReadOptions {
        batch_bytes: 1,
        ..Default::default()
    };
    let a = read_bytes(bytes.clone(), &small).unwrap();
    let b = read(bytes).unwrap();
    assert_eq!(a.events, b.events);
    assert_eq!(a.events.len(), 5000);
    assert_eq!(a.events.t[4999], 14997);
}

#[test]
fn type_strings() {
    use header::parse_type_str;
    let s = |t: &str| match parse_type_str(t) {
        Ok(Dtype::Scalar(s)) => (s.kind, s.size, s.big_endian),
        other => panic!("{t}: {other:?}"),
    };
    assert_eq!(s("<i8"), (Kind::Int, 8, false));
    assert_eq!(s(">u2"), (Kind::UInt, 2, true));
    assert_eq!(s("|b1"), (Kind::Bool, 1, false));
    assert_eq!(s("?"), (Kind::Bool, 1, false));
    assert_eq!(s("b"), (Kind::Int, 1, false));
    assert_eq!(s("<f2"), (Kind::Float, 2, false));
    assert_eq!(s("float32"), (Kind::Float, 4, false));
    assert_eq!(s("<M8[us]"), (Kind::Date(DateUnit::Micros), 8, false));
    assert!(matches!(
        parse_type_str("|V3"),
        Ok(Dtype::Opaque { size: 3, .. })
    ));
    assert!(matches!(
        parse_type_str("<U2"),
        Ok(Dtype::Opaque { size: 8, .. })
    ));
    assert!(parse_type_str("<i3").is_err());
    assert!(parse_type_str("").is_err());
    assert!(parse_type_str("<").is_err());
    let half = Scalar {
        kind: Kind::Float,
        size: 2,
        big_endian: false,
    };
    assert_eq!(half.read(&0x3C00u16.to_le_bytes()), Num::F(1.0));
    assert_eq!(half.read(&0xC100u16.to_le_bytes()), Num::F(-2.5));
}

proptest::proptest! {
    #[test]
    fn random_bytes_after_a_valid_header_never_panic(body in proptest::collection::vec(proptest::num::u8::ANY, 0..400), n in 0u64..100) {
        let dict = format!("{{'descr': [('t', '<f8'), ('x', '>i4'), ('y', '<u2'), ('p', '<f2')], 'fortran_order': False, 'shape': ({n},), }}");
        let _ = read(npy_bytes(1, &dict, &body));
    }

    #[test]
    fn random_headers_never_panic(header in "[{}()\\[\\]',: a-z0-9<>|]{0,120}") {
        let _ = read(npy_bytes(1, &header, &[0; 32]));
    }
}
