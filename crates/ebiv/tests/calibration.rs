//! The calibration of the `imx636` preset (docs/calibration.md): the real wall-flow slice has
//! the pixel activity the page's table gives, and a small simulated wall flow with the preset
//! fires about one event per pixel per particle with gaps of milliseconds, as the camera does.

mod common;

use ebiv::activity::{Activity, ActivityReport, ActivitySettings};
use ebiv::filter::EventFilter;
use ebiv::sim::scenario::Scenario;
use ebiv::{Geometry, PolaritySelection};

/// Positive events of 10–30 ms of the `wallflow` example on a `size`² sensor with `preset`.
fn simulated_wallflow(preset: &str, size: u32) -> ActivityReport {
    let text = Scenario::example("wallflow").expect("built-in example");
    let mut scenario = Scenario::from_toml(text, "wallflow").unwrap();
    scenario.sensor.width = size;
    scenario.sensor.height = size;
    scenario.sensor.preset = preset.into();
    let mut events = scenario
        .simulation()
        .unwrap()
        .run(None, &|_| {})
        .unwrap()
        .events;
    EventFilter {
        polarity: PolaritySelection::Positive,
        ..EventFilter::default()
    }
    .apply(&mut events);
    let geometry = Geometry::new(size, size);
    Activity::measure(
        &events,
        geometry,
        10_000,
        Some(30_000),
        ActivitySettings::default(),
    )
    .unwrap()
}

#[test]
fn imx636_fires_once_per_particle_with_gaps_of_milliseconds() {
    let r = simulated_wallflow("imx636", 160);
    let [median, _] = r.events_per_active_pixel.unwrap();
    let gap = r.gap_us.unwrap();
    println!("imx636: {r:?}");
    assert!(median <= 1.5, "median events per active pixel {median}");
    assert!(gap[1] >= 3_000.0, "median gap {} µs", gap[1]);
    assert!(gap[0] >= 3_000.0, "10th-percentile gap {} µs", gap[0]);
    // The real slice: 31 % of the pixels fire within 20 ms, 266 events per window and slab.
    assert!((0.2..0.4).contains(&r.active_share), "{}", r.active_share);
    let windows = r.window_events.unwrap();
    assert!((150.0..350.0).contains(&windows[1]), "{windows:?}");
    let width = r.trail_width_px.unwrap();
    assert!((2.0..=5.0).contains(&width[1]), "{width:?}");
}

#[test]
fn gen4_fires_bursts_on_the_same_scene() {
    // The µs-refractory model the preset departs from: several events per passage, a few
    // hundred µs apart.
    let r = simulated_wallflow("gen4", 96);
    let [median, _] = r.events_per_active_pixel.unwrap();
    assert!(median >= 2.0, "{r:?}");
    assert!(r.gap_us.unwrap()[1] < 1_000.0, "{r:?}");
}

#[test]
fn real_wallflow_slice_activity() {
    let Some(dir) = common::data_dir() else {
        return;
    };
    let rec =
        ebiv::io::read_all(dir.join("ebiv/wallflow_slice2.npz"), &Default::default()).unwrap();
    let t0 = rec.events.t[0];
    let r = Activity::measure(
        &rec.events,
        Geometry::new(512, 512),
        t0,
        None,
        ActivitySettings::default(),
    )
    .unwrap();
    assert_eq!(r.events, 89_239);
    assert_eq!(r.active_pixels, 81_008);
    assert_eq!(r.events_per_active_pixel, Some([1.0, 1.0]));
    assert_eq!(r.gap_us, Some([4_032.0, 7_495.0, 14_048.0]));
    let w = r.window_events.unwrap();
    assert!(
        (w[0] - 92.75).abs() < 1e-9 && w[1] == 266.0 && (w[2] - 501.3).abs() < 1e-9,
        "{w:?}"
    );
    assert_eq!(r.trail_width_px, Some([1.56, 2.08, 3.2]));
    assert_eq!(r.trails, 1418);
}
