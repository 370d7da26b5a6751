//! Errors of measured velocity fields against a known flow, and agreement of two fields.
//!
//! * [`assess`]: a [`FieldSeries`](crate::field::FieldSeries) against the truth
//!   `truth(x_px, y_px, t_us) → (u, v)` px/ms ([`Truth`]: a simulation's flow or a truth field
//!   file): bias and random error per component, RMS and mean end-point error, outlier and
//!   valid shares, dynamic velocity range (Adrian 1997), error maps, errors binned by true
//!   speed and by events per window, coverage of the per-vector uncertainty, and the
//!   fractional-displacement histogram with its peak-locking index (Christensen 2004). The
//!   metrics follow `docs/algorithms.md` §16.9 and are described in `docs/assess.md`.
//! * [`compare`]: two series (two methods, or ebiv against another tool) matched in time and
//!   space: median |Δv|, share beyond a threshold, mean difference, scatter data (the
//!   statistics of the EBIV paper's wall-flow comparison).
//! * [`field_errors`] and [`agreement`]: the compact summaries the estimator tests use.
//! * [`envelope`]: the operating-envelope study of the two event estimators
//!   (`ebiv bench envelope`).

mod binned;
mod compare;
mod coverage;
pub mod envelope;
mod errors;
mod fractional;
mod metrics;
mod options;
pub mod report;
mod truth;

#[cfg(test)]
mod tests;

pub use binned::{ErrorBin, ErrorMap};
pub use compare::{compare, Agreement, MatchedPair};
pub use coverage::{spearman, Coverage};
pub use errors::{agreement, field_errors, ErrorStats};
pub use fractional::{fractional_part, FractionalHistogram};
pub use metrics::{assess, Assessment};
pub use options::{AssessOptions, CompareOptions};
pub use truth::Truth;

use crate::field::FieldSeries;

/// Standard uncertainties (σ_u, σ_v) of vector `i` in the series' velocity unit, NaN where
/// unknown.
pub(crate) fn uncertainty(series: &FieldSeries, i: usize) -> [f64; 2] {
    let get = |v: &[f32]| v.get(i).map_or(f64::NAN, |&s| s as f64);
    [get(&series.u_unc), get(&series.v_unc)]
}
