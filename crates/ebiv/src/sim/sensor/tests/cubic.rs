//! The cubic Hermite interpolation of a pixel's input between samples
//! ([`SensorBand::push_input_sloped`]).

use super::*;
use crate::sim::sensor::detector::Hermite;
use crate::sim::sensor::response::{Curve, Relaxation};

/// `L(h)` of `dL/dτ = ω·(u(τ) − L)` from `la`, by the classical Runge–Kutta scheme in `n`
/// steps: the reference for the closed form.
fn runge_kutta(cubic: &Hermite, la: f64, omega: f64, n: usize) -> f64 {
    let (ua, ub, ma, mb, h) = (cubic.ua, cubic.ub, cubic.ma, cubic.mb, cubic.h);
    let u = |t: f64| {
        let s = t / h;
        let (h00, h10) = (
            2.0 * s * s * s - 3.0 * s * s + 1.0,
            s * s * s - 2.0 * s * s + s,
        );
        let (h01, h11) = (-2.0 * s * s * s + 3.0 * s * s, s * s * s - s * s);
        h00 * ua + h10 * h * ma + h01 * ub + h11 * h * mb
    };
    let f = |t: f64, l: f64| omega * (u(t) - l);
    let dt = h / n as f64;
    let mut l = la;
    for k in 0..n {
        let t = k as f64 * dt;
        let k1 = f(t, l);
        let k2 = f(t + 0.5 * dt, l + 0.5 * dt * k1);
        let k3 = f(t + 0.5 * dt, l + 0.5 * dt * k2);
        let k4 = f(t + dt, l + dt * k3);
        l += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    l
}

#[test]
fn the_cubic_input_low_pass_end_value_solves_the_filter() {
    // (ω·h, ua, ub, ma·h, mb·h, la): rising and falling inputs, overshooting slopes, an
    // input that turns inside the step, and the smallest ω·h the closed form is used for.
    let cases = [
        (0.5, 0.0, 0.3, 0.9, -0.2, 0.1),
        (1.0, 0.2, -0.4, 0.0, 0.0, 0.2),
        (2.5, 1.0, 1.0, 1.5, -1.5, 0.7),
        (6.0, -0.5, 0.8, 2.0, 0.1, -0.6),
        (20.0, 0.0, 1.79, 0.3, 3.0, -0.1),
    ];
    for (oh, ua, ub, mah, mbh, la) in cases {
        let h = 166.0;
        let omega = oh / h;
        let cubic = Hermite {
            ua,
            ub,
            ma: mah / h,
            mb: mbh / h,
            h,
            inv_h: 1.0 / h,
        };
        let closed = cubic.low_pass_end(la, 1.0 / omega, Relaxation::new(omega, h));
        let reference = runge_kutta(&cubic, la, omega, 20_000);
        assert!(
            (closed - reference).abs() < 1e-11,
            "ω·h {oh}: {closed} against {reference}"
        );
    }
    // With the secant's slope at both ends the cubic is the linear ramp.
    let (h, omega, ua, ub, la) = (200.0, 0.01, 0.1, 0.9, -0.3);
    let m = (ub - ua) / h;
    let cubic = Hermite {
        ua,
        ub,
        ma: m,
        mb: m,
        h,
        inv_h: 1.0 / h,
    };
    let closed = cubic.low_pass_end(la, 1.0 / omega, Relaxation::new(omega, h));
    let ramp = Curve::low_pass(0.0, h, la, ua, ub, omega).end_value();
    assert!((closed - ramp).abs() < 1e-13, "{closed} against {ramp}");
}

/// A bright particle passing one pixel (log input rising by about 1.8 and falling back):
/// sampled every 200 µs with its exact slopes, the events come much closer to those of a
/// sampling every microsecond than with straight lines between the same samples.
#[test]
fn cubic_samples_follow_a_passing_particle_closer_than_ramps() {
    let p = quiet(SensorParams::gen4());
    let irradiance = |t: f64| 1.0 + 5.0 * (-((t - 3000.0) / 500.0).powi(2)).exp();
    let slope = |t: f64| {
        let z = (t - 3000.0) / 500.0;
        -5.0 * 2.0 * z / 500.0 * (-z * z).exp()
    };
    let run = |step: f64, cubic: bool| {
        let mut band = one_pixel(&p, 1.0);
        let mut out = Vec::new();
        let mut t = 0.0;
        while t < 6000.0 {
            t += step;
            band.begin_step(t);
            if cubic {
                band.push_input_sloped(0, irradiance(t) as f32, slope(t) as f32);
            } else {
                band.push_input(0, irradiance(t) as f32);
            }
            band.advance_marked(&mut out);
        }
        hold(&mut band, 8000.0, 100.0, &mut out);
        out
    };
    let reference = run(1.0, false);
    let (ramps, cubic) = (run(200.0, false), run(200.0, true));
    assert!(count(&reference, 1) >= 7, "{reference:?}");
    assert!(count(&reference, 0) >= 7, "{reference:?}");
    let same_counts = |events: &[SimEvent]| {
        [0, 1]
            .iter()
            .all(|&pol| count(events, pol) == count(&reference, pol))
    };
    // Mean distance in time of the k-th event of each polarity from the reference's.
    let distance = |events: &[SimEvent]| -> f64 {
        let total: f64 = [0u8, 1]
            .iter()
            .map(|&pol| {
                let times = |e: &[SimEvent]| -> Vec<f64> {
                    e.iter().filter(|e| e.p == pol).map(|e| e.t_us).collect()
                };
                times(events)
                    .iter()
                    .zip(times(&reference))
                    .map(|(a, b)| (a - b).abs())
                    .sum::<f64>()
            })
            .sum();
        total / reference.len() as f64
    };
    let (d_ramps, d_cubic) = (distance(&ramps), distance(&cubic));
    println!(
        "{} events; ramps: {} events, mean |Δt| {d_ramps:.2} µs; cubic: {} events, {d_cubic:.2} µs",
        reference.len(),
        ramps.len(),
        cubic.len()
    );
    assert!(same_counts(&cubic), "{cubic:?}");
    assert!(d_cubic < 2.0, "{d_cubic}");
    // The straight lines lose events or place them at least three times farther.
    assert!(!same_counts(&ramps) || d_ramps > 3.0 * d_cubic, "{d_ramps}");
}

/// A step whose samples come without slopes is a linear ramp, also after sloped steps.
#[test]
fn steps_without_slopes_are_ramps() {
    let p = quiet(SensorParams::gen4());
    let samples = [(200.0, 2.0f32), (400.0, 4.0), (600.0, 3.0), (800.0, 1.0)];
    let mut plain = one_pixel(&p, 1.0);
    let mut expected = drive(&mut plain, &[(100.0, 1.0)]);
    expected.extend(drive(&mut plain, &samples));
    let mut band = one_pixel(&p, 1.0);
    let mut out = Vec::new();
    band.begin_step(100.0);
    band.push_input_sloped(0, 1.0, 0.0);
    band.advance_marked(&mut out);
    for &(t, i) in &samples {
        band.advance(t, &[(0, i)], &mut out);
    }
    assert!(!expected.is_empty());
    assert_eq!(out, expected);
}

/// One pixel through quiet sloped steps (no level reached): after each step its `L` is the
/// exact low-pass of the cubic that starts with the slope of the pixel's last sample, or
/// flat after a ramp or a held input, as Runge–Kutta integrates it.
#[test]
fn a_pixels_cubic_starts_with_the_slope_of_its_last_sample_or_flat() {
    let p = quiet(SensorParams::gen4());
    let r = response::Response::new(&p);
    let h = 100.0;
    // (time, irradiance, slope per µs or None for a ramp, sampled at all)
    let steps: [(f64, f32, Option<f32>, bool); 6] = [
        (100.0, 1.05, Some(5e-4), true),
        (200.0, 1.08, Some(2e-4), true), // starts with the first step's slope
        (300.0, 1.10, None, true),       // a ramp
        (400.0, 1.12, Some(3e-4), true), // starts flat after the ramp
        (500.0, 1.12, None, false),      // held (no sample, the pixel asleep)
        (600.0, 1.15, Some(-1e-4), true), // starts flat after the held input
    ];
    let mut band = one_pixel(&p, 1.0);
    let mut out = Vec::new();
    let (mut l, mut ia, mut ma, mut t_last) = (0.0f64, 1.0f32, 0.0f64, 0.0);
    for (t, ib, slope, sampled) in steps {
        band.begin_step(t);
        match (sampled, slope) {
            (true, Some(s)) => band.push_input_sloped(0, ib, s),
            (true, None) => band.push_input(0, ib),
            (false, _) => {}
        }
        band.advance_marked(&mut out);
        if !sampled {
            continue;
        }
        let (ua, ub) = (r.log(ia), r.log(ib));
        let omega = r.omega(0.5 * (ia as f64 + ib as f64));
        // The held stretch since the last sample first: constant input.
        let start = t - h;
        l = ua + (l - ua) * (-r.omega(ia as f64) * (start - t_last)).exp();
        let ma_step = if t_last < start { 0.0 } else { ma };
        let mb = slope.map_or(0.0, |s| (s as f64 * r.log_slope(ib as f64)) as f32 as f64);
        l = match slope {
            Some(_) => {
                let cubic = Hermite {
                    ua,
                    ub,
                    ma: ma_step,
                    mb,
                    h,
                    inv_h: 1.0 / h,
                };
                runge_kutta(&cubic, l, omega, 20_000)
            }
            None => Curve::low_pass(0.0, h, l, ua, ub, omega).end_value(),
        };
        let (got, _) = band.log_state(0, 0).unwrap();
        assert!((got - l).abs() < 1e-10, "at {t} µs: {got} against {l}");
        (ia, ma, t_last) = (ib, mb, t);
    }
    assert!(out.is_empty(), "{out:?}");
}
