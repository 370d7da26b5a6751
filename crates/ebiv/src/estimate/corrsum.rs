//! Sum of correlation: an ensemble cross-correlation over time slices of the events of one
//! window (Willert & Klinner, Exp. Fluids 63:101, 2022, "sum of correlation" estimator;
//! `docs/algorithms.md` §5).
//!
//! Two sub-volumes of the window, `S1 = [t0 − T/2 − τ/2, t0 + T/2 − τ/2)` and
//! `S2 = [t0 − T/2 + τ/2, t0 + T/2 + τ/2)` around the field's centre time `t0`, are cut into
//! `N_T` slices of `T/N_T`; slice `z` of S2 is exactly τ later than slice `z` of S1, so its
//! particle images are displaced by `v·τ`. The occupancy images of each slice pair are
//! cross-correlated and the planes summed over slices (the event analogue of ensemble
//! correlation, Meinhart, Wereley & Santiago 2000, J. Fluids Eng. 122:285); the peak gives the
//! displacement `Δ` and `v = Δ/τ`.
//!
//! Unlike the reference code (algorithms.md §5.3) the correlation here is the zero-padded
//! *linear* correlation normalised by the overlap area of every lag (Raffel et al., "Particle
//! Image Velocimetry", 3rd ed., 2018, §5.3: no bias toward zero displacement), each slice is
//! normalised by its own standard deviations so the summed plane, averaged over the slices
//! with data, reads as a correlation coefficient; empty windows are NaN with a status, a
//! peak without enough evidence of its own is flagged (too few coincident voxel pairs behind
//! it, too little contrast over the plane, or absent from the plane of one half of the
//! slices: [`MIN_PEAK_PAIRS`], [`MIN_PEAK_CONTRAST`], [`MIN_HALF_CONSISTENCY`]), a
//! predictor gives a symmetric discrete window offset (Westerweel, Dabiri & Gharib 1997,
//! Exp. Fluids 23:20), and the peak ratio is reported. Two kernels compute the same plane: a
//! direct sum over voxel pairs (fast for the sparse windows typical of EBIV) and an FFT path
//! that sums the slices' cross-spectra and transforms back once.

mod direct;
mod fit;
mod fourier;
mod uncertainty;
mod voxels;

use serde::{Deserialize, Serialize};

use super::{Estimator, Prediction, WindowEstimate};
use crate::deform::events::Deformation;
use crate::error::{Error, Result};
use crate::field::Status;
use crate::grid::Window;
use crate::peak::{argmax, find_peak_within, peak_at, SubPixelFit};
use crate::volume::{Slab, TileRun, TileVisitor, WindowEvents};
use fit::{refine_with_kernel, SmoothingKernel};
use fourier::Fourier;
use voxels::{slice_statistics, Overlap, PlaneShape, SliceStats, SubVolume, Voxeliser, Voxels};

/// How the correlation plane is computed; all kernels give the same plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CorrKernel {
    /// Direct accumulation for sparse windows, FFT for dense ones, chosen per window from the
    /// number of voxel pairs.
    #[default]
    Auto,
    /// Zero-padded FFT: cross-spectra of all slices summed, one inverse transform.
    Fft,
    /// Sum over the voxel pairs of each slice with a lag inside the search radius.
    Direct,
}

/// Value of a voxel (pixel × time slice) in the occupancy images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Weighting {
    /// 1 if the voxel holds any event (the paper's binary occupancy).
    #[default]
    Binary,
    /// The number of events in the voxel.
    Count,
}

/// Parameters of [`SumOfCorrelation`]. Defaults are the reference implementation's
/// (`ebiv_params.cfg`: T = 10 ms, τ = 3 ms, 20 slices).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CorrSumParams {
    /// Length T of each sub-volume, µs.
    pub slab_us: i64,
    /// Delay τ between the two sub-volumes, µs.
    pub tau_us: i64,
    /// Number N_T of time slices per sub-volume.
    pub slices: u32,
    /// Correlation kernel.
    pub kernel: CorrKernel,
    /// Sub-pixel peak estimator. Default: the 2-D Gaussian, because the summed peak is
    /// elongated along the motion (a pixel stays active over several slices while a particle
    /// image crosses it), and axis-wise 3-point fits of a tilted elongated peak are biased
    /// (up to 0.3 px for oblique motion in the tests).
    pub fit: SubPixelFit,
    /// Voxel value: binary occupancy or event count.
    pub weighting: Weighting,
    /// Minimum mean number of events per sub-volume, `(n1 + n2)/2`; fewer gives
    /// [`Status::FEW_EVENTS`].
    pub min_events: u32,
    /// Largest displacement searched from the window offset, px per axis; `None`: a third of
    /// the window (clamped to 1 … window size − 1), the search limit PIVlab applies on its
    /// refinement passes. Beyond it the overlap normalisation amplifies "ghost" peaks of
    /// unrelated particle pairs (up to 4× at the corners of a half-window search) and the
    /// ¼-rule of PIV says the true peak is weak anyway; a larger displacement is better met
    /// with a first pass on larger windows. A peak on the border of the search region is
    /// flagged [`Status::OUT_OF_RANGE`].
    pub search_radius_px: Option<u32>,
    /// Standard deviation, px, of the Gaussian that smooths the summed plane around its
    /// maximum before the sub-pixel fit, against peak locking (0: no smoothing). Default
    /// 1 px: on simulated uniform flows with half-pixel displacements it lowers the RMS error
    /// by about 20 % (and raises it by about 10 % for whole-pixel ones, which lock by luck).
    pub peak_smoothing_px: f64,
    /// With a predictor, keep event positions sub-pixel instead of rounding them to pixels:
    /// S1 and S2 are gathered from windows moved by `∓round(d/2)` for the predicted
    /// displacement `d`, every (deformed) event is moved by the rest, `±(d/2 − round(d/2))`,
    /// and its voxel is spread over the 3 × 3 pixels around its position with weights that
    /// keep its sub-pixel position and add no skew (`voxels::shift_taps`): the occupancy
    /// images are resampled as symmetric PIV window deformation resamples its images
    /// (Scarano 2002, Meas. Sci. Technol. 13:R1), and the correlation peak sits at the
    /// residual displacement, which the repeated last pass drives towards zero. Off
    /// (default): a discrete window offset, and deformed events rounded to their nearest
    /// pixel.
    ///
    /// Measured (simulated gen4 scenes of `tests/estimators.rs`, 64 → 32 px): on the
    /// turntable the rounding of the deformed positions is most of the error, RMS 0.0273 →
    /// 0.0161 px/ms (DVR 116 → 196; removing only the sub-pixel part of `d` from the plane of
    /// rounded events gave 0.030); a uniform flow of (2.17, 0.83) px/ms 0.0215 → 0.0185; the
    /// Lamb–Oseen vortex 0.260 → 0.245. Not the default because of its cost: the spread
    /// voxels multiply the voxel pairs (the FFT kernel takes over in most windows), about
    /// twice the instructions of such a multi-pass run (callgrind).
    pub subpixel_shift: bool,
}

