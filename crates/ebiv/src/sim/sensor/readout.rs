//! The readout: time order, refractory filter, bandwidth limit and 1 µs time stamps
//! (sensor-model.md §2.5, §2.10, §2.11).

mod filter;
mod stream;

pub use stream::StreamingReadout;

use super::params::{SensorParams, TimestampMode};
use super::response::clean;
use super::{PixelCounters, SimEvent};
use crate::event::EventBuffer;
use crate::sim::fastmath::floor_i64;
use rayon::iter::{
    IndexedParallelIterator, IntoParallelIterator, IntoParallelRefIterator,
    IntoParallelRefMutIterator, ParallelIterator,
};
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

/// Sort by time, enforce the refractory period across signal and noise events, apply the
/// readout bandwidth limit, quantise to 1 µs, and return the events in time order.
///
/// * **Order**: exact time, then row, column, polarity — a total order, so the result does not
///   depend on the order of `events` (nor, in [`read_out_parts`], on how they are split into
///   parts).
/// * **Refractory**: an event closer than `refractory_us` (less 1e-6 µs) to the previous event
///   of its pixel that passed this filter is dropped; the earlier event wins (IEBCS: a pixel
///   is blind after any event, §2.5). An event the bandwidth limit then drops has still
///   blinded its pixel.
/// * **Bandwidth** (`bandwidth_ev_per_s = R`, `bandwidth_burst_events = D`): a token bucket.
///   It holds up to D tokens, starts full and refills at R per second; an event passes if a
///   token is available and takes it, and is dropped when the bucket is empty — so the
///   earliest events of a burst pass and at most `D + R·(b − a)` events lie in any interval
///   `[a, b]`. Passing events are not delayed (no FIFO). Real sensors also lose events row-wise
///   (§2.11); this is the simplest model with that bound.
/// * **Time stamps**: `round` or `truncate` (floor) to 1 µs, after the two steps above, which
///   use exact times.
pub fn read_out(events: Vec<SimEvent>, params: &SensorParams) -> (EventBuffer, ReadoutReport) {
    read_out_parts(&[events.as_slice()], params)
}

/// [`read_out`] of the events of several parts taken together (the bands of a simulation),
/// without first copying them into one vector: the same events, in the same order, whatever
/// the parts and their order.
///
/// The work is spread over the threads: the events are put in order by a parallel bucket
/// sort of packed keys ([`sorted_keys`]; one part is scattered by one thread), the
/// refractory filter and the token bucket run over chunks of the keys in parallel, each
/// chunk checked against the state the chunks before leave ([`filter::drops`]; the token
/// bucket sees exactly the events the refractory filter keeps), and the output arrays are
/// filled in parallel. The bucket starts full at the first event overall, which is also the
/// first the refractory filter keeps (its pixel has no earlier event).
pub fn read_out_parts(
    parts: &[&[SimEvent]],
    params: &SensorParams,
) -> (EventBuffer, ReadoutReport) {
    let mut report = ReadoutReport {
        events_in: parts.iter().map(|p| p.len() as u64).sum(),
        ..ReadoutReport::default()
    };
    let keys = sorted_keys(parts);
    report.dropped_invalid = report.events_in - keys.len() as u64;

    let drops = filter::drops(&keys, readout_filters(params));
    report.dropped_refractory = drops.refractory;
    report.dropped_bandwidth = drops.bandwidth;

    let buffer = event_buffer(&keys, &drops.indices, params.timestamp);
    report.events_out = buffer.len() as u64;
    (buffer, report)
}

/// The refractory filter and token bucket `params` ask for.
fn readout_filters(params: &SensorParams) -> filter::Filters {
    filter::Filters {
        refractory: clean(params.refractory_us, 0.0, 1e12, 0.0),
        bucket: params.bandwidth_ev_per_s.filter(|r| *r > 0.0).map(|rate| {
            let burst = clean(params.bandwidth_burst_events, 1.0, 1e12, 1.0);
            (rate * 1e-6, burst)
        }),
    }
}

