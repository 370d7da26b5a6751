//! Errors of a measured field series against a known flow: [`field_errors`] (the summary
//! the estimator tests print) and [`agreement`] of two series on one grid.

use crate::field::FieldSeries;

/// Error statistics of a field series against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorStats {
    /// Vectors compared (valid ones).
    pub compared: usize,
    /// Vectors in the series.
    pub total: usize,
    /// Mean error (u, v), px/ms.
    pub bias: [f64; 2],
    /// Standard deviation of the error (u, v), px/ms.
    pub random: [f64; 2],
    /// Root mean square end-point error, px/ms.
    pub rms: f64,
    /// Mean end-point error, px/ms.
    pub aee: f64,
    /// Largest end-point error, px/ms.
    pub max: f64,
    /// Largest true speed among the compared vectors, px/ms.
    pub max_true_speed: f64,
}

impl ErrorStats {
    /// Dynamic velocity range: largest true speed over the RMS error.
    pub fn dvr(&self) -> f64 {
        self.max_true_speed / self.rms
    }

    /// Share of valid vectors.
    pub fn valid_share(&self) -> f64 {
        self.compared as f64 / self.total.max(1) as f64
    }
}

impl std::fmt::Display for ErrorStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "RMS {:.4} px/ms, mean |e| {:.4}, bias ({:+.4}, {:+.4}), random ({:.4}, {:.4}), max {:.3}, valid {:.1} % of {}, DVR {:.0}",
            self.rms,
            self.aee,
            self.bias[0],
            self.bias[1],
            self.random[0],
            self.random[1],
            self.max,
            100.0 * self.valid_share(),
            self.total,
            self.dvr()
        )
    }
}

/// Compare the valid vectors (status 0) of `series` with `truth(x, y, t_us) → (u, v)` at
/// each vector's position and time.
pub fn field_errors(
    series: &FieldSeries,
    truth: impl Fn(f64, f64, f64) -> (f64, f64),
) -> ErrorStats {
    let mut errors = Vec::new();
    let mut max_true_speed = 0.0f64;
    let total = series.u.len();
    for (ti, &t) in series.t_us.iter().enumerate() {
        for (row, &y) in series.y.iter().enumerate() {
            for (col, &x) in series.x.iter().enumerate() {
                let i = series.index(ti, row, col);
                if !series.status[i].is_valid() || !series.u[i].is_finite() {
                    continue;
                }
                let (ut, vt) = truth(x, y, t as f64);
                max_true_speed = max_true_speed.max(ut.hypot(vt));
                errors.push([series.u[i] as f64 - ut, series.v[i] as f64 - vt]);
            }
        }
    }
    let n = errors.len();
    if n == 0 {
        return ErrorStats {
            total,
            rms: f64::NAN,
            aee: f64::NAN,
            bias: [f64::NAN; 2],
            random: [f64::NAN; 2],
            max: f64::NAN,
            ..ErrorStats::default()
        };
    }
    let mean = |k: usize| errors.iter().map(|e| e[k]).sum::<f64>() / n as f64;
    let bias = [mean(0), mean(1)];
    let sd =
        |k: usize| (errors.iter().map(|e| (e[k] - bias[k]).powi(2)).sum::<f64>() / n as f64).sqrt();
    let epe: Vec<f64> = errors.iter().map(|e| e[0].hypot(e[1])).collect();
    ErrorStats {
        compared: n,
        total,
        bias,
        random: [sd(0), sd(1)],
        rms: (epe.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt(),
        aee: epe.iter().sum::<f64>() / n as f64,
        max: epe.iter().cloned().fold(0.0, f64::max),
        max_true_speed,
    }
}

/// Agreement of two series on the same grid and times: median |Δv| over vectors valid in
/// both, the share differing by more than `outlier` px/ms, and the number compared.
pub fn agreement(a: &FieldSeries, b: &FieldSeries, outlier: f64) -> Option<(f64, f64, usize)> {
    if a.x != b.x || a.y != b.y || a.t_us != b.t_us {
        return None;
    }
    let mut d: Vec<f64> = (0..a.u.len())
        .filter(|&i| a.status[i].is_valid() && b.status[i].is_valid())
        .map(|i| ((a.u[i] - b.u[i]) as f64).hypot((a.v[i] - b.v[i]) as f64))
        .filter(|d| d.is_finite())
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(|x, y| x.total_cmp(y));
    let n = d.len();
    let median = if n % 2 == 1 {
        d[n / 2]
    } else {
        0.5 * (d[n / 2 - 1] + d[n / 2])
    };
    let beyond = d.iter().filter(|&&x| x > outlier).count() as f64 / n as f64;
    Some((median, beyond, n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Status;

    #[test]
    fn errors_of_a_known_series() {
        let mut s = FieldSeries::new(vec![0.0, 1.0], vec![0.0], vec![0]);
        s.u = vec![1.1, 0.9];
        s.v = vec![0.0, 0.0];
        s.status = vec![Status::VALID; 2];
        let e = field_errors(&s, |_, _, _| (1.0, 0.0));
        assert!((e.rms - 0.1).abs() < 1e-6);
        assert!(e.bias[0].abs() < 1e-6 && (e.random[0] - 0.1).abs() < 1e-6);
        assert!((e.dvr() - 10.0).abs() < 1e-4);
        s.status[1] = Status::MEDIAN_TEST;
        let e = field_errors(&s, |_, _, _| (1.0, 0.0));
        assert_eq!((e.compared, e.total), (1, 2));
        let (median, beyond, n) = agreement(&s, &s, 1.0).unwrap();
        assert_eq!((median, beyond, n), (0.0, 0.0, 1));
    }
}
