//! The pixel's photoreceptor: lin-log conversion, intensity-dependent first-order low-pass,
//! and the exact solution of the low-pass over one time step (sensor-model.md §2.2, §2.4, §3).

use super::params::SensorParams;
use crate::sim::fastmath;

/// The constants of the pixel model in simulation units (µs, ln intensity), sanitised so that
/// no parameter value, valid or not, can make the arithmetic panic or loop.
#[derive(Debug, Clone)]
pub(super) struct Response {
    knee: f64,
    ln_knee: f64,
    eps: f64,
    /// 2π f_3dB in rad/µs at and above the reference irradiance; 0 = no low-pass.
    omega_max: f64,
    reference: f64,
    dark: f64,
    /// `1/(reference + dark)`.
    inv_span: f64,
    /// The whole range of [`Response::log`], from irradiance 0 to `f32::MAX`.
    log_range: f64,
    pub theta_on: f64,
    pub theta_off: f64,
    pub sigma: f64,
    pub latency: f64,
    pub jitter: f64,
    pub refractory: f64,
}

/// The value of `v` clamped to `[lo, hi]`, or `fallback` when it is not a number.
pub(super) fn clean(v: f64, lo: f64, hi: f64, fallback: f64) -> f64 {
    if v.is_nan() {
        fallback
    } else {
        v.clamp(lo, hi)
    }
}

/// A usable irradiance: negative and NaN become 0, infinity the largest `f32`.
#[inline]
pub(super) fn clean_irradiance(i: f32) -> f32 {
    if i > 0.0 {
        i.min(f32::MAX)
    } else {
        0.0
    }
}

/// The slowest low-pass corner, rad/µs (a time constant of 1000 s, 0.16 mHz): any slower is
/// frozen over a recording, and the exact low-pass step `L_a + gap·(1 − e^(−x)) + m·(Δt −
/// (1 − e^(−x))/ω)` loses its lag term there: `1 − e^(−x)` keeps an absolute error of 1e-16,
/// so the lag's is 1e-16/ω µs, and for ω·Δt < 1e-16 the lag is 0 and `L` follows its input
/// (a corner of 1e-13 Hz gave a hundred times the events of one of 1e-11 Hz; a pixel in near
/// darkness with `cutoff_dark_irradiance = 0` would too). At the floor the lag is off by at
/// most 1e-7 µs, which moves `L` by the input's slope (per µs) times 1e-7.
pub(super) const OMEGA_FLOOR: f64 = 1e-9;

/// The smallest per-pixel threshold (v2e clamps mismatch draws at 0.01).
pub(super) const MIN_THRESHOLD: f64 = 0.01;

impl Response {
    pub fn new(p: &SensorParams) -> Self {
        let knee = clean(p.linlog_threshold, 0.0, 1e30, 0.0);
        let mut eps = clean(p.log_eps, 0.0, 1e30, 1e-3);
        if knee == 0.0 && eps == 0.0 {
            eps = 1e-3;
        }
        let cutoff = clean(p.cutoff_hz, 0.0, 1e12, 0.0);
        let reference = clean(p.cutoff_reference_irradiance, 0.0, 1e30, 0.0);
        let dark = clean(p.cutoff_dark_irradiance, 0.0, 1e30, 0.0);
        let mut response = Response {
            knee,
            ln_knee: if knee > 0.0 { fastmath::ln(knee) } else { 0.0 },
            eps,
            omega_max: std::f64::consts::TAU * cutoff * 1e-6,
            reference,
            dark,
            inv_span: 1.0 / (reference + dark),
            theta_on: clean(p.threshold_on, MIN_THRESHOLD, 1e3, 0.2),
            theta_off: clean(p.threshold_off, MIN_THRESHOLD, 1e3, 0.2),
            sigma: clean(p.threshold_sigma, 0.0, 1e3, 0.0),
            latency: clean(p.latency_us, 0.0, 1e12, 0.0),
            jitter: clean(p.jitter_us, 0.0, 1e12, 0.0),
            refractory: clean(p.refractory_us, 0.0, 1e12, 0.0),
            log_range: 0.0,
        };
        response.log_range = response.log(f32::MAX) - response.log(0.0);
        response.floor_omega();
        response
    }

