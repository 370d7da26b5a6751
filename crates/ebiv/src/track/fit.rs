//! The smooth path of a track: a local polynomial in time fitted to the track's events
//! around each sample (local regression, Cleveland & Devlin 1988), with tricube weights over
//! `fit_window`, and velocity and acceleration as its derivatives.
//!
//! Model of an event at time t (ms, relative to the sample, less the `latency`), polarity
//! s = +1 (ON) or −1 (OFF):
//!
//! ```text
//!     x = a0 + a1 t + a2 t² + a3 t³ + c s        (and likewise y)
//! ```
//!
//! The term c s takes up the ON events' lead and the OFF events' trail, so the polynomial
//! follows their midpoint — the particle centre when the two are symmetric. A window with
//! one polarity only drops the term. The fit runs twice: the second pass leaves out events
//! further than 3.5 robust standard deviations from the first (stray events of noise or of a
//! particle passing close).
//!
//! Uncertainty: the coefficients' covariance from the weighted residuals (the sandwich form
//! for weighted least squares, `M⁻¹ (Σ w² r rᵀ σ²) M⁻¹`). It covers the scatter of the
//! events about the path, not the sensor's lag (see the `latency` setting).

use super::detect::TrackEvent;
use super::matrix::{cholesky_inverse, dot, mat_vec, sandwich, MAX_TERMS};
use super::params::TrackParams;

/// One sample of a fitted track.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSample {
    /// Time, µs.
    pub t_us: i64,
    /// Position, px.
    pub x: f64,
    /// Position, px.
    pub y: f64,
    /// Velocity, px/ms.
    pub u: f64,
    /// Velocity, px/ms.
    pub v: f64,
    /// Acceleration, px/ms² (NaN for degree 1).
    pub ax: f64,
    /// Acceleration, px/ms².
    pub ay: f64,
    /// Standard uncertainties of x, y (px), u, v (px/ms), ax, ay (px/ms²).
    pub unc: [f64; 6],
    /// Events in the fit window.
    pub events: u32,
    /// RMS distance of those events from the fitted path (both axes), px.
    pub residual: f64,
}

impl TrackSample {
    /// Curvature of the path, 1/px: (u a_y − v a_x) / |v|³ (positive turning clockwise on
    /// screen, image y down).
    pub fn curvature(&self) -> f64 {
        let speed = (self.u * self.u + self.v * self.v).sqrt();
        (self.u * self.ay - self.v * self.ax) / (speed * speed * speed)
    }
}

/// A finished track.
#[derive(Debug, Clone)]
pub struct Track {
    /// Identity, unique in a run.
    pub id: u64,
    /// Samples in time order.
    pub samples: Vec<TrackSample>,
    /// Events of the track.
    pub events: u32,
    /// Events left out as outliers.
    pub outliers: u32,
    /// Time of the first and the last event, µs.
    pub span_us: (i64, i64),
}

impl Track {
    /// Duration from first to last event, µs.
    pub fn duration_us(&self) -> i64 {
        self.span_us.1 - self.span_us.0
    }
}

/// Spacing of the first pass's fits, which find the outliers, µs: the local cubic holds
/// within a millisecond of its centre.
const OUTLIER_PASS_US: f64 = 2000.0;

/// Most samples of one track: a longer track is sampled at a multiple of the interval.
const MAX_SAMPLES: i64 = 1_000_000;

/// Fewest events in a fit window.
const MIN_FIT_EVENTS: f64 = 30.0;

/// Events a fit window is widened to hold, where the track has them: enough for a cubic's
/// velocity and acceleration (a sparse track's window grows; a bright track's does not).
const TARGET_FIT_EVENTS: f64 = 100.0;

/// Fewest events on either side of a sample: a sample is never an extrapolation.
const MIN_SIDE_EVENTS: f64 = 4.0;

/// Highest degree of a fit whose window holds less than a fifth of its events on one side
/// of the sample (near a track's ends).
const END_DEGREE: u32 = 2;