impl Default for CorrSumParams {
    fn default() -> Self {
        CorrSumParams {
            slab_us: 10_000,
            tau_us: 3_000,
            slices: 20,
            kernel: CorrKernel::Auto,
            fit: SubPixelFit::Gaussian2d,
            weighting: Weighting::Binary,
            min_events: 10,
            search_radius_px: None,
            peak_smoothing_px: 1.0,
            subpixel_shift: false,
        }
    }
}

/// Longest sub-volume: local event times are `f32` µs, exact up to 2²⁴ µs.
const MAX_SLAB_US: i64 = 16_000_000;
/// Widest smoothing of the plane before the peak fit, px.
const MAX_PEAK_SMOOTHING_PX: f64 = 5.0;
/// Most slices per sub-volume (slices of T/1000, 10 µs at T = 10 ms; the paper uses 20). The
/// per-thread occupancy bitmaps (and, with count weighting, counts) grow with slices × window
/// area.
const MAX_SLICES: u32 = 1000;

impl CorrSumParams {
    /// The same parameters for a slab of `slab_us`, with the delay τ in the same proportion
    /// to the slab (an adaptive slab, [`crate::estimate::adaptive`]), and at least one slice
    /// long so that paired slices never share events.
    pub fn with_slab(self, slab_us: i64) -> Self {
        let ratio = self.tau_us as f64 / self.slab_us.max(1) as f64;
        let slice_us = (slab_us + self.slices as i64 - 1) / self.slices.max(1) as i64;
        let tau_us = ((slab_us as f64 * ratio).round() as i64)
            .max(slice_us)
            .min(slab_us);
        CorrSumParams {
            slab_us,
            tau_us,
            ..self
        }
    }

    /// Reject parameters that cannot give a meaningful correlation.
    pub fn validate(&self) -> Result<()> {
        let (t, tau, n) = (self.slab_us, self.tau_us, self.slices);
        if t <= 0 || t > MAX_SLAB_US {
            return Err(Error::parameter(
                "slab",
                format!("must be between 1 µs and {MAX_SLAB_US} µs, got {t} µs"),
            ));
        }
        if n == 0 || n > MAX_SLICES {
            return Err(Error::parameter(
                "slices",
                format!("must be between 1 and {MAX_SLICES}, got {n}"),
            ));
        }
        if t < n as i64 {
            return Err(Error::parameter(
                "slices",
                format!("{n} slices of a {t} µs slab are shorter than 1 µs; use fewer slices"),
            ));
        }
        if tau <= 0 {
            return Err(Error::parameter(
                "tau",
                format!("the delay must be positive, got {tau} µs"),
            ));
        }
        if tau > t {
            return Err(Error::parameter(
                "tau",
                format!(
                    "the delay ({tau} µs) must not exceed the slab ({t} µs); the paper uses τ = 3 ms with T = 10 ms"
                ),
            ));
        }
        if tau * (n as i64) < t {
            return Err(Error::parameter(
                "tau",
                format!(
                    "the delay ({tau} µs) is shorter than one slice ({} µs): paired slices would share events and correlate with themselves; use a longer delay or fewer slices",
                    t as f64 / n as f64
                ),
            ));
        }
        if !(0.0..=MAX_PEAK_SMOOTHING_PX).contains(&self.peak_smoothing_px) {
            return Err(Error::parameter(
                "peak-smoothing",
                format!(
                    "must be between 0 (off) and {MAX_PEAK_SMOOTHING_PX} px, got {}",
                    self.peak_smoothing_px
                ),
            ));
        }
        if self.search_radius_px == Some(0) {
            return Err(Error::parameter("search-radius", "must be at least 1 px"));
        }
        Ok(())
    }
}

/// Exclusion half-width around the first peak when searching the second, px (OpenPIV's 2).
const EXCLUSION_PX: usize = 2;

/// The sum-of-correlation estimator (Willert & Klinner 2022), see the module documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct SumOfCorrelation {
    params: CorrSumParams,
    /// The peak smoothing kernel of `params.peak_smoothing_px`.
    smoothing: SmoothingKernel,
}

impl SumOfCorrelation {
    /// An estimator with validated parameters.
    pub fn new(params: CorrSumParams) -> Result<Self> {
        params.validate()?;
        let smoothing = SmoothingKernel::new(params.peak_smoothing_px);
        Ok(SumOfCorrelation { params, smoothing })
    }

    /// The parameters.
    pub fn params(&self) -> &CorrSumParams {
        &self.params
    }

    /// Search radius per axis for a window of `[width, height]` px.
    fn radius(&self, window: [u32; 2]) -> [usize; 2] {
        window.map(|w| {
            let limit = (w as usize).saturating_sub(1).max(1);
            let r = self
                .params
                .search_radius_px
                .map_or(w as usize / 3, |r| r as usize);
            r.clamp(1, limit)
        })
    }

    /// The slab T every estimate records: the length of each sub-volume, µs (validated to
    /// 1 µs … [`MAX_SLAB_US`], so it fits).
    fn slab_us(&self) -> u32 {
        self.params.slab_us as u32
    }

    /// Half the time extent, `⌈(T + τ)/2⌉` µs.
    fn half_extent_us(&self) -> i64 {
        (self.params.slab_us + self.params.tau_us + 1) / 2
    }

