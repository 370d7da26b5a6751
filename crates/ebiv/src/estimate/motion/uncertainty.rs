//! Standard uncertainty of a motion-compensation maximum: the sandwich covariance of
//! [`crate::estimate::uncertainty`] from the gradients of the image blocks at the maximum.
//!
//! Σ I² of the image of warped events is a sum over its pixels; its gradient in the velocity
//! is a sum of one share per event ([`derivatives`] with `record_gradients`). The events are
//! grouped by the block of [`BLOCK_PX`] pixels their warped position falls in, so that a
//! block holds the events of the particle images there, and the scatter of the blocks'
//! gradients at the maximum, through the inverse Hessian, gives the covariance of the
//! maximum: the curvature of the contrast objective (how sharply the events focus) against
//! how consistently its parts agree on where the focus lies. A block weighs its events.

use super::iwe::{derivatives, Canvas, Events, SplatTable, Workspace};
use crate::estimate::uncertainty::{sandwich_sigma, BLOCK_PX};

/// Standard uncertainty, px/ms per component, of `velocity`, a maximum of Σ I² of `events`
/// splatted with `table` (which must have derivatives: a Gaussian splat) on `canvas`.
pub(super) fn velocity_sigma(
    events: &Events,
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
    (gradients, events_in): (&mut Vec<[f64; 2]>, &mut Vec<f64>),
) -> [f64; 2] {
    if events.t.len() < 2 || velocity.iter().any(|v| !v.is_finite()) {
        return [f64::NAN; 2];
    }
    work.record_gradients = true;
    let d = derivatives(events, velocity, canvas, table, work);
    work.record_gradients = false;
    let warped = |i: usize| {
        let t = f64::from(events.t[i]);
        [
            f64::from(events.x[i]) - velocity[0] * t,
            f64::from(events.y[i]) - velocity[1] * t,
        ]
    };
    let n = events.t.len();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for i in 0..n {
        let p = warped(i);
        for axis in 0..2 {
            lo[axis] = lo[axis].min(p[axis]);
            hi[axis] = hi[axis].max(p[axis]);
        }
    }
    let block = BLOCK_PX as f64;
    let [across, down] = [0, 1].map(|axis| ((hi[axis] - lo[axis]) / block).floor() as usize + 1);
    if across.saturating_mul(down) > 1 << 20 {
        return [f64::NAN; 2];
    }
    gradients.clear();
    gradients.resize(across * down, [0.0; 2]);
    events_in.clear();
    events_in.resize(across * down, 0.0);
    for (i, g) in work.event_gradients.iter().enumerate().take(n) {
        let p = warped(i);
        let col = (((p[0] - lo[0]) / block) as usize).min(across - 1);
        let row = (((p[1] - lo[1]) / block) as usize).min(down - 1);
        let cell = &mut gradients[row * across + col];
        cell[0] += g[0];
        cell[1] += g[1];
        events_in[row * across + col] += 1.0;
    }
    sandwich_sigma(d.hessian, gradients, events_in)
}
