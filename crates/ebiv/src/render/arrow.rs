//! Arrows and markers of vector maps, sized for the arrow spacing.

use super::draw::{line, triangle, Colour, Rect};
use image::RgbImage;

/// Colour of the halo around arrows and markers.
pub const HALO: Colour = [0, 0, 0];
/// Colour of the cross marking a vector without a value.
pub const INVALID: Colour = [235, 40, 40];

/// Sizes of arrows and markers for a given arrow spacing in output pixels.
pub struct ArrowSize {
    width: f64,
    head: f64,
    marker: f64,
}

impl ArrowSize {
    pub fn for_spacing(spacing: f64) -> Self {
        let width = (spacing / 22.0).clamp(1.2, 3.5);
        ArrowSize {
            width,
            head: 3.5 * width + 2.0,
            marker: (spacing * 0.14).clamp(2.5, 6.0),
        }
    }

    /// An arrow from `p` along `d` with a halo of `halo` colour.
    pub fn draw(
        &self,
        img: &mut RgbImage,
        p: (f64, f64),
        d: (f64, f64),
        c: Colour,
        halo: Colour,
        clip: &Rect,
    ) {
        let len = d.0.hypot(d.1);
        if len < 1.0 {
            self.dot(img, p, c, clip);
            return;
        }
        let (ux, uy) = (d.0 / len, d.1 / len);
        let head = self.head.min(0.45 * len);
        let half = head * 0.5;
        let tip = (p.0 + d.0, p.1 + d.1);
        let base = (tip.0 - ux * head, tip.1 - uy * head);
        let tri = [
            tip,
            (base.0 - uy * half, base.1 + ux * half),
            (base.0 + uy * half, base.1 - ux * half),
        ];
        let shaft_end = (tip.0 - ux * head * 0.7, tip.1 - uy * head * 0.7);
        line(img, p, shaft_end, self.width + 2.0, halo, clip);
        triangle(img, tri, 1.0, halo, clip);
        line(img, p, shaft_end, self.width, c, clip);
        triangle(img, tri, 0.0, c, clip);
    }

    /// A red cross marking a vector without a value.
    pub fn cross(&self, img: &mut RgbImage, p: (f64, f64), clip: &Rect) {
        let m = self.marker;
        for (c, w) in [(HALO, 3.2), (INVALID, 1.6)] {
            line(img, (p.0 - m, p.1 - m), (p.0 + m, p.1 + m), w, c, clip);
            line(img, (p.0 - m, p.1 + m), (p.0 + m, p.1 - m), w, c, clip);
        }
    }

    /// A small dot (zero vectors, masked nodes).
    pub fn dot(&self, img: &mut RgbImage, p: (f64, f64), c: Colour, clip: &Rect) {
        line(img, p, p, 2.0 * self.width.max(1.5), c, clip);
    }
}
