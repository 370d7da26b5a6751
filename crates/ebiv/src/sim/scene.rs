//! What the sensor looks at: background, a bright static wall, and particle images lit by a
//! continuous or pulsed light sheet (sensor-model.md §1).
//!
//! Irradiance is in units of the background (1 by default). A particle image is the
//! pixel-integrated Gaussian ("erf form", sensor-model.md §1.1) with s = d_τ/√8, normalised so
//! that an in-focus particle centred on a pixel gives that pixel its `brightness`; pixels that
//! would receive less than [`IMAGE_FLOOR`] of the background from a particle are left out of
//! its image.

use super::fastmath::{self, ceil_i64, floor_i64, Erf};
use super::particles::{Particle, SeedingParams};
use crate::error::{Error, Result};
use crate::event::Geometry;

/// How the light sheet is switched.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LightMode {
    /// Always on (the EBIV paper's CW laser).
    Continuous,
    /// On for `duty` of every period of `frequency_hz` (pulsed EBIV, Willert 2023).
    Pulsed,
}

/// A stationary bright object (e.g. a wall reflecting the sheet) that hides the particles
/// behind it and must produce no events.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Wall {
    /// Left column, px.
    pub x: f64,
    /// Top row, px.
    pub y: f64,
    /// Width, px.
    pub width: f64,
    /// Height, px.
    pub height: f64,
    /// Irradiance, background units.
    pub brightness: f64,
}

/// Illumination and static scene content.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct IlluminationParams {
    /// Ambient irradiance where no particle is (background units; 1 unless the sensor preset
    /// is calibrated to another scale).
    pub background: f64,
    /// Continuous or pulsed light sheet.
    pub mode: LightMode,
    /// Pulse frequency, Hz (pulsed mode).
    pub frequency_hz: f64,
    /// Fraction of each period the sheet is on (pulsed mode).
    pub duty: f64,
    /// Time of the first rising edge, µs.
    pub phase_us: f64,
    /// Rise and fall time of a pulse, µs.
    pub edge_us: f64,
    /// Ambient-light flicker frequency, Hz (0 = none), e.g. 100 Hz from mains lighting.
    pub flicker_hz: f64,
    /// Relative flicker amplitude of the ambient light (0..1).
    pub flicker_amplitude: f64,
    /// Stationary bright objects.
    pub walls: Vec<Wall>,
}

impl Default for IlluminationParams {
    fn default() -> Self {
        IlluminationParams {
            background: 1.0,
            mode: LightMode::Continuous,
            frequency_hz: 1000.0,
            duty: 0.1,
            phase_us: 0.0,
            edge_us: 1.0,
            flicker_hz: 0.0,
            flicker_amplitude: 0.0,
            walls: Vec::new(),
        }
    }
}

impl IlluminationParams {
    /// Whether the light is continuous and without flicker: steady apart from the particles,
    /// as [`crate::sim::simulation::Interpolation::Cubic`] needs (it models no slopes of the
    /// light itself).
    pub fn steady(&self) -> bool {
        self.mode == LightMode::Continuous && self.flicker_hz <= 0.0
    }