    /// Slices of the delay τ when it is a whole number of slices `T/N_T` (the reference
    /// settings: τ = 3 ms = 6 slices of 0.5 ms), so that slice `z` of S2 is slice `z + k` of
    /// a voxelisation of `[S1 start, S2 end)`.
    fn delay_in_slices(&self) -> Option<usize> {
        let p = &self.params;
        let scaled = p.tau_us * p.slices as i64;
        (scaled % p.slab_us == 0).then(|| (scaled / p.slab_us) as usize)
    }

    /// Voxelise S1 and S2 of `window`'s events around `t0_us`, with the integer window
    /// offset `[s1, s2]` per axis, the sub-pixel shift and the deformation, if any (see
    /// [`SumOfCorrelation::correlation_plane`]), into `scratch.voxels`. Returns the delay in
    /// slices when both sub-volumes come from one voxelisation ([`sub_volumes`]).
    fn voxelise(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        (offsets, shift): ([[i64; 2]; 2], Option<[f32; 2]>),
        deformation: Option<Deformation>,
        scratch: &mut CorrSumScratch,
    ) -> Option<usize> {
        let p = &self.params;
        let s1_start = t0_us - self.half_extent_us();
        let s2_start = s1_start + p.tau_us;
        let count = p.weighting == Weighting::Count;
        let slices = p.slices as usize;
        // Without a window offset both sub-volumes cover the same pixels: one voxelisation of
        // `[S1 start, S2 end)` serves both (S1 and S2 overlap by T − τ).
        let shared = self
            .delay_in_slices()
            .filter(|_| offsets == [[0; 2]; 2] && shift.is_none());
        if let Some(k) = shared {
            let times = (s1_start, s2_start + p.slab_us);
            let bin = (p.slab_us + p.tau_us, slices + k);
            scratch.bin(
                slab,
                window,
                times,
                bin,
                count,
                deformation.as_ref(),
                None,
                0,
            );
        } else {
            // With the sub-pixel shift S1's events move forward by half the predicted
            // displacement's rest, S2's back by it.
            let rest = |sign: f32| shift.map(|a| a.map(|v| sign * v));
            let windows = [
                (
                    window.shifted(-offsets[0][0], -offsets[0][1]),
                    s1_start,
                    rest(1.0),
                ),
                (
                    window.shifted(offsets[1][0], offsets[1][1]),
                    s2_start,
                    rest(-1.0),
                ),
            ];
            for (k, (w, start, rest)) in windows.into_iter().enumerate() {
                let times = (start, start + p.slab_us);
                let bin = (p.slab_us, slices);
                scratch.bin(slab, &w, times, bin, count, deformation.as_ref(), rest, k);
            }
        }
        shared
    }

    /// Compute the normalised, summed correlation plane of `window`'s events around `t0_us`
    /// with the integer window offset `[s1, s2]` per axis (S1 window moved by `−s1`, S2 by
    /// `+s2`) and, if given, the sub-pixel shift of the events (S1 by `+a`, S2 by `−a`,
    /// [`CorrSumParams::subpixel_shift`]) into `scratch.plane`, and return the event count
    /// and the index of the plane's maximum (`None`: no value above −∞), or the window's
    /// invalid estimate. The maxima of the plane's rows are left in `scratch.accumulators`.
    fn correlation_plane(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        (offsets, shift): ([[i64; 2]; 2], Option<[f32; 2]>),
        predictor: Option<&Prediction>,
        scratch: &mut CorrSumScratch,
    ) -> std::result::Result<(u32, Option<usize>), WindowEstimate> {
        let p = &self.params;
        let deformation = predictor.and_then(|p| p.deformation);
        let shared = self.voxelise(slab, window, t0_us, (offsets, shift), deformation, scratch);
        scratch.shared = shared;
        let (a, b) = sub_volumes(&scratch.voxels, shared, p.slices as usize);
        let (n1, n2) = (a.events(), b.events());
        let events = u32::try_from((n1 + n2) / 2).unwrap_or(u32::MAX);
        if n1 == 0 || n2 == 0 {
            return Err(WindowEstimate::invalid(
                Status::NO_EVENTS,
                events,
                self.slab_us(),
            ));
        }
        if events < p.min_events {
            return Err(WindowEstimate::invalid(
                Status::FEW_EVENTS,
                events,
                self.slab_us(),
            ));
        }
        let shape = scratch.shape;
        slice_statistics(a, b, shape, &mut scratch.stats);
        if scratch.stats.is_empty() {
            return Err(WindowEstimate::invalid(
                Status::NO_PEAK,
                events,
                self.slab_us(),
            ));
        }
        let use_fft = match p.kernel {
            CorrKernel::Fft => true,
            CorrKernel::Direct => false,
            CorrKernel::Auto => {
                let pairs: usize = scratch.stats.iter().map(|s| a.len(s.z) * b.len(s.z)).sum();
                direct_is_slower(pairs, scratch.stats.len(), shape)
            }
        };
        // The plane of each half of the slices with data (earlier and later), combined into
        // the plane of all of them in proportion to their slices: the halves are the
        // evidence test of [`SumOfCorrelation::consistent`].
        let n = scratch.stats.len();
        let k = n / 2;
        let parts: [std::ops::Range<usize>; 2] = if k == 0 { [0..n, n..n] } else { [0..k, k..n] };
        for (h, part) in parts.iter().enumerate() {
            if part.is_empty() {
                continue;
            }
            let stats = &scratch.stats[part.clone()];
            let out = &mut scratch.halves[h];
            if use_fft {
                let fourier = scratch.fourier.get_or_insert_with(|| Fourier::new(shape));
                fourier.correlate(a, b, stats, &scratch.overlap, out);
            } else {
                direct::correlate(
                    a,
                    b,
                    stats,
                    shape,
                    &scratch.overlap,
                    out,
                    &mut scratch.accumulators,
                );
            }
        }
        scratch.split = k > 0;
        if k == 0 {
            scratch.plane.copy_from_slice(&scratch.halves[0]);
        } else {
            let (w0, w1) = (k as f64 / n as f64, (n - k) as f64 / n as f64);
            for ((p, &x0), &x1) in scratch
                .plane
                .iter_mut()
                .zip(&scratch.halves[0])
                .zip(&scratch.halves[1])
            {
                *p = w0 * x0 + w1 * x1;
            }
        }
        let width = shape.plane_width();
        scratch.accumulators.find_row_maxima(&scratch.plane, width);
        let best = argmax(&scratch.plane);
        Ok((events, best))
    }
}

