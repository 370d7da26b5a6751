//! The settings of particle tracking ([`TrackParams`]): one definition, read by the library,
//! the `ebiv track` flags and Python's keyword arguments (by [`TrackParams::set`]).

use crate::error::{Error, Result};
use crate::event::PolaritySelection;

/// How particles are detected in the events, linked into tracks and fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackParams {
    /// Length of the time slabs in which particles are detected, µs; 0 for automatic
    /// ([`super::slab`]). A particle must fire a few events within one slab (`min_events`)
    /// and move less than about its image
    /// diameter plus `gate` across it.
    pub slab_us: i64,
    /// Events of one cluster needed for a detection: fewer are taken as noise.
    pub min_events: u32,
    /// Largest distance between a track's predicted position and a detection it takes, px.
    pub gate_px: f64,
    /// Largest particle speed expected, px/ms: bounds the search for a track's second
    /// detection, before its velocity is known.
    pub max_speed: f64,
    /// Longest time without detections that a track bridges, µs.
    pub max_gap_us: i64,
    /// Shortest track kept, µs (first to last event).
    pub min_duration_us: i64,
    /// Full width of the local polynomial fit around each sample, µs.
    pub fit_window_us: i64,
    /// Degree of the local polynomial in time (1 to 3).
    pub degree: u32,
    /// Time between the samples written for each track, µs.
    pub sample_us: i64,
    /// Delay of the events behind the particle image, µs (sensor latency and photoreceptor
    /// lag): subtracted from every event time before the fit.
    pub latency_us: f64,
    /// Polarities used.
    pub polarity: PolaritySelection,
}

impl Default for TrackParams {
    fn default() -> Self {
        TrackParams {
            slab_us: 0,
            min_events: 4,
            gate_px: 4.0,
            max_speed: 10.0,
            max_gap_us: 3000,
            min_duration_us: 2000,
            fit_window_us: 8000,
            degree: 3,
            sample_us: 500,
            latency_us: 0.0,
            polarity: PolaritySelection::Both,
        }
    }
}

/// The settings by name: (key, value placeholder, help). The CLI's flags and Python's
/// keywords use these names (`_` for `-` in Python).
pub const TRACK_SETTINGS: &[(&str, &str, &str)] = &[
    (
        "slab",
        "DUR|auto",
        "Detection slab length: particles are found as clusters of events within each slab; auto: the shortest of 500us, 1ms, 2ms that puts 80 % of the first 20 ms of events in detections",
    ),
    (
        "min-events",
        "N",
        "Events of one cluster needed for a detection; smaller clusters are noise",
    ),
    (
        "gate",
        "PX",
        "Largest distance between a track's predicted position and the detection it takes",
    ),
    (
        "max-speed",
        "PX/MS",
        "Largest particle speed expected: bounds the search for a new track's second detection",
    ),
    (
        "max-gap",
        "DUR",
        "Longest time without detections a track bridges",
    ),
    (
        "min-duration",
        "DUR",
        "Shortest track kept (first to last event)",
    ),
    (
        "fit-window",
        "DUR",
        "Full width of the local polynomial fit around each sample",
    ),
    ("degree", "1-3", "Degree of the local polynomial in time"),
    (
        "sample",
        "DUR",
        "Time between the samples written for each track",
    ),
    (
        "latency",
        "US",
        "Delay of the events behind the particle, µs, subtracted before the fit",
    ),
    ("polarity", "pos|neg|both", "Polarities used"),
];

impl TrackParams {
    /// Set one setting from its text, by its name in [`TRACK_SETTINGS`] (`-` or `_`).
    pub fn set(&mut self, key: &str, text: &str) -> Result<()> {
        // The settings change only when the new value is valid.
        let mut next = self.clone();
        next.apply(key, text)?;
        next.validate()?;
        *self = next;
        Ok(())
    }