    /// Raise the corner at and above the reference, and the dark irradiance, so that no
    /// irradiance gets a corner below [`OMEGA_FLOOR`] (ω ≥ `omega_max·dark/(reference +
    /// dark)`); with the low-pass off, nothing. The presets' corners lie far above the floor
    /// and are not changed, so the floor costs the pixel updates nothing.
    fn floor_omega(&mut self) {
        if !self.low_pass() {
            return;
        }
        self.omega_max = self.omega_max.max(OMEGA_FLOOR);
        if self.reference > 0.0 {
            // The darkest pixel's share of the corner, dark/(reference + dark), at least q.
            let q = OMEGA_FLOOR / self.omega_max;
            if q >= 1.0 {
                // Every pixel at the floor: a bandwidth independent of irradiance.
                self.reference = 0.0;
            } else if self.dark * (1.0 - q) < q * self.reference {
                self.dark = q * self.reference / (1.0 - q);
                self.inv_span = 1.0 / (self.reference + self.dark);
            }
        }
    }

    /// The whole range of the log response, from irradiance 0 to the largest `f32`.
    #[inline]
    pub fn log_range(&self) -> f64 {
        self.log_range
    }

    /// The photoreceptor's log response to irradiance `i` (sensor-model.md §2.2): `ln i`
    /// above the knee and its tangent line below it (continuous with a continuous slope, unlike
    /// v2e's `x·ln(T)/T` segment, which is kinked and decreasing for T < 1), or `ln(ε + i)`.
    /// The logarithm is [`fastmath::ln`], within about 1 ulp.
    #[inline(always)]
    pub fn log(&self, i: f32) -> f64 {
        let i = i as f64;
        if self.knee > 0.0 {
            if i >= self.knee {
                fastmath::ln(i)
            } else {
                self.ln_knee + (i - self.knee) / self.knee
            }
        } else {
            fastmath::ln(i + self.eps)
        }
    }

    /// [`Response::log`] of every lane, bit for bit, in lane-wise arithmetic
    /// ([`fastmath::ln_lanes`]) that the compiler may vectorise.
    #[inline(always)]
    pub fn log_lanes<const N: usize>(&self, i: [f32; N]) -> [f64; N] {
        let i = i.map(|v| v as f64);
        if self.knee > 0.0 {
            let knee = self.knee;
            // Lanes below the knee take the tangent line; their logarithm is not used.
            let ln = fastmath::ln_lanes(i.map(|v| if v >= knee { v } else { knee }));
            let mut out = [0.0; N];
            for ((o, &v), &l) in out.iter_mut().zip(&i).zip(&ln) {
                *o = if v >= knee {
                    l
                } else {
                    self.ln_knee + (v - knee) / knee
                };
            }
            out
        } else {
            fastmath::ln_lanes(i.map(|v| v + self.eps))
        }
    }

    /// `d log(i)/di`, the slope of [`Response::log`] at irradiance `i`.
    #[inline(always)]
    pub fn log_slope(&self, i: f64) -> f64 {
        if self.knee > 0.0 {
            1.0 / i.max(self.knee)
        } else {
            1.0 / (i + self.eps)
        }
    }

    /// Whether the photoreceptor low-pass is on.
    #[inline]
    pub fn low_pass(&self) -> bool {
        self.omega_max > 0.0
    }

    /// Relative bandwidth in (0, 1] at irradiance `i`: `min(1, (i + I_dark)/(I_ref + I_dark))`,
    /// v2e's `inten01 = (I + 20)/275` (§2.4), or `None` without intensity dependence.
    #[inline]
    pub fn brightness(&self, i: f64) -> Option<f64> {
        if self.reference > 0.0 {
            // A product with the stored reciprocal: within 1 ulp of the quotient, without a
            // division on every pixel update.
            let b = (i + self.dark) * self.inv_span;
            Some(if b < 1.0 { b } else { 1.0 })
        } else {
            None
        }
    }