impl SumOfCorrelation {
    /// The window's own evidence for the displacement `d` (px over τ) of the peak it found:
    /// its events, neither shifted nor deformed, correlated over τ/2 (and, around a
    /// prediction, over τ) at a few single lags ([`direct::correlations_at`]).
    /// `Some(LOW_PEAK_RATIO)` when it fails the test that applies:
    /// - **half delay**, without a prediction: a displacement grows with the delay, so over
    ///   τ/2 the events must correlate at `d/2` at least [`MIN_HALF_DELAY_SUPPORT`] times as
    ///   well as over τ at `d` (the highest of the four lags around each; over τ, the plane
    ///   itself). A true peak passes easily, as the images decorrelate less over the shorter
    ///   delay; a peak of chance alignments of particle streaks (a displacement beyond the
    ///   search radius leaves nothing else) has nothing at half its lag. Around a prediction
    ///   the plane was made of shifted and usually deformed events, whose unshifted,
    ///   undeformed correlation says little in a strong gradient, and the test is not made;
    /// - **at rest**, around a prediction, for a displacement of half a pixel or more: the
    ///   events must not correlate [`AT_REST_MARGIN`] times better at zero lag than at the
    ///   best of the four lags around the displacement other than zero lag, both above the
    ///   zero of unrelated lags. Else the prediction was wrong for this window (a coarser
    ///   pass's window that reached into faster flow, as beside a shear layer), and the peak
    ///   near it is a ridge of the events that the wrong prediction shears. Over τ/2 the
    ///   same must hold at `d/2` where that is a pixel or more from rest: over τ a strong
    ///   gradient alone may decorrelate the undeformed events. A delay whose lags around the
    ///   displacement leave less than a quarter of the window overlapping says nothing, and
    ///   the test is not made. Pixels that fire all through the slab (hot pixels) raise the
    ///   correlation at rest at both delays, so that many of them in a window can flag a
    ///   correct prediction.
    ///
    /// Over τ/2 a slice of S1 and the matching slice of S2 must not share events: where
    /// τ/2 is shorter than a slice, only τ is used (the half-delay test passes).
    fn own_evidence(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        d: [f64; 2],
        predicted: bool,
        scratch: &mut CorrSumScratch,
    ) -> Option<Status> {
        if d.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let failed = if predicted {
            d[0].hypot(d[1]) >= 0.5 && self.rests_better(slab, window, t0_us, d, scratch)
        } else {
            self.half_delay_unsupported(slab, window, t0_us, d, scratch)
        };
        failed.then_some(Status::LOW_PEAK_RATIO)
    }

    /// The half-delay test of [`SumOfCorrelation::own_evidence`], right after the plane of a
    /// pass without prediction: S1 (and S2, if one voxelisation holds both) are still in
    /// `scratch.voxels`, and the plane holds the correlation over τ.
    fn half_delay_unsupported(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        d: [f64; 2],
        scratch: &mut CorrSumScratch,
    ) -> bool {
        let p = &self.params;
        if !self.half_delay_spans_a_slice() {
            return false;
        }
        let slices = p.slices as usize;
        let shape = scratch.shape;
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        let cell = |[dx, dy]: [i64; 2]| {
            let col = (shape.rx as i64 + dx).clamp(0, pw as i64 - 1) as usize;
            let row = (shape.ry as i64 + dy).clamp(0, ph as i64 - 1) as usize;
            scratch.plane[row * pw + col]
        };
        let highest = around(d)
            .map(cell)
            .into_iter()
            .fold(f64::NEG_INFINITY, f64::max);
        if highest.is_nan() || highest <= 0.0 {
            return false;
        }
        // S1 as the plane's voxelisation left it; S2 after τ/2 from the same voxelisation
        // where the delay is an even number of slices, else binned into the third voxels.
        let shared = self.delay_in_slices();
        let even = shared.filter(|k| k % 2 == 0);
        if even.is_none() {
            let start = t0_us - self.half_extent_us() + p.tau_us / 2;
            self.bin_undeformed(slab, window, start, 2, scratch);
        }
        let (a, _) = sub_volumes(&scratch.voxels, shared, slices);
        let half = match even {
            Some(k) => scratch.voxels[0].sub_volume(k / 2, slices),
            None => scratch.voxels[2].all(),
        };
        let (stats, image) = (&mut scratch.stats, &mut scratch.image);
        slice_statistics(a, half, shape, stats);
        let mut values = [0.0; 4];
        direct::correlations_at(
            (a, half),
            stats,
            shape,
            &around(d.map(|v| v / 2.0)),
            image,
            &mut values,
        );
        let highest_half = values.into_iter().fold(f64::NEG_INFINITY, f64::max);
        highest_half < MIN_HALF_DELAY_SUPPORT * highest
    }

