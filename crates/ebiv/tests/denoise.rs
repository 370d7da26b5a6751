//! Denoising against the simulator's truth: a `noisy` recording is simulated twice with the
//! same seed, once with its noise sources off. Noise events do not move a pixel's reference
//! and draw from their own generators (src/sim/sensor/noise.rs), so the quiet recording's
//! events are exactly the signal events of the noisy one, which labels every event.
//!
//! The ignored test `denoise_table` prints the trade-off table of docs/denoise.md:
//! `cargo test --release -p ebiv --test denoise -- --ignored --nocapture`.

use ebiv::assess::{assess, AssessOptions};
use ebiv::denoise::{DenoiseReport, DenoiseSettings, Denoiser, HotPixelLearner};
use ebiv::io::EventSource;
use ebiv::settings::ProcessSettings;
use ebiv::sim::scenario::Scenario;
use ebiv::{EventBuffer, Geometry};
use std::collections::HashMap;
use std::sync::Arc;

/// A recording with each event labelled signal (true) or noise (false).
struct Labelled {
    events: EventBuffer,
    signal: Vec<bool>,
    geometry: Geometry,
    scenario: Scenario,
}

impl Labelled {
    fn noise(&self) -> usize {
        self.signal.iter().filter(|s| !**s).count()
    }
}

/// The `uniform` example on a `width`×`height` sensor with the `noisy` preset, plus hot
/// pixels (`noisy` has none) at `hot_fraction` of the pixels firing at `hot_hz`.
fn scenario(
    width: u32,
    height: u32,
    duration: &str,
    density: f64,
    hot: (f64, f64),
    quiet: bool,
    seed: u64,
) -> Scenario {
    let text = Scenario::example_text("uniform").unwrap();
    let noise = if quiet {
        "leak_rate_hz = 0.0\nshot_noise_rate_hz = 0.0\nhot_pixel_fraction = 0.0\nhot_pixel_rate_hz = 0.0\n"
            .to_string()
    } else {
        format!(
            "hot_pixel_fraction = {}\nhot_pixel_rate_hz = {}\n",
            hot.0, hot.1
        )
    };
    let text = text
        .replace("preset = \"gen4\"", &format!("preset = \"noisy\"\n{noise}"))
        .replace("width = 640", &format!("width = {width}"))
        .replace("height = 480", &format!("height = {height}"))
        .replace("duration = \"20ms\"", &format!("duration = \"{duration}\""))
        .replace("density = 0.005 ", &format!("density = {density} "));
    let mut scenario = Scenario::from_toml(&text, "test").unwrap();
    scenario.seed = seed;
    scenario
}

fn simulate(s: &Scenario) -> EventBuffer {
    s.simulation().unwrap().run(None, &|_| {}).unwrap().events
}

/// The `uniform` example on a `width`×`height` sensor with the `noisy` preset and hot pixels
/// `hot` (fraction, rate in Hz), simulated with seed 1.
fn labelled(width: u32, height: u32, duration: &str, density: f64, hot: (f64, f64)) -> Labelled {
    labelled_with_seed(width, height, duration, density, hot, 1)
}

fn labelled_with_seed(
    width: u32,
    height: u32,
    duration: &str,
    density: f64,
    hot: (f64, f64),
    seed: u64,
) -> Labelled {
    let noisy = scenario(width, height, duration, density, hot, false, seed);
    let events = simulate(&noisy);
    let quiet = simulate(&scenario(width, height, duration, density, hot, true, seed));
    let mut clean: HashMap<(i64, u16, u16, u8), u32> = HashMap::new();
    for e in quiet.iter() {
        *clean.entry((e.t, e.x, e.y, e.p)).or_default() += 1;
    }
    let signal: Vec<bool> = events
        .iter()
        .map(|e| match clean.get_mut(&(e.t, e.x, e.y, e.p)) {
            Some(n) if *n > 0 => {
                *n -= 1;
                true
            }
            _ => false,
        })
        .collect();
    let signal_count = signal.iter().filter(|s| **s).count();
    assert_eq!(
        signal_count,
        quiet.len(),
        "the quiet events are the noisy one's signal"
    );
    Labelled {
        events,
        signal,
        geometry: Geometry::new(width, height),
        scenario: noisy,
    }
}

/// Settings with every default of `ProcessSettings`, filters `filters`.
fn settings(filters: &str) -> DenoiseSettings {
    let mut s = ProcessSettings::default();
    s.set("denoise", &toml::Value::String(filters.into()))
        .unwrap();
    s.denoise_settings().unwrap()
}

