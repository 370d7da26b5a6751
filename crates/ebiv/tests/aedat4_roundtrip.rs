//! Writing AEDAT 4.0 with ebiv's writer and reading it back gives exactly the same events and
//! triggers, for every compression, batch split and time stamp (formats.md §9), and the data
//! table the writer appends lets the reader seek.

use ebiv::io::{self, write, Format, ReadOptions};
use ebiv::{EventBuffer, Geometry, Trigger};
use proptest::prelude::*;
use std::path::Path;
use write::{Aedat4Compression, Aedat4Writer, EventWriter};

const ALL: [Aedat4Compression; 3] = [
    Aedat4Compression::None,
    Aedat4Compression::Lz4,
    Aedat4Compression::Zstd,
];

/// Write `batches` to `path`.
fn write_file(path: &Path, g: Geometry, compression: Aedat4Compression, batches: &[EventBuffer]) {
    let mut w: Box<dyn EventWriter> =
        Box::new(Aedat4Writer::create(path, Some(g), compression).unwrap());
    for b in batches {
        w.write(b).unwrap();
    }
    w.finish().unwrap();
}

fn read_back(path: &Path, batch_bytes: usize) -> io::Recording {
    let options = ReadOptions {
        batch_bytes,
        ..Default::default()
    };
    io::read_all(path, &options).unwrap()
}

/// All events and triggers of `batches`, in order, triggers on channel 0 with value 0/1 and
/// polarities 0/1, as an AEDAT 4.0 reader returns them.
fn expected(batches: &[EventBuffer]) -> EventBuffer {
    let mut all = EventBuffer::new();
    for b in batches {
        for e in b.iter() {
            all.push(e.t, e.x, e.y, (e.p != 0) as u8);
        }
        all.triggers.extend(b.triggers.iter().map(|tr| Trigger {
            t: tr.t,
            channel: 0,
            value: (tr.value != 0) as u8,
        }));
    }
    all
}

/// `n` events of a seeded flow-like stream at Unix-epoch times, with a trigger every 1000.
fn unix_stream(n: usize, g: Geometry, seed: u64) -> EventBuffer {
    let mut b = EventBuffer::with_capacity(n);
    let mut state = seed | 1;
    let t0 = 1_718_000_000_123_456; // 2024-06-10, µs since the Unix epoch
    for k in 0..n {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let t = t0 + (k as i64) / 7;
        b.push(
            t,
            (state % g.width as u64) as u16,
            ((state >> 24) % g.height as u64) as u16,
            ((state >> 50) & 1) as u8,
        );
        if k % 1000 == 0 {
            b.triggers.push(Trigger {
                t,
                channel: 0,
                value: (k / 1000 % 2) as u8,
            });
        }
    }
    b
}

/// Split `all` into batches of `size` events (triggers go with the batch holding their time).
fn split(all: &EventBuffer, size: usize) -> Vec<EventBuffer> {
    let mut batches = Vec::new();
    let mut triggers = all.triggers.iter().peekable();
    for start in (0..all.len()).step_by(size.max(1)) {
        let end = (start + size).min(all.len());
        let mut b = EventBuffer::with_capacity(end - start);
        for i in start..end {
            b.push(all.t[i], all.x[i], all.y[i], all.p[i]);
        }
        let last = all.t[end - 1];
        while let Some(tr) = triggers.next_if(|tr| tr.t <= last) {
            b.triggers.push(*tr);
        }
        batches.push(b);
    }
    let rest: Vec<Trigger> = triggers.copied().collect();
    if !rest.is_empty() {
        let mut b = EventBuffer::new();
        b.triggers = rest;
        batches.push(b);
    }
    batches
}

#[test]
fn every_compression_round_trips_exactly() {
    let g = Geometry::new(640, 480);
    let all = unix_stream(30_000, g, 7);
    let batches = split(&all, 2_500);
    let dir = tempfile::tempdir().unwrap();
    for compression in ALL {
        let path = dir.path().join(format!("{compression:?}.aedat4"));
        write_file(&path, g, compression, &batches);
        for batch_bytes in [1 << 10, 1 << 20] {
            let back = read_back(&path, batch_bytes);
            assert_eq!(back.events, expected(&batches), "{compression:?}");
            assert_eq!(back.metadata.format, Format::Aedat4);
            assert_eq!(back.metadata.geometry, Some(g));
            assert_eq!(back.report.triggers, 30);
            assert!(!back.report.has_problems(), "{:?}", back.report);
        }
    }
}

