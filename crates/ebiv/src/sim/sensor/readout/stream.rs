//! The readout of a recording whose events arrive window by window while it is simulated
//! ([`StreamingReadout`]): the same result as reading all events out at once (which
//! [`super::read_out_parts`] does as one window), with the work done in small pieces that
//! stay in cache and memory that is reused.

use super::super::params::TimestampMode;
use super::filter::{Filters, StreamFilter};
use super::{key_pixel, key_time, ReadoutReport};
use super::{pack, readable, readout_filters, stamp};
use crate::error::Result;
use crate::event::{EventBuffer, Geometry};
use crate::sim::sensor::{SensorParams, SimEvent};

/// Events per bucket of [`StreamingReadout::sort`].
const EVENTS_PER_BUCKET: usize = 16;

/// The readout of [`super::read_out`], fed the events in windows of time.
///
/// Each call of [`StreamingReadout::read_until`] hands in events (in any order) and promises
/// that no event handed in later lies before its `cutoff`; every event before the cutoff is
/// then read out: sorted, filtered and stamped as the next stretch of one pass over the whole
/// recording. Events at or after the cutoff are held for a later call. The result after
/// [`StreamingReadout::finish`] is that of [`super::read_out`] of all events handed in, with
/// two differences:
/// * events outside the sensor's geometry count as invalid (a simulator's pixels are
///   inside it);
/// * an event that breaks the promise (handed in after a cutoff above its time) is read out
///   at the time of the last cutoff, as if it had arrived just in time.
///
/// Memory is that of the output, of one window and of the events held for later windows, not
/// of the whole recording's exact events; the refractory filter keeps one time per pixel of
/// the sensor. Events held for many windows are looked at again in each (a cost only when
/// they are handed in far ahead of their cutoff).
pub struct StreamingReadout {
    geometry: Geometry,
    timestamp: TimestampMode,
    filter: StreamFilter,
    /// Every event before this time has been read out.
    done_until: f64,
    /// Events handed in at or after the last cutoff.
    held: Vec<SimEvent>,
    /// Scratch for the next `held`.
    spare: Vec<SimEvent>,
    /// Scratch: the window's packed events, as handed in.
    unsorted: Vec<u128>,
    /// Scratch: the window's packed events, sorted.
    keys: Vec<u128>,
    /// Scratch: the start of each time bucket in `keys`.
    starts: Vec<usize>,
    /// Scratch: where the next key of each bucket goes.
    next: Vec<usize>,
    out: EventBuffer,
    /// Events read out and handed over by [`StreamingReadout::drain`] so far.
    drained: u64,
    report: ReadoutReport,
    late: u64,
}

impl StreamingReadout {
    /// A readout for a sensor of `geometry` with the readout parameters of `params`, nothing
    /// read out yet.
    pub fn new(params: &SensorParams, geometry: Geometry) -> Self {
        let filters: Filters = readout_filters(params);
        StreamingReadout {
            geometry,
            timestamp: params.timestamp,
            filter: StreamFilter::new(geometry.width as usize, geometry.height as usize, filters),
            done_until: f64::NEG_INFINITY,
            held: Vec::new(),
            spare: Vec::new(),
            unsorted: Vec::new(),
            keys: Vec::new(),
            starts: Vec::new(),
            next: Vec::new(),
            out: EventBuffer::new(),
            drained: 0,
            report: ReadoutReport::default(),
            late: 0,
        }
    }

    /// Hand in the events of `parts` (emptied; their capacity is kept) and read out every
    /// event before `cutoff` (µs; not finite or not above the last cutoff: the last cutoff,
    /// so that the events are only handed in).
    pub fn read_until(&mut self, parts: &mut [Vec<SimEvent>], cutoff: f64) {
        let cutoff = if cutoff.is_finite() {
            cutoff
        } else {
            self.done_until
        };
        self.read_window(parts, cutoff);
        for part in parts.iter_mut() {
            part.clear();
        }
    }

