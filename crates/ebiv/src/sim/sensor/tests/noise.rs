//! Noise rates, threshold mismatch and determinism across bands.

use super::*;

/// `|observed − expected| ≤ 5 σ` for a Poisson count.
fn assert_poisson(observed: usize, expected: f64, what: &str) {
    let bound = 5.0 * expected.sqrt();
    assert!(
        (observed as f64 - expected).abs() <= bound,
        "{what}: {observed} events, expected {expected:.0} ± {bound:.0}"
    );
}

/// `events` in the readout's order: time, then row, column, polarity.
fn sorted_events(mut events: Vec<SimEvent>) -> Vec<SimEvent> {
    events.sort_by(|a, b| {
        a.t_us
            .total_cmp(&b.t_us)
            .then((a.y, a.x, a.p).cmp(&(b.y, b.x, b.p)))
    });
    events
}

#[test]
fn static_scene_gives_only_noise_at_the_configured_rates() {
    let mut p = SensorParams::gen4();
    p.threshold_sigma = 0.0;
    p.noise_rate_cov_decades = 0.0;
    p.leak_rate_hz = 2.0;
    p.shot_noise_rate_hz = 20.0;
    p.hot_pixel_fraction = 0.0;
    let g = Geometry::new(100, 100);
    let background = 1.0f32;
    let mut band = SensorBand::new(g, 0..100, &p, 21);
    band.adapt(0.0, |_, _| background);
    let mut signal = Vec::new();
    hold(&mut band, 2e6, 1e4, &mut signal);
    assert!(
        signal.is_empty(),
        "a static scene fired the change detectors"
    );

    let mut noise = Vec::new();
    let seconds = 2.0;
    band.noise(0.0, seconds * 1e6, &mut noise);
    let n = g.pixels() as f64;
    // v2e's irradiance scaling: 1 − 0.75·(I + I_dark)/(I_ref + I_dark).
    let b = (background as f64 + p.cutoff_dark_irradiance)
        / (p.cutoff_reference_irradiance + p.cutoff_dark_irradiance);
    let shot = n * seconds * p.shot_noise_rate_hz * (1.0 - 0.75 * b);
    let leak = n * seconds * p.leak_rate_hz;
    let c = band.counters();
    assert_poisson(c.leak as usize, leak, "leak");
    assert_poisson(c.shot as usize, shot, "shot noise");
    assert_poisson(count(&noise, 0), shot / 2.0, "OFF shot noise");
    assert_poisson(count(&noise, 1), leak + shot / 2.0, "ON events");
    assert!(noise.iter().all(|e| (0.0..2e6).contains(&e.t_us)));
    // Uniform in time: the first and second halves hold the same number.
    let early = noise.iter().filter(|e| e.t_us < 1e6).count();
    assert_poisson(early, noise.len() as f64 / 2.0, "first second");

    // The frozen log-normal rate factor is normalised to mean 1.
    p.noise_rate_cov_decades = 0.3;
    p.shot_noise_rate_hz = 0.0;
    let mut band = SensorBand::new(g, 0..100, &p, 22);
    band.adapt(0.0, |_, _| background);
    let mut noise = Vec::new();
    band.noise(0.0, seconds * 1e6, &mut noise);
    assert_poisson(noise.len(), leak, "leak with rate spread");
}

#[test]
fn hot_pixels_are_the_configured_fraction_and_rate() {
    let mut p = quiet(SensorParams::gen4());
    p.hot_pixel_fraction = 0.01;
    p.hot_pixel_rate_hz = 100.0;
    let g = Geometry::new(200, 100);
    let mut band = SensorBand::new(g, 0..100, &p, 8);
    let mut noise = Vec::new();
    band.noise(0.0, 1e6, &mut noise);
    let mut per_pixel = std::collections::HashMap::new();
    for e in &noise {
        *per_pixel.entry((e.x, e.y)).or_insert(0usize) += 1;
    }
    let hot = per_pixel.len() as f64;
    let expected = 0.01 * g.pixels() as f64;
    assert!(
        (hot - expected).abs() < 5.0 * (expected * 0.99).sqrt(),
        "{hot} hot pixels"
    );
    assert_poisson(noise.len(), hot * 100.0, "hot-pixel events");
    assert_poisson(count(&noise, 1), hot * 50.0, "hot ON events");
}

