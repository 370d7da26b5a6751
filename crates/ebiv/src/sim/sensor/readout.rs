//! The readout: time order, refractory filter, bandwidth limit and 1 µs time stamps
//! (sensor-model.md §2.5, §2.10, §2.11).

mod filter;
mod stream;

pub use stream::StreamingReadout;

use super::params::{SensorParams, TimestampMode};
use super::response::clean;
use super::{PixelCounters, SimEvent};
use crate::event::{EventBuffer, Geometry};
use crate::sim::fastmath::floor_i64;

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
/// One window of a [`StreamingReadout`] over a sensor just large enough for every event: the
/// events are packed into keys that order them totally, bucket-sorted, filtered in one pass
/// and stamped, on one thread, with two 16-byte keys per event in memory besides the output
/// (a long simulation reads out beside its bands instead, as `ebiv simulate` does).
pub fn read_out_parts(
    parts: &[&[SimEvent]],
    params: &SensorParams,
) -> (EventBuffer, ReadoutReport) {
    let (width, height) = parts
        .iter()
        .flat_map(|part| part.iter().filter(|e| readable(e)))
        .fold((0, 0), |(w, h), e| {
            (w.max(u32::from(e.x) + 1), h.max(u32::from(e.y) + 1))
        });
    StreamingReadout::new(params, Geometry::new(width, height)).finish_parts(parts)
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

/// Whether the readout takes event `e` at all: a finite time and a polarity of 0 or 1.
#[inline]
fn readable(e: &SimEvent) -> bool {
    e.t_us.is_finite() && e.p <= 1
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