/// The 1 µs time stamp of exact time `t`, rounded or truncated.
#[inline]
fn stamp(timestamp: TimestampMode, t: f64) -> i64 {
    match timestamp {
        TimestampMode::Round => t.round() as i64,
        // `floor_i64` is `floor() as i64` without a library call per event.
        TimestampMode::Truncate => floor_i64(t),
    }
}

/// The events of `part` the readout takes at all: a finite time and a polarity of 0 or 1.
/// Every pass over the parts goes through this one filter, so that they agree on the events.
#[inline]
fn valid_events(part: &[SimEvent]) -> impl Iterator<Item = &SimEvent> {
    part.iter().filter(|e| e.t_us.is_finite() && e.p <= 1)
}

/// Events per bucket [`sorted_keys`] aims at.
const EVENTS_PER_BUCKET: usize = 256;

/// The valid events ([`valid_events`]) of all parts packed ([`pack`]) and sorted: by time, then
/// row, column, polarity.
///
/// The key orders events totally (equal keys are identical events), so the result is the
/// same however the work is split. A parallel bucket sort: each part counts its events per
/// bucket of equal time span (a monotone function of time, so the buckets are in order) and
/// writes their keys into the output at its own offsets, the parts in parallel; then each
/// bucket is sorted on its own, in parallel — a few hundred keys in cache instead of one
/// sort of millions.
fn sorted_keys(parts: &[&[SimEvent]]) -> Vec<u128> {
    let (n, t_min, t_max) = parts
        .par_iter()
        .map(|part| {
            valid_events(part).fold(
                (0usize, f64::INFINITY, f64::NEG_INFINITY),
                |(n, lo, hi), e| (n + 1, lo.min(e.t_us), hi.max(e.t_us)),
            )
        })
        .reduce(
            || (0, f64::INFINITY, f64::NEG_INFINITY),
            |a, b| (a.0 + b.0, a.1.min(b.1), a.2.max(b.2)),
        );
    let buckets = n / EVENTS_PER_BUCKET;
    if buckets < 2 || t_max <= t_min {
        let mut keys: Vec<u128> = parts
            .iter()
            .flat_map(|part| valid_events(part).map(pack))
            .collect();
        keys.par_sort_unstable();
        return keys;
    }
    let per_us = buckets as f64 / (t_max - t_min);
    let bucket_of = |e: &SimEvent| (((e.t_us - t_min) * per_us) as usize).min(buckets - 1);

    // Per part, its events per bucket; then where its first and last one go: bucket `b` of
    // the output starts at `start[b]` and holds the part's events after those of the parts
    // before it.
    let counts: Vec<Vec<usize>> = parts
        .par_iter()
        .map(|part| {
            let mut counts = vec![0usize; buckets];
            for e in valid_events(part) {
                counts[bucket_of(e)] += 1;
            }
            counts
        })
        .collect();
    let mut offsets = counts.clone();
    let mut ends = counts;
    let mut start = Vec::with_capacity(buckets + 1);
    start.push(0usize);
    for b in 0..buckets {
        let mut offset = start[b];
        for (first, end) in offsets.iter_mut().zip(ends.iter_mut()) {
            (first[b], end[b]) = (offset, offset + end[b]);
            offset = end[b];
        }
        start.push(offset);
    }

    let mut keys = vec![0u128; n];
    let slots = DisjointSlots::new(&mut keys);
    parts
        .par_iter()
        .zip(offsets.par_iter_mut())
        .zip(ends.par_iter())
        .for_each(|((part, next), ends)| {
            for e in valid_events(part) {
                let b = bucket_of(e);
                let slot = &mut next[b];
                assert!(*slot < ends[b], "bucket {b} of a part overflows its range");
                // SAFETY: part `p` writes bucket `b` only inside `offsets[p][b]..ends[p][b]`
                // (asserted), ranges the prefix sums above lay end to end without overlap,
                // and each part's task is the only one advancing its own offsets.
                unsafe { slots.write(*slot, pack(e)) };
                *slot += 1;
            }
        });

    let mut pieces = Vec::with_capacity(buckets);
    let mut rest = keys.as_mut_slice();
    for b in 0..buckets {
        let (piece, tail) = rest.split_at_mut(start[b + 1] - start[b]);
        pieces.push(piece);
        rest = tail;
    }
    pieces
        .into_par_iter()
        .with_min_len(64)
        .for_each(|piece| piece.sort_unstable());
    keys
}

