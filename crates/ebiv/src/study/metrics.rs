//! What a study measures in each cell: the errors of the measured fields against the
//! simulator's truth, and for solid-body rotation the EBIV paper's turntable analysis.
//!
//! The error statistics are those of `ebiv assess` ([`crate::assess::assess`] with its
//! default options): bias, random error, RMS, mean and median end-point error, DVR (Adrian
//! 1997), the outlier share, and the coverage of the per-vector uncertainty; the gross-error
//! share uses the envelope study's limit ([`gross_limit`]); the peak-locking index is
//! [`peak_locking_index`] of the displacements (Christensen 2004, Exp. Fluids 36:484). For a
//! solid-body rotation the tangential velocity of the valid vectors is fitted linearly
//! against the radius, as in the turntable test of Willert & Klinner (2022, Exp. Fluids
//! 63:101, §4.1): the fit's slope is the measured angular velocity, and the RMS deviation
//! from the fit the random error the paper quotes (0.02 px/ms at T = 10 ms, DVR ≈ 175).

use crate::assess::envelope::gross_limit;
use crate::assess::{assess, AssessOptions};
use crate::field::FieldSeries;
use crate::render::peak_locking_index;
use crate::sim::FlowSpec;

/// Every metric: name (a column of `results.csv`), unit, meaning.
pub const METRICS: [(&str, &str, &str); 25] = [
    ("vectors", "", "vectors in the fields"),
    ("valid_share", "", "share of the vectors that are valid"),
    ("bias_u", "px/ms", "mean error of u"),
    ("bias_v", "px/ms", "mean error of v"),
    ("random_u", "px/ms", "standard deviation of the error of u"),
    ("random_v", "px/ms", "standard deviation of the error of v"),
    ("rms", "px/ms", "RMS end-point error"),
    ("aee", "px/ms", "mean end-point error"),
    ("median_error", "px/ms", "median end-point error"),
    ("max_error", "px/ms", "largest end-point error"),
    (
        "dvr",
        "",
        "dynamic velocity range: largest true speed / RMS error",
    ),
    (
        "gross_share",
        "",
        "share of valid vectors off by more than max(0.2 px/ms, 10 % of |v|)",
    ),
    (
        "outlier_share",
        "",
        "share of valid vectors off by more than 0.5 px over their slab (at least 0.1 px/ms), as `ebiv assess` counts them",
    ),
    (
        "within_1_sigma",
        "",
        "share of the error components within ±1 σ of the per-vector uncertainty (0.683 when σ is right)",
    ),
    (
        "within_2_sigma",
        "",
        "share of the error components within ±2 σ of the per-vector uncertainty (0.954 when σ is right)",
    ),
    (
        "sigma_rank",
        "",
        "Spearman rank correlation of |error| and σ",
    ),
    (
        "peak_locking",
        "",
        "peak-locking index of the displacements (1 − lowest/tallest of 10 fractional bins)",
    ),
    (
        "omega_fit",
        "rad/ms",
        "solid-body rotation: slope of tangential velocity against radius",
    ),
    (
        "omega_error",
        "",
        "solid-body rotation: relative error of omega_fit",
    ),
    (
        "fit_rms",
        "px/ms",
        "solid-body rotation: RMS deviation of the tangential velocity from the linear fit",
    ),
    (
        "radial_rms",
        "px/ms",
        "solid-body rotation: RMS radial velocity (zero in the truth)",
    ),
    (
        "fit_dvr",
        "",
        "solid-body rotation: largest fitted tangential speed / fit_rms (the paper's DVR)",
    ),
    (
        "delay_ms",
        "ms",
        "time over which a displacement is measured: τ (corrsum), T (motion), frame step (piv)",
    ),
    ("events", "", "events in the simulated recording"),
    (
        "seconds",
        "s",
        "processing time of the cell (machine-dependent)",
    ),
];

/// Metrics plotted when a study does not list its own.
pub const PLOTTED: [&str; 6] = [
    "rms",
    "bias_u",
    "random_u",
    "valid_share",
    "gross_share",
    "dvr",
];

/// Metrics plotted additionally for solid-body rotations.
pub const PLOTTED_ROTATION: [&str; 3] = ["fit_rms", "omega_error", "fit_dvr"];

/// Names of every metric.
pub fn names() -> Vec<&'static str> {
    METRICS.iter().map(|m| m.0).collect()
}

/// Whether `name` is a metric.
pub fn is_metric(name: &str) -> bool {
    METRICS.iter().any(|m| m.0 == name)
}

/// Unit and meaning of a metric.
pub fn about(name: &str) -> (&'static str, &'static str) {
    METRICS
        .iter()
        .find(|m| m.0 == name)
        .map_or(("", ""), |m| (m.1, m.2))
}

