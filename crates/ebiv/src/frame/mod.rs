//! Grey-value image frames: read from camera image files or rebuilt from events, the input of
//! the PIV engine ([`crate::piv`]).

/// A single-channel image in `f32` grey values, row-major, `data[y * width + x]`, pixel
/// centres at integer image coordinates (x right, y down).
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Grey values, `width × height`, row-major.
    pub data: Vec<f32>,
}

impl Frame {
    /// A black frame.
    pub fn new(width: u32, height: u32) -> Self {
        Frame {
            width,
            height,
            data: vec![0.0; width as usize * height as usize],
        }
    }

    /// A frame whose pixel `(x, y)` is `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> f32) -> Self {
        let mut data = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Frame {
            width,
            height,
            data,
        }
    }

    /// Grey value at pixel `(x, y)`; panics outside the frame.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.data[y as usize * self.width as usize + x as usize]
    }

    /// One image row.
    #[inline]
    pub fn row(&self, y: u32) -> &[f32] {
        let w = self.width as usize;
        &self.data[y as usize * w..(y as usize + 1) * w]
    }

    /// Width and height as a [`crate::Geometry`], for grids laid over the frame.
    pub fn geometry(&self) -> crate::Geometry {
        crate::Geometry {
            width: self.width,
            height: self.height,
        }
    }
}

pub mod events;
pub mod file;
pub mod pulse;
pub mod pulse_scan;

pub use events::{
    build_frame, despeckle, frame_starts, frames_from_reader, splat, stream_frames, FrameKind,
    FrameRecord, FrameSpec,
};
pub use file::{expand_image_list, load, load_mask, save, Scale};
pub use pulse::{detect_pulses, folded_histogram, pulse_frame_starts, PulseSource, PulseTiming};
pub use pulse_scan::scan_pulse_timing;