    /// The low-pass corner `ω = 1/τ` in 1/µs at irradiance `i` (at least [`OMEGA_FLOOR`],
    /// to within rounding, with the low-pass on: [`Response::new`]).
    #[inline]
    pub fn omega(&self, i: f64) -> f64 {
        match self.brightness(i) {
            Some(b) => self.omega_max * b,
            None => self.omega_max,
        }
    }

    /// v2e's irradiance scaling of the shot-noise rate, `(0.25 − 1)·inten01 + 1` (§2.7): 1 in
    /// the dark, 0.25 at and above the reference irradiance.
    #[inline]
    pub fn shot_noise_factor(&self, i: f64) -> f64 {
        match self.brightness(i) {
            Some(b) => 1.0 - 0.75 * b,
            None => 1.0,
        }
    }
}

/// `1 − e^(−x)`. `exp` rather than `exp_m1` (twice as fast): the absolute error stays at
/// 1e-16 ([`fastmath::exp`]), which is all `L` needs — it is a sum of such terms of order one.
#[inline]
fn one_minus_exp(x: f64) -> f64 {
    1.0 - fastmath::exp(-x)
}

/// The parts of a low-pass step of corner ω over `Δt` that depend on ω and `Δt` alone:
/// `rise = 1 − e^(−ω·Δt)` and `lag = rise/ω` ([`Curve::end_value_from`]). Computed for many
/// pixels at once ([`Relaxation::lanes`]), so that their exponentials and divisions run in
/// vector instructions.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Relaxation {
    pub(super) rise: f64,
    lag: f64,
}

impl Relaxation {
    /// The relaxations of corners `omega` over `dt`, lane by lane, bit for bit
    /// [`Relaxation::new`] of each ([`fastmath::exp_lanes`]).
    #[inline(always)]
    pub(super) fn lanes<const N: usize>(omega: [f64; N], dt: f64) -> [Relaxation; N] {
        let decay = fastmath::exp_lanes(omega.map(|w| -(w * dt)));
        let rise = decay.map(|d| 1.0 - d);
        std::array::from_fn(|k| Relaxation {
            rise: rise[k],
            lag: rise[k] / omega[k],
        })
    }

    /// The relaxation of corner `omega` over `dt`.
    #[inline]
    pub(super) fn new(omega: f64, dt: f64) -> Relaxation {
        let rise = one_minus_exp(omega * dt);
        Relaxation {
            rise,
            lag: rise / omega,
        }
    }
}

/// The low-passed log intensity `L(s)` of one pixel over one step `[ta, tb]`.
///
/// The input `u(s) = u_a + m·(s − ta)` is linear in time (log intensity interpolated between
/// samples, as ESIM does, §2.1); the first-order filter `dL/ds = ω·(u − L)` with ω frozen at the
/// step's mean irradiance then has the exact solution
/// `L(s) = L_a + (u_a − L_a)·(1 − e^(−x)) + m·(Δs − (1 − e^(−x))/ω)`, `x = ω·Δs`, written so
/// that it loses no precision when ω·Δs is small. It has at most one extremum.
#[derive(Debug, Clone, Copy)]
pub(super) struct Curve {
    pub ta: f64,
    pub tb: f64,
    la: f64,
    kind: Kind,
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    /// `L(s) = L_a + slope·(s − ta)`: no low-pass (or a frozen one).
    Linear { slope: f64 },
    /// The exact low-pass response; `gap = u_a − L_a`.
    Relax { gap: f64, m: f64, omega: f64 },
}

/// Newton iterations stop when the time changes by less than this, µs.
const ROOT_TOLERANCE_US: f64 = 1e-7;

impl Curve {
    /// `L` follows the input exactly: from `ua` at `ta` to `ub` at `tb` (a jump when the step
    /// has no length).
    pub fn direct(ta: f64, tb: f64, ua: f64, ub: f64) -> Self {
        let dt = tb - ta;
        if dt > 1e-9 {
            Curve {
                ta,
                tb,
                la: ua,
                kind: Kind::Linear {
                    slope: (ub - ua) / dt,
                },
            }
        } else {
            Curve::constant(ta, ta, ub)
        }
    }

