//! Newton ascent on the IWE's Σ I² with its analytic gradient and Hessian.
//!
//! Gallego, Rebecq & Scaramuzza (CVPR 2018) maximise the contrast with derivatives of the
//! objective in the motion parameters instead of scanning them. With a Gaussian splat the
//! IWE is a smooth function of the velocity, and so are Σ I² and the variance (which differs
//! from Σ I² by a scale and a constant on a canvas that keeps every event), so Newton steps
//! converge fast once inside the peak's basin, whose half-width is about the splat width over
//! the events' r.m.s. time, ≈ 0.3 px/ms for σ = 0.8 px and T = 10 ms: about tenfold per step
//! rather than quadratically, because the kernel's cut-off at ±2.5 σ makes the analytic
//! Hessian 5–15 % smaller than the objective's (see the iwe tests). The start
//! comes from the pair-velocity histogram ([`super::votes`]), which is good to a fraction
//! of its cell.

use super::iwe::{derivatives, Canvas, Derivatives, Events, SplatTable, Workspace};

/// Newton iterations at most.
const MAX_STEPS: usize = 12;
/// Largest step, px/ms: about the basin's half-width.
const TRUST: f64 = 0.25;
/// Converged when a step is shorter than this, px/ms.
const TOLERANCE: f64 = 5e-4;
/// A Newton step shorter than this, px/ms, is the last: taken without evaluating.
const FINISH: f64 = 5e-3;
/// A Newton step shorter than this, px/ms, and at most [`CONTRACTION`] times the whole Newton step
/// before it, is also the last: the steps are contracting (measured on windows of a 1280×720
/// uniform flow of 0.00152 particles per pixel, `gen4`: by about tenfold per step), and with a
/// contraction ratio ρ ≤ 0.25 the distance left after it is below ρ/(1 − ρ) of the step, ≈ 0.007
/// px/ms at most (test: at most 0.0026 px/ms over synthetic windows; those windows move by less
/// than 0.009 px/ms in 99 % against the [`FINISH`]-only rule). Saves one evaluation in about a
/// third of the windows (derivative evaluations 10 964 → 9 832 over 3 548 ascents on two such
/// fields); the accuracy tests' RMS errors change by at most 0.2 %.
const FINISH_CONTRACTED: f64 = 0.02;
/// See [`FINISH_CONTRACTED`].
const CONTRACTION: f64 = 0.25;
/// Halvings of a step that lowered the objective before giving up.
const BACKTRACK: usize = 4;

/// The maximum found: velocity, and Σ I² at the last evaluated velocity (the last step, taken
/// without evaluating, changes it only to second order: the gradient vanishes there).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ascent {
    pub velocity: [f64; 2],
    pub squares: f64,
}

/// Climb Σ I² from `start` inside the box `centre ± half` (each axis), which `canvas` must
/// cover: Newton steps where the Hessian is negative definite, gradient steps of at most
/// [`TRUST`] elsewhere, each step halved while it lowers the objective; at most
/// [`MAX_STEPS`] steps.
pub(crate) fn ascend(
    events: &Events,
    start: [f64; 2],
    centre: [f64; 2],
    half: f64,
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
) -> Ascent {
    let clamp = |v: [f64; 2]| {
        [
            v[0].clamp(centre[0] - half, centre[0] + half),
            v[1].clamp(centre[1] - half, centre[1] + half),
        ]
    };
    let mut v = clamp(start);
    let mut d = derivatives(events, v, canvas, table, work);
    // Length of the last step if it was a whole (not halved) Newton step.
    let mut last_newton: Option<f64> = None;
    for _ in 0..MAX_STEPS {
        let (step, newton) = direction(&d);
        if !(step[0].is_finite() && step[1].is_finite()) {
            break;
        }
        let length = step[0].hypot(step[1]);
        if newton && is_last_step(length, last_newton) {
            // Close enough that the step's own error is negligible: take it without
            // evaluating the objective there.
            v = clamp([v[0] + step[0], v[1] + step[1]]);
            break;
        }
        let mut taken = None;
        let mut scale = 1.0;
        for _ in 0..=BACKTRACK {
            let next = clamp([v[0] + scale * step[0], v[1] + scale * step[1]]);
            if next == v {
                break;
            }
            let dn = derivatives(events, next, canvas, table, work);
            if dn.squares >= d.squares {
                taken = Some((next, dn));
                break;
            }
            scale *= 0.5;
        }
        let Some((next, dn)) = taken else {
            break;
        };
        last_newton = (newton && scale == 1.0).then_some(length);
        let moved = (next[0] - v[0]).hypot(next[1] - v[1]);
        v = next;
        d = dn;
        if moved < TOLERANCE {
            break;
        }
    }
    Ascent {
        velocity: v,
        squares: d.squares,
    }
}

