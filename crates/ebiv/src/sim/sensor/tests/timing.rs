//! Event timing: the photoreceptor low-pass, latency, jitter and the refractory period.

use super::*;

/// ω = 2π f in 1/µs.
fn omega(f_hz: f64) -> f64 {
    std::f64::consts::TAU * f_hz * 1e-6
}

/// After a step of the input at `t0` from log `ua` to `ub`, a first-order low-pass with corner
/// ω reaches `ua + k·θ` at `t0 − ln(1 − kθ/Δ)/ω`.
fn step_crossings(t0: f64, ua: f64, ub: f64, theta: f64, w: f64) -> Vec<f64> {
    let delta = ub - ua;
    (1..)
        .map(|k| k as f64 * theta)
        .take_while(|&level| level < delta)
        .map(|level| t0 - (1.0 - level / delta).ln() / w)
        .collect()
}

#[test]
fn step_response_is_delayed_as_the_first_order_low_pass_predicts() {
    let p = quiet(SensorParams::gen4()); // 10 kHz at I ≥ 10, dark irradiance 0.1
    let theta = p.threshold_on;
    let mut first = Vec::new();
    for &(ia, ib) in &[(10.0f32, 30.0f32), (1.0, 3.0)] {
        let w = omega(p.cutoff_hz)
            * ((ib as f64 + p.cutoff_dark_irradiance)
                / (p.cutoff_reference_irradiance + p.cutoff_dark_irradiance))
                .min(1.0);
        let expected = step_crossings(100.0, log_of(&p, ia), log_of(&p, ib), theta, w);
        assert_eq!(expected.len(), 4);
        for steps in [&[7.0, 0.3, 11.0][..], &[5000.0]] {
            let mut band = one_pixel(&p, ia);
            let mut ev = drive(&mut band, &[(100.0, ia), (100.0, ib)]);
            let mut k = 0;
            while band.time_us() < 5000.0 {
                let t = (band.time_us() + steps[k % steps.len()]).min(5000.0);
                k += 1;
                band.advance(t, &[], &mut ev);
            }
            let times: Vec<f64> = ev.iter().map(|e| e.t_us).collect();
            assert_eq!(times.len(), expected.len(), "{ia} → {ib}");
            for (t, e) in times.iter().zip(&expected) {
                assert!((t - e).abs() < 1e-6, "{ia} → {ib}: {t} vs {e}");
            }
        }
        first.push(expected[0]);
    }
    // Same contrast, ten times dimmer: the bandwidth is 3.1/10.1 of the bright one.
    assert!(first[1] - 100.0 > 3.0 * (first[0] - 100.0), "{first:?}");
}

#[test]
fn a_new_sample_while_the_pixel_waits_for_its_next_crossing_is_exact() {
    // Bright pixel (constant bandwidth): input steps ln 10 → ln 30 at 100 µs, then to ln 300
    // at 140 µs, while the low-pass is between crossings and the pixel asleep.
    let p = quiet(SensorParams::gen4());
    let theta = p.threshold_on;
    let w = omega(p.cutoff_hz);
    let (u0, u1, u2) = (log_of(&p, 10.0), log_of(&p, 30.0), log_of(&p, 300.0));
    let l_at = |t: f64| {
        if t <= 140.0 {
            u1 + (u0 - u1) * (-w * (t - 100.0)).exp()
        } else {
            let l140 = u1 + (u0 - u1) * (-w * 40.0).exp();
            u2 + (l140 - u2) * (-w * (t - 140.0)).exp()
        }
    };
    let expected: Vec<f64> = (1..)
        .map(|k| u0 + k as f64 * theta)
        .take_while(|&level| level < u2)
        .map(|level| bisect(|t| l_at(t) - level, 100.0, 5000.0))
        .collect();
    let mut band = one_pixel(&p, 10.0);
    let mut ev = drive(&mut band, &[(100.0, 10.0), (100.0, 30.0)]);
    for t in [101.0, 102.5, 120.0, 139.0, 140.0] {
        band.advance(t, &[], &mut ev);
    }
    assert!(ev.len() >= 2, "crossings before the second step: {ev:?}");
    band.advance(140.0, &[(0, 300.0)], &mut ev);
    hold(&mut band, 5000.0, 3.7, &mut ev);
    assert_eq!(ev.len(), expected.len());
    for (e, t) in ev.iter().zip(&expected) {
        assert!((e.t_us - t).abs() < 1e-6, "{} vs {t}", e.t_us);
    }
    assert_eq!(band.active_pixels(), 0);
}

