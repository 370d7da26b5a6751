//! Conventional cross-correlation PIV on image pairs and on frames rebuilt from events.
//!
//! Multi-pass interrogation with window deformation (Scarano 2002, Meas. Sci. Technol.
//! 13:R1–R19; Raffel et al., "Particle Image Velocimetry", 3rd ed., §5.5; algorithms.md §16):
//!
//! 1. the first pass correlates windows of the raw frames;
//! 2. its field is validated (normalized median test), gaps are filled and the field is
//!    smoothed: the predictor;
//! 3. every later pass interpolates the predictor to each pixel, deforms both frames by half
//!    of it in opposite directions ([`crate::deform::frames`], central differences), correlates the deformed
//!    windows ([`correlate`]) and adds the residual displacement to the predictor;
//! 4. the last pass may be repeated until the field changes by less than
//!    [`PivParams::repeat_tolerance`] (PIVlab's iterative last pass), and is validated; replacing
//!    its outliers is a separate, optional step, as for the event estimators.
//!
//! Several frame pairs may be evaluated together: their correlation planes are summed window
//! by window before the peak search (ensemble correlation, Meinhart, Wereley & Santiago 2000,
//! J. Fluids Eng. 122:285 — the frame analogue of the EBIV sum of correlation).
//!
//! Results are displacements in px from the first to the second frame of a pair, on the same
//! [`VectorField`] as every other estimator, with status flags, peak (correlation coefficient
//! of the deformed windows), peak ratio and the number of non-zero pixels of the first frame's
//! window in `event_count`. Frames carry no time, so `slab_us` stays 0 here; [`piv_events`]
//! records the time span of each field's frames in it, [`images::piv_image_series`] the time
//! between the frames of a pair when it is given.

pub mod correlate;
pub mod events;
pub mod images;
mod uncertainty;

pub use crate::deform::frames::{DenseField, Interpolation, Resampler};
pub use correlate::{CorrelationKind, Correlator};
pub use events::{piv_events, EventPivParams, FrameClock, FramePlan};

use crate::error::{Error, Result};
use crate::field::{Status, VectorField};
use crate::frame::Frame;
use crate::grid::{Grid, GridSpec, Mask, Window};
use crate::peak::{find_peak, SubPixelFit};
use crate::process::{run_passes, MultiPass, PassEvaluator, PassReport};
use crate::validate::{self, ValidationParams, ValidationSummary};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Which frames are deformed by the predictor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DeformationMode {
    /// Both frames by ∓½ of the predictor (central differences, second-order accurate;
    /// OpenPIV's default).
    #[default]
    Symmetric,
    /// Only the second frame, by the whole predictor (PIVlab's choice).
    Second,
}

impl DeformationMode {
    /// The setting's name: `symmetric` or `second`.
    pub fn name(self) -> &'static str {
        match self {
            DeformationMode::Symmetric => "symmetric",
            DeformationMode::Second => "second",
        }
    }

    /// Parse `symmetric` or `second`.
    pub fn parse(text: &str) -> Option<Self> {
        match text {
            "symmetric" | "central" => Some(DeformationMode::Symmetric),
            "second" | "forward" => Some(DeformationMode::Second),
            _ => None,
        }
    }

    /// Factors applied to the predictor when sampling the first and the second frame.
    fn factors(self) -> (f32, f32) {
        match self {
            DeformationMode::Symmetric => (-0.5, 0.5),
            DeformationMode::Second => (0.0, 1.0),
        }
    }
}

