//! Event deformation: events of a window moved against the non-uniform part of a predicted
//! affine motion, the event-space analogue of PIV window deformation
//! ([`crate::deform::frames`]).

/// A predicted affine motion around a point, used to remove its non-uniform part from the
/// events: the event-space analogue of window deformation in PIV (Scarano 2002, Meas. Sci.
/// Technol. 13:R1).
///
/// Near the centre `c` the velocity is `v(x) = v_c + G (x − c)`. A particle at `p` at time
/// `t0` follows the exact path of this affine field, `x(t) − c = e^{G dt}(p − c) +
/// φ(G dt) v_c dt` with `dt = t − t0` and `φ(A) = (e^A − I) A⁻¹ = Σ A^k/(k + 1)!`; so an event
/// at `x` came from `p − c = e^{−G dt}(x − c) − φ(−G dt) v_c dt`. Each event is moved to
/// `p + v_c dt`: all events then appear to move with the centre's velocity `v_c`, and a window
/// estimate refers to its centre at `t0` instead of to wherever its few particles happened to
/// be. Using the path rather than its first-order part `p + v(p) dt` also removes the
/// curvature of the trails (the centripetal acceleration of a rotation, `G² (p − c) dt²/2`:
/// 1 px at 128 px from the centre of a 0.02 rad/ms turntable after 6.5 ms), as higher-order
/// trajectory models do for time-resolved PIV (Lynch & Scarano 2013, Meas. Sci. Technol.
/// 24:035305).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deformation {
    /// Centre `c`, image px.
    pub centre: [f64; 2],
    /// Predicted velocity `v_c` at the centre, px/ms.
    pub velocity: [f64; 2],
    /// Velocity gradient `G[i][j] = ∂v_i/∂x_j`, 1/ms (rows: u, v; columns: x, y).
    pub gradient: [[f64; 2]; 2],
    /// Time `t0` at which particles are at their reference position, µs.
    pub t0_us: i64,
}

impl Deformation {
    /// `Σ|G_ij|`, 1/ms: an event `dt` from `t0` is deformed while `Σ|G_ij dt|` stays within
    /// [`MAX_STRAIN`].
    fn strain_rate(&self) -> f64 {
        self.gradient.iter().flatten().map(|g| g.abs()).sum()
    }

    /// The paths of events at most `max_dt_ms` from `t0` and `max_offset_px` (per axis) from
    /// the centre, as polynomials in `dt` ([`AffinePaths`]).
    pub(crate) fn paths(&self, max_dt_ms: f64, max_offset_px: f64) -> AffinePaths {
        AffinePaths::new(self, max_dt_ms, max_offset_px)
    }

    /// Where an event at window-relative offset `d = x − c` and time `dt_ms` after `t0` is
    /// moved, relative to `c` (one event; windows use [`Deformation::paths`]).
    #[cfg(test)]
    pub(crate) fn undeform(&self, d: [f64; 2], dt_ms: f64) -> [f64; 2] {
        let reach = d[0].abs().max(d[1].abs());
        self.paths(dt_ms.abs(), reach).undeform(d, dt_ms)
    }

    /// [`Deformation::undeform`] summed term by term to convergence: the reference the
    /// polynomials are tested against.
    #[cfg(test)]
    fn undeform_by_series(&self, d: [f64; 2], dt_ms: f64) -> [f64; 2] {
        let g = self.gradient;
        // A = −G dt: the flow map of the affine field, backwards over dt.
        let a = [
            [-g[0][0] * dt_ms, -g[0][1] * dt_ms],
            [-g[1][0] * dt_ms, -g[1][1] * dt_ms],
        ];
        let norm = a.iter().flatten().map(|x| x.abs()).sum::<f64>();
        if norm.is_nan() || norm > MAX_STRAIN {
            return d;
        }
        let times_a = |v: [f64; 2]| {
            [
                a[0][0] * v[0] + a[0][1] * v[1],
                a[1][0] * v[0] + a[1][1] * v[1],
            ]
        };
        // e^A d = Σ A^k d / k! and φ(A) v_c = Σ A^k v_c / (k + 1)!, summed together.
        let vc = self.velocity;
        let (mut e, mut term_e) = (d, d);
        let (mut f, mut term_f) = (vc, vc);
        for k in 1..64 {
            term_e = times_a(term_e).map(|x| x / k as f64);
            term_f = times_a(term_f).map(|x| x / (k + 1) as f64);
            e = [e[0] + term_e[0], e[1] + term_e[1]];
            f = [f[0] + term_f[0], f[1] + term_f[1]];
            let size = term_e[0].abs() + term_e[1].abs();
            if size + (term_f[0].abs() + term_f[1].abs()) * dt_ms.abs() < 1e-12 {
                break;
            }
        }
        // p − c = e^{−G dt}(x − c) − φ(−G dt) v_c dt, moved to p + v_c dt.
        [e[0] + (vc[0] - f[0]) * dt_ms, e[1] + (vc[1] - f[1]) * dt_ms]
    }
}

