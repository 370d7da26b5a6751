//! Flows with known velocity fields and particle paths (sensor-model.md §5–§6).
//!
//! Positions are image pixels (x right, y down), times µs, velocities px/ms. Every flow gives
//! its Eulerian velocity and moves a particle over a time interval: exactly where a closed
//! form exists, otherwise by adaptive high-order integration ([`super::ode`]). Moving
//! particles along the exact Lagrangian path follows Mendes et al. (SoftwareX 2020); PCM-SA's
//! Euler sub-steps leave an integration error that looks like estimator bias (sensor-model.md
//! §6).
//!
//! Because y points down, every rotation written with a positive angular velocity or
//! circulation turns **clockwise on screen**.
//!
//! * closed-form paths ([`analytic`]): [`Uniform`], [`SolidBodyRotation`], [`RankineVortex`],
//!   [`LambOseenVortex`], [`Couette`], [`MixingLayer`], [`Poiseuille`], [`StagnationPoint`];
//! * integrated paths ([`streams`]): [`Sinusoidal`], [`Cellular`], [`Superposition`],
//!   and the turbulence-like [`RandomVortices`] ([`random`]);
//! * user data ([`gridded`]): [`GriddedFlow`] from CSV or NetCDF classic files;
//! * configuration ([`spec`]): [`FlowSpec`], the `[flow]` table of a scenario file.

pub mod analytic;
pub mod gridded;
pub mod random;
pub mod spec;
pub mod streams;
#[cfg(test)]
mod tests;

pub use analytic::{
    Couette, LambOseenVortex, MixingLayer, Poiseuille, RankineVortex, SolidBodyRotation,
    StagnationPoint, Uniform, LAMB_OSEEN_PEAK_Q,
};
pub use gridded::GriddedFlow;
pub use random::RandomVortices;
pub use spec::FlowSpec;
pub use streams::{Cellular, Sinusoidal, Superposition};

/// A 2-D velocity field `u(x, y, t)` with particle paths.
pub trait Flow: Send + Sync + std::fmt::Debug {
    /// Velocity (u, v) in px/ms at position (x, y) px and time `t_us`.
    fn velocity(&self, x: f64, y: f64, t_us: f64) -> (f64, f64);

    /// Position at `t1_us` of the particle that is at `p` at `t0_us`. The default integrates
    /// [`Flow::velocity`] with the adaptive Dormand–Prince 5(4) scheme to 1e-9 px.
    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        super::ode::integrate(|x, y, t| self.velocity(x, y, t), p, t0_us, t1_us)
    }

    /// An upper bound of the speed (px/ms) inside the rectangle `[0, w] × [0, h]` around
    /// time `t_us`, used to choose the simulation time step.
    fn max_speed(&self, w: f64, h: f64, t_us: f64) -> f64;
}

impl Flow for Box<dyn Flow> {
    fn velocity(&self, x: f64, y: f64, t_us: f64) -> (f64, f64) {
        (**self).velocity(x, y, t_us)
    }

    fn advect(&self, p: (f64, f64), t0_us: f64, t1_us: f64) -> (f64, f64) {
        (**self).advect(p, t0_us, t1_us)
    }

    fn max_speed(&self, w: f64, h: f64, t_us: f64) -> f64 {
        (**self).max_speed(w, h, t_us)
    }
}

/// Elapsed time from `t0_us` to `t1_us` in ms (the time unit of the velocities).
fn elapsed_ms(t0_us: f64, t1_us: f64) -> f64 {
    (t1_us - t0_us) * 1e-3
}

/// The nearest and the farthest distance from `centre` to a point of `[0, w] × [0, h]`.
fn distance_range(centre: (f64, f64), w: f64, h: f64) -> (f64, f64) {
    let (cx, cy) = centre;
    let near_x = cx.clamp(0.0, w.max(0.0));
    let near_y = cy.clamp(0.0, h.max(0.0));
    let far_x = (cx - 0.0).abs().max((cx - w).abs());
    let far_y = (cy - 0.0).abs().max((cy - h).abs());
    ((cx - near_x).hypot(cy - near_y), far_x.hypot(far_y))
}