    /// The at-rest test of [`SumOfCorrelation::own_evidence`]: the window's events, binned
    /// again neither shifted nor deformed.
    fn rests_better(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        d: [f64; 2],
        scratch: &mut CorrSumScratch,
    ) -> bool {
        let p = &self.params;
        let slices = p.slices as usize;
        let count = p.weighting == Weighting::Count;
        let s1_start = t0_us - self.half_extent_us();
        // S1, S2 and S2 after half the delay: three runs of one voxelisation where the
        // delay is an even number of slices, else three voxelisations.
        let runs = match self.delay_in_slices().filter(|k| k % 2 == 0) {
            Some(k) => {
                let times = (s1_start, s1_start + p.tau_us + p.slab_us);
                let bin = (p.slab_us + p.tau_us, slices + k);
                scratch.bin(slab, window, times, bin, count, None, None, 0);
                [(0, 0), (0, k), (0, k / 2)]
            }
            None => {
                for (into, start) in [s1_start, s1_start + p.tau_us, s1_start + p.tau_us / 2]
                    .into_iter()
                    .enumerate()
                {
                    self.bin_undeformed(slab, window, start, into, scratch);
                }
                [(0, 0), (1, 0), (2, 0)]
            }
        };
        let [a, full, half] = runs.map(|(i, first)| scratch.voxels[i].sub_volume(first, slices));
        let shape = scratch.shape;
        let (stats, image) = (&mut scratch.stats, &mut scratch.image);
        // Over one delay: zero lag against the best of the lags around `d` other than zero.
        let mut rests_over = |b, d: [f64; 2]| {
            // Too little overlap at the displacement: the comparison says nothing.
            let overlap = |[dx, dy]: [i64; 2]| {
                let share =
                    |lag: i64, n: usize| (1.0 - lag.unsigned_abs() as f64 / n as f64).max(0.0);
                share(dx, shape.w) * share(dy, shape.h)
            };
            let lags = around(d);
            if lags.into_iter().all(|lag| overlap(lag) < 0.25) {
                return None;
            }
            slice_statistics(a, b, shape, stats);
            let [l0, l1, l2, l3] = lags;
            let mut values = [0.0; 5];
            direct::correlations_at(
                (a, b),
                stats,
                shape,
                &[[0, 0], l0, l1, l2, l3],
                image,
                &mut values,
            );
            let rest = values[0];
            let moving = lags
                .iter()
                .zip(&values[1..])
                .filter(|(&lag, _)| lag != [0, 0])
                .fold(f64::NEG_INFINITY, |m, (_, &c)| m.max(c));
            Some(rest > 0.0 && rest >= AT_REST_MARGIN * moving.max(0.0))
        };
        let halved = d.map(|v| v / 2.0);
        let half_tells = self.half_delay_spans_a_slice() && halved[0].hypot(halved[1]) >= 1.0;
        match rests_over(full, d) {
            Some(true) if half_tells => rests_over(half, halved).unwrap_or(true),
            Some(rests) => rests,
            None => false,
        }
    }

    /// Standard uncertainty, px per axis, of the sub-pixel position of `peak` on the plane
    /// that [`SumOfCorrelation::correlation_plane`] left in `scratch`, from the sub-volumes
    /// it was computed from ([`uncertainty::peak_sigma`]).
    fn peak_uncertainty(&self, peak: &crate::peak::Peak, scratch: &mut CorrSumScratch) -> [f64; 2] {
        let (a, b) = sub_volumes(&scratch.voxels, scratch.shared, self.params.slices as usize);
        uncertainty::peak_sigma(
            (a, b),
            &scratch.stats,
            scratch.shape,
            &scratch.plane,
            peak,
            (&self.smoothing, self.params.fit),
            &mut scratch.image,
            &mut scratch.blocks,
        )
    }

    /// Bin the window's events of one sub-volume from `start`, neither shifted nor deformed,
    /// into `scratch.voxels[into]`.
    fn bin_undeformed(
        &self,
        slab: &Slab,
        window: &Window,
        start: i64,
        into: usize,
        scratch: &mut CorrSumScratch,
    ) {
        let p = &self.params;
        let count = p.weighting == Weighting::Count;
        let (times, bin) = ((start, start + p.slab_us), (p.slab_us, p.slices as usize));
        scratch.bin(slab, window, times, bin, count, None, None, into);
    }

    /// Whether τ/2 is at least one slice long, so that a slice of S1 and the matching slice
    /// of S2 after τ/2 hold different events.
    fn half_delay_spans_a_slice(&self) -> bool {
        let p = &self.params;
        p.tau_us * i64::from(p.slices) >= 2 * p.slab_us
    }
}

/// The four whole-pixel lags around the displacement `d`.
fn around(d: [f64; 2]) -> [[i64; 2]; 4] {
    let [x, y] = d.map(|v| v.floor() as i64);
    [[x, y], [x + 1, y], [x, y + 1], [x + 1, y + 1]]
}

/// How much better the window's events must correlate at rest than at the displacement
/// found around a prediction for the vector to be flagged ([`SumOfCorrelation`]'s test of
/// its prediction): the margin motion compensation asks of a maximum at zero velocity over a
/// moving one.
pub const AT_REST_MARGIN: f64 = 1.5;

/// Smallest correlation of the window's events over τ/2 at half the displacement found, as
/// a share of their correlation over τ at the displacement ([`SumOfCorrelation`]'s half-delay
/// test). On simulated uniform flows of 0.2–10 px/ms (`ebiv bench envelope`, 32 and 64 px
/// windows, T = 10 and 20 ms, one pass) the correct vectors gave 0.6–1.5 (median 1.2), the
/// grossly wrong ones, of flows beyond the search radius, −0.16–0.38.
pub const MIN_HALF_DELAY_SUPPORT: f64 = 0.5;

/// S1 and S2 as [`SumOfCorrelation::voxelise`] left them: two overlapping runs of `slices`
/// slices of the first voxelisation, `shared` slices apart, or one voxelisation each.
fn sub_volumes(
    voxels: &[Voxels],
    shared: Option<usize>,
    slices: usize,
) -> (SubVolume<'_>, SubVolume<'_>) {
    match shared {
        Some(k) => (
            voxels[0].sub_volume(0, slices),
            voxels[0].sub_volume(k, slices),
        ),
        None => (voxels[0].all(), voxels[1].all()),
    }
}

/// What supports a correlation peak beyond its height and ratio: the pairs of coincident
/// voxels behind it, its height over the plane's fluctuations, and whether the earlier and
/// the later half of the slices both show it ([`MIN_PEAK_PAIRS`], [`MIN_PEAK_CONTRAST`],
/// [`MIN_HALF_CONSISTENCY`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Evidence {
    /// Coincident voxel pairs the peak stands for, about: its correlation coefficient times
    /// the events per sub-volume times the overlap of the two windows at its lag (a share of
    /// the window). For sparse binary occupancy images a coefficient `r` at a lag means
    /// about `r·√(n₁n₂)` coinciding voxels, `n` the voxels of the overlapping parts.
    pairs: f64,
    /// Height of the peak over the plane's mean, in standard deviations of the plane.
    contrast: f64,
    /// The smaller of the two halves' [`consistency`].
    halves: f64,
}

