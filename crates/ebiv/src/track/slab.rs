//! The automatic detection slab (`slab = auto`): the shortest slab in which most events fall
//! into clusters big enough to be detections.
//!
//! A camera that fires many events per passing particle (a bright image, several threshold
//! crossings per pixel) gives clusters of tens of events in half a millisecond; one that
//! fires about one event per pixel per particle needs a few milliseconds for the same. Too
//! short a slab leaves particles undetected; too long a one lets images of neighbours touch.
//! The choice is made on the first [`PROBE_US`] of the events.

use super::detect::{Detector, TrackEvent};

/// The slabs tried, shortest first, µs.
pub const CANDIDATES_US: [i64; 3] = [500, 1000, 2000];

/// Length of the stretch of events the choice is made on, µs.
pub const PROBE_US: i64 = 20_000;

/// Most events held for the choice.
pub const PROBE_EVENTS: usize = 2_000_000;

/// Share of the events in detections that a slab must reach to be chosen.
const DETECTED_SHARE: f64 = 0.8;

/// The share of `events` (time order) that fall in clusters of at least `min_events` when
/// cut into slabs of `slab_us`.
pub fn detected_share(
    events: &[TrackEvent],
    detector: &mut Detector,
    slab_us: i64,
    min_events: u32,
) -> f64 {
    if events.is_empty() {
        return 0.0;
    }
    let (mut detected, mut start) = (0usize, 0usize);
    while start < events.len() {
        let slab = events[start].t.div_euclid(slab_us);
        let end = start + events[start..].partition_point(|e| e.t.div_euclid(slab_us) <= slab);
        detected += detector
            .detect(&events[start..end], min_events)
            .iter()
            .map(|d| d.events.len())
            .sum::<usize>();
        start = end;
    }
    detected as f64 / events.len() as f64
}

/// The shortest of [`CANDIDATES_US`] whose detected share reaches 80 %, else the one with the
/// largest share; 500 µs without events.
pub fn choose_slab(events: &[TrackEvent], detector: &mut Detector, min_events: u32) -> i64 {
    let mut best = (CANDIDATES_US[0], -1.0);
    for slab in CANDIDATES_US {
        let share = detected_share(events, detector, slab, min_events);
        if share >= DETECTED_SHARE {
            return slab;
        }
        if share > best.1 {
            best = (slab, share);
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A particle image of 3 px crossing a row at `speed` px/ms, one ON event per pixel
    /// entered and one OFF event per pixel left.
    fn sparse_particle(speed: f64, duration_us: i64) -> Vec<TrackEvent> {
        let mut events = Vec::new();
        let mut x = 10.0f64;
        let mut t = 0;
        while t < duration_us {
            let next = 10.0 + speed * (t + 1) as f64 / 1000.0;
            if next.floor() > x.floor() {
                events.push(TrackEvent {
                    t,
                    x: next.floor() as u16 + 1,
                    y: 5,
                    p: 1,
                });
                events.push(TrackEvent {
                    t,
                    x: next.floor() as u16 - 2,
                    y: 5,
                    p: 0,
                });
            }
            x = next;
            t += 1;
        }
        events
    }

    #[test]
    fn sparse_events_get_a_longer_slab() {
        let g = &mut Detector::new(200, 10);
        // 2 events per px at 1.5 px/ms: 1.5 events per 500 µs, 6 per 2 ms.
        let slow = sparse_particle(1.5, 20_000);
        assert_eq!(choose_slab(&slow, g, 4), 2000);
        // At 8 px/ms, 8 events per 500 µs.
        let fast = sparse_particle(8.0, 20_000);
        assert_eq!(choose_slab(&fast, g, 4), 500);
        assert_eq!(choose_slab(&[], g, 4), 500);
    }
}
