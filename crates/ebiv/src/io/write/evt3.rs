//! Prophesee RAW EVT 3.0 writer (formats.md §4): a `% ` header Metavision tools accept, then
//! 16-bit words. Each event is written as `TIME_HIGH`/`TIME_LOW` (when the time changed),
//! `ADDR_Y` (when the row changed) and `ADDR_X`; readers that follow OpenEB decode it exactly.
//!
//! Time: the file stores the 24-bit sensor clock. When the first event lies outside the first
//! clock loop, the whole number of loops before it goes into the header as `% t0 <µs>` (the
//! key faery uses), so ebiv and faery read back absolute time while Metavision shows the clock
//! a camera would have shown.

use super::{AtomicFile, EventWriter};
use crate::error::{Error, Result};
use crate::event::{EventBuffer, Geometry};
use crate::io::evt3::{EVT3_LOOP_US, EVT3_WRAP_THRESHOLD};
use std::io::Write;
use std::path::Path;

/// Largest step of the time base, in units of 4096 µs, that a reader cannot mistake for a loop.
const MAX_FORWARD_STEP: i64 = EVT3_WRAP_THRESHOLD as i64 - 1;

/// Streaming EVT 3.0 writer.
pub struct Evt3Writer {
    file: AtomicFile,
    geometry: Geometry,
    /// Header written and `t0` fixed, once the first event (or trigger) is seen.
    origin_us: Option<i64>,
    /// The reader's time base in units of 4096 µs since the origin, loops included.
    high_units: i64,
    /// The reader's current time in µs since the origin.
    t_rel: i64,
    y: Option<u16>,
    words: Vec<u8>,
}

impl Evt3Writer {
    /// Start writing `path`; the sensor size is required (and limited to 2048×2048 by the format).
    pub fn create(path: &Path, geometry: Option<Geometry>) -> Result<Self> {
        let geometry = required_geometry(geometry, "EVT 3.0")?;
        Ok(Evt3Writer {
            file: AtomicFile::create(path)?,
            geometry,
            origin_us: None,
            high_units: 0,
            t_rel: 0,
            y: None,
            words: Vec::with_capacity(1 << 16),
        })
    }

    fn write_header(&mut self, first_t: i64) -> Result<i64> {
        let origin = first_t.div_euclid(EVT3_LOOP_US) * EVT3_LOOP_US;
        let header = header_text("3.0", "EVT3", "", self.geometry, origin);
        let io = self.file.writer().write_all(header.as_bytes());
        io.map_err(|e| self.file.err(e))?;
        // The first TIME_HIGH sets the reader's time base.
        let rel = first_t - origin;
        self.high_units = rel >> 12;
        self.push(0x8, (self.high_units & 0xFFF) as u16);
        self.t_rel = self.high_units << 12;
        Ok(origin)
    }

    #[inline]
    fn push(&mut self, kind: u16, payload: u16) {
        self.words
            .extend_from_slice(&((kind << 12) | (payload & 0xFFF)).to_le_bytes());
    }

    /// Bring the reader's clock to `t` µs after the origin.
    fn set_time(&mut self, t: i64) -> Result<()> {
        if t == self.t_rel {
            return Ok(());
        }
        let target_high = t >> 12;
        if target_high < self.high_units {
            let back = self.high_units - target_high;
            let same_loop = (target_high >> 12) == (self.high_units >> 12);
            if !same_loop || back > EVT3_WRAP_THRESHOLD as i64 {
                return Err(Error::parameter(
                    "events",
                    format!(
                        "EVT 3.0 cannot store a time step back of {} µs across its clock loop; sort the events by time first",
                        self.t_rel - t
                    ),
                ));
            }
            self.high_units = target_high;
            self.push(0x8, (target_high & 0xFFF) as u16);
        }
        while self.high_units < target_high {
            self.high_units += (target_high - self.high_units).min(MAX_FORWARD_STEP);
            self.push(0x8, (self.high_units & 0xFFF) as u16);
        }
        // A new TIME_HIGH resets the low part to 0 in the reader.
        let base = self.high_units << 12;
        if self.t_rel >> 12 != self.high_units {
            self.t_rel = base;
        }
        if t != self.t_rel {
            self.push(0x6, (t - base) as u16);
            self.t_rel = t;
        }
        Ok(())
    }

