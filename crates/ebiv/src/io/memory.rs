//! Events already in memory (arrays handed over from Python, a simulation) read through the
//! same streaming [`EventReader`] as a file, so that every command plans and processes them
//! alike.

use super::{DecodeReport, EventReader, Format, FormatReader, Metadata};
use crate::error::Result;
use crate::event::{EventBuffer, Geometry};
use std::sync::Arc;

/// Events per batch: the size of a file reader's batches of a paper-rate recording.
const BATCH_EVENTS: usize = 1 << 16;

/// A reader over `events` (in their given order) on a sensor of `geometry` (`None`: the
/// largest coordinates decide, as for a file without a header).
pub fn open_events(events: Arc<EventBuffer>, geometry: Option<Geometry>) -> EventReader {
    let sorted = events.is_time_sorted();
    let mut metadata = Metadata::new(Format::Memory);
    metadata.geometry = geometry;
    EventReader::new(
        Box::new(MemoryReader {
            events,
            next: 0,
            triggers_sent: false,
            sorted,
            metadata,
            report: DecodeReport::default(),
        }),
        false,
    )
}

struct MemoryReader {
    events: Arc<EventBuffer>,
    /// Index of the next event to hand out.
    next: usize,
    /// Whether the triggers went out (with the first batch).
    triggers_sent: bool,
    /// Whether the events are in time order (then a seek bisects).
    sorted: bool,
    metadata: Metadata,
    report: DecodeReport,
}

impl FormatReader for MemoryReader {
    fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    fn next_batch(&mut self, out: &mut EventBuffer) -> Result<bool> {
        let events = &*self.events;
        if !self.triggers_sent {
            out.triggers.extend_from_slice(&events.triggers);
            self.triggers_sent = true;
        }
        let range = self.next..(self.next + BATCH_EVENTS).min(events.len());
        if range.is_empty() && out.triggers.is_empty() {
            return Ok(false);
        }
        self.next = range.end;
        out.t.extend_from_slice(&events.t[range.clone()]);
        out.x.extend_from_slice(&events.x[range.clone()]);
        out.y.extend_from_slice(&events.y[range.clone()]);
        out.p.extend_from_slice(&events.p[range]);
        Ok(true)
    }

    fn report(&self) -> &DecodeReport {
        &self.report
    }

    /// Events sorted by time are skipped by bisection; unsorted ones are read through.
    fn seek_near(&mut self, t_us: i64) -> Result<bool> {
        if !self.sorted {
            return Ok(false);
        }
        let first = self.events.t.partition_point(|&t| t < t_us);
        let jumped = first > self.next;
        self.next = self.next.max(first);
        Ok(jumped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn events(n: usize) -> Arc<EventBuffer> {
        let mut b = EventBuffer::new();
        for i in 0..n {
            b.push(i as i64 * 3, (i % 7) as u16, (i % 5) as u16, (i % 2) as u8);
        }
        b.triggers.push(crate::Trigger {
            t: 4,
            channel: 0,
            value: 1,
        });
        Arc::new(b)
    }

    #[test]
    fn every_event_and_trigger_comes_out_once_in_order() {
        let source = events(BATCH_EVENTS * 2 + 17);
        let rec = open_events(source.clone(), Some(Geometry::new(7, 5)))
            .read_all()
            .unwrap();
        assert_eq!(rec.events.t, source.t);
        assert_eq!(rec.events.x, source.x);
        assert_eq!(rec.events.p, source.p);
        assert_eq!(rec.events.triggers, source.triggers);
        assert_eq!(rec.metadata.format, Format::Memory);
        assert_eq!(rec.report.events, source.len() as u64);
    }

    #[test]
    fn skipping_lands_on_the_first_event_at_the_time() {
        let source = events(BATCH_EVENTS + 100);
        for target in [
            0,
            1,
            3,
            3 * 5000 + 1,
            3 * (BATCH_EVENTS as i64 + 99),
            i64::MAX,
        ] {
            let mut reader = open_events(source.clone(), None);
            reader.skip_to(target).unwrap();
            let mut batch = EventBuffer::new();
            let first = if reader.read_batch(&mut batch).unwrap() {
                batch.t.first().copied()
            } else {
                None
            };
            let expected = source.t.iter().copied().find(|&t| t >= target);
            assert_eq!(first, expected, "target {target}");
        }
    }

    #[test]
    fn no_events_is_an_empty_stream() {
        let rec = open_events(Arc::new(EventBuffer::new()), None)
            .read_all()
            .unwrap();
        assert!(rec.events.is_empty());
    }
}