/// Fraction of the noise removed, fraction of the signal lost, and the filters' report.
fn score(rec: &Labelled, settings: &DenoiseSettings) -> (f64, f64, DenoiseReport) {
    // The polarity carries the label: no filter looks at it.
    let mut events = rec.events.clone();
    for (p, &s) in events.p.iter_mut().zip(&rec.signal) {
        *p = s as u8;
    }
    let hot = settings.filters.hot_pixels.then(|| {
        let mut learner = HotPixelLearner::new(rec.geometry, settings.hot_pixel_learn_us);
        learner.add(&rec.events);
        learner.finish(settings.hot_pixel_factor)
    });
    let mut d = Denoiser::new(settings, rec.geometry, hot).unwrap();
    d.apply(&mut events);
    let kept_signal = events.p.iter().filter(|&&p| p == 1).count();
    let kept_noise = events.len() - kept_signal;
    let (noise, signal) = (rec.noise(), rec.events.len() - rec.noise());
    (
        1.0 - kept_noise as f64 / noise as f64,
        1.0 - kept_signal as f64 / signal as f64,
        d.report().clone(),
    )
}

#[test]
fn denoising_a_noisy_simulation_removes_most_noise_and_keeps_most_signal() {
    // 0.2 % hot pixels at 3 kHz: about 60 events each in the 20 ms.
    let rec = labelled(256, 192, "20ms", 0.001, (0.002, 3000.0));
    assert!(rec.noise() > 2000, "{} noise events", rec.noise());
    let (noise, lost, _) = score(&rec, &settings("correlation"));
    assert!(noise > 0.85, "correlation removed {noise:.3} of the noise");
    assert!(lost < 0.03, "correlation lost {lost:.4} of the signal");
    let (noise, lost, report) = score(&rec, &settings("hot-pixels"));
    let hot = report.hot_pixels.unwrap();
    // 0.2 % of 49152 pixels is about 98, whose events are about half the noise; a few
    // signal pixels alone in a sparse scene fire as often as their neighbours 5 times.
    assert!((80..=200).contains(&hot), "{hot} hot pixels");
    assert!(noise > 0.4, "hot pixels removed {noise:.3} of the noise");
    assert!(lost < 0.03, "hot pixels lost {lost:.4} of the signal");
    let (noise_all, lost_all, report) = score(&rec, &settings("all"));
    assert!(
        noise_all > 0.94,
        "all filters removed {noise_all:.3} of the noise"
    );
    assert!(
        lost_all < 0.05,
        "all filters lost {lost_all:.4} of the signal"
    );
    assert_eq!(report.events_in, rec.events.len() as u64);
    assert_eq!(
        report.removed(),
        report.removed_hot_pixels.unwrap()
            + report.removed_refractory.unwrap()
            + report.removed_correlation.unwrap()
    );
}

#[test]
fn a_denoised_source_reads_what_the_filters_keep_and_seeks_exactly() {
    let rec = labelled(128, 96, "10ms", 0.001, (0.002, 3000.0));
    let events = Arc::new(rec.events.clone());
    let s = settings("all");
    let source = EventSource::memory(events.clone(), Some(rec.geometry), "sim").denoised(Some(s));
    let read = source.open().unwrap().read_all().unwrap();
    // The same as the filters applied by hand.
    let mut learner = HotPixelLearner::new(rec.geometry, s.hot_pixel_learn_us);
    learner.add(&events);
    let mut d = Denoiser::new(&s, rec.geometry, Some(learner.finish(s.hot_pixel_factor))).unwrap();
    let mut by_hand = (*events).clone();
    d.apply(&mut by_hand);
    assert_eq!(read.events.t, by_hand.t);
    assert_eq!(read.events.x, by_hand.x);
    assert_eq!(read.report.denoise.as_ref(), Some(d.report()));
    assert!(by_hand.len() < events.len());
    // A seek lands where the whole stream would be, counting only what follows.
    let target = events.t[events.len() / 2];
    let mut reader = source.open().unwrap();
    reader.skip_to(target).unwrap();
    let mut tail = EventBuffer::new();
    let mut batch = EventBuffer::new();
    while reader.read_batch(&mut batch).unwrap() {
        tail.extend_from(&batch);
    }
    let first = by_hand.t.iter().position(|&t| t >= target).unwrap();
    assert_eq!(tail.t, by_hand.t[first..]);
    assert_eq!(tail.y, by_hand.y[first..]);
    let report = reader.denoise_report().unwrap();
    assert_eq!(report.events_out, tail.len() as u64);
    assert!(report.events_in < events.len() as u64);
    // The origin of relative times is the recording's first event, denoised or not.
    assert_eq!(source.first_event_time().unwrap(), Some(events.t[0]));
}