#[test]
fn empty_streams_round_trip() {
    let g = Geometry::new(320, 240);
    let dir = tempfile::tempdir().unwrap();
    let only_triggers = {
        let mut b = EventBuffer::new();
        b.triggers.push(Trigger {
            t: 1_600_000_000_000_000,
            channel: 0,
            value: 1,
        });
        b
    };
    for compression in ALL {
        for batches in [
            vec![],
            vec![EventBuffer::new()],
            vec![only_triggers.clone()],
        ] {
            let path = dir.path().join(format!("empty_{compression:?}.aedat4"));
            write_file(&path, g, compression, &batches);
            let back = read_back(&path, 1 << 20);
            assert_eq!(back.events, expected(&batches), "{compression:?}");
            assert_eq!(back.metadata.geometry, Some(g));
            assert!(!back.report.has_problems(), "{:?}", back.report);
            let mut reader = io::open(&path, &ReadOptions::default()).unwrap();
            reader.skip_to(0).unwrap();
            assert_eq!(reader.read_all().unwrap().events.len(), 0);
        }
    }
}

#[test]
fn times_of_any_sign_and_size_are_kept() {
    let g = Geometry::new(32_768, 32_768);
    let mut b = EventBuffer::new();
    let times = [
        1_700_000_000_000_000,
        0,
        -1,
        i64::MIN,
        i64::MAX,
        1_700_000_000_000_000,
        42,
    ];
    for (k, &t) in times.iter().enumerate() {
        b.push(t, 32_767 - k as u16, k as u16, (k % 3) as u8);
        b.triggers.push(Trigger {
            t: !t,
            channel: 0,
            value: (k % 2) as u8,
        });
    }
    b.push(5, 32_767, 32_767, 200);
    let dir = tempfile::tempdir().unwrap();
    for compression in ALL {
        let path = dir.path().join(format!("t_{compression:?}.aedat4"));
        write_file(&path, g, compression, std::slice::from_ref(&b));
        let back = read_back(&path, 1 << 20);
        assert_eq!(back.events, expected(std::slice::from_ref(&b)));
    }
}

#[test]
fn trigger_channels_are_not_stored() {
    // AEDAT 4.0 triggers have no channel: every trigger reads back on channel 0.
    let g = Geometry::new(64, 64);
    let mut b = EventBuffer::new();
    b.push(10, 1, 1, 1);
    for (t, channel, value) in [(11, 3, 1), (12, 3, 0), (13, 0, 7)] {
        b.triggers.push(Trigger { t, channel, value });
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("channels.aedat4");
    write_file(&path, g, Aedat4Compression::Lz4, std::slice::from_ref(&b));
    let back = read_back(&path, 1 << 20);
    let triggers: Vec<_> = back
        .events
        .triggers
        .iter()
        .map(|tr| (tr.t, tr.channel, tr.value))
        .collect();
    assert_eq!(triggers, vec![(11, 0, 1), (12, 0, 0), (13, 0, 1)]);
}

#[test]
fn create_picks_aedat4_from_the_extension() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.AEDAT4");
    assert_eq!(write::format_for_path(&path).unwrap(), Format::Aedat4);
    let g = Geometry::new(100, 50);
    let all = unix_stream(5_000, g, 3);
    let mut w = write::create(&path, Format::Aedat4, Some(g)).unwrap();
    w.write(&all).unwrap();
    w.finish().unwrap();
    let back = read_back(&path, 1 << 20);
    assert_eq!(back.metadata.header_value("compression"), Some("LZ4"));
    assert_eq!(back.events, expected(std::slice::from_ref(&all)));
    let err = write::create(&dir.path().join("x.aedat4"), Format::Aedat4, None)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("sensor size"), "{err}");
    let err = write::format_for_path(Path::new("x.aedat")).unwrap_err();
    assert!(err.to_string().contains(".aedat4"), "{err}");
}

/// Byte offset of the first packet of a file written by ebiv.
fn first_packet(bytes: &[u8]) -> usize {
    18 + i32::from_le_bytes(bytes[14..18].try_into().unwrap()) as usize
}

