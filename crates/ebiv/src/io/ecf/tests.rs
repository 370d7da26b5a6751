use super::*;
use proptest::prelude::*;

fn events(rows: &[(u16, u16, u8, i64)]) -> EcfEvents {
    EcfEvents {
        x: rows.iter().map(|r| r.0).collect(),
        y: rows.iter().map(|r| r.1).collect(),
        p: rows.iter().map(|r| r.2).collect(),
        t: rows.iter().map(|r| r.3).collect(),
    }
}

fn decoded(bytes: &[u8]) -> EcfEvents {
    let mut out = EcfEvents::default();
    decode(bytes, &mut out).expect("decodes");
    out
}

const PACKINGS: [Packing; 4] = [
    Packing::Smallest,
    Packing::AllPacked,
    Packing::XAndPPacked,
    Packing::Masked,
];

/// A buffer written by hand from the layout (formats.md §6.3), not by the encoder: masked x
/// with runs of y and p.
#[test]
fn decodes_a_hand_written_masked_buffer() {
    let mut b = Vec::new();
    b.extend_from_slice(&(3u32 << 2).to_le_bytes());
    b.extend_from_slice(&100u64.to_le_bytes());
    b.extend_from_slice(&[0x02, 0x51]); // two events at +0, one at +5
    b.extend_from_slice(&((7u16 << 5) | 3).to_le_bytes()); // y = 7 for 3 events
    b.extend_from_slice(&((10u16 << 5) | 0b10000).to_le_bytes()); // x = 10 and 11
    b.extend_from_slice(&(20u16 << 5).to_le_bytes()); // x = 20
    b.extend_from_slice(&[(1 << 7) | 2, 1]); // p = 1, 1, 0
    assert_eq!(
        decoded(&b),
        events(&[(10, 7, 1, 100), (11, 7, 1, 100), (20, 7, 0, 105)])
    );
}

/// Large steps (least significant nibble first), the 15 escape of a time-stamp run and the
/// 31 escape of a row run, with x and p packed, written by hand.
#[test]
fn decodes_large_steps_and_escaped_runs() {
    let n = 40usize;
    let mut b = Vec::new();
    b.extend_from_slice(&(((n as u32) << 2) | 1).to_le_bytes());
    b.extend_from_slice(&5u64.to_le_bytes());
    b.extend_from_slice(&[0xF3, 0xF2, 0xF1]); // a step of 0x123 = 291 µs
    b.extend_from_slice(&[0x0F, 20, 0]); // 20 events with no further step
    b.extend_from_slice(&[0x4F, 20, 0]); // 20 events 4 µs later
    b.extend_from_slice(&((9u16 << 5) | 0x1F).to_le_bytes());
    b.extend_from_slice(&(n as u16).to_le_bytes()); // y = 9 for all 40
    for k in 0..n / 4 {
        let v: Vec<u16> = (0..4)
            .map(|j| (((4 * k + j) as u16) << 1) | (j as u16 & 1))
            .collect();
        let words = [
            (v[0] << 4) | (v[1] & 0xF),
            ((v[1] >> 4) << 8) | (v[2] & 0xFF),
            ((v[2] >> 8) << 12) | (v[3] & 0xFFF),
        ];
        for w in words {
            b.extend_from_slice(&w.to_le_bytes());
        }
    }
    let out = decoded(&b);
    assert_eq!(out.len(), n);
    assert!(out.t[..20].iter().all(|&t| t == 5 + 291));
    assert!(out.t[20..].iter().all(|&t| t == 5 + 295));
    assert!(out.y.iter().all(|&y| y == 9));
    assert_eq!(out.x, (0..n as u16).collect::<Vec<_>>());
    assert_eq!(out.p, (0..n).map(|i| (i & 1) as u8).collect::<Vec<_>>());
}

/// All packed, with a partial last group of 4 (the stored padding is ignored).
#[test]
fn decodes_all_packed_with_a_partial_group() {
    let rows = [
        (1, 2, 1, 7),
        (2047, 2047, 0, 7),
        (300, 5, 1, 8),
        (4, 1000, 0, 9),
        (9, 9, 1, 9),
    ];
    let bytes = encode_with(&events(&rows), Packing::AllPacked).unwrap();
    assert_eq!(bytes.len(), 4 + 8 + 3 + 24);
    assert_eq!(decoded(&bytes), events(&rows));
}

#[test]
fn round_trips_edge_cases_in_every_packing() {
    let mut rows = Vec::new();
    // Runs of equal time stamps past both escapes, equal rows past 31, polarity runs past
    // 127, large steps of every size, and steps back.
    let mut t = 1_000i64;
    for k in 0..300u16 {
        t += [0, 1, 14, 15, 16, 255, 4096, 1 << 40][k as usize % 8];
        if k % 37 == 0 {
            t -= 5000;
        }
        rows.push((k % 7 + k / 3, 100 + k / 40, (k / 130 % 2) as u8, t));
    }
    for _ in 0..70 {
        rows.push((5, 5, 1, t));
    }
    rows.push((2047, 0, 0, i64::MAX));
    rows.push((0, 2047, 1, i64::MIN));
    rows.push((0, 0, 1, -1));
    let ev = events(&rows);
    for packing in PACKINGS {
        let bytes = encode_with(&ev, packing).unwrap();
        assert_eq!(decoded(&bytes), ev, "{packing:?}");
    }
}

