//! Parameters of the pixel model, the four presets and their validation.

use crate::error::{Error, Result};

/// How exact event times are turned into the sensor's 1 µs time stamps (sensor-model.md §2.10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TimestampMode {
    /// Nearest microsecond (unbiased; DVS-Voltmeter).
    #[default]
    Round,
    /// The microsecond counter value, `floor(t)` (a camera's clock counter; v2e and IEBCS
    /// truncate).
    Truncate,
}

/// Every parameter of the event-camera pixel model, in physical units.
///
/// Irradiance is in the scene's linear units. The presets assume the convention of
/// sensor-model.md §8: background `B = 1`, particle images peak at `K = 10–100` above it.
/// A TOML scenario may override any field; a missing field takes its [`SensorParams::gen4`]
/// value, except `bandwidth_ev_per_s`, whose absence means "no readout limit".
///
/// # Presets
///
/// | field | `ideal` | `gen4` | `noisy` | sources |
/// |---|---|---|---|---|
/// | `threshold_on` / `_off` (ln) | 0.2 | ln 1.25 = 0.2231 | 0.2 | v2e / ESIM README 0.2; EBIV paper camera table and FED-PV: 25 % contrast (§4.5) |
/// | `threshold_sigma` (ln) | 0 | 0.025 | 0.05 | v2e clean 0.02, default 0.03, noisy 0.05; IEBCS 0.02 (§4.2, §4.3) |
/// | `linlog_threshold` | 0 (pure ln(ε + I)) | 0.1 | 0.1 | v2e knee 20/255 ≈ 8 % of full scale (§2.2, §10) |
/// | `log_eps` | 0.001 | 0.001 | 0.001 | ESIM `log_eps` (§2.2) |
/// | `cutoff_hz` | 0 (no low-pass) | 10 kHz | 1 kHz | §8 study (10 kHz ∝ I); v2e noisy cuts its 300 Hz default ten-fold, scaled here to gen4's 10 kHz (§4.2) |
/// | `cutoff_reference_irradiance` | 10 | 10 | 10 | cutoff reached at a K = 10 particle peak (§8) |
/// | `cutoff_dark_irradiance` | 0.1 | 0.1 | 0.1 | v2e's `+20` in `(I + 20)/275` (§2.4), here 1 % of the reference |
/// | `latency_us` | 0 | 20 | 0 | EBIV paper camera table: 20–150 µs latency (see below) |
/// | `jitter_us` | 0 | 3 | 0 | "a few µs"; IEBCS examples 10–50 µs include photoreceptor jitter (§4.3) |
/// | `refractory_us` | 0 | 5 | 0 | EBIV needs 0–10 µs, not v2e's 0.5 ms CLI default (§2.5, §10) |
/// | `leak_rate_hz` | 0 | 0.1 | 0.1 | v2e class default / noisy preset (§4.2) |
/// | `shot_noise_rate_hz` | 0 | 0.5 | 5 | v2e noisy preset 5 Hz (§4.2); gen4 a tenth of it |
/// | `noise_rate_cov_decades` | 0 | 0.1 | 0.1 | v2e `noise_rate_cov_decades` (§2.6) |
/// | `hot_pixel_fraction` / `_rate_hz` | 0 / 0 | 1e-4 / 50 Hz | 0 / 0 | model choice (no published value) |
/// | `bandwidth_ev_per_s` | none | 4e8 | none | row-wise loss above ≈ 400 ev/µs (§4, §2.11) |
/// | `bandwidth_burst_events` | 1024 | 1024 | 1024 | model choice (readout FIFO depth) |
/// | `timestamp` | round | truncate | truncate | camera clock counter; v2e/IEBCS truncate (§2.10) |
///
/// With `gen4`, the time constant is 1/(2π·10 kHz) = 15.9 µs at and above `I = 10` and
/// 15.9 µs × (10 + 0.1)/(1 + 0.1) = 146 µs on the `B = 1` background. The first event of a
/// 50 % step (Δ = ln 1.5 = 0.405, θ = 0.223) comes `τ·ln(Δ/(Δ − θ)) = 0.80 τ` after the step:
/// 13 µs bright and 117 µs on the background, so with the 20 µs constant latency events are
/// 33–137 µs late — the 20–150 µs of the camera table.
///
/// `imx636` is `gen4` with a refractory period of [`IMX636_REFRACTORY_US`]: the camera of
/// the EBIV paper's wall flow (Prophesee Gen4.1 HD, Sony IMX636) as set for that recording,
/// calibrated on its pixel activity (docs/calibration.md).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// ON contrast threshold θ_on, ln-intensity units (sensor-model.md §2.1, §2.3).
    pub threshold_on: f64,
    /// OFF contrast threshold θ_off, ln-intensity units.
    pub threshold_off: f64,
    /// Standard deviation of the frozen per-pixel threshold mismatch, ln units (v2e model,
    /// §2.3); each pixel's thresholds are clamped to ≥ 0.01.
    pub threshold_sigma: f64,
    /// Knee of the lin-log response in irradiance units: `ln I` above it, the tangent line of
    /// `ln` at the knee below it (§2.2). 0 selects `ln(log_eps + I)` (ESIM).
    pub linlog_threshold: f64,
    /// ε of the pure log response `ln(ε + I)`, used when `linlog_threshold` is 0 (ESIM 0.001).
    pub log_eps: f64,
    /// Photoreceptor 3 dB bandwidth (Hz) at and above the reference irradiance; 0 = no
    /// low-pass (§2.4). No pixel's bandwidth goes below 0.16 mHz (a time constant of
    /// 1000 s), whatever this and the irradiance: a smaller value is raised to it, and the
    /// dark irradiance below as far as needed.
    pub cutoff_hz: f64,
    /// Irradiance at which `cutoff_hz` holds; below it the bandwidth scales as
    /// `(I + I_dark)/(I_ref + I_dark)` (v2e's `(I + 20)/275`, §2.4). 0 = bandwidth
    /// independent of irradiance.
    pub cutoff_reference_irradiance: f64,
    /// Dark-current equivalent irradiance `I_dark` of the bandwidth law; keeps the bandwidth of
    /// a black pixel finite (v2e: 20 on the 0–255 scale).
    pub cutoff_dark_irradiance: f64,
    /// Constant comparator/readout latency added to every event, µs.
    pub latency_us: f64,
    /// Standard deviation of the Gaussian timing jitter of the comparator trip, µs (IEBCS).
    pub jitter_us: f64,
    /// Refractory period, µs: a pixel is blind this long after an event and its reference is
    /// then reset to the current low-passed value (IEBCS semantics, §2.5).
    pub refractory_us: f64,
    /// Mean rate of ON leak events per pixel, Hz (v2e leak, §2.6).
    pub leak_rate_hz: f64,
    /// Mean rate of shot-noise events per pixel (both polarities together) in the dark, Hz;
    /// falls to 25 % at the reference irradiance (v2e, §2.7).
    pub shot_noise_rate_hz: f64,
    /// Spread of the frozen per-pixel leak-rate factor in decades (v2e
    /// `noise_rate_cov_decades`): log-normal, normalised to mean 1.
    pub noise_rate_cov_decades: f64,
    /// Fraction of pixels that are hot.
    pub hot_pixel_fraction: f64,
    /// Event rate of a hot pixel, Hz (random polarity).
    pub hot_pixel_rate_hz: f64,
    /// Readout limit in events per second; `None` = unlimited. Drop policy in
    /// [`super::read_out`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_ev_per_s: Option<f64>,
    /// Depth of the readout token bucket: events that may pass in a burst.
    pub bandwidth_burst_events: f64,
    /// Quantisation of exact event times to 1 µs time stamps.
    pub timestamp: TimestampMode,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self::gen4()
    }
}

