//! Anti-aliased drawing primitives on RGB images: thick line segments, filled triangles,
//! rectangles. Coordinates are `f64` output pixels with pixel `(i, j)` covering
//! `[i, i+1) × [j, j+1)`; everything is clipped to a rectangle, so no input can make a
//! primitive touch more than that rectangle's pixels or loop without bound.

use image::RgbImage;

/// An RGB colour.
pub type Colour = [u8; 3];

/// An axis-aligned clip rectangle `[x0, x1) × [y0, y1)` in output pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    /// Left edge.
    pub x0: f64,
    /// Top edge.
    pub y0: f64,
    /// Right edge (exclusive).
    pub x1: f64,
    /// Bottom edge (exclusive).
    pub y1: f64,
}

impl Rect {
    /// The rectangle with top-left corner `(x, y)` and the given size.
    pub fn new(x: f64, y: f64, w: f64, h: f64) -> Self {
        Rect {
            x0: x,
            y0: y,
            x1: x + w,
            y1: y + h,
        }
    }

    /// The whole of `img`.
    pub fn of(img: &RgbImage) -> Self {
        Rect::new(0.0, 0.0, img.width() as f64, img.height() as f64)
    }

    /// `self` grown by `d` on every side.
    pub fn grown(&self, d: f64) -> Self {
        Rect {
            x0: self.x0 - d,
            y0: self.y0 - d,
            x1: self.x1 + d,
            y1: self.y1 + d,
        }
    }

    /// Integer pixel bounds of `self ∩ img`, or `None` if empty.
    fn pixels(&self, img: &RgbImage) -> Option<(i64, i64, i64, i64)> {
        let x0 = self.x0.max(0.0).floor() as i64;
        let y0 = self.y0.max(0.0).floor() as i64;
        let x1 = self.x1.min(img.width() as f64).ceil() as i64;
        let y1 = self.y1.min(img.height() as f64).ceil() as i64;
        (x0 < x1 && y0 < y1).then_some((x0, y0, x1, y1))
    }
}

/// Blend `colour` over pixel `(x, y)` with opacity `alpha` ∈ [0, 1], if it lies in `clip`.
pub fn blend(img: &mut RgbImage, x: i64, y: i64, colour: Colour, alpha: f64, clip: &Rect) {
    let (fx, fy) = (x as f64, y as f64);
    if alpha <= 0.0 || fx < clip.x0 || fy < clip.y0 || fx >= clip.x1 || fy >= clip.y1 {
        return;
    }
    if x < 0 || y < 0 || x >= img.width() as i64 || y >= img.height() as i64 {
        return;
    }
    let a = alpha.min(1.0) as f32;
    let p = img.get_pixel_mut(x as u32, y as u32);
    for (c, &target) in p.0.iter_mut().zip(&colour) {
        *c = (*c as f32 + a * (target as f32 - *c as f32)).round() as u8;
    }
}

/// Fill `rect ∩ img` with `colour`.
pub fn fill_rect(img: &mut RgbImage, rect: Rect, colour: Colour) {
    if let Some((x0, y0, x1, y1)) = rect.pixels(img) {
        for y in y0..y1 {
            for x in x0..x1 {
                img.put_pixel(x as u32, y as u32, image::Rgb(colour));
            }
        }
    }
}

/// Draw the 1-pixel outline of the pixel rectangle `[x0, x1] × [y0, y1]`.
pub fn outline(img: &mut RgbImage, x0: i64, y0: i64, x1: i64, y1: i64, colour: Colour) {
    let r = |a: i64, b: i64, c: i64, d: i64| {
        Rect::new(a as f64, b as f64, (c - a + 1) as f64, (d - b + 1) as f64)
    };
    fill_rect(img, r(x0, y0, x1, y0), colour);
    fill_rect(img, r(x0, y1, x1, y1), colour);
    fill_rect(img, r(x0, y0, x0, y1), colour);
    fill_rect(img, r(x1, y0, x1, y1), colour);
}

/// Clip the segment `a → b` to `r` (Liang–Barsky); `None` if nothing of it is inside.
pub fn clip_segment(a: (f64, f64), b: (f64, f64), r: &Rect) -> Option<((f64, f64), (f64, f64))> {
    if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
        return None;
    }
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - r.x0),
        (dx, r.x1 - a.0),
        (-dy, a.1 - r.y0),
        (dy, r.y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    (t0 <= t1).then_some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

/// Distance from `p` to the segment `a → b`.
fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p.0 - a.0 - t * dx).powi(2) + (p.1 - a.1 - t * dy).powi(2)).sqrt()
}