/// Whether a Newton step of `length` px/ms ends the ascent, taken without evaluating: below
/// [`FINISH`], or below [`FINISH_CONTRACTED`] and at most [`CONTRACTION`] times the previous
/// step if that was a whole Newton step (`previous`, else `None`).
fn is_last_step(length: f64, previous: Option<f64>) -> bool {
    length < FINISH
        || previous.is_some_and(|p| length < FINISH_CONTRACTED && length <= CONTRACTION * p)
}

/// The Newton step `−H⁻¹ g` if the Hessian is negative definite, else the gradient
/// direction; at most [`TRUST`] long.
/// Whether it is a Newton step is returned with it.
fn direction(d: &Derivatives) -> ([f64; 2], bool) {
    let [[a, b], [_, c]] = d.hessian;
    let g = d.gradient;
    let det = a * c - b * b;
    let newton = a < 0.0 && det > 0.0;
    let step = if newton {
        [-(c * g[0] - b * g[1]) / det, -(a * g[1] - b * g[0]) / det]
    } else {
        let norm = g[0].hypot(g[1]);
        if norm == 0.0 {
            return ([0.0, 0.0], false);
        }
        [TRUST * g[0] / norm, TRUST * g[1] / norm]
    };
    let length = step[0].hypot(step[1]);
    if length > TRUST {
        ([step[0] * TRUST / length, step[1] * TRUST / length], false)
    } else {
        (step, newton)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::motion::test_events::trails;
    use crate::estimate::motion::Splat;

    #[test]
    fn short_steps_after_a_contraction_end_the_ascent() {
        // Below FINISH: always the last.
        assert!(is_last_step(0.004, None));
        // Contracted at least fourfold after a whole Newton step, below FINISH_CONTRACTED.
        assert!(is_last_step(0.015, Some(0.08)));
        assert!(is_last_step(0.0125, Some(0.05)));
        // Not contracted enough, after a gradient or halved step, or too long.
        assert!(!is_last_step(0.015, Some(0.05)));
        assert!(!is_last_step(0.015, None));
        assert!(!is_last_step(0.025, Some(0.5)));
    }

    #[test]
    fn the_ascent_stops_within_a_few_thousandths_of_the_converged_maximum() {
        let table = SplatTable::new(Splat::Gaussian { sigma: 0.8 });
        let canvas = Canvas::covering([40, 40], [30.0, 30.0], 1.0, &table);
        let mut work = Workspace::default();
        let mut worst = 0f64;
        for seed in 1..=24 {
            let velocity = [1.5 - 0.1 * seed as f64, 0.2 + 0.05 * seed as f64];
            let events = trails(velocity, seed);
            work.forget_events();
            // A start a vote cell's fraction off, as the pair-velocity vote gives.
            let start = [velocity[0] + 0.12, velocity[1] - 0.09];
            let first = ascend(&events, start, [0.0; 2], 5.0, &canvas, &table, &mut work);
            // Ascending again from the result takes the remaining Newton step (shorter
            // than FINISH), landing on the converged maximum (to within the objective's
            // fine-scale ripple from the 1/256 px kernel table).
            let v = first.velocity;
            let again = ascend(&events, v, [0.0; 2], 5.0, &canvas, &table, &mut work);
            let gap = (again.velocity[0] - v[0]).hypot(again.velocity[1] - v[1]);
            worst = worst.max(gap);
        }
        println!("largest distance to the converged maximum: {worst:.5} px/ms");
        assert!(worst < 3e-3, "stopped {worst} px/ms short of the maximum");
    }
}