/// Refractory period of the `imx636` preset, µs.
///
/// A pixel of the EBIV paper's wall-flow recording (`wallflow_slice2.npz`: Gen4.1 HD, water
/// at about 1.5 px/ms, 2–3 px particle images) fires one ON event per passing particle
/// (median and 90th percentile 1 event per active pixel over 20 ms), and the time between two
/// events of a pixel is 4.0 / 7.5 / 14 ms at its 10th / 50th / 90th percentiles, with no
/// shorter gaps than the refractory floor allows. The `gen4` model with 5 µs fires a burst of
/// 3–6 events, 0.1–0.3 ms apart, as a 2.5 px particle of contrast 5 crosses a pixel in about
/// 1.7 ms (ln 6 / θ ≈ 8 threshold crossings, fewer after the low-pass). A refractory period
/// longer than that crossing time leaves one event per passage — the IEBCS reset at its end
/// takes the particle's light as the new reference, so the falling edge fires no OFF burst
/// either — and sets the smallest gap: 3.5 ms reproduces the recording's 10th-percentile gap
/// (docs/calibration.md, `ebiv info --activity`). Prophesee's refractory bias
/// (`bias_refr`) sets this period; ms-long settings suppress bursts at slow flows.
pub const IMX636_REFRACTORY_US: f64 = 3500.0;

