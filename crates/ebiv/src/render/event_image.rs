//! Time-coded event images (Willert & Klinner 2022, Fig. 4): every event of an interval
//! drawn at its pixel, coloured by its time relative to a reference time `t0`.

use super::axes::{ColourBar, ImageFigure, ImageFigureStyle};
use super::colormap::time_code;
use crate::error::Result;
use crate::event::{EventBuffer, Geometry, PolaritySelection};
use crate::units::format_us;

/// A time-coded event image, how many events went into it and the interval it shows.
pub struct TimeCodedImage {
    /// The image, one pixel per sensor pixel, black where no event occurred.
    pub image: image::RgbImage,
    /// Events drawn.
    pub events: u64,
    /// Reference time, µs: events at `t0` are white.
    pub t0_us: i64,
    /// Half the length of the interval drawn, µs: events `half_width_us` before `t0` are
    /// fully blue, as long after it fully red.
    pub half_width_us: i64,
}

/// The colour bar of a time-coded image: time from t0 in ms, from `−half_width_us` (blue)
/// through 0 (white) to `+half_width_us` (red).
pub fn time_code_bar(half_width_us: i64) -> ColourBar {
    let half_ms = half_width_us.max(1) as f64 / 1000.0;
    ColourBar::linear((-half_ms, half_ms), "t - t0 [ms]", |s| {
        time_code(2.0 * s - 1.0)
    })
}

/// `image` drawn as a figure: enlarged (nearest neighbour), with axes in sensor pixels, the
/// colour bar of [`time_code_bar`], the title of `style`, and a caption giving t0, the
/// interval and the number of events (times from `style.time_origin_us`). An error for an
/// enlargement out of range (see [`ImageFigureStyle::scale_for`]).
pub fn event_figure(image: &TimeCodedImage, style: &ImageFigureStyle) -> Result<image::RgbImage> {
    let (w, h) = image.image.dimensions();
    let k = style.scale_for(w, h)?;
    Ok(ImageFigure::of_image(
        &image.image,
        k,
        style.title.clone(),
        Some(time_code_bar(image.half_width_us)),
        event_caption(image, style),
    ))
}

/// The caption lines of [`event_figure`].
fn event_caption(image: &TimeCodedImage, style: &ImageFigureStyle) -> Vec<String> {
    let (t0, half) = (image.t0_us, image.half_width_us.max(1));
    vec![
        format!(
            "t0 = {}, window {} to {} ({}), {} events",
            style.time(t0),
            style.time(t0 - half),
            style.time(t0 + half),
            format_us(2 * half),
            image.events
        ),
        "colour: time of the event nearest t0 at each pixel".into(),
    ]
}

/// Draw the events with `t0 − half_width_us ≤ t ≤ t0 + half_width_us` and selected polarity.
/// Where several events hit one pixel, the one closest in time to `t0` is shown, so particles
/// appear white at their position at `t0`, with blue trails behind and red ones ahead.
pub fn time_coded_image(
    events: &EventBuffer,
    geometry: Geometry,
    t0: i64,
    half_width_us: i64,
    polarity: PolaritySelection,
) -> TimeCodedImage {
    let half = half_width_us.max(1);
    let mut closest: Vec<i64> = vec![i64::MAX; geometry.pixels()];
    let mut image = image::RgbImage::new(geometry.width, geometry.height);
    let mut drawn = 0;
    for e in events.iter() {
        let dt = e.t - t0;
        if dt.abs() > half || !polarity.accepts(e.p) || !geometry.contains(e.x as u32, e.y as u32) {
            continue;
        }
        drawn += 1;
        let idx = e.y as usize * geometry.width as usize + e.x as usize;
        if dt.abs() < closest[idx] {
            closest[idx] = dt.abs();
            let colour = time_code(dt as f32 / half as f32);
            image.put_pixel(e.x as u32, e.y as u32, image::Rgb(colour));
        }
    }
    TimeCodedImage {
        image,
        events: drawn,
        t0_us: t0,
        half_width_us: half,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn present_is_white_past_blue_future_red() {
        let mut b = EventBuffer::new();
        b.push(100, 1, 0, 1); // present
        b.push(0, 0, 0, 1); // past
        b.push(200, 2, 0, 1); // future
        b.push(500, 3, 0, 1); // outside
        let img = time_coded_image(&b, Geometry::new(4, 1), 100, 100, PolaritySelection::Both);
        assert_eq!(img.events, 3);
        assert_eq!(img.image.get_pixel(1, 0).0, [255, 255, 255]);
        assert_eq!(img.image.get_pixel(0, 0).0[2], 255);
        assert_eq!(img.image.get_pixel(2, 0).0[0], 255);
        assert_eq!(img.image.get_pixel(3, 0).0, [0, 0, 0]);
    }

    #[test]
    fn event_figure_shows_pixels_axes_time_bar_and_caption() {
        use crate::render::axes::probe::{colour_bar_column, plot_frame};
        let mut b = EventBuffer::new();
        b.push(25_000, 10, 5, 1); // at t0: white
        b.push(23_000, 40, 30, 1); // 2 ms before: blue
        let image = time_coded_image(
            &b,
            Geometry::new(64, 48),
            25_000,
            2_000,
            PolaritySelection::Both,
        );
        let style = ImageFigureStyle {
            pixel_scale: Some(4),
            time_origin_us: 1_000,
            ..Default::default()
        };
        let img = event_figure(&image, &style).unwrap();
        let (l, t, r, bottom) = plot_frame(&img);
        assert_eq!((r - l - 1, bottom - t - 1), (256, 192));
        let at = |x: u32, y: u32| img.get_pixel(l + 1 + 4 * x + 2, t + 1 + 4 * y + 2).0;
        assert_eq!(at(10, 5), [255, 255, 255]);
        assert_eq!(at(40, 30), time_code(-1.0));
        assert_eq!(at(0, 0), [0, 0, 0]);
        // The bar runs from blue (t0 − 2 ms) at the bottom to red (t0 + 2 ms) at the top.
        assert!(colour_bar_column(&img, time_code(1.0), time_code(-1.0)).is_some());
        let bar = time_code_bar(image.half_width_us);
        let labels: Vec<&str> = bar.ticks.iter().map(|t| t.1.as_str()).collect();
        assert_eq!(labels, ["-2", "0", "2"]);
        assert_eq!(
            event_caption(&image, &style)[0],
            "t0 = 24.000 ms, window 22.000 ms to 26.000 ms (4.000 ms), 2 events"
        );
        for k in [0, 17] {
            let bad = ImageFigureStyle {
                pixel_scale: Some(k),
                ..Default::default()
            };
            let e = event_figure(&image, &bad)
                .expect_err("scale out of range")
                .to_string();
            assert!(e.contains("`scale`"), "{e}");
        }
        let huge = time_coded_image(&b, Geometry::new(4000, 10), 0, 1, PolaritySelection::Both);
        let big = ImageFigureStyle {
            pixel_scale: Some(8),
            ..Default::default()
        };
        assert!(event_figure(&huge, &big).is_err(), "32000 px wide");
    }
}
