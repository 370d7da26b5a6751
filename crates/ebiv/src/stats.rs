//! Summary statistics of a recording, accumulated batch by batch (what `ebiv info` prints).

use crate::event::{EventBuffer, Trigger};
use std::collections::{BTreeMap, VecDeque};

/// Width of the bins in which the peak event rate is measured, µs.
pub const PEAK_RATE_BIN_US: i64 = 1000;
/// Bins kept open for events that arrive out of order.
const OPEN_BINS: usize = 64;

/// Counts, ranges and rates of a stream of events.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct RecordingStats {
    /// Number of events.
    pub events: u64,
    /// Number of ON events.
    pub on: u64,
    /// First event in file order `(t, x, y, p)`.
    pub first: Option<(i64, u16, u16, u8)>,
    /// Last event in file order `(t, x, y, p)`.
    pub last: Option<(i64, u16, u16, u8)>,
    /// Smallest time stamp, µs.
    pub t_min: Option<i64>,
    /// Largest time stamp, µs.
    pub t_max: Option<i64>,
    /// Smallest and largest x.
    pub x_range: Option<(u16, u16)>,
    /// Smallest and largest y.
    pub y_range: Option<(u16, u16)>,
    /// Trigger edges per channel: (count, first t, last t).
    pub triggers: BTreeMap<u8, (u64, i64, i64)>,
    /// Largest number of events in one [`PEAK_RATE_BIN_US`] bin.
    pub peak_bin_events: u64,
    #[serde(skip)]
    open_bins: VecDeque<(i64, u64)>,
}

impl RecordingStats {
    /// Empty statistics.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add a batch.
    pub fn add(&mut self, batch: &EventBuffer) {
        for tr in &batch.triggers {
            self.add_trigger(tr);
        }
        if batch.is_empty() {
            return;
        }
        let n = batch.len();
        self.events += n as u64;
        self.on += batch.count_on() as u64;
        let tuple = |i: usize| (batch.t[i], batch.x[i], batch.y[i], batch.p[i]);
        self.first.get_or_insert(tuple(0));
        self.last = Some(tuple(n - 1));
        let (t0, t1) = batch.time_range().unwrap_or_default();
        self.t_min = Some(self.t_min.map_or(t0, |m| m.min(t0)));
        self.t_max = Some(self.t_max.map_or(t1, |m| m.max(t1)));
        self.x_range = merge_range(self.x_range, &batch.x);
        self.y_range = merge_range(self.y_range, &batch.y);
        for &t in &batch.t {
            self.count_in_bin(t.div_euclid(PEAK_RATE_BIN_US));
        }
    }

    fn add_trigger(&mut self, tr: &Trigger) {
        let entry = self.triggers.entry(tr.channel).or_insert((0, tr.t, tr.t));
        entry.0 += 1;
        entry.1 = entry.1.min(tr.t);
        entry.2 = entry.2.max(tr.t);
    }

    #[inline]
    fn count_in_bin(&mut self, bin: i64) {
        if let Some(slot) = self.open_bins.iter_mut().rev().find(|(b, _)| *b == bin) {
            slot.1 += 1;
            self.peak_bin_events = self.peak_bin_events.max(slot.1);
            return;
        }
        if self.open_bins.len() == OPEN_BINS {
            self.open_bins.pop_front();
        }
        self.open_bins.push_back((bin, 1));
        self.peak_bin_events = self.peak_bin_events.max(1);
    }

    /// Duration from first to last time stamp, µs.
    pub fn duration_us(&self) -> i64 {
        match (self.t_min, self.t_max) {
            (Some(a), Some(b)) => b - a,
            _ => 0,
        }
    }

    /// Mean event rate over the duration, events per second.
    pub fn mean_rate(&self) -> f64 {
        let d = self.duration_us();
        if d > 0 {
            self.events as f64 * 1e6 / d as f64
        } else {
            0.0
        }
    }

    /// Peak event rate in 1 ms bins, events per second.
    pub fn peak_rate(&self) -> f64 {
        self.peak_bin_events as f64 * 1e6 / PEAK_RATE_BIN_US as f64
    }

    /// Total number of trigger edges.
    pub fn trigger_count(&self) -> u64 {
        self.triggers.values().map(|v| v.0).sum()
    }
}

fn merge_range(range: Option<(u16, u16)>, values: &[u16]) -> Option<(u16, u16)> {
    let lo = *values.iter().min()?;
    let hi = *values.iter().max()?;
    Some(match range {
        Some((a, b)) => (a.min(lo), b.max(hi)),
        None => (lo, hi),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_ranges_and_peak_rate() {
        let mut b = EventBuffer::new();
        for i in 0..100 {
            // 90 events in the first millisecond, 10 more at 1, 2, ... 10 ms.
            let t = if i < 90 { i } else { 1000 * (i - 89) };
            b.push(t, i as u16, 3, (i % 2) as u8);
        }
        let mut s = RecordingStats::new();
        s.add(&b);
        assert_eq!(s.events, 100);
        assert_eq!(s.on, 50);
        assert_eq!(s.peak_bin_events, 90);
        assert_eq!(s.x_range, Some((0, 99)));
        assert_eq!(s.duration_us(), 10_000);
        assert!((s.peak_rate() - 90_000.0).abs() < 1e-9);
    }
}
