//! The readout: time order, refractory filter, bandwidth limit and 1 µs time stamps
//! (sensor-model.md §2.5, §2.10, §2.11).

use std::collections::HashMap;

use super::params::{SensorParams, TimestampMode};
use super::response::clean;
use super::{PixelCounters, SimEvent};
use crate::event::EventBuffer;
use crate::sim::fastmath::floor_i64;
use rayon::iter::{IndexedParallelIterator, IntoParallelIterator, ParallelIterator};
use rayon::slice::ParallelSliceMut;

/// What the readout did, and (after [`ReadoutReport::absorb`]) what the pixels did.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReadoutReport {
    /// Events handed to the readout.
    pub events_in: u64,
    /// Events in the output buffer.
    pub events_out: u64,
    /// Events dropped because the readout bandwidth was exhausted.
    pub dropped_bandwidth: u64,
    /// Events inside the refractory time of an earlier event of the same pixel: those the
    /// readout removed (noise events colliding with signal events) plus, after
    /// [`ReadoutReport::absorb`], the crossings the pixels themselves suppressed.
    pub dropped_refractory: u64,
    /// Events with a non-finite time or a polarity other than 0/1.
    pub dropped_invalid: u64,
    /// The pixels' counters, summed by [`ReadoutReport::absorb`].
    pub pixels: PixelCounters,
}

impl ReadoutReport {
    /// Add the counters of a band (`SensorBand::counters`), including its suppressed
    /// refractory crossings in `dropped_refractory`.
    pub fn absorb(&mut self, counters: &PixelCounters) {
        self.pixels.merge(counters);
        self.dropped_refractory += counters.suppressed_refractory;
    }
}

/// Spacing tolerance of the refractory filter, µs: differences this close to the refractory
/// period are rounding, not violations.
const REFRACTORY_TOLERANCE_US: f64 = 1e-6;

/// Largest pixel table the refractory filter allocates densely; larger sensors use a map.
const DENSE_TABLE_LIMIT: usize = 1 << 24;

/// Sort by time, enforce the refractory period across signal and noise events, apply the
/// readout bandwidth limit, quantise to 1 µs, and return the events in time order.
///
/// * **Order**: exact time, then row, column, polarity — a total order, so the result does not
///   depend on the order of `events` (how bands were concatenated).
/// * **Refractory**: an event closer than `refractory_us` (less 1e-6 µs) to the previous kept
///   event of its pixel is dropped; the earlier event wins (IEBCS: a pixel is blind after any
///   event, §2.5).
/// * **Bandwidth** (`bandwidth_ev_per_s = R`, `bandwidth_burst_events = D`): a token bucket.
///   It holds up to D tokens, starts full and refills at R per second; an event passes if a
///   token is available and takes it, and is dropped when the bucket is empty — so the
///   earliest events of a burst pass and at most `D + R·(b − a)` events lie in any interval
///   `[a, b]`. Passing events are not delayed (no FIFO). Real sensors also lose events row-wise
///   (§2.11); this is the simplest model with that bound.
/// * **Time stamps**: `round` or `truncate` (floor) to 1 µs, after the two steps above, which
///   use exact times.
pub fn read_out(mut events: Vec<SimEvent>, params: &SensorParams) -> (EventBuffer, ReadoutReport) {
    let mut report = ReadoutReport {
        events_in: events.len() as u64,
        ..ReadoutReport::default()
    };
    let before = events.len();
    events.retain(|e| e.t_us.is_finite() && e.p <= 1);
    report.dropped_invalid = (before - events.len()) as u64;

    sort_events(&mut events);

    let refractory = clean(params.refractory_us, 0.0, 1e12, 0.0);
    if refractory > 0.0 && !events.is_empty() {
        report.dropped_refractory = refractory_filter(&mut events, refractory);
    }

    if let Some(rate) = params.bandwidth_ev_per_s.filter(|r| *r > 0.0) {
        let burst = clean(params.bandwidth_burst_events, 1.0, 1e12, 1.0);
        report.dropped_bandwidth = token_bucket(&mut events, rate * 1e-6, burst);
    }

    let buffer = EventBuffer {
        t: match params.timestamp {
            TimestampMode::Round => events.iter().map(|e| e.t_us.round() as i64).collect(),
            // `floor_i64` is `floor() as i64` without a library call per event.
            TimestampMode::Truncate => events.iter().map(|e| floor_i64(e.t_us)).collect(),
        },
        x: events.iter().map(|e| e.x).collect(),
        y: events.iter().map(|e| e.y).collect(),
        p: events.iter().map(|e| e.p).collect(),
        triggers: Vec::new(),
    };
    report.events_out = buffer.len() as u64;
    (buffer, report)
}

/// Events per bucket [`sort_events`] aims at.
const EVENTS_PER_BUCKET: usize = 256;