    /// `L` stays at `l` over the step.
    pub fn constant(ta: f64, tb: f64, l: f64) -> Self {
        Curve {
            ta,
            tb,
            la: l,
            kind: Kind::Linear { slope: 0.0 },
        }
    }

    /// The low-pass response starting from `la`, input from `ua` to `ub`, corner `omega`.
    pub fn low_pass(ta: f64, tb: f64, la: f64, ua: f64, ub: f64, omega: f64) -> Self {
        let dt = tb - ta;
        if !(omega > 0.0 && dt > 0.0) {
            return Curve::constant(ta, tb.max(ta), la);
        }
        // A product with the reciprocal: a step's many ramps share one division.
        let m = if dt > 1e-9 {
            (ub - ua) * (1.0 / dt)
        } else {
            0.0
        };
        Curve {
            ta,
            tb,
            la,
            kind: Kind::Relax {
                gap: ua - la,
                m,
                omega,
            },
        }
    }

    /// `L(ta)`.
    #[inline]
    pub fn start_value(&self) -> f64 {
        self.la
    }

    /// `L(s)`.
    #[inline]
    pub fn value(&self, s: f64) -> f64 {
        let ds = s - self.ta;
        match self.kind {
            Kind::Linear { slope } => self.la + slope * ds,
            Kind::Relax { gap, m, omega } => {
                self.relaxed(gap, m, omega, ds, one_minus_exp(omega * ds))
            }
        }
    }

    /// `L(tb)`.
    #[inline]
    pub fn end_value(&self) -> f64 {
        self.value(self.tb)
    }

    /// `L(tb)` of a low-pass curve given its [`Relaxation`] over the whole curve: the same
    /// value as [`Curve::end_value`], bit for bit, without its exponential and division.
    #[inline]
    pub fn end_value_from(&self, relax: Relaxation) -> f64 {
        match self.kind {
            Kind::Relax { gap, m, .. } => {
                let mut l = self.la + gap * relax.rise;
                if m != 0.0 {
                    l += m * ((self.tb - self.ta) - relax.lag);
                }
                l
            }
            Kind::Linear { .. } => self.end_value(),
        }
    }

    /// The low-pass response `ds` after `ta`, with `e1 = 1 − e^(−ω·ds)` (the same arithmetic as
    /// [`Curve::end_value_from`]).
    #[inline]
    fn relaxed(&self, gap: f64, m: f64, omega: f64, ds: f64, e1: f64) -> f64 {
        let mut l = self.la + gap * e1;
        if m != 0.0 {
            l += m * (ds - e1 / omega);
        }
        l
    }

    /// `1/ω`, finite even for a subnormal ω (where `e1·(1/ω)` would be 0·∞); 0 without a
    /// low-pass.
    #[inline]
    pub fn inv_omega(&self) -> f64 {
        match self.kind {
            Kind::Relax { omega, .. } => (1.0 / omega).min(f64::MAX),
            Kind::Linear { .. } => 0.0,
        }
    }

    /// `L(s)` as [`Curve::derivatives`] computes it, with `inv_omega` = [`Curve::inv_omega`]:
    /// a multiplication where [`Curve::value`] divides by ω, off the crossing path's chain
    /// of dependent operations (it may differ from [`Curve::value`] in the last bit).
    #[inline]
    pub fn value_fast(&self, s: f64, inv_omega: f64) -> f64 {
        self.derivatives(s, inv_omega).0
    }