    /// Check every value, naming the offending key.
    pub fn validate(&self) -> Result<()> {
        let bad = |k: &str, v: f64, allowed: &str| {
            Err(Error::parameter(
                format!("illumination.{k}"),
                format!("{v} is out of range: must be {allowed}"),
            ))
        };
        if !(self.background > 0.0 && self.background.is_finite()) {
            return bad("background", self.background, "finite and above 0");
        }
        if self.mode == LightMode::Pulsed {
            if !(self.frequency_hz > 0.0 && self.frequency_hz <= 1e6) {
                return bad("frequency_hz", self.frequency_hz, "in (0, 1e6] Hz");
            }
            if !(self.duty > 0.0 && self.duty < 1.0) {
                return bad("duty", self.duty, "in (0, 1)");
            }
            let period = 1e6 / self.frequency_hz;
            let longest = 0.5 * self.duty.min(1.0 - self.duty) * period;
            if !(self.edge_us > 0.0 && 2.0 * self.edge_us < self.duty.min(1.0 - self.duty) * period)
            {
                return bad(
                    "edge_us",
                    self.edge_us,
                    &format!("above 0 and below {longest} µs (half the shorter of pulse and gap)"),
                );
            }
        }
        if !(self.flicker_hz >= 0.0 && self.flicker_hz.is_finite()) {
            return bad("flicker_hz", self.flicker_hz, "finite and at least 0");
        }
        if !(0.0..1.0).contains(&self.flicker_amplitude) {
            return bad("flicker_amplitude", self.flicker_amplitude, "in [0, 1)");
        }
        for (i, w) in self.walls.iter().enumerate() {
            let fields = [
                ("x", w.x, w.x.is_finite(), "finite"),
                ("y", w.y, w.y.is_finite(), "finite"),
                ("width", w.width, w.width > 0.0, "finite and above 0"),
                ("height", w.height, w.height > 0.0, "finite and above 0"),
                (
                    "brightness",
                    w.brightness,
                    w.brightness > 0.0,
                    "finite and above 0",
                ),
            ];
            for (key, value, ok, allowed) in fields {
                if !(ok && value.is_finite()) {
                    return bad(&format!("walls[{i}].{key}"), value, allowed);
                }
            }
        }
        Ok(())
    }

    /// Light-sheet intensity factor at `t_us` (0..1): trapezoidal pulses in pulsed mode.
    pub fn sheet(&self, t_us: f64) -> f64 {
        if self.mode == LightMode::Continuous {
            return 1.0;
        }
        let period = 1e6 / self.frequency_hz;
        let on = self.duty * period;
        let phase = (t_us - self.phase_us).rem_euclid(period);
        let e = self.edge_us;
        if phase < e {
            phase / e
        } else if phase < on {
            1.0
        } else if phase < on + e {
            1.0 - (phase - on) / e
        } else {
            0.0
        }
    }

    /// The corners of the pulse shape in `(t0, t1]`, where the sampling must not step over.
    pub fn corners(&self, t0_us: f64, t1_us: f64) -> Vec<f64> {
        if self.mode == LightMode::Continuous {
            return Vec::new();
        }
        let period = 1e6 / self.frequency_hz;
        let on = self.duty * period;
        let mut out = Vec::new();
        let first = ((t0_us - self.phase_us) / period).floor() as i64;
        let last = ((t1_us - self.phase_us) / period).ceil() as i64;
        for k in first..=last {
            let start = self.phase_us + k as f64 * period;
            for c in [
                start,
                start + self.edge_us,
                start + on,
                start + on + self.edge_us,
            ] {
                if c > t0_us && c <= t1_us {
                    out.push(c);
                }
            }
        }
        out
    }

    /// Ambient irradiance of pixel `(x, y)` at `t_us`: background with flicker, or a wall.
    #[inline]
    pub fn ambient(&self, x: u32, y: u32, t_us: f64) -> f32 {
        let (xf, yf) = (x as f64, y as f64);
        for w in &self.walls {
            if xf >= w.x && xf < w.x + w.width && yf >= w.y && yf < w.y + w.height {
                return w.brightness as f32;
            }
        }
        let flicker = if self.flicker_hz > 0.0 {
            1.0 + self.flicker_amplitude
                * (std::f64::consts::TAU * self.flicker_hz * t_us * 1e-6).sin()
        } else {
            1.0
        };
        (self.background * flicker) as f32
    }

    /// Whether pixel `(x, y)` is hidden behind a wall.
    #[inline]
    pub fn occluded(&self, x: u32, y: u32) -> bool {
        let (xf, yf) = (x as f64, y as f64);
        self.walls
            .iter()
            .any(|w| xf >= w.x && xf < w.x + w.width && yf >= w.y && yf < w.y + w.height)
    }
}

/// Renders particle images into the irradiance of a band of sensor rows.
pub struct ParticleRenderer<'a> {
    seeding: &'a SeedingParams,
    illumination: &'a IlluminationParams,
    geometry: Geometry,
    ex: Vec<f64>,
    ey: Vec<f64>,
    dex: Vec<f64>,
    dey: Vec<f64>,
    erf: Erf,
}