/// Most a fit window is widened to find [`MIN_FIT_EVENTS`] on both sides of a sample.
const MAX_WIDENING: f64 = 3.0;

fn row(t: f64, s: f64, degree: usize, polarity: bool) -> ([f64; MAX_TERMS], usize) {
    let mut r = [0.0; MAX_TERMS];
    let mut p = 1.0;
    for item in r.iter_mut().take(degree + 1) {
        *item = p;
        p *= t;
    }
    let mut n = degree + 1;
    if polarity {
        r[n] = s;
        n += 1;
    }
    (r, n)
}

/// A local fit at one time: coefficients for x and y and their covariance.
struct LocalFit {
    ax: [f64; MAX_TERMS],
    ay: [f64; MAX_TERMS],
    /// Covariance of the coefficients per unit residual variance (sandwich form).
    cov: [[f64; MAX_TERMS]; MAX_TERMS],
    var_x: f64,
    var_y: f64,
    events: u32,
    residual: f64,
    /// Whether the polarity term was fitted.
    polarity: bool,
    /// Degree of the polynomial.
    degree: usize,
}

/// Events of one polarity within one [`BIN_US`] time bin, grouped: the fit treats them as
/// one point of weight `n` at their mean (the tricube weight hardly changes across a bin),
/// with their scatter about the mean kept for the residual.
#[derive(Debug, Clone, Copy)]
struct Point {
    t: f64,
    x: f64,
    y: f64,
    s: f64,
    n: f64,
    /// Σ (x − x̄)² + (y − ȳ)² over the bin's events.
    scatter: f64,
}

/// Width of the time bins that group events for the fit, µs: far below the fit window, so
/// that the grouping changes the fit by a negligible amount while it cuts the work by the
/// events per bin.
const BIN_US: f64 = 50.0;

/// Fits the events of a track (time order) at the sample times.
pub struct PathFitter<'a> {
    params: &'a TrackParams,
    /// Camera time that the times count from, µs: a multiple of the sample interval at or
    /// before the first event, so that the sample times stay multiples of it.
    base: i64,
    /// Event times less the latency, µs from `base` (small numbers whatever the camera's
    /// clock reads).
    times: Vec<f64>,
    xs: Vec<f64>,
    ys: Vec<f64>,
    signs: Vec<f64>,
    keep: Vec<bool>,
    /// The kept events grouped in bins, time order.
    points: Vec<Point>,
}

impl<'a> PathFitter<'a> {
    /// A fitter over `events` (time order).
    pub fn new(events: &[TrackEvent], params: &'a TrackParams) -> Self {
        let base = events
            .first()
            .map_or(0, |e| e.t.div_euclid(params.sample_us) * params.sample_us);
        let times = events
            .iter()
            .map(|e| e.t.saturating_sub(base) as f64 - params.latency_us)
            .collect();
        let xs = events.iter().map(|e| e.x as f64).collect();
        let ys = events.iter().map(|e| e.y as f64).collect();
        let signs = events
            .iter()
            .map(|e| if e.p != 0 { 1.0 } else { -1.0 })
            .collect();
        let mut fitter = PathFitter {
            params,
            base,
            times,
            xs,
            ys,
            signs,
            keep: vec![true; events.len()],
            points: Vec::new(),
        };
        fitter.group();
        fitter
    }

