//! Motion compensation by contrast maximisation (Willert & Klinner, Exp. Fluids 63:101,
//! 2022, §2.3; algorithms.md §4).
//!
//! The events of a window and a time slab `[t0 − T/2, t0 + T/2)` are assumed to move with
//! one velocity `(u, v)`. Warping them to a reference time, `x' = x − u (t − t_ref)`,
//! `y' = y − v (t − t_ref)`, collapses each particle's trail onto its image at `t_ref` when
//! the velocity is right; the sharpness of the image of warped events (IWE) is maximised over
//! the velocity (contrast maximisation: Gallego, Rebecq & Scaramuzza, CVPR 2018; objectives
//! after Stoffregen & Kleeman, CVPR 2019).
//!
//! Differences from the reference implementation (algorithms.md §4.5), all deliberate:
//! correct bilinear weights; an IWE padded so that no candidate loses events; a Gaussian
//! splat by default, which removes the zero-velocity locking of bilinear splatting of
//! integer pixel positions (item 8); candidate grids from integer counts; a coarse-to-fine
//! search around a predictor instead of a fixed 725-candidate scan; NaN with a status for
//! empty windows, flat objectives and edge-of-range peaks instead of zero or clamped vectors.
//!
//! Two searches ([`SearchMethod`]). The paper's prescription ([`SearchMethod::Grid`]): a
//! coarse grid, 5 × 5 refinements down to 0.05 px/ms and a 3-point fit, 100–200 IWE
//! evaluations per window over the paper's range (several hundred over the default range,
//! [`RANGE_WINDOWS`]). The default ([`SearchMethod::Newton`]) uses the fact that with a
//! Gaussian splat Σ I² is a smooth function of the velocity with analytic derivatives
//! (Gallego et al. 2018): Newton steps with the analytic gradient and Hessian converge to the
//! continuous maximum in about three evaluations (no lattice, no fit bias). The objective
//! has a narrow true maximum, about particle size / T wide in velocity, beside broad false
//! ones (at zero velocity wherever pixels fire several times per passing particle), so the
//! ascent starts from every candidate that may hold the global maximum: in a first pass a
//! sum of correlation of the same events (`start_estimator`), a histogram of event-pair
//! velocities, and zero velocity where its objective competes; with a predictor, the
//! predictor and the histogram. The highest maximum wins, and its height against the best
//! value elsewhere is the vector's peak ratio ([`ContrastMaximization`]).
//!
//! Evidence too weak for a valid vector: a peak ratio below 1.2 (below 1.5 for a maximum at
//! zero velocity), a maximum at the edge of the range or a sum-of-correlation start with a
//! clear peak beyond it ([`Status::OUT_OF_RANGE`]), fewer events than one per pixel of the
//! trail the velocity claims ([`Status::FEW_EVENTS`]).

mod iwe;
mod newton;
mod search;
#[cfg(test)]
mod test_events;
mod uncertainty;
mod votes;

use serde::{Deserialize, Serialize};

use super::corrsum::{CorrSumParams, CorrSumScratch, SumOfCorrelation};
use super::{gather_predicted, Estimator, Prediction, WindowEstimate};
use crate::error::{Error, Result};
use crate::field::Status;
use crate::grid::Window;
use crate::peak::SubPixelFit;
use crate::volume::{Slab, WindowEvents};
use iwe::{Events, SplatTable};
use search::{Search, SearchScratch};

/// Sharpness objective of the IWE (all maximised; algorithms.md §4.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Objective {
    /// Population variance over the whole padded canvas (`var`). With every event kept on
    /// a canvas of fixed size, it is the sum of squares divided by the canvas size minus a
    /// constant.
    #[default]
    #[serde(alias = "var")]
    Variance,
    /// Σ I² (`SumSq`).
    #[serde(alias = "sumsq")]
    SumOfSquares,
    /// Σ exp(I) (`SumExp`).
    #[serde(alias = "sumexp")]
    SumExp,
    /// mean(I²) · Σ exp(−3 I) (`R1`).
    R1,
    /// Number of pixels with I > 1 (`isoa`); piecewise constant in the velocity.
    Isoa,
    /// max I (`MOA`); piecewise smooth.
    #[serde(alias = "moa")]
    MaxAccumulation,
}