    /// `L(s)`, `dL/ds` and `d²L/ds²` of the low-pass response from one exponential, for the
    /// root finder: `inv_omega` is `1/ω`, so that the value needs no division (it may differ
    /// from [`Curve::value`] in the last bit, which moves a root by far less than its
    /// tolerance).
    #[inline]
    fn derivatives(&self, s: f64, inv_omega: f64) -> (f64, f64, f64) {
        let ds = s - self.ta;
        match self.kind {
            Kind::Linear { slope } => (self.la + slope * ds, slope, 0.0),
            Kind::Relax { gap, m, omega } => {
                let e = fastmath::exp(-omega * ds);
                let e1 = 1.0 - e;
                let value = self.la + gap * e1 + m * (ds - e1 * inv_omega);
                let slope = gap * omega * e + m * e1;
                let curvature = -omega * e * (gap * omega - m);
                (value, slope, curvature)
            }
        }
    }

    /// Whether `L` may have an extremum inside the step (input and output move apart).
    #[inline]
    pub fn may_turn(&self) -> bool {
        match self.kind {
            Kind::Linear { .. } => false,
            Kind::Relax { gap, m, .. } => m != 0.0 && gap != 0.0 && (gap > 0.0) != (m > 0.0),
        }
    }

    /// The time of the extremum strictly inside the step, if any: where `u(s) = L(s)`.
    pub fn extremum(&self) -> Option<f64> {
        let Kind::Relax { gap, m, omega } = self.kind else {
            return None;
        };
        if m == 0.0 || gap == 0.0 || (gap > 0.0) == (m > 0.0) {
            return None;
        }
        let x = (-gap * omega / m).ln_1p();
        let s = self.ta + x / omega;
        (s > self.ta && s < self.tb).then_some(s)
    }

    /// The time in `[s0, s1]` where `L` reaches `level`, given that `L` is monotone there
    /// with `L(s0) = l0`, `L(s1) = l1` and `level` between them. `inv_omega` is
    /// [`Curve::inv_omega`], which the caller computes once for all crossings of a piece.
    pub fn root(&self, level: f64, s0: f64, s1: f64, l0: f64, l1: f64, inv_omega: f64) -> f64 {
        if s1 <= s0 || l1 == l0 {
            return s0;
        }
        let s = match self.kind {
            Kind::Linear { slope } => self.ta + (level - self.la) / slope,
            Kind::Relax { gap, m: 0.0, omega } => {
                // Pure relaxation: invert `L_a + gap·(1 − e^(−x)) = level` (IEBCS, §2.4).
                let r = (level - self.la) / gap;
                self.ta - (-r).ln_1p() / omega
            }
            Kind::Relax { .. } => self.newton(level, s0, s1, l0, l1, inv_omega),
        };
        if s.is_nan() {
            s0
        } else {
            s.clamp(s0, s1)
        }
    }

    /// The time where `L` reaches `level` on the monotone piece from `(s0, l0)` to `(s1, l1)`,
    /// estimated without an exponential: the cubic Hermite interpolant of the inverse function
    /// `s(L)`, whose slopes at the ends are `1/L′` with `L′ = ω·(u − L)` (the input `u` is known at
    /// every time). Its error is of fourth order in the piece's length: on a 1280×720 uniform flow
    /// of 0.00152 particles per pixel (`gen4`) the root finder then needs 1.28 evaluations per
    /// crossing instead of 1.88 from the linear interpolation. Falls back to the linear
    /// interpolation where the slopes do not give a monotone interpolant (an end at an extremum,
    /// where `L′ = 0`), following Fritsch & Carlson (SIAM J. Numer. Anal. 17, 1980): both end
    /// slopes at most three times the secant's.
    #[inline]
    fn inverse_hermite(&self, level: f64, s0: f64, s1: f64, l0: f64, l1: f64) -> f64 {
        let theta = (level - l0) / (l1 - l0);
        let linear = s0 + theta * (s1 - s0);
        let Kind::Relax { gap, m, omega } = self.kind else {
            return linear;
        };
        let ua = self.la + gap;
        let slope_at = |s: f64, l: f64| omega * (ua + m * (s - self.ta) - l);
        let (d0, d1) = (slope_at(s0, l0), slope_at(s1, l1));
        // `alpha`, `beta`: the end slopes of `s(L)` over the secant's, `S/L′` with `S` the
        // secant slope of `L`, each with one division.
        let (dl, ds) = (l1 - l0, s1 - s0);
        let (alpha, beta) = (dl / (ds * d0), dl / (ds * d1));
        if !(alpha > 0.0 && alpha <= 3.0 && beta > 0.0 && beta <= 3.0) {
            return linear;
        }
        let t2 = theta * theta;
        let t3 = t2 * theta;
        let h01 = 3.0 * t2 - 2.0 * t3;
        let h10 = t3 - 2.0 * t2 + theta;
        let h11 = t3 - t2;
        s0 + (s1 - s0) * (h01 + alpha * h10 + beta * h11)
    }

