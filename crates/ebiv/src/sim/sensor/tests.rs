//! Physics tests of the pixel model (fixed seeds, exact expectations where the model has them).

mod cubic;
mod detector;
mod noise;
mod readout;
mod timing;

use super::*;
use crate::event::Geometry;
use crate::test_rng::xorshift;

/// Bisection of `f` on `[a, b]` (f(a) < 0 < f(b)): the reference for crossing times.
pub(super) fn bisect(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if f(m) < 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// The irradiance whose log response under `p` is `l` (inverse of the lin-log map).
fn irradiance_for_log(p: &SensorParams, l: f64) -> f32 {
    let knee = p.linlog_threshold;
    let i = if knee > 0.0 {
        if l >= knee.ln() {
            l.exp()
        } else {
            knee * (1.0 + l - knee.ln())
        }
    } else {
        l.exp() - p.log_eps
    };
    i as f32
}

/// The log response of `p` to irradiance `i` (as the model computes it).
fn log_of(p: &SensorParams, i: f32) -> f64 {
    response::Response::new(p).log(response::clean_irradiance(i))
}

/// A one-pixel sensor adapted to irradiance `i0` at t = 0.
fn one_pixel(p: &SensorParams, i0: f32) -> SensorBand {
    let mut band = SensorBand::new(Geometry::new(1, 1), 0..1, p, 1);
    band.adapt(0.0, |_, _| i0);
    band
}

/// Drive pixel 0 of `band` through the samples `(t, irradiance)`; returns its events.
fn drive(band: &mut SensorBand, samples: &[(f64, f32)]) -> Vec<SimEvent> {
    let mut out = Vec::new();
    for &(t, i) in samples {
        band.advance(t, &[(0, i)], &mut out);
    }
    out
}

/// Hold the current input until `t_end` in steps of `step` µs.
fn hold(band: &mut SensorBand, t_end: f64, step: f64, out: &mut Vec<SimEvent>) {
    let mut t = band.time_us();
    while t < t_end {
        t = (t + step).min(t_end);
        band.advance(t, &[], out);
    }
}

/// Params with every timing and noise effect off and no mismatch.
fn quiet(mut p: SensorParams) -> SensorParams {
    p.threshold_sigma = 0.0;
    p.latency_us = 0.0;
    p.jitter_us = 0.0;
    p.refractory_us = 0.0;
    p.leak_rate_hz = 0.0;
    p.shot_noise_rate_hz = 0.0;
    p.hot_pixel_fraction = 0.0;
    p
}

fn count(events: &[SimEvent], p: u8) -> usize {
    events.iter().filter(|e| e.p == p).count()
}

/// Where the processor has AVX2, [`SensorBand::advance`] runs the AVX2 build of the pixel
/// update ([`crate::simd`]): it must give the same events, bit for bit, as the portable build,
/// for a noisy sensor whose pixels see many different irradiance ramps.
#[test]
fn the_avx2_and_portable_pixel_updates_give_the_same_events() {
    let p = SensorParams::noisy();
    let geometry = Geometry::new(37, 5);
    let mut dispatched = SensorBand::new(geometry, 0..5, &p, 9);
    dispatched.adapt(0.0, |x, y| 50.0 + (x * 7 + y * 13) as f32);
    let mut portable = dispatched.clone();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut rng = xorshift(0x2545_f491_4f6c_dd1d);
    for step in 1..=300 {
        let t = step as f64 * 10.0;
        // A deterministic pseudo-random third of the pixels changes at every step.
        let changed: Vec<(u32, f32)> = (0..geometry.width * geometry.height)
            .filter_map(|i| {
                let state = rng();
                (state % 3 == 0).then(|| (i, 5.0 + (state >> 40) as f32 / 1e4))
            })
            .collect();
        dispatched.advance(t, &changed, &mut a);
        portable.begin_step(t);
        for &(i, irr) in &changed {
            portable.set_input(i as usize, irr);
        }
        portable.advance_marked_portable(&mut b);
    }
    assert!(a.len() > 1000, "{} events", a.len());
    assert_eq!(a, b);
    println!(
        "{} events, AVX2 used: {}",
        a.len(),
        crate::simd::avx2_available()
    );
}
