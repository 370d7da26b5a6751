//! A band of sensor rows: per-pixel state, fixed pattern and the active set.

use std::ops::Range;

use super::active::ActiveSet;
use super::detector::{HermiteEnds, Pixel, Ramp, StepContext};
use super::noise::RowNoiseBound;
use super::params::SensorParams;
use super::response::{clean_irradiance, Curve, Response, MIN_THRESHOLD};
use super::{PixelCounters, SimEvent};
use crate::error::{Error, Result};
use crate::event::Geometry;
use crate::sim::fastmath;
use crate::sim::rng::{Rng, Stream};

/// Largest sensor side: event coordinates are `u16`.
const MAX_SIDE: u32 = 1 << 16;

/// Most pixels [`SensorBand::try_new`] accepts in one band (64 bytes of state each).
const MAX_BAND_PIXELS: u64 = 1 << 26;

/// New samples prepared together by [`StepContext::prepare_lanes`].
const PREPARE_LANES: usize = 8;

/// Sub-seed labels for the temporal random streams (one [`Stream::Temporal`] generator per
/// pixel or row and per label, so that no two draws share a generator).
pub(super) const TAG_JITTER: u64 = 0x4A49_5454;
pub(super) const TAG_NOISE: u64 = 0x4E4F_4953;
pub(super) const TAG_HOT: u64 = 0x484F_5421;

