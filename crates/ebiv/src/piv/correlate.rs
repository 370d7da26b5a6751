//! Cross-correlation of two interrogation windows by FFT.
//!
//! The correlation plane `R(s) = Σₓ a(x)·b(x + s)` peaks at the displacement `s` that carries
//! the pattern of window `a` onto window `b` (Raffel et al., "Particle Image Velocimetry",
//! 3rd ed., §5.3). Both windows are transformed by one complex 2-D FFT of `a + i·b`, their
//! spectra separated by Hermitian symmetry, `conj(A)·B` formed, and one inverse transform
//! gives `R`. Two flavours (algorithms.md §16.2):
//!
//! * **circular**: transform size = window size; shifts wrap around (the default of OpenPIV and
//!   PIVlab), adequate once a predictor keeps the residual displacement small;
//! * **linear**: windows zero-padded to twice their size, so no wrap-around; the plane is
//!   cropped to the window size around zero shift.
//!
//! The plane is returned in "shifted" order: index `(row, col)` holds the shift
//! `(col − w/2, row − h/2)`, divided by `√(Σa²·Σb²)` so that its values are correlation
//! coefficients (for mean-free windows) and comparable between windows.

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Correlation flavour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CorrelationKind {
    /// Transform size = window size; periodic wrap-around.
    #[default]
    Circular,
    /// Zero-padded to twice the window size; no wrap-around, about 3× slower.
    Linear,
}

impl CorrelationKind {
    /// The setting's name: `circular` or `linear`.
    pub fn name(self) -> &'static str {
        match self {
            CorrelationKind::Circular => "circular",
            CorrelationKind::Linear => "linear",
        }
    }

    /// Parse `circular` or `linear`.
    pub fn parse(text: &str) -> Option<Self> {
        match text {
            "circular" | "cyclic" => Some(CorrelationKind::Circular),
            "linear" | "padded" => Some(CorrelationKind::Linear),
            _ => None,
        }
    }
}

/// FFT plans and buffers for correlating `w × h` windows; one per thread.
pub struct Correlator {
    /// Window width and height.
    w: usize,
    h: usize,
    /// Transform width and height (window size, or doubled for linear correlation).
    tw: usize,
    th: usize,
    rows_forward: Arc<dyn Fft<f32>>,
    cols_forward: Arc<dyn Fft<f32>>,
    rows_inverse: Arc<dyn Fft<f32>>,
    cols_inverse: Arc<dyn Fft<f32>>,
    /// Row-major `th × tw` buffer.
    grid: Vec<Complex<f32>>,
    /// Transposed `tw × th` buffer.
    transposed: Vec<Complex<f32>>,
    scratch: Vec<Complex<f32>>,
}

impl Correlator {
    /// Plans for `w × h` windows.
    pub fn new(w: usize, h: usize, kind: CorrelationKind) -> Self {
        let (tw, th) = match kind {
            CorrelationKind::Circular => (w, h),
            CorrelationKind::Linear => (2 * w, 2 * h),
        };
        let mut planner = FftPlanner::new();
        let rows_forward = planner.plan_fft_forward(tw);
        let cols_forward = planner.plan_fft_forward(th);
        let rows_inverse = planner.plan_fft_inverse(tw);
        let cols_inverse = planner.plan_fft_inverse(th);
        let scratch_len = [&rows_forward, &cols_forward, &rows_inverse, &cols_inverse]
            .iter()
            .map(|f| f.get_inplace_scratch_len())
            .max()
            .unwrap_or(0);
        Correlator {
            w,
            h,
            tw,
            th,
            rows_forward,
            cols_forward,
            rows_inverse,
            cols_inverse,
            grid: vec![Complex::default(); tw * th],
            transposed: vec![Complex::default(); tw * th],
            scratch: vec![Complex::default(); scratch_len],
        }
    }

    /// Window width and height this correlator was planned for.
    pub fn window(&self) -> [usize; 2] {
        [self.w, self.h]
    }

    /// Add the correlation plane of windows `a` and `b` (row-major `w × h`, preferably
    /// mean-free) to `plane` (`w × h`, shifted order), scaled by `weight`. Returns `Σa²·Σb²`.
    pub fn accumulate(&mut self, a: &[f32], b: &[f32], plane: &mut [f64], weight: f64) -> f64 {
        let (w, h, tw, th) = (self.w, self.h, self.tw, self.th);
        debug_assert!(a.len() >= w * h && b.len() >= w * h && plane.len() >= w * h);
        let (mut ea, mut eb) = (0.0f64, 0.0f64);
        self.grid.fill(Complex::default());
        for y in 0..h {
            let row = &mut self.grid[y * tw..y * tw + w];
            for (x, z) in row.iter_mut().enumerate() {
                let (va, vb) = (a[y * w + x], b[y * w + x]);
                ea += (va * va) as f64;
                eb += (vb * vb) as f64;
                *z = Complex::new(va, vb);
            }
        }
        // Forward: rows, transpose, rows of the transpose (= columns).
        self.rows_forward
            .process_with_scratch(&mut self.grid[..tw * h], &mut self.scratch);
        transpose(&self.grid, &mut self.transposed, tw, th);
        self.cols_forward
            .process_with_scratch(&mut self.transposed, &mut self.scratch);
        // Z = A + iB with A, B the spectra of the real windows: A(k) = (Z(k) + Z*(−k))/2,
        // B(k) = (Z(k) − Z*(−k))/(2i). Cross spectrum conj(A)·B, in the transposed layout
        // (index kx·th + ky).
        let z = &self.transposed;
        for kx in 0..tw {
            let nkx = (tw - kx) % tw;
            for ky in 0..th {
                let nky = (th - ky) % th;
                let zk = z[kx * th + ky];
                let zc = z[nkx * th + nky].conj();
                let fa = (zk + zc) * 0.5;
                let d = (zk - zc) * 0.5;
                let fb = Complex::new(d.im, -d.re);
                self.grid[kx * th + ky] = fa.conj() * fb;
            }
        }
        // Inverse: columns (in the transposed layout), transpose back, rows.
        self.cols_inverse
            .process_with_scratch(&mut self.grid, &mut self.scratch);
        transpose(&self.grid, &mut self.transposed, th, tw);
        self.rows_inverse
            .process_with_scratch(&mut self.transposed, &mut self.scratch);
        let energy = ea * eb;
        if energy <= 0.0 {
            return energy;
        }
        let scale = weight / ((tw * th) as f64 * energy.sqrt());
        let (hw, hh) = (w / 2, h / 2);
        for row in 0..h {
            let sy = (row + th - hh) % th;
            for col in 0..w {
                let sx = (col + tw - hw) % tw;
                plane[row * w + col] += self.transposed[sy * tw + sx].re as f64 * scale;
            }
        }
        energy
    }
}