    /// Safeguarded Halley iteration (cubic convergence; `L`, `L′` and `L″` come from one
    /// exponential) from the linear interpolation of the bracket, with bisection whenever a
    /// step would leave the bracket. A Halley step `h` leaves an error of about `K·|h|³`,
    /// `K = c² + ω|c|/3` with `c = L″/(2L′)` (here `L‴ = −ω·L″`); a Newton step (taken when
    /// the Halley correction is large) about `|c|·h²`. Once that is below the tolerance the
    /// step is taken without a further evaluation.
    ///
    /// The iterations form one chain of dependent operations, so it is written with one
    /// division per step on that chain: the Halley step `f/L′ / (1 − f·c/L′)` as
    /// `2fL′ / (2L′² − fL″)`, and `1/ω` given (the stopping rule's `c` is a division off
    /// the chain).
    fn newton(&self, level: f64, s0: f64, s1: f64, l0: f64, l1: f64, inv_omega: f64) -> f64 {
        let omega = match self.kind {
            Kind::Relax { omega, .. } => omega,
            Kind::Linear { .. } => 0.0,
        };
        let increasing = l1 > l0;
        let (mut lo, mut hi) = (s0, s1);
        let mut s = self.inverse_hermite(level, s0, s1, l0, l1);
        for _ in 0..40 {
            let (value, slope, curvature) = self.derivatives(s, inv_omega);
            let f = value - level;
            if f == 0.0 {
                return s;
            }
            if (f < 0.0) == increasing {
                lo = s;
            } else {
                hi = s;
            }
            // Halley's denominator 1 − f·c/L′ > ½, i.e. 2L′² − fL″ > L′².
            let slope2 = slope * slope;
            let denominator = 2.0 * slope2 - f * curvature;
            let halley = denominator > slope2;
            let h = if halley {
                2.0 * f * slope / denominator
            } else {
                f / slope
            };
            let mut next = s - h;
            let in_bracket = next > lo && next < hi;
            if !in_bracket {
                next = 0.5 * (lo + hi);
            }
            let step = (next - s).abs();
            s = next;
            if step <= ROOT_TOLERANCE_US || hi - lo <= ROOT_TOLERANCE_US {
                break;
            }
            if in_bracket {
                let c = curvature / (2.0 * slope);
                let predicted = if halley {
                    (c * c + omega * c.abs() / 3.0) * step * step * step
                } else {
                    c.abs() * step * step
                };
                if predicted < ROOT_TOLERANCE_US {
                    break;
                }
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::{Curve, Relaxation, Response, OMEGA_FLOOR};
    use crate::sim::sensor::SensorParams;
    use crate::test_rng::xorshift;

    /// `s` in `[s0, s1]` where the monotone `curve` reaches `level`, by bisection.
    fn bisect(curve: &Curve, level: f64, s0: f64, s1: f64) -> f64 {
        let sign = if curve.value(s1) > curve.value(s0) {
            1.0
        } else {
            -1.0
        };
        crate::sim::sensor::tests::bisect(|s| sign * (curve.value(s) - level), s0, s1)
    }

    /// On random low-pass responses to linear inputs (rising, falling, with and without an
    /// extremum inside the step), the crossing times agree with bisection to 1e-6 µs, and
    /// the inverse Hermite start of the root finder stays in the bracket and, on the pieces
    /// where it does not fall back to the linear interpolation (an end at an extremum), its
    /// mean error is under 0.35 of the linear start's.
    #[test]
    fn crossing_times_agree_with_bisection_and_the_start_is_close() {
        let mut next = xorshift(0xC0FF_EE11);
        let mut uniform = move || (next() >> 11) as f64 / (1u64 << 53) as f64;
        let mut hermite_starts = 0;
        let (mut hermite_error, mut linear_error) = (0.0, 0.0);
        for _ in 0..2_000 {
            let (ta, dt) = (1e3 * uniform(), 1.0 + 300.0 * uniform());
            let tb = ta + dt;
            let omega = 0.002 + 0.08 * uniform();
            let (la, ua, ub) = (
                uniform() - 0.5,
                2.0 * uniform() - 1.0,
                2.0 * uniform() - 1.0,
            );
            let curve = Curve::low_pass(ta, tb, la, ua, ub, omega);
            let mut pieces = vec![ta];
            pieces.extend(curve.extremum());
            pieces.push(tb);
            for piece in pieces.windows(2) {
                let (s0, s1) = (piece[0], piece[1]);
                let (l0, l1) = (curve.value(s0), curve.value(s1));
                if (l1 - l0).abs() < 1e-6 {
                    continue;
                }
                let level = l0 + (0.05 + 0.9 * uniform()) * (l1 - l0);
                let want = bisect(&curve, level, s0, s1);
                let got = curve.root(level, s0, s1, l0, l1, curve.inv_omega());
                assert!((got - want).abs() < 1e-6, "{curve:?}: {got} vs {want}");
                let start = curve.inverse_hermite(level, s0, s1, l0, l1);
                let linear = s0 + (level - l0) / (l1 - l0) * (s1 - s0);
                assert!(
                    start >= s0 && start <= s1,
                    "{curve:?}: start {start} outside [{s0}, {s1}]"
                );
                if start != linear {
                    hermite_starts += 1;
                    hermite_error += (start - want).abs();
                    linear_error += (linear - want).abs();
                }
            }
        }
        assert!(hermite_starts > 300, "{hermite_starts}");
        assert!(
            hermite_error < 0.35 * linear_error,
            "{hermite_error} vs {linear_error}"
        );
    }

    /// A corner of 1e-13 Hz, or a pixel in near darkness without a dark irradiance, takes the
    /// slowest corner, [`OMEGA_FLOOR`]: over a 100 µs ramp `L` then barely moves, as the exact
    /// solution `L = L_a + gap·x + m·Δt·(x/2 − …)`, `x = ω·Δt`, says (before the floor, `1 −
    /// e^(−x)` rounded to 0 made `L` follow its input with no lag at all). Without a low-pass
    /// there is no floor, and a normal corner is not touched by it.
    #[test]
    fn a_frozen_low_pass_stays_frozen() {
        let slow = SensorParams {
            cutoff_hz: 1e-13,
            ..SensorParams::gen4()
        };
        let dark = SensorParams {
            cutoff_dark_irradiance: 0.0,
            ..SensorParams::gen4()
        };
        let (h, la, ua, ub) = (100.0, 0.25, 0.5, 1.5);
        for (params, irradiance) in [(&slow, 1.0), (&dark, 1e-30), (&dark, 0.0)] {
            let omega = Response::new(params).omega(irradiance);
            assert!((omega / OMEGA_FLOOR - 1.0).abs() < 1e-12, "{omega}");
            let x = omega * h;
            let exact = la + (ua - la) * x + (ub - ua) * x / 2.0;
            let curve = Curve::low_pass(0.0, h, la, ua, ub, omega);
            for l in [
                curve.end_value(),
                curve.end_value_from(Relaxation::new(omega, h)),
                curve.value_fast(h, curve.inv_omega()),
            ] {
                assert!((l - exact).abs() < 1e-8, "{l} against {exact}");
            }
        }
        let off = SensorParams {
            cutoff_hz: 0.0,
            ..SensorParams::gen4()
        };
        assert_eq!(Response::new(&off).omega(1.0), 0.0);
        let gen4 = Response::new(&SensorParams::gen4());
        assert_eq!(gen4.omega(1e6), std::f64::consts::TAU * 1e4 * 1e-6);
    }
}