    fn flush_words(&mut self) -> Result<()> {
        let io = self.file.writer().write_all(&self.words);
        io.map_err(|e| self.file.err(e))?;
        self.words.clear();
        Ok(())
    }
}

impl EventWriter for Evt3Writer {
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
        let g = self.geometry;
        let mut triggers = events.triggers.iter().peekable();
        for i in 0..events.len() {
            let t = events.t[i];
            while let Some(tr) = triggers.next_if(|tr| tr.t <= t) {
                self.write_trigger(origin, tr.t, tr.channel, tr.value)?;
            }
            let (x, y) = (events.x[i], events.y[i]);
            if !g.contains(x as u32, y as u32) {
                return Err(Error::parameter(
                    "events",
                    format!("event {i} at ({x}, {y}) lies outside the {g} sensor"),
                ));
            }
            self.set_time(checked_rel(t, origin)?)?;
            if self.y != Some(y) {
                self.push(0x0, y);
                self.y = Some(y);
            }
            self.push(0x2, x | (u16::from(events.p[i] != 0) << 11));
        }
        for tr in triggers {
            self.write_trigger(origin, tr.t, tr.channel, tr.value)?;
        }
        self.flush_words()
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        if self.origin_us.is_none() {
            self.write_header(0)?;
        }
        self.flush_words()?;
        self.file.commit()
    }
}

impl Evt3Writer {
    fn write_trigger(&mut self, origin: i64, t: i64, channel: u8, value: u8) -> Result<()> {
        if channel > 15 {
            return Err(Error::parameter(
                "triggers",
                format!("EVT 3.0 stores trigger channels 0-15; got channel {channel}"),
            ));
        }
        self.set_time(checked_rel(t, origin)?)?;
        self.push(0xA, ((channel as u16) << 8) | (value & 1) as u16);
        Ok(())
    }
}

fn checked_rel(t: i64, origin: i64) -> Result<i64> {
    let rel = t - origin;
    if rel < 0 {
        return Err(Error::parameter(
            "events",
            format!("time {t} µs lies before the file's clock origin {origin} µs; sort the events by time first"),
        ));
    }
    Ok(rel)
}

/// The sensor size a RAW writer needs: present, and within the 11-bit coordinates of EVT.
pub(crate) fn required_geometry(geometry: Option<Geometry>, encoding: &str) -> Result<Geometry> {
    let geometry = geometry.ok_or_else(|| {
        Error::parameter(
            "geometry",
            format!("{encoding} output needs the sensor size; the input does not state it, pass --geometry WIDTHxHEIGHT"),
        )
    })?;
    if geometry.width > 2048 || geometry.height > 2048 {
        return Err(Error::parameter(
            "geometry",
            format!("{encoding} stores 11-bit coordinates; {geometry} is larger than 2048x2048"),
        ));
    }
    Ok(geometry)
}

/// A RAW header in the Metavision 4 style (`evt`, `format` with size, `geometry`, `% end`),
/// plus `t0` when the clock origin is not 0. `format_options` starts with `;` when present.
pub(crate) fn header_text(
    evt: &str,
    name: &str,
    format_options: &str,
    g: Geometry,
    origin: i64,
) -> String {
    let mut header = format!(
        "% evt {evt}\n% format {name};height={};width={}{format_options}\n% geometry {}x{}\n",
        g.height, g.width, g.width, g.height
    );
    header.push_str(&format!(
        "% plugin_integrator_name ebiv\n% software ebiv {}\n",
        env!("CARGO_PKG_VERSION")
    ));
    if origin != 0 {
        header.push_str(&format!("% t0 {origin}\n"));
    }
    header.push_str("% end\n");
    header
}
