//! Image files in and out: camera frames for PIV (PNG, TIFF, BMP, JPEG) and frames rebuilt
//! from events written as 16-bit grey images.
//!
//! Decoding goes through the `image` crate, which detects the format from the file's content
//! (its magic bytes), not its name. Colour images are reduced to luma with the ITU-R BT.601
//! weights (Y = 0.299 R + 0.587 G + 0.114 B), the conversion of MATLAB's `rgb2gray`, OpenCV
//! and PIVlab, so that grey values match what PIV users get from their usual tools.

use crate::error::{Error, Result};
use crate::frame::Frame;
use image::{DynamicImage, ImageBuffer, ImageError, ImageFormat, Luma};
use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// The image formats [`load`] decodes, for messages.
const READABLE: &str = "PNG, TIFF, BMP or JPEG";

/// A [`crate::grid::Mask`] from an image file of the sensor's size: its non-zero pixels are
/// masked. The error names the file when its size is not `geometry`'s.
pub fn load_mask(path: &Path, geometry: crate::event::Geometry) -> Result<crate::grid::Mask> {
    let image = load(path)?;
    if image.width != geometry.width || image.height != geometry.height {
        return Err(Error::parameter(
            "mask",
            format!(
                "{} is {}×{} px but the sensor is {geometry}",
                path.display(),
                image.width,
                image.height
            ),
        ));
    }
    Ok(crate::grid::Mask {
        width: image.width,
        height: image.height,
        masked: image.data.iter().map(|&v| v != 0.0).collect(),
    })
}

/// Read the image file at `path` as a grey [`Frame`], in the file's own scale: 0..255 for
/// 8-bit images, 0..65535 for 16-bit ones, 0..1 for floating-point TIFF. Colour is reduced
/// to ITU-R BT.601 luma, alpha is ignored. The format is recognised by content.
pub fn load(path: &Path) -> Result<Frame> {
    // No path given to the reader: the format comes from the content alone, never from a
    // misleading extension.
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let reader = image::ImageReader::new(std::io::BufReader::new(file))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let Some(format) = reader.format() else {
        return Err(Error::UnknownFormat {
            path: path.to_path_buf(),
            hint: format!("not an image file ebiv reads ({READABLE})"),
        });
    };
    let image = reader.decode().map_err(|e| decode_error(path, format, e))?;
    frame_of(image).map_err(|message| Error::unsupported(path.display().to_string(), message))
}

/// Turn an `image` decoding error into one that names the file and says what to do.
fn decode_error(path: &Path, format: ImageFormat, e: ImageError) -> Error {
    let name = format!("{format:?}").to_ascii_uppercase();
    match e {
        ImageError::IoError(source) => Error::io(path, source),
        ImageError::Unsupported(u) => Error::unsupported(
            path.display().to_string(),
            format!("{name} image not supported: {u} (ebiv reads {READABLE}, 8 or 16 bit)"),
        ),
        ImageError::Limits(l) => Error::unsupported(
            path.display().to_string(),
            format!("{name} image too large to decode: {l}"),
        ),
        other => Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("damaged or truncated {name} image: {other}"),
            ),
        ),
    }
}

/// The grey values of a decoded image, in its native scale.
fn frame_of(image: DynamicImage) -> std::result::Result<Frame, String> {
    let (width, height) = (image.width(), image.height());
    let data = match &image {
        DynamicImage::ImageLuma8(b) => grey(b.as_raw(), 1),
        DynamicImage::ImageLumaA8(b) => grey(b.as_raw(), 2),
        DynamicImage::ImageRgb8(b) => luma(b.as_raw(), 3),
        DynamicImage::ImageRgba8(b) => luma(b.as_raw(), 4),
        DynamicImage::ImageLuma16(b) => grey(b.as_raw(), 1),
        DynamicImage::ImageLumaA16(b) => grey(b.as_raw(), 2),
        DynamicImage::ImageRgb16(b) => luma(b.as_raw(), 3),
        DynamicImage::ImageRgba16(b) => luma(b.as_raw(), 4),
        DynamicImage::ImageRgb32F(b) => luma(b.as_raw(), 3),
        DynamicImage::ImageRgba32F(b) => luma(b.as_raw(), 4),
        other => return Err(format!("pixel type {:?} is not supported", other.color())),
    };
    Ok(Frame {
        width,
        height,
        data,
    })
}