/// Transpose the row-major `rows × cols` matrix `src` into `dst` (`cols × rows`).
fn transpose(src: &[Complex<f32>], dst: &mut [Complex<f32>], cols: usize, rows: usize) {
    const BLOCK: usize = 16;
    for r0 in (0..rows).step_by(BLOCK) {
        for c0 in (0..cols).step_by(BLOCK) {
            for r in r0..(r0 + BLOCK).min(rows) {
                for c in c0..(c0 + BLOCK).min(cols) {
                    dst[c * rows + r] = src[r * cols + c];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Plain spatial-domain correlation, shifted order, circular or linear.
    fn direct(a: &[f32], b: &[f32], w: usize, h: usize, circular: bool) -> Vec<f64> {
        let mut plane = vec![0.0; w * h];
        let (ea, eb): (f64, f64) = (
            a.iter().map(|&v| (v * v) as f64).sum(),
            b.iter().map(|&v| (v * v) as f64).sum(),
        );
        for row in 0..h {
            for col in 0..w {
                let (sx, sy) = (col as i64 - (w / 2) as i64, row as i64 - (h / 2) as i64);
                let mut s = 0.0;
                for y in 0..h as i64 {
                    for x in 0..w as i64 {
                        let (mut xb, mut yb) = (x + sx, y + sy);
                        if circular {
                            xb = xb.rem_euclid(w as i64);
                            yb = yb.rem_euclid(h as i64);
                        } else if xb < 0 || yb < 0 || xb >= w as i64 || yb >= h as i64 {
                            continue;
                        }
                        s += a[(y * w as i64 + x) as usize] as f64
                            * b[(yb * w as i64 + xb) as usize] as f64;
                    }
                }
                plane[row * w + col] = s / (ea * eb).sqrt();
            }
        }
        plane
    }

    fn pattern(w: usize, h: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        (0..w * h)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 33) as f32 / (1u64 << 31) as f32) - 0.5
            })
            .collect()
    }

    #[test]
    fn fft_planes_equal_direct_sums_for_both_kinds() {
        for &(w, h) in &[(8usize, 8usize), (12, 6), (16, 10)] {
            let (a, b) = (pattern(w, h, 1), pattern(w, h, 2));
            for (kind, circular) in [
                (CorrelationKind::Circular, true),
                (CorrelationKind::Linear, false),
            ] {
                let mut c = Correlator::new(w, h, kind);
                let mut plane = vec![0.0; w * h];
                c.accumulate(&a, &b, &mut plane, 1.0);
                let reference = direct(&a, &b, w, h, circular);
                for (p, r) in plane.iter().zip(&reference) {
                    assert!((p - r).abs() < 1e-5, "{w}×{h} {kind:?}: {p} vs {r}");
                }
            }
        }
    }

    #[test]
    fn peak_sits_at_the_shift_that_carries_a_onto_b() {
        let (w, h) = (16, 16);
        let big = pattern(32, 32, 7);
        // b(x) = a(x − d) with d = (3, −2): b's window starts 3 left, 2 below of a's.
        let a: Vec<f32> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x + 8, y + 8)))
            .map(|(x, y)| big[y * 32 + x])
            .collect();
        let b: Vec<f32> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x + 8 - 3, y + 8 + 2)))
            .map(|(x, y)| big[y * 32 + x])
            .collect();
        let mut c = Correlator::new(w, h, CorrelationKind::Linear);
        let mut plane = vec![0.0; w * h];
        c.accumulate(&a, &b, &mut plane, 1.0);
        let best = (0..w * h)
            .max_by(|&i, &j| plane[i].total_cmp(&plane[j]))
            .unwrap();
        assert_eq!(
            (best % w) as i64 - 8,
            3,
            "x shift, plane row {:?}",
            best / w
        );
        assert_eq!((best / w) as i64 - 8, -2);
    }

    #[test]
    fn empty_windows_leave_the_plane_untouched() {
        let mut c = Correlator::new(8, 8, CorrelationKind::Circular);
        let mut plane = vec![0.0; 64];
        let energy = c.accumulate(&[0.0; 64], &pattern(8, 8, 3), &mut plane, 1.0);
        assert_eq!(energy, 0.0);
        assert!(plane.iter().all(|&p| p == 0.0));
    }
}
