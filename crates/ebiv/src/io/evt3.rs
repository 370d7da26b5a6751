//! Prophesee EVT 3.0 decoder: 16-bit stateful words (formats.md §4; Prophesee "EVT 3.0
//! format" documentation; OpenEB `evt3_event_types.h` and the standalone EVT 3.0 decoder).
//!
//! Semantics follow OpenEB: words before the first `TIME_HIGH` are dropped (and counted),
//! the 24-bit time base loops when a `TIME_HIGH` is more than 2048 units below the previous
//! one, `TIME_LOW` never carries into the high part and its regressions pass through.

use super::bytestream::WordDecoder;
use super::DecodeReport;
use crate::event::{EventBuffer, Geometry, Trigger};

const ADDR_Y: u16 = 0x0;
const ADDR_X: u16 = 0x2;
const VECT_BASE_X: u16 = 0x3;
const VECT_12: u16 = 0x4;
const VECT_8: u16 = 0x5;
const TIME_LOW: u16 = 0x6;
const CONTINUED_4: u16 = 0x7;
const TIME_HIGH: u16 = 0x8;
const EXT_TRIGGER: u16 = 0xA;
const IMU: u16 = 0xD;
const OTHERS: u16 = 0xE;
const CONTINUED_12: u16 = 0xF;

/// One loop of the 24-bit time base, in µs.
pub(crate) const EVT3_LOOP_US: i64 = 1 << 24;
/// A `TIME_HIGH` this many units below the previous one means the time base looped.
pub(crate) const EVT3_WRAP_THRESHOLD: u16 = 2048;

/// Stateful EVT 3.0 decoder.
pub(crate) struct Evt3Decoder {
    width: u32,
    height: u32,
    offset_us: i64,
    loops_us: i64,
    time_high: u16,
    /// `loops + time_high << 12 + offset`, valid once a `TIME_HIGH` was seen.
    high_us: i64,
    t: i64,
    seen_time_high: bool,
    first_time_high: Option<u16>,
    y: u16,
    y_valid: bool,
    base_x: u32,
    vect_pol: u8,
    seen_vector_base: bool,
}

impl Evt3Decoder {
    pub fn new(geometry: Option<Geometry>, offset_us: i64) -> Self {
        let g = geometry.unwrap_or(Geometry::new(u32::MAX, u32::MAX));
        Evt3Decoder {
            width: g.width,
            height: g.height,
            offset_us,
            loops_us: 0,
            time_high: 0,
            high_us: 0,
            t: 0,
            seen_time_high: false,
            first_time_high: None,
            y: 0,
            y_valid: false,
            base_x: 0,
            vect_pol: 0,
            seen_vector_base: false,
        }
    }

    /// Emit the events of a vector mask of `bits` bits at the current vector base.
    #[inline]
    fn vector(
        &mut self,
        mut mask: u32,
        bits: u32,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        if !self.seen_time_high || !self.seen_vector_base || !self.y_valid {
            let n = mask.count_ones() as u64;
            if self.seen_time_high {
                report.malformed += n;
            } else {
                report.before_time_base += n;
            }
            self.base_x += bits;
            return;
        }
        while mask != 0 {
            let x = self.base_x + mask.trailing_zeros();
            mask &= mask - 1;
            if x >= self.width {
                report.out_of_range += 1;
            } else {
                out.push(self.t, x as u16, self.y, self.vect_pol);
            }
        }
        self.base_x += bits;
    }
}

impl WordDecoder for Evt3Decoder {
    const WORD_BYTES: usize = 2;

    fn decode(
        &mut self,
        bytes: &[u8],
        offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        out.reserve(bytes.len() / 2);
        for (i, word) in bytes.chunks_exact(2).enumerate() {
            let w = u16::from_le_bytes([word[0], word[1]]);
            match w >> 12 {
                ADDR_X => {
                    if !self.seen_time_high {
                        report.before_time_base += 1;
                        continue;
                    }
                    let x = (w & 0x7FF) as u32;
                    if x >= self.width || !self.y_valid {
                        report.out_of_range += 1;
                        continue;
                    }
                    out.push(self.t, x as u16, self.y, ((w >> 11) & 1) as u8);
                }
                TIME_LOW => {
                    self.t = self.high_us + (w & 0xFFF) as i64;
                }
                ADDR_Y => {
                    let y = w & 0x7FF;
                    self.y = y;
                    self.y_valid = (y as u32) < self.height;
                }
                VECT_BASE_X => {
                    self.base_x = (w & 0x7FF) as u32;
                    self.vect_pol = ((w >> 11) & 1) as u8;
                    self.seen_vector_base = true;
                }
                VECT_12 => self.vector((w & 0xFFF) as u32, 12, out, report),
                VECT_8 => self.vector((w & 0xFF) as u32, 8, out, report),
                TIME_HIGH => {
                    let th = w & 0xFFF;
                    if self.seen_time_high {
                        if th + EVT3_WRAP_THRESHOLD < self.time_high {
                            self.loops_us += EVT3_LOOP_US;
                        }
                    } else {
                        self.first_time_high = Some(th);
                    }
                    let same = self.seen_time_high && th == self.time_high;
                    self.time_high = th;
                    self.seen_time_high = true;
                    self.high_us = self.offset_us + self.loops_us + ((th as i64) << 12);
                    // A repeated TIME_HIGH keeps the current TIME_LOW (OpenEB HAL).
                    if !same {
                        self.t = self.high_us;
                    }
                }
                EXT_TRIGGER => {
                    if self.seen_time_high {
                        out.triggers.push(Trigger {
                            t: self.t,
                            channel: ((w >> 8) & 0xF) as u8,
                            value: (w & 1) as u8,
                        });
                    } else {
                        report.before_time_base += 1;
                    }
                }
                CONTINUED_4 | CONTINUED_12 | OTHERS | IMU => report.skipped_other += 1,
                kind => {
                    if report.unknown_words == 0 {
                        report.warn(format!(
                            "EVT 3.0: unknown word type {kind:#x} at byte {}; skipped and counted",
                            offset + 2 * i as u64
                        ));
                    }
                    report.unknown_words += 1;
                }
            }
        }
    }

    /// Metavision SDK shift: (first `TIME_HIGH` − 1) << 12 (formats.md §14.1).
    fn metavision_time_shift(&self) -> Option<i64> {
        self.first_time_high
            .map(|th| self.offset_us + ((th as i64 - 1) << 12))
    }
}
