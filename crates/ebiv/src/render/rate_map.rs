//! Event-rate maps: events per pixel per second, accumulated batch by batch.

use super::colormap::inferno;
use crate::event::{EventBuffer, Geometry, PolaritySelection};

/// Per-pixel event counts over a time interval.
pub struct EventRateMap {
    geometry: Geometry,
    counts: Vec<u32>,
    t_range: Option<(i64, i64)>,
}

/// A rendered rate map with its colour scale.
pub struct RateMapImage {
    /// The map with a colour bar along its right edge (bottom = 0, top = `max_rate`).
    pub image: image::RgbImage,
    /// Rate at the top of the colour scale, events per pixel per second.
    pub max_rate: f64,
    /// Mean rate over pixels that saw at least one event.
    pub mean_active_rate: f64,
    /// Pixels with at least one event.
    pub active_pixels: u64,
}

impl EventRateMap {
    /// An empty map for a sensor of `geometry`.
    pub fn new(geometry: Geometry) -> Self {
        EventRateMap {
            geometry,
            counts: vec![0; geometry.pixels()],
            t_range: None,
        }
    }

    /// Count the events of `batch` within `[t_start, t_end)` of the selected polarity.
    pub fn add(
        &mut self,
        batch: &EventBuffer,
        t_start: i64,
        t_end: i64,
        polarity: PolaritySelection,
    ) {
        let w = self.geometry.width as usize;
        for e in batch.iter() {
            if e.t < t_start || e.t >= t_end || !polarity.accepts(e.p) {
                continue;
            }
            if !self.geometry.contains(e.x as u32, e.y as u32) {
                continue;
            }
            let c = &mut self.counts[e.y as usize * w + e.x as usize];
            *c = c.saturating_add(1);
            self.t_range = Some(match self.t_range {
                Some((a, b)) => (a.min(e.t), b.max(e.t)),
                None => (e.t, e.t),
            });
        }
    }

    /// Event count at pixel `(x, y)`.
    pub fn count(&self, x: u32, y: u32) -> u32 {
        self.counts[y as usize * self.geometry.width as usize + x as usize]
    }

    /// Render with the inferno map on a square-root scale (so sparse pixels stay visible),
    /// saturating at the 99.9th percentile of active pixels. `duration_us` converts counts to
    /// rates; when `None`, the span of the counted events is used.
    pub fn render(&self, duration_us: Option<i64>) -> RateMapImage {
        let span = duration_us
            .or(self.t_range.map(|(a, b)| b - a + 1))
            .unwrap_or(1)
            .max(1) as f64
            * 1e-6;
        let mut active: Vec<u32> = self.counts.iter().copied().filter(|&c| c > 0).collect();
        active.sort_unstable();
        let top = active
            .get(((active.len() as f64 * 0.999) as usize).min(active.len().saturating_sub(1)))
            .copied()
            .unwrap_or(1)
            .max(1) as f64;
        let mean = if active.is_empty() {
            0.0
        } else {
            active.iter().map(|&c| c as f64).sum::<f64>() / active.len() as f64
        };
        let (w, h) = (self.geometry.width, self.geometry.height);
        let bar = (w / 40).max(6);
        let gap = bar / 2;
        let mut image = image::RgbImage::from_pixel(w + gap + bar, h, image::Rgb([255, 255, 255]));
        for y in 0..h {
            for x in 0..w {
                let c = self.count(x, y) as f64;
                image.put_pixel(x, y, image::Rgb(inferno((c / top).sqrt() as f32)));
            }
            let s = 1.0 - y as f32 / (h.max(2) - 1) as f32;
            for x in w + gap..w + gap + bar {
                image.put_pixel(x, y, image::Rgb(inferno(s)));
            }
        }
        RateMapImage {
            image,
            max_rate: top / span,
            mean_active_rate: mean / span,
            active_pixels: active.len() as u64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_only_the_interval_and_polarity() {
        let mut b = EventBuffer::new();
        for t in 0..10 {
            b.push(t * 100, 1, 1, 1);
            b.push(t * 100, 0, 0, 0);
        }
        let mut map = EventRateMap::new(Geometry::new(2, 2));
        map.add(&b, 0, 500, PolaritySelection::Positive);
        assert_eq!(map.count(1, 1), 5);
        assert_eq!(map.count(0, 0), 0);
        let img = map.render(Some(500));
        assert_eq!(img.active_pixels, 1);
        assert!((img.max_rate - 10_000.0).abs() < 1e-6);
    }
}