/// The largest accepted rate of any noise process, Hz (one event per µs per pixel).
const MAX_RATE_HZ: f64 = 1e6;

impl SensorParams {
    /// The ideal change detector of ESIM (Rebecq et al., CoRL 2018): θ = 0.2, no mismatch,
    /// no low-pass, latency, refractory period or noise.
    pub fn ideal() -> Self {
        SensorParams {
            threshold_on: 0.2,
            threshold_off: 0.2,
            threshold_sigma: 0.0,
            linlog_threshold: 0.0,
            log_eps: 1e-3,
            cutoff_hz: 0.0,
            cutoff_reference_irradiance: 10.0,
            cutoff_dark_irradiance: 0.1,
            latency_us: 0.0,
            jitter_us: 0.0,
            refractory_us: 0.0,
            leak_rate_hz: 0.0,
            shot_noise_rate_hz: 0.0,
            noise_rate_cov_decades: 0.0,
            hot_pixel_fraction: 0.0,
            hot_pixel_rate_hz: 0.0,
            bandwidth_ev_per_s: None,
            bandwidth_burst_events: 1024.0,
            timestamp: TimestampMode::Round,
        }
    }

    /// A modern HD sensor (Prophesee Gen4 / IMX636 class) as in the EBIV paper's camera
    /// table (Willert & Klinner, Exp. Fluids 63:101, 2022); values and sources in the table
    /// of [`SensorParams`].
    pub fn gen4() -> Self {
        SensorParams {
            threshold_on: 1.25f64.ln(),
            threshold_off: 1.25f64.ln(),
            threshold_sigma: 0.025,
            linlog_threshold: 0.1,
            log_eps: 1e-3,
            cutoff_hz: 10_000.0,
            cutoff_reference_irradiance: 10.0,
            cutoff_dark_irradiance: 0.1,
            latency_us: 20.0,
            jitter_us: 3.0,
            refractory_us: 5.0,
            leak_rate_hz: 0.1,
            shot_noise_rate_hz: 0.5,
            noise_rate_cov_decades: 0.1,
            hot_pixel_fraction: 1e-4,
            hot_pixel_rate_hz: 50.0,
            bandwidth_ev_per_s: Some(4e8),
            bandwidth_burst_events: 1024.0,
            timestamp: TimestampMode::Truncate,
        }
    }

    /// The camera of the EBIV paper's wall flow (Prophesee Gen4.1 HD, Sony IMX636) as set
    /// for that recording: [`SensorParams::gen4`] with a refractory period of
    /// [`IMX636_REFRACTORY_US`], calibrated so that a simulated wall flow has the real
    /// recording's pixel activity (docs/calibration.md).
    pub fn imx636() -> Self {
        SensorParams {
            refractory_us: IMX636_REFRACTORY_US,
            ..Self::gen4()
        }
    }

