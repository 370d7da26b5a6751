//! Interrogation grids: window size, grid step, region of interest and mask.
//!
//! A window covers the half-open pixel range `[x0, x0 + width) × [y0, y0 + height)`; its
//! vector sits at the window's centroid `x0 + (width − 1)/2`, `y0 + (height − 1)/2` in image
//! coordinates (pixel centres at integers). Windows lie entirely inside the region of
//! interest and the sensor.

use crate::error::{Error, Result};
use crate::event::Geometry;
use crate::filter::Roi;

/// "64x64 px step 32 -> 40x40 px step 20": the passes' windows and steps, for messages.
pub fn describe_passes(passes: &[GridSpec]) -> String {
    passes
        .iter()
        .map(|g| format!("{}x{} px step {}", g.window[0], g.window[1], g.step[0]))
        .collect::<Vec<_>>()
        .join(" -> ")
}

/// How to lay interrogation windows over the sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSpec {
    /// Window width and height, px.
    pub window: [u32; 2],
    /// Distance between neighbouring window origins along x and y, px.
    pub step: [u32; 2],
    /// Region the windows must lie in (whole sensor if `None`).
    pub roi: Option<Roi>,
}

impl GridSpec {
    /// Square windows of `window` px on a `step` px grid over the whole sensor.
    pub fn square(window: u32, step: u32) -> Self {
        GridSpec {
            window: [window, window],
            step: [step, step],
            roi: None,
        }
    }
}

/// A pixel mask: `true` marks pixels to leave out (walls, bodies, reflections).
#[derive(Debug, Clone, PartialEq)]
pub struct Mask {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major, `true` = masked.
    pub masked: Vec<bool>,
}

impl Mask {
    /// True if pixel `(x, y)` is masked; pixels outside the mask image are not.
    pub fn is_masked(&self, x: i64, y: i64) -> bool {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return false;
        }
        self.masked[y as usize * self.width as usize + x as usize]
    }
}

/// One interrogation window: its pixel rectangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// Left column of the window (may be negative or beyond the sensor for shifted windows).
    pub x0: i64,
    /// Top row.
    pub y0: i64,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
}

impl Window {
    /// Centroid of the window's pixels, image coordinates.
    pub fn centre(&self) -> [f64; 2] {
        [
            self.x0 as f64 + (self.width as f64 - 1.0) / 2.0,
            self.y0 as f64 + (self.height as f64 - 1.0) / 2.0,
        ]
    }

    /// The same window moved by whole pixels.
    pub fn shifted(&self, dx: i64, dy: i64) -> Window {
        Window {
            x0: self.x0 + dx,
            y0: self.y0 + dy,
            ..*self
        }
    }
}

/// The windows of a [`GridSpec`] on a given sensor, row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Window width and height, px.
    pub window: [u32; 2],
    /// Left columns of the windows, one per grid column.
    pub x0: Vec<i64>,
    /// Top rows of the windows, one per grid row.
    pub y0: Vec<i64>,
}

impl Grid {
    /// Lay out `spec` on a sensor of `geometry`: as many windows as fit in the region, the
    /// first at the region's top-left corner.
    pub fn new(spec: &GridSpec, geometry: Geometry) -> Result<Grid> {
        let [w, h] = spec.window;
        let [sx, sy] = spec.step;
        if w < 2 || h < 2 {
            return Err(Error::parameter(
                "window",
                format!("must be at least 2×2 px, got {w}×{h}"),
            ));
        }
        if sx == 0 || sy == 0 {
            return Err(Error::parameter("step", "must be at least 1 px"));
        }
        let roi = spec.roi.unwrap_or(Roi {
            x: 0,
            y: 0,
            width: geometry.width,
            height: geometry.height,
        });
        let right = (roi.x as u64 + roi.width as u64).min(geometry.width as u64);
        let bottom = (roi.y as u64 + roi.height as u64).min(geometry.height as u64);
        let x0 = starts(roi.x as u64, right, w, sx);
        let y0 = starts(roi.y as u64, bottom, h, sy);
        if x0.is_empty() || y0.is_empty() {
            return Err(Error::parameter(
                "window",
                format!(
                    "a {w}×{h} px window does not fit in the region {}×{} px at ({}, {}) of the {}×{} sensor",
                    roi.width, roi.height, roi.x, roi.y, geometry.width, geometry.height
                ),
            ));
        }
        Ok(Grid {
            window: spec.window,
            x0,
            y0,
        })
    }