/// Median and RMS end-point error and valid share of `method` on `events`, against the
/// scenario's flow, with the filters `denoise` and the settings `more` (key, TOML value).
fn measure(
    rec: &Labelled,
    events: &EventBuffer,
    method: &str,
    denoise: &str,
    more: &[(&str, toml::Value)],
) -> (f64, f64, f64) {
    let mut s = ProcessSettings::default();
    s.set("input", &toml::Value::String("sim".into())).unwrap();
    s.set("method", &toml::Value::String(method.into()))
        .unwrap();
    s.set("denoise", &toml::Value::String(denoise.into()))
        .unwrap();
    for (key, value) in more {
        s.set(key, value).unwrap();
    }
    let run = s.resolve().unwrap();
    let source = EventSource::memory(Arc::new(events.clone()), Some(rec.geometry), "sim");
    let m = run.measure(&source, &mut ()).unwrap();
    let sim = rec.scenario.simulation().unwrap();
    let truth = |x: f64, y: f64, t: f64| sim.flow.velocity(x, y, t);
    let a = assess(&m.series, &truth, &AssessOptions::default());
    (a.median, a.rms, a.valid_share)
}

/// Without denoising, hot pixels in a sparse scene make sum of correlation report valid
/// vectors at rest (their events correlate with themselves at zero lag); leaving the lone
/// persistent pixels out of each field's slab (`drop-lone-pixels`, on by default) removes
/// them. Two seeds; the flow is 2 px/ms, so a vector at rest is an error of 2 px/ms.
#[test]
fn lone_hot_pixels_make_no_valid_vectors_at_rest() {
    let keep = [("drop-lone-pixels", toml::Value::Boolean(false))];
    for seed in [1, 2] {
        let rec = labelled_with_seed(320, 240, "40ms", 0.0005, (0.001, 2000.0), seed);
        let (_, rms, valid) = measure(&rec, &rec.events, "corrsum", "none", &[]);
        let (_, rms_kept, _) = measure(&rec, &rec.events, "corrsum", "none", &keep);
        println!(
            "seed {seed}: RMS {rms:.4} px/ms, {valid:.3} valid; hot pixels kept: RMS {rms_kept:.4}"
        );
        assert!(
            rms < 0.05 && valid > 0.3,
            "seed {seed}: RMS error {rms:.4} px/ms with {:.1} % valid",
            100.0 * valid
        );
        assert!(
            rms_kept > 4.0 * rms,
            "seed {seed}: keeping the hot pixels gives an RMS error of {rms_kept:.4} px/ms, leaving them out {rms:.4}"
        );
    }
    // Adaptive slabs: the field's slab (the longest, 200 ms) reaches far past these 40 ms of
    // events, while its windows use short slabs in which a hot pixel fires throughout.
    let rec = labelled_with_seed(320, 240, "40ms", 0.0005, (0.001, 2000.0), 1);
    let auto = ("slab", toml::Value::String("auto".into()));
    let (_, rms, valid) = measure(
        &rec,
        &rec.events,
        "corrsum",
        "none",
        std::slice::from_ref(&auto),
    );
    let (_, rms_kept, _) = measure(
        &rec,
        &rec.events,
        "corrsum",
        "none",
        &[auto, keep[0].clone()],
    );
    println!(
        "adaptive slabs: RMS {rms:.4} px/ms, {valid:.3} valid; hot pixels kept: RMS {rms_kept:.4}"
    );
    assert!(
        rms < 0.05 && valid > 0.3,
        "adaptive: RMS error {rms:.4} px/ms, {valid:.3} valid"
    );
    assert!(
        rms_kept > 4.0 * rms,
        "adaptive: kept {rms_kept:.4}, left out {rms:.4}"
    );
}

#[test]
#[ignore = "prints the table of docs/denoise.md; run with --release --ignored --nocapture"]
fn denoise_table() {
    for density in [0.005, 0.0005] {
        table(
            &labelled(640, 480, "40ms", density, (0.001, 2000.0)),
            density,
        );
    }
}

