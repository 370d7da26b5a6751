//! The refractory filter: at most one event per pixel per refractory period.
//!
//! A pixel's event is removed when it comes less than Δt_ref after that pixel's previous
//! *kept* event (whatever its polarity), so a kept event at `t` blinds its pixel during
//! `[t, t + Δt_ref)` and an event exactly Δt_ref later is kept. This is the refractory
//! period of the DVS pixel (Lichtsteiner, Posch & Delbruck, IEEE JSSC 43:566, 2008) applied
//! after the fact, as Metavision's `RefractoryPeriodFilter` / tonic's `RefractoryPeriod`
//! do: it thins bursts of a flickering or oscillating pixel and caps every pixel's rate at
//! 1/Δt_ref. Events whose time stamp runs backwards in a pixel (a time regression) are
//! removed too: they fall before the pixel's end of blindness.

use super::PixelMap;
use crate::event::Geometry;

/// Per-pixel time of the last kept event.
#[derive(Debug, Clone)]
pub struct RefractoryFilter {
    last_kept: PixelMap<i64>,
    period_us: i64,
}

impl RefractoryFilter {
    /// A filter with refractory period `period_us` on a sensor of `geometry`.
    pub fn new(geometry: Geometry, period_us: i64) -> Self {
        RefractoryFilter {
            last_kept: PixelMap::new(geometry, i64::MIN),
            period_us,
        }
    }

    /// Whether the event (t, x, y), the next of the stream, is kept; updates the state.
    /// Events off the sensor are kept.
    #[inline]
    pub fn keep(&mut self, t: i64, x: u16, y: u16) -> bool {
        let Some(i) = self.last_kept.index(x, y) else {
            return true;
        };
        let last = &mut self.last_kept.values[i];
        if t.saturating_sub(*last) >= self.period_us {
            *last = t;
            true
        } else {
            false
        }
    }
}
