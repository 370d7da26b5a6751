//! Prophesee EVT 2.1 decoder: 64-bit vector words, in either byte order (formats.md §3;
//! Prophesee "EVT 2.1 format" documentation; OpenEB `evt21_event_types.h`).

use super::bytestream::WordDecoder;
use super::evt2::TimeBase34;
use super::prophesee_header::Evt21Order;
use super::DecodeReport;
use crate::event::{EventBuffer, Geometry, Trigger};

const EVT_NEG: u64 = 0x0;
const EVT_POS: u64 = 0x1;
const TIME_HIGH: u64 = 0x8;
const EXT_TRIGGER: u64 = 0xA;
const OTHERS: u64 = 0xE;
const CONTINUED: u64 = 0xF;

/// The logical 64-bit word stored at `bytes` in the given byte order.
#[inline]
pub(crate) fn load_word(bytes: &[u8], order: Evt21Order) -> u64 {
    let lo = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as u64;
    let hi = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as u64;
    match order {
        Evt21Order::Little => lo | hi << 32,
        Evt21Order::Legacy => lo << 32 | hi,
    }
}

/// Stateful EVT 2.1 decoder.
pub(crate) struct Evt21Decoder {
    time: TimeBase34,
    order: Evt21Order,
    width: u32,
    height: u32,
}

impl Evt21Decoder {
    pub fn new(geometry: Option<Geometry>, order: Evt21Order, offset_us: i64) -> Self {
        let g = geometry.unwrap_or(Geometry::new(u32::MAX, u32::MAX));
        Evt21Decoder {
            time: TimeBase34::new(offset_us),
            order,
            width: g.width,
            height: g.height,
        }
    }
}

impl WordDecoder for Evt21Decoder {
    const WORD_BYTES: usize = 8;

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
        let mut base = self.time.base();
        for (i, word) in bytes.chunks_exact(8).enumerate() {
            let w = load_word(word, self.order);
            match w >> 60 {
                EVT_NEG | EVT_POS => {
                    let mut mask = w as u32;
                    let Some(b) = base else {
                        report.before_time_base += mask.count_ones() as u64;
                        continue;
                    };
                    let t = b + ((w >> 54) & 0x3F) as i64;
                    let x0 = ((w >> 43) & 0x7FF) as u32;
                    let y = ((w >> 32) & 0x7FF) as u32;
                    let p = (w >> 60) as u8;
                    if y >= self.height {
                        report.out_of_range += mask.count_ones() as u64;
                        continue;
                    }
                    out.reserve(mask.count_ones() as usize);
                    while mask != 0 {
                        let x = x0 + mask.trailing_zeros();
                        mask &= mask - 1;
                        if x >= self.width {
                            report.out_of_range += 1;
                        } else {
                            out.push(t, x as u16, y as u16, p);
                        }
                    }
                }
                TIME_HIGH => {
                    self.time.set_high((w >> 32) as u32);
                    base = self.time.base();
                }
                EXT_TRIGGER => match base {
                    Some(b) => out.triggers.push(Trigger {
                        t: b + ((w >> 54) & 0x3F) as i64,
                        channel: ((w >> 40) & 0x1F) as u8,
                        value: ((w >> 32) & 1) as u8,
                    }),
                    None => report.before_time_base += 1,
                },
                OTHERS | CONTINUED => report.skipped_other += 1,
                kind => {
                    if report.unknown_words == 0 {
                        report.warn(format!(
                            "EVT 2.1: unknown word type {kind:#x} at byte {}; skipped and counted",
                            offset + 8 * i as u64
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