/// How one warped event is spread over the IWE's pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Splat {
    /// Bilinear weights of a point (2 × 2 pixels). Events sit on integer pixels, so at a
    /// velocity component of 0 all events of a pixel coincide and the objective has a
    /// spurious maximum there (zero-velocity locking, algorithms.md §4.5 item 8).
    Bilinear,
    /// A normalised Gaussian of standard deviation `sigma` px, truncated at 2.5 σ. For
    /// σ ≥ 0.8 px a point's energy on the pixel grid varies by < 1 % with its sub-pixel
    /// position (29 % at σ = 0.5, 300 % bilinear), so no velocity is special.
    Gaussian {
        /// Standard deviation, px (0.3 … 1.5).
        sigma: f64,
    },
}

impl Default for Splat {
    fn default() -> Self {
        Splat::Gaussian { sigma: 0.8 }
    }
}

/// How the velocity that maximises the objective is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SearchMethod {
    /// Newton steps with the objective's analytic gradient and Hessian until the step is
    /// below 0.005 px/ms (or below 0.02 px/ms after a step four times longer), about three
    /// objective evaluations per ascent, from every start that may hold the global maximum:
    /// a sum of correlation of the window (first pass) or the predictor, the peaks of a
    /// histogram of event-pair velocities, and zero velocity where its objective competes.
    /// Needs a smooth objective: with a bilinear splat or an objective other than the
    /// variance or Σ I², [`SearchMethod::Grid`] is used instead.
    #[default]
    Newton,
    /// The paper's prescription: a coarse grid over the whole range (through a pyramid of
    /// coarser canvases for wide ranges), 5 × 5 neighbourhoods at `coarse_step`, halving the
    /// step down to `final_step`, then a 3-point fit: 100–200 evaluations per window over
    /// `W / T`, several hundred over the default range. The same climb from `coarse_step`
    /// down also runs from the sum-of-correlation start of a first pass; the higher maximum
    /// wins.
    Grid,
}

/// The time the events are warped to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReferenceTime {
    /// The field time t0, the centre of the slab (as the reference code).
    #[default]
    SlabCentre,
    /// The mean time of the window's events.
    MeanEventTime,
}

impl Objective {
    /// The setting's name of this objective (`variance`, `sum-of-squares`, `sum-exp`, `r1`,
    /// `isoa`, `max-accumulation`).
    pub fn name(self) -> &'static str {
        match self {
            Objective::Variance => "variance",
            Objective::SumOfSquares => "sum-of-squares",
            Objective::SumExp => "sum-exp",
            Objective::R1 => "r1",
            Objective::Isoa => "isoa",
            Objective::MaxAccumulation => "max-accumulation",
        }
    }
}

impl SearchMethod {
    /// The setting's name: `newton` or `grid`.
    pub fn name(self) -> &'static str {
        match self {
            SearchMethod::Newton => "newton",
            SearchMethod::Grid => "grid",
        }
    }
}

impl ReferenceTime {
    /// What the events are warped to, in words.
    pub fn describe(self) -> &'static str {
        match self {
            ReferenceTime::SlabCentre => "slab centre",
            ReferenceTime::MeanEventTime => "mean time of the window's events",
        }
    }
}

