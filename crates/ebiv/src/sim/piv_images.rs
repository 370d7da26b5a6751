//! Synthetic PIV image pairs with a known displacement field, for testing and Monte-Carlo
//! error analysis (Raffel et al., "Particle Image Velocimetry", 3rd ed., §6.1; the
//! pixel-integrated Gaussian particle image of sensor-model.md §1.1).
//!
//! Each particle has a mid-way position `p`; it is drawn at `p − d(p)/2` in the first frame
//! and at `p + d(p)/2` in the second, so the true displacement at a point is `d` evaluated
//! there (the central-difference convention of symmetric window deformation).

use crate::frame::Frame;
use crate::sim::rng::{Rng, Stream};
use libm::erf;
use serde::{Deserialize, Serialize};

/// How to draw a synthetic particle image pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ParticleImageParams {
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Seeding density, particles per pixel.
    pub density: f64,
    /// Mean particle-image diameter `d_τ` at the e⁻² intensity level, px.
    pub diameter: f64,
    /// Standard deviation of the diameter, px.
    pub diameter_std: f64,
    /// Peak grey value of an in-focus particle centred on a pixel.
    pub brightness: f64,
    /// Standard deviation of additive Gaussian noise, grey values.
    pub noise: f64,
    /// Grey values are rounded and clipped to `0..2^bits − 1`; 0 keeps them continuous.
    pub bits: u32,
}

impl Default for ParticleImageParams {
    fn default() -> Self {
        ParticleImageParams {
            width: 256,
            height: 256,
            density: 0.05,
            diameter: 3.0,
            diameter_std: 0.0,
            brightness: 200.0,
            noise: 0.0,
            bits: 0,
        }
    }
}

/// Add one pixel-integrated Gaussian particle image centred at `(cx, cy)`.
fn draw_particle(frame: &mut Frame, cx: f64, cy: f64, diameter: f64, peak: f64) {
    // Intensity ∝ exp(−8 r²/d²) (e⁻² diameter d), integrated over each pixel's area.
    let k = 8f64.sqrt() / diameter;
    let norm = {
        let e = erf(0.5 * k) - erf(-0.5 * k);
        peak / (e * e)
    };
    let reach = (1.5 * diameter).ceil() as i64 + 1;
    let (w, h) = (frame.width as i64, frame.height as i64);
    let (x0, x1) = (
        (cx.round() as i64 - reach).max(0),
        (cx.round() as i64 + reach).min(w - 1),
    );
    let (y0, y1) = (
        (cy.round() as i64 - reach).max(0),
        (cy.round() as i64 + reach).min(h - 1),
    );
    if x0 > x1 || y0 > y1 {
        return;
    }
    let along = |from: i64, to: i64, c: f64| -> Vec<f64> {
        (from..=to)
            .map(|p| erf((p as f64 + 0.5 - c) * k) - erf((p as f64 - 0.5 - c) * k))
            .collect()
    };
    let (gx, gy) = (along(x0, x1, cx), along(y0, y1, cy));
    for (j, y) in (y0..=y1).enumerate() {
        let row = y as usize * frame.width as usize;
        for (i, x) in (x0..=x1).enumerate() {
            frame.data[row + x as usize] += (norm * gx[i] * gy[j]) as f32;
        }
    }
}

/// Add noise and quantise as `params` ask.
fn finish(frame: &mut Frame, params: &ParticleImageParams, rng: &mut Rng) {
    let max = if params.bits > 0 {
        ((1u64 << params.bits.min(24)) - 1) as f32
    } else {
        f32::INFINITY
    };
    for v in frame.data.iter_mut() {
        if params.noise > 0.0 {
            *v += (params.noise * rng.normal()) as f32;
        }
        if params.bits > 0 {
            *v = v.round().clamp(0.0, max);
        }
    }
}

/// A particle image pair whose displacement at mid-way position `(x, y)` is
/// `displacement(x, y)` px. Particles are seeded uniformly over the frame enlarged by a
/// margin, so that particles entering or leaving at the borders are drawn as well.
pub fn particle_image_pair(
    params: &ParticleImageParams,
    displacement: impl Fn(f64, f64) -> [f64; 2],
    seed: u64,
) -> (Frame, Frame) {
    let mut rng = Rng::new(seed, Stream::Seeding, 0x5EED);
    let margin = 16.0;
    let (w, h) = (params.width as f64, params.height as f64);
    let area = (w + 2.0 * margin) * (h + 2.0 * margin);
    let count = (params.density * area).round() as usize;
    let mut a = Frame::new(params.width, params.height);
    let mut b = Frame::new(params.width, params.height);
    for _ in 0..count {
        let px = -margin + rng.uniform() * (w + 2.0 * margin);
        let py = -margin + rng.uniform() * (h + 2.0 * margin);
        let d = (params.diameter + params.diameter_std * rng.normal()).max(0.5);
        let [dx, dy] = displacement(px, py);
        draw_particle(&mut a, px - dx / 2.0, py - dy / 2.0, d, params.brightness);
        draw_particle(&mut b, px + dx / 2.0, py + dy / 2.0, d, params.brightness);
    }
    finish(&mut a, params, &mut rng);
    finish(&mut b, params, &mut rng);
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_centred_particle_has_the_requested_peak_and_integrated_intensity() {
        let params = ParticleImageParams {
            width: 21,
            height: 21,
            ..Default::default()
        };
        let mut f = Frame::new(params.width, params.height);
        draw_particle(&mut f, 10.0, 10.0, 3.0, 200.0);
        assert!((f.get(10, 10) - 200.0).abs() < 1e-3);
        assert!((f.get(9, 10) - f.get(11, 10)).abs() < 1e-4);
        assert!(f.get(9, 10) < f.get(10, 10) && f.get(9, 10) > 0.0);
        assert_eq!(f.get(0, 0), 0.0);
    }

    #[test]
    fn pairs_are_reproducible_and_shifted() {
        let params = ParticleImageParams {
            width: 64,
            height: 48,
            density: 0.02,
            noise: 2.0,
            bits: 8,
            ..Default::default()
        };
        let (a1, b1) = particle_image_pair(&params, |_, _| [1.5, -0.5], 3);
        let (a2, b2) = particle_image_pair(&params, |_, _| [1.5, -0.5], 3);
        assert_eq!(a1, a2);
        assert_eq!(b1, b2);
        let (a3, _) = particle_image_pair(&params, |_, _| [1.5, -0.5], 4);
        assert_ne!(a1, a3);
        assert!(a1
            .data
            .iter()
            .all(|&v| (0.0..=255.0).contains(&v) && v.fract() == 0.0));
        // Zero displacement: both frames are identical before noise.
        let clean = ParticleImageParams {
            noise: 0.0,
            bits: 0,
            ..params
        };
        let (a, b) = particle_image_pair(&clean, |_, _| [0.0, 0.0], 5);
        assert_eq!(a, b);
    }
}
