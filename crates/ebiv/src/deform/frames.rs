//! Image deformation by a displacement field, for multi-pass PIV with window deformation
//! (Scarano 2002, Meas. Sci. Technol. 13:R1–R19; algorithms.md §16.1).
//!
//! The predictor — a vector field on the previous pass's grid — is interpolated bilinearly to
//! every pixel, and each frame is resampled there: symmetric (central-difference) deformation
//! samples the first frame at `x − d(x)/2` and the second at `x + d(x)/2`, so particles of both
//! frames land on their mid-way positions and the residual displacement refers to the window
//! centre (Wereley & Meinhart 2001, Exp. Fluids 31:258). Resampling uses quintic (default) or
//! cubic B-splines (Unser, Aldroubi & Eden 1991, IEEE Trans. Signal Process. 39:277; Unser
//! 1999, IEEE Signal Process. Mag. 16(6):22), whose interpolation error for particle images is
//! far below that of bilinear resampling (Astarita & Cardone 2005, Exp. Fluids 38:233), or
//! bilinearly.

use crate::field::VectorField;
use crate::frame::Frame;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How frames are resampled at non-integer positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// Bilinear: fast, but smooths particle images and biases sub-pixel shifts.
    Linear,
    /// Cubic B-spline with exact interpolation (prefiltered coefficients), 4 × 4 taps.
    Cubic,
    /// Quintic B-spline, 6 × 6 taps: smaller phase errors at fractional shifts, hence less
    /// bias in the measured displacement (as in gpiv).
    #[default]
    Quintic,
}

impl Interpolation {
    /// The setting's name: `linear`, `cubic` or `quintic`.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Linear => "linear",
            Interpolation::Cubic => "cubic",
            Interpolation::Quintic => "quintic",
        }
    }

    /// Parse `linear`, `cubic` or `quintic`.
    pub fn parse(text: &str) -> Option<Self> {
        match text {
            "linear" | "bilinear" => Some(Interpolation::Linear),
            "cubic" => Some(Interpolation::Cubic),
            "quintic" | "spline" | "bspline" => Some(Interpolation::Quintic),
            _ => None,
        }
    }
}

/// A displacement at every pixel of a frame, px.
#[derive(Debug, Clone)]
pub struct DenseField {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// x displacement per pixel, row-major.
    pub dx: Vec<f32>,
    /// y displacement per pixel, row-major.
    pub dy: Vec<f32>,
}

/// Node indices and weight of a pixel coordinate on an ascending axis, clamped at the ends
/// (constant extrapolation beyond the outermost nodes).
fn axis_weights(axis: &[f64], n: usize) -> Vec<(usize, usize, f32)> {
    (0..n)
        .map(|p| {
            let (lo, hi, f) = crate::field::bracket(axis, p as f64);
            (lo, hi, f as f32)
        })
        .collect()
}

impl DenseField {
    /// Bilinear interpolation of `field` (which must have a value at every node, e.g. after
    /// [`crate::validate::replace_invalid`]; NaN nodes give NaN pixels) to every pixel of a
    /// `width × height` frame, the same interpolation as [`VectorField::sample`].
    pub fn from_field(field: &VectorField, width: usize, height: usize) -> Self {
        let xs = axis_weights(&field.x, width);
        let ys = axis_weights(&field.y, height);
        let mut dx = vec![0.0f32; width * height];
        let mut dy = vec![0.0f32; width * height];
        let nx = field.x.len();
        dx.par_chunks_mut(width)
            .zip(dy.par_chunks_mut(width))
            .enumerate()
            .for_each(|(y, (row_x, row_y))| {
                let (r0, r1, fy) = ys[y];
                for (x, &(c0, c1, fx)) in xs.iter().enumerate() {
                    let lerp = |a: &[f32]| {
                        let top = a[r0 * nx + c0] * (1.0 - fx) + a[r0 * nx + c1] * fx;
                        let bottom = a[r1 * nx + c0] * (1.0 - fx) + a[r1 * nx + c1] * fx;
                        top * (1.0 - fy) + bottom * fy
                    };
                    row_x[x] = lerp(&field.u);
                    row_y[x] = lerp(&field.v);
                }
            });
        DenseField {
            width,
            height,
            dx,
            dy,
        }
    }