/// Sort finite-time events by time, then row, column, polarity.
///
/// The key orders events totally (equal keys are identical events), so the result is the
/// same however the work is split. A bucket sort: events go to buckets of equal time span
/// (a monotone function of time, so the buckets are in order), then each bucket is sorted
/// on its own, in parallel — a few hundred events in cache instead of one sort of millions.
/// What is sorted is each event packed into one integer ([`pack`]): a comparison is then
/// two machine comparisons instead of a four-field tuple built from both events.
fn sort_events(events: &mut [SimEvent]) {
    let n = events.len();
    let (t_min, t_max) = events
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), e| {
            (lo.min(e.t_us), hi.max(e.t_us))
        });
    let buckets = n / EVENTS_PER_BUCKET;
    if buckets < 2 || t_max <= t_min {
        events.par_sort_unstable_by_key(pack);
        return;
    }
    let per_us = buckets as f64 / (t_max - t_min);
    let bucket_of = |e: &SimEvent| (((e.t_us - t_min) * per_us) as usize).min(buckets - 1);
    let mut start = vec![0usize; buckets + 1];
    for e in events.iter() {
        start[bucket_of(e) + 1] += 1;
    }
    for b in 0..buckets {
        start[b + 1] += start[b];
    }
    let mut next = start.clone();
    let mut sorted = vec![0u128; n];
    for e in events.iter() {
        let slot = &mut next[bucket_of(e)];
        sorted[*slot] = pack(e);
        *slot += 1;
    }
    // Cut the output at bucket boundaries into pieces for the threads.
    let mut pieces = Vec::with_capacity(buckets);
    let mut rest = sorted.as_mut_slice();
    for b in 0..buckets {
        let (piece, tail) = rest.split_at_mut(start[b + 1] - start[b]);
        pieces.push(piece);
        rest = tail;
    }
    pieces
        .into_par_iter()
        .with_min_len(64)
        .for_each(|piece| piece.sort_unstable());
    for (e, &key) in events.iter_mut().zip(&sorted) {
        *e = unpack(key);
    }
}

/// An event of finite time as one integer whose order is that of (time, row, column,
/// polarity), and from which [`unpack`] gives the event back bit for bit.
#[inline]
fn pack(e: &SimEvent) -> u128 {
    ((ordered_bits(e.t_us) as u128) << 64)
        | ((e.y as u128) << 32)
        | ((e.x as u128) << 16)
        | e.p as u128
}

/// The event packed by [`pack`].
#[inline]
fn unpack(key: u128) -> SimEvent {
    let low = key as u64;
    SimEvent {
        t_us: f64::from_bits(unordered_bits((key >> 64) as u64)),
        x: (low >> 16) as u16,
        y: (low >> 32) as u16,
        p: low as u8,
    }
}

/// A key whose unsigned order is the numeric order of finite `t`.
#[inline]
fn ordered_bits(t: f64) -> u64 {
    let bits = t.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | (1 << 63)
    }
}

/// The bits of `t` given [`ordered_bits`]`(t)`.
#[inline]
fn unordered_bits(key: u64) -> u64 {
    if key >> 63 == 1 {
        key & !(1 << 63)
    } else {
        !key
    }
}

/// Drop events within `refractory` µs of the previous kept event of the same pixel; returns
/// how many were dropped. `events` is in time order.
fn refractory_filter(events: &mut Vec<SimEvent>, refractory: f64) -> u64 {
    let (x_max, y_max) = events
        .iter()
        .fold((0, 0), |(x, y), e| (x.max(e.x), y.max(e.y)));
    let (width, height) = (x_max as usize + 1, y_max as usize + 1);
    let limit = refractory - REFRACTORY_TOLERANCE_US;
    let before = events.len();
    if width * height <= DENSE_TABLE_LIMIT {
        let mut last = vec![f64::NEG_INFINITY; width * height];
        events.retain(|e| {
            let slot = &mut last[e.y as usize * width + e.x as usize];
            if e.t_us - *slot < limit {
                false
            } else {
                *slot = e.t_us;
                true
            }
        });
    } else {
        let mut last: HashMap<(u16, u16), f64> = HashMap::new();
        events.retain(|e| {
            let slot = last.entry((e.x, e.y)).or_insert(f64::NEG_INFINITY);
            if e.t_us - *slot < limit {
                false
            } else {
                *slot = e.t_us;
                true
            }
        });
    }
    (before - events.len()) as u64
}

/// The token bucket of [`read_out`]: `rate` tokens per µs, depth `burst`; returns the number
/// of events dropped. `events` is in time order.
fn token_bucket(events: &mut Vec<SimEvent>, rate: f64, burst: f64) -> u64 {
    let Some(first) = events.first() else {
        return 0;
    };
    let mut tokens = burst;
    let mut last = first.t_us;
    let before = events.len();
    events.retain(|e| {
        tokens = (tokens + (e.t_us - last) * rate).min(burst);
        last = e.t_us;
        if tokens >= 1.0 - 1e-9 {
            tokens -= 1.0;
            true
        } else {
            false
        }
    });
    (before - events.len()) as u64
}

#[cfg(test)]
mod tests {
    use super::{pack, unpack, SimEvent};

    #[test]
    fn packed_events_come_back_bit_for_bit_and_sort_in_order() {
        let events = [
            (-3.5, 9, 1, 0),
            (-0.0, 0, 0, 1),
            (0.0, 0, 0, 0),
            (1e-300, 65_535, 65_535, 1),
            (2.0, 4, 7, 1),
            (2.0, 5, 6, 0),
            (2.0, 4, 7, 0),
            (f64::MAX, 1, 2, 1),
        ]
        .map(|(t_us, x, y, p)| SimEvent { t_us, x, y, p });
        for e in &events {
            let back = unpack(pack(e));
            assert_eq!(back.t_us.to_bits(), e.t_us.to_bits());
            assert_eq!((back.x, back.y, back.p), (e.x, e.y, e.p));
        }
        let mut by_tuple = events.to_vec();
        by_tuple.sort_by(|a, b| {
            a.t_us
                .total_cmp(&b.t_us)
                .then((a.y, a.x, a.p).cmp(&(b.y, b.x, b.p)))
        });
        let mut by_key = events.to_vec();
        by_key.sort_by_key(pack);
        assert_eq!(by_key, by_tuple);
    }
}