#[test]
fn log_ramp_through_a_fixed_low_pass_fires_at_the_exact_solution() {
    let mut p = quiet(SensorParams::ideal());
    p.cutoff_hz = 5000.0;
    p.cutoff_reference_irradiance = 0.0; // bandwidth independent of irradiance
    let (w, slope, theta) = (omega(5000.0), 0.05, p.threshold_on);
    let i0 = irradiance_for_log(&p, 0.0);
    let u0 = log_of(&p, i0);
    // L(t) = m·t − (m/ω)(1 − e^(−ωt)) for u(t) = m·t, L(0) = 0.
    let exact = |t: f64| slope * t - slope / w * (1.0 - (-w * t).exp());
    for steps in [&[0.5, 1.7, 0.2][..], &[40.0, 13.0]] {
        let mut band = one_pixel(&p, i0);
        let mut ev = Vec::new();
        let mut t = 0.0f64;
        let mut k = 0;
        while t < 300.0 {
            t = (t + steps[k % steps.len()]).min(300.0);
            k += 1;
            let i = irradiance_for_log(&p, slope * t);
            band.advance(t, &[(0, i)], &mut ev);
        }
        assert_eq!(ev.len(), (exact(300.0) / theta) as usize);
        for (j, e) in ev.iter().enumerate() {
            let level = u0 + (j + 1) as f64 * theta;
            let t_exact = bisect(|t| exact(t) - level, 0.0, 300.0);
            assert!((e.t_us - t_exact).abs() < 1e-4, "{} vs {t_exact}", e.t_us);
        }
    }
}

#[test]
fn extremum_inside_one_step_matches_fine_steps() {
    // Input up over 20 µs, then down over 200 µs: the low-pass output peaks inside the
    // second sample interval. One coarse step must give the fine-step events.
    let mut p = quiet(SensorParams::ideal());
    p.cutoff_hz = 5000.0;
    p.cutoff_reference_irradiance = 0.0;
    let i0 = irradiance_for_log(&p, 0.0);
    let run = |dt: f64| {
        let mut band = one_pixel(&p, i0);
        let mut ev = Vec::new();
        let input = |t: f64| {
            if t <= 20.0 {
                0.1 * t
            } else {
                2.0 - 0.01 * (t - 20.0)
            }
        };
        let mut t = 0.0f64;
        while t < 1000.0 {
            t += if t < 20.0 {
                20.0_f64.min(dt)
            } else {
                dt.min(1000.0 - t)
            };
            let l = input(t.min(220.0)).max(0.0);
            band.advance(t, &[(0, irradiance_for_log(&p, l))], &mut ev);
        }
        ev
    };
    let coarse = run(200.0);
    let fine = run(0.25);
    assert!(
        count(&coarse, 1) >= 3 && count(&coarse, 0) >= 3,
        "{coarse:?}"
    );
    assert_eq!(coarse.len(), fine.len());
    for (a, b) in coarse.iter().zip(&fine) {
        assert_eq!(a.p, b.p);
        assert!((a.t_us - b.t_us).abs() < 1e-4, "{} vs {}", a.t_us, b.t_us);
    }
}

/// Events of a Gaussian spot crossing a row of 24 pixels under `p`.
fn spot_events(p: &SensorParams) -> Vec<SimEvent> {
    let g = Geometry::new(24, 1);
    let mut band = SensorBand::new(g, 0..1, p, 11);
    let irr = |x: u32, t: f64| {
        let dx = x as f64 - (-3.0 + 0.02 * t);
        (1.0 + 30.0 * (-dx * dx).exp()) as f32
    };
    band.adapt(0.0, |x, _| irr(x, 0.0));
    let mut out = Vec::new();
    let mut changed = Vec::new();
    for k in 1..=1500 {
        let t = k as f64;
        changed.clear();
        changed.extend((0..24).map(|x| (x, irr(x, t))));
        band.advance(t, &changed, &mut out);
    }
    out
}

#[test]
fn latency_shifts_every_event_by_exactly_its_value() {
    let mut p = quiet(SensorParams::gen4());
    p.refractory_us = 5.0;
    let base = spot_events(&p);
    p.latency_us = 37.5;
    let late = spot_events(&p);
    assert!(base.len() > 100);
    assert_eq!(base.len(), late.len());
    for (a, b) in base.iter().zip(&late) {
        assert_eq!((a.x, a.y, a.p), (b.x, b.y, b.p));
        assert!((b.t_us - a.t_us - 37.5).abs() < 1e-9);
    }
}

