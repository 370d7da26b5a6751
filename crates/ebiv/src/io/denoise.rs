//! Denoising attached to a reader ([`crate::denoise`]): the sensor size and the hot pixels
//! are found from the recording itself, read a second time without denoising.

use super::EventReader;
use crate::denoise::{DenoiseSettings, Denoiser, HotPixelLearner};
use crate::error::Result;
use crate::event::{EventBuffer, Geometry};

/// Attach the filters of `settings` to `reader`. `raw` opens the same recording again,
/// without denoising: it is read for the sensor size when neither the file nor the options
/// state it (to the end), and for the hot pixels over their learning interval.
pub(crate) fn attach(
    reader: &mut EventReader,
    settings: &DenoiseSettings,
    mut raw: impl FnMut() -> Result<EventReader>,
) -> Result<()> {
    if !settings.filters.any() {
        return Ok(());
    }
    settings.check()?;
    let geometry = match reader.metadata().geometry {
        Some(g) => g,
        None => largest_coordinates(&mut raw()?)?,
    };
    crate::denoise::check_geometry(geometry)?;
    let hot = if settings.filters.hot_pixels {
        let mut learner = HotPixelLearner::new(geometry, settings.hot_pixel_learn_us);
        let mut scan = raw()?;
        let mut batch = EventBuffer::new();
        while scan.read_batch(&mut batch)? {
            if !learner.add(&batch) {
                break;
            }
        }
        Some(learner.finish(settings.hot_pixel_factor))
    } else {
        None
    };
    reader.denoiser = Some(Denoiser::new(settings, geometry, hot)?);
    Ok(())
}

/// The sensor the largest coordinates of `reader` imply (1×1 without events).
fn largest_coordinates(reader: &mut EventReader) -> Result<Geometry> {
    let (mut w, mut h) = (0u16, 0u16);
    let mut batch = EventBuffer::new();
    while reader.read_batch(&mut batch)? {
        w = w.max(batch.x.iter().copied().max().unwrap_or(0));
        h = h.max(batch.y.iter().copied().max().unwrap_or(0));
    }
    Ok(Geometry::new(w as u32 + 1, h as u32 + 1))
}