/// Draw an anti-aliased line of `width` px with round caps from `a` to `b`, clipped to
/// `clip`. Work is proportional to the visible length times the width.
pub fn line(
    img: &mut RgbImage,
    a: (f64, f64),
    b: (f64, f64),
    width: f64,
    colour: Colour,
    clip: &Rect,
) {
    let half = (width * 0.5).clamp(0.25, 64.0);
    let Some((a, b)) = clip_segment(a, b, &clip.grown(half + 1.0)) else {
        return;
    };
    let steep = (b.1 - a.1).abs() > (b.0 - a.0).abs();
    // Work in (major, minor) coordinates; swap back when plotting.
    let sw = |p: (f64, f64)| if steep { (p.1, p.0) } else { p };
    let (mut p, mut q) = (sw(a), sw(b));
    if p.0 > q.0 {
        std::mem::swap(&mut p, &mut q);
    }
    let slope = if q.0 > p.0 {
        (q.1 - p.1) / (q.0 - p.0)
    } else {
        0.0
    };
    let reach = half * 1.5 + 1.5;
    let m0 = (p.0 - half - 1.0).floor() as i64;
    let m1 = (q.0 + half + 1.0).ceil() as i64;
    for major in m0..=m1 {
        let mc = major as f64 + 0.5;
        let centre = p.1 + slope * (mc.clamp(p.0, q.0) - p.0);
        for minor in (centre - reach).floor() as i64..=(centre + reach).ceil() as i64 {
            let pt = (mc, minor as f64 + 0.5);
            let d = segment_distance(pt, p, q);
            let cover = (half + 0.5 - d).clamp(0.0, 1.0);
            let (x, y) = if steep {
                (minor, major)
            } else {
                (major, minor)
            };
            blend(img, x, y, colour, cover, clip);
        }
    }
}

/// Fill the triangle `t` with anti-aliased edges, grown outward by `grow` px (for halos).
pub fn triangle(img: &mut RgbImage, t: [(f64, f64); 3], grow: f64, colour: Colour, clip: &Rect) {
    if !t.iter().all(|p| p.0.is_finite() && p.1.is_finite()) {
        return;
    }
    let area = (t[1].0 - t[0].0) * (t[2].1 - t[0].1) - (t[1].1 - t[0].1) * (t[2].0 - t[0].0);
    if area.abs() < 1e-9 {
        return;
    }
    let sign = area.signum();
    let m = grow + 1.0;
    let bbox = Rect {
        x0: t.iter().map(|p| p.0).fold(f64::INFINITY, f64::min) - m,
        y0: t.iter().map(|p| p.1).fold(f64::INFINITY, f64::min) - m,
        x1: t.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max) + m,
        y1: t.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max) + m,
    };
    let bbox = Rect {
        x0: bbox.x0.max(clip.x0),
        y0: bbox.y0.max(clip.y0),
        x1: bbox.x1.min(clip.x1),
        y1: bbox.y1.min(clip.y1),
    };
    let Some((x0, y0, x1, y1)) = bbox.pixels(img) else {
        return;
    };
    for y in y0..y1 {
        for x in x0..x1 {
            let p = (x as f64 + 0.5, y as f64 + 0.5);
            let mut inside = f64::INFINITY;
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
                let d = sign * ((b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)) / len;
                inside = inside.min(d);
            }
            blend(
                img,
                x,
                y,
                colour,
                (inside + grow + 0.5).clamp(0.0, 1.0),
                clip,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_inside_part() {
        let r = Rect::new(0.0, 0.0, 10.0, 10.0);
        let (a, b) = clip_segment((-5.0, 5.0), (15.0, 5.0), &r).unwrap();
        assert_eq!((a.0, b.0), (0.0, 10.0));
        assert!(clip_segment((-5.0, -5.0), (-1.0, 20.0), &r).is_none());
        assert!(clip_segment((0.0, 0.0), (f64::INFINITY, 1.0), &r).is_none());
    }

    #[test]
    fn huge_lines_are_clipped_and_drawn() {
        let mut img = RgbImage::new(50, 50);
        let clip = Rect::of(&img);
        line(&mut img, (25.0, 25.5), (1e300, 25.5), 2.0, [255; 3], &clip);
        assert_eq!(img.get_pixel(40, 25).0, [255; 3]);
        assert_eq!(img.get_pixel(20, 25).0, [0; 3]);
        triangle(
            &mut img,
            [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0)],
            0.0,
            [9; 3],
            &clip,
        );
        assert_eq!(img.get_pixel(2, 2).0, [9; 3]);
    }
}
