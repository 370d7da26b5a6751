//! Adaptive Dormand–Prince 5(4) integration of particle paths (Dormand & Prince, J. Comput.
//! Appl. Math. 6, 1980; step control after Hairer, Nørsett & Wanner, Solving ODE I, §II.4).
//!
//! This is the exact-path ground truth of `docs/sensor-model.md` §6 for flows without a
//! closed-form path (sinusoidal and cellular streams, superpositions, gridded CFD/DNS fields):
//! Euler sub-steps, as in PCM-SA, leave an integration error that looks like estimator bias in
//! curved flows, so the local error is held below [`TOLERANCE_PX`] instead.
//!
//! The integrator never loops forever and never panics: steps are never shorter than the
//! interval divided by [`MAX_STEPS`]; a step that cannot meet the tolerance at that length is
//! accepted anyway, and after [`MAX_ATTEMPTS`] attempts the rest of the interval is covered
//! with that smallest step. A non-finite velocity stops the particle at the last position
//! where the velocity was finite.

/// Absolute tolerance on the local position error of one step, px.
pub const TOLERANCE_PX: f64 = 1e-9;

/// Relative tolerance: keeps the error test meaningful where `TOLERANCE_PX` is below the
/// rounding error of large coordinates.
const RELATIVE_TOLERANCE: f64 = 1e-14;

/// The smallest step is the interval divided by this number.
pub const MAX_STEPS: usize = 100_000;

/// Step attempts (accepted or rejected) after which the integrator stops adapting and covers
/// the rest of the interval with the smallest step.
pub const MAX_ATTEMPTS: usize = 4 * MAX_STEPS;

const SAFETY: f64 = 0.9;
const SHRINK_MIN: f64 = 0.2;
const GROW_MAX: f64 = 10.0;

// Dormand–Prince 5(4) tableau (Hairer, Nørsett & Wanner, Table II.5.2).
const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const B1: f64 = 35.0 / 384.0;
const B3: f64 = 500.0 / 1113.0;
const B4: f64 = 125.0 / 192.0;
const B5: f64 = -2187.0 / 6784.0;
const B6: f64 = 11.0 / 84.0;
// Difference between the 5th- and the embedded 4th-order weights.
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;

type Vec2 = [f64; 2];

fn axpy(y: Vec2, terms: &[(f64, Vec2)], h: f64) -> Vec2 {
    let mut out = [0.0; 2];
    for (i, o) in out.iter_mut().enumerate() {
        let s: f64 = terms.iter().map(|(a, k)| a * k[i]).sum();
        *o = y[i] + h * s;
    }
    out
}

/// One Dormand–Prince step of length `h` (signed, µs) from `(t, y)` with `k1 = f(t, y)`.
/// Returns the 5th-order position, the slope there (first stage of the next step) and the
/// error estimate relative to the tolerance, or `None` if a stage velocity is not finite.
fn step(
    f: &impl Fn(f64, Vec2) -> Option<Vec2>,
    t: f64,
    y: Vec2,
    k1: Vec2,
    h: f64,
) -> Option<(Vec2, Vec2, f64)> {
    let k2 = f(t + C2 * h, axpy(y, &[(A21, k1)], h))?;
    let k3 = f(t + C3 * h, axpy(y, &[(A31, k1), (A32, k2)], h))?;
    let k4 = f(t + C4 * h, axpy(y, &[(A41, k1), (A42, k2), (A43, k3)], h))?;
    let k5 = f(
        t + C5 * h,
        axpy(y, &[(A51, k1), (A52, k2), (A53, k3), (A54, k4)], h),
    )?;
    let k6 = f(
        t + h,
        axpy(
            y,
            &[(A61, k1), (A62, k2), (A63, k3), (A64, k4), (A65, k5)],
            h,
        ),
    )?;
    let y_new = axpy(y, &[(B1, k1), (B3, k3), (B4, k4), (B5, k5), (B6, k6)], h);
    if !(y_new[0].is_finite() && y_new[1].is_finite()) {
        return None;
    }
    let k7 = f(t + h, y_new)?;
    let e = axpy(
        [0.0; 2],
        &[(E1, k1), (E3, k3), (E4, k4), (E5, k5), (E6, k6), (E7, k7)],
        h,
    );
    let scale = TOLERANCE_PX
        + RELATIVE_TOLERANCE
            * y[0]
                .abs()
                .max(y[1].abs())
                .max(y_new[0].abs().max(y_new[1].abs()));
    let err = e[0].hypot(e[1]) / scale;
    err.is_finite().then_some((y_new, k7, err))
}

