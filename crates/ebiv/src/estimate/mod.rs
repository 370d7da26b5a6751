//! Velocity estimators for one interrogation window, behind one [`Estimator`] trait.
//!
//! The two event-native estimators of Willert & Klinner (Exp. Fluids 63:101, 2022):
//! sum of correlation over time slices ([`corrsum`]) and motion compensation by contrast
//! maximisation ([`motion`]). Both take a window, the slab holding its events and an
//! optional predictor (from a previous pass), and return one velocity with its status and
//! quality measures. Shared kernels: sub-pixel peak fits ([`peak`]).

pub mod adaptive;
pub mod corrsum;
pub mod motion;
pub mod uncertainty;
pub use crate::peak;

use crate::field::Status;
use crate::grid::Window;
use crate::volume::{Slab, WindowEvents};

pub use crate::deform::events::Deformation;

/// What a previous pass predicts for a window: the velocity at its centre and, where the
/// predictor field allows, the local velocity gradient used to deform the events.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Velocity at the window centre, px/ms.
    pub velocity: [f64; 2],
    /// Affine motion around the window centre (PIV window deformation, for events).
    pub deformation: Option<Deformation>,
    /// Restrict the search to velocities within this distance (px/ms, per axis) of
    /// `velocity`; `None` or a non-finite value: the estimator's own range. Honoured by the
    /// estimators whose [`Estimator::finds_secondary_peaks`] is true, ignored by the others;
    /// used to re-evaluate a window whose highest peak failed validation on a lower peak
    /// near its neighbours' median.
    pub search_radius: Option<f64>,
}

/// Gather the events of `window` in `[t_from, t_to)` (times relative to `t_ref_us`),
/// deformed by the prediction's affine motion when there is one.
pub(crate) fn gather_predicted(
    slab: &Slab,
    window: &Window,
    (t_from, t_to, t_ref_us): (i64, i64, i64),
    prediction: Option<&Prediction>,
    out: &mut WindowEvents,
) {
    match prediction.and_then(|p| p.deformation) {
        Some(d) => slab.gather_deformed(window, t_from, t_to, t_ref_us, &d, out),
        None => slab.gather(window, t_from, t_to, t_ref_us, out),
    }
}

/// The result for one window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowEstimate {
    /// x velocity, px/ms (NaN if invalid).
    pub u: f64,
    /// y velocity (image rows, positive down), px/ms (NaN if invalid).
    pub v: f64,
    /// Standard uncertainty (one standard deviation) of `u`, px/ms; NaN where unknown.
    pub u_unc: f32,
    /// Standard uncertainty (one standard deviation) of `v`, px/ms; NaN where unknown.
    pub v_unc: f32,
    /// Why the estimate is invalid, if it is.
    pub status: Status,
    /// Peak value: summed normalised correlation, or the objective's maximum.
    pub peak: f32,
    /// First-to-second peak ratio (NaN where not defined).
    pub peak_ratio: f32,
    /// Events the estimate is based on.
    pub event_count: u32,
    /// Length T of the time slab the window was evaluated over, µs (sum of correlation: the
    /// length of each sub-volume; motion compensation: the slab of warped events); 0 for a
    /// window that was not evaluated (masked). Set for invalid estimates too: a window
    /// without events was still looked at over its slab. `u32` like
    /// [`VectorField::slab_us`](crate::field::VectorField::slab_us), where it is written.
    pub slab_us: u32,
}

impl WindowEstimate {
    /// An invalid estimate: NaN velocity with `status`, from `event_count` events of a slab
    /// of `slab_us` µs (0: the window was not evaluated).
    pub fn invalid(status: Status, event_count: u32, slab_us: u32) -> Self {
        WindowEstimate {
            u: f64::NAN,
            v: f64::NAN,
            u_unc: f32::NAN,
            v_unc: f32::NAN,
            status,
            peak: f32::NAN,
            peak_ratio: f32::NAN,
            event_count,
            slab_us,
        }
    }
}

/// A velocity estimator for one window of events.
pub trait Estimator: Sync {
    /// Per-thread working memory (FFT buffers, images), reused across windows.
    type Scratch: Send;

    /// Short name written into output metadata (`corrsum`, `motion`).
    fn name(&self) -> &'static str;

    /// Working memory for windows of `window` = [width, height] px.
    fn scratch(&self, window: [u32; 2]) -> Self::Scratch;

    /// Events needed around a field time t0: `[t0 − before, t0 + after)`, as `(before,
    /// after)` in µs.
    fn time_extent_us(&self) -> (i64, i64);

    /// The extent of [`Estimator::time_extent_us`] that a field needs to be measured: field
    /// times are planned so that it lies within the recording. The same, except for an
    /// estimator whose slab varies per window ([`adaptive::AdaptiveSlab`]: its first pass's).
    fn planning_extent_us(&self) -> (i64, i64) {
        self.time_extent_us()
    }

    /// Estimate the velocity of the events of `window` around time `t0_us`. `predictor` is
    /// what a previous pass expects there; without it the estimator searches its default
    /// range on undeformed events.
    fn estimate(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        predictor: Option<&Prediction>,
        scratch: &mut Self::Scratch,
    ) -> WindowEstimate;

    /// The parameters as `(name, value with unit)` pairs, for output metadata.
    fn parameters(&self) -> Vec<(String, String)>;

    /// Turn off (`skip`) or back on the per-vector uncertainty (`u_unc`, `v_unc`) of the
    /// estimates made with `scratch`; it is on in a new scratch. The passes whose vectors
    /// only predict the next pass skip it: for sum of correlation it costs about half as much
    /// again as the estimate itself (docs/uncertainty.md).
    fn skip_uncertainty(&self, _scratch: &mut Self::Scratch, _skip: bool) {}

    /// True if [`Prediction::search_radius`] restricts the search to a lower peak whose
    /// `peak` is comparable with that of the unrestricted estimate (same correlation plane),
    /// so that multiple-peak validation can use this estimator.
    fn finds_secondary_peaks(&self) -> bool {
        false
    }
}
