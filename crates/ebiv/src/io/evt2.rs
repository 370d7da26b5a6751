//! Prophesee EVT 2.0 decoder: 32-bit little-endian words (formats.md §2; Prophesee
//! "EVT 2.0 format" documentation; OpenEB `evt2_event_types.h`).

use super::bytestream::WordDecoder;
use super::sink::{self, EventSink};
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

    /// A word other than an event after the first time base: an event before it, a time
    /// base, a trigger, a skipped or an unknown type (`at`: its file offset).
    #[cold]
    fn other_word(&mut self, w: u32, at: u64, sink: &mut EventSink, report: &mut DecodeReport) {
        let base = self.time.base();
        match w >> 28 {
            CD_OFF | CD_ON => report.before_time_base += 1,
            TIME_HIGH => self.time.set_high(w),
            EXT_TRIGGER => match base {
                Some(b) => sink.triggers.push(Trigger {
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
                        "EVT 2.0: unknown word type {kind:#x} at byte {at}; skipped and counted"
                    ));
                }
                report.unknown_words += 1;
            }
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

    /// Event words take the straight path: the event is written into the next slot of the
    /// output and kept when its pixel is on the sensor, without a branch on that; every other
    /// word (time base, trigger, skipped types) takes [`Evt2Decoder::other_word`].
    fn decode(
        &mut self,
        bytes: &[u8],
        offset: u64,
        out: &mut EventBuffer,
        report: &mut DecodeReport,
    ) {
        let (width, height) = (self.width, self.height);
        sink::append(out, bytes.len() / 4, |sink| {
            let mut words = bytes
                .chunks_exact(4)
                .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                .enumerate();
            let mut out_of_range = 0u64;
            loop {
                let counted = &mut out_of_range;
                // `move`: the closure holds copies of the sensor size and the time base, which
                // then stay in registers.
                let stop = match self.time.base() {
                    Some(base) => sink.extend_while(&mut words, move |&(_, w)| {
                        let kind = w >> 28;
                        (kind <= CD_ON).then(|| {
                            let x = (w >> 11) & 0x7FF;
                            let y = w & 0x7FF;
                            let inside = (x < width) & (y < height);
                            *counted += !inside as u64;
                            let t = base + ((w >> 22) & 0x3F) as i64;
                            (inside, t, x as u16, y as u16, kind as u8)
                        })
                    }),
                    None => words.next(),
                };
                let Some((i, w)) = stop else { break };
                self.other_word(w, offset + 4 * i as u64, sink, report);
            }
            report.out_of_range += out_of_range;
        });
    }

    fn metavision_time_shift(&self) -> Option<i64> {
        self.time.metavision_shift()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The format read word by word in the plainest way, to hold the decoder to.
    fn reference(words: &[u32], g: Geometry) -> (EventBuffer, DecodeReport) {
        let mut time = TimeBase34::new(0);
        let (mut out, mut report) = (EventBuffer::new(), DecodeReport::default());
        for (i, &w) in words.iter().enumerate() {
            match (w >> 28, time.base()) {
                (CD_OFF | CD_ON, None) => report.before_time_base += 1,
                (CD_OFF | CD_ON, Some(b)) => {
                    let (x, y) = ((w >> 11) & 0x7FF, w & 0x7FF);
                    if x < g.width && y < g.height {
                        let t = b + ((w >> 22) & 0x3F) as i64;
                        out.push(t, x as u16, y as u16, (w >> 28) as u8);
                    } else {
                        report.out_of_range += 1;
                    }
                }
                (TIME_HIGH, _) => time.set_high(w),
                (EXT_TRIGGER, None) => report.before_time_base += 1,
                (EXT_TRIGGER, Some(b)) => out.triggers.push(Trigger {
                    t: b + ((w >> 22) & 0x3F) as i64,
                    channel: ((w >> 8) & 0x1F) as u8,
                    value: (w & 1) as u8,
                }),
                (IMU | OTHERS | CONTINUED, _) => report.skipped_other += 1,
                (kind, _) => {
                    if report.unknown_words == 0 {
                        report.warn(format!(
                            "EVT 2.0: unknown word type {kind:#x} at byte {}; skipped and counted",
                            4 * i
                        ));
                    }
                    report.unknown_words += 1;
                }
            }
        }
        (out, report)
    }

    /// The decoder fed `words` in pieces ending at the word indices `cuts`.
    fn decode_in_pieces(words: &[u32], cuts: &[usize], g: Geometry) -> (EventBuffer, DecodeReport) {
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let mut dec = Evt2Decoder::new(Some(g), 0);
        let (mut out, mut report) = (EventBuffer::new(), DecodeReport::default());
        let mut ends: Vec<usize> = cuts.iter().map(|&c| c.min(words.len())).collect();
        ends.push(words.len());
        ends.sort_unstable();
        let mut start = 0;
        for end in ends {
            dec.decode(
                &bytes[4 * start..4 * end],
                4 * start as u64,
                &mut out,
                &mut report,
            );
            start = end;
        }
        (out, report)
    }

    /// Words of every type: mostly events (some off the sensor), time bases that advance,
    /// repeat, step back a little or wrap around 2^34 µs, triggers, skipped and unknown types.
    fn word() -> impl Strategy<Value = u32> {
        let event = (0u32..2, 0u32..64, 0u32..0x800, 0u32..0x800)
            .prop_map(|(p, t, x, y)| p << 28 | t << 22 | (x.min(1400)) << 11 | y.min(800));
        let high = prop_oneof![
            0u32..64,
            (0x0FFF_FF00u32..0x1000_0000),
            (0x0FFF_F000u32..0x0FFF_FFFF),
        ]
        .prop_map(|h| TIME_HIGH << 28 | h);
        let other = (0u32..16, any::<u32>()).prop_map(|(k, v)| k << 28 | (v & 0x0FFF_FFFF));
        prop_oneof![8 => event, 2 => high, 1 => other]
    }

    proptest! {
        #[test]
        fn straight_path_matches_the_reference(
            words in prop::collection::vec(word(), 0..400),
            cuts in prop::collection::vec(0usize..400, 0..5),
        ) {
            let g = Geometry::new(1280, 720);
            let (want, want_report) = reference(&words, g);
            let (got, got_report) = decode_in_pieces(&words, &cuts, g);
            prop_assert_eq!(got, want);
            prop_assert_eq!(got_report, want_report);
        }
    }

    #[test]
    fn time_high_wrap_and_pieces_of_one_word() {
        let g = Geometry::new(64, 64);
        let ev = |t: u32, x: u32, y: u32| CD_ON << 28 | t << 22 | x << 11 | y;
        let words = [
            ev(1, 1, 1),                   // before the first time base
            TIME_HIGH << 28 | 0x0FFF_FFFF, // 2^34 - 64 µs
            ev(5, 2, 3),
            ev(6, 64, 3), // off the sensor
            EXT_TRIGGER << 28 | 7 << 22 | 3 << 8 | 1,
            TIME_HIGH << 28 | 1, // wrapped
            CD_OFF << 28 | 2 << 22 | 4 << 11 | 5,
        ];
        let cuts: Vec<usize> = (1..words.len()).collect();
        let (out, report) = decode_in_pieces(&words, &cuts, g);
        let top = (1i64 << 34) - 64;
        assert_eq!(out.t, vec![top + 5, (1 << 34) + 64 + 2]);
        assert_eq!(out.x, vec![2, 4]);
        assert_eq!(out.p, vec![1, 0]);
        assert_eq!(out.triggers[0].t, top + 7);
        assert_eq!((report.before_time_base, report.out_of_range), (1, 1));
        assert_eq!((out.clone(), report), reference(&words, g));
    }
}
