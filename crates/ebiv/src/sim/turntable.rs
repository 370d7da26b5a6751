//! Particles on a turntable (solid-body rotation) seen by an ideal event sensor.
//!
//! Each particle is a Gaussian spot (Willert & Klinner 2022 use ~10 µm tracers imaged to a
//! few pixels). The ideal change detector (Gallego et al., "Event-based vision: a survey",
//! IEEE TPAMI 2022, Eq. 1) emits an event whenever a pixel's log intensity has moved by the
//! contrast threshold since its last event. Log intensity is sampled every `step_us`, so time
//! stamps are quantised to that step; this generator has no noise, latency or mismatch.

use crate::event::{EventBuffer, Geometry};

/// Parameters of the turntable recording.
#[derive(Debug, Clone)]
pub struct TurntableSpec {
    /// Sensor size.
    pub geometry: Geometry,
    /// Recording length, µs.
    pub duration_us: i64,
    /// Particles per pixel.
    pub density_ppp: f64,
    /// Gaussian particle-image radius (standard deviation), px.
    pub sigma_px: f64,
    /// Peak particle intensity over the background (arbitrary units; background is 1).
    pub peak_contrast: f64,
    /// Angular velocity, radians per ms (positive = clockwise on screen, since y points down).
    pub omega_rad_per_ms: f64,
    /// Log-intensity contrast threshold for both polarities.
    pub threshold: f64,
    /// Sampling step of the sensor model, µs.
    pub step_us: i64,
    /// Random seed: the same seed gives the same events.
    pub seed: u64,
}

impl Default for TurntableSpec {
    fn default() -> Self {
        TurntableSpec {
            geometry: Geometry::new(320, 240),
            duration_us: 50_000,
            density_ppp: 0.006,
            sigma_px: 0.8,
            peak_contrast: 3.0,
            omega_rad_per_ms: 0.01,
            threshold: 0.3,
            step_us: 10,
            seed: 1,
        }
    }
}

impl TurntableSpec {
    /// The true velocity at pixel `(x, y)`, px/ms.
    pub fn velocity(&self, x: f64, y: f64) -> (f64, f64) {
        let (cx, cy) = self.centre();
        (
            -self.omega_rad_per_ms * (y - cy),
            self.omega_rad_per_ms * (x - cx),
        )
    }

    /// Centre of rotation (the sensor centre), px.
    pub fn centre(&self) -> (f64, f64) {
        (
            (self.geometry.width as f64 - 1.0) / 2.0,
            (self.geometry.height as f64 - 1.0) / 2.0,
        )
    }
}