    /// Group the kept events into [`Point`]s.
    fn group(&mut self) {
        self.points.clear();
        let mut i = 0;
        let n = self.times.len();
        while i < n {
            let slot = (self.times[i] / BIN_US).floor();
            let mut j = i;
            while j < n && (self.times[j] / BIN_US).floor() == slot {
                j += 1;
            }
            for sign in [1.0, -1.0] {
                let (mut k, mut st, mut sx, mut sy, mut sxx) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for e in i..j {
                    if self.keep[e] && self.signs[e] == sign {
                        k += 1.0;
                        st += self.times[e];
                        sx += self.xs[e];
                        sy += self.ys[e];
                        sxx += self.xs[e] * self.xs[e] + self.ys[e] * self.ys[e];
                    }
                }
                if k > 0.0 {
                    let (x, y) = (sx / k, sy / k);
                    self.points.push(Point {
                        t: st / k,
                        x,
                        y,
                        s: sign,
                        n: k,
                        scatter: (sxx - k * (x * x + y * y)).max(0.0),
                    });
                }
            }
            i = j;
        }
        self.points.sort_by(|a, b| a.t.total_cmp(&b.t));
    }

    /// The samples of the track: every multiple of `sample` between its first and last
    /// event (at least one, at the middle, for a track shorter than a sample interval), and
    /// the number of outliers left out.
    pub fn fit(mut self) -> (Vec<TrackSample>, u32) {
        let n = self.times.len();
        if n == 0 {
            return (Vec::new(), 0);
        }
        let (first, last) = (self.times[0], self.times[n - 1]);
        // Sample times from `base`, µs: multiples of the interval within the events' span
        // (the middle of a span shorter than one interval); at most MAX_SAMPLES a track, a
        // longer track sampled at a multiple of the interval.
        let step = self.params.sample_us;
        let k0 = (first / step as f64).ceil() as i64;
        let k1 = (last / step as f64).floor() as i64;
        let count = (k1 - k0 + 1).max(0);
        let stride = (count / MAX_SAMPLES + 1).max(1);
        let mut times_us: Vec<i64> = (0..count.div_euclid(stride) + i64::from(count % stride != 0))
            .map(|i| (k0 + i * stride) * step)
            .filter(|&t| t as f64 <= last)
            .collect();
        if times_us.is_empty() {
            times_us.push(((first + last) / 2.0).round() as i64);
        }
        let times: Vec<f64> = times_us.iter().map(|&t| t as f64).collect();
        let step = step as f64;
        // First pass: fits every [`OUTLIER_PASS_US`], and the residual of every event from
        // the nearest of them.
        let coarse: Vec<f64> = {
            let stride = ((OUTLIER_PASS_US / step).round() as usize).max(1);
            let mut c: Vec<f64> = times.iter().step_by(stride).copied().collect();
            if c.last() != times.last() {
                c.extend(times.last());
            }
            c
        };
        let first_pass: Vec<Option<LocalFit>> = coarse.iter().map(|&t| self.local(t)).collect();
        let mut residuals = Vec::with_capacity(n);
        let mut nearest = 0usize;
        for i in 0..n {
            let t = self.times[i];
            while nearest + 1 < coarse.len()
                && (coarse[nearest + 1] - t).abs() < (coarse[nearest] - t).abs()
            {
                nearest += 1;
            }
            residuals.push(match &first_pass[nearest] {
                Some(fit) => {
                    let (px, py) = fit.position_at(t - coarse[nearest], self.signs[i]);
                    ((self.xs[i] - px).powi(2) + (self.ys[i] - py).powi(2)).sqrt()
                }
                None => f64::NAN,
            });
        }
        let mut sorted: Vec<f64> = residuals
            .iter()
            .copied()
            .filter(|r| r.is_finite())
            .collect();
        let mut outliers = 0;
        if sorted.len() >= 8 {
            sorted.sort_by(f64::total_cmp);
            // The median distance of a 2-D Gaussian is 1.1774 σ.
            let sigma = sorted[sorted.len() / 2] / 1.1774;
            let limit = 3.5 * sigma.max(0.3);
            for (keep, r) in self.keep.iter_mut().zip(&residuals) {
                if *r > limit {
                    *keep = false;
                    outliers += 1;
                }
            }
        }
        if outliers > 0 {
            self.group();
        }
        let samples = times_us
            .iter()
            .filter_map(|&t| {
                let fit = self.local(t as f64)?;
                Some(fit.sample(self.base.saturating_add(t)))
            })
            .collect();
        (samples, outliers)
    }