impl<'a> ParticleRenderer<'a> {
    /// A renderer for a sensor of `geometry`.
    pub fn new(
        seeding: &'a SeedingParams,
        illumination: &'a IlluminationParams,
        geometry: Geometry,
    ) -> Self {
        ParticleRenderer {
            seeding,
            illumination,
            geometry,
            ex: Vec::new(),
            ey: Vec::new(),
            dex: Vec::new(),
            dey: Vec::new(),
            erf: Erf::new(),
        }
    }

    /// The peak irradiance of `p`'s image at light factor `light`: its brightness dimmed by
    /// its place in the light sheet (sensor-model.md §1.2).
    #[inline]
    fn peak(&self, p: &Particle, light: f64) -> f64 {
        p.brightness * self.seeding.sheet_profile(p.z) * light
    }

    /// The relative rate of change (1/µs) of `p`'s image brightness as it moves through the
    /// light sheet: `d ln(profile(z))/dt = −16·z·w/Δz0²` ([`SeedingParams::sheet_profile`]).
    pub fn fade_rate(&self, p: &Particle) -> f64 {
        let t = self.seeding.sheet_thickness;
        -16.0 * p.z * p.w * 1e-3 / (t * t)
    }

    /// The irradiance below which a particle's contribution to a pixel is left out of its
    /// image: [`IMAGE_FLOOR`] of the background.
    #[inline]
    fn floor(&self) -> f64 {
        IMAGE_FLOOR * self.illumination.background
    }

    /// The image of `p` at light factor `light`, or `None` when no pixel would receive
    /// [`IMAGE_FLOOR`] of the background from it.
    ///
    /// Its box holds every pixel above the floor: a pixel at distance `D ≥ ½` along one axis
    /// collects at most `c·exp(−8 (D − ½)²/d_τ²)` of the peak along that axis (the Gaussian
    /// at the pixel's near edge times the pixel width, over the centred pixel's share;
    /// `c = 2/(√π·s·n)`, `n = 2 erf(1/(2s))`), and at most 1 along the other axis.
    pub fn spot(&self, p: &Particle, light: f64) -> Option<Spot> {
        let peak = self.peak(p, light);
        let floor = self.floor();
        if peak.is_nan() || peak < floor {
            return None;
        }
        let s = p.diameter / std::f64::consts::SQRT_2 / 2.0;
        let norm = 2.0 * self.erf.eval(0.5 / s);
        let c = (std::f64::consts::FRAC_2_SQRT_PI / (s * norm)).max(1.0);
        let reach = p.diameter * ((c * peak / floor).ln() / 8.0).sqrt() + 0.5;
        let scale = peak / (norm * norm);
        Some(Spot {
            x: p.x,
            y: p.y,
            inv_s: 1.0 / s,
            scale,
            // A pixel gets `scale·ex·ey` with `ex, ey ≤ n`: a row or column whose factor is
            // below `floor/(scale·n)` holds no pixel above the floor.
            line_floor: floor / (scale * norm),
            reach,
        })
    }

    /// The rows `(first, last)` the image of `p` at light factor `light` may reach (not
    /// clipped to the sensor), or `None` when [`ParticleRenderer::add`] would draw nothing.
    pub fn rows_reached(&self, p: &Particle, light: f64) -> Option<(i64, i64)> {
        self.spot(p, light).map(|s| s.rows())
    }

    /// Add the image of `p` at light factor `light` to the band holding rows `rows` (stored
    /// row-major in `acc`, one entry per pixel of the band, 0 where nothing is drawn yet);
    /// every pixel first written (its entry was 0) is appended to `touched` (its index within
    /// the band). Every contribution drawn is positive (or NaN, for an infinitely bright
    /// particle), so an entry is 0 exactly while no image has been drawn on it.
    pub fn add(
        &mut self,
        p: &Particle,
        light: f64,
        rows: std::ops::Range<u32>,
        acc: &mut [f32],
        touched: &mut Vec<u32>,
    ) {
        if let Some(spot) = self.spot(p, light) {
            self.draw(&spot, rows, acc, touched);
        }
    }