/// SplitMix64: a tiny, well-tested generator (Steele et al., OOPSLA 2014), so results do not
/// depend on any crate's version.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Generate the recording: events in time order.
pub fn turntable(spec: &TurntableSpec) -> EventBuffer {
    let g = spec.geometry;
    let (w, h) = (g.width as usize, g.height as usize);
    let (cx, cy) = spec.centre();
    let mut rng = SplitMix64(spec.seed);
    // Seed the whole disc the frame rotates through, so the view never empties.
    let radius = (cx * cx + cy * cy).sqrt() + 4.0;
    let disc_area = std::f64::consts::PI * radius * radius;
    let n = (spec.density_ppp * disc_area).round() as usize;
    let particles: Vec<(f64, f64)> = (0..n)
        .map(|_| {
            let r = radius * rng.next_f64().sqrt();
            let a = std::f64::consts::TAU * rng.next_f64();
            (r * a.cos(), r * a.sin())
        })
        .collect();
    let reach = (3.0 * spec.sigma_px).ceil() as i64;
    let inv_two_sigma2 = 1.0 / (2.0 * spec.sigma_px * spec.sigma_px);
    let mut intensity = vec![1.0f32; w * h];
    let mut reference = vec![0.0f32; w * h]; // log(1) = 0: the background
    let mut touched: Vec<usize> = Vec::new();
    let mut previously: Vec<usize> = Vec::new();
    let mut mark = vec![false; w * h];
    let mut events = EventBuffer::new();
    let threshold = spec.threshold as f32;
    let mut t = 0;
    while t <= spec.duration_us {
        let angle = spec.omega_rad_per_ms * t as f64 * 1e-3;
        let (sin, cos) = angle.sin_cos();
        for &i in &previously {
            intensity[i] = 1.0;
        }
        touched.clear();
        for &(px, py) in &particles {
            let x = cx + px * cos - py * sin;
            let y = cy + px * sin + py * cos;
            let (xi, yi) = (x.round() as i64, y.round() as i64);
            for yy in (yi - reach).max(0)..=(yi + reach).min(h as i64 - 1) {
                for xx in (xi - reach).max(0)..=(xi + reach).min(w as i64 - 1) {
                    let d2 = (xx as f64 - x).powi(2) + (yy as f64 - y).powi(2);
                    let i = yy as usize * w + xx as usize;
                    intensity[i] += (spec.peak_contrast * (-d2 * inv_two_sigma2).exp()) as f32;
                    if !mark[i] {
                        mark[i] = true;
                        touched.push(i);
                    }
                }
            }
        }
        // Pixels lit now or a step ago may have changed. At t = 0 the sensor has adapted
        // to the scene already: references start at the first image.
        for &i in previously.iter().chain(touched.iter()) {
            let level = intensity[i].ln();
            if t == 0 {
                reference[i] = level;
                continue;
            }
            while level - reference[i] >= threshold {
                reference[i] += threshold;
                events.push(t, (i % w) as u16, (i / w) as u16, 1);
            }
            while reference[i] - level >= threshold {
                reference[i] -= threshold;
                events.push(t, (i % w) as u16, (i / w) as u16, 0);
            }
        }
        for &i in &touched {
            mark[i] = false;
        }
        std::mem::swap(&mut previously, &mut touched);
        t += spec.step_us;
    }
    events
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_events_and_both_polarities() {
        let spec = TurntableSpec {
            geometry: Geometry::new(64, 48),
            duration_us: 5_000,
            density_ppp: 0.03,
            ..Default::default()
        };
        let a = turntable(&spec);
        let b = turntable(&spec);
        assert_eq!(a, b);
        assert!(a.len() > 1000, "{} events", a.len());
        let on = a.count_on();
        assert!(on > a.len() / 4 && on < 3 * a.len() / 4);
        assert!(a.is_time_sorted());
    }

    #[test]
    fn events_follow_the_rotation() {
        // Events warped back to t0 by the true rotation give the sharpest image (the
        // contrast-maximisation principle); no rotation, the opposite one or a 50 % faster one
        // blur it.
        let spec = TurntableSpec {
            geometry: Geometry::new(96, 96),
            duration_us: 20_000,
            density_ppp: 0.01,
            ..Default::default()
        };
        let ev = turntable(&spec);
        let (cx, cy) = spec.centre();
        let t0 = 10_000;
        let sharpness = |omega: f64| {
            let mut img = vec![0u32; 96 * 96];
            for e in ev.iter().filter(|e| (e.t - t0).abs() <= 5000 && e.p == 1) {
                let a = -omega * (e.t - t0) as f64 * 1e-3;
                let (s, c) = a.sin_cos();
                let (dx, dy) = (e.x as f64 - cx, e.y as f64 - cy);
                let x = (cx + dx * c - dy * s).round();
                let y = (cy + dx * s + dy * c).round();
                if (0.0..96.0).contains(&x) && (0.0..96.0).contains(&y) {
                    img[y as usize * 96 + x as usize] += 1;
                }
            }
            img.iter().map(|&v| (v * v) as u64).sum::<u64>()
        };
        let w = spec.omega_rad_per_ms;
        let truth = sharpness(w);
        for other in [0.0, -w, 1.5 * w, 0.5 * w] {
            assert!(
                truth > sharpness(other),
                "omega {other} is as sharp as the truth"
            );
        }
    }
}
