//! Prophesee EVT 3.0 decoder: 16-bit stateful words (formats.md §4; Prophesee "EVT 3.0
//! format" documentation; OpenEB `evt3_event_types.h` and the standalone EVT 3.0 decoder).
//!
//! Semantics follow OpenEB: words before the first `TIME_HIGH` are dropped (and counted),
//! the 24-bit time base loops when a `TIME_HIGH` is more than 2048 units below the previous
//! one, `TIME_LOW` never carries into the high part and its regressions pass through.

use super::bytestream::WordDecoder;
use super::sink::{self, EventSink};
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

/// Words decoded into one reservation of the output (twelve events per word at most).
const PIECE_WORDS: usize = 4096;

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
        sink: &mut EventSink,
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
                sink.push(self.t, x as u16, self.y, self.vect_pol);
            }
        }
        self.base_x += bits;
    }

    /// One word, as the format defines it (`at`: its file offset).
    fn word(&mut self, w: u16, at: u64, sink: &mut EventSink, report: &mut DecodeReport) {
        match w >> 12 {
            ADDR_X => {
                if !self.seen_time_high {
                    report.before_time_base += 1;
                    return;
                }
                let x = (w & 0x7FF) as u32;
                if x >= self.width || !self.y_valid {
                    report.out_of_range += 1;
                    return;
                }
                sink.push(self.t, x as u16, self.y, ((w >> 11) & 1) as u8);
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
            VECT_12 => self.vector((w & 0xFFF) as u32, 12, sink, report),
            VECT_8 => self.vector((w & 0xFF) as u32, 8, sink, report),
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
                    sink.triggers.push(Trigger {
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
                        "EVT 3.0: unknown word type {kind:#x} at byte {at}; skipped and counted"
                    ));
                }
                report.unknown_words += 1;
            }
        }
    }

    /// The run of `ADDR_Y`, `ADDR_X` pairs at word `i` of `piece`, after the first time base:
    /// each pair is one event, written and kept when its pixel is on the sensor, as
    /// [`Evt3Decoder::word`] would decode the two words. Returns the index of the first word
    /// after the run.
    fn addr_pairs(
        &mut self,
        piece: &[u8],
        i: usize,
        sink: &mut EventSink,
        report: &mut DecodeReport,
    ) -> usize {
        let (width, height, t) = (self.width, self.height, self.t);
        let (mut pairs, mut out_of_range, mut last_y) = (0usize, 0u64, self.y);
        let (counted, taken, row) = (&mut out_of_range, &mut pairs, &mut last_y);
        let mut words = piece[2 * i..]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        sink.extend_while(&mut words, move |&pair| {
            // Low half ADDR_Y (type 0x0), high half ADDR_X (type 0x2).
            (pair & 0xF000_F000 == (ADDR_X as u32) << 28).then(|| {
                let y = (pair & 0x7FF) as u16;
                let x = ((pair >> 16) & 0x7FF) as u16;
                let inside = ((x as u32) < width) & ((y as u32) < height);
                *counted += !inside as u64;
                *taken += 1;
                *row = y;
                (inside, t, x, y, ((pair >> 27) & 1) as u8)
            })
        });
        report.out_of_range += out_of_range;
        self.y = last_y;
        self.y_valid = (last_y as u32) < height;
        i + 2 * pairs
    }
}

impl WordDecoder for Evt3Decoder {
    const WORD_BYTES: usize = 2;

    /// Everything but the sensor size and the header's offset, in field order.
    fn state(&self) -> Option<Vec<i64>> {
        Some(vec![
            self.loops_us,
            self.time_high as i64,
            self.high_us,
            self.t,
            self.seen_time_high as i64,
            self.first_time_high.map_or(-1, i64::from),
            self.y as i64,
            self.y_valid as i64,
            self.base_x as i64,
            self.vect_pol as i64,
            self.seen_vector_base as i64,
        ])
    }

    fn restore(&mut self, state: &[i64]) -> Option<()> {
        let &[loops, time_high, high, t, seen_high, first_high, y, y_valid, base_x, pol, seen_base] =
            state
        else {
            return None;
        };
        self.loops_us = loops;
        self.time_high = u16::try_from(time_high).ok()?;
        self.high_us = high;
        self.t = t;
        self.seen_time_high = seen_high != 0;
        self.first_time_high = (first_high >= 0)
            .then(|| u16::try_from(first_high).ok())
            .flatten();
        self.y = u16::try_from(y).ok()?;
        self.y_valid = y_valid != 0;
        self.base_x = u32::try_from(base_x).ok()?;
        self.vect_pol = u8::try_from(pol).ok()?;
        self.seen_vector_base = seen_base != 0;
        Some(())
    }

