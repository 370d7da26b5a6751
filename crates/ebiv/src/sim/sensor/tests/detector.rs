//! The change detector: event counts, exact crossing times, idle pixels, a moving spot.

use super::*;

#[test]
fn rise_by_delta_gives_floor_delta_over_theta_on_events() {
    let p = SensorParams::ideal();
    let theta = p.threshold_on;
    for &delta in &[0.05, 0.37, 1.03, 2.91, 7.77] {
        for &ramp_us in &[0.0, 1.0, 250.0] {
            let i0 = irradiance_for_log(&p, 0.0);
            let i1 = irradiance_for_log(&p, delta);
            let mut band = one_pixel(&p, i0);
            let mut ev = drive(&mut band, &[(10.0, i0), (10.0 + ramp_us, i1)]);
            hold(&mut band, 1000.0, 50.0, &mut ev);
            let expected = (delta / theta).floor() as usize;
            assert_eq!(count(&ev, 1), expected, "Δ = {delta}, ramp {ramp_us} µs");
            assert_eq!(count(&ev, 0), 0, "Δ = {delta}");
        }
    }
}

#[test]
fn rise_then_fall_gives_equal_on_and_off_counts() {
    for cutoff in [0.0, 1000.0] {
        let mut p = SensorParams::ideal();
        p.cutoff_hz = cutoff;
        for &delta in &[0.15, 0.61, 1.99, 4.47] {
            let i0 = irradiance_for_log(&p, 0.3);
            let i1 = irradiance_for_log(&p, 0.3 + delta);
            let mut band = one_pixel(&p, i0);
            let mut ev = drive(&mut band, &[(0.0, i0), (40.0, i1)]);
            // The low-pass approaches its input exponentially (τ ≈ 1 ms here), and the last
            // OFF level is the start value itself: hold for many time constants.
            hold(&mut band, 100_000.0, 100.0, &mut ev);
            let on = count(&ev, 1);
            ev.extend(drive(&mut band, &[(100_040.0, i0)]));
            hold(&mut band, 200_000.0, 100.0, &mut ev);
            assert_eq!(on, (delta / p.threshold_on).floor() as usize);
            assert_eq!(count(&ev, 0), on, "Δ = {delta}, cutoff {cutoff}");
            assert_eq!(count(&ev, 1), on);
        }
    }
}

#[test]
fn linear_log_ramp_gives_analytic_crossing_times() {
    let p = SensorParams::ideal();
    let theta = p.threshold_on;
    for &slope in &[0.013f64, -0.29, 2.5] {
        // L(t) = l0 + slope·(t − 5), sampled at uneven times.
        let l0 = 0.5;
        let i0 = irradiance_for_log(&p, l0);
        let mut band = one_pixel(&p, i0);
        band.advance(5.0, &[], &mut Vec::new());
        let mut samples = Vec::new();
        // Keep L within 6 ln units of the start (ε = 0.001 floors it at ln ε).
        let t_end = (5.0 + 6.0 / slope.abs()).min(400.0);
        let mut t = 5.0;
        let mut k = 0;
        while t < t_end {
            t += [0.7, 1.9, 3.1, 0.25][k % 4];
            k += 1;
            samples.push((t, irradiance_for_log(&p, l0 + slope * (t - 5.0))));
        }
        let ev = drive(&mut band, &samples);
        let u0 = log_of(&p, i0);
        let span = samples.last().map_or(0.0, |s| log_of(&p, s.1) - u0);
        let n = (span.abs() / theta).floor() as usize;
        assert_eq!(ev.len(), n, "slope {slope}");
        for (j, e) in ev.iter().enumerate() {
            // Level crossed: u0 ± (j + 1)θ; the sampled logs carry f32 rounding, so compare
            // with the crossing of the piecewise-linear interpolation of the samples.
            let level = u0 + slope.signum() * (j + 1) as f64 * theta;
            let mut prev = (5.0, u0);
            let mut expected = f64::NAN;
            for &(ts, is) in &samples {
                let ls = log_of(&p, is);
                if (ls - level) * (prev.1 - level) <= 0.0 && ls != prev.1 {
                    expected = prev.0 + (level - prev.1) * (ts - prev.0) / (ls - prev.1);
                    break;
                }
                prev = (ts, ls);
            }
            let analytic = 5.0 + (level - l0) / slope;
            assert!((e.t_us - expected).abs() < 1e-9, "{} vs {expected}", e.t_us);
            assert!((e.t_us - analytic).abs() < 0.01, "{} vs {analytic}", e.t_us);
            assert_eq!(e.p, (slope > 0.0) as u8);
        }
    }
}

