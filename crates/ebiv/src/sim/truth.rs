//! Ground truth of a simulation: the Eulerian velocity field on a grid, at chosen times
//! (sensor-model.md §6: compare estimates with the field at the window centre and mid-time,
//! or with Lagrangian displacements from the particle tracks).

use super::flow::Flow;
use crate::event::Geometry;
use crate::field::{FieldSeries, TimeBasis};

/// The velocity of `flow` on a grid of spacing `step_px` covering the sensor (first node at
/// `step_px / 2`), at `start_us, start_us + interval_us, …` up to `end_us` inclusive.
///
/// The series is marked [`FieldSeries::ground_truth`] (the writers leave out the status and
/// the quality variables, which a sampled flow does not have) with times of
/// [`TimeBasis::Instant`]. The caller may add a description of the flow to its attributes
/// (e.g. [`FlowSpec::describe`](super::flow::FlowSpec::describe)).
pub fn velocity_field(
    flow: &dyn Flow,
    geometry: Geometry,
    step_px: f64,
    start_us: i64,
    end_us: i64,
    interval_us: i64,
) -> FieldSeries {
    let step = if step_px > 0.0 { step_px } else { 16.0 };
    let half = step / 2.0 - 0.5;
    let x = FieldSeries::axis(half, geometry.width as f64 - 1.0, step);
    let y = FieldSeries::axis(half, geometry.height as f64 - 1.0, step);
    let mut times = Vec::new();
    let mut t = start_us;
    while t <= end_us {
        times.push(t);
        t += interval_us.max(1);
    }
    let mut field = FieldSeries::new(x, y, times);
    for ti in 0..field.t_us.len() {
        let t = field.t_us[ti] as f64;
        for row in 0..field.y.len() {
            for col in 0..field.x.len() {
                let (u, v) = flow.velocity(field.x[col], field.y[row], t);
                let i = field.index(ti, row, col);
                field.u[i] = u as f32;
                field.v[i] = v as f32;
                field.status[i] = crate::field::Status::VALID;
            }
        }
    }
    field.attributes.push((
        "content".into(),
        "ground truth: Eulerian velocity of the simulated flow".into(),
    ));
    field.ground_truth = true;
    field.time_basis = TimeBasis::Instant;
    field
}