/// Fewest coincident voxel pairs behind a valid peak (peak coefficient × events per
/// sub-volume × overlap share of the windows at the peak's lag); fewer: [`Status::FEW_EVENTS`].
/// A peak of a handful of chance coincidences is what a window gives when its particles move
/// less than a pixel over the slab or its events are few.
pub const MIN_PEAK_PAIRS: f64 = 12.0;
/// Smallest height of a valid peak over the plane's mean, in standard deviations of the
/// plane; lower: [`Status::LOW_PEAK_RATIO`]. A displacement beyond the search radius leaves a
/// plane of ridges of unrelated particle streaks, whose highest point stands out little.
pub const MIN_PEAK_CONTRAST: f64 = 5.0;
/// Smallest share of its own maximum that the plane of the earlier half of the slices, and
/// that of the later half, reach within one pixel of a valid peak; lower:
/// [`Status::LOW_PEAK_RATIO`]. A true displacement shows in both halves of the slab; chance
/// coincidences of a few events, or of unrelated particles, in one of them.
pub const MIN_HALF_CONSISTENCY: f64 = 0.5;

impl Evidence {
    fn of(
        scratch: &CorrSumScratch,
        [pw, ph]: [usize; 2],
        peak: &crate::peak::Peak,
        events: u32,
    ) -> Self {
        let plane = &scratch.plane;
        let n = plane.len() as f64;
        let mean = plane.iter().sum::<f64>() / n;
        let rms = (plane.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n).sqrt();
        let shape = scratch.shape;
        let overlap = scratch.overlap.area[peak.row * pw + peak.col] / (shape.w * shape.h) as f64;
        let c = consistency(scratch, [pw, ph], [peak.col, peak.row]);
        Evidence {
            pairs: peak.value * f64::from(events) * overlap,
            contrast: if rms > 0.0 {
                (peak.value - mean) / rms
            } else {
                f64::INFINITY
            },
            halves: c[0].min(c[1]),
        }
    }

    /// Why the peak is too weak to be a measurement, if it is.
    fn weak(&self) -> Option<Status> {
        if self.pairs < MIN_PEAK_PAIRS {
            Some(Status::FEW_EVENTS)
        } else if self.contrast < MIN_PEAK_CONTRAST || self.halves < MIN_HALF_CONSISTENCY {
            Some(Status::LOW_PEAK_RATIO)
        } else {
            None
        }
    }
}

/// How strongly each half of the slices supports the peak at `[col, row]` of the plane: the
/// highest value of the half's plane within one pixel of it over the half's own maximum
/// (1: the half peaks there too; near 0 or negative: the half shows nothing there). Both 1
/// without two halves.
fn consistency(scratch: &CorrSumScratch, [pw, ph]: [usize; 2], [col, row]: [usize; 2]) -> [f64; 2] {
    if !scratch.split {
        return [1.0; 2];
    }
    scratch.halves.each_ref().map(|half| {
        let top = half.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mut near = f64::NEG_INFINITY;
        for r in row.saturating_sub(1)..(row + 2).min(ph) {
            for c in col.saturating_sub(1)..(col + 2).min(pw) {
                near = near.max(half[r * pw + c]);
            }
        }
        if top > 0.0 {
            near / top
        } else {
            0.0
        }
    })
}

/// Auto kernel choice: direct costs about `PAIR_NS` per voxel pair, the FFT path about
/// `FFT_NS_PER_BIN` per padded half-spectrum bin and slice (relative costs measured with the
/// `timing` test of `tests/corrsum.rs`: for 40 px windows the FFT wins above roughly 2500
/// events per sub-volume, about 110 voxels per slice).
fn direct_is_slower(pairs: usize, valid_slices: usize, shape: PlaneShape) -> bool {
    const PAIR_NS: f64 = 1.0;
    const FFT_NS_PER_BIN: f64 = 10.0;
    let [nx, ny] = Fourier::size(shape);
    let bins = (nx / 2 + 1) * ny;
    pairs as f64 * PAIR_NS > valid_slices as f64 * bins as f64 * FFT_NS_PER_BIN
}

/// Columns and rows of the correlation plane to search for a peak within `radius_px` of the
/// predicted displacement: the plane's centre `[rx, ry]` is the predicted displacement
/// rounded to whole pixels (up to half a pixel off), and [`find_peak_within`] only takes
/// maxima strictly inside the box, so the box reaches `⌈radius + ½⌉ + 1` cells each way.
fn search_box(radius_px: f64, centre: [usize; 2]) -> [std::ops::Range<usize>; 2] {
    let half = if radius_px.is_finite() {
        (radius_px.abs() + 0.5).ceil().min(1e6) as usize + 1
    } else {
        usize::MAX / 4
    };
    centre.map(|c| c.saturating_sub(half)..c.saturating_add(half + 1))
}

/// Symmetric discrete window offset for a predicted displacement `d` px: S1 is gathered from
/// the window moved by `−s1`, S2 by `+s2`, `s1 = round(d/2)`, `s2 = round(d − s1)`, so the
/// residual `d − s1 − s2` is at most half a pixel.
fn window_offsets(predicted_px: [f64; 2]) -> [[i64; 2]; 2] {
    let mut s = [[0i64; 2]; 2];
    for axis in 0..2 {
        let d = predicted_px[axis];
        if !d.is_finite() {
            continue;
        }
        let d = d.clamp(-1e6, 1e6);
        let s1 = (d / 2.0).round();
        s[0][axis] = s1 as i64;
        s[1][axis] = (d - s1).round() as i64;
    }
    s
}

/// Symmetric split of a predicted displacement `d` px for [`CorrSumParams::subpixel_shift`]:
/// both windows move by `s = round(d/2)` (S1 by `−s`, S2 by `+s`) and the sub-pixel rest
/// `a = d/2 − s` (|a| ≤ ½) is added to S1's event positions and subtracted from S2's, so
/// that both occupancy images are resampled by the same fraction of a pixel and the removed
/// displacement is `2s + 2a = d` exactly.
fn symmetric_shift(predicted_px: [f64; 2]) -> ([[i64; 2]; 2], [f32; 2]) {
    let mut s = [[0i64; 2]; 2];
    let mut a = [0f32; 2];
    for axis in 0..2 {
        let half = predicted_px[axis].clamp(-1e6, 1e6) / 2.0;
        let whole = half.round();
        s[0][axis] = whole as i64;
        s[1][axis] = whole as i64;
        a[axis] = (half - whole) as f32;
    }
    (s, a)
}

