//! The streaming reader every format is read through.

use super::{DecodeReport, FormatReader, Metadata};
use crate::error::Result;
use crate::event::EventBuffer;

/// A recording decoded into memory.
#[derive(Debug, Clone)]
pub struct Recording {
    /// All events (and triggers) in file order.
    pub events: EventBuffer,
    /// What the file says about itself.
    pub metadata: Metadata,
    /// What was dropped or skipped while decoding.
    pub report: DecodeReport,
}

/// A streaming event reader: batches of bounded size in file order, the file's metadata, and
/// a running report of everything dropped. Obtain one with [`crate::io::open`].
pub struct EventReader {
    inner: Box<dyn FormatReader>,
    apply_metavision_shift: bool,
    shift_us: i64,
    last_t: Option<i64>,
    own: DecodeReport,
    /// Events decoded past a seek target, handed out by the next `read_batch`.
    pending: Option<EventBuffer>,
    metadata: Metadata,
    /// The recording's index, when one is stored for it ([`super::index`]).
    pub(crate) index: Option<std::sync::Arc<super::index::RecordingIndex>>,
    /// Filters applied to every decoded batch ([`crate::denoise`]).
    pub(crate) denoiser: Option<crate::denoise::Denoiser>,
}

impl EventReader {
    pub(crate) fn new(inner: Box<dyn FormatReader>, apply_metavision_shift: bool) -> Self {
        let metadata = inner.metadata().clone();
        EventReader {
            inner,
            apply_metavision_shift,
            shift_us: 0,
            last_t: None,
            own: DecodeReport::default(),
            pending: None,
            metadata,
            index: None,
            denoiser: None,
        }
    }

    pub(crate) fn inner(&self) -> &dyn FormatReader {
        &*self.inner
    }

    pub(crate) fn inner_mut(&mut self) -> &mut dyn FormatReader {
        &mut *self.inner
    }

    pub(crate) fn applies_metavision_shift(&self) -> bool {
        self.apply_metavision_shift
    }

    pub(crate) fn shift_us(&self) -> i64 {
        self.shift_us
    }

    /// Whether seeking uses an index of the recording ([`super::index`]).
    pub fn has_index(&self) -> bool {
        self.index.is_some()
    }

    /// What the file says about itself (format, geometry, header).
    pub fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    /// What was dropped or skipped so far; complete once the reader is exhausted.
    pub fn report(&self) -> DecodeReport {
        let mut report = self.own.merged_with(self.inner.report());
        report.denoise = self.denoise_report();
        report
    }

    /// What the denoising filters removed so far, when the reader denoises: counted over the
    /// events handed out and removed, not over those a seek ([`EventReader::skip_to`])
    /// passed.
    pub fn denoise_report(&self) -> Option<crate::denoise::DenoiseReport> {
        self.denoiser.as_ref().map(|d| d.report().clone())
    }

    /// Bytes of the file consumed so far, where the format's reader tracks it.
    pub fn position(&self) -> Option<u64> {
        self.inner.position()
    }

