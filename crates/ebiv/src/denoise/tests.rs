//! The filters on hand-made events: kept and removed exactly as specified, at the exact
//! boundaries, on the sensor's edge, empty, and split into batches anywhere.

use super::*;

fn events(list: &[(i64, u16, u16)]) -> EventBuffer {
    let mut b = EventBuffer::new();
    for &(t, x, y) in list {
        b.push(t, x, y, 1);
    }
    b
}

fn settings(filters: DenoiseFilters) -> DenoiseSettings {
    DenoiseSettings {
        filters,
        correlation_dt_us: 1000,
        refractory_us: 500,
        hot_pixel_factor: 5.0,
        hot_pixel_learn_us: 10_000,
    }
}

const CORRELATION: DenoiseFilters = DenoiseFilters {
    hot_pixels: false,
    refractory: false,
    correlation: true,
};
const REFRACTORY: DenoiseFilters = DenoiseFilters {
    hot_pixels: false,
    refractory: true,
    correlation: false,
};

fn kept(filters: DenoiseFilters, g: Geometry, list: &[(i64, u16, u16)]) -> Vec<(i64, u16, u16)> {
    let mut d = Denoiser::new(&settings(filters), g, None).unwrap();
    let mut b = events(list);
    d.apply(&mut b);
    b.iter().map(|e| (e.t, e.x, e.y)).collect()
}

#[test]
fn correlation_keeps_events_with_a_neighbour_at_most_dt_before() {
    let g = Geometry::new(10, 10);
    // (5,5) at 0 supports (6,6) at exactly Δt = 1000 (kept) and (4,5) at 1001 is too late
    // for (5,5) but (6,6) at 1000 supports it.
    let out = kept(
        CORRELATION,
        g,
        &[(0, 5, 5), (1000, 6, 6), (1001, 4, 5), (2002, 4, 5)],
    );
    // (5,5) has no earlier neighbour; (6,6) is supported by (5,5) at exactly Δt; (4,5) at
    // 1001 is 1 µs too late for (5,5) and not a neighbour of (6,6) (two columns apart);
    // (4,5) again at 2002 has only itself.
    assert_eq!(out, vec![(1000, 6, 6)]);
    // One µs earlier it is supported.
    let out = kept(CORRELATION, g, &[(0, 5, 5), (1000, 4, 5)]);
    assert_eq!(out, vec![(1000, 4, 5)]);
    let out = kept(CORRELATION, g, &[(0, 5, 5), (1001, 4, 5)]);
    assert!(out.is_empty(), "{out:?}");
}

#[test]
fn correlation_ignores_the_pixel_itself_and_remembers_removed_events() {
    let g = Geometry::new(10, 10);
    // Repeated events of one pixel never support each other.
    let out = kept(CORRELATION, g, &[(0, 3, 3), (10, 3, 3), (20, 3, 3)]);
    assert!(out.is_empty());
    // A removed event still supports its neighbour; pixels two apart do not.
    let out = kept(CORRELATION, g, &[(0, 3, 3), (10, 4, 4), (20, 6, 4)]);
    assert_eq!(out, vec![(10, 4, 4)]);
    // Every one of the 8 neighbours supports, nothing further away does.
    for (dx, dy) in [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ] {
        let (x, y) = ((5 + dx) as u16, (5 + dy) as u16);
        assert_eq!(
            kept(CORRELATION, g, &[(0, x, y), (5, 5, 5)]),
            vec![(5, 5, 5)]
        );
    }
    for (x, y) in [(3, 5), (7, 5), (5, 3), (5, 7), (3, 3)] {
        assert!(kept(CORRELATION, g, &[(0, x, y), (5, 5, 5)]).is_empty());
    }
}

#[test]
fn correlation_on_the_sensor_edge_and_corners() {
    let g = Geometry::new(4, 3);
    // Corners: (0,0) supported by (1,1); (3,2) by (2,1); (3,0) by (2,1); (0,1) on the left
    // edge by (0,0).
    let out = kept(
        CORRELATION,
        g,
        &[
            (0, 1, 1),
            (5, 0, 0),
            (10, 2, 1),
            (15, 3, 2),
            (20, 3, 0),
            (25, 0, 1),
        ],
    );
    assert_eq!(
        out,
        vec![(5, 0, 0), (10, 2, 1), (15, 3, 2), (20, 3, 0), (25, 0, 1)]
    );
    // (0,1) after (3,0): the previous row's last pixel is not its neighbour.
    let out = kept(CORRELATION, g, &[(0, 3, 0), (5, 0, 1)]);
    assert!(out.is_empty());
    // A one-pixel-wide sensor.
    let out = kept(CORRELATION, Geometry::new(1, 3), &[(0, 0, 0), (5, 0, 1)]);
    assert_eq!(out, vec![(5, 0, 1)]);
}