    fn apply(&mut self, key: &str, text: &str) -> Result<()> {
        let key = key.replace('_', "-");
        let bad = |why: String| Error::parameter(key.clone(), format!("{text:?}: {why}"));
        let duration = || crate::units::parse_us(text).map_err(bad);
        let number = || {
            text.trim()
                .parse::<f64>()
                .map_err(|_| bad("not a number".into()))
        };
        match key.as_str() {
            "slab" if text.trim().eq_ignore_ascii_case("auto") => self.slab_us = 0,
            "slab" => {
                self.slab_us = duration()?;
                if self.slab_us == 0 {
                    return Err(bad("must be longer than 0 (or auto)".into()));
                }
            }
            "min-events" => {
                let n = number()?;
                if n.fract() != 0.0 || !(1.0..=1e6).contains(&n) {
                    return Err(bad("must be a whole number from 1 to 1000000".into()));
                }
                self.min_events = n as u32
            }
            "gate" => self.gate_px = number()?,
            "max-speed" => self.max_speed = number()?,
            "max-gap" => self.max_gap_us = duration()?,
            "min-duration" => self.min_duration_us = duration()?,
            "fit-window" => self.fit_window_us = duration()?,
            "degree" => {
                let d = number()?;
                if d.fract() != 0.0 {
                    return Err(bad("must be 1, 2 or 3".into()));
                }
                self.degree = d.clamp(0.0, 99.0) as u32
            }
            "sample" => self.sample_us = duration()?,
            "latency" => self.latency_us = number()?,
            "polarity" => {
                self.polarity = PolaritySelection::parse(text)
                    .ok_or_else(|| bad("must be pos, neg or both".into()))?
            }
            _ => {
                let names: Vec<&str> = TRACK_SETTINGS.iter().map(|s| s.0).collect();
                return Err(Error::parameter(
                    key.clone(),
                    format!("unknown track setting; known: {}", names.join(", ")),
                ));
            }
        }
        Ok(())
    }

    /// The value of one setting as text, by its name in [`TRACK_SETTINGS`] (`None` for an
    /// unknown name).
    pub fn get(&self, key: &str) -> Option<String> {
        let us = |t: i64| {
            if t % 1000 == 0 {
                format!("{}ms", t / 1000)
            } else {
                format!("{t}us")
            }
        };
        Some(match key.replace('_', "-").as_str() {
            "slab" if self.slab_us == 0 => "auto".into(),
            "slab" => us(self.slab_us),
            "min-events" => self.min_events.to_string(),
            "gate" => self.gate_px.to_string(),
            "max-speed" => self.max_speed.to_string(),
            "max-gap" => us(self.max_gap_us),
            "min-duration" => us(self.min_duration_us),
            "fit-window" => us(self.fit_window_us),
            "degree" => self.degree.to_string(),
            "sample" => us(self.sample_us),
            "latency" => self.latency_us.to_string(),
            "polarity" => self.polarity.name().to_string(),
            _ => return None,
        })
    }

    /// Every setting as (key, value text), for file attributes and reports.
    pub fn describe(&self) -> Vec<(String, String)> {
        TRACK_SETTINGS
            .iter()
            .filter_map(|(key, _, _)| Some((key.to_string(), self.get(key)?)))
            .collect()
    }

    /// Check every value, naming the offending setting.
    pub fn validate(&self) -> Result<()> {
        let fail = |name: &str, why: String| Err(Error::parameter(name, why));
        if !(0..=1_000_000).contains(&self.slab_us) {
            return fail(
                "slab",
                format!("{} µs: must be 1 µs to 1 s, or 0 (auto)", self.slab_us),
            );
        }
        if self.min_events < 1 {
            return fail("min-events", "must be at least 1".into());
        }
        if !(self.gate_px.is_finite() && self.gate_px > 0.0 && self.gate_px <= 100.0) {
            return fail("gate", format!("{} px: must be in (0, 100]", self.gate_px));
        }
        if !(self.max_speed.is_finite() && self.max_speed >= 0.0 && self.max_speed <= 1e4) {
            return fail(
                "max-speed",
                format!("{}: must be in [0, 10000] px/ms", self.max_speed),
            );
        }
        if !(0..=10_000_000).contains(&self.max_gap_us) {
            return fail(
                "max-gap",
                format!("{} µs: must be 0 to 10 s", self.max_gap_us),
            );
        }
        if !(0..=1_000_000_000).contains(&self.min_duration_us) {
            return fail(
                "min-duration",
                format!("{} µs: must be 0 to 1000 s", self.min_duration_us),
            );
        }
        if !(10..=10_000_000).contains(&self.fit_window_us) {
            return fail(
                "fit-window",
                format!("{} µs: must be 10 µs to 10 s", self.fit_window_us),
            );
        }
        if !(1..=3).contains(&self.degree) {
            return fail("degree", format!("{}: must be 1, 2 or 3", self.degree));
        }
        if !(1..=10_000_000).contains(&self.sample_us) {
            return fail(
                "sample",
                format!("{} µs: must be 1 µs to 10 s", self.sample_us),
            );
        }
        if !(self.latency_us.is_finite() && self.latency_us.abs() <= 1e6) {
            return fail(
                "latency",
                format!("{} µs: must be within ±1 s", self.latency_us),
            );
        }
        Ok(())
    }
}