#[test]
fn seeking_uses_the_written_data_table() {
    let g = Geometry::new(640, 480);
    let all = unix_stream(40_000, g, 11);
    let batches = split(&all, 3_000);
    let want = expected(&batches);
    let dir = tempfile::tempdir().unwrap();
    for compression in ALL {
        let path = dir.path().join(format!("seek_{compression:?}.aedat4"));
        write_file(&path, g, compression, &batches);
        for k in [0, 9_000, 20_000, 39_999] {
            let t = want.t[k];
            let mut reader = io::open(&path, &ReadOptions::default()).unwrap();
            reader.skip_to(t).unwrap();
            let rest = reader.read_all().unwrap();
            assert_eq!(
                rest.events.len(),
                want.t.iter().filter(|&&x| x >= t).count()
            );
            assert_eq!(rest.events.t.first(), Some(&t));
            let triggers: Vec<_> = want.triggers.iter().filter(|tr| tr.t >= t).collect();
            assert_eq!(rest.events.triggers.iter().collect::<Vec<_>>(), triggers);
        }
    }

    // Spoil the first packet of an uncompressed file: decoding from the start meets it, a
    // seek through the table jumps over it.
    let path = dir.path().join("seek_None.aedat4");
    let mut bytes = std::fs::read(&path).unwrap();
    let body = first_packet(&bytes) + 8;
    assert_eq!(&bytes[body + 8..body + 12], b"EVTS");
    bytes[body + 8..body + 12].copy_from_slice(b"XXXX");
    let spoiled = dir.path().join("spoiled.aedat4");
    std::fs::write(&spoiled, &bytes).unwrap();
    assert_eq!(read_back(&spoiled, 1 << 20).report.malformed, 1);
    let t = want.t[30_000];
    let mut reader = io::open(&spoiled, &ReadOptions::default()).unwrap();
    reader.skip_to(t).unwrap();
    let rest = reader.read_all().unwrap();
    assert_eq!(rest.report.malformed, 0, "{:?}", rest.report);
    assert_eq!(rest.events.t.first(), Some(&t));
    assert_eq!(
        rest.events.len(),
        want.t.iter().filter(|&&x| x >= t).count()
    );
}

#[test]
fn packets_hold_4096_events_and_the_table_indexes_them() {
    let g = Geometry::new(640, 480);
    let all = unix_stream(10_000, g, 5);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("packets.aedat4");
    // Batches of 1000 events: packets fill across batches.
    write_file(&path, g, Aedat4Compression::None, &split(&all, 1_000));
    let bytes = std::fs::read(&path).unwrap();
    let table: usize = read_back(&path, 1 << 20)
        .metadata
        .header_value("dataTablePosition")
        .unwrap()
        .parse()
        .unwrap();
    let mut pos = first_packet(&bytes);
    let mut counts = Vec::new();
    while pos < table {
        let id = i32::from_le_bytes(bytes[pos..pos + 4].try_into().unwrap());
        let size = i32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let body = &bytes[pos + 8..pos + 8 + size];
        if id == 0 {
            // Size prefix, root offset and identifier; the root table's field 0 points at the
            // vector of events.
            assert_eq!(&body[8..12], b"EVTS");
            let u32_at =
                |at: usize| u32::from_le_bytes(body[at..at + 4].try_into().unwrap()) as usize;
            let root = 4 + u32_at(4);
            let field = root + 4;
            let vector = field + u32_at(field);
            assert_eq!((vector + 4) % 8, 0, "events are 8-aligned");
            assert_eq!(vector + 4 + 16 * u32_at(vector), size);
            counts.push(u32_at(vector));
        }
        pos += 8 + size;
    }
    assert_eq!(pos, table, "packets end where the table starts");
    assert_eq!(counts, [4096, 4096, 1808]);
    assert_eq!(&bytes[table + 8..table + 12], b"FTAB");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any events on the sensor, any times, any triggers, any batch split, any compression.
    #[test]
    fn arbitrary_streams_round_trip(
        w in 1u32..3000,
        h in 1u32..3000,
        raw in proptest::collection::vec((any::<i64>(), any::<u16>(), any::<u16>(), any::<u8>()), 0..9000),
        triggers in proptest::collection::vec((any::<i64>(), any::<u8>(), any::<u8>()), 0..50),
        batch in 1usize..5000,
        compression in 0usize..3,
    ) {
        let g = Geometry::new(w, h);
        let mut all = EventBuffer::new();
        for (t, x, y, p) in raw {
            all.push(t, x % w as u16, y % h as u16, p);
        }
        all.triggers = triggers.into_iter().map(|(t, channel, value)| Trigger { t, channel, value }).collect();
        let mut batches: Vec<EventBuffer> = Vec::new();
        for start in (0..all.len()).step_by(batch) {
            let mut b = EventBuffer::new();
            for i in start..(start + batch).min(all.len()) {
                b.push(all.t[i], all.x[i], all.y[i], all.p[i]);
            }
            batches.push(b);
        }
        match batches.first_mut() {
            Some(b) => b.triggers = all.triggers.clone(),
            None => {
                let mut b = EventBuffer::new();
                b.triggers = all.triggers.clone();
                batches.push(b);
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.aedat4");
        write_file(&path, g, ALL[compression], &batches);
        let back = read_back(&path, 1 << 16);
        prop_assert_eq!(back.events, expected(&batches));
        // Unsorted times are counted as regressions; nothing may be dropped or damaged.
        let r = back.report;
        prop_assert_eq!((r.out_of_range, r.malformed, r.unknown_words, r.truncated_bytes), (0, 0, 0, 0));
        prop_assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    }
}