    /// [`ParticleRenderer::add`] of a prepared [`ParticleRenderer::spot`].
    ///
    /// Pixels that would receive less than [`IMAGE_FLOOR`] of the background are left out:
    /// such light moves a pixel's log intensity by less than 1e-3, 1/200 of a threshold of
    /// ≈ 0.2 ln units. Drawing only the pixels above the floor (a disc, smaller for dim,
    /// out-of-focus particles) rather than a square around the particle spares the sensor
    /// model about two thirds of its pixel updates.
    pub fn draw(
        &mut self,
        spot: &Spot,
        rows: std::ops::Range<u32>,
        acc: &mut [f32],
        touched: &mut Vec<u32>,
    ) {
        self.draw_with::<false>(spot, &SpotMotion::default(), rows, acc, &mut [], touched);
    }

    /// [`ParticleRenderer::draw`], also adding to `dacc` (laid out as `acc`) the time
    /// derivative of each pixel's light, per µs, as the image changes by `motion`: its
    /// centre's velocity (`−v·∇` of the pixel-edge erf integrals) and its brightness change
    /// ([`ParticleRenderer::fade_rate`]), for [`crate::sim::simulation::Interpolation::Cubic`].
    /// `acc` and `touched` get exactly what [`ParticleRenderer::draw`] gives them.
    pub fn draw_sloped(
        &mut self,
        spot: &Spot,
        motion: &SpotMotion,
        rows: std::ops::Range<u32>,
        acc: &mut [f32],
        dacc: &mut [f32],
        touched: &mut Vec<u32>,
    ) {
        self.draw_with::<true>(spot, motion, rows, acc, dacc, touched);
    }

    /// [`ParticleRenderer::draw`], and with `SLOPES` [`ParticleRenderer::draw_sloped`].
    #[inline(always)]
    fn draw_with<const SLOPES: bool>(
        &mut self,
        spot: &Spot,
        motion: &SpotMotion,
        rows: std::ops::Range<u32>,
        acc: &mut [f32],
        dacc: &mut [f32],
        touched: &mut Vec<u32>,
    ) {
        let r = spot.reach;
        let w = self.geometry.width as i64;
        let x0 = floor_i64(spot.x - r).max(0);
        let x1 = ceil_i64(spot.x + r).min(w - 1);
        let y0 = floor_i64(spot.y - r).max(rows.start as i64);
        let y1 = ceil_i64(spot.y + r).min(rows.end as i64 - 1);
        if x0 > x1 || y0 > y1 {
            return;
        }
        let floor = self.floor();
        let scale = spot.scale;
        integrate_axis(self.erf, &mut self.ey, y0, y1, spot.y, spot.inv_s);
        let Some(first) = self.ey.iter().position(|&e| e >= spot.line_floor) else {
            return;
        };
        integrate_axis(self.erf, &mut self.ex, x0, x1, spot.x, spot.inv_s);
        if SLOPES {
            edge_slopes(&mut self.dey, y0, y1, spot.y, spot.inv_s);
            edge_slopes(&mut self.dex, x0, x1, spot.x, spot.inv_s);
        }
        let walls = !self.illumination.walls.is_empty();
        let fade = motion.fade as f32;
        let (x0, x1) = (x0 as usize, x1 as usize);
        for (j, yy) in (y0..=y1).enumerate().skip(first) {
            if self.ey[j] < spot.line_floor {
                continue;
            }
            let wy = self.ey[j] * scale;
            let pixel_floor = floor / wy;
            let row = (yy - rows.start as i64) as usize * w as usize;
            let span = row + x0..=row + x1;
            let pixels = acc[span].iter_mut().zip(&self.ex[..=x1 - x0]);
            for (i, (a, &wx)) in pixels.enumerate() {
                if wx < pixel_floor {
                    continue;
                }
                let xx = x0 + i;
                if walls && self.illumination.occluded(xx as u32, yy as u32) {
                    continue;
                }
                let light = (wy * wx) as f32;
                // Not zero, or nothing is drawn (a background so dark that the light
                // underflows), so that `acc` is 0 exactly where no image lies.
                if light <= 0.0 {
                    continue;
                }
                if *a == 0.0 {
                    touched.push((row + xx) as u32);
                }
                *a += light;
                if SLOPES {
                    // d(ex·ey)/dt = ex′·ẋ·ey + ex·ey′·ẏ, the primes by the centre.
                    let moving =
                        wy * self.dex[i] * motion.vx + self.dey[j] * scale * motion.vy * wx;
                    dacc[row + xx] += moving as f32 + light * fade;
                }
            }
        }
    }
}

