//! Background activity: leak, shot noise and hot pixels (sensor-model.md §2.6, §2.7).
//!
//! Each is a Poisson process per pixel, independent of the pixel's change detector: noise
//! events do not move its reference. (v2e and IEBCS reset the reference after a noise event;
//! at ≤ 5 Hz per pixel over recordings of milliseconds the difference is far below one
//! event per pixel.) The readout's refractory filter ([`super::read_out`]) removes noise
//! events that fall inside a pixel's blind time.

use super::band::{sub_seed, SensorBand, TAG_HOT, TAG_NOISE};
use super::params::SensorParams;
use super::response::{clean, Response};
use super::SimEvent;
use crate::sim::rng::{Rng, Stream};

/// Hz to events per µs.
const PER_US: f64 = 1e-6;

impl SensorBand {
    /// Leak, shot-noise and hot-pixel events of this band over `[t0_us, t1_us)`, appended to
    /// `out` with exact times.
    ///
    /// * Leak (v2e, Hu et al. CVPRW 2021): ON events at `leak_rate_hz · n(x)` with a frozen
    ///   log-normal factor `n(x) = 10^(c·z)` (c = `noise_rate_cov_decades`), normalised to mean 1.
    /// * Shot noise (v2e): `shot_noise_rate_hz / 2` per polarity, scaled by
    ///   `θ_nominal / θ(x)` (low-threshold pixels are noisier) and by `1 − 0.75·b(I)` with b the
    ///   relative bandwidth at the pixel's irradiance, so 25 % of the dark rate at and above
    ///   the reference irradiance.
    /// * Hot pixels: `hot_pixel_rate_hz`, each event ON or OFF with probability ½.
    ///
    /// Leak and shot noise are drawn per row (exact thinning of a bounding Poisson process),
    /// hot pixels per pixel; rows and pixels index the generators, so bands do not matter.
    /// Successive calls draw from fresh generators; all bands must see the same calls.
    /// [`SensorBand::noise_stream`] draws the same events window by window.
    pub fn noise(&mut self, t0_us: f64, t1_us: f64, out: &mut Vec<SimEvent>) {
        let mut stream = self.noise_stream(t0_us);
        if t1_us > t0_us {
            self.noise_until(&mut stream, t1_us, out);
        }
    }

    /// The background activity of this band from `t0_us` on, to be drawn window by window
    /// with [`SensorBand::noise_until`]: up to any time, the events [`SensorBand::noise`]
    /// gives from `t0_us` to that time, each candidate decided with the pixel's irradiance
    /// when the window that holds it is drawn (`noise` decides all with the irradiance at
    /// its call). Counts as a call of `noise` (fresh generators). A start that is not finite
    /// gives no events.
    pub fn noise_stream(&mut self, t0_us: f64) -> NoiseStream {
        let call = self.noise_calls;
        self.noise_calls += 1;
        let width = self.geometry.width as usize;
        let start = |rate: f64, seed: u64, index: u64| {
            let mut rng = Rng::new(seed, Stream::Temporal, (call << 32) | index);
            let next = if t0_us.is_finite() && rate > 0.0 && width > 0 {
                t0_us + rng.exponential(rate)
            } else {
                f64::NAN
            };
            Poisson { rng, next }
        };
        let noise_seed = sub_seed(self.seed, TAG_NOISE);
        let rows = self
            .row_noise_bound
            .iter()
            .enumerate()
            .map(|(row, &bound)| {
                let y = self.rows.start as u64 + row as u64;
                // NaN fails the rate test: no events.
                start(bound * width as f64, noise_seed, y)
            })
            .collect();
        let hot_rate = clean(self.params.hot_pixel_rate_hz, 0.0, 1e6, 0.0) * PER_US;
        let hot_seed = sub_seed(self.seed, TAG_HOT);
        let first = self.rows.start as u64 * width as u64;
        let hot = self
            .hot
            .iter()
            .map(|&local| start(hot_rate, hot_seed, first + local as u64))
            .collect();
        NoiseStream { rows, hot }
    }

