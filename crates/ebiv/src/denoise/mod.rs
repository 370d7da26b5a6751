//! Event denoising: filters that remove background activity (leak and shot noise), hot
//! pixels and bursts from a stream of events before any measurement, as the vendor tools
//! (Metavision's `ActivityNoiseFilterAlgorithm`) and tonic (`transforms.Denoise`) do.
//!
//! Three filters, each streaming over batches with per-pixel state only (memory does not grow
//! with the recording), run in this order:
//!
//! 1. [`HotPixelFilter`]: removes every event of the pixels whose event rate in a leading
//!    learning interval of the recording is far above that of their neighbours.
//! 2. [`RefractoryFilter`]: removes an event of a pixel less than Δt_ref after that pixel's
//!    previous kept event.
//! 3. [`CorrelationFilter`]: the background-activity filter of Delbrück (2008): keeps an
//!    event only if one of its 8 neighbours fired at most Δt before it.
//!
//! Selection by time, region and polarity is [`crate::filter`]'s, a different purpose:
//! selection keeps what the user asks for, denoising decides from the events themselves
//! which are sensor artefacts, and needs per-pixel state across batches. The readers apply a
//! [`Denoiser`] when their [`crate::io::ReadOptions`] ask for one, so every command that reads
//! a recording shares it. Polarity plays no part: each filter looks at pixels and times.

mod correlation;
mod hot_pixels;
mod refractory;
#[cfg(test)]
mod tests;

pub use correlation::CorrelationFilter;
pub use hot_pixels::{HotPixelFilter, HotPixelLearner, MIN_HOT_PIXEL_EVENTS};
pub use refractory::RefractoryFilter;

use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};

/// Most pixels a denoised sensor may have (per-pixel state of 8 bytes each: 1 GiB).
pub const MAX_DENOISE_PIXELS: u64 = 1 << 27;

/// Which filters run: `--denoise hot-pixels,refractory,correlation` (any of them, in any
/// order; they always run in the order of [`DenoiseFilters::NAMES`]), `all`, or `none`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DenoiseFilters {
    /// Remove the events of hot pixels.
    pub hot_pixels: bool,
    /// Remove events within the refractory period of a pixel's previous kept event.
    pub refractory: bool,
    /// Keep only events with a recent neighbour (background-activity filter).
    pub correlation: bool,
}

impl DenoiseFilters {
    /// The filters' names, in the order they run.
    pub const NAMES: [&'static str; 3] = ["hot-pixels", "refractory", "correlation"];

    /// Every filter.
    pub const ALL: DenoiseFilters = DenoiseFilters {
        hot_pixels: true,
        refractory: true,
        correlation: true,
    };

    /// Parse a comma-separated list of [`DenoiseFilters::NAMES`], `all` or `none`.
    pub fn parse(text: &str) -> std::result::Result<Self, String> {
        Self::parse_names(text.split(','))
    }

    /// The filters named by `names` (each one of [`DenoiseFilters::NAMES`], `all` or `none`).
    pub fn parse_names<'a>(
        names: impl IntoIterator<Item = &'a str>,
    ) -> std::result::Result<Self, String> {
        let mut f = DenoiseFilters::default();
        for name in names {
            match name.trim() {
                "hot-pixels" | "hot_pixels" => f.hot_pixels = true,
                "refractory" => f.refractory = true,
                "correlation" => f.correlation = true,
                "all" => f = DenoiseFilters::ALL,
                "none" | "" => {}
                other => {
                    return Err(format!(
                        "`{other}` is not a denoising filter; use hot-pixels, refractory, correlation, all or none"
                    ))
                }
            }
        }
        Ok(f)
    }

    /// Whether any filter runs.
    pub fn any(&self) -> bool {
        self.hot_pixels || self.refractory || self.correlation
    }

    /// The names of the filters that run, in their order.
    pub fn names(&self) -> Vec<&'static str> {
        let on = [self.hot_pixels, self.refractory, self.correlation];
        Self::NAMES
            .iter()
            .zip(on)
            .filter_map(|(n, on)| on.then_some(*n))
            .collect()
    }

    /// `hot-pixels,correlation`, or `none`.
    pub fn text(&self) -> String {
        let names = self.names();
        if names.is_empty() {
            "none".into()
        } else {
            names.join(",")
        }
    }
}

