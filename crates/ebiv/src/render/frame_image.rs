//! A grey-value frame (camera image or frame rebuilt from events) as a figure background.

use crate::frame::Frame;
use image::RgbImage;

/// `frame` as a grey RGB image, stretched so that the 99.5th percentile of its positive
/// pixels is white (a few hot pixels do not darken the rest); black stays black.
pub fn frame_image(frame: &Frame) -> RgbImage {
    let mut values: Vec<f32> = frame.data.iter().copied().filter(|v| *v > 0.0).collect();
    let top = if values.is_empty() {
        1.0
    } else {
        let k = ((values.len() as f64 * 0.995) as usize).min(values.len() - 1);
        *values.select_nth_unstable_by(k, f32::total_cmp).1
    };
    let scale = if top > 0.0 { 255.0 / top } else { 1.0 };
    RgbImage::from_fn(frame.width, frame.height, |x, y| {
        let g = (frame.get(x, y) * scale).clamp(0.0, 255.0) as u8;
        image::Rgb([g, g, g])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bright_outliers_saturate_and_the_rest_is_stretched() {
        let mut f = Frame::from_fn(100, 100, |x, _| if x < 50 { 0.0 } else { 50.0 });
        f.data[9999] = 1e6;
        f.data[9998] = 25.0;
        let img = frame_image(&f);
        assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(img.get_pixel(75, 5).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(98, 99).0, [127, 127, 127]);
        assert_eq!(img.get_pixel(99, 99).0, [255, 255, 255]);
    }
}