/// Parameters of [`ContrastMaximization`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionParams {
    /// Slab length T, µs: the window's events come from `[t0 − T/2, t0 + T/2)`.
    pub slab_us: i64,
    /// Sharpness objective.
    pub objective: Objective,
    /// Half-width of the search range around the predictor (or zero), px/ms. `None`:
    /// [`RANGE_WINDOWS`] windows per slab, `4 max(W, H) / T` (16 px/ms for 40 px and 10 ms),
    /// see [`RANGE_WINDOWS`]; a sixteenth of that, `max(W, H) / (4 T)`, around a predictor,
    /// which a previous pass knows to a fraction of it. At least two coarse steps.
    pub search_range: Option<f64>,
    /// Step of the coarse candidate grid, px/ms.
    pub coarse_step: f64,
    /// Smallest refinement step, px/ms: the step is halved from `coarse_step` while it stays
    /// at or above this (0.25 → 0.125 → 0.0625 for 0.05), then a sub-grid fit.
    pub final_step: f64,
    /// Splatting kernel of the IWE at and below the coarse step.
    pub splat: Splat,
    /// Reference time of the warp.
    pub t_ref: ReferenceTime,
    /// Windows with fewer events are flagged [`Status::FEW_EVENTS`].
    pub min_events: u32,
    /// Sub-grid fit of the objective around its best candidate ([`SearchMethod::Grid`]).
    pub fit: SubPixelFit,
    /// Search strategy.
    pub search: SearchMethod,
}

impl Default for MotionParams {
    fn default() -> Self {
        MotionParams {
            slab_us: 10_000,
            objective: Objective::Variance,
            search_range: None,
            coarse_step: 0.25,
            final_step: 0.05,
            splat: Splat::default(),
            t_ref: ReferenceTime::SlabCentre,
            min_events: 10,
            fit: SubPixelFit::Gaussian3,
            search: SearchMethod::Newton,
        }
    }
}

impl MotionParams {
    /// Reject values that cannot give a meaningful or bounded search.
    pub fn validate(&self) -> Result<()> {
        if !(1..=60_000_000).contains(&self.slab_us) {
            return Err(Error::parameter(
                "slab",
                format!("must be 1 µs … 60 s, got {} µs", self.slab_us),
            ));
        }
        if !(self.coarse_step.is_finite() && self.coarse_step > 0.0) {
            return Err(Error::parameter("coarse-step", "must be a positive number"));
        }
        if !(self.final_step.is_finite()
            && self.final_step > 0.0
            && self.final_step <= self.coarse_step
            && self.coarse_step / self.final_step <= 1024.0)
        {
            return Err(Error::parameter(
                "final-step",
                format!(
                    "must be positive, at most coarse_step ({}) and at least 1/1024 of it",
                    self.coarse_step
                ),
            ));
        }
        if let Some(r) = self.search_range {
            if !(r.is_finite() && r > 0.0 && r / self.coarse_step <= 1024.0) {
                return Err(Error::parameter(
                    "search-range",
                    "must be positive and at most 1024 coarse steps",
                ));
            }
        }
        if let Splat::Gaussian { sigma } = self.splat {
            if !(0.3..=1.5).contains(&sigma) {
                return Err(Error::parameter(
                    "splat.gaussian.sigma",
                    format!("must be 0.3 … 1.5 px, got {sigma}"),
                ));
            }
        }
        Ok(())
    }
}

/// Motion-compensation estimator: contrast maximisation of the image of warped events.
///
/// `peak` is the objective's value at the best refined candidate (for [`Objective::Variance`]
/// the variance over the padded canvas, which depends on the canvas size and so on the
/// search range). `peak_ratio` plays the role of the correlation peak ratio: with the Newton
/// search, the height of the winning maximum of Σ I² over the best value outside its basin
/// (another maximum, a start, a probe of the background), both above the lowest value seen;
/// with the grid search, the first-to-second local maximum ratio of the objective over the
/// coarsest full scan of the range, both measured above the scan's minimum (NaN without a
/// second maximum).
#[derive(Debug, Clone)]
pub struct ContrastMaximization {
    params: MotionParams,
    fine: SplatTable,
    coarse: SplatTable,
    /// Sum of correlation over the same slab, whose velocity starts the search of windows
    /// without a predictor ([`start_estimator`]); `None` for slabs whose sub-volumes
    /// (12 T / 13) are longer than sum of correlation accepts (16 s), where the vote and
    /// zero velocity are the only starts.
    start: Option<SumOfCorrelation>,
}

