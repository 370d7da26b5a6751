//! Finding the pulse timing of a recording: the events and trigger edges of its first
//! seconds handed to [`detect_pulses`].

use super::pulse::{detect_pulses, PulseTiming};
use crate::error::Result;
use crate::event::{EventBuffer, PolaritySelection};
use crate::io::EventReader;

/// Longest stretch of a recording read to find the pulse timing, µs.
pub const PULSE_SCAN_US: i64 = 2_000_000;
/// Most events read to find the pulse timing.
pub const PULSE_SCAN_EVENTS: usize = 4_000_000;

/// The pulse timing of `reader` from its events of `polarity` and its trigger edges in
/// `[start_us, end_us)`, reading at most [`PULSE_SCAN_US`] from `start_us` (the first event
/// when `None`) and at most [`PULSE_SCAN_EVENTS`] events. `nominal_hz` narrows the search
/// (see [`detect_pulses`]).
pub fn scan_pulse_timing(
    reader: &mut EventReader,
    polarity: PolaritySelection,
    start_us: Option<i64>,
    end_us: Option<i64>,
    nominal_hz: Option<f64>,
) -> Result<PulseTiming> {
    if let Some(start) = start_us {
        reader.skip_to(start)?;
    }
    let mut batch = EventBuffer::new();
    let (mut times, mut triggers) = (Vec::new(), Vec::new());
    let mut interval: Option<(i64, i64)> = start_us.map(|s| (s, scan_end(s, end_us)));
    'read: while reader.read_batch(&mut batch)? {
        let Some(&first) = batch.t.first() else {
            continue;
        };
        let (start, until) = *interval.get_or_insert((first, scan_end(first, end_us)));
        triggers.extend(
            batch
                .triggers
                .iter()
                .filter(|tr| tr.t >= start && tr.t < until),
        );
        for i in 0..batch.len() {
            let t = batch.t[i];
            if t >= until || times.len() >= PULSE_SCAN_EVENTS {
                break 'read;
            }
            if t >= start && polarity.accepts(batch.p[i]) {
                times.push(t);
            }
        }
    }
    detect_pulses(&times, &triggers, nominal_hz)
}

fn scan_end(start: i64, end_us: Option<i64>) -> i64 {
    let most = start.saturating_add(PULSE_SCAN_US);
    end_us.map_or(most, |e| e.min(most))
}
