//! Hot-pixel removal by event rate.
//!
//! A hot pixel (a defect with a high leak current, or a stuck comparator) fires at a rate far
//! above its neighbours whatever the scene. The filter counts each pixel's events over a
//! leading learning interval of the recording — the first `denoise-hot-learn` from its first
//! event, the whole recording when it is shorter — and removes every event of the pixels
//! whose count is more than `denoise-hot-factor` times the mean count of the pixels with at
//! least one event, and at least [`MIN_HOT_PIXEL_EVENTS`]. This is the rate test of
//! Metavision's hot-pixel calibration and of v2e's / Delbruck's hot-pixel filters, made
//! relative so that it does not depend on the scene's overall activity.
//!
//! Learning from a leading interval rather than from a pass over the whole file keeps the
//! cost independent of the recording's length and lets a run over any part of it (a shard,
//! a late `--time`) decide the same set; memory is one counter per pixel.

use super::PixelMap;
use crate::event::{EventBuffer, Geometry};

/// A pixel is hot only with at least this many events in the learning interval: below it a
/// high count relative to a sparse scene is chance, not a defect.
pub const MIN_HOT_PIXEL_EVENTS: u32 = 10;

/// Counts per pixel over the learning interval.
#[derive(Debug, Clone)]
pub struct HotPixelLearner {
    counts: PixelMap<u32>,
    learn_us: i64,
    end_us: Option<i64>,
    done: bool,
}

impl HotPixelLearner {
    /// A learner over the first `learn_us` of a recording on a sensor of `geometry`.
    pub fn new(geometry: Geometry, learn_us: i64) -> Self {
        HotPixelLearner {
            counts: PixelMap::new(geometry, 0),
            learn_us,
            end_us: None,
            done: false,
        }
    }

    /// Count the events of `batch` (the next of the recording, in file order) that fall in
    /// the learning interval; `false` once a batch reaches its end, when no more are needed.
    pub fn add(&mut self, batch: &EventBuffer) -> bool {
        for i in 0..batch.len() {
            let t = batch.t[i];
            let end = *self
                .end_us
                .get_or_insert_with(|| t.saturating_add(self.learn_us));
            if t >= end {
                self.done = true;
                continue;
            }
            if let Some(k) = self.counts.index(batch.x[i], batch.y[i]) {
                let c = &mut self.counts.values[k];
                *c = c.saturating_add(1);
            }
        }
        !self.done
    }

    /// The hot pixels by `factor` (see the module documentation).
    pub fn finish(self, factor: f64) -> HotPixelFilter {
        let counts = &self.counts.values;
        let (sum, active) = counts
            .iter()
            .filter(|&&c| c > 0)
            .fold((0u64, 0u64), |(s, n), &c| (s + c as u64, n + 1));
        let mean = if active > 0 {
            sum as f64 / active as f64
        } else {
            0.0
        };
        let threshold = factor * mean;
        let hot: Vec<bool> = counts
            .iter()
            .map(|&c| c >= MIN_HOT_PIXEL_EVENTS && c as f64 > threshold)
            .collect();
        HotPixelFilter {
            hot: PixelMap {
                width: self.counts.width,
                height: self.counts.height,
                values: hot,
            },
        }
    }
}

/// The set of hot pixels, whose events are removed.
#[derive(Debug, Clone)]
pub struct HotPixelFilter {
    hot: PixelMap<bool>,
}

impl HotPixelFilter {
    /// A filter removing the events of `pixels` on a sensor of `geometry` (pixels off the
    /// sensor are ignored).
    pub fn from_pixels(geometry: Geometry, pixels: &[(u16, u16)]) -> Self {
        let mut hot = PixelMap::new(geometry, false);
        for &(x, y) in pixels {
            if let Some(i) = hot.index(x, y) {
                hot.values[i] = true;
            }
        }
        HotPixelFilter { hot }
    }

    /// Whether an event of pixel (x, y) is kept.
    #[inline]
    pub fn keep(&self, x: u16, y: u16) -> bool {
        self.hot.index(x, y).is_none_or(|i| !self.hot.values[i])
    }

    /// The hot pixels, `(x, y)` row by row.
    pub fn pixels(&self) -> Vec<(u16, u16)> {
        let w = self.hot.width;
        self.hot
            .values
            .iter()
            .enumerate()
            .filter(|(_, &h)| h)
            .map(|(i, _)| ((i % w) as u16, (i / w) as u16))
            .collect()
    }

    /// How many pixels are hot.
    pub fn count(&self) -> u64 {
        self.hot.values.iter().filter(|&&h| h).count() as u64
    }
}
