//! Synthetic recordings with known motion: a seeded flow in a light sheet, imaged onto an
//! event-camera pixel model, with the ground truth (velocity field and particle paths).
//!
//! Facts, formulas and the defaults of established simulators are in the project's
//! `docs/sensor-model.md`.

mod fastmath;
pub mod flow;
pub mod ode;
pub mod particles;
pub mod piv_images;
pub mod rng;
pub mod scenario;
pub mod scene;
pub mod sensor;
pub mod simulation;
pub mod truth;

pub use flow::{Flow, FlowSpec};