    /// Runs of `ADDR_Y`, `ADDR_X` pairs (one event on its own row, the common word pair of
    /// sparse recordings) take a straight path, [`Evt3Decoder::addr_pairs`]; every other word
    /// goes through [`Evt3Decoder::word`].
    fn decode(
        &mut self,
        bytes: &[u8],
        offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        out.reserve(bytes.len() / 2);
        // Pieces whose worst case (twelve events per vector word) is reserved up front.
        for (k, piece) in bytes.chunks(2 * PIECE_WORDS).enumerate() {
            let start = offset + (2 * PIECE_WORDS * k) as u64;
            let n = piece.len() / 2;
            let word = |i: usize| u16::from_le_bytes([piece[2 * i], piece[2 * i + 1]]);
            sink::append(out, n * 12, |sink| {
                let mut i = 0;
                while i < n {
                    let w = word(i);
                    if w >> 12 == ADDR_Y
                        && self.seen_time_high
                        && i + 1 < n
                        && word(i + 1) >> 12 == ADDR_X
                    {
                        i = self.addr_pairs(piece, i, sink, report);
                    } else {
                        self.word(w, start + 2 * i as u64, sink, report);
                        i += 1;
                    }
                }
            });
        }
    }

    /// Metavision SDK shift: (first `TIME_HIGH` − 1) << 12 (formats.md §14.1).
    fn metavision_time_shift(&self) -> Option<i64> {
        self.first_time_high
            .map(|th| self.offset_us + ((th as i64 - 1) << 12))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn decode(words: &[u16], geometry: Geometry) -> (EventBuffer, DecodeReport) {
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let mut dec = Evt3Decoder::new(Some(geometry), 0);
        let (mut out, mut report) = (EventBuffer::new(), DecodeReport::default());
        // Word by word, as if every word arrived in its own read buffer.
        for (i, pair) in bytes.chunks(2).enumerate() {
            dec.decode(pair, 2 * i as u64, &mut out, &mut report);
        }
        (out, report)
    }

    const fn w(kind: u16, payload: u16) -> u16 {
        kind << 12 | payload
    }

    #[test]
    fn vectors_emit_32_pixel_masks() {
        let g = Geometry::new(1280, 720);
        let words = [
            w(TIME_HIGH, 5),
            w(TIME_LOW, 7),
            w(ADDR_Y, 100),
            w(VECT_BASE_X, 1 << 11 | 64), // ON, base 64
            w(VECT_12, 0b1000_0000_0001), // x 64, 75
            w(VECT_12, 0b0000_0000_0010), // x 77
            w(VECT_8, 0b1000_0000),       // x 95
            w(ADDR_X, 3),                 // one OFF event, base unchanged
        ];
        let (out, report) = decode(&words, g);
        assert_eq!(out.x, vec![64, 75, 77, 95, 3]);
        assert_eq!(out.p, vec![1, 1, 1, 1, 0]);
        assert!(out.t.iter().all(|&t| t == 5 * 4096 + 7));
        assert!(out.y.iter().all(|&y| y == 100));
        assert!(!report.has_problems());
    }

    #[test]
    fn bad_vectors_and_pixels_are_counted_not_emitted() {
        let g = Geometry::new(100, 50);
        let words = [
            w(VECT_12, 0xFFF), // before any time base
            w(TIME_HIGH, 1),
            w(ADDR_Y, 10),
            w(VECT_12, 0b11), // no vector base yet
            w(VECT_BASE_X, 96),
            w(VECT_8, 0b1111_1111), // x 96..103: 4 beyond the width
            w(ADDR_Y, 60),          // beyond the height
            w(ADDR_X, 1),
            w(0x9, 0), // unused type
        ];
        let (out, report) = decode(&words, g);
        assert_eq!(out.x, vec![96, 97, 98, 99]);
        assert_eq!(report.before_time_base, 12);
        assert_eq!(report.malformed, 2);
        assert_eq!(report.out_of_range, 5);
        assert_eq!(report.unknown_words, 1);
        assert_eq!(report.warnings.len(), 1);
    }

    #[test]
    fn time_low_regressions_pass_through_and_others_are_skipped() {
        let g = Geometry::new(64, 64);
        let words = [
            w(TIME_HIGH, 2),
            w(ADDR_Y, 1),
            w(TIME_LOW, 100),
            w(ADDR_X, 1),
            w(TIME_LOW, 90),
            w(ADDR_X, 2),
            w(OTHERS, 0x14),
            w(CONTINUED_12, 0xABC),
            w(CONTINUED_12, 0xDEF),
            w(CONTINUED_4, 0x3),
            w(EXT_TRIGGER, 5 << 8 | 1),
            w(TIME_HIGH, 2), // repeated: keeps TIME_LOW
            w(ADDR_X, 3),
            w(TIME_HIGH, 3), // new: low part restarts at 0
            w(ADDR_X, 4),
        ];
        let (out, report) = decode(&words, g);
        let base = 2 * 4096;
        assert_eq!(out.t, vec![base + 100, base + 90, base + 90, 3 * 4096]);
        assert_eq!(report.skipped_other, 4);
        assert_eq!(
            out.triggers,
            vec![Trigger {
                t: base + 90,
                channel: 5,
                value: 1
            }]
        );
    }

    #[test]
    fn time_high_loop_follows_openeb_threshold() {
        let g = Geometry::new(64, 64);
        let words = [
            w(TIME_HIGH, 4095),
            w(ADDR_Y, 0),
            w(ADDR_X, 0),
            w(TIME_HIGH, 2047), // a drop of 2048: not a loop
            w(ADDR_X, 0),
            w(TIME_HIGH, 4000),
            w(TIME_HIGH, 10), // a drop of 3990: a loop
            w(ADDR_X, 0),
        ];
        let (out, _) = decode(&words, g);
        assert_eq!(out.t, vec![4095 * 4096, 2047 * 4096, (1 << 24) + 10 * 4096]);
    }

    /// Words of every type, with runs of `ADDR_Y`, `ADDR_X` pairs (rows and columns partly
    /// off the sensor), time bases that step forward, back and loop.
    fn word() -> impl Strategy<Value = Vec<u16>> {
        let pair = (0u16..800, 0u16..1400, 0u16..2)
            .prop_map(|(y, x, p)| vec![w(ADDR_Y, y), w(ADDR_X, p << 11 | x)]);
        let high = prop_oneof![0u16..8, 4000u16..4096].prop_map(|h| vec![w(TIME_HIGH, h)]);
        let any = (0u16..16, 0u16..0x1000).prop_map(|(k, v)| vec![w(k, v)]);
        prop_oneof![6 => pair, 1 => high, 3 => any]
    }

    proptest! {
        #[test]
        fn pairs_path_matches_word_by_word(
            groups in prop::collection::vec(word(), 0..300),
            cuts in prop::collection::vec(0usize..700, 0..5),
        ) {
            let words: Vec<u16> = groups.concat();
            let g = Geometry::new(1280, 720);
            let want = decode(&words, g);
            let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
            let mut ends: Vec<usize> = cuts.iter().map(|&c| c.min(words.len())).collect();
            ends.push(words.len());
            ends.sort_unstable();
            let mut dec = Evt3Decoder::new(Some(g), 0);
            let (mut out, mut report) = (EventBuffer::new(), DecodeReport::default());
            let mut start = 0;
            for end in ends {
                dec.decode(&bytes[2 * start..2 * end], 2 * start as u64, &mut out, &mut report);
                start = end;
            }
            prop_assert_eq!((out, report), want);
        }
    }

    #[test]
    fn pieces_longer_than_one_reservation() {
        let g = Geometry::new(1280, 720);
        let mut words = vec![w(TIME_HIGH, 3), w(ADDR_Y, 5), w(VECT_BASE_X, 0)];
        for i in 0..3 * PIECE_WORDS as u16 {
            words.push(w(VECT_12, 0xFFF));
            if i % 100 == 0 {
                words.extend([w(ADDR_Y, i % 720), w(ADDR_X, i % 1280), w(VECT_BASE_X, 0)]);
            }
        }
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let mut dec = Evt3Decoder::new(Some(g), 0);
        let (mut out, mut report) = (EventBuffer::new(), DecodeReport::default());
        dec.decode(&bytes, 0, &mut out, &mut report);
        assert_eq!((out, report), decode(&words, g));
    }
}