/// One valid vector with its truth, as stored for the figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorRecord {
    /// Field time, µs.
    pub t_us: i64,
    /// Window centre, px.
    pub x: f64,
    /// Window centre, px.
    pub y: f64,
    /// Measured velocity, px/ms.
    pub u: f64,
    /// Measured velocity, px/ms.
    pub v: f64,
    /// True velocity, px/ms.
    pub u_true: f64,
    /// True velocity, px/ms.
    pub v_true: f64,
}

/// The valid vectors of `series` with the truth at their positions and times.
pub fn valid_vectors(
    series: &FieldSeries,
    truth: &dyn Fn(f64, f64, f64) -> (f64, f64),
) -> Vec<VectorRecord> {
    let mut out = Vec::new();
    for (ti, &t) in series.t_us.iter().enumerate() {
        for (row, &y) in series.y.iter().enumerate() {
            for (col, &x) in series.x.iter().enumerate() {
                let i = series.index(ti, row, col);
                let (u, v) = (f64::from(series.u[i]), f64::from(series.v[i]));
                if !series.status[i].is_valid() || !u.is_finite() || !v.is_finite() {
                    continue;
                }
                let (u_true, v_true) = truth(x, y, t as f64);
                out.push(VectorRecord {
                    t_us: t,
                    x,
                    y,
                    u,
                    v,
                    u_true,
                    v_true,
                });
            }
        }
    }
    out
}

/// The metrics of one cell: `series` measured on a flow `flow` whose velocity is `truth`,
/// its valid vectors `vectors`, displacements over `delay_ms` (for the peak-locking index),
/// from a recording of `events` events, processed in `seconds`.
pub fn measure(
    series: &FieldSeries,
    vectors: &[VectorRecord],
    truth: &dyn Fn(f64, f64, f64) -> (f64, f64),
    flow: &FlowSpec,
    delay_ms: Option<f64>,
    events: usize,
    seconds: f64,
) -> Vec<(&'static str, f64)> {
    let e = assess(series, truth, &AssessOptions::default());
    let gross = vectors
        .iter()
        .filter(|r| (r.u - r.u_true).hypot(r.v - r.v_true) > gross_limit(r.u_true.hypot(r.v_true)))
        .count();
    let share = |n: usize| {
        if vectors.is_empty() {
            f64::NAN
        } else {
            n as f64 / vectors.len() as f64
        }
    };
    let both: Vec<f32> = vectors
        .iter()
        .flat_map(|r| [r.u as f32, r.v as f32])
        .collect();
    let locking = match delay_ms {
        Some(d) if !both.is_empty() => peak_locking_index(&both, d),
        _ => f64::NAN,
    };
    let mut m = vec![
        ("vectors", e.total as f64),
        ("valid_share", e.valid_share),
        ("bias_u", e.bias[0]),
        ("bias_v", e.bias[1]),
        ("random_u", e.random[0]),
        ("random_v", e.random[1]),
        ("rms", e.rms),
        ("aee", e.aee),
        ("median_error", e.median),
        ("max_error", e.max),
        ("dvr", e.dvr),
        ("gross_share", share(gross)),
        ("outlier_share", e.outlier_share),
        ("within_1_sigma", e.coverage.within_1_sigma),
        ("within_2_sigma", e.coverage.within_2_sigma),
        ("sigma_rank", e.coverage.spearman),
        ("peak_locking", locking),
    ];
    let rotation = match flow {
        FlowSpec::SolidBody { centre, omega } => {
            rotation_fit(vectors, (centre[0], centre[1]), *omega)
        }
        _ => None,
    };
    let fit = rotation.unwrap_or(RotationFit {
        slope: f64::NAN,
        intercept: f64::NAN,
        fit_rms: f64::NAN,
        radial_rms: f64::NAN,
        max_radius: f64::NAN,
    });
    let omega = match flow {
        FlowSpec::SolidBody { omega, .. } => *omega,
        _ => f64::NAN,
    };
    m.extend([
        ("omega_fit", fit.slope * omega.signum()),
        ("omega_error", (fit.slope - omega.abs()) / omega.abs()),
        ("fit_rms", fit.fit_rms),
        ("radial_rms", fit.radial_rms),
        (
            "fit_dvr",
            (fit.slope * fit.max_radius + fit.intercept) / fit.fit_rms,
        ),
        ("delay_ms", delay_ms.unwrap_or(f64::NAN)),
        ("events", events as f64),
        ("seconds", seconds),
    ]);
    debug_assert_eq!(m.len(), METRICS.len());
    m
}

/// The linear fit u_θ = slope·r + intercept of a solid-body rotation's valid vectors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationFit {
    /// Slope, rad/ms (the measured |ω|).
    pub slope: f64,
    /// Intercept, px/ms.
    pub intercept: f64,
    /// RMS deviation of u_θ from the fit, px/ms.
    pub fit_rms: f64,
    /// RMS radial velocity, px/ms.
    pub radial_rms: f64,
    /// Largest radius among the vectors, px.
    pub max_radius: f64,
}

