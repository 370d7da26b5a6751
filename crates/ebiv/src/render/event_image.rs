//! Time-coded event images (Willert & Klinner 2022, Fig. 4): every event of an interval
//! drawn at its pixel, coloured by its time relative to a reference time `t0`.

use super::colormap::time_code;
use crate::event::{EventBuffer, Geometry, PolaritySelection};

/// A time-coded event image and how many events went into it.
pub struct TimeCodedImage {
    /// The image, one pixel per sensor pixel, black where no event occurred.
    pub image: image::RgbImage,
    /// Events drawn.
    pub events: u64,
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
}
