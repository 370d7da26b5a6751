//! FFT kernel: zero-padded linear correlation in the Fourier domain. The cross-spectra of all
//! slices are summed and transformed back once (ensemble correlation, Meinhart et al. 2000;
//! linear FFT correlation, Raffel et al. 2018 §5.3).
//!
//! The padded size `N ≥ W + r` per axis is enough for the lags `|Δ| ≤ r` to be free of
//! wrap-around. Slices are sparse, so each image's spectrum along x is a direct DFT of its
//! voxels (one twiddle per voxel and frequency) followed by column FFTs; the window mean is
//! removed in the Fourier domain by subtracting `mean × spectrum(window indicator)`.

use std::sync::Arc;

use realfft::{ComplexToReal, RealFftPlanner};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use super::voxels::{Overlap, PlaneShape, SliceStats, SubVolume, Voxels};

/// Smallest even length `≥ n` whose only prime factors are 2, 3 and 5.
fn smooth_even(n: usize) -> usize {
    let mut m = n.max(2);
    loop {
        let mut r = m;
        for p in [2, 3, 5] {
            while r % p == 0 {
                r /= p;
            }
        }
        if r == 1 && m % 2 == 0 {
            return m;
        }
        m += 1;
    }
}

/// FFT plans and buffers for one [`PlaneShape`]. Spectra are stored column-major:
/// `(nx/2 + 1)` columns of `ny` complex values.
pub(super) struct Fourier {
    shape: PlaneShape,
    nx: usize,
    ny: usize,
    columns_forward: Arc<dyn Fft<f64>>,
    columns_inverse: Arc<dyn Fft<f64>>,
    rows_inverse: Arc<dyn ComplexToReal<f64>>,
    /// `exp(−2πi k/nx)`, k in `0..nx`.
    twiddle: Vec<Complex<f64>>,
    window_spectrum: Vec<Complex<f64>>,
    spectrum_a: Vec<Complex<f64>>,
    spectrum_b: Vec<Complex<f64>>,
    sum: Vec<Complex<f64>>,
    fft_scratch: Vec<Complex<f64>>,
    row_in: Vec<Complex<f64>>,
    row_out: Vec<f64>,
    row_scratch: Vec<Complex<f64>>,
}

impl Fourier {
    /// Padded transform size `[nx, ny]` for `shape`.
    pub fn size(shape: PlaneShape) -> [usize; 2] {
        [
            smooth_even(shape.w + shape.rx),
            smooth_even(shape.h + shape.ry),
        ]
    }

    pub fn new(shape: PlaneShape) -> Self {
        let [nx, ny] = Fourier::size(shape);
        let mut planner = FftPlanner::new();
        let columns_forward = planner.plan_fft_forward(ny);
        let columns_inverse = planner.plan_fft_inverse(ny);
        let rows_inverse = RealFftPlanner::new().plan_fft_inverse(nx);
        let scratch_len = columns_forward
            .get_inplace_scratch_len()
            .max(columns_inverse.get_inplace_scratch_len());
        let bins = (nx / 2 + 1) * ny;
        let twiddle = (0..nx)
            .map(|k| Complex::from_polar(1.0, -2.0 * std::f64::consts::PI * k as f64 / nx as f64))
            .collect();
        let mut fourier = Fourier {
            shape,
            nx,
            ny,
            row_scratch: rows_inverse.make_scratch_vec(),
            columns_forward,
            columns_inverse,
            rows_inverse,
            twiddle,
            window_spectrum: vec![Complex::default(); bins],
            spectrum_a: vec![Complex::default(); bins],
            spectrum_b: vec![Complex::default(); bins],
            sum: vec![Complex::default(); bins],
            fft_scratch: vec![Complex::default(); scratch_len],
            row_in: vec![Complex::default(); nx / 2 + 1],
            row_out: vec![0.0; nx],
        };
        let window = Voxels {
            x: (0..shape.w * shape.h)
                .map(|i| (i % shape.w) as u16)
                .collect(),
            y: (0..shape.w * shape.h)
                .map(|i| (i / shape.w) as u16)
                .collect(),
            v: vec![1.0; shape.w * shape.h],
            start: vec![0, shape.w * shape.h],
            slice_events: vec![0],
            unit: true,
        };
        let mut spectrum = std::mem::take(&mut fourier.window_spectrum);
        fourier.forward(window.all(), 0, 0.0, &mut spectrum);
        fourier.window_spectrum = spectrum;
        fourier
    }