/// The derivative of [`integrate_axis`]'s values with respect to the centre `c`:
/// `−(2/√π)/s·(e^(−z_r²) − e^(−z_l²))` at each pixel's right and left edges. The Gaussians of
/// edges `z_k = z_0 + k·δ` (`δ = 1/s`) follow from three exponentials by the recurrence
/// `g_(k+1) = g_k·r_k`, `r_(k+1) = r_k·e^(−2δ²)` (`r_k = e^(−2z_kδ − δ²)`).
fn edge_slopes(out: &mut Vec<f64>, lo: i64, hi: i64, c: f64, inv_s: f64) {
    let n = usize::try_from(hi - lo + 1).unwrap_or(0);
    out.clear();
    let z0 = (lo as f64 - c - 0.5) * inv_s;
    let d = inv_s;
    let mut g = fastmath::exp(-(z0 * z0));
    let mut r = fastmath::exp(-(2.0 * z0 * d + d * d));
    let q = fastmath::exp(-2.0 * d * d);
    let k = -std::f64::consts::FRAC_2_SQRT_PI * inv_s;
    // Far from a normal range (images of absurd brightness reach that far) the recurrence
    // would lose its precision: one exponential per edge instead.
    if !(r.is_finite() && g > 1e-250) {
        let gauss = |i: i64| {
            let z = (i as f64 - c - 0.5) * inv_s;
            fastmath::exp(-(z * z))
        };
        out.extend((lo..=hi).map(|i| k * (gauss(i + 1) - gauss(i))));
        return;
    }
    out.extend((0..n).map(|_| {
        let right = g * r;
        let slope = k * (right - g);
        g = right;
        r *= q;
        slope
    }));
}

/// A particle image at one sample, ready to draw ([`ParticleRenderer::spot`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spot {
    /// Centre, px.
    pub x: f64,
    /// Centre, px.
    pub y: f64,
    /// `1/s`, s = d_τ/√8 the Gaussian scale of the erf form, 1/px.
    inv_s: f64,
    /// Pixel value per product of the two axis integrals: `peak/n²`.
    scale: f64,
    /// Smallest axis integral of a row or column with a pixel above the floor.
    line_floor: f64,
    /// Half-size of the box holding every pixel above the floor, px.
    reach: f64,
}

/// How a particle image changes at a sample, for [`ParticleRenderer::draw_sloped`] (kept apart
/// from its [`Spot`], which only [`crate::sim::simulation::Interpolation::Cubic`] needs).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SpotMotion {
    /// Velocity of the centre, px/µs.
    pub vx: f64,
    /// Velocity of the centre, px/µs.
    pub vy: f64,
    /// Relative rate of change of the image's brightness ([`ParticleRenderer::fade_rate`]),
    /// 1/µs.
    pub fade: f64,
}

impl Spot {
    /// The same image centred at `(x, y)`: what [`ParticleRenderer::spot`] gives for the same
    /// particle moved there (nothing else of an image depends on the particle's position).
    pub(crate) fn centred_at(self, x: f64, y: f64) -> Spot {
        Spot { x, y, ..self }
    }

    /// The rows `(first, last)` the image may reach (not clipped to the sensor).
    pub fn rows(&self) -> (i64, i64) {
        (
            floor_i64(self.y - self.reach),
            ceil_i64(self.y + self.reach),
        )
    }
}

