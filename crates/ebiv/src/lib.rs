//! `ebiv` — event-based imaging velocimetry.
//!
//! Measures fluid flows with event cameras, after Willert & Klinner, "Event-based imaging
//! velocimetry: an assessment of event-based cameras for the measurement of fluid flows",
//! Exp. Fluids 63:101 (2022). This crate holds all the science; the `ebiv` binary in
//! `ebiv-cli` only parses options and reports progress.
//!
//! Layers (lowest first): data types ([`event`]), file input/output ([`io`]), statistics
//! ([`stats`]), figures ([`render`]).

pub mod error;
pub mod event;
pub mod export;
pub mod field;
pub mod filter;
pub mod io;
pub mod render;
pub mod sim;
pub mod stats;
pub mod units;

pub use error::{Error, Result};
pub use event::{Event, EventBuffer, Geometry, Polarity, PolaritySelection, Trigger};
