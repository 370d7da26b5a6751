//! Hot-pixel removal by event rate.
//!
//! A hot pixel (a defect with a high leak current, or a stuck comparator) fires at a rate far
//! above its neighbours whatever the scene. The filter counts each pixel's events over a
//! leading learning interval of the recording — the first `denoise-hot-learn` from its first
//! event, the whole recording when it is shorter — and removes every event of the pixels
//! whose count is more than `denoise-hot-factor` times the median count of their 8
//! neighbours (fewer on the sensor's edge), and at least [`MIN_HOT_PIXEL_EVENTS`], and whose
//! first and last events in the interval lie at least [`MIN_HOT_SPREAD`] of it apart.
//!
//! The typical rate is taken locally, the way image sensors find defect pixels against the
//! median of their neighbourhood, rather than from the whole sensor: in a seeded flow the
//! pixels' rates spread widely (where particles pass, with the pixels' threshold mismatch),
//! so a sensor-wide mean or an absolute rate either misses hot pixels in a busy scene or
//! takes busy signal pixels for hot ones; a particle image lights neighbouring pixels
//! together, a hot pixel alone. The median ignores a second hot pixel next to the first.
//!
//! A hot pixel fires all through the interval; a signal pixel fires in bursts, while a
//! particle image crosses it. In a long recording many crossings spread a busy signal
//! pixel's events too, but its neighbours are as busy and the rate test keeps it; in a
//! recording of tens of milliseconds a pixel that one or two particles crossed, alone in a
//! sparse region, can fire many times its neighbours' median, and the spread test keeps it.
//!
//! Learning from a leading interval rather than from a pass over the whole file keeps the
//! cost independent of the recording's length and lets a run over any part of it (a shard,
//! a late `--time`) decide the same set; memory is a count and two times per pixel (12 bytes).

use super::PixelMap;
use crate::event::{EventBuffer, Geometry};

/// A pixel is hot only with at least this many events in the learning interval: below it a
/// high count relative to a sparse scene is chance, not a defect.
pub const MIN_HOT_PIXEL_EVENTS: u32 = 10;

/// A pixel is hot only if its first and last events in the learning interval lie at least
/// this fraction of the interval apart (of the recording's span, when that is shorter). Ten
/// events of a steady rate spread over less than half the interval with probability 1 %.
pub const MIN_HOT_SPREAD: f64 = 0.5;

/// Counts, and times of the first and last events, per pixel over the learning interval.
#[derive(Debug, Clone)]
pub struct HotPixelLearner {
    counts: PixelMap<u32>,
    /// µs from the interval's start (saturating at `u32::MAX`, 71 minutes).
    first_us: PixelMap<u32>,
    last_us: PixelMap<u32>,
    /// The latest event time in the interval, µs from its start.
    latest_us: u32,
    learn_us: i64,
    /// The interval `[start, end)`, from the first event.
    interval: Option<(i64, i64)>,
    done: bool,
}

impl HotPixelLearner {
    /// A learner over the first `learn_us` of a recording on a sensor of `geometry`.
    pub fn new(geometry: Geometry, learn_us: i64) -> Self {
        HotPixelLearner {
            counts: PixelMap::new(geometry, 0),
            first_us: PixelMap::new(geometry, u32::MAX),
            last_us: PixelMap::new(geometry, 0),
            latest_us: 0,
            learn_us,
            interval: None,
            done: false,
        }
    }

    /// Count the events of `batch` (the next of the recording, in file order) that fall in
    /// the learning interval; `false` once a batch reaches its end, when no more are needed.
    pub fn add(&mut self, batch: &EventBuffer) -> bool {
        for i in 0..batch.len() {
            let t = batch.t[i];
            let (start, end) = *self
                .interval
                .get_or_insert_with(|| (t, t.saturating_add(self.learn_us)));
            if t >= end {
                self.done = true;
                continue;
            }
            // (An event before the first one, in a file not in time order, counts at 0.)
            let at = u32::try_from(t.saturating_sub(start).max(0)).unwrap_or(u32::MAX);
            self.latest_us = self.latest_us.max(at);
            if let Some(k) = self.counts.index(batch.x[i], batch.y[i]) {
                let c = &mut self.counts.values[k];
                *c = c.saturating_add(1);
                let first = &mut self.first_us.values[k];
                *first = (*first).min(at);
                let last = &mut self.last_us.values[k];
                *last = (*last).max(at);
            }
        }
        !self.done
    }

    /// The hot pixels by `factor` (see the module documentation).
    pub fn finish(self, factor: f64) -> HotPixelFilter {
        let (w, h) = (self.counts.width, self.counts.height);
        let counts = &self.counts.values;
        let min_spread = MIN_HOT_SPREAD * f64::from(self.latest_us);
        let mut hot = vec![false; counts.len()];
        let mut around = Vec::with_capacity(8);
        for y in 0..h {
            for x in 0..w {
                let c = counts[y * w + x];
                let k = y * w + x;
                let spread = self.last_us.values[k].saturating_sub(self.first_us.values[k]);
                if c < MIN_HOT_PIXEL_EVENTS || f64::from(spread) < min_spread {
                    continue;
                }
                around.clear();
                for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                    for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                        if (nx, ny) != (x, y) {
                            around.push(counts[ny * w + nx]);
                        }
                    }
                }
                hot[y * w + x] = c as f64 > factor * median(&mut around);
            }
        }
        HotPixelFilter {
            hot: PixelMap {
                width: self.counts.width,
                height: self.counts.height,
                values: hot,
            },
        }
    }
}

/// The median of `values` (the mean of the middle two of an even count; 0 for none).
fn median(values: &mut [u32]) -> f64 {
    values.sort_unstable();
    let n = values.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => values[n / 2] as f64,
        _ => (values[n / 2 - 1] as f64 + values[n / 2] as f64) / 2.0,
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
