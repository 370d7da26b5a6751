//! Flows without an elementary particle path, integrated with the adaptive Dormand–Prince
//! scheme of [`crate::sim::ode`] (sensor-model.md §6). Each has an invariant that checks the
//! integration: the streamline offset and the speed of the sinusoidal stream, the stream
//! function of the cellular flow.

use super::Flow;
use std::f64::consts::TAU;

/// Sinusoidal stream of constant speed along the curves `y = a sin(2π x / b) + c` (PCM-SA:
/// a = 5 or 6 px, b = 128 px, speed 5 px/ms): `θ = atan(a (2π/b) cos(2π x/b))`,
/// `u = s cos θ`, `v = s sin θ` (sensor-model.md §5).
///
/// Streams of several wavelengths give a method's spatial amplitude response. A positive
/// speed moves to the right. Paths are integrated; `y − a sin(2π x/b)` is conserved
/// ([`Sinusoidal::streamline_offset`]) and the particle covers the arc length `|s| t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sinusoidal {
    /// Amplitude a of the streamlines, px.
    pub amplitude_px: f64,
    /// Wavelength b of the streamlines along x, px.
    pub wavelength_px: f64,
    /// Speed s along the streamlines, px/ms (positive = towards +x).
    pub speed: f64,
}

impl Sinusoidal {
    /// The streamline label `c = y − a sin(2π x / b)`, conserved along paths, px.
    pub fn streamline_offset(&self, x: f64, y: f64) -> f64 {
        y - self.amplitude_px * (TAU * x / self.wavelength_px).sin()
    }

    /// Slope dy/dx of the streamline through `x`.
    pub fn slope(&self, x: f64) -> f64 {
        let k = TAU / self.wavelength_px;
        self.amplitude_px * k * (k * x).cos()
    }
}

impl Flow for Sinusoidal {
    fn velocity(&self, x: f64, _y: f64, _t_us: f64) -> (f64, f64) {
        // cos θ = 1/√(1+m²), sin θ = m/√(1+m²) for θ = atan m.
        let m = self.slope(x);
        let norm = m.hypot(1.0);
        (self.speed / norm, self.speed * m / norm)
    }

    fn max_speed(&self, _w: f64, _h: f64, _t_us: f64) -> f64 {
        self.speed.abs()
    }
}

/// Cellular (Taylor–Green-like) flow `u = V sin(2π x/p) cos(2π y/p)`,
/// `v = −V cos(2π x/p) sin(2π y/p)` (PCM-SA: V = 10 px/ms, p = 128 px): square cells of side
/// p/2 turning alternately, with stagnation points at their corners.
///
/// Paths are integrated; the stream function `ψ = (V p/2π) sin(2π x/p) sin(2π y/p)` is
/// conserved ([`Cellular::stream_function`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cellular {
    /// Velocity amplitude V, px/ms.
    pub amplitude: f64,
    /// Period p of the pattern in x and y, px (one cell is p/2 wide).
    pub period_px: f64,
}

impl Cellular {
    /// The stream function ψ (u = ∂ψ/∂y, v = −∂ψ/∂x), px²/ms.
    pub fn stream_function(&self, x: f64, y: f64) -> f64 {
        let k = TAU / self.period_px;
        self.amplitude / k * (k * x).sin() * (k * y).sin()
    }
}

impl Flow for Cellular {
    fn velocity(&self, x: f64, y: f64, _t_us: f64) -> (f64, f64) {
        let k = TAU / self.period_px;
        let (sx, cx) = (k * x).sin_cos();
        let (sy, cy) = (k * y).sin_cos();
        (self.amplitude * sx * cy, -self.amplitude * cx * sy)
    }

    fn max_speed(&self, _w: f64, _h: f64, _t_us: f64) -> f64 {
        // |u|² + |v|² = V² (sx² cy² + cx² sy²) ≤ V².
        self.amplitude.abs()
    }
}

/// The sum of several flows' velocities (Mendes et al.: Rankine vortex + uniform stream).
/// Paths are integrated, even where every part has a closed form.
#[derive(Debug, Default)]
pub struct Superposition(pub Vec<Box<dyn Flow>>);

impl Flow for Superposition {
    fn velocity(&self, x: f64, y: f64, t_us: f64) -> (f64, f64) {
        self.0.iter().fold((0.0, 0.0), |(u, v), flow| {
            let (du, dv) = flow.velocity(x, y, t_us);
            (u + du, v + dv)
        })
    }

    fn max_speed(&self, w: f64, h: f64, t_us: f64) -> f64 {
        self.0.iter().map(|flow| flow.max_speed(w, h, t_us)).sum()
    }
}