    /// The weighted local fit at `t` (µs, latency removed): over the fit window, widened
    /// (up to [`MAX_WIDENING`] times) while it holds fewer than [`TARGET_FIT_EVENTS`]
    /// events; `None` when the widest window still holds fewer than [`MIN_FIT_EVENTS`], or
    /// fewer than [`MIN_SIDE_EVENTS`] on either side of `t` (a sample is never an
    /// extrapolation). Where less than a fifth of the events lie on one side (near a track's
    /// ends) the degree is at most [`END_DEGREE`]: a lower degree extrapolates less from the
    /// side with the events.
    fn local(&self, t: f64) -> Option<LocalFit> {
        let base = self.params.fit_window_us as f64 / 2.0;
        let points = &self.points;
        let count = |a: usize, b: usize| points[a..b].iter().map(|p| p.n).sum::<f64>();
        let mut half = base;
        let (lo, mid, hi) = loop {
            let lo = points.partition_point(|p| p.t < t - half);
            let mid = points.partition_point(|p| p.t < t);
            let hi = points.partition_point(|p| p.t <= t + half);
            if count(lo, hi) >= TARGET_FIT_EVENTS || half >= base * MAX_WIDENING {
                break (lo, mid, hi);
            }
            half = (half * 1.5).min(base * MAX_WIDENING);
        };
        let (left, right) = (count(lo, mid), count(mid, hi));
        let total = left + right;
        if total < MIN_FIT_EVENTS || left < MIN_SIDE_EVENTS || right < MIN_SIDE_EVENTS {
            return None;
        }
        let lopsided = 5.0 * left.min(right) < total;
        let degree = if lopsided {
            self.params.degree.min(END_DEGREE)
        } else {
            self.params.degree
        };
        self.fit_window(t, half, &points[lo..hi], degree as usize)
    }