/// The smallest particle contribution to a pixel that is rendered, as a fraction of the
/// background irradiance: 1e-3, a change of 1e-3 ln units, 1/200 of a 0.2 threshold.
///
/// Measured against a floor of 1e-4 on 100 ms of a 1280×720 uniform flow of 0.00152
/// particles per pixel (`gen4`):
/// 98 % of the events are identical to the µs (mean |Δt| 0.16 µs), the event count changes
/// by 7 in 2.1 M, and both floors are equally far from a reference sampled five times finer
/// (0.05 px per step: median |Δt| 3 µs, mean 12.4 µs, the error of the 0.25 px time
/// sampling), so the cut is about two orders of magnitude below the model's sampling error.
/// The simulator runs 9–11 % faster than with 1e-4 (fewer pixels per particle image: for a
/// 2.5 px particle of peak 5, the disc above the floor shrinks from a radius of about 2.9 px
/// to 2.6 px).
pub const IMAGE_FLOOR: f64 = 1e-3;

/// Fraction of a unit Gaussian line spread (scale `s`) falling on each pixel `lo..=hi` around
/// centre `c` (`inv_s` = 1/s): erf((i − c + ½)/s) − erf((i − c − ½)/s), each to within 1e-15
/// ([`Erf`]); with AVX2 ([`crate::simd`]) four edges per instruction ([`Erf::eval4_avx2`]),
/// the same values bit for bit.
fn integrate_axis(erf: Erf, out: &mut Vec<f64>, lo: i64, hi: i64, c: f64, inv_s: f64) {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx2_available() {
        // SAFETY: the processor has AVX2 (`avx2_available`).
        return unsafe { integrate_axis_avx2(erf, out, lo, hi, c, inv_s) };
    }
    integrate_axis_with(
        out,
        lo,
        hi,
        c,
        inv_s,
        |x| erf.eval(x),
        |x| erf.eval_lanes(x),
    )
}

/// [`integrate_axis`] with [`Erf::eval4_avx2`].
///
/// # Safety
/// Only where the processor has AVX2 ([`crate::simd::avx2_available`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn integrate_axis_avx2(erf: Erf, out: &mut Vec<f64>, lo: i64, hi: i64, c: f64, inv_s: f64) {
    // SAFETY: this function runs only where the processor has AVX2.
    let lanes = |x| unsafe { erf.eval4_avx2(x) };
    integrate_axis_with(out, lo, hi, c, inv_s, |x| erf.eval(x), lanes)
}

/// The body of [`integrate_axis`], given erf of one value and of [`ERF_LANES`] values.
///
/// `out` is resized to the pixel count and written in place (no per-pixel `push`, whose
/// capacity check cost as much as the subtraction it stores).
#[inline(always)]
fn integrate_axis_with(
    out: &mut Vec<f64>,
    lo: i64,
    hi: i64,
    c: f64,
    inv_s: f64,
    erf: impl Fn(f64) -> f64,
    erf_lanes: impl Fn([f64; ERF_LANES]) -> [f64; ERF_LANES],
) {
    let n = usize::try_from(hi - lo + 1).unwrap_or(0);
    out.resize(n, 0.0);
    let mut left = erf((lo as f64 - c - 0.5) * inv_s);
    let mut i = lo;
    // Right edges `ERF_LANES` at a time, the rest one by one.
    let mut batches = out.chunks_exact_mut(ERF_LANES);
    for batch in &mut batches {
        let edges: [f64; ERF_LANES] =
            std::array::from_fn(|k| ((i + k as i64) as f64 - c + 0.5) * inv_s);
        for (slot, right) in batch.iter_mut().zip(erf_lanes(edges)) {
            *slot = right - left;
            left = right;
        }
        i += ERF_LANES as i64;
    }
    for slot in batches.into_remainder() {
        let right = erf((i as f64 - c + 0.5) * inv_s);
        *slot = right - left;
        left = right;
        i += 1;
    }
}

