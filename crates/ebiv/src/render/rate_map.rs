//! Event-rate maps: events per pixel per second, accumulated batch by batch.

use super::axes::{format_value, nice_ticks, ColourBar, ImageFigure, ImageFigureStyle};
use super::colormap::inferno;
use crate::error::Result;
use crate::event::{EventBuffer, Geometry, PolaritySelection};
use crate::units::format_us;

/// Per-pixel event counts over a time interval.
pub struct EventRateMap {
    geometry: Geometry,
    counts: Vec<u32>,
    t_range: Option<(i64, i64)>,
}

/// A rendered rate map with its colour scale.
pub struct RateMapImage {
    /// The figure: the map with axes in sensor pixels, a colour bar in events/s per pixel
    /// (bottom = 0, top = `max_rate`) and a caption with the interval.
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

    /// Draw the map as a figure (see [`ImageFigureStyle`]) with the inferno map on a
    /// square-root scale (so sparse pixels stay visible), saturating at the 99.9th
    /// percentile of active pixels. Counts become rates over `interval` = `[start, end)` µs;
    /// when `None`, over the span of the counted events. An error for an enlargement out of
    /// range (see [`ImageFigureStyle::scale_for`]).
    pub fn render(
        &self,
        interval: Option<(i64, i64)>,
        style: &ImageFigureStyle,
    ) -> Result<RateMapImage> {
        let (w, h) = (self.geometry.width, self.geometry.height);
        let k = style.scale_for(w, h)?;
        let (start, end) = interval
            .or(self.t_range.map(|(a, b)| (a, b + 1)))
            .unwrap_or((0, 1));
        let span = (end.saturating_sub(start)).max(1) as f64 * 1e-6;
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
        let map = image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb(inferno((self.count(x, y) as f64 / top).sqrt() as f32))
        });
        let max_rate = top / span;
        let caption = vec![
            format!(
                "events from {} to {} ({})",
                style.time(start),
                style.time(end),
                format_us(end.saturating_sub(start))
            ),
            format!(
                "{} active pixels, mean {} events/s per active pixel",
                active.len(),
                format_value(mean / span, mean / span / 100.0)
            ),
            "colour: events/s per pixel, square-root scale".into(),
        ];
        let image = ImageFigure::of_image(
            &map,
            k,
            style.title.clone(),
            Some(rate_bar(max_rate)),
            caption,
        );
        Ok(RateMapImage {
            image,
            max_rate,
            mean_active_rate: mean / span,
            active_pixels: active.len() as u64,
        })
    }
}

/// The colour bar of a rate map saturating at `max_rate`: inferno on a square-root scale,
/// ticks at squares of round numbers (evenly spaced on that scale) and at the maximum.
fn rate_bar(max_rate: f64) -> ColourBar {
    let root = max_rate.max(0.0).sqrt();
    let (roots, step) = nice_ticks(0.0, root, 5);
    let mut ticks: Vec<(f64, String)> = roots
        .iter()
        .map(|&r| (r / root, format_value(r * r, step * step)))
        .collect();
    if roots.last().is_none_or(|&r| r / root < 0.85) {
        ticks.push((1.0, format_value(max_rate, max_rate / 100.0)));
    }
    ColourBar {
        colours: inferno,
        ticks,
        title: "rate [events/s per px]".into(),
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
        let img = map
            .render(Some((0, 500)), &ImageFigureStyle::default())
            .unwrap();
        assert_eq!(img.active_pixels, 1);
        assert!((img.max_rate - 10_000.0).abs() < 1e-6);
    }

    #[test]
    fn rate_figure_has_a_square_root_bar_in_events_per_second() {
        use crate::render::axes::probe::{colour_bar_column, ink_in, plot_frame};
        let bar = rate_bar(10_000.0);
        let ticks: Vec<(f64, &str)> = bar.ticks.iter().map(|(s, l)| (*s, l.as_str())).collect();
        // Squares of 0, 20, … 100 at even steps of the square-root scale.
        assert_eq!(ticks.len(), 6);
        assert_eq!(ticks[2], (0.4, "1600"));
        assert_eq!(ticks[5], (1.0, "10000"));
        // Uneven maximum: its value is labelled at the top.
        let bar = rate_bar(1340.0);
        assert_eq!(bar.ticks.last().unwrap(), &(1.0, "1340".to_string()));

        let mut b = EventBuffer::new();
        for t in 0..100 {
            b.push(t * 10, 3, 2, 1);
        }
        b.push(5, 0, 0, 1);
        let mut map = EventRateMap::new(Geometry::new(32, 24));
        map.add(&b, 0, 1000, PolaritySelection::Both);
        let style = ImageFigureStyle {
            pixel_scale: Some(8),
            ..Default::default()
        };
        let fig = map.render(Some((0, 1000)), &style).unwrap();
        assert_eq!(fig.max_rate, 100_000.0);
        let img = &fig.image;
        let (l, t, r, bottom) = plot_frame(img);
        assert_eq!((r - l - 1, bottom - t - 1), (256, 192));
        let at = |x: u32, y: u32| img.get_pixel(l + 1 + 8 * x + 4, t + 1 + 8 * y + 4).0;
        assert_eq!(at(3, 2), inferno(1.0));
        assert_eq!(at(0, 0), inferno(0.1), "1 of 100 events: sqrt(0.01)");
        assert_eq!(at(5, 5), inferno(0.0));
        let x = colour_bar_column(img, inferno(1.0), inferno(0.0)).expect("colour bar");
        assert!(
            ink_in(img, x + 22, t, img.width(), bottom) > 200,
            "bar labels and title"
        );
        assert!(
            ink_in(img, l, bottom + 40, r, img.height()) > 200,
            "caption"
        );
        assert!(map
            .render(
                None,
                &ImageFigureStyle {
                    pixel_scale: Some(0),
                    ..style
                }
            )
            .is_err());
    }
}