/// Radius, tangential and radial velocity of a vector about `centre`; the tangential
/// direction is that of the rotation `omega` (positive clockwise on screen, y down), so a
/// correct measurement gives u_θ = |ω| r.
pub fn polar(r: &VectorRecord, centre: (f64, f64), omega: f64) -> (f64, f64, f64) {
    let (dx, dy) = (r.x - centre.0, r.y - centre.1);
    let radius = dx.hypot(dy);
    if radius == 0.0 {
        return (0.0, f64::NAN, f64::NAN);
    }
    let (ex, ey) = (dx / radius, dy / radius);
    // Clockwise on screen with y down: the tangent of (ex, ey) is (−ey, ex).
    let s = if omega < 0.0 { -1.0 } else { 1.0 };
    let tangential = s * (-ey * r.u + ex * r.v);
    let radial = ex * r.u + ey * r.v;
    (radius, tangential, radial)
}

/// Least-squares line of u_θ against r over `vectors` (those at least 1 px from the
/// centre); `None` with fewer than three.
pub fn rotation_fit(
    vectors: &[VectorRecord],
    centre: (f64, f64),
    omega: f64,
) -> Option<RotationFit> {
    let points: Vec<(f64, f64, f64)> = vectors
        .iter()
        .map(|r| polar(r, centre, omega))
        .filter(|p| p.0 >= 1.0 && p.1.is_finite())
        .collect();
    let n = points.len() as f64;
    if points.len() < 3 {
        return None;
    }
    let mean_r = points.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_t = points.iter().map(|p| p.1).sum::<f64>() / n;
    let srr: f64 = points.iter().map(|p| (p.0 - mean_r).powi(2)).sum();
    let srt: f64 = points.iter().map(|p| (p.0 - mean_r) * (p.1 - mean_t)).sum();
    if srr <= 0.0 {
        return None;
    }
    let slope = srt / srr;
    let intercept = mean_t - slope * mean_r;
    let fit_rms = (points
        .iter()
        .map(|p| (p.1 - slope * p.0 - intercept).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let radial_rms = (points.iter().map(|p| p.2 * p.2).sum::<f64>() / n).sqrt();
    let max_radius = points.iter().map(|p| p.0).fold(0.0, f64::max);
    Some(RotationFit {
        slope,
        intercept,
        fit_rms,
        radial_rms,
        max_radius,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::flow::{Flow, SolidBodyRotation};

    #[test]
    fn a_solid_body_rotation_is_fitted_with_its_angular_velocity() {
        let flow = SolidBodyRotation {
            centre: (50.0, 40.0),
            omega_per_ms: 0.02,
        };
        // Pairs of points at the same radius, the tangential velocity of the first 0.01
        // px/ms too high and of the second 0.01 too low: the fit is exact, its RMS 0.01.
        let mut vectors = Vec::new();
        for (k, (x, y)) in [
            (80.0, 40.0),
            (20.0, 40.0),
            (90.0, 40.0),
            (50.0, 0.0),
            (50.0, 90.0),
            (100.0, 40.0),
        ]
        .into_iter()
        .enumerate()
        {
            let (u, v) = flow.velocity(x, y, 0.0);
            let radius = (x - flow.centre.0).hypot(y - flow.centre.1);
            let delta = if k % 2 == 0 { 0.01 } else { -0.01 };
            let scale = 1.0 + delta / (0.02 * radius);
            vectors.push(VectorRecord {
                t_us: 0,
                x,
                y,
                u: u * scale,
                v: v * scale,
                u_true: u,
                v_true: v,
            });
        }
        for r in &vectors {
            let (radius, tangential, radial) = polar(r, flow.centre, 0.02);
            assert!(((tangential - 0.02 * radius).abs() - 0.01).abs() < 1e-12);
            assert!(radial.abs() < 1e-9);
        }
        let fit = rotation_fit(&vectors, flow.centre, 0.02).unwrap();
        assert!((fit.slope - 0.02).abs() < 1e-12, "{fit:?}");
        assert!(fit.intercept.abs() < 1e-12, "{fit:?}");
        assert!((fit.fit_rms - 0.01).abs() < 1e-12, "{fit:?}");
        assert!(fit.radial_rms < 1e-9);
        // The same flow turning the other way.
        let mirrored: Vec<VectorRecord> = vectors
            .iter()
            .map(|r| VectorRecord {
                u: -r.u,
                v: -r.v,
                ..*r
            })
            .collect();
        let back = rotation_fit(&mirrored, flow.centre, -0.02).unwrap();
        assert!((back.slope - fit.slope).abs() < 1e-12);
    }
}