#[test]
fn round_trips_an_empty_and_a_full_buffer() {
    let empty = EcfEvents::default();
    assert!(decoded(&encode(&empty).unwrap()).is_empty());
    let full = events(
        &(0..MAX_EVENTS)
            .map(|i| {
                (
                    (i % 2048) as u16,
                    (i / 2048) as u16,
                    (i % 3 == 0) as u8,
                    (i / 5) as i64,
                )
            })
            .collect::<Vec<_>>(),
    );
    for packing in PACKINGS {
        assert_eq!(decoded(&encode_with(&full, packing).unwrap()), full);
    }
    let mut over = full.clone();
    over.x.push(0);
    over.y.push(0);
    over.p.push(0);
    over.t.push(0);
    assert!(encode(&over).is_err());
}

#[test]
fn the_smallest_packing_is_chosen() {
    // Events along rows with neighbouring columns: masked x is smallest.
    let row: Vec<_> = (0..600u16).map(|i| (i, i / 200, 1, i64::from(i))).collect();
    let masked = encode(&events(&row)).unwrap();
    assert_eq!(masked[0] & 3, 0);
    // Events scattered over rows: everything packed.
    let scattered: Vec<_> = (0..600u16)
        .map(|i| {
            (
                (i * 37) % 2000,
                (i * 91) % 1500,
                (i % 2) as u8,
                i64::from(i),
            )
        })
        .collect();
    let packed = encode(&events(&scattered)).unwrap();
    assert_eq!(packed[0] & 3, 2);
    for other in [Packing::XAndPPacked, Packing::Masked] {
        assert!(encode_with(&events(&scattered), other).unwrap().len() >= packed.len());
    }
}

#[test]
fn rejects_what_it_cannot_store() {
    assert!(encode(&events(&[(2048, 0, 0, 0)])).is_err());
    assert!(encode(&events(&[(0, 0, 2, 0)])).is_err());
    let mut ragged = events(&[(0, 0, 0, 0)]);
    ragged.x.push(1);
    assert!(encode(&ragged).is_err());
}

#[test]
fn damaged_buffers_give_errors() {
    let rows: Vec<_> = (0..50u16)
        .map(|i| (i * 3, i / 4, (i % 2) as u8, i64::from(i) * 20))
        .collect();
    for packing in PACKINGS {
        let bytes = encode_with(&events(&rows), packing).unwrap();
        // Cut anywhere: an error naming where the buffer ends, never a panic.
        for cut in 0..bytes.len() {
            let err = decode(&bytes[..cut], &mut EcfEvents::default()).unwrap_err();
            assert!(
                err.message.contains("ends inside"),
                "{packing:?} cut at {cut}: {err}"
            );
        }
    }
    // Bytes after the events (a damaged count): the buffer is refused.
    let mut longer = encode(&events(&rows)).unwrap();
    longer.push(0);
    assert!(decode(&longer, &mut EcfEvents::default())
        .unwrap_err()
        .message
        .contains("follow"));
    // More events than a buffer may hold.
    let mut big = Vec::new();
    big.extend_from_slice(&(70_000u32 << 2).to_le_bytes());
    big.extend_from_slice(&[0; 16]);
    assert!(decode(&big, &mut EcfEvents::default())
        .unwrap_err()
        .message
        .contains("at most"));
    // A run longer than the events left.
    let mut run = Vec::new();
    run.extend_from_slice(&(2u32 << 2).to_le_bytes());
    run.extend_from_slice(&0u64.to_le_bytes());
    run.push(0x03);
    assert!(decode(&run, &mut EcfEvents::default())
        .unwrap_err()
        .message
        .contains("passes"));
    // A time step of more than 64 bits.
    let mut wide = Vec::new();
    wide.extend_from_slice(&(1u32 << 2).to_le_bytes());
    wide.extend_from_slice(&0u64.to_le_bytes());
    wide.extend_from_slice(&[0xF1; 17]);
    assert!(decode(&wide, &mut EcfEvents::default())
        .unwrap_err()
        .message
        .contains("64 bits"));
}

#[test]
fn records_are_the_dataset_layout_padded_to_the_chunk() {
    let ev = events(&[(3, 4, 1, 1_317_888), (5, 6, 0, 1_317_890)]);
    let recs = decode_records(&encode(&ev).unwrap(), Some(4)).unwrap();
    assert_eq!(recs.len(), 4 * RECORD_BYTES);
    assert_eq!(&recs[..8], &[3, 0, 4, 0, 1, 0, 0, 0]);
    assert_eq!(
        i64::from_le_bytes(recs[8..16].try_into().unwrap()),
        1_317_888
    );
    assert_eq!(&recs[16..22], &[5, 0, 6, 0, 0, 0]);
    assert!(recs[32..].iter().all(|&b| b == 0));
}

proptest! {
    #[test]
    fn any_events_round_trip(
        rows in prop::collection::vec(
            (0u16..=2047, 0u16..=2047, 0u8..=1, prop_oneof![0i64..40, -5i64..5, 0i64..1 << 50]),
            0..400,
        ),
        pick in 0usize..4,
    ) {
        let mut t = 0i64;
        let rows: Vec<_> = rows
            .into_iter()
            .map(|(x, y, p, dt)| {
                t = t.wrapping_add(dt);
                (x, y, p, t)
            })
            .collect();
        let ev = events(&rows);
        let bytes = encode_with(&ev, PACKINGS[pick]).unwrap();
        prop_assert_eq!(decoded(&bytes), ev);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let mut out = EcfEvents::default();
        if decode(&bytes, &mut out).is_ok() {
            prop_assert_eq!(Some(out.len()), declared_events(&bytes));
        }
    }
}