/// A slice that several threads write at once, each at indices no other thread writes
/// ([`sorted_keys`]' scatter, whose destinations are laid out by prefix sums).
struct DisjointSlots<'a> {
    ptr: *mut u128,
    len: usize,
    _slice: std::marker::PhantomData<&'a mut [u128]>,
}

// SAFETY: shared between threads only through `write`, whose callers guarantee that no two
// threads write the same index; the slice stays mutably borrowed, so untouched by anything
// else, until every task of the scatter has ended.
unsafe impl Sync for DisjointSlots<'_> {}

impl<'a> DisjointSlots<'a> {
    fn new(slice: &'a mut [u128]) -> Self {
        DisjointSlots {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _slice: std::marker::PhantomData,
        }
    }

    /// Write `value` at `index` (panics if out of bounds).
    ///
    /// # Safety
    /// No other thread may read or write `index` while the slots exist.
    #[inline]
    unsafe fn write(&self, index: usize, value: u128) {
        assert!(index < self.len, "slot {index} of {}", self.len);
        // SAFETY: in bounds (checked), and the caller rules out concurrent access.
        unsafe { self.ptr.add(index).write(value) }
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
#[cfg(test)]
fn unpack(key: u128) -> SimEvent {
    let (x, y) = key_pixel(key);
    SimEvent {
        t_us: key_time(key),
        x,
        y,
        p: key as u8,
    }
}

/// The exact time of a packed event ([`pack`]).
#[inline]
fn key_time(key: u128) -> f64 {
    f64::from_bits(unordered_bits((key >> 64) as u64))
}

/// The column and row of a packed event ([`pack`]).
#[inline]
fn key_pixel(key: u128) -> (u16, u16) {
    ((key >> 16) as u16, (key >> 32) as u16)
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

/// Events per task when [`event_buffer`] fills its arrays.
const BUFFER_CHUNK: usize = 1 << 16;

/// The packed events `keys` but those at the indices `dropped` (ascending) as an event buffer,
/// time stamps rounded or truncated to 1 µs; filled in parallel.
fn event_buffer(keys: &[u128], dropped: &[usize], timestamp: TimestampMode) -> EventBuffer {
    let n = keys.len() - dropped.len();
    let mut buffer = EventBuffer {
        t: vec![0; n],
        x: vec![0; n],
        y: vec![0; n],
        p: vec![0; n],
        triggers: Vec::new(),
    };
    buffer
        .t
        .par_chunks_mut(BUFFER_CHUNK)
        .zip(buffer.x.par_chunks_mut(BUFFER_CHUNK))
        .zip(buffer.y.par_chunks_mut(BUFFER_CHUNK))
        .zip(buffer.p.par_chunks_mut(BUFFER_CHUNK))
        .enumerate()
        .for_each(|(chunk, (((t, x), y), p))| {
            // The chunk's first output is the kept key after `skipped` dropped ones.
            let first = chunk * BUFFER_CHUNK;
            let mut skipped = dropped_before_kept(dropped, first);
            let mut i = first + skipped;
            for k in 0..t.len() {
                while dropped.get(skipped) == Some(&i) {
                    skipped += 1;
                    i += 1;
                }
                let key = keys[i];
                t[k] = stamp(timestamp, key_time(key));
                (x[k], y[k]) = key_pixel(key);
                p[k] = key as u8;
                i += 1;
            }
        });
    buffer
}

/// How many of the `dropped` indices (ascending) come before the `kept`-th index not among
/// them (counting from 0): `dropped[j]` does iff at most `kept` indices before it are kept,
/// `dropped[j] − j ≤ kept`, which holds for a prefix of `j`.
fn dropped_before_kept(dropped: &[usize], kept: usize) -> usize {
    let (mut lo, mut hi) = (0, dropped.len());
    while lo < hi {
        let mid = (lo + hi) / 2;
        if dropped[mid] - mid <= kept {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
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