    /// Append the events of `stream` before `t1_us` not drawn yet (see
    /// [`SensorBand::noise_stream`]); a `t1_us` that is not finite draws nothing.
    pub fn noise_until(&mut self, stream: &mut NoiseStream, t1_us: f64, out: &mut Vec<SimEvent>) {
        if !t1_us.is_finite() {
            return;
        }
        let leak = clean(self.params.leak_rate_hz, 0.0, 1e6, 0.0) * PER_US;
        let shot = clean(self.params.shot_noise_rate_hz, 0.0, 1e6, 0.0) * PER_US;
        let width = self.geometry.width as usize;
        let (theta_on_nominal, theta_off_nominal) =
            (self.response.theta_on, self.response.theta_off);

        for (row_index, process) in stream.rows.iter_mut().enumerate() {
            let bound = self.row_noise_bound[row_index];
            let total = bound * width as f64;
            let y = self.rows.start + row_index as u32;
            // `next` is NaN for a row without noise: the comparison fails.
            while process.next < t1_us {
                let t = process.next;
                let rng = &mut process.rng;
                let x = ((rng.uniform() * width as f64) as usize).min(width - 1);
                let mut u = rng.uniform() * bound;
                process.next = t + rng.exponential(total);
                let i = row_index * width + x;
                let factor = self.noise_factor.get(i).map_or(1.0, |&f| f as f64);
                let rate_leak = leak * factor;
                let (theta_on, theta_off) = self.thresholds_of(i);
                let scale = 0.5
                    * shot
                    * self
                        .response
                        .shot_noise_factor(self.irradiance_of(i) as f64);
                let rate_on = scale * theta_on_nominal / theta_on;
                let rate_off = scale * theta_off_nominal / theta_off;
                let p = if u < rate_leak {
                    self.counters.leak += 1;
                    1
                } else {
                    u -= rate_leak;
                    if u < rate_on {
                        self.counters.shot += 1;
                        1
                    } else if u - rate_on < rate_off {
                        self.counters.shot += 1;
                        0
                    } else {
                        continue;
                    }
                };
                out.push(SimEvent {
                    t_us: t,
                    x: x as u16,
                    y: y as u16,
                    p,
                });
            }
        }

        let hot_rate = clean(self.params.hot_pixel_rate_hz, 0.0, 1e6, 0.0) * PER_US;
        for (&local, process) in self.hot.iter().zip(&mut stream.hot) {
            let x = local as usize % width;
            let y = self.rows.start as usize + local as usize / width;
            while process.next < t1_us {
                let t = process.next;
                let p = (process.rng.uniform() < 0.5) as u8;
                process.next = t + process.rng.exponential(hot_rate);
                self.counters.hot += 1;
                out.push(SimEvent {
                    t_us: t,
                    x: x as u16,
                    y: y as u16,
                    p,
                });
            }
        }
    }
}

/// The Poisson processes of a band's background activity, between windows
/// ([`SensorBand::noise_stream`]).
#[derive(Debug, Clone)]
pub struct NoiseStream {
    /// Leak and shot noise, per row of the band.
    rows: Vec<Poisson>,
    /// Per hot pixel of the band.
    hot: Vec<Poisson>,
}

/// One Poisson process: its generator and its next event time, drawn but not yet reached
/// (NaN: none).
#[derive(Debug, Clone)]
struct Poisson {
    rng: Rng,
    next: f64,
}

/// Per row, an upper bound (events/µs) of any pixel's leak + shot-noise rate, for the
/// thinning in [`SensorBand::noise`]: fed the fixed pattern of a row's pixels one by one.
pub(super) struct RowNoiseBound {
    leak: f64,
    /// Half the shot-noise rate (per polarity) at the nominal thresholds.
    half_shot: f64,
    theta_on: f64,
    theta_off: f64,
    max_leak: f64,
    max_shot: f64,
}

impl RowNoiseBound {
    pub(super) fn new(params: &SensorParams, response: &Response) -> Self {
        RowNoiseBound {
            leak: clean(params.leak_rate_hz, 0.0, 1e6, 0.0) * PER_US,
            half_shot: 0.5 * clean(params.shot_noise_rate_hz, 0.0, 1e6, 0.0) * PER_US,
            theta_on: response.theta_on,
            theta_off: response.theta_off,
            max_leak: 0.0,
            max_shot: 0.0,
        }
    }

    /// A pixel of the row with noise-rate factor `factor` and thresholds `theta_on`,
    /// `theta_off`.
    #[inline]
    pub(super) fn add(&mut self, factor: f64, theta_on: f64, theta_off: f64) {
        if self.leak > 0.0 || self.half_shot > 0.0 {
            self.max_leak = self.max_leak.max(self.leak * factor);
            let s = self.half_shot * (self.theta_on / theta_on + self.theta_off / theta_off);
            self.max_shot = self.max_shot.max(s);
        }
    }

    /// The bound of the pixels added since the last call.
    pub(super) fn take(&mut self) -> f64 {
        let bound = self.max_leak + self.max_shot;
        (self.max_leak, self.max_shot) = (0.0, 0.0);
        bound
    }
}