/// Most terms of the path polynomials (the series of `e^A` at `Σ|A_ij|` = [`MAX_STRAIN`]
/// needs about 40 for 1e-10 px).
const MAX_TERMS: usize = 64;
/// Truncation error allowed in the path polynomials, px (f32 positions resolve about 4e-6
/// px at 40 px).
const PATH_TOLERANCE_PX: f64 = 1e-10;

/// The exact affine paths of a [`Deformation`] for one window's events, as polynomials in
/// the time offset `dt`. With `B = −G`, every power of the 2 × 2 matrix is `B^k = p_k I +
/// q_k B` (Cayley–Hamilton: `B² = tr(B) B − det(B) I`), so
///
/// ```text
/// e^{B dt} = α(dt) I + β(dt) B,             α = Σ p_k dt^k/k!,  β = Σ q_k dt^k/k!,
/// φ(B dt) v_c − v_c = dt (γ(dt) v_c + δ(dt) B v_c),
///                                           γ = Σ p_{k+1} dt^k/(k+2)!,  δ = Σ q_{k+1} dt^k/(k+2)!.
/// ```
///
/// The four scalar series are computed once per window and truncated where their terms fall
/// below [`PATH_TOLERANCE_PX`] over the window's time and space, so each event costs four
/// Horner evaluations instead of a matrix series summed term by term.
#[derive(Debug, Clone)]
pub(crate) struct AffinePaths {
    /// `B = −G` as `[b00, b01, b10, b11]`.
    b: [f64; 4],
    /// `B v_c`.
    b_velocity: [f64; 2],
    velocity: [f64; 2],
    strain_rate: f64,
    terms: usize,
    /// Coefficients of α, β, γ, δ, term by term.
    coefficients: [[f64; 4]; MAX_TERMS],
}

impl AffinePaths {
    fn new(deformation: &Deformation, max_dt_ms: f64, max_offset_px: f64) -> AffinePaths {
        let g = deformation.gradient;
        let b = [-g[0][0], -g[0][1], -g[1][0], -g[1][1]];
        let vc = deformation.velocity;
        let (trace, det) = (b[0] + b[3], b[0] * b[3] - b[1] * b[2]);
        let strain_rate = deformation.strain_rate();
        // Events beyond MAX_STRAIN are left as they are, so the series need not reach them.
        let reach = (strain_rate * max_dt_ms.abs()).min(MAX_STRAIN);
        let scale = max_offset_px.abs() + (vc[0].abs() + vc[1].abs()) * max_dt_ms.abs() + 1.0;
        let mut paths = AffinePaths {
            b,
            b_velocity: [b[0] * vc[0] + b[1] * vc[1], b[2] * vc[0] + b[3] * vc[1]],
            velocity: vc,
            strain_rate,
            terms: 1,
            coefficients: [[0.0; 4]; MAX_TERMS],
        };
        // (p_k, q_k)/k! for k and k + 1.
        let next = |(p, q): (f64, f64), k: usize| {
            let k1 = (k + 1) as f64;
            (-q * det / k1, (p + q * trace) / k1)
        };
        let mut current = (1.0, 0.0);
        // (reach^k / k!) · scale bounds the k-th term of every series.
        let mut bound = scale;
        for k in 0..MAX_TERMS {
            let following = next(current, k);
            // p_{k+1}/(k+2)! = (p_{k+1}/(k+1)!)/(k+2).
            let k2 = (k + 2) as f64;
            paths.coefficients[k] = [current.0, current.1, following.0 / k2, following.1 / k2];
            paths.terms = k + 1;
            bound *= reach / (k + 1) as f64;
            if bound.is_nan() || bound < PATH_TOLERANCE_PX {
                break;
            }
            current = following;
        }
        // Gradients so large that the coefficients overflow move no event (all exceed
        // MAX_STRAIN but those at dt = 0, which an infinite rate leaves in place too).
        if paths.coefficients[..paths.terms]
            .iter()
            .flatten()
            .any(|c| !c.is_finite())
        {
            paths.strain_rate = f64::INFINITY;
        }
        paths
    }

    /// Where an event at offset `d = x − c` and time `dt_ms` after `t0` is moved, relative to
    /// `c`: `p − c + v_c dt` with `p − c = e^{−G dt}(x − c) − φ(−G dt) v_c dt`. Events beyond
    /// [`MAX_STRAIN`] (or with a non-finite gradient) stay where they are.
    #[inline]
    pub(crate) fn undeform(&self, d: [f64; 2], dt_ms: f64) -> [f64; 2] {
        let norm = self.strain_rate * dt_ms.abs();
        if norm.is_nan() || norm > MAX_STRAIN {
            return d;
        }
        let mut s = [0.0; 4];
        for c in self.coefficients[..self.terms].iter().rev() {
            s = [
                s[0] * dt_ms + c[0],
                s[1] * dt_ms + c[1],
                s[2] * dt_ms + c[2],
                s[3] * dt_ms + c[3],
            ];
        }
        let [alpha, beta, gamma, delta] = s;
        let b = self.b;
        let bd = [b[0] * d[0] + b[1] * d[1], b[2] * d[0] + b[3] * d[1]];
        let (vc, bv, dt2) = (self.velocity, self.b_velocity, dt_ms * dt_ms);
        [
            alpha * d[0] + beta * bd[0] - dt2 * (gamma * vc[0] + delta * bv[0]),
            alpha * d[1] + beta * bd[1] - dt2 * (gamma * vc[1] + delta * bv[1]),
        ]
    }
}