fn table(rec: &Labelled, density: f64) {
    println!(
        "\nuniform example, seeding {density} per px, noisy preset + 0.1 % hot pixels at 2 kHz, 640x480, 40 ms: {} events, {} noise ({:.1} %)",
        rec.events.len(),
        rec.noise(),
        100.0 * rec.noise() as f64 / rec.events.len() as f64
    );
    println!("\n| filters | parameter | noise removed | signal lost |");
    println!("|---|---|---|---|");
    let row = |label: &str, param: String, s: DenoiseSettings| {
        let (noise, lost, _) = score(rec, &s);
        println!(
            "| {label} | {param} | {:.1} % | {:.2} % |",
            100.0 * noise,
            100.0 * lost
        );
    };
    for dt in [250, 500, 1000, 2000, 5000] {
        let mut s = settings("correlation");
        s.correlation_dt_us = dt;
        row("correlation", format!("denoise-dt {dt}us"), s);
    }
    for r in [10, 30, 100, 1000] {
        let mut s = settings("refractory");
        s.refractory_us = r;
        row("refractory", format!("denoise-refractory {r}us"), s);
    }
    for f in [3.0, 5.0, 10.0, 30.0] {
        let mut s = settings("hot-pixels");
        s.hot_pixel_factor = f;
        row("hot-pixels", format!("denoise-hot-factor {f}"), s);
    }
    row("all", "defaults".into(), settings("all"));

    // The signal alone: the same scene without noise.
    let mut signal = EventBuffer::new();
    for (i, e) in rec.events.iter().enumerate() {
        if rec.signal[i] {
            signal.push(e.t, e.x, e.y, e.p);
        }
    }
    println!("\n| method | events | denoise | median error px/ms | RMS error px/ms | valid |");
    println!("|---|---|---|---|---|---|");
    let keep = [("drop-lone-pixels", toml::Value::Boolean(false))];
    for method in ["corrsum", "motion"] {
        for (what, events, denoise, more) in [
            ("noisy, lone pixels kept", &rec.events, "none", &keep[..]),
            ("noisy", &rec.events, "none", &[]),
            ("noisy", &rec.events, "correlation", &[]),
            ("noisy", &rec.events, "all", &[]),
            ("signal only", &signal, "none", &[]),
        ] {
            let (median, rms, valid) = measure(rec, events, method, denoise, more);
            println!(
                "| {method} | {what} | {denoise} | {median:.4} | {rms:.4} | {:.1} % |",
                100.0 * valid
            );
        }
    }
}

/// Small images creeping at 0.05 px/ms without any noise: the pixels they enter fire ON all
/// through a field's slab, one pixel wide; the OFF events of the pixels they leave keep
/// most of them from passing for lone hot pixels. Prints the share left out per image
/// diameter: about 1 % for 1 px images, the price of a neighbour limit that also catches
/// hot pixels in adaptive slabs (`volume/lone_pixels.rs`, `NEIGHBOUR_MAX`); 2 % bounds it
/// (a limit of a quarter of the sub-intervals left out about 5 %).
#[test]
fn small_slow_particle_images_are_not_taken_for_hot_pixels() {
    for diameter in [1.0, 1.5, 2.5] {
        let text = Scenario::example_text("uniform")
            .unwrap()
            .replace("width = 640", "width = 320")
            .replace("height = 480", "height = 240")
            .replace("duration = \"20ms\"", "duration = \"40ms\"")
            .replace("u = 2.0 ", "u = 0.05 ")
            .replace("diameter = 2.5 ", &format!("diameter = {diameter} "));
        let scenario = Scenario::from_toml(&text, "test").unwrap();
        let events = simulate(&scenario);
        let mut s = ProcessSettings::default();
        s.set("input", &toml::Value::String("sim".into())).unwrap();
        let run = s.resolve().unwrap();
        let geometry = Geometry::new(320, 240);
        let source = EventSource::memory(Arc::new(events.clone()), Some(geometry), "sim");
        let m = run.measure(&source, &mut ()).unwrap();
        let share = m.summary.lone_pixel_events as f64 / events.len() as f64;
        println!(
            "{diameter} px images: {} of {} events left out ({:.2} %)",
            m.summary.lone_pixel_events,
            events.len(),
            100.0 * share
        );
        assert!(
            share < 0.02,
            "{diameter} px: {:.2} % left out",
            100.0 * share
        );
    }
}

/// In a recording of a few tens of milliseconds, a pixel that a particle or two crossed fires
/// far more than its neighbours' median; it is not hot, since its events come in bursts
/// rather than all through the learning interval.
#[test]
fn busy_signal_pixels_of_a_short_recording_are_not_hot() {
    for density in [0.0005, 0.002, 0.005] {
        let rec = labelled(320, 240, "20ms", density, (0.0, 0.0));
        let (_, lost, report) = score(&rec, &settings("hot-pixels"));
        let hot = report.hot_pixels.unwrap();
        println!(
            "seeding {density}: {hot} hot pixels, {:.3} % of the signal lost",
            100.0 * lost
        );
        assert!(
            lost < 0.003,
            "seeding {density}: {hot} pixels taken for hot, {:.3} % of the signal lost",
            100.0 * lost
        );
    }
}
