//! Particle tracking against the simulator's particle paths, and its streaming, binning and
//! settings.

use ebiv::export::TrackTable;
use ebiv::sim::scenario::Scenario;
use ebiv::track::bin::{bin_tracks, BinParams};
use ebiv::track::score::{score_tracks, ScoreOptions};
use ebiv::track::{track_events, Track, TrackParams, Tracker};
use ebiv::{EventBuffer, Geometry};

/// The vortex example on a smaller sensor (the vortex scaled to it), 16 ms.
fn vortex(seed: u64, density: f64) -> (Scenario, ebiv::sim::simulation::SimOutput) {
    let text = Scenario::example_text("vortex")
        .unwrap()
        .replace("width = 640", "width = 256")
        .replace("height = 480", "height = 192")
        .replace("centre = [319.5, 239.5]", "centre = [127.5, 95.5]")
        .replace("circulation = 2500.0", "circulation = 1200.0")
        .replace("core_radius = 40.0", "core_radius = 25.0")
        .replace("density = 0.005", &format!("density = {density}"))
        .replace("duration = \"20ms\"", "duration = \"16ms\"");
    let mut scenario = Scenario::from_toml(&text, "test").unwrap();
    scenario.seed = seed;
    let sim = scenario.simulation().unwrap();
    let out = sim.run(Some(100.0), &|_| {}).unwrap();
    (scenario, out)
}

#[test]
fn vortex_tracks_follow_the_particles() {
    for seed in [3, 4] {
        let (scenario, out) = vortex(seed, 0.004);
        let g = Geometry {
            width: 256,
            height: 192,
        };
        let (tracks, summary) = track_events(&out.events, g, &TrackParams::default()).unwrap();
        let mut options = ScoreOptions::for_scenario(&scenario);
        options.min_visible_us = 8000;
        let score = score_tracks(&tracks, &out.tracks, &options);
        println!("seed {seed}: {summary:?}\n{}", score.summary());
        assert!(score.particles >= 20, "{score:?}");
        assert!(score.yield_fraction >= 0.8, "{score:?}");
        assert!(score.spurious_fraction <= 0.15, "{score:?}");
        assert!(score.velocity_rms <= 0.04 * score.peak_speed, "{score:?}");
        assert!(
            score.acceleration_rms <= 0.3 * score.peak_acceleration,
            "{score:?}"
        );
        assert!(score.position_rms <= 0.8, "{score:?}");
        // Stated velocity uncertainties cover the errors (not far too small).
        assert!(score.velocity_coverage_2sigma >= 0.8, "{score:?}");
    }
}

#[test]
fn a_latency_setting_removes_the_lag_it_measures() {
    let (scenario, out) = vortex(5, 0.004);
    let g = Geometry {
        width: 256,
        height: 192,
    };
    let options = ScoreOptions::for_scenario(&scenario);
    let (tracks, _) = track_events(&out.events, g, &TrackParams::default()).unwrap();
    let plain = score_tracks(&tracks, &out.tracks, &options);
    assert!(plain.lag_us > 20.0, "the sensor model lags: {plain:?}");
    let params = TrackParams {
        latency_us: plain.lag_us,
        ..TrackParams::default()
    };
    let (tracks, _) = track_events(&out.events, g, &params).unwrap();
    let corrected = score_tracks(&tracks, &out.tracks, &options);
    assert!(
        corrected.lag_us.abs() < plain.lag_us / 2.0,
        "{plain:?}\n{corrected:?}"
    );
    assert!(
        corrected.position_rms < plain.position_rms,
        "{plain:?}\n{corrected:?}"
    );
}

#[test]
fn batches_of_any_size_give_the_same_tracks() {
    let (_, out) = vortex(6, 0.003);
    let g = Geometry {
        width: 256,
        height: 192,
    };
    // A fixed slab: the automatic one holds the first 20 ms (here all) until it is chosen.
    let mut params = TrackParams::default();
    params.set("slab", "500us").unwrap();
    let (whole, _) = track_events(&out.events, g, &params).unwrap();
    assert!(!whole.is_empty());
    for size in [1000, 77_777] {
        assert_same_tracks(&in_batches(&out.events, g, &params, size), &whole);
    }
}

/// The tracks of `events` pushed to a tracker in batches of `size`.
fn in_batches(events: &EventBuffer, g: Geometry, params: &TrackParams, size: usize) -> Vec<Track> {
    let mut tracker = Tracker::new(g, params.clone()).unwrap();
    let mut tracks = Vec::new();
    for start in (0..events.len()).step_by(size) {
        let mut batch = EventBuffer::new();
        for i in start..(start + size).min(events.len()) {
            batch.push(events.t[i], events.x[i], events.y[i], events.p[i]);
        }
        tracker.push(&batch, &mut |t| tracks.push(t));
    }
    tracker.finish(&mut |t| tracks.push(t));
    tracks
}

fn assert_same_tracks(tracks: &[Track], expected: &[Track]) {
    assert_eq!(tracks.len(), expected.len());
    for (a, b) in tracks.iter().zip(expected) {
        assert_eq!(a.id, b.id);
        assert_eq!(a.samples, b.samples);
    }
}

#[test]
fn no_events_or_noise_only_give_no_tracks() {
    let g = Geometry {
        width: 64,
        height: 64,
    };
    let (tracks, _) = track_events(&EventBuffer::new(), g, &TrackParams::default()).unwrap();
    assert!(tracks.is_empty());
    // Scattered single events, 1 per 10 µs at pseudo-random pixels.
    let mut noise = EventBuffer::new();
    let mut state = 12345u64;
    for k in 0..20_000 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let (x, y) = ((state >> 33) % 64, (state >> 45) % 64);
        noise.push(k * 10, x as u16, y as u16, (state >> 60) as u8 & 1);
    }
    let (tracks, _) = track_events(&noise, g, &TrackParams::default()).unwrap();
    assert!(tracks.len() <= 2, "{} tracks from noise", tracks.len());
}