#[test]
fn threshold_mismatch_has_the_configured_spread() {
    let mut p = SensorParams::ideal();
    p.threshold_sigma = 0.03;
    let g = Geometry::new(400, 250);
    let band = SensorBand::new(g, 0..250, &p, 77);
    for pol in 0..2 {
        let theta: Vec<f64> = (0..250)
            .flat_map(|y| (0..400).map(move |x| (x, y)))
            .map(|(x, y)| {
                let (on, off) = band.thresholds(x, y).unwrap_or((0.0, 0.0));
                if pol == 1 {
                    on
                } else {
                    off
                }
            })
            .collect();
        let n = theta.len() as f64;
        let mean = theta.iter().sum::<f64>() / n;
        let sd = (theta.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert!((mean - 0.2).abs() < 0.001, "mean {mean}");
        assert!((sd / 0.03 - 1.0).abs() < 0.02, "std {sd}");
    }
}

/// A Gaussian spot on a diagonal path over a 48 × 40 sensor, seen by bands `splits`.
fn spot_recording(p: &SensorParams, splits: &[u32]) -> Vec<SimEvent> {
    let g = Geometry::new(48, 40);
    let mut bands: Vec<SensorBand> = splits
        .windows(2)
        .map(|r| SensorBand::new(g, r[0]..r[1], p, 1234))
        .collect();
    let irr = |x: u32, y: u32, t: f64| {
        let (cx, cy) = (-4.0 + 0.05 * t, 2.0 + 0.035 * t);
        let r2 = (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2);
        (1.0 + 40.0 * (-8.0 * r2 / 6.25).exp()) as f32
    };
    for band in &mut bands {
        band.adapt(0.0, |x, y| irr(x, y, 0.0));
    }
    let mut out = Vec::new();
    let mut changed = Vec::new();
    for k in 1..=1100 {
        let t = k as f64;
        changed.clear();
        for i in 0..g.pixels() as u32 {
            let v = irr(i % 48, i / 48, t);
            if v != irr(i % 48, i / 48, t - 1.0) {
                changed.push((i, v));
            }
        }
        for band in &mut bands {
            band.advance(t, &changed, &mut out);
        }
        if k % 500 == 0 {
            for band in &mut bands {
                band.noise(t - 500.0, t, &mut out);
            }
        }
    }
    out
}

#[test]
fn same_seed_gives_the_same_events_for_any_band_split() {
    let mut p = SensorParams::gen4();
    p.shot_noise_rate_hz = 2000.0;
    p.leak_rate_hz = 500.0;
    p.hot_pixel_fraction = 0.01;
    let one = spot_recording(&p, &[0, 40]);
    let three = spot_recording(&p, &[0, 7, 25, 40]);
    let many = spot_recording(&p, &[0, 1, 2, 13, 14, 39, 40]);
    assert!(one.len() > 500, "{}", one.len());
    let (a, ra) = read_out(one.clone(), &p);
    let (b, rb) = read_out(three, &p);
    let (c, _) = read_out(many.clone(), &p);
    assert_eq!(a, b);
    assert_eq!(a, c);
    assert_eq!(ra, rb);
    assert_eq!(sorted_events(one), sorted_events(many));
    // A different seed gives different events.
    let g = Geometry::new(48, 40);
    let other = SensorBand::new(g, 0..40, &p, 1235);
    let same = SensorBand::new(g, 0..40, &p, 1234);
    assert_ne!(other.thresholds(3, 3), same.thresholds(3, 3));
}

/// Background activity drawn window by window is that of one call over the whole time when
/// the irradiance does not change: the same events and counters, whatever the windows.
#[test]
fn noise_drawn_in_windows_is_noise_drawn_at_once() {
    let mut p = SensorParams::gen4();
    p.leak_rate_hz = 300.0;
    p.shot_noise_rate_hz = 1000.0;
    p.hot_pixel_fraction = 0.02;
    let g = Geometry::new(30, 20);
    let mut once = SensorBand::new(g, 3..17, &p, 99);
    once.adapt(0.0, |x, _| 1.0 + x as f32);
    let mut want = Vec::new();
    once.noise(-50.0, 2e5, &mut want);
    assert!(want.len() > 1_000, "{}", want.len());
    let cut_sets: [Vec<f64>; 3] = [
        vec![],
        vec![-50.0, 0.0, 1.0, 1.0, 7e4],
        vec![1e3, 5e4, 1.5e5, 3e5],
    ];
    for cuts in cut_sets {
        let mut band = SensorBand::new(g, 3..17, &p, 99);
        band.adapt(0.0, |x, _| 1.0 + x as f32);
        let mut stream = band.noise_stream(-50.0);
        let mut got = Vec::new();
        for &cut in cuts.iter().chain(&[2e5]) {
            band.noise_until(&mut stream, cut.min(2e5), &mut got);
        }
        assert_eq!(
            sorted_events(got),
            sorted_events(want.clone()),
            "cuts {cuts:?}"
        );
        assert_eq!(band.counters(), once.counters(), "cuts {cuts:?}");
    }
}