/// The parameters of denoising; the defaults are those of
/// [`crate::settings::ProcessSettings`] (`denoise`, `denoise-dt`, …).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenoiseSettings {
    /// Which filters run.
    pub filters: DenoiseFilters,
    /// Correlation filter: the longest time, µs, between an event and the latest event of
    /// a neighbour that supports it.
    pub correlation_dt_us: i64,
    /// Refractory filter: the period after a pixel's kept event in which its events are
    /// removed, µs.
    pub refractory_us: i64,
    /// Hot-pixel filter: a pixel is hot when its count in the learning interval exceeds
    /// this many times the median count of its 8 neighbours.
    pub hot_pixel_factor: f64,
    /// Hot-pixel filter: the leading interval of the recording, from its first event, µs,
    /// whose counts decide which pixels are hot.
    pub hot_pixel_learn_us: i64,
}

impl DenoiseSettings {
    /// Check every parameter of the filters that run; the error names the setting.
    pub fn check(&self) -> Result<()> {
        let positive = |name: &str, v: i64| {
            if v > 0 {
                Ok(())
            } else {
                Err(Error::parameter(
                    name,
                    format!("{v} µs: must be longer than 0"),
                ))
            }
        };
        if self.filters.correlation {
            positive("denoise-dt", self.correlation_dt_us)?;
        }
        if self.filters.refractory {
            positive("denoise-refractory", self.refractory_us)?;
        }
        if self.filters.hot_pixels {
            positive("denoise-hot-learn", self.hot_pixel_learn_us)?;
            if !(self.hot_pixel_factor.is_finite() && self.hot_pixel_factor > 1.0) {
                return Err(Error::parameter(
                    "denoise-hot-factor",
                    format!("{}: must be a number above 1", self.hot_pixel_factor),
                ));
            }
        }
        Ok(())
    }

    /// "correlation (Δt 1ms), refractory (100us)": what runs, for messages and attributes.
    pub fn describe(&self) -> String {
        let d = crate::units::format_us;
        let mut parts = Vec::new();
        if self.filters.hot_pixels {
            parts.push(format!(
                "hot-pixels (above {}× the neighbours' median count over the first {})",
                self.hot_pixel_factor,
                d(self.hot_pixel_learn_us)
            ));
        }
        if self.filters.refractory {
            parts.push(format!("refractory ({})", d(self.refractory_us)));
        }
        if self.filters.correlation {
            parts.push(format!("correlation (Δt {})", d(self.correlation_dt_us)));
        }
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(", ")
        }
    }
}

/// How many events each filter removed; a filter that did not run is `None`.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct DenoiseReport {
    /// Events that entered the first filter.
    pub events_in: u64,
    /// Events that left the last filter.
    pub events_out: u64,
    /// Pixels found hot in the learning interval.
    pub hot_pixels: Option<u64>,
    /// Events removed by the hot-pixel filter.
    pub removed_hot_pixels: Option<u64>,
    /// Events removed by the refractory filter.
    pub removed_refractory: Option<u64>,
    /// Events removed by the correlation filter.
    pub removed_correlation: Option<u64>,
}

impl DenoiseReport {
    /// One line per filter that ran: `correlation: removed 1234 of 5678 events (21.7 %)`.
    /// Each filter's share is of the events that reached it.
    pub fn lines(&self) -> Vec<String> {
        let mut lines = Vec::new();
        let mut reaching = self.events_in;
        let stages = [
            ("hot-pixels", self.removed_hot_pixels),
            ("refractory", self.removed_refractory),
            ("correlation", self.removed_correlation),
        ];
        for (name, removed) in stages {
            if let Some(removed) = removed {
                let share = if reaching > 0 {
                    100.0 * removed as f64 / reaching as f64
                } else {
                    0.0
                };
                let hot = match (name, self.hot_pixels) {
                    ("hot-pixels", Some(n)) => format!(" ({n} hot pixel(s))"),
                    _ => String::new(),
                };
                lines.push(format!(
                    "{name}: removed {removed} of {reaching} events ({share:.1} %){hot}"
                ));
                reaching -= removed;
            }
        }
        lines.push(format!(
            "denoising kept {} of {} events",
            self.events_out, self.events_in
        ));
        lines
    }

    /// Events removed by all filters together.
    pub fn removed(&self) -> u64 {
        self.events_in - self.events_out
    }
}

/// The filters of [`DenoiseSettings`] in their order, with their counts: feed it every batch
/// of a recording in file order ([`Denoiser::apply`]).
#[derive(Debug, Clone)]
pub struct Denoiser {
    hot_pixels: Option<HotPixelFilter>,
    refractory: Option<RefractoryFilter>,
    correlation: Option<CorrelationFilter>,
    report: DenoiseReport,
}