    /// The weighted fit at `t` over `points`, within `half` µs of it.
    ///
    /// One pass over the points gathers the weighted moments of time (Σ w tᵏ up to t⁶, and
    /// with the polarity sign), of the positions, and of their squares: the normal equations,
    /// the matrix of the sandwich covariance and the residual sum of squares
    /// (Σ w x² − 2 aᵀb + aᵀMa) all follow from them. Positions are taken from the first
    /// point's, so that the sums of squares do not lose the residual's digits.
    fn fit_window(&self, t: f64, half: f64, points: &[Point], degree: usize) -> Option<LocalFit> {
        let has_on = points.iter().any(|p| p.s > 0.0);
        let has_off = points.iter().any(|p| p.s < 0.0);
        let polarity = has_on && has_off;
        let nt = degree + 1 + polarity as usize;
        let (x0, y0) = points.first().map_or((0.0, 0.0), |p| (p.x, p.y));
        let scale = half / 1000.0;
        // Σ w n tᵏ and Σ w² n tᵏ (k ≤ 6); Σ w n s tᵏ, Σ w² n s tᵏ (k ≤ 3); Σ w n x tᵏ,
        // Σ w n y tᵏ (k ≤ 3) and with s; Σ w (n x² + scatter / 2), likewise y.
        let (mut tw, mut tw2) = ([0.0f64; 7], [0.0f64; 7]);
        let (mut sw, mut sw2) = ([0.0f64; 4], [0.0f64; 4]);
        let (mut xw, mut yw) = ([0.0f64; 4], [0.0f64; 4]);
        let (mut xsw, mut ysw, mut xx, mut yy) = (0.0, 0.0, 0.0, 0.0);
        let mut count = 0.0;
        for p in points {
            // Time in units of the half window: |u| < 1 keeps the moments of order 6
            // well scaled whatever the window.
            let u = (p.t - t) / 1000.0 / scale;
            if u.abs() >= 1.0 {
                continue;
            }
            let c = 1.0 - u.abs().powi(3);
            let w = c * c * c;
            let (wn, w2n) = (w * p.n, w * w * p.n);
            let (x, y) = (p.x - x0, p.y - y0);
            let mut power = 1.0;
            for k in 0..7 {
                tw[k] += wn * power;
                tw2[k] += w2n * power;
                if k < 4 {
                    sw[k] += wn * p.s * power;
                    sw2[k] += w2n * p.s * power;
                    xw[k] += wn * x * power;
                    yw[k] += wn * y * power;
                }
                power *= u;
            }
            xsw += wn * x * p.s;
            ysw += wn * y * p.s;
            xx += w * (p.n * x * x + p.scatter / 2.0);
            yy += w * (p.n * y * y + p.scatter / 2.0);
            count += p.n;
        }
        let (sum_w, sum_w2) = (tw[0], tw2[0]);
        if count < (2 * nt + 2) as f64 || sum_w <= 0.0 {
            return None;
        }
        // The normal equations from the moments.
        let mut m = [[0.0; MAX_TERMS]; MAX_TERMS];
        let mut m2 = [[0.0; MAX_TERMS]; MAX_TERMS];
        let (mut bx, mut by) = ([0.0; MAX_TERMS], [0.0; MAX_TERMS]);
        for a in 0..=degree {
            m[a][..=degree].copy_from_slice(&tw[a..=a + degree]);
            m2[a][..=degree].copy_from_slice(&tw2[a..=a + degree]);
            bx[a] = xw[a];
            by[a] = yw[a];
        }
        if polarity {
            let q = degree + 1;
            for a in 0..=degree {
                m[a][q] = sw[a];
                m[q][a] = sw[a];
                m2[a][q] = sw2[a];
                m2[q][a] = sw2[a];
            }
            m[q][q] = sum_w;
            m2[q][q] = sum_w2;
            bx[q] = xsw;
            by[q] = ysw;
        }
        let inv = cholesky_inverse(&m, nt)?;
        let mut ax = mat_vec(&inv, &bx, nt);
        let mut ay = mat_vec(&inv, &by, nt);
        // Residual sums of squares: Σ w x² − aᵀ b (with a = M⁻¹ b, aᵀ M a = aᵀ b).
        let rx = (xx - dot(&ax, &bx, nt)).max(0.0);
        let ry = (yy - dot(&ay, &by, nt)).max(0.0);
        ax[0] += x0;
        ay[0] += y0;
        // Effective degrees of freedom of weighted data (Kish): (Σw)² / Σw².
        let n_eff = sum_w * sum_w / sum_w2;
        let dof = (n_eff - nt as f64).max(1.0);
        let correction = n_eff / dof;
        let var_x = rx / sum_w * correction;
        let var_y = ry / sum_w * correction;
        // Sandwich covariance per unit variance: M⁻¹ M2 M⁻¹.
        let mut cov = sandwich(&inv, &m2, nt);
        // Back from half windows to ms: the coefficient of uᵏ over scaleᵏ.
        let factor = |k: usize| {
            if k <= degree {
                scale.powi(k as i32)
            } else {
                1.0
            }
        };
        for (i, row) in cov.iter_mut().enumerate().take(nt) {
            ax[i] /= factor(i);
            ay[i] /= factor(i);
            for (j, c) in row.iter_mut().enumerate().take(nt) {
                *c /= factor(i) * factor(j);
            }
        }
        let normal_count = count as u32;
        let residual = ((rx + ry) / sum_w).sqrt();
        Some(LocalFit {
            polarity,
            degree,
            ax,
            ay,
            cov,
            var_x,
            var_y,
            events: normal_count,
            residual,
        })
    }
}

impl LocalFit {
    /// Position of an event of sign `s` at `dt` µs from the fit's centre.
    fn position_at(&self, dt_us: f64, s: f64) -> (f64, f64) {
        let (r, nt) = row(dt_us / 1000.0, s, self.degree, self.polarity);
        (dot(&r, &self.ax, nt), dot(&r, &self.ay, nt))
    }

