//! Pixel activity of a recording: how often and how regularly pixels fire, how many events a
//! window of a time slab holds, and how wide particle trails are — the statistics that compare
//! a simulated recording with a real one (`ebiv info --activity`, docs/calibration.md).
//!
//! All statistics are taken over the events handed to [`Activity::add`] (select polarity,
//! region and interval first, e.g. with [`crate::filter::EventFilter`]):
//!
//! * **events per active pixel**: the number of events of each pixel with at least one;
//! * **time between events of one pixel**: the differences between successive time stamps of
//!   each pixel, in the order read (a time stamp earlier than its pixel's previous one counts
//!   as 0), pooled over all pixels;
//! * **active share**: the fraction of the sensor's (or region's) pixels with any event;
//! * **events per window**: the events in each square window of `window_px` (tiles from the
//!   top-left corner, whole windows only) and each time slab of `slab_us` (consecutive from
//!   the start of the interval, whole slabs only), zeros included;
//! * **trail width**: see [`trails`]; measured on each whole slab's image of active pixels.
//!
//! Quantiles follow [`quantile`] (linear interpolation, NumPy's default). Memory is bounded by
//! the sensor size, not the recording length: per-pixel counters, two open slabs, and
//! histograms (gaps exact to 1 µs below [`EXACT_GAP_US`], to 1/1024 relative above; trail
//! widths to [`WIDTH_BIN_PX`]).

pub mod quantile;
pub mod trails;

use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use std::collections::{BTreeMap, HashMap};

/// Gaps shorter than this, µs, are kept exactly; longer ones to a relative 1/1024.
pub const EXACT_GAP_US: i64 = 1 << 20;
/// Resolution of the trail-width histogram, px.
pub const WIDTH_BIN_PX: f64 = 0.01;
/// Slabs kept open for events that arrive slightly out of time order.
const OPEN_SLABS: i64 = 2;

/// Window and slab of the events-per-window statistic and the trail width.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ActivitySettings {
    /// Side of the square windows, px (the EBIV paper's wall flow: 40).
    pub window_px: u32,
    /// Length of the time slabs, µs (the paper's T = 10 ms).
    pub slab_us: i64,
}

impl Default for ActivitySettings {
    fn default() -> Self {
        ActivitySettings {
            window_px: 40,
            slab_us: 10_000,
        }
    }
}

/// The statistics of [`Activity`]; quantiles are `None` where nothing was measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ActivityReport {
    /// Events taken into account.
    pub events: u64,
    /// Pixels of the sensor or region.
    pub pixels: u64,
    /// Pixels with at least one event.
    pub active_pixels: u64,
    /// `active_pixels / pixels`.
    pub active_share: f64,
    /// Events per active pixel: median and 90th percentile.
    pub events_per_active_pixel: Option<[f64; 2]>,
    /// Time between successive events of one pixel, µs: 10th, 50th and 90th percentiles.
    pub gap_us: Option<[f64; 3]>,
    /// Number of such gaps.
    pub gaps: u64,
    /// Events per window and slab: 5th, 50th and 95th percentiles.
    pub window_events: Option<[f64; 3]>,
    /// Number of (window, slab) cells counted.
    pub window_cells: u64,
    /// Whole slabs measured.
    pub slabs: u64,
    /// Trail width, px: 25th, 50th and 75th percentiles.
    pub trail_width_px: Option<[f64; 3]>,
    /// Number of trails measured.
    pub trails: u64,
    /// Events that arrived after their slab was closed (more than a slab out of time order);
    /// they count in every statistic but the windows and trails.
    pub late_events: u64,
    /// The settings used.
    pub settings: ActivitySettings,
}

/// Accumulates the activity statistics batch by batch.
#[derive(Debug)]
pub struct Activity {
    geometry: Geometry,
    settings: ActivitySettings,
    origin_us: i64,
    end_us: Option<i64>,
    count: Vec<u32>,
    last_t: Vec<i64>,
    gaps: HashMap<i64, u64>,
    windows_x: usize,
    windows_y: usize,
    open: BTreeMap<i64, Slab>,
    next_slab: i64,
    window_hist: HashMap<u32, u64>,
    width_hist: HashMap<u32, u64>,
    slabs: u64,
    events: u64,
    late: u64,
    t_max: Option<i64>,
}

