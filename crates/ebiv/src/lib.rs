//! `ebiv` — event-based imaging velocimetry.
//!
//! Measures fluid flows with event cameras, after Willert & Klinner, "Event-based imaging
//! velocimetry: an assessment of event-based cameras for the measurement of fluid flows",
//! Exp. Fluids 63:101 (2022). This crate holds all the science; the `ebiv` binary in
//! `ebiv-cli` only parses options and reports progress.
//!
//! Layers (lowest first): data types ([`event`], [`field`], [`grid`]) and quantities derived
//! from a field's velocity gradient ([`derived`]), file input/output ([`io`]) and simulation
//! ([`sim`]), tiled time slabs ([`volume`]) and deformation by a predicted motion
//! ([`deform`]), correlation peaks shared by every method ([`peak`]), window estimators
//! ([`estimate`]), validation ([`validate`]), the one multi-pass engine and run planning
//! ([`process`]), image frames read from files or rebuilt from events and pulse timing
//! ([`frame`]), cross-correlation PIV on frames and pulsed EBIV ([`piv`]), the settings of a
//! run ([`settings`]), outputs ([`export`], [`render`]).

pub mod activity;
pub mod assess;
pub mod deform;
pub mod denoise;
pub mod derived;
pub mod error;
pub mod estimate;
pub mod event;
pub mod export;
pub mod field;
pub mod filter;
pub mod frame;
pub mod grid;
pub mod io;
pub mod live;
pub mod peak;
pub mod piv;
pub mod process;
pub mod render;
pub mod settings;
pub mod sim;
mod simd;
pub mod statistics;
pub mod stats;
pub mod study;
#[cfg(test)]
mod test_rng;
pub mod track;
pub mod units;
pub mod validate;
pub mod volume;

pub use error::{Error, Result};
pub use event::{Event, EventBuffer, Geometry, Polarity, PolaritySelection, Trigger};
