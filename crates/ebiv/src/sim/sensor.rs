//! The event-camera pixel model: irradiance in, events with exact times out.
//!
//! Per pixel (sensor-model.md §0, §2):
//!
//! ```text
//! I ──lin-log──► u ──first-order low-pass, cutoff ∝ I──► L_lp ──compare with L_ref ± θ(x)──►
//!   crossing times (exact) ──refractory (reset to L_lp)──► + jitter + latency ──► events
//! + leak, shot noise, hot pixels (Poisson) ──read_out: order, refractory, bandwidth, 1 µs──►
//! ```
//!
//! * Log response ([`SensorParams::linlog_threshold`]): lin-log after v2e (Hu, Liu & Delbruck,
//!   "v2e: from video frames to realistic DVS events", CVPRW 2021), or `ln(ε + I)` after ESIM
//!   (Rebecq, Gehrig & Scaramuzza, "ESIM: an open event camera simulator", CoRL 2018), §2.2.
//! * Photoreceptor: first-order low-pass whose bandwidth grows with irradiance up to
//!   `cutoff_hz` (v2e's intensity dependence, §2.4), solved exactly over each step for a
//!   log input linear in time — no sub-stepping error, no ε limit.
//! * Change detector: ON when `L_lp − L_ref ≥ θ_on(x)`, OFF when `≤ −θ_off(x)`; the reference
//!   then moves by exactly one threshold (residual kept); θ(x) frozen per pixel, N(θ, σ)
//!   clamped ≥ 0.01 (v2e, §2.1, §2.3). Crossing times are those of the continuous `L_lp`
//!   (linear interpolation where `L_lp` is linear, safeguarded Halley iteration on the exact
//!   solution otherwise), so they are not quantised to the caller's steps (§2.9, §3).
//! * Refractory period: after an event the pixel is blind until trip + `refractory_us`;
//!   crossings in that time are counted, not reported, and at its end the reference resets to
//!   the current `L_lp` (IEBCS: Joubert et al., "Event camera simulator improvements via
//!   characterized parameters", Front. Neurosci. 2021; §2.5).
//! * Timing: Gaussian comparator jitter and a constant latency (IEBCS, §2.4); the low-pass
//!   adds the irradiance-dependent part of the latency (§8: bright particles fire earlier).
//! * Noise ([`SensorBand::noise`]), readout ([`read_out`]).
//!
//! Randomness comes from [`crate::sim::rng`] streams indexed by pixel (row for row-wise noise)
//! and the seed, so events do not depend on bands or threads.
//!
//! Typical use: one [`SensorBand`] per group of rows (run in parallel), `adapt` to the first
//! frame, then per time step `advance` with the pixels whose irradiance changed, `noise` over
//! the recording, and finally [`read_out_parts`] of all bands' events (add each band's
//! [`SensorBand::counters`] to the report with [`ReadoutReport::absorb`]). A long recording
//! is better read out while it is simulated, as `ebiv simulate` does: noise drawn window by
//! window ([`SensorBand::noise_stream`]) and the events handed to a [`StreamingReadout`],
//! which gives the same result with the memory of one window (`read_out_parts` is its one
//! window).

mod active;
mod band;
mod detector;
mod noise;
mod params;
mod readout;
mod response;
#[cfg(test)]
mod tests;

pub use band::SensorBand;
pub use noise::NoiseStream;
pub use params::{SensorParams, TimestampMode};
pub use readout::{read_out, read_out_parts, ReadoutReport, StreamingReadout};

/// One simulated event with its exact time, before the readout quantises it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimEvent {
    /// Exact time, µs, including latency and jitter.
    pub t_us: f64,
    /// Column.
    pub x: u16,
    /// Row.
    pub y: u16,
    /// Polarity, 1 = ON, 0 = OFF.
    pub p: u8,
}

/// What the pixels of a band did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct PixelCounters {
    /// ON events emitted by the change detectors.
    pub on: u64,
    /// OFF events emitted by the change detectors.
    pub off: u64,
    /// Threshold crossings inside a refractory period (not reported).
    pub suppressed_refractory: u64,
    /// Leak events.
    pub leak: u64,
    /// Shot-noise events.
    pub shot: u64,
    /// Hot-pixel events.
    pub hot: u64,
}

impl PixelCounters {
    /// Add `other` to these counters.
    pub fn merge(&mut self, other: &PixelCounters) {
        self.on += other.on;
        self.off += other.off;
        self.suppressed_refractory += other.suppressed_refractory;
        self.leak += other.leak;
        self.shot += other.shot;
        self.hot += other.hot;
    }
}
