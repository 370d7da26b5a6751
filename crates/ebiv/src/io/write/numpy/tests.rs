use super::*;
use crate::io::{self, Format, ReadOptions};

fn edge_events() -> EventBuffer {
    let mut e = EventBuffer::new();
    e.push(i64::MIN, 0, 0, 0);
    e.push(-1, 65535, 65535, 1);
    e.push(0, 1, 2, 1);
    e.push(3811, 96, 133, 0);
    e.push(i64::MAX, 65535, 0, 1);
    e
}

fn write_all(writer: Box<dyn EventWriter>, batches: &[EventBuffer]) {
    let mut writer = writer;
    for b in batches {
        writer.write(b).unwrap();
    }
    writer.finish().unwrap();
}

fn twice(events: &EventBuffer) -> EventBuffer {
    let mut all = events.clone();
    all.extend_from(events);
    all
}

#[test]
fn header_is_64_byte_aligned_and_patchable() {
    for count in [0u64, 7, 1 << 40, u64::MAX] {
        let h = npy_header(RECORD_DESCR, count, None);
        assert_eq!(h.len() % 64, 0);
        assert_eq!(h.last(), Some(&b'\n'));
        assert!(h.len() <= reserved_header_len(RECORD_DESCR));
        let fixed = npy_header(RECORD_DESCR, count, Some(reserved_header_len(RECORD_DESCR)));
        assert_eq!(fixed.len(), reserved_header_len(RECORD_DESCR));
        let text = String::from_utf8_lossy(&fixed[10..]);
        assert!(text.contains(&format!("'shape': ({count},)")), "{text}");
    }
}

#[test]
fn npy_round_trip_with_edge_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("events.npy");
    let events = edge_events();
    write_all(
        Box::new(NpyWriter::create(&path).unwrap()),
        &[events.clone(), EventBuffer::new(), events.clone()],
    );
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!((bytes.len() - reserved_header_len(RECORD_DESCR)) % 13, 0);
    let rec = io::read_all(&path, &ReadOptions::default()).unwrap();
    assert_eq!(rec.metadata.format, Format::Npy);
    assert_eq!(rec.events, twice(&events));
    assert!(rec.report.warnings.is_empty(), "{:?}", rec.report);
    assert!(!dir.path().join("events.npy.partial").exists());
}

#[test]
fn npz_round_trip_with_edge_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("events.npz");
    let events = edge_events();
    write_all(
        Box::new(NpzWriter::create(&path).unwrap()),
        &[events.clone(), events.clone()],
    );
    let rec = io::read_all(&path, &ReadOptions::default()).unwrap();
    assert_eq!(rec.metadata.format, Format::Npz);
    assert_eq!(rec.events, twice(&events));
    assert!(rec.report.warnings.is_empty(), "{:?}", rec.report);
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers, vec![std::ffi::OsString::from("events.npz")]);
    // The members numpy expects, uncompressed.
    let mut zip = zip::ZipArchive::new(std::fs::File::open(&path).unwrap()).unwrap();
    let names: Vec<String> = zip.file_names().map(str::to_string).collect();
    assert_eq!(names, ["t.npy", "x.npy", "y.npy", "p.npy"]);
    let t = zip.by_name("t.npy").unwrap();
    assert_eq!(t.compression(), zip::CompressionMethod::Stored);
    assert_eq!(
        t.size(),
        (npy_header("'<i8'", 10, None).len() + 8 * 10) as u64
    );
}

#[test]
fn empty_streams_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["empty.npy", "empty.npz"] {
        let path = dir.path().join(name);
        let writer: Box<dyn EventWriter> = if name.ends_with("npy") {
            Box::new(NpyWriter::create(&path).unwrap())
        } else {
            Box::new(NpzWriter::create(&path).unwrap())
        };
        write_all(writer, &[]);
        let rec = io::read_all(&path, &ReadOptions::default()).unwrap();
        assert!(rec.events.is_empty(), "{name}");
        assert!(!rec.report.has_problems(), "{name}: {:?}", rec.report);
    }
}

#[test]
fn dropped_writers_leave_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    {
        let mut a = NpyWriter::create(&dir.path().join("a.npy")).unwrap();
        a.write(&edge_events()).unwrap();
        let mut b = NpzWriter::create(&dir.path().join("b.npz")).unwrap();
        b.write(&edge_events()).unwrap();
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn polarity_is_stored_as_zero_or_one() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.npz");
    let mut e = EventBuffer::new();
    e.push(1, 1, 1, 7);
    write_all(Box::new(NpzWriter::create(&path).unwrap()), &[e]);
    let rec = io::read_all(&path, &ReadOptions::default()).unwrap();
    assert_eq!(rec.events.p, vec![1]);
}