/// Everything about a PIV evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct PivParams {
    /// Interrogation grids, first pass first (e.g. 64 → 32 → 16 px, step half the window).
    pub passes: Vec<GridSpec>,
    /// Circular or zero-padded linear correlation.
    pub correlation: CorrelationKind,
    /// Sub-pixel peak estimator.
    pub fit: SubPixelFit,
    /// Which frames the predictor deforms.
    pub deformation: DeformationMode,
    /// Image interpolation used for the deformation.
    pub interpolation: Interpolation,
    /// Outlier detection after every pass; ε and limits in px of displacement.
    pub validation: ValidationParams,
    /// Replace the outliers of the last pass (they keep their flag plus
    /// [`Status::REPLACED`]); between passes they are always replaced.
    pub replace_final: bool,
    /// Gaussian smoothing of the predictor between passes, in grid nodes (0 = off).
    pub predictor_smoothing: f64,
    /// Repetitions of the last pass at most, each with the previous result as predictor.
    pub last_pass_repeats: u32,
    /// The repetitions stop once the mean change of the vectors valid in two successive ones
    /// is below this, px ([`crate::process::multipass`]; PIVlab stops at an RMS change of
    /// 0.025 px).
    pub repeat_tolerance: f64,
    /// Pixels to leave out: they count as the window mean; windows whose centre is masked
    /// are not evaluated.
    pub mask: Option<Mask>,
    /// Estimate the per-vector uncertainty on the last pass.
    pub uncertainty: bool,
}

impl Default for PivParams {
    fn default() -> Self {
        PivParams {
            passes: vec![
                GridSpec::square(64, 32),
                GridSpec::square(32, 16),
                GridSpec::square(16, 8),
            ],
            correlation: CorrelationKind::Circular,
            fit: SubPixelFit::Gaussian3,
            deformation: DeformationMode::Symmetric,
            interpolation: Interpolation::Quintic,
            validation: ValidationParams::default(),
            replace_final: false,
            predictor_smoothing: 0.5,
            last_pass_repeats: 2,
            repeat_tolerance: 0.01,
            mask: None,
            uncertainty: true,
        }
    }
}

impl PivParams {
    /// Passes of square windows `sizes` with `overlap` (0 ≤ overlap < 1) between neighbours.
    pub fn passes_with_overlap(sizes: &[u32], overlap: f64) -> Result<Vec<GridSpec>> {
        if !(0.0..1.0).contains(&overlap) {
            return Err(Error::parameter(
                "overlap",
                format!("must lie in [0, 1), got {overlap}"),
            ));
        }
        if sizes.is_empty() {
            return Err(Error::parameter(
                "passes",
                "at least one window size is needed",
            ));
        }
        Ok(sizes
            .iter()
            .map(|&s| {
                let step = ((s as f64 * (1.0 - overlap)).round() as u32).max(1);
                GridSpec::square(s, step)
            })
            .collect())
    }

    /// These settings for frames `dt_ms` apart when the validation limits (ε, largest
    /// velocity) are given in px/ms: converted to px of displacement, the engine's unit.
    pub fn over_interval(&self, dt_ms: f64) -> PivParams {
        let mut p = self.clone();
        p.validation.median_epsilon *= dt_ms;
        p.validation.max_velocity = p.validation.max_velocity.map(|v| v * dt_ms);
        p
    }

    /// Check that every parameter is in range.
    pub fn check(&self) -> Result<()> {
        if self.passes.is_empty() {
            return Err(Error::parameter("passes", "at least one pass is needed"));
        }
        self.validation.check()?;
        if !(self.predictor_smoothing.is_finite() && self.predictor_smoothing >= 0.0) {
            return Err(Error::parameter(
                "predictor-smoothing",
                format!("must be zero or positive, got {}", self.predictor_smoothing),
            ));
        }
        if !(self.repeat_tolerance.is_finite() && self.repeat_tolerance >= 0.0) {
            return Err(Error::parameter(
                "repeat-tolerance",
                format!("must be zero or positive, got {}", self.repeat_tolerance),
            ));
        }
        Ok(())
    }
}