/// Per-thread working memory of [`ContrastMaximization`].
#[derive(Debug, Default)]
pub struct MotionScratch {
    gathered: WindowEvents,
    events: Events,
    search: SearchScratch,
    start: Option<CorrSumScratch>,
    /// No per-vector uncertainty ([`Estimator::skip_uncertainty`]).
    skip_uncertainty: bool,
}

/// Default half-width of the search range without a predictor, in windows per slab: a
/// displacement over the slab of up to four window sizes per component, `4 max(W, H) / T`.
///
/// A particle faster than `W / T` crosses the window within the slab but still leaves a
/// straight trail across it, as long as the window and as rich in events (every pixel it
/// crosses fires), and more of them: the slab holds every particle that crossed. What
/// shrinks is the time the trail spends in the window, `W / |v|`: at four windows per slab
/// it is a quarter of the slab (a fifth to a sixth diagonally), and the contrast maximum is
/// about four times wider than at `W / T`, still narrow against the range. The bound is one
/// of cost rather than evidence: the canvas of warped events grows as the range squared,
/// and the sum-of-correlation start must shorten its delay as the range grows
/// ([`start_estimator`]). Faster flows need a longer window, a shorter slab or
/// `search_range`.
pub const RANGE_WINDOWS: f64 = 4.0;

/// The sum of correlation that gives a window without a predictor one start of its search:
/// the slab `T` split as sub-volumes of `T − τ` at a delay `τ = T / 13`
/// ([`start_delay_us`]) in 16 slices.
///
/// Contrast maximisation has a narrow true maximum (about particle size / T wide in
/// velocity) beside broad false ones: where every pixel fires several times as a particle
/// passes, or several particles pass one pixel within the slab (dense seeding, particle
/// images of a pixel), all events of a pixel stack up at zero velocity. A vote of event
/// pairs can miss the true maximum there; the correlation of two
/// sub-volumes cannot, as it compares whole images rather than pairs. Its search reaches a
/// third of the window over τ, `W / (3 τ)`: with `τ = T/13` the default search range,
/// `4 W / T` ([`RANGE_WINDOWS`]). A longer delay would be more precise but would not reach
/// it (at T/5, 5 W / (3 T); beyond, a ghost peak inside its search region comes out valid);
/// a start only needs to fall inside the contrast maximum's basin. Where it has a clear peak
/// on the border of its search region ([`CLEAR_BORDER_PEAK`]), the events move faster than
/// the range, and the window is flagged out of range.
/// Only a start: the velocity comes from the contrast maximum, which wins over the other
/// starts by its objective.
///
/// Slabs of a few µs get slices of 1 µs (fewer, or more where τ is 1 µs).
fn start_estimator(slab_us: i64) -> Result<SumOfCorrelation> {
    let tau_us = start_delay_us(slab_us);
    let sub_us = (slab_us - tau_us).max(1);
    SumOfCorrelation::new(CorrSumParams {
        slab_us: sub_us,
        tau_us,
        // No slice longer than τ (paired slices would share events), none shorter than 1 µs.
        slices: ((sub_us + tau_us - 1) / tau_us).max(16).min(sub_us) as u32,
        min_events: 1,
        ..CorrSumParams::default()
    })
}

/// Peak ratio from which the sum-of-correlation start's peak on the border of its search
/// region flags the window out of range. On simulated uniform flows beyond the range
/// (10 px/ms, 32 px windows, T = 20 ms, `ideal` sensor), 95 % of these border peaks have
/// ratios above 3.2 (0.002 particles/px) and 4.7 (0.05).
const CLEAR_BORDER_PEAK: f64 = 2.0;

