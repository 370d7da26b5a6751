use super::*;

fn settings(window_px: u32, slab_us: i64) -> ActivitySettings {
    ActivitySettings { window_px, slab_us }
}

#[test]
fn counts_gaps_and_share_by_hand() {
    // 4×4 sensor. Pixel (0,0) fires at 0, 100, 400 µs; (1,0) at 50 and 1050; (3,3) at 700.
    // Events per active pixel: [3, 2, 1] → median 2, 90th 2 + 0.8·(3 − 2) = 2.8.
    // Gaps: [100, 300, 1000] → 10th 100 + 0.2·200 = 140, median 300, 90th 300 + 0.8·700 = 860.
    // Active share 3/16.
    let mut b = EventBuffer::new();
    for (t, x, y) in [
        (0, 0, 0),
        (50, 1, 0),
        (100, 0, 0),
        (400, 0, 0),
        (700, 3, 3),
        (1050, 1, 0),
    ] {
        b.push(t, x, y, 1);
    }
    let r = Activity::measure(&b, Geometry::new(4, 4), 0, None, settings(2, 500)).unwrap();
    assert_eq!((r.events, r.pixels, r.active_pixels), (6, 16, 3));
    assert_eq!(r.active_share, 3.0 / 16.0);
    let e = r.events_per_active_pixel.unwrap();
    assert_eq!(e[0], 2.0);
    assert!((e[1] - 2.8).abs() < 1e-12);
    assert_eq!(r.gaps, 3);
    let g = r.gap_us.unwrap();
    assert!((g[0] - 140.0).abs() < 1e-9 && g[1] == 300.0 && (g[2] - 860.0).abs() < 1e-9);
    // Slabs of 500 µs up to the last event (1050 + 1): two whole slabs, [0, 500) and
    // [500, 1000); four 2×2 windows each. Slab 0: window (0,0) holds 4 events, the others 0;
    // slab 1: window (1,1) holds 1. Cells [4, 0, 0, 0, 0, 0, 0, 1]: sorted 0×6, 1, 4;
    // 5th percentile 0, median 0, 95th at rank 6.65: 1 + 0.65·3 = 2.95.
    assert_eq!((r.slabs, r.window_cells), (2, 8));
    let w = r.window_events.unwrap();
    assert_eq!((w[0], w[1]), (0.0, 0.0));
    assert!((w[2] - 2.95).abs() < 1e-9, "{w:?}");
    assert_eq!(r.trails, 0);
    assert!(r.trail_width_px.is_none());
}

#[test]
fn interval_end_empty_slabs_and_out_of_order_events() {
    // 8×2 sensor with 2 px windows (four windows), 1 ms slabs over [0, 4 ms): slab 1 is empty.
    let mut b = EventBuffer::new();
    b.push(100, 0, 0, 1);
    b.push(3_500, 7, 1, 1);
    b.push(3_400, 7, 1, 1); // earlier than its pixel's previous event: a gap of 0
    b.push(2_200, 0, 0, 1); // slab 2 is still open
    b.push(250, 0, 0, 1); // slab 0 was closed: late
    b.push(9_000, 0, 0, 1); // beyond the interval: ignored
    let r = Activity::measure(&b, Geometry::new(8, 2), 0, Some(4_000), settings(2, 1_000)).unwrap();
    assert_eq!(r.events, 5);
    assert_eq!(r.late_events, 1);
    assert_eq!(r.slabs, 4);
    assert_eq!(r.window_cells, 16);
    // Cells: slab 0 one event (the late one is not counted), slab 2 one, slab 3 two.
    let w = r.window_events.unwrap();
    assert_eq!(w[1], 0.0);
    // Gaps: pixel (7,1): 0; pixel (0,0): 2100, then |250 − 2200| clamped to 0.
    assert_eq!(r.gaps, 3);
    assert_eq!(r.gap_us.unwrap()[1], 0.0);
}

#[test]
fn trail_width_over_slabs() {
    // Two 1 ms slabs on a 30×10 sensor: a 3×12 band in the first, a 2×10 band in the second.
    let mut b = EventBuffer::new();
    for x in 2..14u16 {
        for y in 2..5u16 {
            b.push(100 + x as i64, x, y, 1);
        }
    }
    for x in 5..15u16 {
        for y in 6..8u16 {
            b.push(1_100 + x as i64, x, y, 1);
        }
    }
    let r = Activity::measure(
        &b,
        Geometry::new(30, 10),
        0,
        Some(2_000),
        settings(10, 1_000),
    )
    .unwrap();
    assert_eq!(r.trails, 2);
    let w = r.trail_width_px.unwrap();
    assert!((w[1] - 2.5).abs() < 1e-9, "{w:?}");
}

#[test]
fn rejects_bad_settings_and_pixels_outside() {
    let g = Geometry::new(4, 4);
    assert!(Activity::new(g, 0, None, settings(0, 10)).is_err());
    assert!(Activity::new(g, 0, None, settings(4, 0)).is_err());
    let mut b = EventBuffer::new();
    b.push(0, 4, 0, 1);
    assert!(Activity::measure(&b, g, 0, None, settings(2, 10)).is_err());
    let r = Activity::measure(&EventBuffer::new(), g, 0, None, settings(2, 10)).unwrap();
    assert_eq!((r.events, r.slabs, r.active_pixels), (0, 0, 0));
    assert!(r.events_per_active_pixel.is_none() && r.gap_us.is_none() && r.window_events.is_none());
}

#[test]
fn long_gaps_keep_ten_significant_bits() {
    for gap in [0, 1, 999, EXACT_GAP_US - 1] {
        assert_eq!(gap_value(gap_key(gap)), gap as f64);
    }
    for gap in [EXACT_GAP_US, 3_000_001, 1 << 40] {
        let v = gap_value(gap_key(gap));
        assert!(
            v <= gap as f64 && (gap as f64 - v) / (gap as f64) < 1.0 / 1024.0,
            "{gap} {v}"
        );
    }
}
