//! Animated GIFs of a field series: every time step drawn as a vector map with one colour
//! range and one arrow scale, so frames compare, then encoded with a fixed palette.

use super::palette::{cell, median_cut};
use super::vector_map::{
    arrow_stride, auto_range, auto_scale, magnitudes, vector_map, VectorMapStyle,
};
use crate::error::{Error, Result};
use crate::event::Geometry;
use crate::field::FieldSeries;
use image::RgbImage;
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;

/// Write `frames` as an endlessly looping GIF, `delay_ms` per frame (GIF counts in 10 ms;
/// browsers slow delays under 20 ms down, so shorter ones are raised to 20 ms). All frames
/// share one 256-colour palette made by median cut, so figures with few colours stay exact.
/// The file is written under a temporary name and renamed.
/// All frames must have the same size, at most 65535 px on a side.
pub fn write_gif(frames: &[RgbImage], delay_ms: u16, path: &Path) -> Result<()> {
    let first = frames
        .first()
        .ok_or_else(|| Error::parameter("frames", "no frames to write"))?;
    let (w, h) = first.dimensions();
    if let Some(i) = frames.iter().position(|f| f.dimensions() != (w, h)) {
        return Err(Error::parameter(
            "frames",
            format!(
                "frame {i} is {:?}, the first {w}×{h}",
                frames[i].dimensions()
            ),
        ));
    }
    let (Ok(gw), Ok(gh)) = (u16::try_from(w), u16::try_from(h)) else {
        return Err(Error::parameter(
            "frames",
            format!("{w}×{h} exceeds the GIF limit of 65535 px"),
        ));
    };
    if w == 0 || h == 0 {
        return Err(Error::parameter("frames", "frames are empty"));
    }
    let (palette, lut) = median_cut(frames);
    let indexed: Vec<Vec<u8>> = frames
        .par_iter()
        .map(|f| f.pixels().map(|p| lut[cell(p.0)]).collect())
        .collect();
    let mut flat: Vec<u8> = palette.iter().flatten().copied().collect();
    flat.resize(3 * 256, 0);
    let delay = delay_ms.div_ceil(10).max(2);

    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let temp = path.with_file_name(name);
    let file = std::fs::File::create(&temp).map_err(|e| Error::io(path, e))?;
    let gif_error = |e: gif::EncodingError| match e {
        gif::EncodingError::Io(e) => Error::io(path, e),
        other => Error::Write {
            what: path.display().to_string(),
            message: other.to_string(),
        },
    };
    let result = (|| {
        let mut enc =
            gif::Encoder::new(std::io::BufWriter::new(file), gw, gh, &flat).map_err(gif_error)?;
        enc.set_repeat(gif::Repeat::Infinite).map_err(gif_error)?;
        for pixels in &indexed {
            let frame = gif::Frame {
                width: gw,
                height: gh,
                delay,
                buffer: std::borrow::Cow::Borrowed(pixels),
                ..gif::Frame::default()
            };
            enc.write_frame(&frame).map_err(gif_error)?;
        }
        let mut out = enc.into_inner().map_err(|e| Error::io(path, e))?;
        out.flush().map_err(|e| Error::io(path, e))
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&temp);
        return Err(e);
    }
    std::fs::rename(&temp, path).map_err(|e| Error::io(path, e))
}