/// The fastest velocity per axis, px/ms, whose displacement over the delay of
/// [`start_estimator`] stays inside sum of correlation's default search region (a third of
/// the window, whole pixels).
fn start_reach(slab_us: i64, window: [u32; 2]) -> f64 {
    let tau_ms = start_delay_us(slab_us) as f64 / 1000.0;
    let third = (window[0].min(window[1]) as f64 / 3.0).clamp(1.0, f64::MAX);
    third / tau_ms
}

/// Delay τ of [`start_estimator`], µs: `T / 13`, at least 1 µs. Over τ, sum of
/// correlation reaches a third of the window in whole pixels, `⌊W/3⌋ / τ`, which covers the
/// default range `4 W / T` ([`RANGE_WINDOWS`]) for windows of 16 px and from 26 px up
/// (`T / 12` would fall short of it by the rounding of `W/3`).
fn start_delay_us(slab_us: i64) -> i64 {
    (slab_us / 13).max(1)
}

impl ContrastMaximization {
    /// An estimator with validated `params`.
    pub fn new(params: MotionParams) -> Result<Self> {
        params.validate()?;
        Ok(ContrastMaximization {
            fine: SplatTable::new(params.splat),
            coarse: SplatTable::new(Splat::Bilinear),
            start: start_estimator(params.slab_us).ok(),
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &MotionParams {
        &self.params
    }

    /// Search half-width for a window of `window` px, with or without a predictor.
    pub fn search_range(&self, window: [u32; 2], predicted: bool) -> f64 {
        let p = &self.params;
        let range = p.search_range.unwrap_or_else(|| {
            let crossing = window[0].max(window[1]) as f64 / (p.slab_us as f64 / 1000.0);
            if predicted {
                crossing / 4.0
            } else {
                RANGE_WINDOWS * crossing
            }
        });
        range.max(if p.search_range.is_some() {
            0.0
        } else {
            2.0 * p.coarse_step
        })
    }
}

/// Fewest events that can show the displacement `|v| T` of `velocity` over a slab of
/// `slab_us` in a window of `window` px: one per pixel of one particle's trail across the
/// window, `min(|v| T, diagonal)`. A particle image crossing a pixel changes its brightness
/// and makes it fire, so a window with fewer events holds no whole trail of that length, and
/// a maximum claiming it rests on a few chance alignments of unrelated events.
fn trail_events(velocity: [f64; 2], slab_us: i64, window: [u32; 2]) -> u32 {
    let length = velocity[0].hypot(velocity[1]) * slab_us as f64 / 1000.0;
    let diagonal = f64::from(window[0]).hypot(f64::from(window[1]));
    if length.is_nan() {
        // No velocity (an invalid vector) claims nothing.
        return 0;
    }
    length.min(diagonal) as u32
}

/// Whole-pixel origin and size `[width, height]` of the box covering the window
/// `[0, dims)` and every event (events outside it come from deformation); NaN coordinates are
/// ignored. `(origin, dims)` when all events lie inside the window.
fn event_extent(x: &[f32], y: &[f32], dims: [u32; 2]) -> ([f32; 2], [u32; 2]) {
    let span = |v: &[f32], size: u32| {
        let (lo, hi) = v
            .iter()
            .filter(|a| a.is_finite())
            .fold((0f32, size as f32 - 1.0), |(lo, hi), &a| {
                (lo.min(a), hi.max(a))
            });
        let origin = lo.floor();
        // Bounded by the deformation's largest strain; clamp anyway so the canvas stays finite.
        let extent = (hi - origin + 1.0).ceil().clamp(size as f32, 1e6) as u32;
        (origin, extent)
    };
    let (ox, wx) = span(x, dims[0]);
    let (oy, wy) = span(y, dims[1]);
    ([ox, oy], [wx, wy])
}

impl Estimator for ContrastMaximization {
    type Scratch = MotionScratch;

    fn name(&self) -> &'static str {
        "motion"
    }

    fn scratch(&self, _window: [u32; 2]) -> MotionScratch {
        MotionScratch::default()
    }

    fn skip_uncertainty(&self, scratch: &mut MotionScratch, skip: bool) {
        scratch.skip_uncertainty = skip;
    }

    fn time_extent_us(&self) -> (i64, i64) {
        let before = self.params.slab_us / 2;
        (before, self.params.slab_us - before)
    }

    fn estimate(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        predictor: Option<&Prediction>,
        scratch: &mut MotionScratch,
    ) -> WindowEstimate {
        let (before, after) = self.time_extent_us();
        // Validated to 1 µs … 60 s, so it fits.
        let slab_us = self.params.slab_us as u32;
        scratch.gathered.clear();
        let times = (t0_us - before, t0_us + after, t0_us);
        gather_predicted(slab, window, times, predictor, &mut scratch.gathered);
        let n = scratch.gathered.len();
        let count = n.min(u32::MAX as usize) as u32;
        if n == 0 {
            return WindowEstimate::invalid(Status::NO_EVENTS, 0, slab_us);
        }
        if count < self.params.min_events {
            return WindowEstimate::invalid(Status::FEW_EVENTS, count, slab_us);
        }
        let ev = &mut scratch.events;
        let g = &scratch.gathered;
        ev.x.clear();
        ev.y.clear();
        ev.t.clear();
        // Deformed events may lie outside the window: the canvas covers their bounding box,
        // moved by whole pixels (the objective does not change under such a shift).
        let dims = [window.width, window.height];
        let (origin, extent) = event_extent(&g.x, &g.y, dims);
        ev.x.extend(g.x.iter().map(|&x| x - origin[0]));
        ev.y.extend(g.y.iter().map(|&y| y - origin[1]));
        let shift = match self.params.t_ref {
            ReferenceTime::SlabCentre => 0.0,
            ReferenceTime::MeanEventTime => g.t.iter().map(|&t| t as f64).sum::<f64>() / n as f64,
        };
        ev.t.extend(g.t.iter().map(|&t| ((t as f64 - shift) / 1000.0) as f32));

        let predictor = predictor
            .map(|p| p.velocity)
            .filter(|p| p[0].is_finite() && p[1].is_finite());
        let range = self.search_range(dims, predictor.is_some());
        let (mut correlated, mut beyond) = (None, false);
        if let (None, Some(start)) = (predictor, &self.start) {
            let scratch = scratch.start.get_or_insert_with(|| {
                // Only the start's velocity is used.
                let mut s = start.scratch(dims);
                start.skip_uncertainty(&mut s, true);
                s
            });
            let e = start.estimate(slab, window, t0_us, None, scratch);
            let valid = e.status.is_valid() && e.u.is_finite() && e.v.is_finite();
            correlated = valid.then_some([e.u, e.v]);
            // A clear peak (twice any other) on the border of its search region: the events
            // move faster than it reaches, and so faster than the range if that is no wider.
            // (In windows of a few particles, a weak border peak is noise.)
            beyond = e.status.contains(Status::OUT_OF_RANGE)
                && f64::from(e.peak_ratio) >= CLEAR_BORDER_PEAK
                && range <= start_reach(self.params.slab_us, dims) * (1.0 + 1e-9);
        }
        if beyond {
            return WindowEstimate::invalid(Status::OUT_OF_RANGE, count, slab_us);
        }
        let search = Search {
            start: correlated,
            events: &scratch.events,
            window: dims,
            extent,
            centre: predictor.unwrap_or([0.0, 0.0]),
            predicted: predictor.is_some(),
            range,
            params: &self.params,
            fine: &self.fine,
            coarse: &self.coarse,
        };
        let Some(out) = search.run(&mut scratch.search) else {
            return WindowEstimate::invalid(Status::OUT_OF_RANGE, count, slab_us);
        };
        let mut status = out.status;
        if status.is_valid() && count < trail_events(out.velocity, self.params.slab_us, dims) {
            status = Status::FEW_EVENTS;
        }
        let valid = status.is_valid();
        let [u_unc, v_unc] = if valid && !scratch.skip_uncertainty {
            search.uncertainty(out.velocity, &mut scratch.search)
        } else {
            [f64::NAN; 2]
        };
        WindowEstimate {
            u: if valid { out.velocity[0] } else { f64::NAN },
            v: if valid { out.velocity[1] } else { f64::NAN },
            status,
            peak: out.peak as f32,
            peak_ratio: out.peak_ratio as f32,
            event_count: count,
            slab_us,
            u_unc: u_unc as f32,
            v_unc: v_unc as f32,
        }
    }

    fn parameters(&self) -> Vec<(String, String)> {
        let p = &self.params;
        let splat = match p.splat {
            Splat::Bilinear => "bilinear".to_string(),
            Splat::Gaussian { sigma } => format!("gaussian sigma={sigma} px"),
        };
        vec![
            (
                "estimator".into(),
                "motion compensation (contrast maximisation)".into(),
            ),
            ("slab".into(), format!("{} us", p.slab_us)),
            ("objective".into(), p.objective.name().into()),
            (
                "search_range".into(),
                p.search_range.map_or(
                    "auto (4 max(W,H)/T; max(W,H)/(4T) with predictor)".into(),
                    |r| format!("{r} px/ms"),
                ),
            ),
            ("coarse_step".into(), format!("{} px/ms", p.coarse_step)),
            ("final_step".into(), format!("{} px/ms", p.final_step)),
            ("splat".into(), splat),
            ("t_ref".into(), p.t_ref.describe().into()),
            ("min_events".into(), p.min_events.to_string()),
            ("fit".into(), p.fit.name().into()),
            ("search".into(), p.search.name().into()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::event_extent;

    /// Every slab the parameters accept, 1 µs to 60 s, builds the estimator; up to sum of
    /// correlation's 16 s, with its sum-of-correlation start.
    #[test]
    fn every_valid_slab_builds_the_estimator() {
        for slab_us in [
            1, 2, 5, 16, 17, 20, 99, 10_000, 16_000_000, 17_000_000, 18_000_000, 60_000_000,
        ] {
            let params = super::MotionParams {
                slab_us,
                ..Default::default()
            };
            let built = super::ContrastMaximization::new(params);
            let built = built.unwrap_or_else(|e| panic!("slab {slab_us} µs: {e}"));
            // Sub-volumes of T − T/13 up to sum of correlation's 16 s.
            let sub_us = slab_us - slab_us / 13;
            assert_eq!(built.start.is_some(), sub_us <= 16_000_000, "{slab_us}");
        }
    }

    #[test]
    fn a_claimed_displacement_needs_a_trail_of_events() {
        // 5 px/ms over 10 ms: 50 px, more than the 45 px diagonal of a 32 px window.
        assert_eq!(super::trail_events([3.0, 4.0], 10_000, [32, 32]), 45);
        assert_eq!(super::trail_events([0.6, 0.8], 10_000, [32, 32]), 10);
        assert_eq!(super::trail_events([f64::NAN; 2], 10_000, [32, 32]), 0);
    }

    #[test]
    fn event_extent_covers_deformed_events_by_whole_pixels() {
        let (x, y) = ([0.0, 31.0, 5.5], [0.0, 31.0, 2.0]);
        assert_eq!(event_extent(&x, &y, [32, 32]), ([0.0, 0.0], [32, 32]));
        let (x, y) = ([-3.4, 40.2, f32::NAN], [0.0, 31.0, 1.0]);
        let (origin, extent) = event_extent(&x, &y, [32, 32]);
        assert_eq!(origin, [-4.0, 0.0]);
        assert_eq!(extent, [46, 32]);
    }
}