impl Denoiser {
    /// The filters of `settings` on a sensor of `geometry`; `hot` is the hot-pixel filter,
    /// learnt beforehand ([`HotPixelLearner`]), required when `settings` asks for it.
    pub fn new(
        settings: &DenoiseSettings,
        geometry: Geometry,
        hot: Option<HotPixelFilter>,
    ) -> Result<Self> {
        settings.check()?;
        check_geometry(geometry)?;
        let f = settings.filters;
        let hot_pixels = match (f.hot_pixels, hot) {
            (true, Some(h)) => Some(h),
            (true, None) => {
                return Err(Error::parameter(
                    "denoise",
                    "the hot-pixel filter needs the hot pixels learnt from the recording",
                ))
            }
            (false, _) => None,
        };
        let report = DenoiseReport {
            hot_pixels: hot_pixels.as_ref().map(|h| h.count()),
            removed_hot_pixels: f.hot_pixels.then_some(0),
            removed_refractory: f.refractory.then_some(0),
            removed_correlation: f.correlation.then_some(0),
            ..DenoiseReport::default()
        };
        Ok(Denoiser {
            hot_pixels,
            refractory: f
                .refractory
                .then(|| RefractoryFilter::new(geometry, settings.refractory_us)),
            correlation: f
                .correlation
                .then(|| CorrelationFilter::new(geometry, settings.correlation_dt_us)),
            report,
        })
    }

    /// Remove the noise events of `batch` (the next batch of the stream), in place; triggers
    /// are kept.
    pub fn apply(&mut self, batch: &mut EventBuffer) {
        let r = &mut self.report;
        r.events_in += batch.len() as u64;
        let (hot, refr, corr) = (
            &mut self.hot_pixels,
            &mut self.refractory,
            &mut self.correlation,
        );
        let (mut n_hot, mut n_refr, mut n_corr) = (0u64, 0u64, 0u64);
        batch.retain(|e| {
            if let Some(h) = hot.as_ref() {
                if !h.keep(e.x, e.y) {
                    n_hot += 1;
                    return false;
                }
            }
            if let Some(f) = refr.as_mut() {
                if !f.keep(e.t, e.x, e.y) {
                    n_refr += 1;
                    return false;
                }
            }
            if let Some(f) = corr.as_mut() {
                if !f.keep(e.t, e.x, e.y) {
                    n_corr += 1;
                    return false;
                }
            }
            true
        });
        let add = |c: &mut Option<u64>, n: u64| {
            if let Some(c) = c {
                *c += n;
            }
        };
        add(&mut r.removed_hot_pixels, n_hot);
        add(&mut r.removed_refractory, n_refr);
        add(&mut r.removed_correlation, n_corr);
        r.events_out += batch.len() as u64;
    }

    /// The counts so far.
    pub fn report(&self) -> &DenoiseReport {
        &self.report
    }

    /// Replace the counts (a reader's seek feeds the events before its target to the filters
    /// for their state, and leaves them out of the counts).
    pub(crate) fn set_report(&mut self, report: DenoiseReport) {
        self.report = report;
    }
}

/// An error for a sensor too large for per-pixel state.
pub fn check_geometry(geometry: Geometry) -> Result<()> {
    let pixels = geometry.width as u64 * geometry.height as u64;
    if pixels == 0 || pixels > MAX_DENOISE_PIXELS {
        return Err(Error::parameter(
            "denoise",
            format!(
                "a {geometry} sensor has {pixels} pixels; denoising keeps state for at most {MAX_DENOISE_PIXELS}"
            ),
        ));
    }
    Ok(())
}

/// Per-pixel values on a sensor, row by row.
#[derive(Debug, Clone)]
pub(crate) struct PixelMap<T> {
    width: usize,
    height: usize,
    values: Vec<T>,
}

impl<T: Copy> PixelMap<T> {
    pub(crate) fn new(geometry: Geometry, value: T) -> Self {
        let (width, height) = (geometry.width as usize, geometry.height as usize);
        PixelMap {
            width,
            height,
            values: vec![value; width * height],
        }
    }

    /// The index of pixel (x, y), `None` off the sensor.
    #[inline]
    pub(crate) fn index(&self, x: u16, y: u16) -> Option<usize> {
        let (x, y) = (x as usize, y as usize);
        (x < self.width && y < self.height).then(|| y * self.width + x)
    }
}
