//! Writing then reading Prophesee RAW (EVT 3.0, 2.0, 2.1 in both byte orders) gives back
//! exactly the same events and triggers, across clock loops and at every coordinate edge.

use ebiv::io::{self, write, Evt21Order, Format, ReadOptions};
use ebiv::{EventBuffer, Geometry, Trigger};
use proptest::prelude::*;
use std::path::Path;

const ALL: [(Format, Option<Evt21Order>); 4] = [
    (Format::Evt3, None),
    (Format::Evt2, None),
    (Format::Evt21, Some(Evt21Order::Little)),
    (Format::Evt21, Some(Evt21Order::Legacy)),
];

fn write_raw(
    path: &Path,
    format: Format,
    order: Option<Evt21Order>,
    g: Geometry,
    events: &EventBuffer,
) {
    let mut w: Box<dyn write::EventWriter> = match order {
        Some(o) => Box::new(
            write::Evt2Writer::create(path, Some(g), write::Evt2Variant::Evt21(o)).unwrap(),
        ),
        None => write::create(path, format, Some(g)).unwrap(),
    };
    // Two batches, to cross a batch boundary in the writer too.
    let half = events.len() / 2;
    let (mut a, mut b) = (EventBuffer::new(), EventBuffer::new());
    for (i, e) in events.iter().enumerate() {
        let target = if i < half { &mut a } else { &mut b };
        target.push(e.t, e.x, e.y, e.p);
    }
    let split_t = b.t.first().copied().unwrap_or(i64::MAX);
    for tr in &events.triggers {
        if tr.t < split_t { &mut a } else { &mut b }
            .triggers
            .push(*tr);
    }
    w.write(&a).unwrap();
    w.write(&b).unwrap();
    w.finish().unwrap();
}

fn read_back(path: &Path, batch_bytes: usize) -> io::Recording {
    let options = ReadOptions {
        batch_bytes,
        ..Default::default()
    };
    io::read_all(path, &options).unwrap()
}

fn assert_round_trip(events: &EventBuffer, g: Geometry, batch_bytes: usize) {
    let dir = tempfile::tempdir().unwrap();
    for (format, order) in ALL {
        let path = dir.path().join(format!("rt_{format:?}_{order:?}.raw"));
        write_raw(&path, format, order, g, events);
        let back = read_back(&path, batch_bytes);
        assert_eq!(back.metadata.format, format);
        assert_eq!(back.metadata.geometry, Some(g));
        assert_eq!(back.events.t, events.t, "{format:?} {order:?}: times");
        assert_eq!(back.events.x, events.x, "{format:?} {order:?}: x");
        assert_eq!(back.events.y, events.y, "{format:?} {order:?}: y");
        assert_eq!(back.events.p, events.p, "{format:?} {order:?}: p");
        let mut want = events.triggers.clone();
        want.sort_by_key(|tr| tr.t);
        assert_eq!(back.events.triggers, want, "{format:?} {order:?}: triggers");
        let regressions = events.t.windows(2).filter(|w| w[1] < w[0]).count() as u64;
        let report = &back.report;
        assert_eq!(
            report.time_regressions, regressions,
            "{format:?}: counted, not clamped"
        );
        assert_eq!(
            report.out_of_range
                + report.before_time_base
                + report.unknown_words
                + report.malformed
                + report.truncated_bytes,
            0,
            "{format:?}: {report:?}"
        );
    }
}

/// Events with time steps drawn from `steps` (µs, may be huge), all corners of the sensor.
fn stream_from(start: i64, steps: &[(i64, u16, u16, bool)], g: Geometry) -> EventBuffer {
    let mut b = EventBuffer::new();
    let mut t = start;
    for &(dt, x, y, p) in steps {
        t += dt;
        b.push(t, x % g.width as u16, y % g.height as u16, p as u8);
    }
    b
}

#[test]
fn edges_of_the_sensor_and_both_polarities() {
    let g = Geometry::new(1280, 720);
    let mut b = EventBuffer::new();
    for (i, &(x, y)) in [(0, 0), (1279, 0), (0, 719), (1279, 719), (640, 360)]
        .iter()
        .enumerate()
    {
        b.push(100 + i as i64, x, y, (i % 2) as u8);
        b.push(100 + i as i64, x, y, 1 - (i % 2) as u8);
    }
    b.triggers.push(Trigger {
        t: 101,
        channel: 3,
        value: 1,
    });
    b.triggers.push(Trigger {
        t: 104,
        channel: 0,
        value: 0,
    });
    assert_round_trip(&b, g, 4096);
}