/// The settings of a PIV run as output attributes (NetCDF, NPZ, Tecplot), the validation
/// limits in `unit` (the unit of the vectors `p` validates: `px` for the displacements of the
/// engine, `px/ms` for settings given before [`PivParams::over_interval`]). The writers add the
/// software and the status legend.
pub fn attributes(p: &PivParams, unit: &str) -> Vec<(String, String)> {
    let passes = p
        .passes
        .iter()
        .map(|g| {
            format!(
                "{}x{} px step {}x{}",
                g.window[0], g.window[1], g.step[0], g.step[1]
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    vec![
        ("passes".to_string(), passes),
        ("correlation".to_string(), p.correlation.name().to_string()),
        ("subpixel_fit".to_string(), p.fit.name().to_string()),
        ("deformation".to_string(), p.deformation.name().to_string()),
        (
            "interpolation".to_string(),
            p.interpolation.name().to_string(),
        ),
        (
            "final_pass_iterations".to_string(),
            format!(
                "up to {} repetitions, until the mean change < {} px",
                p.last_pass_repeats, p.repeat_tolerance
            ),
        ),
        (
            "predictor_smoothing_nodes".to_string(),
            p.predictor_smoothing.to_string(),
        ),
        ("uncertainty".to_string(), p.uncertainty.to_string()),
        ("validation".to_string(), p.validation.describe(unit)),
        ("replace_final".to_string(), p.replace_final.to_string()),
        (
            "position".to_string(),
            "window centroid, image coordinates: x right, y down, pixel centres at integers"
                .to_string(),
        ),
        (
            "peak".to_string(),
            "correlation coefficient at the peak of the (summed) correlation plane".to_string(),
        ),
        (
            "event_count".to_string(),
            "non-zero pixels in the first frame's window (summed over the pairs)".to_string(),
        ),
    ]
}

/// The result of a PIV evaluation.
#[derive(Debug, Clone)]
pub struct PivOutput {
    /// The last pass's displacement field, px.
    pub field: VectorField,
    /// What validation found in the last pass.
    pub validation: ValidationSummary,
    /// Vectors replaced in the last pass (0 unless `replace_final`).
    pub replaced: usize,
    /// One report per pass.
    pub passes: Vec<PassReport>,
}

/// Multi-pass PIV of one image pair: displacements in px from `a` to `b`.
pub fn piv_pair(a: &Frame, b: &Frame, params: &PivParams) -> Result<PivOutput> {
    piv_ensemble(&[(a, b)], params)
}

/// Multi-pass PIV of several image pairs of the same scene whose correlation planes are
/// summed before each peak search (ensemble correlation; e.g. the pairs (1,2), (2,3), (3,4) of
/// a four-frame sequence, or many pairs of a statistically steady flow).
pub fn piv_ensemble(pairs: &[(&Frame, &Frame)], params: &PivParams) -> Result<PivOutput> {
    params.check()?;
    let (first, _) = pairs
        .first()
        .ok_or_else(|| Error::parameter("frames", "at least one frame pair is needed"))?;
    let (width, height) = (first.width, first.height);
    for (i, (a, b)) in pairs.iter().enumerate() {
        for (which, f) in [("first", a), ("second", b)] {
            if f.width != width || f.height != height {
                return Err(Error::parameter(
                    "frames",
                    format!(
                        "the {which} frame of pair {} is {}×{} px, the first frame is {width}×{height} px; all frames must have the same size",
                        i + 1,
                        f.width,
                        f.height
                    ),
                ));
            }
            if f.data.len() != width as usize * height as usize {
                return Err(Error::parameter(
                    "frames",
                    format!(
                        "the {which} frame of pair {} has the wrong number of pixels",
                        i + 1
                    ),
                ));
            }
        }
    }
    if let Some(m) = &params.mask {
        if m.width != width || m.height != height {
            return Err(Error::parameter(
                "mask",
                format!(
                    "the mask is {}×{} px but the frames are {width}×{height} px",
                    m.width, m.height
                ),
            ));
        }
    }
    let grids: Vec<Grid> = params
        .passes
        .iter()
        .map(|p| Grid::new(p, first.geometry()))
        .collect::<Result<_>>()?;
    let needs_resampling = grids.len() > 1 || params.last_pass_repeats > 0;
    let resamplers: Vec<(Resampler, Resampler)> = if needs_resampling {
        pairs
            .iter()
            .map(|(a, b)| {
                (
                    Resampler::new(a, params.interpolation),
                    Resampler::new(b, params.interpolation),
                )
            })
            .collect()
    } else {
        Vec::new()
    };

    let outcome = run_passes(
        &FramePasses {
            pairs,
            resamplers: &resamplers,
            params,
        },
        &grids,
        &MultiPass {
            validation: &params.validation,
            last_pass_repeats: params.last_pass_repeats.min(MAX_FINAL_ITERATIONS),
            repeat_single_pass: true,
            repeat_tolerance: params.repeat_tolerance,
            secondary_peaks: false,
            replace_final: params.replace_final,
            uncertainty: params.uncertainty,
        },
    );
    Ok(PivOutput {
        field: outcome.field,
        validation: outcome.validation,
        replaced: outcome.replaced,
        passes: outcome.passes,
    })
}

/// The passes of PIV on one or more frame pairs.
struct FramePasses<'a> {
    pairs: &'a [(&'a Frame, &'a Frame)],
    resamplers: &'a [(Resampler, Resampler)],
    params: &'a PivParams,
}

impl PassEvaluator for FramePasses<'_> {
    fn evaluate(
        &self,
        grid: &Grid,
        predictor: Option<&VectorField>,
        uncertainty: bool,
    ) -> VectorField {
        evaluate_pass(
            self.pairs,
            self.resamplers,
            grid,
            self.params,
            (predictor, uncertainty),
        )
    }

    fn prepare_predictor(&self, field: &mut VectorField) {
        prepare_predictor(field, self.params);
    }
}

/// Most repetitions of the last pass.
pub const MAX_FINAL_ITERATIONS: u32 = 20;

/// Fill the gaps of a validated field and smooth it, so it can predict the next pass. Nodes
/// that stay empty — masked ones, or holes too large to inpaint — take the mean of their
/// nearest filled neighbours, so the predictor has a value at every pixel (it is never
/// output; the masked vectors of the result stay flagged).
fn prepare_predictor(field: &mut VectorField, params: &PivParams) {
    validate::replace_invalid(field, &Default::default());
    if params.predictor_smoothing > 0.0 {
        validate::smooth(field, params.predictor_smoothing);
    }
    fill_everywhere(field);
}

/// Give every node without a finite value the mean of its finite 3 × 3 neighbours, pass by
/// pass until all are filled; zero displacement if the field has no value at all.
fn fill_everywhere(field: &mut VectorField) {
    let (h, w) = (field.height(), field.width());
    let finite = |f: &VectorField, i: usize| f.u[i].is_finite() && f.v[i].is_finite();
    if !(0..field.len()).any(|i| finite(field, i)) {
        field.u.fill(0.0);
        field.v.fill(0.0);
        return;
    }
    loop {
        let mut fills = Vec::new();
        for r in 0..h {
            for c in 0..w {
                let i0 = field.index(r, c);
                if finite(field, i0) {
                    continue;
                }
                let (mut su, mut sv, mut n) = (0.0f64, 0.0f64, 0u32);
                for rr in r.saturating_sub(1)..(r + 2).min(h) {
                    for cc in c.saturating_sub(1)..(c + 2).min(w) {
                        let i = field.index(rr, cc);
                        if finite(field, i) {
                            su += field.u[i] as f64;
                            sv += field.v[i] as f64;
                            n += 1;
                        }
                    }
                }
                if n > 0 {
                    fills.push((i0, (su / n as f64) as f32, (sv / n as f64) as f32));
                }
            }
        }
        if fills.is_empty() {
            return;
        }
        for (i, u, v) in fills {
            field.u[i] = u;
            field.v[i] = v;
        }
    }
}

/// Per-thread buffers of one pass.
struct Scratch {
    correlator: Correlator,
    plane: Vec<f64>,
    a: Vec<f32>,
    b: Vec<f32>,
    /// Blocks' contributions to the plane near its peak ([`uncertainty`]).
    contributions: Vec<f64>,
    /// Whether to estimate the per-vector uncertainty.
    uncertainty: bool,
}

/// One evaluation of every window of `grid`, with the frames deformed by `predictor`, with
/// or without the per-vector uncertainty.
fn evaluate_pass(
    pairs: &[(&Frame, &Frame)],
    resamplers: &[(Resampler, Resampler)],
    grid: &Grid,
    params: &PivParams,
    (predictor, uncertainty): (Option<&VectorField>, bool),
) -> VectorField {
    let (width, height) = (pairs[0].0.width as usize, pairs[0].0.height as usize);
    let dense = predictor.map(|p| DenseField::from_field(p, width, height));
    let warped: Vec<(Frame, Frame)> = match &dense {
        Some(d) => {
            let (fa, fb) = params.deformation.factors();
            resamplers
                .iter()
                .map(|(ra, rb)| (ra.warp(d, fa), rb.warp(d, fb)))
                .collect()
        }
        None => Vec::new(),
    };
    let frames: Vec<(&Frame, &Frame)> = if dense.is_some() {
        warped.iter().map(|(a, b)| (a, b)).collect()
    } else {
        pairs.to_vec()
    };
    let [ww, wh] = grid.window.map(|v| v as usize);
    let mut field = VectorField::new(grid.x_centres(), grid.y_centres());
    let results: Vec<WindowResult> = (0..grid.len())
        .into_par_iter()
        .map_init(
            || Scratch {
                correlator: Correlator::new(ww, wh, params.correlation),
                plane: vec![0.0; ww * wh],
                a: vec![0.0; ww * wh],
                b: vec![0.0; ww * wh],
                contributions: Vec::new(),
                uncertainty,
            },
            |scratch, i| {
                if grid.is_masked(i, params.mask.as_ref()) {
                    return WindowResult::invalid(Status::MASKED, 0);
                }
                let window = grid.window(i);
                let base = dense
                    .as_ref()
                    .map(|d| {
                        let c = window.centre();
                        d.at(c[0], c[1])
                    })
                    .unwrap_or([0.0, 0.0]);
                let nonzero = pairs.iter().map(|(a, _)| count_nonzero(a, &window)).sum();
                correlate_window(&frames, nonzero, &window, params, scratch, base)
            },
        )
        .collect();
    for (i, r) in results.into_iter().enumerate() {
        field.u[i] = r.u;
        field.v[i] = r.v;
        field.u_unc[i] = r.u_unc;
        field.v_unc[i] = r.v_unc;
        field.status[i] = r.status;
        field.peak[i] = r.peak;
        field.peak_ratio[i] = r.peak_ratio;
        field.event_count[i] = r.nonzero;
    }
    field
}

/// The outcome of one window.
struct WindowResult {
    u: f32,
    v: f32,
    /// Standard uncertainty of `u`, `v` (px); NaN where unknown.
    u_unc: f32,
    v_unc: f32,
    status: Status,
    peak: f32,
    peak_ratio: f32,
    nonzero: u32,
}

impl WindowResult {
    fn invalid(status: Status, nonzero: u32) -> Self {
        WindowResult {
            u: f32::NAN,
            v: f32::NAN,
            u_unc: f32::NAN,
            v_unc: f32::NAN,
            status,
            peak: f32::NAN,
            peak_ratio: f32::NAN,
            nonzero,
        }
    }
}

/// Copy the window of `frame` into `out` with its mean removed; masked (and non-finite)
/// pixels count as the mean of the others.
fn extract(frame: &Frame, window: &Window, mask: Option<&Mask>, out: &mut [f32]) {
    let (w, h) = (window.width as usize, window.height as usize);
    let (x0, y0) = (window.x0 as usize, window.y0 as usize);
    let (mut sum, mut n) = (0.0f64, 0usize);
    for r in 0..h {
        let row = &frame.row((y0 + r) as u32)[x0..x0 + w];
        let dst = &mut out[r * w..(r + 1) * w];
        for (c, (d, &s)) in dst.iter_mut().zip(row).enumerate() {
            let masked = !s.is_finite()
                || mask.is_some_and(|m| m.is_masked((x0 + c) as i64, (y0 + r) as i64));
            if masked {
                *d = f32::NAN;
                continue;
            }
            *d = s;
            sum += s as f64;
            n += 1;
        }
    }
    let mean = if n > 0 { (sum / n as f64) as f32 } else { 0.0 };
    for d in out[..w * h].iter_mut() {
        *d = if d.is_nan() { 0.0 } else { *d - mean };
    }
}

/// Non-zero pixels of `frame` inside `window` (for event frames: pixels with events).
fn count_nonzero(frame: &Frame, window: &Window) -> u32 {
    let (x0, w) = (window.x0 as usize, window.width as usize);
    (0..window.height)
        .map(|r| {
            let row = &frame.row(window.y0 as u32 + r)[x0..x0 + w];
            row.iter().filter(|&&v| v != 0.0).count() as u32
        })
        .sum()
}

/// Correlate one window over all frame pairs and locate the summed plane's peak; the
/// displacement is `base` (the predictor at the window centre) plus the residual.
/// `nonzero` is the window's count of non-zero pixels in the raw first frames.
fn correlate_window(
    frames: &[(&Frame, &Frame)],
    nonzero: u32,
    window: &Window,
    params: &PivParams,
    scratch: &mut Scratch,
    base: [f64; 2],
) -> WindowResult {
    let (w, h) = (window.width as usize, window.height as usize);
    scratch.plane.fill(0.0);
    let weight = 1.0 / frames.len() as f64;
    let mask = params.mask.as_ref();
    let mut signal = false;
    for (a, b) in frames {
        extract(a, window, mask, &mut scratch.a);
        extract(b, window, mask, &mut scratch.b);
        let energy =
            scratch
                .correlator
                .accumulate(&scratch.a, &scratch.b, &mut scratch.plane, weight);
        signal |= energy > 0.0;
    }
    if !signal {
        return WindowResult::invalid(Status::NO_EVENTS, nonzero);
    }
    let Some(peak) = find_peak(&scratch.plane, w, h, params.fit, 2) else {
        return WindowResult::invalid(Status::NO_PEAK, nonzero);
    };
    let mut result = WindowResult::invalid(Status::NO_PEAK, nonzero);
    result.peak = peak.value as f32;
    result.peak_ratio = peak.ratio() as f32;
    if peak.on_edge {
        result.status = Status::OUT_OF_RANGE;
        return result;
    }
    let (rx, ry) = (peak.x - (w / 2) as f64, peak.y - (h / 2) as f64);
    if !(rx.is_finite() && ry.is_finite()) {
        return result;
    }
    result.u = (base[0] + rx) as f32;
    result.v = (base[1] + ry) as f32;
    result.status = Status::VALID;
    if !scratch.uncertainty {
        return result;
    }
    let Scratch {
        a,
        b,
        contributions,
        ..
    } = scratch;
    let mut each_pair = |add: &mut dyn FnMut(uncertainty::WindowPair<'_>)| {
        for (fa, fb) in frames {
            extract(fa, window, mask, a);
            extract(fb, window, mask, b);
            add((&a[..w * h], &b[..w * h]));
        }
    };
    let [su, sv] = uncertainty::peak_sigma(
        [w, h],
        params.correlation,
        &peak,
        params.fit,
        &mut each_pair,
        contributions,
    );
    result.u_unc = su as f32;
    result.v_unc = sv as f32;
    result
}
