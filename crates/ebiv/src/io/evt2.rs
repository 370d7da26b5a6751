//! Prophesee EVT 2.0 decoder: 32-bit little-endian words (formats.md §2; Prophesee
//! "EVT 2.0 format" documentation; OpenEB `evt2_event_types.h`).

use super::bytestream::WordDecoder;
use super::DecodeReport;
use crate::event::{EventBuffer, Geometry, Trigger};

const CD_OFF: u32 = 0x0;
const CD_ON: u32 = 0x1;
const TIME_HIGH: u32 = 0x8;
const EXT_TRIGGER: u32 = 0xA;
const IMU: u32 = 0xD;
const OTHERS: u32 = 0xE;
const CONTINUED: u32 = 0xF;

/// The 34-bit time base shared by EVT 2.0 and EVT 2.1: `TIME_HIGH` holds t[33:6], event
/// words t[5:0]; a wrap (every 2^34 µs ≈ 4 h 46 min) is a new `TIME_HIGH` smaller than the
/// previous one by at least 2^34 − 10 000 µs (OpenEB's rule).
#[derive(Debug, Clone, Default)]
pub(crate) struct TimeBase34 {
    /// Current time base in µs, loops included, offset included; `None` before the first.
    base: Option<i64>,
    last_high_us: i64,
    loops_us: i64,
    first_high_us: Option<i64>,
    offset_us: i64,
}

const LOOP_US: i64 = 1 << 34;
const WRAP_MARGIN_US: i64 = 10_000;

impl TimeBase34 {
    pub fn new(offset_us: i64) -> Self {
        TimeBase34 {
            offset_us,
            ..Default::default()
        }
    }

    /// Apply a `TIME_HIGH` payload (t[33:6]).
    #[inline]
    pub fn set_high(&mut self, payload: u32) {
        let high_us = ((payload & 0x0FFF_FFFF) as i64) << 6;
        if self.base.is_some() && self.last_high_us - high_us >= LOOP_US - WRAP_MARGIN_US {
            self.loops_us += LOOP_US;
        }
        self.first_high_us.get_or_insert(high_us);
        self.last_high_us = high_us;
        self.base = Some(self.offset_us + self.loops_us + high_us);
    }

    /// The time base, `None` before the first `TIME_HIGH`.
    #[inline]
    pub fn base(&self) -> Option<i64> {
        self.base
    }

    /// The Metavision SDK shift: first `TIME_HIGH` << 6 (formats.md §14.1).
    pub fn metavision_shift(&self) -> Option<i64> {
        self.first_high_us.map(|h| h + self.offset_us)
    }

    /// The state carried between words (the header's offset is not part of it):
    /// `[has base, base, last high, loops, has first high, first high]`.
    pub fn state(&self) -> Vec<i64> {
        vec![
            self.base.is_some() as i64,
            self.base.unwrap_or(0),
            self.last_high_us,
            self.loops_us,
            self.first_high_us.is_some() as i64,
            self.first_high_us.unwrap_or(0),
        ]
    }

    /// Resume with a [`TimeBase34::state`].
    pub fn restore(&mut self, state: &[i64]) -> Option<()> {
        let &[has_base, base, last_high, loops, has_first, first] = state else {
            return None;
        };
        self.base = (has_base != 0).then_some(base);
        self.last_high_us = last_high;
        self.loops_us = loops;
        self.first_high_us = (has_first != 0).then_some(first);
        Some(())
    }
}

/// Stateful EVT 2.0 decoder.
pub(crate) struct Evt2Decoder {
    time: TimeBase34,
    width: u32,
    height: u32,
}

impl Evt2Decoder {
    pub fn new(geometry: Option<Geometry>, offset_us: i64) -> Self {
        let g = geometry.unwrap_or(Geometry::new(u32::MAX, u32::MAX));
        Evt2Decoder {
            time: TimeBase34::new(offset_us),
            width: g.width,
            height: g.height,
        }
    }
}

impl WordDecoder for Evt2Decoder {
    const WORD_BYTES: usize = 4;

    fn state(&self) -> Option<Vec<i64>> {
        Some(self.time.state())
    }

    fn restore(&mut self, state: &[i64]) -> Option<()> {
        self.time.restore(state)
    }

    fn decode(
        &mut self,
        bytes: &[u8],
        offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        out.reserve(bytes.len() / 4);
        let mut base = self.time.base();
        for (i, word) in bytes.chunks_exact(4).enumerate() {
            let w = u32::from_le_bytes([word[0], word[1], word[2], word[3]]);
            match w >> 28 {
                CD_OFF | CD_ON => {
                    let Some(b) = base else {
                        report.before_time_base += 1;
                        continue;
                    };
                    let x = (w >> 11) & 0x7FF;
                    let y = w & 0x7FF;
                    if x >= self.width || y >= self.height {
                        report.out_of_range += 1;
                        continue;
                    }
                    let t = b + ((w >> 22) & 0x3F) as i64;
                    out.push(t, x as u16, y as u16, (w >> 28) as u8);
                }
                TIME_HIGH => {
                    self.time.set_high(w);
                    base = self.time.base();
                }
                EXT_TRIGGER => match base {
                    Some(b) => out.triggers.push(Trigger {
                        t: b + ((w >> 22) & 0x3F) as i64,
                        channel: ((w >> 8) & 0x1F) as u8,
                        value: (w & 1) as u8,
                    }),
                    None => report.before_time_base += 1,
                },
                IMU | OTHERS | CONTINUED => report.skipped_other += 1,
                kind => {
                    if report.unknown_words == 0 {
                        report.warn(format!(
                            "EVT 2.0: unknown word type {kind:#x} at byte {}; skipped and counted",
                            offset + 4 * i as u64
                        ));
                    }
                    report.unknown_words += 1;
                }
            }
        }
    }

    fn metavision_time_shift(&self) -> Option<i64> {
        self.time.metavision_shift()
    }
}
