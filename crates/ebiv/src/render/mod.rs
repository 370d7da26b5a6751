//! Figures: the images a user looks at first.

mod animation;
mod arrow;
mod axes;
mod colormap;
mod draw;
mod event_image;
pub mod font;
mod frame_image;
mod histogram;
mod palette;
mod rate_map;
mod vector_map;

pub use animation::{series_animation, write_gif};
pub use colormap::{inferno, time_code};
pub use event_image::{time_coded_image, TimeCodedImage};
pub use frame_image::frame_image;
pub use histogram::{
    histogram, peak_locking_index, valid_components, velocity_histograms, Histogram, HistogramStyle,
};
pub use rate_map::{EventRateMap, RateMapImage};
pub use vector_map::{vector_map, VectorMapStyle};

use crate::error::{Error, Result};
use std::path::Path;

/// Enlarge an image by an integer factor with nearest-neighbour sampling, so pixels stay
/// visible as pixels.
pub fn upscale(img: &image::RgbImage, factor: u32) -> image::RgbImage {
    if factor <= 1 {
        return img.clone();
    }
    image::imageops::resize(
        img,
        img.width() * factor,
        img.height() * factor,
        image::imageops::FilterType::Nearest,
    )
}

/// Save a PNG through a temporary file, so a failed write leaves no partial image.
pub fn save_png(img: &image::RgbImage, path: &Path) -> Result<()> {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let temp = path.with_file_name(name);
    img.save_with_format(&temp, image::ImageFormat::Png)
        .map_err(|e| Error::Write {
            what: path.display().to_string(),
            message: e.to_string(),
        })?;
    std::fs::rename(&temp, path).map_err(|e| Error::io(path, e))
}