/// Largest `Σ|G_ij dt|` for which events are deformed: beyond it the affine prediction
/// folds the window over itself within the slab and the events are left as they are.
const MAX_STRAIN: f64 = 8.0;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn deformation_inverts_affine_paths() {
        // Shear, strain and rotation plus translation: p moves along dx/dt = v_c + G (x − c),
        // integrated here by RK4 in 1000 steps (positions relative to c).
        let d = Deformation {
            centre: [5.0, 7.0],
            velocity: [1.5, -0.5],
            gradient: [[0.01, -0.03], [0.03, 0.02]],
            t0_us: 1000,
        };
        let g = d.gradient;
        let f = |x: [f64; 2]| {
            [
                d.velocity[0] + g[0][0] * x[0] + g[0][1] * x[1],
                d.velocity[1] + g[1][0] * x[0] + g[1][1] * x[1],
            ]
        };
        for (p, dt) in [([3.0, -4.0], 6.5), ([-10.0, 2.0], -6.5), ([0.0, 0.0], 3.0)] {
            let (steps, mut x) = (1000, p);
            let h = dt / steps as f64;
            for _ in 0..steps {
                let k1 = f(x);
                let k2 = f([x[0] + 0.5 * h * k1[0], x[1] + 0.5 * h * k1[1]]);
                let k3 = f([x[0] + 0.5 * h * k2[0], x[1] + 0.5 * h * k2[1]]);
                let k4 = f([x[0] + h * k3[0], x[1] + h * k3[1]]);
                for k in 0..2 {
                    x[k] += h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]);
                }
            }
            let moved = d.undeform(x, dt);
            let expected = [p[0] + d.velocity[0] * dt, p[1] + d.velocity[1] * dt];
            for k in 0..2 {
                assert!(
                    (moved[k] - expected[k]).abs() < 1e-9,
                    "{moved:?} {expected:?}"
                );
            }
        }
    }

    #[test]
    fn deformation_follows_the_circular_paths_of_a_rotation() {
        // Solid-body rotation about o = c + (−40, 25), Ω = 0.02 rad/ms: v(x) = Ω J (x − o).
        let omega = 0.02f64;
        let (c, o) = ([100.0, 80.0], [60.0, 105.0]);
        let velocity = [-omega * (c[1] - o[1]), omega * (c[0] - o[0])];
        let d = Deformation {
            centre: c,
            velocity,
            gradient: [[0.0, -omega], [omega, 0.0]],
            t0_us: 0,
        };
        for (p, dt) in [
            ([110.0, 70.0], 6.5),
            ([85.0, 95.0], -6.5),
            ([100.0, 80.0], 5.0),
        ] {
            let (s, co) = (omega * dt).sin_cos();
            let r = [p[0] - o[0], p[1] - o[1]];
            let x = [o[0] + co * r[0] - s * r[1], o[1] + s * r[0] + co * r[1]];
            let moved = d.undeform([x[0] - c[0], x[1] - c[1]], dt);
            let expected = [
                p[0] - c[0] + velocity[0] * dt,
                p[1] - c[1] + velocity[1] * dt,
            ];
            for k in 0..2 {
                assert!(
                    (moved[k] - expected[k]).abs() < 1e-9,
                    "{moved:?} {expected:?}"
                );
            }
        }
    }

    proptest! {
        /// The per-window path polynomials equal the series summed event by event, up to the
        /// strain limit where deformation stops.
        #[test]
        fn path_polynomials_equal_the_series(
            g in prop::array::uniform4(-0.3f64..0.3), v in prop::array::uniform2(-5.0f64..5.0),
            d in prop::array::uniform2(-40.0f64..40.0), dt in -15.0f64..15.0,
        ) {
            let deformation = Deformation {
                centre: [0.0, 0.0],
                velocity: v,
                gradient: [[g[0], g[1]], [g[2], g[3]]],
                t0_us: 0,
            };
            let paths = deformation.paths(15.0, 40.0);
            let (fast, series) = (paths.undeform(d, dt), deformation.undeform_by_series(d, dt));
            for k in 0..2 {
                prop_assert!((fast[k] - series[k]).abs() < 1e-9 * (1.0 + series[k].abs()),
                    "{fast:?} vs {series:?}");
            }
        }
    }
}