/// The first channel of interleaved samples with `channels` channels.
fn grey<T: Copy + Into<f32>>(samples: &[T], channels: usize) -> Vec<f32> {
    samples
        .chunks_exact(channels)
        .map(|p| p[0].into())
        .collect()
}

/// BT.601 luma of interleaved RGB(A) samples; grey pixels (R = G = B, as in grey images
/// stored as colour) keep their value exactly.
fn luma<T: Copy + Into<f32>>(samples: &[T], channels: usize) -> Vec<f32> {
    samples
        .chunks_exact(channels)
        .map(|p| {
            let (r, g, b) = (p[0].into(), p[1].into(), p[2].into());
            if r == g && g == b {
                r
            } else {
                0.299 * r + 0.587 * g + 0.114 * b
            }
        })
        .collect()
}

/// How grey values are mapped to the 0..65535 range of a 16-bit image by [`save`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scale {
    /// Multiply by this factor, round, and clamp to 0..65535 (1 keeps counts as they are).
    Fixed(f32),
    /// Map 0 to 0 and the frame's largest value to 65535 (negative values become 0).
    Stretch,
}

/// Write `frame` as a 16-bit grey image, PNG or TIFF by the extension of `path` (`.png`,
/// `.tif`, `.tiff`), grey values mapped by `scale`. NaN becomes 0. The file is written
/// under a temporary name and renamed when complete.
pub fn save(frame: &Frame, path: &Path, scale: Scale) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let format = match ext.as_deref() {
        Some("png") => ImageFormat::Png,
        Some("tif" | "tiff") => ImageFormat::Tiff,
        _ => {
            return Err(Error::unsupported(
                path.display().to_string(),
                "cannot tell the image format from the extension; use .png, .tif or .tiff",
            ))
        }
    };
    let pixels = frame.width as usize * frame.height as usize;
    if pixels == 0 || frame.data.len() != pixels {
        return Err(Error::parameter(
            "frame",
            format!(
                "{}x{} frame with {} values cannot be written to {}",
                frame.width,
                frame.height,
                frame.data.len(),
                path.display()
            ),
        ));
    }
    let factor = match scale {
        Scale::Fixed(f) if f.is_finite() && f >= 0.0 => f,
        Scale::Fixed(f) => {
            return Err(Error::parameter(
                "scale",
                format!("{f} is not a usable grey-value factor (need a finite number ≥ 0)"),
            ))
        }
        Scale::Stretch => {
            let max = frame
                .data
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(0.0f32, f32::max);
            if max > 0.0 {
                65535.0 / max
            } else {
                0.0
            }
        }
    };
    let values: Vec<u16> = frame
        .data
        .iter()
        .map(|&v| {
            let s = v * factor;
            if s.is_nan() {
                0
            } else {
                s.round().clamp(0.0, 65535.0) as u16
            }
        })
        .collect();
    let image: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_raw(frame.width, frame.height, values).ok_or_else(|| {
            Error::parameter("frame", "pixel count does not match the frame size")
        })?;
    crate::export::write_atomic(path, |w| {
        image.write_to(w, format).map_err(|e| match e {
            ImageError::IoError(io) => io,
            other => std::io::Error::other(other),
        })
    })
}

