//! Prophesee RAW EVT 2.0 and EVT 2.1 writers (formats.md §2, §3): one 32-bit word per event
//! (EVT 2.0) or 64-bit words carrying up to 32 events of one row, time and polarity (EVT 2.1,
//! either byte order), with `TIME_HIGH` words for the 34-bit clock.
//!
//! As in the EVT 3.0 writer, whole clock loops (2^34 µs) before the first event go into the
//! header as `% t0 <µs>`; later loops are crossed with the `TIME_HIGH` sequence OpenEB's loop
//! rule recognises.

use super::{AtomicFile, EventWriter};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry, Trigger};
use crate::io::prophesee_header::Evt21Order;
use std::io::Write;
use std::path::Path;

const LOOP_US: i64 = 1 << 34;
/// OpenEB's loop rule: a drop of the time high by at least this much is a loop.
const WRAP_MARGIN_US: i64 = 10_000;
/// The largest `TIME_HIGH` payload (t[33:6]).
const LAST_HIGH: i64 = (1 << 28) - 1;

/// Which EVT 2.x encoding to write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Evt2Variant {
    /// EVT 2.0, 32-bit words.
    Evt2,
    /// EVT 2.1, 64-bit vector words in the given byte order.
    Evt21(Evt21Order),
}

/// Streaming EVT 2.0 / 2.1 writer.
pub struct Evt2Writer {
    file: AtomicFile,
    geometry: Geometry,
    variant: Evt2Variant,
    origin_us: Option<i64>,
    /// The reader's current time high in units of 64 µs since the origin, loops included.
    high: Option<i64>,
    bytes: Vec<u8>,
}

impl Evt2Writer {
    /// Start writing `path`; the sensor size is required (at most 2048×2048).
    pub fn create(path: &Path, geometry: Option<Geometry>, variant: Evt2Variant) -> Result<Self> {
        let geometry = super::evt3::required_geometry(geometry, "EVT 2")?;
        Ok(Evt2Writer {
            file: AtomicFile::create(path)?,
            geometry,
            variant,
            origin_us: None,
            high: None,
            bytes: Vec::with_capacity(1 << 16),
        })
    }

    fn write_header(&mut self, first_t: i64) -> Result<i64> {
        let origin = first_t.div_euclid(LOOP_US) * LOOP_US;
        let g = self.geometry;
        let (evt, name, endianness) = match self.variant {
            Evt2Variant::Evt2 => ("2.0", "EVT2", ""),
            Evt2Variant::Evt21(Evt21Order::Legacy) => ("2.1", "EVT21", ";endianness=legacy"),
            Evt2Variant::Evt21(Evt21Order::Little) => ("2.1", "EVT21", ";endianness=little"),
        };
        let header = super::evt3::header_text(evt, name, endianness, g, origin);
        let io = self.file.writer().write_all(header.as_bytes());
        io.map_err(|e| self.file.err(e))?;
        Ok(origin)
    }

    fn word(&mut self, w: u64) {
        match self.variant {
            Evt2Variant::Evt2 => self.bytes.extend_from_slice(&(w as u32).to_le_bytes()),
            Evt2Variant::Evt21(Evt21Order::Little) => {
                self.bytes.extend_from_slice(&w.to_le_bytes())
            }
            Evt2Variant::Evt21(Evt21Order::Legacy) => {
                self.bytes
                    .extend_from_slice(&((w >> 32) as u32).to_le_bytes());
                self.bytes.extend_from_slice(&(w as u32).to_le_bytes());
            }
        }
    }

    fn time_high_word(&mut self, payload: i64) {
        let w = match self.variant {
            Evt2Variant::Evt2 => 0x8 << 28 | payload as u64,
            Evt2Variant::Evt21(_) => 0x8 << 60 | (payload as u64) << 32,
        };
        self.word(w);
    }