    /// Displacement at a (fractional) point, bilinear between pixels, clamped at the border.
    pub fn at(&self, x: f64, y: f64) -> [f64; 2] {
        let xc = x.clamp(0.0, (self.width - 1) as f64);
        let yc = y.clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (xc.floor() as usize, yc.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (xc - x0 as f64, yc - y0 as f64);
        let get = |a: &[f32], xx: usize, yy: usize| a[yy * self.width + xx] as f64;
        let lerp = |a: &[f32]| {
            let top = get(a, x0, y0) * (1.0 - fx) + get(a, x1, y0) * fx;
            let bottom = get(a, x0, y1) * (1.0 - fx) + get(a, x1, y1) * fx;
            top * (1.0 - fy) + bottom * fy
        };
        [lerp(&self.dx), lerp(&self.dy)]
    }
}

/// A frame prepared for resampling: the frame itself (bilinear) or its cubic B-spline
/// coefficients.
#[derive(Debug, Clone)]
pub struct Resampler {
    width: usize,
    height: usize,
    kind: Interpolation,
    /// Grey values (linear) or B-spline coefficients (cubic), row-major.
    coefficients: Vec<f32>,
}

/// The pole of the cubic B-spline's inverse filter, √3 − 2 (Unser 1999, Table I).
const CUBIC_POLES: [f64; 1] = [-0.267_949_192_431_122_7];
/// The poles of the quintic B-spline's inverse filter (Unser 1999, Table I).
const QUINTIC_POLES: [f64; 2] = [-0.430_575_347_099_973_8, -0.043_096_288_203_264_65];

/// In-place B-spline prefilter of one line for the given poles, so that the spline through
/// the coefficients interpolates the samples (Unser 1999, Box 2).
fn prefilter_line(line: &mut [f64], poles: &[f64]) {
    if line.len() < 2 {
        return;
    }
    let gain: f64 = poles.iter().map(|&z| (1.0 - z) * (1.0 - 1.0 / z)).product();
    for v in line.iter_mut() {
        *v *= gain;
    }
    for &z in poles {
        recursive_pass(line, z);
    }
}

/// Causal then anti-causal first-order recursion with pole `z` and mirror-symmetric
/// boundaries (Unser 1999, Box 2).
fn recursive_pass(line: &mut [f64], z: f64) {
    let n = line.len();
    // Causal initialisation: sum of the mirrored signal, truncated where z^k < 1e-9 or
    // exact for short lines.
    let horizon = ((1e-9f64).ln() / z.abs().ln()).ceil() as usize;
    if n > horizon {
        let mut zn = z;
        let mut sum = line[0];
        for &v in line.iter().skip(1).take(horizon) {
            sum += zn * v;
            zn *= z;
        }
        line[0] = sum;
    } else {
        let zn1 = z.powi(n as i32 - 1);
        let z2n2 = zn1 * zn1;
        let mut sum = line[0] + zn1 * line[n - 1];
        let mut zk = z;
        let mut z2 = zn1 * zn1 / z;
        for &v in line.iter().take(n - 1).skip(1) {
            sum += (zk + z2) * v;
            zk *= z;
            z2 /= z;
        }
        line[0] = sum / (1.0 - z2n2);
    }
    for k in 1..n {
        line[k] += z * line[k - 1];
    }
    // Anti-causal initialisation for mirror boundaries.
    line[n - 1] = (z / (z * z - 1.0)) * (z * line[n - 2] + line[n - 1]);
    for k in (0..n - 1).rev() {
        line[k] = z * (line[k + 1] - line[k]);
    }
}

/// B-spline weights of the nodes around a sample at fractional offset `t` in [0, 1) from
/// node `i`: nodes `i − 1 … i + 2` for the cubic, `i − 2 … i + 3` for the quintic spline.
trait Kernel<const N: usize> {
    fn weights(t: f32) -> [f32; N];