/// The image files named by `args`: each argument is a file, or a pattern with `*` (any run
/// of characters) or `?` (one character) in its file-name part, e.g. `run1/img_*.tif`.
/// A pattern's matches are sorted naturally (`img_2` before `img_10`); arguments keep their
/// order. A pattern that matches nothing, or a file that does not exist, is an error.
pub fn expand_image_list(args: &[String]) -> Result<Vec<PathBuf>> {
    if args.is_empty() {
        return Err(Error::parameter("images", "no image files given"));
    }
    let mut out = Vec::new();
    for arg in args {
        let path = Path::new(arg);
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if !name.contains(['*', '?']) {
            if arg.contains(['*', '?']) {
                return Err(wildcard_in_directory(arg));
            }
            if !path.is_file() {
                let source = match std::fs::metadata(path) {
                    Err(e) => e,
                    Ok(_) => std::io::Error::other("not a regular file"),
                };
                return Err(Error::io(path, source));
            }
            out.push(path.to_path_buf());
            continue;
        }
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if dir.to_string_lossy().contains(['*', '?']) {
            return Err(wildcard_in_directory(arg));
        }
        let pattern: Vec<char> = name.chars().collect();
        let mut matches = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
            let entry = entry.map_err(|e| Error::io(dir, e))?;
            let file_name = entry.file_name();
            let Some(file_name) = file_name.to_str() else {
                continue;
            };
            let chars: Vec<char> = file_name.chars().collect();
            if glob_match(&pattern, &chars) && entry.path().is_file() {
                matches.push((file_name.to_string(), entry.path()));
            }
        }
        if matches.is_empty() {
            return Err(Error::parameter(
                "images",
                format!("no file matches `{arg}`"),
            ));
        }
        matches.sort_by(|a, b| natural_cmp(&a.0, &b.0));
        if path.parent().is_none_or(|d| d.as_os_str().is_empty()) {
            out.extend(matches.into_iter().map(|(n, _)| PathBuf::from(n)));
        } else {
            out.extend(matches.into_iter().map(|(_, p)| p));
        }
    }
    Ok(out)
}

fn wildcard_in_directory(arg: &str) -> Error {
    Error::parameter(
        "images",
        format!("`{arg}`: wildcards (* ?) are only allowed in the file name, not in folders"),
    )
}

/// Whether `name` matches the glob `pattern` (`*` any run, `?` one character), by the
/// classic backtracking on the last `*`.
fn glob_match(pattern: &[char], name: &[char]) -> bool {
    let (mut p, mut n) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while n < name.len() {
        if p < pattern.len() && (pattern[p] == '?' || pattern[p] == name[n]) {
            p += 1;
            n += 1;
        } else if p < pattern.len() && pattern[p] == '*' {
            star = Some((p, n));
            p += 1;
        } else if let Some((sp, sn)) = star {
            p = sp + 1;
            n = sn + 1;
            star = Some((sp, sn + 1));
        } else {
            return false;
        }
    }
    pattern[p..].iter().all(|&c| c == '*')
}

/// Natural order of file names: runs of digits compare by value, so `img_9` < `img_10`.
fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if a[i].is_ascii_digit() && b[j].is_ascii_digit() {
            let (si, sj) = (i, j);
            while i < a.len() && a[i].is_ascii_digit() {
                i += 1;
            }
            while j < b.len() && b[j].is_ascii_digit() {
                j += 1;
            }
            let (da, db) = (trim_zeros(&a[si..i]), trim_zeros(&b[sj..j]));
            let order = da.len().cmp(&db.len()).then_with(|| da.cmp(db));
            if order != Ordering::Equal {
                return order;
            }
        } else {
            if a[i] != b[j] {
                return a[i].cmp(&b[j]);
            }
            i += 1;
            j += 1;
        }
    }
    (a.len() - i).cmp(&(b.len() - j)).then_with(|| a.cmp(b))
}