/// Draw every time step of `series` as a vector map (see [`vector_map`]) with one magnitude
/// range and one arrow scale for all frames (from the whole series unless `style` fixes
/// them) and the title "t = … ms" (after `style.title`, if any). Frames are drawn in
/// parallel; feed them to [`write_gif`].
pub fn series_animation(
    series: &FieldSeries,
    geometry: Geometry,
    style: &VectorMapStyle,
) -> Vec<RgbImage> {
    let mags = magnitudes(&series.u, &series.v, &series.status);
    let mut common = style.clone();
    if common.magnitude_range.is_none() {
        common.magnitude_range = Some(auto_range(&mags));
    }
    if common.scale.is_none() {
        let stride = arrow_stride(&series.x, &series.y, geometry, style);
        common.scale = Some(auto_scale(&mags, &series.x, &series.y, geometry) * stride as f64);
    }
    (0..series.t_us.len())
        .into_par_iter()
        .map(|t| {
            let mut s = common.clone();
            let time = format!("t = {:.3} ms", series.t_us[t] as f64 / 1000.0);
            s.title = Some(match &style.title {
                Some(title) => format!("{title}, {time}"),
                None => time,
            });
            vector_map(&series.field(t), geometry, None, &s)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gif_round_trips_frame_count_and_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.gif");
        let frames: Vec<RgbImage> = (0..3)
            .map(|i| {
                RgbImage::from_fn(40, 30, |x, y| {
                    [(x * 6) as u8, (y * 8) as u8, i * 100].into()
                })
            })
            .collect();
        write_gif(&frames, 100, &path).unwrap();
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(std::fs::File::open(&path).unwrap()).unwrap();
        assert_eq!((dec.width(), dec.height()), (40, 30));
        let mut n = 0;
        while let Some(f) = dec.read_next_frame().unwrap() {
            assert_eq!((f.width, f.height, f.delay), (40, 30, 10));
            n += 1;
        }
        assert_eq!(n, 3);
        assert!(!dir.path().join("a.gif.partial").exists());
        assert!(write_gif(&[], 100, &path).is_err());
        let odd = [frames[0].clone(), RgbImage::new(3, 3)];
        assert!(write_gif(&odd, 100, &path).is_err());
    }

    /// The sample animation: a Lamb–Oseen vortex whose strength swells and fades over 8
    /// frames. Checks that every frame is a full vector map of one size with a colour bar,
    /// that the frames share one arrow scale (the strong frames draw more arrow than the weak
    /// ones) and that the titles give the time; writes the GIF and one frame to
    /// `$EBIV_RENDER_SAMPLES` when set, for looking at.
    #[test]
    fn sample_animation() {
        use crate::render::axes::probe::{colour_bar_column, ink_in, plot_frame};
        use crate::render::inferno;
        let base = super::super::vector_map::tests::lamb_oseen(320.0, 240.0, 16.0, 1.5, 40.0);
        let mut series = FieldSeries::on_grid(base.x.clone(), base.y.clone());
        let strength: Vec<f32> = (0..8).map(|t| 0.5 + 0.5 * (t as f32 * 0.8).cos()).collect();
        for (t, a) in strength.iter().enumerate() {
            let mut f = base.clone();
            f.u.iter_mut().for_each(|u| *u *= a);
            f.v.iter_mut().for_each(|v| *v *= a);
            series.push(t as i64 * 2500, &f).unwrap();
        }
        let frames = series_animation(&series, Geometry::new(320, 240), &Default::default());
        assert_eq!(frames.len(), 8);
        let size = frames[0].dimensions();
        assert!(size.0 > 960 && size.1 > 720, "{size:?}");
        // Light grey to white pixels inside the plot frame: the arrows' bodies.
        let arrow_pixels = |img: &RgbImage| {
            let (l, t, r, b) = plot_frame(img);
            image::imageops::crop_imm(img, l + 1, t + 1, r - l - 1, b - t - 1)
                .to_image()
                .pixels()
                .filter(|p| p.0.iter().all(|&c| c >= 140) && p.0[0].abs_diff(p.0[2]) <= 10)
                .count()
        };
        for (t, frame) in frames.iter().enumerate() {
            assert_eq!(frame.dimensions(), size, "frame {t}");
            assert!(colour_bar_column(frame, inferno(1.0), inferno(0.0)).is_some());
        }
        let (strong, weak) = (arrow_pixels(&frames[0]), arrow_pixels(&frames[4]));
        assert!(
            strength[4] < 0.01 && strong > 5 * weak,
            "{strong} vs {weak}"
        );
        // The titles differ ("t = 0.000 ms", "t = 2.500 ms").
        let title = |img: &RgbImage| -> Vec<u8> {
            image::imageops::crop_imm(img, 0, 0, size.0, 40)
                .to_image()
                .into_raw()
        };
        assert_ne!(title(&frames[0]), title(&frames[1]));
        assert!(ink_in(&frames[1], 0, 0, size.0, 40) > 100);
        if let Some(dir) = std::env::var_os("EBIV_RENDER_SAMPLES") {
            let dir = std::path::PathBuf::from(dir);
            write_gif(&frames, 250, &dir.join("vortex.gif")).unwrap();
            crate::render::save_png(&frames[3], &dir.join("vortex_frame3.png")).unwrap();
        }
    }
}