/// Pixel edges of one axis integrated together by [`integrate_axis`].
const ERF_LANES: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    fn particle(x: f64, y: f64) -> Particle {
        Particle {
            id: 0,
            x,
            y,
            z: 0.0,
            w: 0.0,
            diameter: 2.5,
            brightness: 20.0,
        }
    }

    #[test]
    fn centred_particle_peaks_at_its_brightness_and_conserves_total() {
        let seeding = SeedingParams::default();
        let illum = IlluminationParams::default();
        let g = Geometry::new(20, 20);
        let mut r = ParticleRenderer::new(&seeding, &illum, g);
        let mut acc = vec![0f32; 400];
        let mut touched = Vec::new();
        r.add(&particle(10.0, 10.0), 1.0, 0..20, &mut acc, &mut touched);
        assert!((acc[10 * 20 + 10] - 20.0).abs() < 1e-4);
        // The integral of the spot is peak · (√(2π) σ)² / (pixel fraction)²: symmetric, and
        // moving the particle by a sub-pixel amount keeps the total.
        let total: f32 = acc.iter().sum();
        let mut acc2 = vec![0f32; 400];
        r.add(&particle(10.3, 9.6), 1.0, 0..20, &mut acc2, &mut Vec::new());
        let total2: f32 = acc2.iter().sum();
        assert!((total - total2).abs() < 1e-3 * total, "{total} {total2}");
        assert!((acc[10 * 20 + 9] - acc[10 * 20 + 11]).abs() < 1e-5);
    }

    /// `draw_sloped` draws what `draw` draws, bit for bit, and adds the time derivative of
    /// each pixel's light: that of the image moved along its velocity and brightened at its
    /// fade rate, by central differences over ±0.5 µs.
    #[test]
    fn sloped_drawing_adds_the_derivative_of_the_moving_fading_image() {
        let seeding = SeedingParams::default();
        let illum = IlluminationParams::default();
        let g = Geometry::new(24, 24);
        let mut r = ParticleRenderer::new(&seeding, &illum, g);
        let p = Particle {
            z: 4.0,
            w: -30.0,
            ..particle(11.3, 12.6)
        };
        let (vx, vy) = (0.0021, -0.0013); // px/µs
        let fade = r.fade_rate(&p);
        assert!(fade > 0.0, "{fade}"); // moving towards the sheet centre
        let spot = r.spot(&p, 1.0).unwrap();
        let motion = SpotMotion { vx, vy, fade };
        let (mut acc, mut touched) = (vec![0f32; 576], Vec::new());
        r.draw(&spot, 0..24, &mut acc, &mut touched);
        let (mut acc_s, mut dacc, mut touched_s) = (vec![0f32; 576], vec![0f32; 576], Vec::new());
        r.draw_sloped(&spot, &motion, 0..24, &mut acc_s, &mut dacc, &mut touched_s);
        assert_eq!(acc, acc_s);
        assert_eq!(touched, touched_s);
        // The image at t ± δ: the centre moved, the brightness scaled by e^(±fade·δ). Its
        // floor moves with it, so only pixels drawn in all three images are compared.
        let delta = 0.5;
        let at = |dt: f64| {
            let mut moved = spot.centred_at(spot.x + vx * dt, spot.y + vy * dt);
            moved.scale *= (fade * dt).exp();
            let mut a = vec![0f32; 576];
            ParticleRenderer::new(&seeding, &illum, g).draw(&moved, 0..24, &mut a, &mut Vec::new());
            a
        };
        let (later, earlier) = (at(delta), at(-delta));
        let largest = dacc.iter().fold(0f32, |m, d| m.max(d.abs()));
        assert!(largest > 1e-3, "{largest}");
        let mut compared = 0;
        for k in 0..576 {
            if later[k] > 0.0 && earlier[k] > 0.0 && acc[k] > 0.0 {
                let difference = (later[k] as f64 - earlier[k] as f64) / (2.0 * delta);
                assert!(
                    (dacc[k] as f64 - difference).abs() < 2e-3 * largest as f64,
                    "pixel {k}: {} against {difference}",
                    dacc[k]
                );
                compared += 1;
            }
        }
        assert!(compared > 15, "{compared}");
    }

    /// The Gaussians of the pixel edges by recurrence give the derivative of the erf
    /// integrals, as one exponential per edge does, also far out where the recurrence gives
    /// way to the direct form.
    #[test]
    fn edge_slopes_are_the_derivatives_of_the_axis_integrals() {
        let erf = Erf::new();
        for (c, inv_s, lo, hi) in [(5.3, 1.13, 1, 10), (0.0, 0.7, -6, 6), (0.4, 2.0, -30, 2)] {
            let mut slopes = Vec::new();
            edge_slopes(&mut slopes, lo, hi, c, inv_s);
            let (mut plus, mut minus) = (Vec::new(), Vec::new());
            let d = 1e-5;
            integrate_axis(erf, &mut plus, lo, hi, c + d, inv_s);
            integrate_axis(erf, &mut minus, lo, hi, c - d, inv_s);
            assert_eq!(slopes.len(), (hi - lo + 1) as usize);
            for (k, &s) in slopes.iter().enumerate() {
                let difference = (plus[k] - minus[k]) / (2.0 * d);
                assert!(
                    (s - difference).abs() < 1e-8,
                    "{c} {inv_s} pixel {k}: {s} {difference}"
                );
            }
        }
    }

    #[test]
    fn band_rows_and_walls_clip_the_image() {
        let seeding = SeedingParams::default();
        let illum = IlluminationParams {
            walls: vec![Wall {
                x: 0.0,
                y: 0.0,
                width: 10.0,
                height: 20.0,
                brightness: 50.0,
            }],
            ..Default::default()
        };
        let g = Geometry::new(20, 20);
        let mut r = ParticleRenderer::new(&seeding, &illum, g);
        let mut acc = vec![0f32; 5 * 20];
        let mut touched = Vec::new();
        r.add(&particle(10.0, 11.0), 1.0, 10..15, &mut acc, &mut touched);
        assert!(
            touched.iter().all(|&k| k % 20 >= 10),
            "nothing behind the wall"
        );
        assert!(acc[20 + 10] > 19.0, "row 11 is row 1 of the band");
        assert_eq!(illum.ambient(3, 3, 0.0), 50.0);
        assert_eq!(illum.ambient(15, 3, 0.0), 1.0);
    }

    #[test]
    fn pulses_are_trapezoids_with_listed_corners() {
        let illum = IlluminationParams {
            mode: LightMode::Pulsed,
            frequency_hz: 1000.0,
            duty: 0.1,
            edge_us: 2.0,
            ..Default::default()
        };
        illum.validate().unwrap();
        assert_eq!(illum.sheet(1.0), 0.5);
        assert_eq!(illum.sheet(50.0), 1.0);
        assert_eq!(illum.sheet(101.0), 0.5);
        assert_eq!(illum.sheet(500.0), 0.0);
        assert_eq!(illum.sheet(1050.0), 1.0);
        assert_eq!(illum.corners(0.0, 1000.0), vec![2.0, 100.0, 102.0, 1000.0]);
    }

    /// A bad value is named with its key (a wall by its index) and what would be allowed.
    #[test]
    fn bad_illumination_names_its_key_and_the_allowed_values() {
        let wall = Wall {
            x: 0.0,
            y: 0.0,
            width: 4.0,
            height: 4.0,
            brightness: 2.0,
        };
        let cases = [
            (
                IlluminationParams {
                    mode: LightMode::Pulsed,
                    frequency_hz: 1000.0,
                    duty: 0.1,
                    edge_us: 60.0,
                    ..Default::default()
                },
                "`illumination.edge_us`: 60 is out of range: must be above 0 and below 50 µs",
            ),
            (
                IlluminationParams {
                    walls: vec![
                        wall,
                        Wall {
                            height: f64::INFINITY,
                            ..wall
                        },
                    ],
                    ..Default::default()
                },
                "`illumination.walls[1].height`: inf is out of range: must be finite",
            ),
            (
                IlluminationParams {
                    flicker_hz: f64::NAN,
                    ..Default::default()
                },
                "`illumination.flicker_hz`: NaN is out of range",
            ),
        ];
        for (illum, message) in cases {
            let err = illum.validate().unwrap_err().to_string();
            assert!(err.contains(message), "{err}");
        }
    }
}
