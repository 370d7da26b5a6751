//! PIV of a series of camera images: loading them, pairing them (1,2), (3,4), … or as a
//! sequence (1,2), (2,3), …, one field per pair or one ensemble field of all pairs, and
//! velocities instead of displacements when the time between the frames is known.

use super::{piv_ensemble, PivParams};
use crate::error::{Error, Result};
use crate::field::{FieldSeries, Quantity, TimeBasis, VectorField};
use crate::frame::Frame;
use crate::grid::Grid;
use crate::process::RunSummary;
use std::path::{Path, PathBuf};

/// Most memory the images of one run may take, bytes.
pub const MAX_IMAGE_MEMORY_BYTES: u64 = 8 << 30;

/// How a series of images is evaluated.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageSeriesParams {
    /// The PIV engine's settings; validation ε and limits in px/ms when `dt_us` is given,
    /// else in px.
    pub piv: PivParams,
    /// Pairs (1,2), (2,3), … instead of (1,2), (3,4), ….
    pub sequence: bool,
    /// One field from the summed correlation planes of all pairs.
    pub ensemble: bool,
    /// Time between the two frames of a pair, µs: velocities in px/ms instead of
    /// displacements in px. The fields record it as their
    /// [`slab_us`](crate::field::VectorField::slab_us) (0 without it: image files carry no
    /// time).
    pub dt_us: Option<i64>,
}

/// Load every image of `paths` (at least two, all of one size, within
/// [`MAX_IMAGE_MEMORY_BYTES`]); `on_loaded` is called after each.
pub fn load_images(
    paths: &[PathBuf],
    ensemble: bool,
    on_loaded: &mut dyn FnMut(),
) -> Result<Vec<Frame>> {
    if paths.len() < 2 {
        return Err(Error::parameter(
            "images",
            format!("PIV needs at least two images, got {}", paths.len()),
        ));
    }
    let mut frames: Vec<Frame> = Vec::with_capacity(paths.len());
    for path in paths {
        let frame = crate::frame::file::load(path)?;
        // All images are held; an ensemble also holds resampling coefficients and deformed
        // copies of each.
        let per_image = frame.data.len() as u64 * 4 * if ensemble { 3 } else { 1 };
        if per_image * paths.len() as u64 > MAX_IMAGE_MEMORY_BYTES {
            return Err(Error::parameter(
                "images",
                format!(
                    "{} images of {}×{} px need about {} GiB; process fewer at a time",
                    paths.len(),
                    frame.width,
                    frame.height,
                    (per_image * paths.len() as u64) >> 30
                ),
            ));
        }
        if let Some(first) = frames.first() {
            if frame.width != first.width || frame.height != first.height {
                return Err(Error::parameter(
                    "images",
                    format!(
                        "{} is {}×{} px but {} is {}: all images must have the same size",
                        path.display(),
                        frame.width,
                        frame.height,
                        paths[0].display(),
                        first.geometry()
                    ),
                ));
            }
        }
        frames.push(frame);
        on_loaded();
    }
    Ok(frames)
}

/// The pairs of `count` images (0-based indices): (1,2), (3,4), … or, as a `sequence`,
/// (1,2), (2,3), ….
pub fn image_pairs(count: usize, sequence: bool) -> Result<Vec<(usize, usize)>> {
    if count < 2 {
        return Err(Error::parameter(
            "images",
            format!("PIV needs at least two images, got {count}"),
        ));
    }
    if sequence {
        return Ok((0..count - 1).map(|i| (i, i + 1)).collect());
    }
    if count % 2 != 0 {
        return Err(Error::parameter(
            "images",
            format!(
                "{count} images do not form pairs (1,2), (3,4), …: give an even number, or --sequence for (1,2), (2,3), …"
            ),
        ));
    }
    Ok((0..count / 2).map(|i| (2 * i, 2 * i + 1)).collect())
}

/// What the caller sees after each field of an image series.
pub struct ImageFieldDone<'a> {
    /// Index of the field.
    pub index: usize,
    /// The image pairs of this field.
    pub pairs: &'a [(usize, usize)],
    /// The field (last pass, validated, scaled to velocities with a `dt`).
    pub field: &'a VectorField,
}