#[test]
fn refractory_period_blinds_the_pixel_and_counts_what_it_hides() {
    // L = 0.2·t for 100 µs with θ = 0.2: a crossing every µs. With T_ref = 4.3 µs the pixel
    // fires at t = 1, is blind until 5.3 (hiding 4 crossings), resets to L(5.3) = 1.06 and fires
    // next at 6.3: every 5.3 µs, 19 events up to 100 µs; 18 × 4 + 3 hidden crossings.
    let mut p = SensorParams::ideal();
    p.refractory_us = 4.3;
    let i0 = irradiance_for_log(&p, 0.0);
    let mut band = one_pixel(&p, i0);
    let samples: Vec<(f64, f32)> = (1..=200)
        .map(|k| (k as f64 * 0.5, irradiance_for_log(&p, 0.1 * k as f64)))
        .collect();
    let mut ev = drive(&mut band, &samples);
    hold(&mut band, 200.0, 10.0, &mut ev);
    assert_eq!(ev.len(), 19);
    for (k, e) in ev.iter().enumerate() {
        assert!(
            (e.t_us - (1.0 + 5.3 * k as f64)).abs() < 1e-5,
            "{k}: {}",
            e.t_us
        );
    }
    assert_eq!(band.counters().suppressed_refractory, 75);
    assert_eq!(band.active_pixels(), 0);

    // With jitter and latency the spacing still never falls below T_ref, and the readout
    // reports the hidden crossings.
    p.jitter_us = 2.0;
    p.latency_us = 3.0;
    let g = Geometry::new(50, 1);
    let mut band = SensorBand::new(g, 0..1, &p, 9);
    band.adapt(0.0, |_, _| i0);
    let mut ev = Vec::new();
    for &(t, i) in &samples {
        let changed: Vec<(u32, f32)> = (0..50).map(|x| (x, i)).collect();
        band.advance(t, &changed, &mut ev);
    }
    hold(&mut band, 200.0, 10.0, &mut ev);
    ev.sort_by(|a, b| a.t_us.total_cmp(&b.t_us));
    for x in 0..50 {
        let ts: Vec<f64> = ev.iter().filter(|e| e.x == x).map(|e| e.t_us).collect();
        assert!(ts.len() >= 15);
        for pair in ts.windows(2) {
            assert!(pair[1] - pair[0] >= 4.3 - 1e-9, "{pair:?}");
        }
    }
    let n = ev.len() as u64;
    let (buffer, mut report) = read_out(ev, &p);
    assert_eq!(report.dropped_refractory, 0);
    report.absorb(&band.counters());
    assert_eq!(buffer.len() as u64, n);
    assert!(report.dropped_refractory > 50 * 50);
    assert_eq!(
        report.dropped_refractory,
        band.counters().suppressed_refractory
    );
}

#[test]
fn jitter_has_the_configured_spread_and_keeps_events_causal() {
    let mut p = quiet(SensorParams::ideal());
    p.jitter_us = 2.0;
    p.latency_us = 1.0;
    let g = Geometry::new(100, 100);
    let mut band = SensorBand::new(g, 0..100, &p, 4);
    let i0 = irradiance_for_log(&p, 0.0);
    let i1 = irradiance_for_log(&p, 0.3);
    band.adapt(0.0, |_, _| i0);
    let changed: Vec<(u32, f32)> = (0..10_000).map(|i| (i, i1)).collect();
    let mut ev = Vec::new();
    band.advance(50.0, &[], &mut ev);
    band.advance(50.0, &changed, &mut ev);
    assert_eq!(ev.len(), 10_000);
    // Delay = max(0, latency + N(0, jitter)): never negative, mean and spread of the clamp.
    let d: Vec<f64> = ev.iter().map(|e| e.t_us - 50.0).collect();
    assert!(d.iter().all(|&d| d >= 0.0));
    let zeros = d.iter().filter(|&&d| d == 0.0).count() as f64 / d.len() as f64;
    // P(N(1, 2) < 0) = Φ(−0.5) = 0.3085
    assert!((zeros - 0.3085).abs() < 0.015, "{zeros}");
    let positive: Vec<f64> = d.iter().copied().filter(|&d| d > 0.0).collect();
    let mean = positive.iter().sum::<f64>() / positive.len() as f64;
    // E[X | X > 0] for X ~ N(1, 2²): 1 + 2·φ(0.5)/Φ(0.5) = 1 + 2·0.3521/0.6915 = 2.018
    assert!((mean - 2.018).abs() < 0.06, "{mean}");
}