/// A seed derived from `seed` and a label (SplitMix64 finaliser).
pub(super) fn sub_seed(seed: u64, tag: u64) -> u64 {
    let mut z = seed ^ tag.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The pixels of rows `rows` of a sensor of `geometry` (sensor-model.md §2).
///
/// Bands run in parallel; every random number a pixel uses comes from a generator indexed by
/// its pixel index in the full sensor (noise by its row), so splitting the sensor into bands
/// changes nothing.
///
/// Work is proportional to changes and events, not to pixels × steps (sensor-model.md §3):
/// * a pixel whose input and low-pass output both lie strictly between its two threshold
///   levels cannot fire while its input is constant: it leaves the *active set*, frozen, and
///   its exponential relaxation is applied in one piece when its input next changes;
/// * an active pixel with constant input sleeps until its next crossing (computed from the
///   exponential, as IEBCS does) or the end of its blind time; visiting it costs one
///   comparison per step until then;
/// * pixels whose irradiance changed are updated every step (exact low-pass over the step).
#[derive(Debug, Clone)]
pub struct SensorBand {
    pub(super) geometry: Geometry,
    pub(super) rows: Range<u32>,
    pixels: Vec<Pixel>,
    /// New samples `(local pixel, irradiance)` for the step being prepared, one per pixel
    /// (the pixel carries the `CHANGED` mark).
    changed: Vec<(u32, f32)>,
    /// Irradiance slopes (per µs) of the entries of `changed`, when given
    /// ([`SensorBand::push_input_sloped`]): the input between samples is then a cubic Hermite
    /// interpolant instead of a linear ramp.
    changed_slopes: Vec<f32>,
    /// Per pixel, the log-response slope (per µs) of its last sample (empty until slopes
    /// are given).
    slope: Vec<f32>,
    /// Scratch: [`StepContext::hermite_lanes`] of the new samples.
    ends: Vec<HermiteEnds>,
    /// Scratch: [`StepContext::prepare`] of each entry of `changed`.
    ramps: Vec<Ramp>,
    /// Per active pixel, the time before which it need not be visited unless changed.
    wake: Vec<f64>,
    active: ActiveSet,
    t_now: f64,
    /// The end of the step being prepared ([`SensorBand::begin_step`]).
    t_next: f64,
    pub(super) response: Response,
    pub(super) seed: u64,
    pub(super) counters: PixelCounters,
    /// Frozen per-pixel noise-rate factor (empty when all are 1).
    pub(super) noise_factor: Vec<f32>,
    /// Per row, an upper bound of the leak + shot-noise rate of any pixel, events/µs.
    pub(super) row_noise_bound: Vec<f64>,
    /// Local indices of hot pixels.
    pub(super) hot: Vec<u32>,
    pub(super) params: SensorParams,
    pub(super) noise_calls: u64,
    updates: u64,
}

impl SensorBand {
    /// The pixels of rows `rows` of `geometry`, with fixed-pattern properties (threshold
    /// mismatch, noise-rate factors, hot pixels) drawn from `seed`. All pixels start adapted to
    /// irradiance 0 at t = 0; call [`SensorBand::adapt`] first.
    ///
    /// Never panics: rows are clipped to the sensor, a side beyond 65 536 pixels (the range of
    /// event coordinates) is clipped, and parameters are clamped to usable values. Use
    /// [`SensorBand::try_new`] to have them checked instead.
    pub fn new(geometry: Geometry, rows: Range<u32>, params: &SensorParams, seed: u64) -> Self {
        Self::new_adapted(geometry, rows, params, seed, 0.0, |_, _| 0.0)
    }

    /// [`SensorBand::new`] followed by [`SensorBand::adapt`]`(t0_us, irradiance)`, in one pass
    /// over the pixels.
    pub fn new_adapted(
        geometry: Geometry,
        rows: Range<u32>,
        params: &SensorParams,
        seed: u64,
        t0_us: f64,
        irradiance: impl Fn(u32, u32) -> f32,
    ) -> Self {
        let geometry = Geometry::new(geometry.width.min(MAX_SIDE), geometry.height.min(MAX_SIDE));
        let end = rows.end.min(geometry.height);
        let rows = rows.start.min(end)..end;
        let response = Response::new(params);
        let width = geometry.width as usize;
        let n = width * rows.len();
        let first = rows.start as u64 * geometry.width as u64;
        let t0 = if t0_us.is_finite() { t0_us } else { 0.0 };

        let cov = super::response::clean(params.noise_rate_cov_decades, 0.0, 2.0, 0.0);
        let sigma_ln = cov * std::f64::consts::LN_10;
        let factor_norm = (-0.5 * sigma_ln * sigma_ln).exp();
        let hot_fraction = super::response::clean(params.hot_pixel_fraction, 0.0, 1.0, 0.0);

        let mut pixels = Vec::with_capacity(n);
        let mut noise_factor = Vec::with_capacity(if cov > 0.0 { n } else { 0 });
        let mut hot = Vec::new();
        let mut row_noise_bound = Vec::with_capacity(rows.len());
        let mut bound = RowNoiseBound::new(params, &response);
        // Scenes are mostly one irradiance: reuse the last logarithm.
        let (mut last_irr, mut last_u) = (0.0, response.log(0.0));
        // Row by row, each row's pixels in one `extend` of a range: its length is known, so
        // the pixels are written without a capacity check each.
        for (row, y) in rows.clone().enumerate() {
            pixels.extend((0..width as u32).map(|x| {
                let i = row * width + x as usize;
                // Fixed-pattern draws in a fixed order, whatever the parameters (v2e: frozen
                // N(θ, σ) thresholds clamped ≥ 0.01, log-normal noise-rate factor); the factor
                // comes last, so switching it off leaves thresholds and hot pixels as they are.
                let mut rng = Rng::new(seed, Stream::FixedPattern, first + i as u64);
                let (z_on, z_off) = (rng.normal_fast(), rng.normal_fast());
                let u_hot = rng.uniform();
                let theta_on = (response.theta_on + response.sigma * z_on).max(MIN_THRESHOLD);
                let theta_off = (response.theta_off + response.sigma * z_off).max(MIN_THRESHOLD);
                let mut factor = 1.0;
                if cov > 0.0 {
                    factor = (fastmath::exp(sigma_ln * rng.normal_fast()) * factor_norm) as f32;
                    noise_factor.push(factor);
                }
                if u_hot < hot_fraction {
                    hot.push(i as u32);
                }
                bound.add(factor as f64, theta_on, theta_off);
                let irr = clean_irradiance(irradiance(x, y));
                if irr != last_irr {
                    (last_irr, last_u) = (irr, response.log(irr));
                }
                let mut px = Pixel::new(theta_on, theta_off);
                px.adapt(irr, last_u, t0);
                px
            }));
            row_noise_bound.push(bound.take());
        }
        SensorBand {
            geometry,
            rows,
            pixels,
            changed: Vec::new(),
            changed_slopes: Vec::new(),
            slope: Vec::new(),
            ends: Vec::new(),
            ramps: Vec::new(),
            // Read only for members of the active set, which set it first; zeroed memory is
            // not touched (or paged in) until then.
            wake: vec![0.0; n],
            active: ActiveSet::new(n),
            t_now: t0,
            t_next: t0,
            response,
            seed,
            counters: PixelCounters::default(),
            noise_factor,
            row_noise_bound,
            hot,
            params: params.clone(),
            noise_calls: 0,
            updates: 0,
        }
    }

    /// [`SensorBand::new`] after checking the parameters, the geometry and the rows.
    pub fn try_new(
        geometry: Geometry,
        rows: Range<u32>,
        params: &SensorParams,
        seed: u64,
    ) -> Result<Self> {
        params.validate()?;
        if geometry.width > MAX_SIDE || geometry.height > MAX_SIDE {
            return Err(Error::parameter(
                "geometry",
                format!("{geometry} exceeds the 65536 × 65536 range of event coordinates"),
            ));
        }
        if rows.start > rows.end || rows.end > geometry.height {
            return Err(Error::parameter(
                "rows",
                format!("{rows:?} is not a range of rows of {geometry}"),
            ));
        }
        let pixels = geometry.width as u64 * rows.len() as u64;
        if pixels > MAX_BAND_PIXELS {
            return Err(Error::parameter(
                "rows",
                format!(
                    "a band of {pixels} pixels exceeds the limit of {MAX_BAND_PIXELS}; \
                     split the sensor into more bands"
                ),
            ));
        }
        Ok(Self::new(geometry, rows, params, seed))
    }

    /// Start: every pixel adapted to the irradiance `irradiance(x, y)` at time `t0_us`, its
    /// low-pass settled and its reference equal to its log response (no events).
    pub fn adapt(&mut self, t0_us: f64, irradiance: impl Fn(u32, u32) -> f32) {
        let t0 = if t0_us.is_finite() { t0_us } else { 0.0 };
        let width = self.geometry.width;
        // Scenes are mostly one irradiance: reuse the last logarithm.
        let (mut last_irr, mut last_u) = (0.0, self.response.log(0.0));
        for (i, px) in self.pixels.iter_mut().enumerate() {
            let x = (i % width as usize) as u32;
            let y = self.rows.start + (i / width as usize) as u32;
            let irr = clean_irradiance(irradiance(x, y));
            if irr != last_irr {
                (last_irr, last_u) = (irr, self.response.log(irr));
            }
            px.adapt(irr, last_u, t0);
        }
        for &(local, _) in &self.changed {
            self.pixels[local as usize].clear_changed();
        }
        self.changed.clear();
        self.changed_slopes.clear();
        self.slope.iter_mut().for_each(|s| *s = 0.0);
        self.active.clear();
        self.t_now = t0;
        self.t_next = t0;
    }

    /// Advance to `t_us` (µs; a time before the current one, or not finite, is taken as the
    /// current time, i.e. an instantaneous change).
    ///
    /// `changed` lists `(pixel index y·width + x in the full sensor, new irradiance)` for every
    /// pixel whose irradiance differs from its previous sample; entries outside this band are
    /// ignored, a repeated pixel takes its last value. Between samples a pixel's log response
    /// varies linearly in time (ESIM's interpolation, §2.1 — for the fine steps of §3 this is
    /// the linear irradiance ramp to within O(Δ²)). Pixels not listed keep their irradiance;
    /// their low-pass still relaxes and may fire.
    ///
    /// Appends events with exact threshold-crossing times (linear input: analytic; low-pass:
    /// the exact first-order solution, root-found to 1e-7 µs), plus jitter and latency, in no
    /// particular order. An event is never earlier than its crossing, so all are at or after
    /// the previous time; latency, jitter and the refractory release can put them after
    /// `t_us` (keep a margin of latency + refractory period + a few jitter σ when reading out
    /// a stream in pieces). Allocation-free apart from the growth of `out`.
    pub fn advance(&mut self, t_us: f64, changed: &[(u32, f32)], out: &mut Vec<SimEvent>) {
        self.begin_step(t_us);
        let first = self.rows.start as u64 * self.geometry.width as u64;
        let n = self.pixels.len() as u64;
        for &(index, irr) in changed {
            let local = (index as u64).wrapping_sub(first);
            if local < n {
                self.set_input(local as usize, irr);
            }
        }
        self.advance_marked(out);
    }

    /// Start a step to `t_us` (same rules as [`SensorBand::advance`]); then give the new
    /// samples with [`SensorBand::set_input`] and run the step with
    /// [`SensorBand::advance_marked`].
    pub fn begin_step(&mut self, t_us: f64) {
        let ta = self.t_now;
        self.t_next = if t_us.is_finite() && t_us > ta {
            t_us
        } else {
            ta
        };
    }

    /// Give local pixel `local` (`(y − first row)·width + x`, < [`SensorBand::pixel_count`])
    /// the irradiance `irr` at the end of the step begun by [`SensorBand::begin_step`]; a
    /// repeated pixel takes its last value. Calling this for a pixel whose irradiance did not
    /// change is allowed but costs a full pixel update.
    #[inline]
    pub fn set_input(&mut self, local: usize, irr: f32) {
        if self.pixels[local].mark_changed() {
            self.changed.push((local as u32, irr));
        } else if let Some(entry) = self
            .changed
            .iter_mut()
            .rev()
            .find(|e| e.0 as usize == local)
        {
            entry.1 = irr;
        }
    }

    /// [`SensorBand::set_input`] for a caller that gives each pixel at most one new sample
    /// per step (and does not also use `set_input` in that step): the sample is queued
    /// without marking the pixel or looking for an earlier one.
    #[inline]
    pub(crate) fn push_input(&mut self, local: usize, irr: f32) {
        self.changed.push((local as u32, irr));
    }

    /// [`SensorBand::push_input`] with the irradiance's time derivative `slope` (per µs) at
    /// the sample: the pixel's log input up to it is then the cubic Hermite interpolant of
    /// its last two samples and their slopes ([`StepContext::hermite_step`]) instead of a
    /// straight line. All new samples of a step are to be given this way (if some are not,
    /// the step's slopes are ignored).
    #[inline]
    pub(crate) fn push_input_sloped(&mut self, local: usize, irr: f32, slope: f32) {
        self.changed.push((local as u32, irr));
        self.changed_slopes.push(slope);
    }

    /// Run the step begun by [`SensorBand::begin_step`] (see [`SensorBand::advance`]).
    ///
    /// Every pixel with a new sample is updated, joining the active set if it may fire while
    /// its input stays constant and leaving it otherwise; then the members of the active set
    /// not yet at the step's end (those without a new sample) are visited when due. Each
    /// pixel's update depends on that pixel alone, so the order of the two passes changes
    /// nothing but the order of `out`.
    pub fn advance_marked(&mut self, out: &mut Vec<SimEvent>) {
        if crate::simd::avx2_available() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the processor has AVX2 (`avx2_available`).
            return unsafe { self.advance_marked_avx2(out) };
        }
        self.advance_marked_portable(out)
    }

    /// [`SensorBand::advance_marked`] compiled for AVX2 ([`crate::simd`]): the lane-wise
    /// pixel set-up (`prepare_lanes` with its exp and ln lanes) runs four `f64` lanes per
    /// instruction instead of two; the same operations in the same order, the same events.
    ///
    /// # Safety
    /// Only where the processor has AVX2 ([`crate::simd::avx2_available`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn advance_marked_avx2(&mut self, out: &mut Vec<SimEvent>) {
        self.advance_marked_portable(out)
    }

    /// [`SensorBand::advance_marked`] for any processor.
    #[inline(always)]
    pub(super) fn advance_marked_portable(&mut self, out: &mut Vec<SimEvent>) {
        let (ta, tb) = (self.t_now, self.t_next);
        let first = self.rows.start as u64 * self.geometry.width as u64;
        let mut ctx = StepContext {
            response: &self.response,
            jitter_seed: sub_seed(self.seed, TAG_JITTER),
            width: self.geometry.width,
            row0: self.rows.start,
            first: first as u32,
            counters: &mut self.counters,
            out,
        };
        let (pixels, wake, active) = (&mut self.pixels, &mut self.wake, &mut self.active);
        let mut updates = self.changed.len() as u64;
        let ramps = &mut self.ramps;
        ramps.clear();
        let dt = tb - ta;
        let changed = &self.changed;
        let mut batches = changed.chunks_exact(PREPARE_LANES);
        for (b, batch) in (&mut batches).enumerate() {
            // The pixels of the batch after next: each is a cache miss.
            let ahead = (b + 2) * PREPARE_LANES;
            for &(local, _) in changed.get(ahead..ahead + PREPARE_LANES).unwrap_or(&[]) {
                if let Some(px) = pixels.get(local as usize) {
                    crate::simd::prefetch(px);
                }
            }
            // Loops rather than `std::array::from_fn`, which the compiler stopped inlining
            // here once the cubic step was inlined beside it (a call per batch).
            let (mut old, mut new) = ([0.0f32; PREPARE_LANES], [0.0f32; PREPARE_LANES]);
            for ((old, new), &(local, irr)) in old.iter_mut().zip(&mut new).zip(batch) {
                *old = pixels[local as usize].irr;
                *new = irr;
            }
            ramps.extend(StepContext::prepare_lanes(ctx.response, old, new, dt));
        }
        ramps.extend(batches.remainder().iter().map(|&(local, irr)| {
            StepContext::prepare(ctx.response, &pixels[local as usize], irr, dt)
        }));
        // Slopes for every new sample, or none (a caller mixing the two gets ramps).
        let sloped = !self.changed.is_empty() && self.changed_slopes.len() == self.changed.len();
        if sloped && self.slope.len() != pixels.len() {
            self.slope = vec![0.0; pixels.len()];
        }
        let ends = &mut self.ends;
        if sloped {
            StepContext::hermite_lanes(ctx.response, ramps, &self.changed_slopes, ends);
        }
        let span = (ta, tb, 1.0 / dt);
        let slopes = &mut self.slope;
        for (j, (&(local, _), ramp)) in self.changed.iter().zip(ramps.iter()).enumerate() {
            let i = local as usize;
            let px = &mut pixels[i];
            px.clear_changed();
            let next = if sloped {
                let end = &ends[j];
                let next = ctx.hermite_step(px, local, span, ramp, slopes[i], end);
                slopes[i] = end.mb;
                next
            } else {
                // A ramp: a later cubic starts flat from this sample.
                if let Some(s) = slopes.get_mut(i) {
                    *s = 0.0;
                }
                match StepContext::quiet_ramp(ctx.response, px, ta, tb, ramp) {
                    Some(next) => next,
                    None => ctx.step(px, local, ta, tb, Some(ramp)),
                }
            };
            match next {
                Some(next) => {
                    wake[i] = next;
                    active.insert(i);
                }
                None => active.remove(i),
            }
        }
        self.changed.clear();
        self.changed_slopes.clear();
        if active.len() > 0 {
            active.retain(|local| {
                if wake[local] > tb {
                    return true;
                }
                let px = &mut pixels[local];
                // Updated to `tb` above (a pixel without a new sample is at or before `ta`;
                // in a step of no length it has nothing to do).
                if px.t >= tb {
                    return true;
                }
                updates += 1;
                // Its input held over the step: the next sample's cubic starts flat.
                if let Some(s) = slopes.get_mut(local) {
                    *s = 0.0;
                }
                match ctx.step(px, local as u32, ta, tb, None) {
                    Some(next) => {
                        wake[local] = next;
                        true
                    }
                    None => false,
                }
            });
        }
        self.updates += updates;
        self.t_now = tb;
    }

    /// The band's current time, µs.
    pub fn time_us(&self) -> f64 {
        self.t_now
    }

    /// Number of pixels in the active set.
    pub fn active_pixels(&self) -> usize {
        self.active.len()
    }

    /// Pixel updates computed so far by `advance` (each an exact low-pass step of one
    /// pixel): the measure of the simulator's work.
    pub fn pixel_updates(&self) -> u64 {
        self.updates
    }

    /// Number of pixels of the band.
    pub fn pixel_count(&self) -> usize {
        self.pixels.len()
    }

    /// What the pixels of this band did so far.
    pub fn counters(&self) -> PixelCounters {
        self.counters
    }

    /// The frozen ON and OFF thresholds of pixel `(x, y)`, if it belongs to this band.
    pub fn thresholds(&self, x: u32, y: u32) -> Option<(f64, f64)> {
        let px = self.pixel(x, y)?;
        Some((px.theta_on, px.theta_off))
    }

    /// The low-passed log intensity of pixel `(x, y)` at the band's current time, and its
    /// reference level as of its last update (a pixel asleep until its next event or the end
    /// of its blind time is updated when visited).
    pub fn log_state(&self, x: u32, y: u32) -> Option<(f64, f64)> {
        let px = self.pixel(x, y)?;
        let l = if px.t < self.t_now && self.response.low_pass() {
            let omega = self.response.omega(px.irr as f64);
            Curve::low_pass(px.t, self.t_now, px.l, px.u, px.u, omega).value(self.t_now)
        } else {
            px.l
        };
        Some((l, px.l_ref))
    }

    fn pixel(&self, x: u32, y: u32) -> Option<&Pixel> {
        if x >= self.geometry.width || !self.rows.contains(&y) {
            return None;
        }
        let local = (y - self.rows.start) as usize * self.geometry.width as usize + x as usize;
        self.pixels.get(local)
    }

    /// Irradiance of local pixel `i` (for the noise model).
    #[inline]
    pub(super) fn irradiance_of(&self, i: usize) -> f32 {
        self.pixels[i].irr
    }

    /// ON and OFF thresholds of local pixel `i`.
    #[inline]
    pub(super) fn thresholds_of(&self, i: usize) -> (f64, f64) {
        let px = &self.pixels[i];
        (px.theta_on, px.theta_off)
    }
}
