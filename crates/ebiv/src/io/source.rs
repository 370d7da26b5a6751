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
        /// Filters applied as the events are read ([`crate::denoise`]).
        denoise: Option<crate::denoise::DenoiseSettings>,
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

    /// Events in memory on a sensor of `geometry`, called `name`, not denoised.
    pub fn memory(events: Arc<EventBuffer>, geometry: Option<Geometry>, name: &str) -> Self {
        EventSource::Memory {
            events,
            geometry,
            name: name.to_string(),
            denoise: None,
        }
    }

    /// A new reader at the start of the events, denoised when the source says so.
    pub fn open(&self) -> Result<EventReader> {
        match self {
            EventSource::File { path, options } => super::open(path, options),
            EventSource::Memory {
                events,
                geometry,
                denoise,
                ..
            } => {
                let raw = || Ok(super::open_events(events.clone(), *geometry));
                let mut reader = raw()?;
                if let Some(settings) = denoise {
                    super::denoise::attach(&mut reader, settings, raw)?;
                }
                Ok(reader)
            }
        }
    }

    /// A new reader at the start of the events, never denoised: for what planning reads
    /// (the first event, the span and the size of the recording).
    pub fn open_raw(&self) -> Result<EventReader> {
        self.denoised(None).open()
    }

    /// The same source, read through the filters of `denoise` (`None`: not denoised).
    pub fn denoised(&self, denoise: Option<crate::denoise::DenoiseSettings>) -> Self {
        let mut source = self.clone();
        match &mut source {
            EventSource::File { options, .. } => options.denoise = denoise,
            EventSource::Memory { denoise: d, .. } => *d = denoise,
        }
        source
    }

    /// The denoising filters the source is read through.
    pub fn denoise(&self) -> Option<&crate::denoise::DenoiseSettings> {
        match self {
            EventSource::File { options, .. } => options.denoise.as_ref(),
            EventSource::Memory { denoise, .. } => denoise.as_ref(),
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
    /// Not denoised: the origin is the recording's, whatever the filters remove.
    pub fn first_event_time(&self) -> Result<Option<i64>> {
        let mut reader = self.open_raw()?;
        let mut batch = EventBuffer::new();
        while reader.read_batch(&mut batch)? {
            if let Some(&t) = batch.t.first() {
                return Ok(Some(t));
            }
        }
        Ok(None)
    }
}