#[test]
fn refractory_removes_events_within_the_period_of_the_last_kept_one() {
    let g = Geometry::new(4, 4);
    // Period 500: 0 kept, 499 removed, 500 kept (exactly the period), 700 removed (200
    // after the kept 500, although 200 after the removed 499+…), 1000 kept.
    let out = kept(
        REFRACTORY,
        g,
        &[
            (0, 1, 1),
            (499, 1, 1),
            (500, 1, 1),
            (700, 1, 1),
            (1000, 1, 1),
        ],
    );
    assert_eq!(out, vec![(0, 1, 1), (500, 1, 1), (1000, 1, 1)]);
    // The period counts from the last *kept* event: 0 kept, 300 and 600 removed? 600 is 600
    // after 0, kept; 900 removed (300 after 600).
    let out = kept(
        REFRACTORY,
        g,
        &[(0, 2, 2), (300, 2, 2), (600, 2, 2), (900, 2, 2)],
    );
    assert_eq!(out, vec![(0, 2, 2), (600, 2, 2)]);
    // Pixels are independent, corners included; polarity plays no part.
    let out = kept(REFRACTORY, g, &[(0, 0, 0), (1, 3, 3), (2, 0, 3), (3, 3, 0)]);
    assert_eq!(out.len(), 4);
    // A time regression within a pixel is removed.
    let out = kept(REFRACTORY, g, &[(1000, 1, 2), (900, 1, 2)]);
    assert_eq!(out, vec![(1000, 1, 2)]);
}

/// Events in `0..learn` with `counts[y][x]` events at each pixel, in time order.
fn from_counts(counts: &[[u32; 12]; 12], learn: i64) -> Vec<(i64, u16, u16)> {
    let mut list = Vec::new();
    for (y, row) in counts.iter().enumerate() {
        for (x, &n) in row.iter().enumerate() {
            for k in 0..n as i64 {
                list.push((k * learn / n as i64, x as u16, y as u16));
            }
        }
    }
    list.sort();
    list
}

#[test]
fn hot_pixels_are_learnt_from_the_leading_interval_against_their_neighbours() {
    let g = Geometry::new(12, 12);
    let mut counts = [[2u32; 12]; 12];
    counts[11][11] = 60; // a corner: 3 neighbours, median 2
    counts[4][4] = 50; // two hot neighbours: the median of 8 ignores the other
    counts[4][5] = 50;
    counts[1][1] = 10; // exactly 5 × the median 2: not above it
    counts[1][8] = 11; // just above
    counts[8][1] = 9; // above 5 × 2 but fewer than MIN_HOT_PIXEL_EVENTS
    for row in counts.iter_mut().skip(6).take(3) {
        // A busy trail across the sensor, as particles moving along x leave.
        row.iter_mut().for_each(|c| *c = 40);
    }
    let list = from_counts(&counts, 10_000);
    // Events after the learning interval do not count: pixel (0,11) fires 100 times later.
    let late: Vec<(i64, u16, u16)> = (0..100).map(|k| (10_000 + k, 0, 11)).collect();
    let mut learner = HotPixelLearner::new(g, 10_000);
    assert!(learner.add(&events(&list)));
    assert!(!learner.add(&events(&late)));
    let hot = learner.finish(5.0);
    assert_eq!(hot.pixels(), vec![(8, 1), (4, 4), (5, 4), (11, 11)]);
    let mut d = Denoiser::new(
        &settings(DenoiseFilters {
            hot_pixels: true,
            ..DenoiseFilters::default()
        }),
        g,
        Some(hot),
    )
    .unwrap();
    let mut b = events(&list);
    d.apply(&mut b);
    assert_eq!(b.len(), list.len() - 11 - 50 - 50 - 60);
    assert!(b.iter().all(|e| (e.x, e.y) != (11, 11)));
    assert_eq!(d.report().removed_hot_pixels, Some(171));
    assert_eq!(d.report().hot_pixels, Some(4));
}

#[test]
fn a_hot_pixel_needs_a_minimum_count_and_the_learner_handles_nothing() {
    let g = Geometry::new(8, 8);
    // One pixel with 9 events among silent ones: far above its neighbours, but too few.
    let list: Vec<(i64, u16, u16)> = (0..9).map(|k| (k, 0, 0)).collect();
    let mut learner = HotPixelLearner::new(g, 1000);
    learner.add(&events(&list));
    assert_eq!(learner.finish(1.5).count(), 0);
    let learner = HotPixelLearner::new(g, 1000);
    assert_eq!(learner.finish(10.0).count(), 0);
}

