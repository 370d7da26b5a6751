//! Synthetic recordings with known motion.
//!
//! For now this holds a small generator with an ideal event sensor, enough for the built-in
//! demo and for tests that need particle-like events with a known flow. The full simulator
//! (flows, light sheet, realistic pixel model) is planned in `docs/sensor-model.md`.

mod turntable;

pub use turntable::{turntable, TurntableSpec};