#[test]
fn binning_averages_the_samples_of_enough_tracks() {
    let (_, out) = vortex(7, 0.004);
    let g = Geometry {
        width: 256,
        height: 192,
    };
    let (tracks, _) = track_events(&out.events, g, &TrackParams::default()).unwrap();
    let mut table = TrackTable::default();
    for t in &tracks {
        table.push(t);
    }
    let field = bin_tracks(&table, g, &BinParams::default()).unwrap();
    assert_eq!(field.t_us.len(), 1);
    assert_eq!(field.x.len(), 16);
    let valid: Vec<usize> = (0..field.u.len())
        .filter(|&i| field.status[i].is_valid())
        .collect();
    assert!(valid.len() > 20, "{} valid bins", valid.len());
    // Compare with the flow at the bin centres: a stream of 1 px/ms plus the vortex.
    let scenario_flow = vortex(7, 0.0).0.flow.build().unwrap();
    let mut errors: Vec<f64> = valid
        .iter()
        .map(|&i| {
            let (row, col) = (i / field.x.len(), i % field.x.len());
            let (u, v) = scenario_flow.velocity(field.x[col], field.y[row], 8000.0);
            (field.u[i] as f64 - u).hypot(field.v[i] as f64 - v)
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    assert!(median < 0.3, "median |Δv| {median} px/ms");
    let empty = TrackTable::default();
    assert!(bin_tracks(&empty, g, &BinParams::default()).is_err());
}

#[test]
fn settings_by_name_round_trip_and_bad_values_name_the_setting() {
    let mut p = TrackParams::default();
    for (key, _, _) in ebiv::track::TRACK_SETTINGS {
        let text = p.get(key).unwrap();
        p.set(key, &text).unwrap();
    }
    assert_eq!(p, TrackParams::default());
    p.set("fit_window", "6ms").unwrap();
    assert_eq!(p.fit_window_us, 6000);
    for (key, bad) in [
        ("degree", "4"),
        ("degree", "1.5"),
        ("gate", "-1"),
        ("slab", "0"),
        ("polarity", "up"),
        ("latency", "nan"),
        ("nope", "1"),
    ] {
        let e = TrackParams::default()
            .set(key, bad)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(key) || e.contains(&key.replace('_', "-")),
            "{key}={bad}: {e}"
        );
    }
}

#[test]
fn the_automatic_slab_gives_the_same_tracks_in_batches() {
    let (_, out) = vortex(8, 0.003);
    let g = Geometry {
        width: 256,
        height: 192,
    };
    let params = TrackParams::default();
    let (whole, summary) = track_events(&out.events, g, &params).unwrap();
    assert_eq!(summary.slab_us, 500, "bright particles: the shortest slab");
    assert_same_tracks(&in_batches(&out.events, g, &params, 5000), &whole);
}

#[test]
fn hostile_inputs_give_errors_or_nothing_never_a_crash() {
    // A sensor too large for the tracker's maps.
    let huge = Geometry {
        width: 65535,
        height: 65535,
    };
    let e = Tracker::new(huge, TrackParams::default())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("65535x65535"), "{e}");
    // A hot pixel firing every 100 µs for 2 s: no track, and no track alive at the end.
    let g = Geometry {
        width: 32,
        height: 32,
    };
    let mut hot = EventBuffer::new();
    for k in 0..20_000 {
        hot.push(k * 100, 7, 9, (k % 2) as u8);
    }
    let (tracks, summary) = track_events(&hot, g, &TrackParams::default()).unwrap();
    assert!(tracks.is_empty(), "{} tracks", tracks.len());
    assert!(summary.peak_live <= 2, "{summary:?}");
    // Time stamps near the end of i64 (a clock in ns read as µs): no hang, no crash.
    let mut late = EventBuffer::new();
    let t0 = i64::MAX - 50_000_000;
    for k in 0..4000i64 {
        let x = 5 + (k / 200) as u16;
        late.push(t0 + k * 10, x, 10, 1);
        late.push(t0 + k * 10 + 3, x.saturating_sub(3), 10, 0);
    }
    let mut params = TrackParams::default();
    params.set("sample", "1us").unwrap();
    let (tracks, _) = track_events(&late, g, &params).unwrap();
    for t in &tracks {
        assert!(t.samples.iter().all(|s| s.t_us >= t0));
    }
}

#[test]
fn samples_stop_short_of_the_sensor_edge() {
    // A particle image (3 rows; ON events at its leading column, OFF one column behind)
    // crossing a 32 px sensor to the right at 0.5 px/ms and leaving it: the sensor cuts its
    // image, whose events stay at the edge while the particle leaves, so the samples stop
    // a margin inside the outermost pixel centres (without it, the last sample is at 30.95).
    let g = Geometry {
        width: 32,
        height: 32,
    };
    let mut events = EventBuffer::new();
    for k in 0..9000i64 {
        let lead = 5 + k / 200;
        for (column, polarity, delay) in [(lead, 1u8, 0i64), (lead - 1, 0, 3)] {
            if column < 32 {
                events.push(k * 10 + delay, column as u16, 9 + (k % 3) as u16, polarity);
            }
        }
    }
    let (tracks, _) = track_events(&events, g, &TrackParams::default()).unwrap();
    assert_eq!(tracks.len(), 1, "{} tracks", tracks.len());
    // The outermost pixel centre is 31; the margin is 1 px.
    let last = tracks[0].samples.last().unwrap();
    assert!(last.x <= 30.0 && last.x > 29.5, "last sample {last:?}");
}