/// The field series of `frames` (loaded from `paths`, for the attributes), one field per
/// pair or one for all; `on_field` is called after each field, and an error from it ends the
/// run and is returned.
pub fn piv_image_series(
    frames: &[Frame],
    paths: &[PathBuf],
    params: &ImageSeriesParams,
    on_field: &mut dyn FnMut(&ImageFieldDone) -> Result<()>,
) -> Result<(FieldSeries, RunSummary)> {
    let pairs = image_pairs(frames.len(), params.sequence)?;
    let groups: Vec<Vec<(usize, usize)>> = if params.ensemble {
        vec![pairs.clone()]
    } else {
        pairs.iter().map(|&pair| vec![pair]).collect()
    };
    let piv = scaled_params(params);
    let geometry = frames[0].geometry();
    for pass in &piv.passes {
        Grid::new(pass, geometry)?;
    }
    let dt_ms = params.dt_us.map(|d| d as f64 / 1000.0);
    let slab_us = match params.dt_us {
        None => 0,
        Some(dt) => u32::try_from(dt).ok().filter(|&d| d > 0).ok_or_else(|| {
            Error::parameter(
                "dt",
                format!(
                    "{dt} µs: the time between the frames must be 1 µs to {} µs",
                    u32::MAX
                ),
            )
        })?,
    };
    let mut series: Option<FieldSeries> = None;
    let mut summary = RunSummary::default();
    for (index, group) in groups.iter().enumerate() {
        let frame_pairs: Vec<(&Frame, &Frame)> = group
            .iter()
            .map(|&(a, b)| (&frames[a], &frames[b]))
            .collect();
        let out = piv_ensemble(&frame_pairs, &piv)?;
        let mut field = out.field;
        if let Some(dt) = dt_ms {
            field.scale(1.0 / dt);
        }
        field.set_slab_us(slab_us);
        summary.fields += 1;
        summary.vectors += field.len();
        summary.valid += field.status.iter().filter(|s| s.is_valid()).count();
        summary.flagged += out.validation.valid_before - out.validation.valid_after;
        let series =
            series.get_or_insert_with(|| FieldSeries::on_grid(field.x.clone(), field.y.clone()));
        series.push(index as i64, &field)?;
        on_field(&ImageFieldDone {
            index,
            pairs: group,
            field: &field,
        })?;
    }
    let mut series = series.expect("at least one pair");
    series.quantity = if dt_ms.is_some() {
        Quantity::Velocity
    } else {
        Quantity::Displacement
    };
    series.time_basis = TimeBasis::PairIndex;
    series.attributes = series_attributes(paths, &pairs, params);
    // `params.piv` holds the validation limits as given: px/ms with a `dt`, else px.
    let unit = if params.dt_us.is_some() {
        "px/ms"
    } else {
        "px"
    };
    series
        .attributes
        .extend(super::attributes(&params.piv, unit));
    Ok((series, summary))
}

/// The engine's settings for this series: validation limits given in px/ms converted to
/// px of displacement when a `dt` is known.
pub fn scaled_params(params: &ImageSeriesParams) -> PivParams {
    match params.dt_us {
        Some(dt) => params.piv.over_interval(dt as f64 / 1000.0),
        None => params.piv.clone(),
    }
}

/// The input of an image series as output attributes: method, files, pairs, ensemble and
/// the time between the frames of a pair when given.
fn series_attributes(
    paths: &[PathBuf],
    pairs: &[(usize, usize)],
    params: &ImageSeriesParams,
) -> Vec<(String, String)> {
    let mut a = vec![
        ("method".into(), "piv of image pairs".into()),
        (
            "source".into(),
            paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
        ),
        (
            "pairs".into(),
            pairs
                .iter()
                .map(|(a, b)| format!("({},{})", a + 1, b + 1))
                .collect::<Vec<_>>()
                .join(" "),
        ),
        ("ensemble".into(), params.ensemble.to_string()),
    ];
    if let Some(dt) = params.dt_us {
        a.push((
            "frame_interval".into(),
            format!(
                "{dt} us between the two frames of a pair; u, v are the displacements divided by it"
            ),
        ));
    }
    a
}

/// The folder the images come from, for messages.
pub fn image_folder(paths: &[PathBuf]) -> String {
    paths
        .first()
        .and_then(|p| p.parent())
        .map(Path::display)
        .map(|d| d.to_string())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_pair_as_pairs_or_as_a_sequence() {
        assert_eq!(image_pairs(4, false).unwrap(), vec![(0, 1), (2, 3)]);
        assert_eq!(image_pairs(3, true).unwrap(), vec![(0, 1), (1, 2)]);
        let e = image_pairs(3, false).unwrap_err();
        assert!(e.to_string().contains("--sequence"), "{e}");
        assert!(image_pairs(1, true).is_err());
    }

    /// A pair's fields record the time between its frames when it is given, and none (0)
    /// when image files are all there is.
    #[test]
    fn fields_record_the_time_between_the_frames() {
        let dots = |shift: u32| {
            Frame::from_fn(64, 64, move |x, y| {
                let x = x.wrapping_sub(shift);
                f32::from(u8::from(
                    (x.wrapping_mul(7919) ^ y.wrapping_mul(104_729)) % 11 == 0,
                ))
            })
        };
        let frames = [dots(0), dots(1)];
        let paths = [PathBuf::from("a.png"), PathBuf::from("b.png")];
        let params = |dt_us| ImageSeriesParams {
            piv: PivParams {
                passes: vec![crate::grid::GridSpec::square(32, 16)],
                ..PivParams::default()
            },
            sequence: false,
            ensemble: false,
            dt_us,
        };
        let run = |dt_us| piv_image_series(&frames, &paths, &params(dt_us), &mut |_| Ok(()));
        let (series, _) = run(Some(2000)).unwrap();
        assert!(!series.slab_us.is_empty());
        assert!(series.slab_us.iter().all(|&s| s == 2000));
        let (series, _) = run(None).unwrap();
        assert!(series.slab_us.iter().all(|&s| s == 0));
        let e = run(Some(0)).unwrap_err();
        assert!(e.to_string().contains("dt"), "{e}");
    }
}