impl Estimator for SumOfCorrelation {
    type Scratch = CorrSumScratch;

    fn name(&self) -> &'static str {
        "corrsum"
    }

    fn scratch(&self, window: [u32; 2]) -> CorrSumScratch {
        CorrSumScratch::new(window, self.radius(window), self.params.slices)
    }

    fn skip_uncertainty(&self, scratch: &mut CorrSumScratch, skip: bool) {
        scratch.skip_uncertainty = skip;
    }

    fn time_extent_us(&self) -> (i64, i64) {
        let e = self.half_extent_us();
        (e, e)
    }

    fn estimate(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        predictor: Option<&Prediction>,
        scratch: &mut CorrSumScratch,
    ) -> WindowEstimate {
        let size = [window.width, window.height];
        if scratch.window != size || scratch.slices != self.params.slices {
            let skip = scratch.skip_uncertainty;
            *scratch = self.scratch(size);
            scratch.skip_uncertainty = skip;
        }
        let tau_ms = self.params.tau_us as f64 / 1000.0;
        let predictor = predictor.filter(|p| p.velocity.iter().all(|v| v.is_finite()));
        let predicted_px = predictor.map(|p| p.velocity.map(|v| v * tau_ms));
        let (offsets, shift) = match predicted_px {
            Some(d) if self.params.subpixel_shift => {
                let (offsets, shift) = symmetric_shift(d);
                (offsets, Some(shift))
            }
            Some(d) => (window_offsets(d), None),
            None => ([[0; 2]; 2], None),
        };
        let plane =
            self.correlation_plane(slab, window, t0_us, (offsets, shift), predictor, scratch);
        let (events, best) = match plane {
            Ok(found) => found,
            Err(invalid) => return invalid,
        };
        let shape = scratch.shape;
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        let fit = self.params.fit;
        let peak = match predictor.and_then(|p| p.search_radius) {
            Some(radius) => {
                let [cols, rows] = search_box(radius * tau_ms, [shape.rx, shape.ry]);
                find_peak_within(&scratch.plane, pw, ph, fit, EXCLUSION_PX, cols, rows)
            }
            None => best.and_then(|i| {
                let rows = scratch.accumulators.row_maxima();
                peak_at(&scratch.plane, [pw, ph], i, fit, EXCLUSION_PX, Some(rows))
            }),
        };
        let Some(peak) = peak else {
            return WindowEstimate::invalid(Status::NO_PEAK, events, self.slab_us());
        };
        let mut result = WindowEstimate::invalid(Status::NO_PEAK, events, self.slab_us());
        result.peak = peak.value as f32;
        result.peak_ratio = peak.ratio() as f32;
        if peak.value.is_nan() || peak.value <= 0.0 {
            return result;
        }
        if peak.on_edge {
            result.status = Status::OUT_OF_RANGE;
            return result;
        }
        let evidence = Evidence::of(scratch, [pw, ph], &peak, events);
        if let Some(status) = evidence.weak() {
            result.status = status;
            return result;
        }
        let [px, py] = refine_with_kernel(&scratch.plane, [pw, ph], &peak, &self.smoothing, fit);
        // The displacement removed before correlating: the window offsets plus, with the
        // sub-pixel shift, twice the rest moved in each sub-volume.
        let removed = |axis: usize| {
            let rest = shift.map_or(0.0, |a| 2.0 * f64::from(a[axis]));
            (offsets[0][axis] + offsets[1][axis]) as f64 + rest
        };
        let dx = removed(0) + px - shape.rx as f64;
        let dy = removed(1) + py - shape.ry as f64;
        result.u = dx / tau_ms;
        result.v = dy / tau_ms;
        result.status = Status::VALID;
        // The uncertainty from the sub-volumes the plane was computed from, before the
        // evidence tests bin other ones.
        if !scratch.skip_uncertainty {
            let [su, sv] = self.peak_uncertainty(&peak, scratch);
            result.u_unc = (su / tau_ms) as f32;
            result.v_unc = (sv / tau_ms) as f32;
        }
        let predicted = predictor.is_some();
        if let Some(status) = self.own_evidence(slab, window, t0_us, [dx, dy], predicted, scratch) {
            result.status = status;
            result.u = f64::NAN;
            result.v = f64::NAN;
            result.u_unc = f32::NAN;
            result.v_unc = f32::NAN;
        }
        result
    }

    fn finds_secondary_peaks(&self) -> bool {
        true
    }

    fn parameters(&self) -> Vec<(String, String)> {
        let p = &self.params;
        let kernel = match p.kernel {
            CorrKernel::Auto => "auto",
            CorrKernel::Fft => "fft",
            CorrKernel::Direct => "direct",
        };
        let fit = match p.fit {
            SubPixelFit::Gaussian3 => "gauss3",
            SubPixelFit::Parabolic3 => "parabolic",
            SubPixelFit::Gaussian2d => "gauss2d",
        };
        let weighting = match p.weighting {
            Weighting::Binary => "binary",
            Weighting::Count => "count",
        };
        let radius = p
            .search_radius_px
            .map_or("a third of the window".to_string(), |r| format!("{r} px"));
        vec![
            ("slab".into(), format!("{} us", p.slab_us)),
            ("tau".into(), format!("{} us", p.tau_us)),
            ("slices".into(), p.slices.to_string()),
            ("kernel".into(), kernel.into()),
            ("subpixel_fit".into(), fit.into()),
            ("weighting".into(), weighting.into()),
            ("min_events".into(), p.min_events.to_string()),
            ("search_radius".into(), radius),
            (
                "peak_smoothing".into(),
                format!("{} px", p.peak_smoothing_px),
            ),
            ("subpixel_shift".into(), p.subpixel_shift.to_string()),
        ]
    }
}