#[test]
fn ideal_static_scene_gives_zero_events() {
    let p = SensorParams::ideal();
    let g = Geometry::new(40, 30);
    let mut band = SensorBand::new(g, 0..30, &p, 5);
    let irr = |x: u32, y: u32| 1.0 + ((x * 7 + y * 13) % 17) as f32;
    band.adapt(0.0, irr);
    let same: Vec<(u32, f32)> = (0..g.pixels() as u32)
        .map(|i| (i, irr(i % 40, i / 40)))
        .collect();
    let mut out = Vec::new();
    for k in 1..=100 {
        let changed: &[(u32, f32)] = if k % 2 == 0 { &same } else { &[] };
        band.advance(k as f64 * 10.0, changed, &mut out);
    }
    band.noise(0.0, 1e6, &mut out);
    assert!(out.is_empty());
    assert_eq!(band.active_pixels(), 0);
}

#[test]
fn settled_pixels_leave_the_active_set() {
    let p = quiet(SensorParams::gen4());
    let g = Geometry::new(16, 16);
    let mut band = SensorBand::new(g, 0..16, &p, 2);
    band.adapt(0.0, |_, _| 1.0);
    let mut out = Vec::new();
    let changed: Vec<(u32, f32)> = (0..32).map(|i| (i, 30.0)).collect();
    band.advance(1.0, &changed, &mut out);
    assert_eq!(band.active_pixels(), 32);
    hold(&mut band, 20_000.0, 10.0, &mut out);
    assert_eq!(band.active_pixels(), 0);
    assert_eq!(
        count(&out, 1),
        32 * (30f64.ln() / p.threshold_on).floor() as usize
    );
}

/// A Gaussian spot (e⁻² diameter 2.5 px, contrast 10 over background 1) crosses a row of
/// pixels at 50 px/ms: each pixel's ON events come before the spot centre passes it, its OFF
/// events after (sensor-model.md §8).
#[test]
fn moving_spot_on_events_lead_off_events_trail() {
    let p = SensorParams::ideal();
    let (w, speed, d) = (48u32, 0.05, 2.5); // px, px/µs, px
    let g = Geometry::new(w, 1);
    let mut band = SensorBand::new(g, 0..1, &p, 3);
    let x_at = |t: f64| -5.0 + speed * t;
    let irr = |x: u32, t: f64| {
        let dx = x as f64 - x_at(t);
        (1.0 + 10.0 * (-8.0 * dx * dx / (d * d)).exp()) as f32
    };
    band.adapt(0.0, |x, _| irr(x, 0.0));
    let mut out = Vec::new();
    let mut changed = Vec::new();
    let mut t = 0.0;
    while t < 1200.0 {
        t += 1.0;
        changed.clear();
        changed.extend((0..w).map(|x| (x, irr(x, t))));
        band.advance(t, &changed, &mut out);
    }
    for x in 5..40u16 {
        let t_pass = (x as f64 + 5.0) / speed;
        let mean = |pol: u8| {
            let ts: Vec<f64> = out
                .iter()
                .filter(|e| e.x == x && e.p == pol)
                .map(|e| e.t_us - t_pass)
                .collect();
            assert!(!ts.is_empty(), "pixel {x}, polarity {pol}");
            ts.iter().sum::<f64>() / ts.len() as f64
        };
        let (on, off) = (mean(1), mean(0));
        assert!(
            on < -5.0 && off > 5.0,
            "pixel {x}: ON {on:.1} µs, OFF {off:.1} µs"
        );
    }
}

/// A pixel listed twice in one step takes its last sample; its mark is cleared for the next
/// step, where it is updated again as if it had been listed once.
#[test]
fn a_repeated_pixel_takes_its_last_sample_and_is_updated_again_next_step() {
    let p = SensorParams::gen4();
    let (a, b, c) = (1.0f32, 4.0f32, 0.5f32);
    let mut twice = one_pixel(&p, a);
    let mut once = one_pixel(&p, a);
    let (mut ev_twice, mut ev_once) = (Vec::new(), Vec::new());
    twice.advance(100.0, &[(0, 9.0), (0, b)], &mut ev_twice);
    once.advance(100.0, &[(0, b)], &mut ev_once);
    assert_eq!(twice.log_state(0, 0), once.log_state(0, 0));
    for (t, i) in [(200.0, c), (300.0, b), (400.0, b)] {
        twice.advance(t, &[(0, i)], &mut ev_twice);
        once.advance(t, &[(0, i)], &mut ev_once);
        assert_eq!(twice.log_state(0, 0), once.log_state(0, 0), "t = {t}");
    }
    hold(&mut twice, 2000.0, 100.0, &mut ev_twice);
    hold(&mut once, 2000.0, 100.0, &mut ev_once);
    assert!(
        count(&ev_once, 1) > 0 && count(&ev_once, 0) > 0,
        "{ev_once:?}"
    );
    assert_eq!(ev_twice, ev_once);
}