fn trim_zeros(digits: &[u8]) -> &[u8] {
    let first = digits
        .iter()
        .position(|&d| d != b'0')
        .unwrap_or(digits.len());
    &digits[first..]
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{GrayImage, Rgb, RgbImage};

    fn ramp8(w: u32, h: u32) -> GrayImage {
        GrayImage::from_fn(w, h, |x, y| Luma([(x * 7 + y * 31) as u8]))
    }

    fn ramp16(w: u32, h: u32) -> ImageBuffer<Luma<u16>, Vec<u16>> {
        ImageBuffer::from_fn(w, h, |x, y| Luma([(x * 1000 + y * 7919) as u16]))
    }

    #[test]
    fn eight_bit_grey_round_trips_in_png_tiff_bmp() {
        let dir = tempfile::tempdir().unwrap();
        let img = ramp8(13, 7);
        for ext in ["png", "tif", "bmp"] {
            let path = dir.path().join(format!("g8.{ext}"));
            img.save(&path).unwrap();
            let f = load(&path).unwrap();
            assert_eq!((f.width, f.height), (13, 7), "{ext}");
            for (x, y, p) in img.enumerate_pixels() {
                assert_eq!(f.get(x, y), p.0[0] as f32, "{ext} at {x},{y}");
            }
        }
    }

    #[test]
    fn sixteen_bit_grey_keeps_its_scale_in_png_and_tiff() {
        let dir = tempfile::tempdir().unwrap();
        let img = ramp16(9, 8);
        for ext in ["png", "tiff"] {
            let path = dir.path().join(format!("g16.{ext}"));
            img.save(&path).unwrap();
            let f = load(&path).unwrap();
            assert_eq!((f.width, f.height), (9, 8));
            for (x, y, p) in img.enumerate_pixels() {
                assert_eq!(f.get(x, y), p.0[0] as f32, "{ext} at {x},{y}");
            }
            assert!(f.data.iter().any(|&v| v > 255.0));
        }
    }

    #[test]
    fn colour_becomes_bt601_luma() {
        let dir = tempfile::tempdir().unwrap();
        let img = RgbImage::from_fn(4, 2, |x, y| match (x, y) {
            (0, 0) => Rgb([255, 0, 0]),
            (1, 0) => Rgb([0, 255, 0]),
            (2, 0) => Rgb([0, 0, 255]),
            _ => Rgb([100, 100, 100]),
        });
        let path = dir.path().join("colour.png");
        img.save(&path).unwrap();
        let f = load(&path).unwrap();
        assert!((f.get(0, 0) - 0.299 * 255.0).abs() < 1e-3);
        assert!((f.get(1, 0) - 0.587 * 255.0).abs() < 1e-3);
        assert!((f.get(2, 0) - 0.114 * 255.0).abs() < 1e-3);
        assert!((f.get(3, 1) - 100.0).abs() < 1e-3);
        // 16-bit colour keeps the 16-bit scale.
        let img16: ImageBuffer<Rgb<u16>, Vec<u16>> =
            ImageBuffer::from_fn(2, 2, |_, _| Rgb([60000, 60000, 60000]));
        let path = dir.path().join("colour16.png");
        img16.save(&path).unwrap();
        assert!((load(&path).unwrap().get(1, 1) - 60000.0).abs() < 0.1);
    }

    #[test]
    fn jpeg_decodes_close_to_the_original() {
        let dir = tempfile::tempdir().unwrap();
        let img = GrayImage::from_fn(32, 16, |x, _| Luma([if x < 16 { 40 } else { 200 }]));
        let path = dir.path().join("img.jpg");
        img.save(&path).unwrap();
        let f = load(&path).unwrap();
        assert_eq!((f.width, f.height), (32, 16));
        assert!((f.get(4, 8) - 40.0).abs() < 6.0, "{}", f.get(4, 8));
        assert!((f.get(28, 8) - 200.0).abs() < 6.0, "{}", f.get(28, 8));
    }

    #[test]
    fn format_comes_from_content_not_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("really_a_png.tif");
        ramp8(5, 5)
            .save_with_format(&path, ImageFormat::Png)
            .unwrap();
        assert_eq!(load(&path).unwrap().get(2, 3), (2 * 7 + 3 * 31) as f32);
    }

    #[test]
    fn bad_files_give_errors_naming_them() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.png");
        let e = load(&missing).unwrap_err().to_string();
        assert!(e.contains("missing.png"), "{e}");

        let text = dir.path().join("notes.png");
        std::fs::write(&text, "hello, not an image").unwrap();
        let e = load(&text).unwrap_err().to_string();
        assert!(e.contains("notes.png") && e.contains("unrecognised"), "{e}");

        let png = dir.path().join("cut.png");
        ramp8(64, 64).save(&png).unwrap();
        let bytes = std::fs::read(&png).unwrap();
        std::fs::write(&png, &bytes[..bytes.len() / 2]).unwrap();
        let e = load(&png).unwrap_err().to_string();
        assert!(e.contains("cut.png"), "{e}");

        let gif = dir.path().join("anim.gif");
        std::fs::write(&gif, b"GIF89a\x01\x00\x01\x00\x00\x00\x00;").unwrap();
        let e = load(&gif).unwrap_err().to_string();
        assert!(e.contains("anim.gif"), "{e}");
    }

    #[test]
    fn save_writes_16_bit_png_and_tiff_with_scaling() {
        let dir = tempfile::tempdir().unwrap();
        let frame = Frame::from_fn(6, 4, |x, y| (x + 10 * y) as f32);
        for name in ["f.png", "f.tif", "f.TIFF"] {
            let path = dir.path().join(name);
            save(&frame, &path, Scale::Fixed(100.0)).unwrap();
            let back = image::open(&path).unwrap();
            assert!(matches!(back, DynamicImage::ImageLuma16(_)), "{name}");
            let f = load(&path).unwrap();
            assert_eq!(f.get(5, 3), 3500.0, "{name}");
            assert!(!dir.path().join(format!("{name}.partial")).exists());
        }
        let path = dir.path().join("s.png");
        save(&frame, &path, Scale::Stretch).unwrap();
        let f = load(&path).unwrap();
        assert_eq!(f.get(5, 3), 65535.0);
        assert_eq!(f.get(0, 0), 0.0);
        assert_eq!(f.get(1, 0), (65535.0f32 / 35.0).round());
        // Clamping, NaN and negative values.
        let odd = Frame {
            width: 3,
            height: 1,
            data: vec![f32::NAN, -4.0, 1e9],
        };
        save(&odd, &path, Scale::Fixed(1.0)).unwrap();
        assert_eq!(load(&path).unwrap().data, vec![0.0, 0.0, 65535.0]);
    }

    #[test]
    fn save_rejects_bad_requests() {
        let dir = tempfile::tempdir().unwrap();
        let frame = Frame::new(4, 4);
        let e = save(&frame, &dir.path().join("f.bmp"), Scale::Stretch)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("f.bmp") && e.contains(".png") && e.contains(".tif"),
            "{e}"
        );
        assert!(save(&frame, &dir.path().join("f"), Scale::Stretch).is_err());
        let e = save(&frame, &dir.path().join("f.png"), Scale::Fixed(f32::NAN)).unwrap_err();
        assert!(e.to_string().contains("scale"), "{e}");
        let e = save(&Frame::new(0, 3), &dir.path().join("e.png"), Scale::Stretch).unwrap_err();
        assert!(e.to_string().contains("0x3"), "{e}");
        let e = save(
            &frame,
            &dir.path().join("no/such/dir/f.png"),
            Scale::Stretch,
        )
        .unwrap_err();
        assert!(e.to_string().contains("f.png"), "{e}");
    }

    #[test]
    fn image_lists_expand_patterns_in_natural_order() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "img_10.tif",
            "img_2.tif",
            "img_1.tif",
            "img_1.txt",
            "other.tif",
        ] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        let d = dir.path().display();
        let list = expand_image_list(&[format!("{d}/img_*.tif")]).unwrap();
        let names: Vec<_> = list
            .iter()
            .map(|p| p.file_name().unwrap().to_str().unwrap())
            .collect();
        assert_eq!(names, ["img_1.tif", "img_2.tif", "img_10.tif"]);
        let list = expand_image_list(&[format!("{d}/img_?.t*"), format!("{d}/other.tif")]).unwrap();
        assert_eq!(list.len(), 4);
        assert!(list[3].ends_with("other.tif"));

        let e = expand_image_list(&[format!("{d}/nothing_*.png")]).unwrap_err();
        assert!(e.to_string().contains("nothing_*.png"), "{e}");
        let e = expand_image_list(&[format!("{d}/absent.png")]).unwrap_err();
        assert!(e.to_string().contains("absent.png"), "{e}");
        assert!(expand_image_list(&[format!("{d}/*/img_1.tif")]).is_err());
        assert!(expand_image_list(&[]).is_err());
    }

    #[test]
    fn glob_and_natural_order_helpers() {
        let m = |p: &str, n: &str| {
            glob_match(
                &p.chars().collect::<Vec<_>>(),
                &n.chars().collect::<Vec<_>>(),
            )
        };
        assert!(m("a*b", "ab") && m("a*b", "axxb") && m("*", "") && m("a?c", "abc"));
        assert!(!m("a*b", "abc") && !m("a?c", "ac") && !m("a", "ab"));
        assert!(m("*_*.png", "x_1.png") && m("**a", "a"));
        assert_eq!(natural_cmp("f2", "f10"), Ordering::Less);
        assert_eq!(natural_cmp("f010", "f9"), Ordering::Greater);
        assert_eq!(natural_cmp("a", "a1"), Ordering::Less);
        assert_ne!(natural_cmp("f01", "f1"), Ordering::Equal);
    }
}