/// Per-thread working memory of [`SumOfCorrelation`] for one window size: voxel bitmaps and
/// lists, the correlation plane and (built on first use) the FFT plans and buffers.
pub struct CorrSumScratch {
    window: [u32; 2],
    slices: u32,
    shape: PlaneShape,
    overlap: Overlap,
    /// Deformed events of one sub-volume before binning.
    events: WindowEvents,
    voxeliser: Voxeliser,
    /// S1 and S2, or (shared) both in the first; the third for S2 after half the delay
    /// ([`SumOfCorrelation::own_evidence`]).
    voxels: [Voxels; 3],
    /// How S1 and S2 of the last plane lie in `voxels` ([`sub_volumes`]).
    shared: Option<usize>,
    stats: Vec<SliceStats>,
    /// A zeroed grid of the window for [`direct::correlations_at`].
    image: Vec<f64>,
    plane: Vec<f64>,
    /// The planes of the earlier and the later half of the slices with data.
    halves: [Vec<f64>; 2],
    /// Whether `halves` hold two halves (more than one slice with data).
    split: bool,
    accumulators: direct::Accumulators,
    fourier: Option<Fourier>,
    /// Working memory of the peak's uncertainty.
    blocks: uncertainty::BlockPlanes,
    /// No per-vector uncertainty ([`Estimator::skip_uncertainty`]).
    skip_uncertainty: bool,
}

impl CorrSumScratch {
    fn new(window: [u32; 2], radius: [usize; 2], slices: u32) -> Self {
        let shape = PlaneShape {
            w: window[0] as usize,
            h: window[1] as usize,
            rx: radius[0],
            ry: radius[1],
        };
        CorrSumScratch {
            window,
            slices,
            shape,
            overlap: Overlap::new(shape),
            events: WindowEvents::default(),
            voxeliser: Voxeliser::new(shape.w, shape.h),
            voxels: Default::default(),
            shared: None,
            stats: Vec::with_capacity(slices as usize),
            image: vec![0.0; shape.w * shape.h],
            plane: vec![0.0; shape.plane_width() * shape.plane_height()],
            halves: [0, 1].map(|_| vec![0.0; shape.plane_width() * shape.plane_height()]),
            split: false,
            accumulators: direct::Accumulators::new(shape),
            fourier: None,
            blocks: Default::default(),
            skip_uncertainty: false,
        }
    }

    /// Voxelise the events of `window` in `[from, to)` (deformed by the predictor, if any)
    /// into `voxels[into]`, as `bin = (length µs, slices)` slices from `from`. With a `shift`
    /// (px, [`CorrSumParams::subpixel_shift`]) every event is moved by it and its voxel
    /// splatted at the resulting sub-pixel position ([`Voxeliser::add_splat`]); otherwise
    /// events are rounded to their nearest pixel.
    #[allow(clippy::too_many_arguments)]
    fn bin(
        &mut self,
        slab: &Slab,
        window: &Window,
        (from, to): (i64, i64),
        (length_us, slices): (i64, usize),
        count: bool,
        deformation: Option<&Deformation>,
        shift: Option<[f32; 2]>,
        into: usize,
    ) {
        let voxeliser = &mut self.voxeliser;
        match shift {
            Some(_) => voxeliser.begin_splat(length_us, slices, count),
            None => voxeliser.begin(length_us, slices, count),
        }
        if deformation.is_none() && shift.is_none() {
            // Raw events sit on pixels: `visit_runs` (and `visit`) deliver exactly the events
            // of the window and of `[from, to)`, the sub-volume's `length_us`.
            debug_assert_eq!(to - from, length_us);
            // Tiles inside the window as runs; a visitor per weighting, so that each loop
            // is compiled without its test.
            let interval = (from, to);
            if voxeliser.is_narrow() && count {
                let mut narrow = Narrow::<true>::new(voxeliser, window, from);
                slab.visit_runs(window, interval, from, &mut narrow);
            } else if voxeliser.is_narrow() {
                let mut narrow = Narrow::<false>::new(voxeliser, window, from);
                slab.visit_runs(window, interval, from, &mut narrow);
            } else {
                slab.visit(window, from, to, from, |x, y, t| {
                    voxeliser.add_pixel(x as usize, y as usize, t)
                });
            }
        } else {
            self.events.clear();
            match deformation {
                Some(d) => slab.gather_deformed(window, from, to, from, d, &mut self.events),
                None => slab.gather(window, from, to, from, &mut self.events),
            }
            let e = &self.events;
            let events = e.x.iter().zip(&e.y).zip(&e.t);
            match shift {
                Some([ax, ay]) => {
                    events.for_each(|((&x, &y), &t)| voxeliser.add_splat(x + ax, y + ay, t))
                }
                None => events.for_each(|((&x, &y), &t)| voxeliser.add(x, y, t)),
            }
        }
        voxeliser.finish(&mut self.voxels[into]);
    }
}

/// Raw events of a narrow window into the voxeliser ([`Voxeliser::add_narrow_run`] and
/// [`Voxeliser::add_narrow_inside`]), `COUNT` its count weighting.
struct Narrow<'a, const COUNT: bool> {
    voxeliser: &'a mut Voxeliser,
    /// The window's top-left pixel and the sub-volume's start.
    origin: [i64; 3],
}

impl<'a, const COUNT: bool> Narrow<'a, COUNT> {
    fn new(voxeliser: &'a mut Voxeliser, window: &Window, from: i64) -> Self {
        let origin = [window.x0, window.y0, from];
        Narrow { voxeliser, origin }
    }
}

impl<const COUNT: bool> TileVisitor for Narrow<'_, COUNT> {
    fn run(&mut self, events: TileRun<'_>) {
        self.voxeliser.add_narrow_run::<COUNT>(events, self.origin);
    }

    fn event(&mut self, x: i64, y: i64, t: i64) {
        self.voxeliser
            .add_narrow_inside::<COUNT>(x as usize, y as usize, t);
    }
}

impl std::fmt::Debug for CorrSumScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CorrSumScratch")
            .field("window", &self.window)
            .field("shape", &self.shape)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests;