#[test]
fn evt3_crosses_the_24_bit_clock_loop_many_times() {
    let g = Geometry::new(640, 480);
    // Steps of 1..7 s: the 16.777 s loop is crossed a dozen times, sometimes by a wide gap.
    let steps: Vec<_> = (0..60)
        .map(|i| {
            (
                1_000_000 + (i * 977_777) % 6_000_000,
                i as u16 * 7,
                i as u16 * 3,
                i % 3 == 0,
            )
        })
        .collect();
    let b = stream_from(5, &steps, g);
    assert!(b.t.last().unwrap() > &(10 * (1 << 24)));
    assert_round_trip(&b, g, 4096);
}

#[test]
fn evt2_crosses_the_34_bit_clock_loop() {
    let g = Geometry::new(640, 480);
    let loop_us = 1i64 << 34;
    let mut b = EventBuffer::new();
    for (i, t) in [
        loop_us - 70,
        loop_us - 1,
        loop_us,
        loop_us + 5,
        3 * loop_us + 1234,
        3 * loop_us + 9_999_999,
    ]
    .into_iter()
    .enumerate()
    {
        b.push(t, i as u16, 2 * i as u16, 1);
    }
    assert_round_trip(&b, g, 4096);
}

#[test]
fn unix_epoch_times_and_small_regressions_survive() {
    // AEDAT 4 time stamps are Unix µs; a RAW copy keeps them through `% t0`.
    let g = Geometry::new(320, 240);
    let t0 = 1_605_537_493_718_345i64;
    let mut b = EventBuffer::new();
    for (i, dt) in [0i64, 3, 3, 1, 2, 4095, 4097, 70_000, 69_990]
        .into_iter()
        .enumerate()
    {
        b.push(t0 + dt, (i * 30) as u16, (i * 20) as u16, (i % 2) as u8);
    }
    assert_round_trip(&b, g, 4096);
}

#[test]
fn empty_stream_gives_a_valid_empty_file() {
    assert_round_trip(&EventBuffer::new(), Geometry::new(8, 8), 4096);
}

#[test]
fn writer_rejects_what_the_format_cannot_hold() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.raw");
    let big = write::create(&path, Format::Evt3, Some(Geometry::new(4096, 10)));
    assert!(big.is_err(), "11-bit coordinates");
    assert!(
        write::create(&path, Format::Evt3, None).is_err(),
        "geometry required"
    );
    let mut w = write::create(&path, Format::Evt3, Some(Geometry::new(10, 10))).unwrap();
    let mut b = EventBuffer::new();
    b.push(0, 10, 0, 1);
    assert!(w.write(&b).is_err(), "x outside the sensor");
    drop(w);
    assert!(!path.exists(), "no partial output under the final name");
    let mut w = write::create(&path, Format::Evt3, Some(Geometry::new(10, 10))).unwrap();
    let mut b = EventBuffer::new();
    b.push(30_000_000, 1, 1, 1);
    b.push(1_000, 1, 1, 1);
    let err = w.write(&b).unwrap_err().to_string();
    assert!(err.contains("sort the events"), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn random_streams_round_trip(
        start in 0i64..(1i64 << 40),
        steps in prop::collection::vec(
            (prop_oneof![8 => 0i64..70, 3 => 0i64..5000, 1 => 0i64..40_000_000], any::<u16>(), any::<u16>(), any::<bool>()),
            0..400,
        ),
        trig in prop::collection::vec((0usize..400, 0u8..16, 0u8..2), 0..5),
        batch_kib in 4usize..64,
    ) {
        let g = Geometry::new(1280, 720);
        let mut b = stream_from(start, &steps, g);
        for (i, channel, value) in trig {
            if let Some(&t) = b.t.get(i) {
                b.triggers.push(Trigger { t, channel, value });
            }
        }
        b.triggers.sort_by_key(|tr| tr.t);
        assert_round_trip(&b, g, batch_kib * 1024);
    }
}
