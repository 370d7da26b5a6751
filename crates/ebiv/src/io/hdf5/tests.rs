use super::*;

#[test]
fn seek_table_starts_at_or_before_the_target() {
    let table = SeekTable {
        entries: vec![(100, 0), (2100, 60), (4100, 121)],
    };
    assert_eq!(table.start_for(99), None);
    assert_eq!(table.start_for(100), Some(0));
    assert_eq!(table.start_for(2099), Some(0));
    assert_eq!(table.start_for(2100), Some(60));
    assert_eq!(table.start_for(1 << 40), Some(121));
}

fn fixture(name: &str) -> Box<dyn ReadSeek> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/hdf5")
        .join(name);
    Box::new(std::io::Cursor::new(std::fs::read(path).unwrap()))
}

/// The indexes are used: a seek jumps ahead without decoding what lies before.
#[test]
fn seeking_jumps_by_the_index() {
    for name in ["metavision_ecf.hdf5", "dsec_columns.h5"] {
        let mut reader = open_reader(fixture(name), name.into(), &ReadOptions::default()).unwrap();
        let mut all = EventBuffer::new();
        let mut batch = EventBuffer::new();
        while reader.next_batch(&mut batch).unwrap() {
            all.extend_from(&batch);
            batch.clear();
        }
        let t0 = all.t[0];
        let target = t0 + 10_000;
        let mut reader = open_reader(fixture(name), name.into(), &ReadOptions::default()).unwrap();
        assert!(reader.seek_near(target).unwrap(), "{name}");
        assert!(reader.next_batch(&mut batch).unwrap());
        // It skipped events, and only events before the target.
        let landed = reader.next as usize - batch.len();
        assert!(landed > 0, "{name}");
        assert_eq!(batch.t[0], all.t[landed], "{name}");
        assert!(all.t[..landed].iter().all(|&t| t < target), "{name}");
        // Never backwards, and not past the end.
        assert!(!reader.seek_near(t0).unwrap());
    }
}