    /// The weights of [`LANES`] offsets at once, `[node][lane]` (written so the compiler can
    /// vectorise across lanes).
    #[inline]
    fn lanes(t: &[f32; LANES]) -> [[f32; LANES]; N] {
        let mut out = [[0.0; LANES]; N];
        for (k, &tk) in t.iter().enumerate() {
            let w = Self::weights(tk);
            for (node, &wi) in w.iter().enumerate() {
                out[node][k] = wi;
            }
        }
        out
    }
}

/// Pixels resampled together by [`Resampler::warp`].
const LANES: usize = 8;

struct CubicKernel;
struct QuinticKernel;

impl Kernel<4> for CubicKernel {
    #[inline]
    fn weights(t: f32) -> [f32; 4] {
        let t2 = t * t;
        let t3 = t2 * t;
        let one = 1.0 - t;
        [
            one * one * one / 6.0,
            (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
            (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
            t3 / 6.0,
        ]
    }
}

impl Kernel<6> for QuinticKernel {
    /// The pieces of β⁵(t − j), j = −2 … 3, as polynomials in t (times 120).
    #[inline]
    fn weights(t: f32) -> [f32; 6] {
        let one = 1.0 - t;
        let one2 = one * one;
        let t5 = t * t * t * t * t;
        const S: f32 = 1.0 / 120.0;
        [
            one2 * one2 * one * S,
            (26.0 + t * (-50.0 + t * (20.0 + t * (20.0 + t * (-20.0 + t * 5.0))))) * S,
            (66.0 + t * t * (-60.0 + t * t * (30.0 - 10.0 * t))) * S,
            (26.0 + t * (50.0 + t * (20.0 + t * (-20.0 + t * (-20.0 + t * 10.0))))) * S,
            (1.0 + t * (5.0 + t * (10.0 + t * (10.0 + t * (5.0 - 5.0 * t))))) * S,
            t5 * S,
        ]
    }
}

/// Mirror an index into `0..n` (whole-sample symmetric, matching the prefilter).
#[inline]
fn mirror(i: i64, n: usize) -> usize {
    let n = n as i64;
    if n == 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let mut k = i.rem_euclid(period);
    if k >= n {
        k = period - k;
    }
    k as usize
}

impl Resampler {
    /// Prepare `frame` for resampling with `kind`.
    pub fn new(frame: &Frame, kind: Interpolation) -> Self {
        let (width, height) = (frame.width as usize, frame.height as usize);
        let poles: &[f64] = match kind {
            Interpolation::Linear => &[],
            Interpolation::Cubic => &CUBIC_POLES,
            Interpolation::Quintic => &QUINTIC_POLES,
        };
        let coefficients = match kind {
            Interpolation::Linear => frame.data.clone(),
            Interpolation::Cubic | Interpolation::Quintic => {
                let mut c: Vec<f32> = frame.data.clone();
                c.par_chunks_mut(width.max(1)).for_each(|row| {
                    let mut line: Vec<f64> = row.iter().map(|&v| v as f64).collect();
                    prefilter_line(&mut line, poles);
                    for (d, s) in row.iter_mut().zip(&line) {
                        *d = *s as f32;
                    }
                });
                // Columns: filter blocks of columns together for cache locality.
                let mut transposed = vec![0.0f32; width * height];
                for y in 0..height {
                    for x in 0..width {
                        transposed[x * height + y] = c[y * width + x];
                    }
                }
                transposed.par_chunks_mut(height.max(1)).for_each(|col| {
                    let mut line: Vec<f64> = col.iter().map(|&v| v as f64).collect();
                    prefilter_line(&mut line, poles);
                    for (d, s) in col.iter_mut().zip(&line) {
                        *d = *s as f32;
                    }
                });
                for y in 0..height {
                    for x in 0..width {
                        c[y * width + x] = transposed[x * height + y];
                    }
                }
                c
            }
        };
        Resampler {
            width,
            height,
            kind,
            coefficients,
        }
    }

    /// Interpolated grey value at `(x, y)`; positions outside the frame take the mirrored
    /// (cubic) or nearest (linear) border values.
    #[inline]
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        match self.kind {
            Interpolation::Linear => self.sample_linear(x, y),
            Interpolation::Cubic => self.sample_spline::<4, CubicKernel>(x, y),
            Interpolation::Quintic => self.sample_spline::<6, QuinticKernel>(x, y),
        }
    }

    #[inline]
    fn sample_linear(&self, x: f32, y: f32) -> f32 {
        let xc = x.clamp(0.0, (self.width - 1) as f32);
        let yc = y.clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (xc as usize, yc as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (xc - x0 as f32, yc - y0 as f32);
        let c = &self.coefficients;
        let w = self.width;
        let top = c[y0 * w + x0] * (1.0 - fx) + c[y0 * w + x1] * fx;
        let bottom = c[y1 * w + x0] * (1.0 - fx) + c[y1 * w + x1] * fx;
        top * (1.0 - fy) + bottom * fy
    }

    #[inline]
    fn sample_spline<const N: usize, K: Kernel<N>>(&self, x: f32, y: f32) -> f32 {
        let (fx, fy) = (x.floor(), y.floor());
        let wx = K::weights(x - fx);
        let wy = K::weights(y - fy);
        let before = (N / 2 - 1) as i64;
        self.taps::<N>(fx as i64 - before, fy as i64 - before, |i| wx[i], |j| wy[j])
    }

    /// The frame resampled at `x + factor·d(x)` for every pixel `x`.
    pub fn warp(&self, field: &DenseField, factor: f32) -> Frame {
        let (w, h) = (self.width, self.height);
        let mut data = vec![0.0f32; w * h];
        data.par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(y, row)| {
                let (dx, dy) = (&field.dx[y * w..(y + 1) * w], &field.dy[y * w..(y + 1) * w]);
                match self.kind {
                    Interpolation::Linear => {
                        for (x, out) in row.iter_mut().enumerate() {
                            *out = self.sample_linear(
                                x as f32 + factor * dx[x],
                                y as f32 + factor * dy[x],
                            );
                        }
                    }
                    Interpolation::Cubic => self.warp_row::<4, CubicKernel>(y, dx, dy, factor, row),
                    Interpolation::Quintic => {
                        self.warp_row::<6, QuinticKernel>(y, dx, dy, factor, row)
                    }
                }
            });
        Frame {
            width: w as u32,
            height: h as u32,
            data,
        }
    }

    /// One output row of a spline warp, [`LANES`] pixels at a time: weights for all lanes
    /// first, then the taps.
    fn warp_row<const N: usize, K: Kernel<N>>(
        &self,
        y: usize,
        dx: &[f32],
        dy: &[f32],
        factor: f32,
        row: &mut [f32],
    ) {
        let before = (N / 2 - 1) as i64;
        for (chunk, out) in row.chunks_mut(LANES).enumerate() {
            let start = chunk * LANES;
            let (mut tx, mut ty) = ([0.0f32; LANES], [0.0f32; LANES]);
            let (mut ix, mut iy) = ([0i64; LANES], [0i64; LANES]);
            for k in 0..out.len() {
                let sx = (start + k) as f32 + factor * dx[start + k];
                let sy = y as f32 + factor * dy[start + k];
                let (fx, fy) = (sx.floor(), sy.floor());
                tx[k] = sx - fx;
                ty[k] = sy - fy;
                ix[k] = fx as i64 - before;
                iy[k] = fy as i64 - before;
            }
            let wx = K::lanes(&tx);
            let wy = K::lanes(&ty);
            for (k, o) in out.iter_mut().enumerate() {
                *o = self.taps::<N>(ix[k], iy[k], |i| wx[i][k], |j| wy[j][k]);
            }
        }
    }

    /// Σⱼ wy(j) Σᵢ wx(i) c[iy + j][ix + i], with mirrored indices outside the frame.
    #[inline]
    fn taps<const N: usize>(
        &self,
        ix: i64,
        iy: i64,
        wx: impl Fn(usize) -> f32,
        wy: impl Fn(usize) -> f32,
    ) -> f32 {
        let (w, h) = (self.width, self.height);
        let c = &self.coefficients;
        let inside =
            ix >= 0 && iy >= 0 && ix + (N as i64) <= w as i64 && iy + (N as i64) <= h as i64;
        let mut sum = 0.0f32;
        if inside {
            let (ix, iy) = (ix as usize, iy as usize);
            for j in 0..N {
                let row = &c[(iy + j) * w + ix..(iy + j) * w + ix + N];
                let mut s = 0.0f32;
                for (i, &v) in row.iter().enumerate() {
                    s += wx(i) * v;
                }
                sum += wy(j) * s;
            }
        } else {
            for j in 0..N {
                let r = mirror(iy + j as i64, h) * w;
                let mut s = 0.0f32;
                for i in 0..N {
                    s += wx(i) * c[r + mirror(ix + i as i64, w)];
                }
                sum += wy(j) * s;
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn smooth_frame(w: u32, h: u32) -> Frame {
        Frame::from_fn(w, h, |x, y| {
            let (x, y) = (x as f32, y as f32);
            100.0 + 40.0 * (0.31 * x).sin() * (0.23 * y).cos() + 0.5 * x
        })
    }

    #[test]
    fn splines_interpolate_the_samples_exactly() {
        let f = smooth_frame(37, 23);
        for kind in [Interpolation::Cubic, Interpolation::Quintic] {
            let r = Resampler::new(&f, kind);
            for y in 0..23 {
                for x in 0..37 {
                    let s = r.sample(x as f32, y as f32);
                    assert!((s - f.get(x, y)).abs() < 1e-3, "{kind:?} ({x},{y}) {s}");
                }
            }
        }
    }

    #[test]
    fn quintic_weights_are_a_partition_of_unity_and_symmetric() {
        for k in 0..10 {
            let t = k as f32 / 10.0;
            let w = QuinticKernel::weights(t);
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            let m = QuinticKernel::weights(1.0 - t);
            for i in 0..6 {
                assert!((w[i] - m[5 - i]).abs() < 1e-6, "t {t}");
            }
        }
        // At a node: β⁵(0) = 66/120, β⁵(±1) = 26/120, β⁵(±2) = 1/120.
        let w = QuinticKernel::weights(0.0);
        assert!((w[2] - 66.0 / 120.0).abs() < 1e-7 && (w[1] - 26.0 / 120.0).abs() < 1e-7);
    }

    #[test]
    fn splines_shift_a_smooth_image_accurately() {
        let f = smooth_frame(64, 64);
        let r = Resampler::new(&f, Interpolation::Cubic);
        let q = Resampler::new(&f, Interpolation::Quintic);
        let l = Resampler::new(&f, Interpolation::Linear);
        let truth = |x: f32, y: f32| 100.0 + 40.0 * (0.31 * x).sin() * (0.23 * y).cos() + 0.5 * x;
        let (mut ec, mut eq, mut el) = (0.0f32, 0.0f32, 0.0f32);
        // Away from the border, where the mirrored extension's kink (the linear ramp) reaches
        // further into the quintic spline (pole 0.43) than into the cubic (pole 0.27).
        for y in 20..44 {
            for x in 20..44 {
                let (sx, sy) = (x as f32 + 0.37, y as f32 - 0.61);
                ec = ec.max((r.sample(sx, sy) - truth(sx, sy)).abs());
                eq = eq.max((q.sample(sx, sy) - truth(sx, sy)).abs());
                el = el.max((l.sample(sx, sy) - truth(sx, sy)).abs());
            }
        }
        assert!(ec < 0.05, "cubic max error {ec}");
        assert!(ec < el / 5.0, "cubic {ec} not much better than linear {el}");
        assert!(eq < ec, "quintic {eq} not better than cubic {ec}");
    }

    #[test]
    fn warping_by_a_constant_field_shifts_the_frame() {
        let f = smooth_frame(40, 30);
        let r = Resampler::new(&f, Interpolation::Cubic);
        let field = DenseField {
            width: 40,
            height: 30,
            dx: vec![2.0; 1200],
            dy: vec![-1.0; 1200],
        };
        let g = r.warp(&field, 1.0);
        for y in 2..28 {
            for x in 2..37 {
                assert!((g.get(x, y) - f.get(x + 2, y - 1)).abs() < 1e-3);
            }
        }
    }

    #[test]
    fn short_lines_are_interpolated_exactly_too() {
        for n in [2u32, 3, 5, 9] {
            let f = Frame::from_fn(n, 1, |x, _| (x * x) as f32 + 3.0);
            let r = Resampler::new(&f, Interpolation::Cubic);
            for x in 0..n {
                assert!(
                    (r.sample(x as f32, 0.0) - f.get(x, 0)).abs() < 1e-3,
                    "n {n} x {x}"
                );
            }
        }
    }

    #[test]
    fn dense_field_interpolates_the_grid_and_clamps_outside() {
        let mut field = VectorField::new(vec![10.0, 20.0], vec![5.0, 15.0]);
        field.u = vec![0.0, 1.0, 2.0, 3.0];
        field.v = vec![1.0; 4];
        field.status = vec![crate::field::Status::VALID; 4];
        let d = DenseField::from_field(&field, 30, 20);
        assert_eq!(d.dx[5 * 30 + 15], 0.5);
        assert_eq!(d.dx[10 * 30 + 15], 1.5);
        assert_eq!(d.dx[0], 0.0);
        assert_eq!(d.dx[19 * 30 + 29], 3.0);
        assert_eq!(d.at(15.0, 10.0), [1.5, 1.0]);
        let s = field.sample(15.0, 10.0).unwrap();
        assert!((s[0] - 1.5).abs() < 1e-12);
    }
}