    /// Spectrum of slice `z` of `vox` minus `mean` over the window, into `out`.
    fn forward(&mut self, sub: SubVolume<'_>, z: usize, mean: f64, out: &mut [Complex<f64>]) {
        let (nx, ny) = (self.nx, self.ny);
        let vox = sub.vox;
        out.fill(Complex::default());
        for i in sub.range(z) {
            let (x, y, v) = (vox.x[i] as usize, vox.y[i] as usize, vox.v[i]);
            let mut phase = 0usize;
            for kx in 0..=nx / 2 {
                out[kx * ny + y] += self.twiddle[phase] * v;
                phase += x;
                if phase >= nx {
                    phase -= nx;
                }
            }
        }
        self.columns_forward
            .process_with_scratch(out, &mut self.fft_scratch);
        if mean != 0.0 {
            for (o, w) in out.iter_mut().zip(&self.window_spectrum) {
                *o -= w * mean;
            }
        }
    }

    /// Fill `plane` with the normalised correlation of the slices in `stats`.
    pub fn correlate(
        &mut self,
        a: SubVolume<'_>,
        b: SubVolume<'_>,
        stats: &[SliceStats],
        overlap: &Overlap,
        plane: &mut [f64],
    ) {
        let mut spectrum_a = std::mem::take(&mut self.spectrum_a);
        let mut spectrum_b = std::mem::take(&mut self.spectrum_b);
        self.sum.fill(Complex::default());
        for s in stats {
            self.forward(a, s.z, s.mean_a, &mut spectrum_a);
            self.forward(b, s.z, s.mean_b, &mut spectrum_b);
            for ((acc, fa), fb) in self.sum.iter_mut().zip(&spectrum_a).zip(&spectrum_b) {
                *acc += fa.conj() * fb * s.weight;
            }
        }
        self.spectrum_a = spectrum_a;
        self.spectrum_b = spectrum_b;
        self.inverse(plane);
        overlap.normalise(plane, stats.len());
    }

    /// Inverse transform of the summed spectrum, cropped to the search lags.
    fn inverse(&mut self, plane: &mut [f64]) {
        let (nx, ny) = (self.nx, self.ny);
        let shape = self.shape;
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        self.columns_inverse
            .process_with_scratch(&mut self.sum, &mut self.fft_scratch);
        let scale = 1.0 / (nx * ny) as f64;
        for iy in 0..ph {
            let row = (iy as isize - shape.ry as isize).rem_euclid(ny as isize) as usize;
            for (kx, r) in self.row_in.iter_mut().enumerate() {
                *r = self.sum[kx * ny + row];
            }
            // The x-DC and Nyquist terms of a real image are real; drop rounding residue.
            self.row_in[0].im = 0.0;
            self.row_in[nx / 2].im = 0.0;
            let out = &mut plane[iy * pw..(iy + 1) * pw];
            if self
                .rows_inverse
                .process_with_scratch(&mut self.row_in, &mut self.row_out, &mut self.row_scratch)
                .is_err()
            {
                out.fill(f64::NAN);
                continue;
            }
            for (ix, o) in out.iter_mut().enumerate() {
                let col = (ix as isize - shape.rx as isize).rem_euclid(nx as isize) as usize;
                *o = self.row_out[col] * scale;
            }
        }
    }
}