    /// [`StreamingReadout::read_until`] for any cutoff above the last; +∞ reads out every
    /// event.
    fn read_window<P: AsRef<[SimEvent]>>(&mut self, parts: &[P], cutoff: f64) {
        let start = self.done_until;
        let cutoff = if cutoff > start { cutoff } else { start };
        let (width, height) = (self.geometry.width, self.geometry.height);

        // Split: the events before the cutoff are final and packed, the rest wait for a
        // later window.
        let held = std::mem::take(&mut self.held);
        let mut next_held = std::mem::take(&mut self.spare);
        next_held.clear();
        let mut unsorted = std::mem::take(&mut self.unsorted);
        unsorted.clear();
        let (mut t_lo, mut t_hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let parts = parts.iter().map(|part| part.as_ref());
        for (k, part) in std::iter::once(held.as_slice()).chain(parts).enumerate() {
            let handed_in = k > 0;
            if handed_in {
                self.report.events_in += part.len() as u64;
            }
            for e in part {
                let valid = readable(e) && u32::from(e.x) < width && u32::from(e.y) < height;
                if !valid {
                    self.report.dropped_invalid += 1;
                    continue;
                }
                // A late event is read out at the last cutoff.
                let t = if e.t_us < start {
                    self.late += 1;
                    start
                } else {
                    e.t_us
                };
                if t < cutoff {
                    t_lo = t_lo.min(t);
                    t_hi = t_hi.max(t);
                    unsorted.push(pack(&SimEvent { t_us: t, ..*e }));
                } else {
                    next_held.push(SimEvent { t_us: t, ..*e });
                }
            }
        }
        self.sort(&unsorted, t_lo, t_hi);
        self.unsorted = unsorted;

        let drops = self.filter.drops(&self.keys);
        self.report.dropped_refractory += drops.refractory;
        self.report.dropped_bandwidth += drops.bandwidth;
        self.append(&drops.indices);

        self.held = next_held;
        self.spare = held;
        self.done_until = cutoff;
    }

    /// `keys` (packed, times from `t_lo` to `t_hi`) sorted into `self.keys` by a bucket
    /// sort: buckets of equal time span in order, each sorted on its own.
    fn sort(&mut self, keys: &[u128], t_lo: f64, t_hi: f64) {
        let n = keys.len();
        let buckets = n / EVENTS_PER_BUCKET;
        let sorted = &mut self.keys;
        sorted.clear();
        if buckets < 2 || t_hi <= t_lo {
            sorted.extend_from_slice(keys);
            sorted.sort_unstable();
            return;
        }
        let per_us = buckets as f64 / (t_hi - t_lo);
        let bucket_of = |key: u128| (((key_time(key) - t_lo) * per_us) as usize).min(buckets - 1);
        let starts = &mut self.starts;
        starts.clear();
        starts.resize(buckets + 1, 0);
        for &key in keys {
            starts[bucket_of(key) + 1] += 1;
        }
        for b in 0..buckets {
            starts[b + 1] += starts[b];
        }
        sorted.resize(n, 0);
        // `next[b]`: where the next key of bucket `b` goes.
        let next = &mut self.next;
        next.clear();
        next.extend_from_slice(&starts[..buckets]);
        for &key in keys {
            let slot = &mut next[bucket_of(key)];
            sorted[*slot] = key;
            *slot += 1;
        }
        for b in 0..buckets {
            sorted[starts[b]..starts[b + 1]].sort_unstable();
        }
    }

    /// Append the sorted keys of the window but those at the indices `dropped` (ascending) to
    /// the output, stamped.
    fn append(&mut self, dropped: &[usize]) {
        let timestamp = self.timestamp;
        let out = &mut self.out;
        let kept = self.keys.len() - dropped.len();
        out.t.reserve(kept);
        out.x.reserve(kept);
        out.y.reserve(kept);
        out.p.reserve(kept);
        let mut dropped = dropped.iter().peekable();
        for (i, &key) in self.keys.iter().enumerate() {
            if dropped.peek() == Some(&&i) {
                dropped.next();
                continue;
            }
            let (x, y) = key_pixel(key);
            out.t.push(stamp(timestamp, key_time(key)));
            out.x.push(x);
            out.y.push(y);
            out.p.push(key as u8);
        }
    }

    /// Events handed in after a cutoff above their time (read out at that cutoff).
    pub fn late_events(&self) -> u64 {
        self.late
    }

    /// Hand the events read out so far and not yet drained to `sink` (in time order, one
    /// call if there are any), then forget them: a recording streamed to a file keeps only
    /// a window of its events in memory. [`StreamingReadout::finish`] then returns the rest.
    pub fn drain(&mut self, sink: &mut dyn FnMut(&EventBuffer) -> Result<()>) -> Result<()> {
        if self.out.is_empty() {
            return Ok(());
        }
        sink(&self.out)?;
        self.drained += self.out.len() as u64;
        self.out.clear();
        Ok(())
    }

    /// Hand in the events of `parts` and read out every event handed in and not yet read
    /// out; return all events in time order that were not drained
    /// ([`StreamingReadout::drain`]), with the report of all.
    pub fn finish(self, parts: &mut [Vec<SimEvent>]) -> (EventBuffer, ReadoutReport) {
        let result = self.finish_parts(parts);
        for part in parts.iter_mut() {
            part.clear();
        }
        result
    }

    /// [`StreamingReadout::finish`] of parts it may not empty.
    pub(super) fn finish_parts<P: AsRef<[SimEvent]>>(
        mut self,
        parts: &[P],
    ) -> (EventBuffer, ReadoutReport) {
        self.read_window(parts, f64::INFINITY);
        self.report.events_out = self.drained + self.out.len() as u64;
        (self.out, self.report)
    }
}