    /// v2e's `noisy` preset (Hu, Liu & Delbruck, CVPRW 2021): σ_θ = 0.05, leak 0.1 Hz,
    /// shot noise 5 Hz, a slow photoreceptor (1 kHz at the reference irradiance).
    pub fn noisy() -> Self {
        SensorParams {
            threshold_on: 0.2,
            threshold_off: 0.2,
            threshold_sigma: 0.05,
            linlog_threshold: 0.1,
            log_eps: 1e-3,
            cutoff_hz: 1_000.0,
            cutoff_reference_irradiance: 10.0,
            cutoff_dark_irradiance: 0.1,
            latency_us: 0.0,
            jitter_us: 0.0,
            refractory_us: 0.0,
            leak_rate_hz: 0.1,
            shot_noise_rate_hz: 5.0,
            noise_rate_cov_decades: 0.1,
            hot_pixel_fraction: 0.0,
            hot_pixel_rate_hz: 0.0,
            bandwidth_ev_per_s: None,
            bandwidth_burst_events: 1024.0,
            timestamp: TimestampMode::Truncate,
        }
    }

    /// The preset called `name` (`ideal`, `gen4`, `imx636`, `noisy`; case-insensitive).
    pub fn preset(name: &str) -> Option<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "ideal" => Some(Self::ideal()),
            "gen4" => Some(Self::gen4()),
            "imx636" => Some(Self::imx636()),
            "noisy" => Some(Self::noisy()),
            _ => None,
        }
    }

    /// The names [`SensorParams::preset`] knows.
    pub const PRESETS: [&'static str; 4] = ["ideal", "gen4", "imx636", "noisy"];

    /// Check every value; the error names the offending key.
    pub fn validate(&self) -> Result<()> {
        let in_range = |name: &str, v: f64, lo: f64, hi: f64| -> Result<()> {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err(Error::parameter(
                    name,
                    format!("{v} is outside [{lo}, {hi}]"),
                ))
            }
        };
        in_range("threshold_on", self.threshold_on, 0.01, 20.0)?;
        in_range("threshold_off", self.threshold_off, 0.01, 20.0)?;
        in_range("threshold_sigma", self.threshold_sigma, 0.0, 5.0)?;
        in_range("linlog_threshold", self.linlog_threshold, 0.0, 1e30)?;
        in_range("log_eps", self.log_eps, 0.0, 1e30)?;
        if self.linlog_threshold == 0.0 && self.log_eps == 0.0 {
            return Err(Error::parameter(
                "log_eps",
                "must be positive when linlog_threshold is 0 (ln 0 is undefined)",
            ));
        }
        in_range("cutoff_hz", self.cutoff_hz, 0.0, 1e9)?;
        in_range(
            "cutoff_reference_irradiance",
            self.cutoff_reference_irradiance,
            0.0,
            1e30,
        )?;
        in_range(
            "cutoff_dark_irradiance",
            self.cutoff_dark_irradiance,
            0.0,
            1e30,
        )?;
        in_range("latency_us", self.latency_us, 0.0, 1e9)?;
        in_range("jitter_us", self.jitter_us, 0.0, 1e9)?;
        in_range("refractory_us", self.refractory_us, 0.0, 1e9)?;
        in_range("leak_rate_hz", self.leak_rate_hz, 0.0, MAX_RATE_HZ)?;
        in_range(
            "shot_noise_rate_hz",
            self.shot_noise_rate_hz,
            0.0,
            MAX_RATE_HZ,
        )?;
        in_range(
            "noise_rate_cov_decades",
            self.noise_rate_cov_decades,
            0.0,
            2.0,
        )?;
        in_range("hot_pixel_fraction", self.hot_pixel_fraction, 0.0, 1.0)?;
        in_range(
            "hot_pixel_rate_hz",
            self.hot_pixel_rate_hz,
            0.0,
            MAX_RATE_HZ,
        )?;
        if let Some(rate) = self.bandwidth_ev_per_s {
            if !(rate.is_finite() && rate > 0.0) {
                return Err(Error::parameter(
                    "bandwidth_ev_per_s",
                    format!("{rate} must be a positive number of events per second"),
                ));
            }
        }
        in_range(
            "bandwidth_burst_events",
            self.bandwidth_burst_events,
            1.0,
            1e12,
        )?;
        Ok(())
    }
}