    /// Number of grid columns.
    pub fn columns(&self) -> usize {
        self.x0.len()
    }

    /// Number of grid rows.
    pub fn rows(&self) -> usize {
        self.y0.len()
    }

    /// Number of windows.
    pub fn len(&self) -> usize {
        self.x0.len() * self.y0.len()
    }

    /// True for a grid without windows (never produced by [`Grid::new`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The window of flat index `i` (row-major).
    pub fn window(&self, i: usize) -> Window {
        let (row, col) = (i / self.x0.len(), i % self.x0.len());
        Window {
            x0: self.x0[col],
            y0: self.y0[row],
            width: self.window[0],
            height: self.window[1],
        }
    }

    /// Vector positions along x (window centroids), px.
    pub fn x_centres(&self) -> Vec<f64> {
        let half = (self.window[0] as f64 - 1.0) / 2.0;
        self.x0.iter().map(|&x| x as f64 + half).collect()
    }

    /// Vector positions along y, px.
    pub fn y_centres(&self) -> Vec<f64> {
        let half = (self.window[1] as f64 - 1.0) / 2.0;
        self.y0.iter().map(|&y| y as f64 + half).collect()
    }

    /// True if the centre pixel of window `i` is masked.
    pub fn is_masked(&self, i: usize, mask: Option<&Mask>) -> bool {
        mask.is_some_and(|m| {
            let c = self.window(i).centre();
            m.is_masked(c[0].round() as i64, c[1].round() as i64)
        })
    }
}

/// Window origins `start, start + step, …` whose window of `size` ends at or before `end`.
fn starts(start: u64, end: u64, size: u32, step: u32) -> Vec<i64> {
    let mut out = Vec::new();
    let mut s = start;
    while s + size as u64 <= end {
        out.push(s as i64);
        s += step as u64;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_fit_the_sensor_and_centres_are_centroids() {
        let g = Grid::new(&GridSpec::square(40, 20), Geometry::new(100, 60)).unwrap();
        assert_eq!(g.x0, vec![0, 20, 40, 60]);
        assert_eq!(g.y0, vec![0, 20]);
        assert_eq!(g.x_centres()[0], 19.5);
        let w = g.window(5);
        assert_eq!((w.x0, w.y0), (20, 20));
        assert_eq!(w.centre(), [39.5, 39.5]);
    }

    #[test]
    fn roi_limits_the_grid_and_bad_specs_are_rejected() {
        let spec = GridSpec {
            window: [10, 10],
            step: [5, 5],
            roi: Some(Roi {
                x: 10,
                y: 0,
                width: 20,
                height: 10,
            }),
        };
        let g = Grid::new(&spec, Geometry::new(100, 100)).unwrap();
        assert_eq!(g.x0, vec![10, 15, 20]);
        assert_eq!(g.y0, vec![0]);
        assert!(Grid::new(&GridSpec::square(200, 10), Geometry::new(100, 100)).is_err());
        assert!(Grid::new(&GridSpec::square(10, 0), Geometry::new(100, 100)).is_err());
        assert!(Grid::new(&GridSpec::square(1, 1), Geometry::new(100, 100)).is_err());
    }

    #[test]
    fn mask_marks_windows_by_their_centre() {
        let g = Grid::new(&GridSpec::square(4, 4), Geometry::new(8, 4)).unwrap();
        let mut m = Mask {
            width: 8,
            height: 4,
            masked: vec![false; 32],
        };
        m.masked[2 * 8 + 6] = true; // centre (5.5, 1.5) rounds to (6, 2)
        assert!(!g.is_masked(0, Some(&m)));
        assert!(g.is_masked(1, Some(&m)));
        assert!(!g.is_masked(1, None));
    }
}