    /// Decode the next batch into `out` (cleared first). Returns `false` when the file is
    /// exhausted; a batch may hold triggers but no events.
    pub fn read_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        out.clear();
        if let Some(pending) = self.pending.take() {
            *out = pending;
            return Ok(true);
        }
        loop {
            if !self.inner.next_batch(out)? {
                return Ok(false);
            }
            self.after_decode(out);
            if let Some(denoiser) = &mut self.denoiser {
                denoiser.apply(out);
            }
            if !out.is_empty() || !out.triggers.is_empty() {
                return Ok(true);
            }
        }
    }

    fn after_decode(&mut self, out: &mut EventBuffer) {
        if self.apply_metavision_shift && self.shift_us == 0 {
            if let Some(shift) = self.inner.metavision_time_shift() {
                self.shift_us = shift;
                self.metadata.time_shift_us = shift;
            }
        }
        if self.shift_us != 0 {
            out.t.iter_mut().for_each(|t| *t -= self.shift_us);
            out.triggers.iter_mut().for_each(|tr| tr.t -= self.shift_us);
        }
        let t = &out.t;
        let mut regressions = match (self.last_t, t.first()) {
            (Some(last), Some(&first)) => (first < last) as u64,
            _ => 0,
        };
        // Pairs of neighbours, with no dependence from one to the next: vectorised.
        regressions += t
            .iter()
            .zip(t.iter().skip(1))
            .map(|(a, b)| (b < a) as u64)
            .sum::<u64>();
        if let Some(&last) = t.last() {
            self.last_t = Some(last);
        }
        self.own.time_regressions += regressions;
        self.own.events += out.len() as u64;
        self.own.triggers += out.triggers.len() as u64;
    }

    /// Skip to the first event at or after `t_us` (camera time, after any shift): jumps by the
    /// file's index where the format has one, and otherwise decodes and discards quickly.
    /// A denoising reader never jumps: its filters' state depends on every event before, so
    /// it decodes from where it is and feeds the skipped events to the filters (leaving
    /// them out of the counts); what follows is then exactly what reading from the start
    /// gives.
    pub fn skip_to(&mut self, t_us: i64) -> Result<()> {
        if self.denoiser.is_some() {
            return self.skip_denoised(t_us);
        }
        if self.pending.is_none() && !self.jump_by_index(t_us)? {
            self.inner.seek_near(t_us + self.shift_us)?;
        }
        let mut batch = EventBuffer::new();
        while self.read_batch(&mut batch)? {
            let first = batch.t.iter().position(|&t| t >= t_us);
            let discarded = first.unwrap_or(batch.len());
            self.own.events -= discarded as u64;
            if let Some(first) = first {
                let mut rest = EventBuffer::with_capacity(batch.len() - first);
                for i in first..batch.len() {
                    rest.push(batch.t[i], batch.x[i], batch.y[i], batch.p[i]);
                }
                rest.triggers = batch
                    .triggers
                    .into_iter()
                    .filter(|tr| tr.t >= t_us)
                    .collect();
                self.pending = Some(rest);
                return Ok(());
            }
        }
        Ok(())
    }

    /// [`EventReader::skip_to`] of a denoising reader.
    fn skip_denoised(&mut self, t_us: i64) -> Result<()> {
        if let Some(mut pending) = self.pending.take() {
            // Already filtered and counted.
            if let Some(first) = pending.t.iter().position(|&t| t >= t_us) {
                let mut rest = pending.split_off(first);
                rest.triggers = std::mem::take(&mut pending.triggers);
                rest.triggers.retain(|tr| tr.t >= t_us);
                self.pending = Some(rest);
                return Ok(());
            }
        }
        let mut batch = EventBuffer::new();
        loop {
            batch.clear();
            if !self.inner.next_batch(&mut batch)? {
                return Ok(());
            }
            self.after_decode(&mut batch);
            let first = batch.t.iter().position(|&t| t >= t_us);
            let mut rest = batch.split_off(first.unwrap_or(batch.len()));
            self.own.events -= batch.len() as u64;
            let denoiser = self.denoiser.as_mut().expect("a denoising reader");
            let counts = denoiser.report().clone();
            denoiser.apply(&mut batch);
            denoiser.set_report(counts);
            if first.is_some() {
                denoiser.apply(&mut rest);
                rest.triggers = std::mem::take(&mut batch.triggers);
                rest.triggers.retain(|tr| tr.t >= t_us);
                self.pending = Some(rest);
                return Ok(());
            }
        }
    }

    /// Decode everything that is left into memory.
    pub fn read_all(mut self) -> Result<Recording> {
        let mut events = EventBuffer::new();
        let mut batch = EventBuffer::new();
        while self.read_batch(&mut batch)? {
            events.extend_from(&batch);
        }
        Ok(Recording {
            events,
            report: self.report(),
            metadata: self.metadata,
        })
    }
}
