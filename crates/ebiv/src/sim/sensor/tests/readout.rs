//! The readout, parameters and robustness.

use super::*;
use crate::error::Error;
use crate::event::EventBuffer;

fn ev(t_us: f64, x: u16, y: u16, p: u8) -> SimEvent {
    SimEvent { t_us, x, y, p }
}

#[test]
fn bandwidth_limit_drops_by_token_bucket_and_caps_the_rate() {
    // A burst of 100 events/µs for 100 µs, then 1 event/µs: limit 20 events/µs, depth 5.
    let mut events = Vec::new();
    for k in 0..10_000u32 {
        events.push(ev(
            k as f64 * 0.01,
            (k % 300) as u16,
            (k / 300) as u16,
            (k % 2) as u8,
        ));
    }
    for k in 0..200u32 {
        events.push(ev(100.0 + k as f64, 7, 7, 1));
    }
    events.reverse(); // the readout orders them itself
    let mut p = SensorParams::ideal();
    p.bandwidth_ev_per_s = Some(2e7);
    p.bandwidth_burst_events = 5.0;
    p.timestamp = TimestampMode::Truncate;
    let (out, report) = read_out(events, &p);
    assert_eq!(report.events_in, 10_200);
    assert_eq!(report.events_out as usize, out.len());
    assert_eq!(report.dropped_bandwidth + report.events_out, 10_200);
    // The burst passes 5 + 20·100 events (± rounding of the bucket), the tail all of its 200.
    let in_burst = out.t.iter().filter(|&&t| t < 100).count() as f64;
    assert!((in_burst - 2005.0).abs() <= 2.0, "{in_burst}");
    assert!(out.t.iter().filter(|&&t| t >= 100).count() >= 199);
    // The earliest events of the burst pass: the first five, at t = 0.00 … 0.04.
    assert_eq!(&out.x[..5], &[0, 1, 2, 3, 4]);
    // No window of W µs holds more than depth + rate·(W + 1) events (+1: 1 µs stamps).
    for w in [1i64, 3, 10, 50] {
        for &t0 in &out.t {
            let n = out.t.iter().filter(|&&t| t >= t0 && t < t0 + w).count() as f64;
            assert!(
                n <= 5.0 + 20.0 * (w + 1) as f64,
                "{n} events in [{t0}, {t0}+{w})"
            );
        }
    }
    assert!(out.t.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn read_out_orders_quantises_and_filters() {
    let mut p = SensorParams::ideal();
    p.refractory_us = 3.0;
    let events = vec![
        ev(10.6, 1, 1, 1),
        ev(2.5, 1, 1, 0),
        ev(11.2, 2, 1, 1),
        ev(4.9, 1, 1, 1), // 2.4 µs after the event at 2.5: refractory
        ev(f64::NAN, 0, 0, 1),
        ev(7.0, 0, 0, 3),
    ];
    let (out, report) = read_out(events.clone(), &p);
    assert_eq!(out.t, vec![3, 11, 11]); // 2.5 rounds half away from zero
    assert_eq!(out.x, vec![1, 1, 2]);
    assert_eq!(out.p, vec![0, 1, 1]);
    assert_eq!(report.dropped_refractory, 1);
    assert_eq!(report.dropped_invalid, 2);
    p.timestamp = TimestampMode::Truncate;
    let (out, _) = read_out(events, &p);
    assert_eq!(out.t, vec![2, 10, 11]);
}

/// The readout as its documentation defines it, one step at a time: drop invalid events,
/// sort by (time, row, column, polarity), the refractory filter, the token bucket, stamps.
fn reference_read_out(events: &[SimEvent], p: &SensorParams) -> (EventBuffer, ReadoutReport) {
    let mut kept: Vec<SimEvent> = events
        .iter()
        .copied()
        .filter(|e| e.t_us.is_finite() && e.p <= 1)
        .collect();
    let mut report = ReadoutReport {
        events_in: events.len() as u64,
        dropped_invalid: (events.len() - kept.len()) as u64,
        ..ReadoutReport::default()
    };
    kept.sort_by(|a, b| {
        a.t_us
            .total_cmp(&b.t_us)
            .then((a.y, a.x, a.p).cmp(&(b.y, b.x, b.p)))
    });
    let mut last = std::collections::HashMap::new();
    let before = kept.len();
    kept.retain(|e| {
        let slot = last.entry((e.x, e.y)).or_insert(f64::NEG_INFINITY);
        let keep = e.t_us - *slot >= p.refractory_us - 1e-6;
        if keep {
            *slot = e.t_us;
        }
        keep
    });
    report.dropped_refractory = (before - kept.len()) as u64;
    let rate = p.bandwidth_ev_per_s.filter(|&r| r > 0.0);
    if let (Some(rate), Some(first)) = (rate, kept.first().copied()) {
        let rate = rate * 1e-6; // per µs
        let (mut tokens, mut t_last) = (p.bandwidth_burst_events, first.t_us);
        let before = kept.len();
        kept.retain(|e| {
            tokens = (tokens + (e.t_us - t_last) * rate).min(p.bandwidth_burst_events);
            t_last = e.t_us;
            let pass = tokens >= 1.0 - 1e-9;
            if pass {
                tokens -= 1.0;
            }
            pass
        });
        report.dropped_bandwidth = (before - kept.len()) as u64;
    }
    report.events_out = kept.len() as u64;
    let stamp = |t: f64| match p.timestamp {
        TimestampMode::Round => t.round() as i64,
        TimestampMode::Truncate => t.floor() as i64,
    };
    let buffer = EventBuffer {
        t: kept.iter().map(|e| stamp(e.t_us)).collect(),
        x: kept.iter().map(|e| e.x).collect(),
        y: kept.iter().map(|e| e.y).collect(),
        p: kept.iter().map(|e| e.p).collect(),
        triggers: Vec::new(),
    };
    (buffer, report)
}

/// The parallel readout of several parts (bucket sort over the parts, one filter pass, the
/// arrays filled in parallel) against the step-by-step definition, on events with ties in
/// time, invalid ones, refractory collisions and a saturated bandwidth, cut into parts in
/// several ways and in every thread count from 1 to 4.
#[test]
fn read_out_of_parts_matches_the_step_by_step_definition() {
    let mut next = crate::test_rng::xorshift(0x5EED_0EAD);
    let mut events = Vec::new();
    for k in 0..40_000u64 {
        let r = next();
        // Times on a coarse grid (many exact ties) or anywhere, a few invalid.
        let t_us = match r % 50 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2..=24 => ((r >> 8) % 5_000) as f64 * 0.25,
            _ => ((r >> 8) % 1_250_000) as f64 * 1e-3 - 7.0,
        };
        let p = if k % 997 == 0 {
            2
        } else {
            ((r >> 40) & 1) as u8
        };
        events.push(ev(
            t_us,
            ((r >> 20) % 40) as u16,
            ((r >> 30) % 30) as u16,
            p,
        ));
    }
    for (refractory, bandwidth, timestamp) in [
        (0.0, None, TimestampMode::Round),
        (3.0, None, TimestampMode::Truncate),
        (1.0, Some(2e7), TimestampMode::Round),
        (0.5, Some(4e8), TimestampMode::Truncate),
    ] {
        let mut p = SensorParams::ideal();
        p.refractory_us = refractory;
        p.bandwidth_ev_per_s = bandwidth;
        p.bandwidth_burst_events = 8.0;
        p.timestamp = timestamp;
        let (want, want_report) = reference_read_out(&events, &p);
        assert!(want_report.dropped_invalid > 0 && want.len() > 10_000);
        if refractory > 0.0 {
            assert!(want_report.dropped_refractory > 0, "{want_report:?}");
        }
        if bandwidth == Some(2e7) {
            assert!(want_report.dropped_bandwidth > 0, "{want_report:?}");
        }
        assert_parts_match_reference(
            &events,
            &p,
            &[vec![], vec![1, 2, 20_000], vec![0, 0, 5_000, 5_001, 39_999]],
        );
    }
}

/// [`read_out_parts`] of `events` cut at each of `cut_sets` (and the parts reversed) against
/// [`reference_read_out`].
fn assert_parts_match_reference(events: &[SimEvent], p: &SensorParams, cut_sets: &[Vec<usize>]) {
    let (want, want_report) = reference_read_out(events, p);
    for cuts in cut_sets {
        let mut parts = Vec::new();
        let mut from = 0;
        for &c in cuts.iter().chain([events.len()].iter()) {
            parts.push(&events[from..c]);
            from = c;
        }
        parts.reverse(); // any order of parts
        let (got, report) = read_out_parts(&parts, p);
        assert_eq!(report, want_report, "cuts {cuts:?}");
        assert!(got == want, "cuts {cuts:?}: buffers differ");
    }
}

/// The same on the edges: few events (one sort instead of buckets), every event at one
/// time, the extreme finite times with both zeros, a subnormal spread, pixels beyond the
/// dense table (a map of last times), and a bandwidth of 0 (no limit).
#[test]
fn read_out_of_parts_matches_the_definition_on_edge_cases() {
    let mut p = SensorParams::ideal();
    p.refractory_us = 2.0;
    let cuts = [vec![], vec![0, 1], vec![3, 3, 200]];
    let few: Vec<SimEvent> = (0..400u16)
        .map(|k| ev(f64::from(k % 37) * 0.7, k % 5, k % 3, (k % 2) as u8))
        .collect();
    assert_parts_match_reference(&few, &p, &cuts);
    let same_time: Vec<SimEvent> = (0..3_000u16)
        .map(|k| ev(5.0, k % 61, k / 61, (k % 2) as u8))
        .collect();
    assert_parts_match_reference(&same_time, &p, &cuts);
    let mut extremes = Vec::new();
    for k in 0..2_000u16 {
        let t = [f64::MAX, -f64::MAX, 0.0, -0.0, 1e-310, 5e-324][k as usize % 6];
        extremes.push(ev(t, k % 7, 65_535 - k % 3, 1));
    }
    extremes.push(ev(3.0, 65_535, 65_535, 0));
    extremes.push(ev(4.0, 65_535, 65_535, 1)); // within 2 µs: refractory, in the map
    p.bandwidth_ev_per_s = Some(0.0);
    let (_, report) = reference_read_out(&extremes, &p);
    assert!(report.dropped_refractory > 0, "{report:?}");
    assert_parts_match_reference(&extremes, &p, &cuts);
    let subnormal: Vec<SimEvent> = (0..2_000u16)
        .map(|k| ev(f64::from(k % 9) * 5e-324, k % 11, k % 13, 0))
        .collect();
    assert_parts_match_reference(&subnormal, &p, &cuts);
}

#[test]
fn presets_validate_and_round_trip_through_serde() {
    for name in SensorParams::PRESETS {
        let p = SensorParams::preset(name).expect("known preset");
        p.validate().expect("presets are valid");
        let text = serde_json::to_string(&p).expect("serialise");
        let back: SensorParams = serde_json::from_str(&text).expect("deserialise");
        assert_eq!(back, p, "{name}");
    }
    assert!(SensorParams::preset("gen5").is_none());
    assert_eq!(SensorParams::gen4().threshold_on, 1.25f64.ln());
    // A partial table takes the gen4 values; unknown keys are rejected.
    let partial: SensorParams =
        serde_json::from_str(r#"{"threshold_on": 0.3, "timestamp": "round"}"#).expect("partial");
    assert_eq!(partial.threshold_on, 0.3);
    assert_eq!(partial.cutoff_hz, SensorParams::gen4().cutoff_hz);
    assert_eq!(partial.bandwidth_ev_per_s, None);
    assert!(serde_json::from_str::<SensorParams>(r#"{"threshold": 0.3}"#).is_err());
}

#[test]
fn validate_names_the_offending_key() {
    type Spoil = Box<dyn Fn(&mut SensorParams)>;
    let cases: Vec<(&str, Spoil)> = vec![
        ("threshold_on", Box::new(|p| p.threshold_on = 0.0)),
        ("threshold_off", Box::new(|p| p.threshold_off = f64::NAN)),
        ("threshold_sigma", Box::new(|p| p.threshold_sigma = -0.1)),
        (
            "linlog_threshold",
            Box::new(|p| p.linlog_threshold = f64::INFINITY),
        ),
        (
            "log_eps",
            Box::new(|p| {
                p.linlog_threshold = 0.0;
                p.log_eps = 0.0
            }),
        ),
        ("cutoff_hz", Box::new(|p| p.cutoff_hz = -1.0)),
        (
            "cutoff_reference_irradiance",
            Box::new(|p| p.cutoff_reference_irradiance = -1.0),
        ),
        (
            "cutoff_dark_irradiance",
            Box::new(|p| p.cutoff_dark_irradiance = f64::NAN),
        ),
        ("latency_us", Box::new(|p| p.latency_us = -5.0)),
        ("jitter_us", Box::new(|p| p.jitter_us = f64::NAN)),
        ("refractory_us", Box::new(|p| p.refractory_us = -1.0)),
        ("leak_rate_hz", Box::new(|p| p.leak_rate_hz = 1e9)),
        (
            "shot_noise_rate_hz",
            Box::new(|p| p.shot_noise_rate_hz = -1.0),
        ),
        (
            "noise_rate_cov_decades",
            Box::new(|p| p.noise_rate_cov_decades = 10.0),
        ),
        (
            "hot_pixel_fraction",
            Box::new(|p| p.hot_pixel_fraction = 1.5),
        ),
        (
            "hot_pixel_rate_hz",
            Box::new(|p| p.hot_pixel_rate_hz = f64::NAN),
        ),
        (
            "bandwidth_ev_per_s",
            Box::new(|p| p.bandwidth_ev_per_s = Some(0.0)),
        ),
        (
            "bandwidth_burst_events",
            Box::new(|p| p.bandwidth_burst_events = 0.5),
        ),
    ];
    for (key, spoil) in cases {
        let mut p = SensorParams::gen4();
        spoil(&mut p);
        match p.validate() {
            Err(Error::Parameter { name, .. }) => assert_eq!(name, key),
            other => panic!("{key}: {other:?}"),
        }
    }
    let g = Geometry::new(10, 10);
    assert!(SensorBand::try_new(g, 0..11, &SensorParams::gen4(), 1).is_err());
    assert!(SensorBand::try_new(Geometry::new(70_000, 1), 0..1, &SensorParams::gen4(), 1).is_err());
    assert!(SensorBand::try_new(g, 3..7, &SensorParams::gen4(), 1).is_ok());
}

#[test]
fn garbage_parameters_and_inputs_do_not_panic() {
    let garbage = [f64::NAN, f64::INFINITY, -1e300, 0.0, 1e300];
    for (k, &v) in garbage.iter().enumerate() {
        let p = SensorParams {
            threshold_on: v,
            threshold_off: v,
            threshold_sigma: v,
            linlog_threshold: v,
            log_eps: v,
            cutoff_hz: v,
            cutoff_reference_irradiance: v,
            cutoff_dark_irradiance: v,
            latency_us: v,
            jitter_us: v,
            refractory_us: v,
            leak_rate_hz: if v > 1e6 { 1e6 } else { v },
            shot_noise_rate_hz: v.min(1e6),
            noise_rate_cov_decades: v,
            hot_pixel_fraction: v,
            hot_pixel_rate_hz: v.min(1e6),
            bandwidth_ev_per_s: Some(v),
            bandwidth_burst_events: v,
            timestamp: TimestampMode::Round,
        };
        let g = Geometry::new(6, 5);
        let mut band = SensorBand::new(g, 2..9, &p, k as u64);
        band.adapt(f64::NAN, |x, _| {
            [f32::NAN, -1.0, f32::INFINITY, 0.0, 3.0][x as usize % 5]
        });
        let mut out = Vec::new();
        let inputs = [f32::NAN, f32::INFINITY, -3.0, 0.0, 1e-30, 5.0];
        for (s, t) in [1.0, f64::NAN, -5.0, 2.0, 2.0, f64::INFINITY, 3.0]
            .into_iter()
            .enumerate()
        {
            let changed: Vec<(u32, f32)> =
                (0..40).map(|i| (i, inputs[(i as usize + s) % 6])).collect();
            band.advance(t, &changed, &mut out);
        }
        band.noise(0.0, 1e-3, &mut out);
        band.noise(f64::NAN, 1.0, &mut out);
        let _ = read_out(out, &p);
    }
}

/// The streaming readout against the step-by-step definition: random events (ties, invalid
/// ones, a few outside the sensor, refractory collisions, a bucket that runs dry) handed in
/// over random windows in several parts each, many events handed in windows before the one
/// that reads them out; with every combination of filters.
#[test]
fn streaming_readout_matches_the_step_by_step_definition() {
    let g = crate::event::Geometry::new(40, 30);
    let mut next = crate::test_rng::xorshift(0x57AE_A111);
    for trial in 0..24 {
        let n = 200 + (next() % 6_000) as usize;
        let mut events = Vec::with_capacity(n);
        let mut outside = 0;
        for _ in 0..n {
            let r = next();
            let t_us = match r % 40 {
                0 => f64::NAN,
                1 => f64::NEG_INFINITY,
                2..=20 => ((r >> 8) % 400) as f64 * 0.25,
                _ => ((r >> 8) % 100_000) as f64 * 1e-3 - 3.0,
            };
            let (mut x, mut y) = (((r >> 20) % 40) as u16, ((r >> 30) % 30) as u16);
            if r % 97 == 0 {
                (x, y) = (40 + x, 30 + y);
                outside += 1;
            }
            events.push(ev(
                t_us,
                x,
                y,
                ((r >> 40) & 1) as u8 + u8::from(r % 89 == 0),
            ));
        }
        let mut p = SensorParams::ideal();
        p.refractory_us = [0.0, 0.5, 2.0][trial % 3];
        p.bandwidth_ev_per_s = [None, Some(2e8), Some(4e7)][(trial / 3) % 3];
        p.bandwidth_burst_events = 4.0;
        p.timestamp = [TimestampMode::Round, TimestampMode::Truncate][(trial / 9) % 2];

        // Windows: cutoffs rising through the events' times; each event is handed in with
        // the window that reads it out or, for a third of them, with an earlier one.
        let mut cutoffs: Vec<f64> = (0..1 + next() % 12)
            .map(|_| (next() % 110_000) as f64 * 1e-3 - 4.0)
            .collect();
        cutoffs.sort_by(f64::total_cmp);
        let window_of = |t: f64| cutoffs.iter().position(|&c| t < c).unwrap_or(cutoffs.len());
        let mut windows: Vec<Vec<Vec<SimEvent>>> = vec![vec![Vec::new(); 3]; cutoffs.len() + 1];
        for e in &events {
            let r = next();
            let mut w = window_of(e.t_us).min(cutoffs.len());
            if r % 3 == 0 {
                w = (r >> 8) as usize % (w + 1);
            }
            windows[w][(r >> 16) as usize % 3].push(*e);
        }
        let mut stream = StreamingReadout::new(&p, g);
        for (w, parts) in windows.iter_mut().enumerate() {
            match cutoffs.get(w) {
                Some(&cutoff) => stream.read_until(parts, cutoff),
                None => stream.read_until(parts, f64::INFINITY),
            }
            assert!(
                parts.iter().all(Vec::is_empty),
                "trial {trial}: parts not emptied"
            );
        }
        assert_eq!(stream.late_events(), 0, "trial {trial}");
        let (got, report) = stream.finish(&mut []);

        let inside: Vec<SimEvent> = events
            .iter()
            .copied()
            .filter(|e| e.x < 40 && e.y < 30)
            .collect();
        let (want, mut want_report) = reference_read_out(&inside, &p);
        want_report.events_in += outside;
        want_report.dropped_invalid += outside;
        assert_eq!(report, want_report, "trial {trial}: {p:?}");
        assert!(got == want, "trial {trial}: buffers differ");
    }
}

/// The events handed in, read out and dropped as invalid, from a report.
fn stream_late(report: &ReadoutReport) -> (u64, u64, u64) {
    (report.events_in, report.events_out, report.dropped_invalid)
}

/// An event handed in after a cutoff above its time is read out at that cutoff, and
/// counted; reading to the same or an earlier cutoff again changes nothing, and a cutoff
/// that is not finite only hands the events in.
#[test]
fn streaming_readout_reads_a_late_event_at_the_last_cutoff() {
    let mut p = SensorParams::ideal();
    p.timestamp = TimestampMode::Truncate;
    let mut stream = StreamingReadout::new(&p, crate::event::Geometry::new(4, 4));
    stream.read_until(&mut [vec![ev(3.5, 1, 1, 1), ev(12.0, 2, 2, 0)]], 10.0);
    stream.read_until(&mut [vec![ev(7.25, 3, 3, 1)]], 10.0);
    stream.read_until(&mut [], 5.0);
    // Not finite: the events are handed in, nothing more is read out.
    stream.read_until(&mut [vec![ev(11.0, 0, 0, 0)]], f64::INFINITY);
    stream.read_until(&mut [vec![ev(10.5, 0, 1, 1)]], f64::NAN);
    assert_eq!(stream.late_events(), 1);
    let (out, report) = stream.finish(&mut [vec![ev(9.0, 1, 0, 0), ev(30.0, 1, 2, 1)]]);
    assert_eq!(out.t, vec![3, 10, 10, 10, 11, 12, 30]);
    assert_eq!(out.x, vec![1, 1, 3, 0, 0, 2, 1]);
    assert_eq!(stream_late(&report), (7, 7, 0));
    let mut stream = StreamingReadout::new(&p, crate::event::Geometry::new(4, 4));
    stream.read_until(&mut [vec![ev(1.0, 1, 1, 1)]], f64::NEG_INFINITY);
    let (out, _) = stream.finish(&mut []);
    assert_eq!(out.t, vec![1]);
}