/// Counts of one open slab.
#[derive(Debug)]
struct Slab {
    windows: Vec<u32>,
    active: Vec<bool>,
}

impl Activity {
    /// Statistics over a `geometry`-sized sensor for events from `origin_us` on; slabs start
    /// at `origin_us`. With `end_us` (exclusive) slabs up to it count as whole; without it,
    /// those up to the last event's time stamp.
    pub fn new(
        geometry: Geometry,
        origin_us: i64,
        end_us: Option<i64>,
        settings: ActivitySettings,
    ) -> Result<Self> {
        if settings.window_px == 0 {
            return Err(Error::parameter("window", "must be at least 1 px"));
        }
        if settings.slab_us <= 0 {
            return Err(Error::parameter("slab", "must be longer than 0 µs"));
        }
        let pixels = geometry.pixels();
        let (w, h) = (geometry.width as usize, geometry.height as usize);
        let win = settings.window_px as usize;
        Ok(Activity {
            geometry,
            settings,
            origin_us,
            end_us,
            count: vec![0; pixels],
            last_t: vec![i64::MIN; pixels],
            gaps: HashMap::new(),
            windows_x: w / win,
            windows_y: h / win,
            open: BTreeMap::new(),
            next_slab: 0,
            window_hist: HashMap::new(),
            width_hist: HashMap::new(),
            slabs: 0,
            events: 0,
            late: 0,
            t_max: None,
        })
    }

    /// The statistics of one buffer of events.
    pub fn measure(
        events: &EventBuffer,
        geometry: Geometry,
        origin_us: i64,
        end_us: Option<i64>,
        settings: ActivitySettings,
    ) -> Result<ActivityReport> {
        let mut a = Activity::new(geometry, origin_us, end_us, settings)?;
        a.add(events)?;
        Ok(a.finish())
    }

    /// Add a batch. Events outside the sensor are an error (crop with a region first); events
    /// before the origin or at or after the end are ignored.
    pub fn add(&mut self, batch: &EventBuffer) -> Result<()> {
        let (w, win) = (
            self.geometry.width as usize,
            self.settings.window_px as usize,
        );
        for i in 0..batch.len() {
            let (t, x, y) = (batch.t[i], batch.x[i] as u32, batch.y[i] as u32);
            if t < self.origin_us || self.end_us.is_some_and(|e| t >= e) {
                continue;
            }
            if !self.geometry.contains(x, y) {
                return Err(Error::parameter(
                    "events",
                    format!(
                        "event at x={x} y={y} lies outside the {} sensor (pass --geometry or --roi)",
                        self.geometry
                    ),
                ));
            }
            self.events += 1;
            self.t_max = Some(self.t_max.map_or(t, |m| m.max(t)));
            let k = y as usize * w + x as usize;
            self.count[k] = self.count[k].saturating_add(1);
            let last = self.last_t[k];
            if last != i64::MIN {
                *self
                    .gaps
                    .entry(gap_key(t.saturating_sub(last).max(0)))
                    .or_default() += 1;
            }
            self.last_t[k] = t;
            let slab = (t - self.origin_us) / self.settings.slab_us;
            if slab < self.next_slab {
                self.late += 1;
                continue;
            }
            self.close_before(slab - OPEN_SLABS + 1);
            let (wx, wy) = (x as usize / win, y as usize / win);
            let (nx, ny, pixels) = (self.windows_x, self.windows_y, self.geometry.pixels());
            let s = self.open.entry(slab).or_insert_with(|| Slab {
                windows: vec![0; nx * ny],
                active: vec![false; pixels],
            });
            if wx < nx && wy < ny {
                s.windows[wy * nx + wx] += 1;
            }
            s.active[k] = true;
        }
        Ok(())
    }