#[test]
fn empty_input_and_counts() {
    let g = Geometry::new(4, 4);
    let mut d = Denoiser::new(
        &settings(DenoiseFilters::ALL),
        g,
        Some(HotPixelFilter::from_pixels(g, &[])),
    )
    .unwrap();
    let mut b = EventBuffer::new();
    b.triggers.push(crate::event::Trigger {
        t: 5,
        channel: 0,
        value: 1,
    });
    d.apply(&mut b);
    assert!(b.is_empty());
    assert_eq!(b.triggers.len(), 1, "triggers pass");
    let r = d.report();
    assert_eq!((r.events_in, r.events_out), (0, 0));
    assert_eq!(r.removed_correlation, Some(0));
}

/// A pseudo-random stream with clusters (signal) and isolated events (noise).
fn stream() -> EventBuffer {
    let mut next = crate::test_rng::xorshift(7);
    let mut uniform = move || (next() >> 11) as f64 / (1u64 << 53) as f64;
    let mut b = EventBuffer::new();
    let mut t = 0i64;
    for _ in 0..5000 {
        t += (uniform() * 40.0) as i64;
        let x = (uniform() * 32.0) as u16;
        let y = (uniform() * 24.0) as u16;
        b.push(t, x.min(31), y.min(23), (uniform() < 0.5) as u8);
        if uniform() < 0.3 {
            b.push(t + 3, (x + 1).min(31), y.min(23), 1);
        }
        if uniform() < 0.05 {
            b.push(t + 1, 31, 23, 1); // a busy corner pixel
        }
    }
    b
}

#[test]
fn batches_split_anywhere_give_the_result_of_one_batch() {
    let g = Geometry::new(32, 24);
    let all = stream();
    let s = settings(DenoiseFilters::ALL);
    let learn = || {
        let mut l = HotPixelLearner::new(g, s.hot_pixel_learn_us);
        l.add(&all);
        l.finish(s.hot_pixel_factor)
    };
    let mut whole = Denoiser::new(&s, g, Some(learn())).unwrap();
    let mut one = all.clone();
    whole.apply(&mut one);
    assert!(one.len() < all.len() && !one.is_empty());
    let r = whole.report();
    assert!(r.removed_correlation.unwrap() > 0 && r.removed_refractory.unwrap() > 0);
    for cuts in [
        vec![1],
        vec![0, 7, 7, 1000],
        vec![2500, 2501, 4000],
        (1..all.len()).step_by(97).collect(),
    ] {
        let mut d = Denoiser::new(&s, g, Some(learn())).unwrap();
        let mut out = EventBuffer::new();
        let mut start = 0;
        for &cut in cuts.iter().chain(std::iter::once(&all.len())) {
            let cut = cut.clamp(start, all.len());
            let mut part = EventBuffer::new();
            for i in start..cut {
                part.push(all.t[i], all.x[i], all.y[i], all.p[i]);
            }
            d.apply(&mut part);
            out.extend_from(&part);
            start = cut;
        }
        assert_eq!(out.t, one.t);
        assert_eq!(out.x, one.x);
        assert_eq!(d.report(), whole.report());
    }
}

#[test]
fn settings_are_checked_and_named() {
    assert_eq!(
        DenoiseFilters::parse("correlation, hot-pixels").unwrap(),
        DenoiseFilters {
            hot_pixels: true,
            refractory: false,
            correlation: true
        }
    );
    assert_eq!(DenoiseFilters::parse("all").unwrap(), DenoiseFilters::ALL);
    assert!(!DenoiseFilters::parse("none").unwrap().any());
    assert!(DenoiseFilters::parse("median")
        .unwrap_err()
        .contains("median"));
    assert_eq!(
        DenoiseFilters::ALL.text(),
        "hot-pixels,refractory,correlation"
    );
    let mut s = settings(DenoiseFilters::ALL);
    s.correlation_dt_us = 0;
    assert!(s.check().unwrap_err().to_string().contains("denoise-dt"));
    let mut s = settings(DenoiseFilters::ALL);
    s.hot_pixel_factor = 1.0;
    assert!(s
        .check()
        .unwrap_err()
        .to_string()
        .contains("denoise-hot-factor"));
    let huge = Geometry::new(65536, 65536);
    assert!(Denoiser::new(&settings(CORRELATION), huge, None).is_err());
    assert!(Denoiser::new(&settings(DenoiseFilters::ALL), Geometry::new(4, 4), None).is_err());
}