    /// The sample at camera time `t_us`, the particle's time (the event times less the
    /// latency).
    fn sample(&self, t_us: i64) -> TrackSample {
        let sd = |k: usize, var: f64| (self.cov[k][k] * var).sqrt();
        let acc = self.degree >= 2;
        TrackSample {
            t_us,
            x: self.ax[0],
            y: self.ay[0],
            u: self.ax[1],
            v: self.ay[1],
            ax: if acc { 2.0 * self.ax[2] } else { f64::NAN },
            ay: if acc { 2.0 * self.ay[2] } else { f64::NAN },
            unc: [
                sd(0, self.var_x),
                sd(0, self.var_y),
                sd(1, self.var_x),
                sd(1, self.var_y),
                if acc {
                    2.0 * sd(2, self.var_x)
                } else {
                    f64::NAN
                },
                if acc {
                    2.0 * sd(2, self.var_y)
                } else {
                    f64::NAN
                },
            ],
            events: self.events,
            residual: self.residual,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Events of a particle on x = 100 + 2 t + 0.1 t², y = 50 + 0.5 t (t in ms), one ON
    /// event 1 px ahead and one OFF event 1 px behind every 20 µs, with a deterministic
    /// scatter of up to ±0.5 px across.
    fn parabola_events(duration_ms: f64) -> Vec<TrackEvent> {
        let mut events = Vec::new();
        let mut k = 0u32;
        let mut t_us = 0i64;
        while (t_us as f64) < duration_ms * 1000.0 {
            let t = t_us as f64 / 1000.0;
            let (x, y) = (100.0 + 2.0 * t + 0.1 * t * t, 50.0 + 0.5 * t);
            let jitter = ((k * 7919) % 11) as f64 / 10.0 - 0.5;
            for (p, lead) in [(1u8, 1.0), (0u8, -1.0)] {
                events.push(TrackEvent {
                    t: t_us,
                    x: (x + lead).round() as u16,
                    y: (y + jitter).round() as u16,
                    p,
                });
            }
            k += 1;
            t_us += 20;
        }
        events
    }

    #[test]
    fn a_parabola_gives_its_velocity_and_acceleration() {
        let params = TrackParams::default();
        let events = parabola_events(20.0);
        let (samples, _) = PathFitter::new(&events, &params).fit();
        assert!(samples.len() >= 35, "{} samples", samples.len());
        let mid = samples
            .iter()
            .find(|s| s.t_us == 10_000)
            .expect("a sample at 10 ms");
        let t = 10.0;
        assert!((mid.u - (2.0 + 0.2 * t)).abs() < 0.02, "{mid:?}");
        assert!((mid.v - 0.5).abs() < 0.02, "{mid:?}");
        assert!(
            (mid.ax - 0.2).abs() < 0.02 && mid.ay.abs() < 0.02,
            "{mid:?}"
        );
        // Pixels round the positions: within half a pixel of the path's midpoint.
        assert!(
            (mid.x - (100.0 + 2.0 * t + 0.1 * t * t)).abs() < 0.5,
            "{mid:?}"
        );
        assert!(mid.unc.iter().all(|u| u.is_finite() && *u > 0.0), "{mid:?}");
        // Every sample lies within the events' span, and none is far off the path.
        for s in &samples {
            let t = s.t_us as f64 / 1000.0;
            assert!((0.0..=20.0).contains(&t));
            assert!((s.u - (2.0 + 0.2 * t)).abs() < 0.15, "{s:?}");
        }
    }

    #[test]
    fn too_few_events_give_no_samples() {
        let params = TrackParams::default();
        let events = parabola_events(0.2);
        let (samples, _) = PathFitter::new(&events, &params).fit();
        assert!(samples.is_empty(), "{samples:?}");
        let (samples, outliers) = PathFitter::new(&[], &params).fit();
        assert!(samples.is_empty() && outliers == 0);
    }
}
