//! Where a run's events come from: a file, or events already in memory. Planning a run
//! opens its source more than once (to find the first event, the sensor size, the span),
//! so a source is a recipe for a reader rather than a reader.

use super::{EventReader, ReadOptions};
use crate::error::Result;
use crate::event::{EventBuffer, Geometry};
use std::path::PathBuf;
use std::sync::Arc;

/// The events of a run: a recording on disk, read with `options`, or events in memory.
#[derive(Debug, Clone)]
pub enum EventSource {
    /// An event file in any format [`super::open`] reads.
    File {
        /// The file.
        path: PathBuf,
        /// How to read it.
        options: ReadOptions,
    },
    /// Events in memory, in their order, on a sensor of `geometry` (`None`: the largest
    /// coordinates decide).
    Memory {
        /// The events and triggers.
        events: Arc<EventBuffer>,
        /// The sensor size, when known.
        geometry: Option<Geometry>,
        /// What messages and the output's `source` attribute call these events.
        name: String,
    },
}

impl EventSource {
    /// The file at `path`, read with `options`.
    pub fn file(path: impl Into<PathBuf>, options: &ReadOptions) -> Self {
        EventSource::File {
            path: path.into(),
            options: options.clone(),
        }
    }

    /// A new reader at the start of the events.
    pub fn open(&self) -> Result<EventReader> {
        match self {
            EventSource::File { path, options } => super::open(path, options),
            EventSource::Memory {
                events, geometry, ..
            } => Ok(super::open_events(events.clone(), *geometry)),
        }
    }

    /// The file's path, or the name given to the events in memory.
    pub fn name(&self) -> String {
        match self {
            EventSource::File { path, .. } => path.display().to_string(),
            EventSource::Memory { name, .. } => name.clone(),
        }
    }

    /// Time stamp of the first event in file order (the origin of every command's relative
    /// times), decoding only as far as that event; `None` without events.
    pub fn first_event_time(&self) -> Result<Option<i64>> {
        let mut reader = self.open()?;
        let mut batch = EventBuffer::new();
        while reader.read_batch(&mut batch)? {
            if let Some(&t) = batch.t.first() {
                return Ok(Some(t));
            }
        }
        Ok(None)
    }
}