/// Integrate `dx/dt = velocity(x, y, t)` (velocity in px/ms, t in µs) from `p` at `t0_us`
/// to `t1_us`; `t1_us < t0_us` integrates backward in time.
///
/// The local error of each step is held below [`TOLERANCE_PX`] (Euclidean norm of the
/// difference between the 5th- and 4th-order solutions). Non-finite input returns `p`; a
/// non-finite velocity stops the particle where it is (see the module documentation).
pub fn integrate(
    velocity: impl Fn(f64, f64, f64) -> (f64, f64),
    p: (f64, f64),
    t0_us: f64,
    t1_us: f64,
) -> (f64, f64) {
    let finite = p.0.is_finite() && p.1.is_finite() && t0_us.is_finite() && t1_us.is_finite();
    if !finite || t0_us == t1_us {
        return p;
    }
    // Slopes in px/µs.
    let f = |t: f64, y: Vec2| -> Option<Vec2> {
        let (u, v) = velocity(y[0], y[1], t);
        (u.is_finite() && v.is_finite()).then_some([u * 1e-3, v * 1e-3])
    };
    let direction = (t1_us - t0_us).signum();
    let length = (t1_us - t0_us).abs();
    let h_min = length / MAX_STEPS as f64;

    let mut t = t0_us;
    let mut y = [p.0, p.1];
    let Some(mut k1) = f(t, y) else {
        return p;
    };
    // First guess: a step that moves the particle by about one pixel; the controller adapts.
    let speed = k1[0].hypot(k1[1]);
    let mut h = if speed > 0.0 { 1.0 / speed } else { length };
    h = h.clamp(h_min, length);

    let mut attempts = 0usize;
    loop {
        let remaining = (t1_us - t) * direction;
        if remaining <= 0.0 {
            break;
        }
        attempts += 1;
        let exhausted = attempts > MAX_ATTEMPTS;
        if exhausted {
            h = h_min;
        }
        // Land exactly on t1; avoid leaving a sliver of the interval for a last tiny step.
        let last = h >= remaining * (1.0 - 1e-9);
        if last {
            h = remaining;
        }
        let forced = exhausted || h <= h_min;
        match step(&f, t, y, k1, direction * h) {
            Some((y_new, k_new, err)) if err <= 1.0 || forced => {
                t = if last { t1_us } else { t + direction * h };
                y = y_new;
                k1 = k_new;
                let factor = if err == 0.0 {
                    GROW_MAX
                } else {
                    (SAFETY * err.powf(-0.2)).clamp(SHRINK_MIN, GROW_MAX)
                };
                h = (h * factor).max(h_min);
            }
            Some((_, _, err)) => {
                h = (h * (SAFETY * err.powf(-0.2)).clamp(SHRINK_MIN, 1.0)).max(h_min);
            }
            // A stage left the region where the velocity is defined: shorten the step to
            // approach the boundary; at the smallest step the particle stops.
            None if forced => break,
            None => h = (h * 0.25).max(h_min),
        }
    }
    (y[0], y[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
        (a.0 - b.0).hypot(a.1 - b.1)
    }

    /// Solid-body rotation about (160, 120), positive ω clockwise on screen.
    fn rotation(omega: f64) -> impl Fn(f64, f64, f64) -> (f64, f64) {
        move |x, y, _| (-omega * (y - 120.0), omega * (x - 160.0))
    }

    fn rotated(p: (f64, f64), angle: f64) -> (f64, f64) {
        let (s, c) = angle.sin_cos();
        let (dx, dy) = (p.0 - 160.0, p.1 - 120.0);
        (160.0 + c * dx - s * dy, 120.0 + s * dx + c * dy)
    }

    #[test]
    fn rotation_matches_exact_solution_over_many_turns() {
        let omega = 0.06; // rad/ms: 12 px/ms at r = 200 px
        for &p in &[(360.0, 120.0), (170.0, 125.0), (40.0, 10.0)] {
            for &t1 in &[1_000.0, 20_000.0, 1_000_000.0] {
                let got = integrate(rotation(omega), p, 0.0, t1);
                let want = rotated(p, omega * t1 * 1e-3);
                assert!(dist(got, want) < 1e-6, "{p:?} t1 {t1}: {got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn stagnation_flow_matches_exponential_solution() {
        let k = 0.1; // 1/ms
        let velocity = |x: f64, y: f64, _t: f64| (k * (x - 100.0), -k * (y - 50.0));
        let p = (103.0, 250.0);
        for &t1 in &[5_000.0, 20_000.0, 30_000.0] {
            let got = integrate(velocity, p, 0.0, t1);
            let e = (k * t1 * 1e-3).exp();
            let want = (100.0 + 3.0 * e, 50.0 + 200.0 / e);
            assert!(dist(got, want) < 1e-6, "t1 {t1}: {got:?} vs {want:?}");
        }
    }

    #[test]
    fn backward_integration_inverts_forward() {
        let omega = -0.03;
        let p = (200.0, 80.0);
        let back = integrate(rotation(omega), p, 5_000.0, -15_000.0);
        assert!(dist(back, rotated(p, -omega * 20.0)) < 1e-6);
        let forth = integrate(rotation(omega), back, -15_000.0, 5_000.0);
        assert!(dist(forth, p) < 1e-6);
    }

    #[test]
    fn time_dependent_velocity_is_integrated_in_time() {
        // u = a t (t in ms): x = x0 + a t²/2.
        let velocity = |_x: f64, _y: f64, t: f64| (0.5 * t * 1e-3, 0.0);
        let got = integrate(velocity, (1.0, 2.0), 0.0, 20_000.0);
        assert!(dist(got, (1.0 + 0.25 * 400.0, 2.0)) < 1e-9);
    }

    #[test]
    fn equal_times_and_non_finite_input_return_the_start() {
        let v = rotation(0.1);
        assert_eq!(integrate(&v, (1.0, 2.0), 5.0, 5.0), (1.0, 2.0));
        assert_eq!(integrate(&v, (1.0, 2.0), f64::NAN, 5.0), (1.0, 2.0));
        assert_eq!(integrate(&v, (1.0, 2.0), 0.0, f64::INFINITY), (1.0, 2.0));
        let got = integrate(&v, (f64::NAN, 2.0), 0.0, 5.0);
        assert!(got.0.is_nan() && got.1 == 2.0);
    }

    #[test]
    fn nan_velocity_stops_the_particle() {
        let nan = |_x: f64, _y: f64, _t: f64| (f64::NAN, 1.0);
        assert_eq!(integrate(nan, (3.0, 4.0), 0.0, 1_000.0), (3.0, 4.0));
        // Moving at 1 px/ms towards a region x > 10 where the velocity is undefined: the
        // particle stops just before the boundary.
        let edge = |x: f64, _y: f64, _t: f64| {
            if x > 10.0 {
                (f64::NAN, 0.0)
            } else {
                (1.0, 0.0)
            }
        };
        let got = integrate(edge, (0.0, 0.0), 0.0, 50_000.0);
        assert!(got.0 <= 10.0 && got.0 > 9.9, "{got:?}");
        assert_eq!(got.1, 0.0);
    }

    #[test]
    fn discontinuous_and_singular_velocities_terminate() {
        // Chattering across x = 0: the tolerance cannot be met; integration still ends.
        let chatter = |x: f64, _y: f64, _t: f64| (-10.0 * x.signum(), 1.0);
        let got = integrate(chatter, (5.0, 0.0), 0.0, 10_000.0);
        assert!(got.0.abs() < 0.01, "{got:?}");
        assert!((got.1 - 10.0).abs() < 1e-6, "{got:?}");
        // Finite-time blow-up: dx/dt = x² reaches infinity at t = 1 ms from x0 = 1.
        let blow_up = |x: f64, _y: f64, _t: f64| (x * x, 0.0);
        let got = integrate(blow_up, (1.0, 0.0), 0.0, 5_000.0);
        assert!(got.0.is_finite() && got.0 > 1.0, "{got:?}");
        // Huge velocities overflow the position: stops, does not panic.
        let huge = |_x: f64, _y: f64, _t: f64| (1e306, 0.0);
        let got = integrate(huge, (0.0, 0.0), 0.0, 1e9);
        assert!(got.0.is_finite());
    }
}
