//! HDF5 event files: the fixtures of `tests/data/hdf5` (made by `make_fixtures.py` there, with
//! an ECF encoder of its own) decode to exactly the events stored beside them, in every batch
//! size, seek by their indexes, and damaged copies give errors, never a panic.

use ebiv::io::{self, Format, ReadOptions};
use ebiv::EventBuffer;
use std::path::PathBuf;
use std::sync::Arc;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/hdf5")
        .join(name)
}

fn read(name: &str, options: &ReadOptions) -> io::Recording {
    io::read_all(fixture(name), options).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn same_events(a: &EventBuffer, b: &EventBuffer) {
    assert_eq!(a.len(), b.len(), "event count");
    assert_eq!(a.t, b.t, "t");
    assert_eq!(a.x, b.x, "x");
    assert_eq!(a.y, b.y, "y");
    assert_eq!(a.p, b.p, "p");
}

#[test]
fn every_layout_decodes_to_its_events() {
    let expected = read("metavision.expected.npz", &ReadOptions::default()).events;
    for name in ["metavision_ecf.hdf5", "metavision_plain.hdf5"] {
        for batch_bytes in [1, 20_000, 1 << 20] {
            let options = ReadOptions {
                batch_bytes,
                ..ReadOptions::default()
            };
            let rec = read(name, &options);
            assert_eq!(rec.metadata.format, Format::Hdf5);
            same_events(&rec.events, &expected);
            assert!(!rec.report.has_problems(), "{name}: {:?}", rec.report);
            let g = rec.metadata.geometry.expect("geometry attribute");
            assert_eq!([g.width, g.height], [640, 480]);
        }
    }
    let dsec = read("dsec_columns.h5", &ReadOptions::default());
    same_events(
        &dsec.events,
        &read("dsec.expected.npz", &ReadOptions::default()).events,
    );
    assert!(dsec.metadata.geometry.is_none());
}

#[test]
fn triggers_come_in_time_with_the_events() {
    let rec = read(
        "metavision_ecf.hdf5",
        &ReadOptions {
            batch_bytes: 1,
            ..ReadOptions::default()
        },
    );
    let expected = read("metavision.expected.npz", &ReadOptions::default()).events;
    let got: Vec<(i64, u8, u8)> = rec
        .events
        .triggers
        .iter()
        .map(|tr| (tr.t, tr.channel, tr.value))
        .collect();
    let t = |i: usize| expected.t[i] + 1;
    assert_eq!(
        got,
        vec![
            (t(100), 0, 1),
            (t(900), 0, 0),
            (t(2000), 3, 1),
            (t(4000), 3, 0)
        ]
    );
}

#[test]
fn the_metavision_time_option_subtracts_the_time_shift_attribute() {
    let options = ReadOptions {
        metavision_time_shift: true,
        ..ReadOptions::default()
    };
    let shifted = read("metavision_ecf.hdf5", &options);
    let plain = read("metavision_ecf.hdf5", &ReadOptions::default());
    assert_eq!(shifted.events.t[0], 0);
    assert_eq!(shifted.metadata.time_shift_us, plain.events.t[0]);
    assert_eq!(
        shifted.events.triggers[0].t,
        plain.events.triggers[0].t - plain.events.t[0]
    );
}

/// Seeking by `/CD/indexes` (Metavision) or `ms_to_idx` (DSEC) gives the events from the
/// target on, triggers included.
#[test]
fn seeking_gives_the_events_from_the_target_on() {
    for (name, expected) in [
        ("metavision_ecf.hdf5", "metavision.expected.npz"),
        ("metavision_plain.hdf5", "metavision.expected.npz"),
        ("dsec_columns.h5", "dsec.expected.npz"),
    ] {
        let all = read(expected, &ReadOptions::default()).events;
        let full = read(name, &ReadOptions::default()).events;
        let (t0, t1) = all.time_range().unwrap();
        for target in [
            t0,
            t0 + 1999,
            t0 + 2000,
            t0 + 13_777,
            t0 + 60_000,
            t1,
            t1 + 1,
        ] {
            let mut reader = io::open(fixture(name), &ReadOptions::default()).unwrap();
            reader.skip_to(target).unwrap();
            let mut got = EventBuffer::new();
            let mut batch = EventBuffer::new();
            while reader.read_batch(&mut batch).unwrap() {
                got.extend_from(&batch);
            }
            let want: Vec<i64> = all.t.iter().copied().filter(|&t| t >= target).collect();
            assert_eq!(got.t, want, "{name} from {target}");
            let triggers: Vec<i64> = full
                .triggers
                .iter()
                .map(|tr| tr.t)
                .filter(|&t| t >= target)
                .collect();
            let got_triggers: Vec<i64> = got.triggers.iter().map(|tr| tr.t).collect();
            assert_eq!(got_triggers, triggers, "{name} triggers from {target}");
        }
    }
}

/// Decode a damaged copy from memory: an error or events, never a panic.
fn decode_bytes(bytes: Vec<u8>) -> Result<usize, String> {
    let mut reader = io::open_memory(Arc::from(bytes), "damaged.hdf5", &ReadOptions::default())
        .map_err(|e| e.to_string())?;
    let mut n = 0;
    let mut batch = EventBuffer::new();
    while reader.read_batch(&mut batch).map_err(|e| e.to_string())? {
        n += batch.len();
    }
    Ok(n)
}

/// A truncated file gives an error, unless what was cut held none of the events (the end of
/// an HDF5 file may hold metadata that reading does not need); never some of the events.
#[test]
fn truncated_files_give_errors() {
    let bytes = std::fs::read(fixture("metavision_ecf.hdf5")).unwrap();
    let all = read("metavision_ecf.hdf5", &ReadOptions::default())
        .events
        .len();
    let mut errors = 0;
    let cuts: Vec<usize> = (0..bytes.len())
        .step_by(997)
        .chain([bytes.len() - 1])
        .collect();
    for &cut in &cuts {
        match decode_bytes(bytes[..cut].to_vec()) {
            Err(e) => {
                assert!(!e.is_empty());
                errors += 1;
            }
            Ok(n) => assert_eq!(
                n,
                all,
                "cut at {cut} of {} lost events silently",
                bytes.len()
            ),
        }
    }
    assert!(
        errors > cuts.len() * 9 / 10,
        "{errors} errors in {} cuts",
        cuts.len()
    );
}

/// Every byte of every ECF chunk overwritten in turn (a damaged chunk) and random bytes
/// anywhere: an error naming the problem, or events; never a panic.
#[test]
fn damaged_chunks_give_errors_not_panics() {
    let bytes = std::fs::read(fixture("metavision_ecf.hdf5")).unwrap();
    let mut errors = Vec::new();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for k in 0..400 {
        let mut damaged = bytes.clone();
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let at = (state % bytes.len() as u64) as usize;
        let len = 1 + k % 8;
        for b in damaged.iter_mut().skip(at).take(len) {
            *b = (state >> 8) as u8 ^ *b ^ 0x5A;
        }
        if let Err(e) = decode_bytes(damaged) {
            errors.push(e);
        }
    }
    assert!(!errors.is_empty());
    assert!(errors.iter().all(|e| !e.is_empty()));
    // Some damage lands in the ECF data and is reported as such.
    assert!(errors.iter().any(|e| e.contains("ECF")), "{errors:?}");
}

#[test]
fn files_without_events_say_what_they_hold() {
    // An HDF5 file with only the index group of a Metavision file: `/CD/events` removed by
    // renaming its link is beyond this test; a DSEC file read as a Metavision one is not.
    let bytes = std::fs::read(fixture("dsec_columns.h5")).unwrap();
    let needle = b"events";
    let at = bytes
        .windows(needle.len())
        .position(|w| w == needle)
        .unwrap();
    let mut renamed = bytes.clone();
    renamed[at..at + needle.len()].copy_from_slice(b"evenTs");
    let err = decode_bytes(renamed).unwrap_err();
    assert!(err.contains("no events found"), "{err}");
}