    /// Close, in order, every slab before `slab` (those without events as empty slabs).
    fn close_before(&mut self, slab: i64) {
        while self.next_slab < slab {
            let s = self.open.remove(&self.next_slab);
            self.close(s);
            self.next_slab += 1;
        }
    }

    /// Fold one whole slab into the window and trail histograms.
    fn close(&mut self, slab: Option<Slab>) {
        self.slabs += 1;
        let cells = self.windows_x * self.windows_y;
        match slab {
            None => *self.window_hist.entry(0).or_default() += cells as u64,
            Some(s) => {
                for &c in &s.windows {
                    *self.window_hist.entry(c).or_default() += 1;
                }
                let (w, h) = (self.geometry.width as usize, self.geometry.height as usize);
                for width in trails::trail_widths(&s.active, w, h) {
                    let bin = (width / WIDTH_BIN_PX).round() as u32;
                    *self.width_hist.entry(bin).or_default() += 1;
                }
            }
        }
    }

    /// The statistics.
    pub fn finish(mut self) -> ActivityReport {
        let end = match (self.end_us, self.t_max) {
            (Some(e), _) => Some(e),
            (None, Some(t)) => Some(t + 1),
            (None, None) => None,
        };
        let whole = end.map_or(0, |e| (e - self.origin_us).max(0) / self.settings.slab_us);
        self.close_before(whole.max(self.next_slab));
        let active = self.count.iter().filter(|&&c| c > 0).count() as u64;
        let mut per_pixel: HashMap<u32, u64> = HashMap::new();
        for &c in self.count.iter().filter(|&&c| c > 0) {
            *per_pixel.entry(c).or_default() += 1;
        }
        let pairs = |h: &HashMap<u32, u64>, scale: f64| -> Vec<(f64, u64)> {
            h.iter().map(|(&v, &c)| (v as f64 * scale, c)).collect()
        };
        let gap_pairs: Vec<(f64, u64)> =
            self.gaps.iter().map(|(&k, &c)| (gap_value(k), c)).collect();
        let pixels = self.geometry.pixels() as u64;
        let window_cells = self.window_hist.values().sum();
        let trails = self.width_hist.values().sum();
        ActivityReport {
            events: self.events,
            pixels,
            active_pixels: active,
            active_share: if pixels > 0 {
                active as f64 / pixels as f64
            } else {
                0.0
            },
            events_per_active_pixel: quantile::quantiles(pairs(&per_pixel, 1.0), &[0.5, 0.9])
                .map(|q| [q[0], q[1]]),
            gaps: self.gaps.values().sum(),
            gap_us: quantile::quantiles(gap_pairs, &[0.1, 0.5, 0.9]).map(|q| [q[0], q[1], q[2]]),
            window_events: quantile::quantiles(pairs(&self.window_hist, 1.0), &[0.05, 0.5, 0.95])
                .map(|q| [q[0], q[1], q[2]]),
            window_cells,
            slabs: self.slabs,
            trail_width_px: quantile::quantiles(
                pairs(&self.width_hist, WIDTH_BIN_PX),
                &[0.25, 0.5, 0.75],
            )
            .map(|q| [q[0], q[1], q[2]]),
            trails,
            late_events: self.late,
            settings: self.settings,
        }
    }
}

/// Histogram key of a gap: the gap itself below [`EXACT_GAP_US`], else its value with the
/// lowest bits cleared so that 10 significant bits remain, tagged negative.
fn gap_key(gap: i64) -> i64 {
    if gap < EXACT_GAP_US {
        return gap;
    }
    let shift = (63 - gap.leading_zeros() as i64 - 10).max(0);
    -((gap >> shift) << shift) - 1
}

/// The gap, µs, a histogram key stands for.
fn gap_value(key: i64) -> f64 {
    if key >= 0 {
        key as f64
    } else {
        (-(key + 1)) as f64
    }
}

#[cfg(test)]
mod tests;
