//! The spatio-temporal correlation (background-activity) filter of Delbrück, "Frame-free
//! dynamic digital vision", Proc. Int. Symp. Secure-Life Electronics, 2008, pp. 21–26.
//!
//! Background activity (leak and shot noise) fires pixels independently of their
//! neighbours, while a moving edge or particle image fires neighbouring pixels within a
//! short time. An event is kept only if one of its 8 neighbours fired at most Δt before it
//! (an event exactly Δt earlier supports it). The pixel itself does not count: support from
//! the same pixel is what a hot or flickering pixel gives itself, and an isolated noise
//! event of a pixel that fired before would pass. Every event that reaches the filter,
//! kept or not, is remembered as its pixel's latest, as in Delbrück's filter (a noise event
//! can support a later neighbour; a removed one still marks its pixel active). Pixels on
//! the sensor's edge have fewer neighbours. Metavision's `ActivityNoiseFilterAlgorithm` and
//! tonic's `Denoise` follow the same idea. A neighbour's event stamped *later* than the
//! event (time stamps that run backwards in file order) supports it too.

use super::PixelMap;
use crate::event::Geometry;

/// Per-pixel time of the latest event.
#[derive(Debug, Clone)]
pub struct CorrelationFilter {
    last: PixelMap<i64>,
    dt_us: i64,
}

impl CorrelationFilter {
    /// A filter with support window `dt_us` on a sensor of `geometry`.
    pub fn new(geometry: Geometry, dt_us: i64) -> Self {
        CorrelationFilter {
            last: PixelMap::new(geometry, i64::MIN),
            dt_us,
        }
    }

    /// Whether the event (t, x, y), the next of the stream, is kept; updates the state.
    /// Events off the sensor are kept.
    #[inline]
    pub fn keep(&mut self, t: i64, x: u16, y: u16) -> bool {
        let Some(i) = self.last.index(x, y) else {
            return true;
        };
        let (w, h) = (self.last.width, self.last.height);
        let (xu, yu) = (x as usize, y as usize);
        let (x0, x1) = (xu.saturating_sub(1), (xu + 1).min(w - 1));
        let (y0, y1) = (yu.saturating_sub(1), (yu + 1).min(h - 1));
        let mut supported = false;
        'rows: for ny in y0..=y1 {
            let row = &self.last.values[ny * w..ny * w + w];
            for (nx, &last) in row.iter().enumerate().take(x1 + 1).skip(x0) {
                if (nx != xu || ny != yu) && t.saturating_sub(last) <= self.dt_us {
                    supported = true;
                    break 'rows;
                }
            }
        }
        self.last.values[i] = t;
        supported
    }
}
