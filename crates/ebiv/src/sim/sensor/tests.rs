//! Physics tests of the pixel model (fixed seeds, exact expectations where the model has them).

mod detector;
mod noise;
mod readout;
mod timing;

use super::*;
use crate::event::Geometry;

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
