//! Figures: the images a user looks at first.

mod animation;
mod arrow;
mod assessment;
mod axes;
mod colormap;
mod draw;
mod event_image;
mod field_maps;
pub mod font;
mod frame_image;
mod histogram;
mod histogram2d;
mod line_plot;
mod palette;
pub mod plot;
mod rate_map;
mod scalar_map;
pub mod tracks;
mod vector_map;

pub use animation::{series_animation, write_gif};
pub use assessment::{
    coverage_figure, differences_figure, error_bins_figure, error_map_figure, fractional_figure,
    scatter_figure, write_agreement_report, write_assessment_report,
};
pub use axes::{ColourBar, ImageFigureStyle, MAX_PIXEL_SCALE};
pub use colormap::{blue_red, inferno, time_code};
pub use event_image::{event_figure, time_code_bar, time_coded_image, TimeCodedImage};
pub use field_maps::{field_map, series_range, FieldMapStyle, MapQuantity};
pub use frame_image::frame_image;
pub use histogram::{
    histogram, peak_locking_index, peak_locking_noise, valid_components, velocity_histograms,
    Histogram, HistogramStyle,
};
pub use histogram2d::{histogram2d_figure, Histogram2d};
pub use line_plot::{line_plot, LinePlot, Series, SeriesStyle, XAxis, SERIES_COLOURS};
pub use rate_map::{EventRateMap, RateMapImage};
pub use scalar_map::{grid_geometry, scalar_map, scalar_range, ScalarMapStyle};
pub use tracks::{track_histograms, track_map, TrackMapStyle};
pub use vector_map::{auto_stride, vector_map, VectorMapStyle, MAX_ARROWS_ACROSS, MIN_ARROW_GAP};

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

/// File extensions (lower case) of the formats figures can be written in.
pub const FIGURE_EXTENSIONS: &[&str] = &["png", "jpg", "jpeg", "tif", "tiff", "bmp"];

/// JPEG quality of figures: high, so thin lines and small text keep sharp edges.
const JPEG_QUALITY: u8 = 92;

/// The image format named by the extension of `path` (case-insensitive), one of
/// [`FIGURE_EXTENSIONS`]; an error naming `parameter` and the supported extensions otherwise,
/// so a figure is never written in a format its name does not say.
pub fn figure_format(path: &Path, parameter: &str) -> Result<image::ImageFormat> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "png" => Ok(image::ImageFormat::Png),
        "jpg" | "jpeg" => Ok(image::ImageFormat::Jpeg),
        "tif" | "tiff" => Ok(image::ImageFormat::Tiff),
        "bmp" => Ok(image::ImageFormat::Bmp),
        _ => Err(Error::parameter(
            parameter,
            format!(
                "{}: unsupported figure format; use .{}",
                path.display(),
                FIGURE_EXTENSIONS.join(", .")
            ),
        )),
    }
}

/// Save a figure in the format its extension names (see [`figure_format`]; JPEG at high
/// quality), through a temporary file, so a failed write leaves no partial image.
pub fn save_figure(img: &image::RgbImage, path: &Path) -> Result<()> {
    let format = figure_format(path, "output")?;
    write_through_temporary(path, |file| match format {
        image::ImageFormat::Jpeg => img.write_with_encoder(
            image::codecs::jpeg::JpegEncoder::new_with_quality(file, JPEG_QUALITY),
        ),
        other => img.write_to(file, other),
    })
}

/// Save a PNG through a temporary file, so a failed write leaves no partial image.
pub fn save_png(img: &image::RgbImage, path: &Path) -> Result<()> {
    write_through_temporary(path, |file| img.write_to(file, image::ImageFormat::Png))
}

/// Run `write` on a buffered temporary file next to `path`, then rename it to `path`; the
/// temporary file is removed when writing fails.
fn write_through_temporary(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> image::ImageResult<()>,
) -> Result<()> {
    use std::io::Write;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let temp = path.with_file_name(name);
    let file = std::fs::File::create(&temp).map_err(|e| Error::io(path, e))?;
    let mut out = std::io::BufWriter::new(file);
    let result = write(&mut out)
        .map_err(|e| Error::Write {
            what: path.display().to_string(),
            message: e.to_string(),
        })
        .and_then(|()| out.flush().map_err(|e| Error::io(path, e)));
    drop(out);
    if let Err(e) = result {
        let _ = std::fs::remove_file(&temp);
        return Err(e);
    }
    std::fs::rename(&temp, path).map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_are_written_in_the_format_their_extension_names() {
        let dir = tempfile::tempdir().unwrap();
        let img =
            image::RgbImage::from_fn(40, 30, |x, y| [(x * 6) as u8, (y * 8) as u8, 90].into());
        for (name, magic) in [
            ("a.png", &b"\x89PNG"[..]),
            ("a.JPG", &[0xFF, 0xD8, 0xFF][..]),
            ("a.jpeg", &[0xFF, 0xD8, 0xFF][..]),
            ("a.tif", &b"II*\0"[..]),
            ("a.bmp", &b"BM"[..]),
        ] {
            let path = dir.path().join(name);
            save_figure(&img, &path).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            assert!(bytes.starts_with(magic), "{name}: {:02x?}", &bytes[..4]);
            let back = image::open(&path).unwrap().to_rgb8();
            assert_eq!(back.dimensions(), (40, 30), "{name}");
        }
        for name in ["a.gif", "a", "a.png.txt"] {
            let err = save_figure(&img, &dir.path().join(name)).unwrap_err();
            let text = err.to_string();
            assert!(text.contains("output") && text.contains(".jpg"), "{text}");
            assert!(!dir.path().join(name).exists());
        }
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            5,
            "no partial files"
        );
    }
}