    /// Bring the reader's time high to that of `rel` µs after the origin.
    fn set_time(&mut self, rel: i64) -> Result<()> {
        if rel < 0 {
            return Err(Error::parameter(
                "events",
                "a time lies before the file's clock origin; sort the events by time first",
            ));
        }
        let target = rel >> 6;
        let Some(mut current) = self.high else {
            self.time_high_word(target & LAST_HIGH);
            self.high = Some(target);
            return Ok(());
        };
        if target == current {
            return Ok(());
        }
        let loop_of = |h: i64| h >> 28;
        let mistaken_for_loop = current - target >= (LOOP_US - WRAP_MARGIN_US) >> 6;
        if target < current && (loop_of(target) != loop_of(current) || mistaken_for_loop) {
            return Err(Error::parameter(
                "events",
                "EVT 2 cannot store a step back across its 2^34 µs clock loop; sort the events by time first",
            ));
        }
        while loop_of(current) < loop_of(target) {
            // End of this loop, then its start: a drop OpenEB's rule reads as one loop.
            let end = (loop_of(current) << 28) | LAST_HIGH;
            if current != end {
                self.time_high_word(LAST_HIGH);
            }
            current = (loop_of(current) + 1) << 28;
            self.time_high_word(0);
        }
        if current != target {
            self.time_high_word(target & LAST_HIGH);
        }
        self.high = Some(target);
        Ok(())
    }

    fn flush(&mut self) -> Result<()> {
        let io = self.file.writer().write_all(&self.bytes);
        io.map_err(|e| self.file.err(e))?;
        self.bytes.clear();
        Ok(())
    }

    fn write_trigger(&mut self, origin: i64, tr: &Trigger) -> Result<()> {
        if tr.channel > 31 {
            return Err(Error::parameter(
                "triggers",
                format!(
                    "EVT 2 stores trigger channels 0-31; got channel {}",
                    tr.channel
                ),
            ));
        }
        let rel = tr.t - origin;
        self.set_time(rel)?;
        let (low, channel, value) = ((rel & 63) as u64, tr.channel as u64, (tr.value & 1) as u64);
        self.word(match self.variant {
            Evt2Variant::Evt2 => 0xA << 28 | low << 22 | channel << 8 | value,
            Evt2Variant::Evt21(_) => 0xA << 60 | low << 54 | channel << 40 | value << 32,
        });
        Ok(())
    }

    fn check_pixel(&self, events: &EventBuffer, i: usize) -> Result<()> {
        let (x, y) = (events.x[i] as u32, events.y[i] as u32);
        if !self.geometry.contains(x, y) {
            return Err(Error::parameter(
                "events",
                format!(
                    "event {i} at ({x}, {y}) lies outside the {} sensor",
                    self.geometry
                ),
            ));
        }
        Ok(())
    }
}

impl EventWriter for Evt2Writer {
    fn write(&mut self, events: &EventBuffer) -> Result<()> {
        let first = events
            .t
            .first()
            .copied()
            .or(events.triggers.first().map(|tr| tr.t));
        let origin = match (self.origin_us, first) {
            (Some(o), _) => o,
            (None, Some(t)) => {
                let o = self.write_header(t)?;
                self.origin_us = Some(o);
                o
            }
            (None, None) => return Ok(()),
        };
        let mut triggers = events.triggers.iter().peekable();
        let mut i = 0;
        while i < events.len() {
            let t = events.t[i];
            while let Some(tr) = triggers.next_if(|tr| tr.t <= t) {
                self.write_trigger(origin, tr)?;
            }
            self.check_pixel(events, i)?;
            let rel = t - origin;
            self.set_time(rel)?;
            let (x, y, p) = (
                events.x[i] as u64,
                events.y[i] as u64,
                (events.p[i] != 0) as u64,
            );
            let low = (rel & 63) as u64;
            match self.variant {
                Evt2Variant::Evt2 => {
                    self.word(p << 28 | low << 22 | x << 11 | y);
                    i += 1;
                }
                Evt2Variant::Evt21(_) => {
                    // A run of events of this time, row and polarity with increasing x within
                    // 32 columns shares one word; the reader emits them in the same order.
                    let mut mask = 1u64;
                    let mut last_x = x;
                    let mut j = i + 1;
                    while j < events.len()
                        && events.t[j] == t
                        && events.y[j] as u64 == y
                        && (events.p[j] != 0) as u64 == p
                        && (events.x[j] as u64) > last_x
                        && (events.x[j] as u64) < x + 32
                    {
                        self.check_pixel(events, j)?;
                        last_x = events.x[j] as u64;
                        mask |= 1 << (last_x - x);
                        j += 1;
                    }
                    self.word(p << 60 | low << 54 | x << 43 | y << 32 | mask);
                    i = j;
                }
            }
        }
        for tr in triggers {
            self.write_trigger(origin, tr)?;
        }
        self.flush()
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        if self.origin_us.is_none() {
            self.write_header(0)?;
        }
        self.flush()?;
        self.file.commit()
    }
}
