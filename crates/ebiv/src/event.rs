//! The event model: one change-detection event per pixel, stored as a struct of arrays.
//!
//! Conventions: time is `i64` microseconds as the camera decoded it,
//! coordinates are image coordinates (x right, y down, origin top-left), polarity `1` = ON
//! (brightness increased), `0` = OFF.

use std::fmt;

/// Brightness change direction of an event.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Polarity {
    /// Brightness decreased (stored as 0).
    Off = 0,
    /// Brightness increased (stored as 1).
    On = 1,
}

impl Polarity {
    /// The polarity of a stored value: 0 is OFF, anything else ON.
    pub fn from_bit(bit: u8) -> Self {
        if bit == 0 {
            Polarity::Off
        } else {
            Polarity::On
        }
    }
}

/// Which polarities to keep when selecting events.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PolaritySelection {
    /// Only ON (positive) events.
    Positive,
    /// Only OFF (negative) events.
    Negative,
    /// Both polarities.
    #[default]
    Both,
}

impl PolaritySelection {
    /// The setting's name of this selection: `pos`, `neg` or `both`.
    pub fn name(self) -> &'static str {
        match self {
            PolaritySelection::Positive => "pos",
            PolaritySelection::Negative => "neg",
            PolaritySelection::Both => "both",
        }
    }

    /// Parse `pos`/`positive`/`on`, `neg`/`negative`/`off` or `both`.
    pub fn parse(text: &str) -> Option<Self> {
        match text.trim().to_ascii_lowercase().as_str() {
            "pos" | "positive" | "on" | "+" => Some(PolaritySelection::Positive),
            "neg" | "negative" | "off" | "-" => Some(PolaritySelection::Negative),
            "both" | "all" => Some(PolaritySelection::Both),
            _ => None,
        }
    }

    /// Whether an event of stored polarity `p` (0/1) is selected.
    #[inline]
    pub fn accepts(self, p: u8) -> bool {
        match self {
            PolaritySelection::Positive => p != 0,
            PolaritySelection::Negative => p == 0,
            PolaritySelection::Both => true,
        }
    }
}

/// Sensor size in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub struct Geometry {
    /// Number of pixel columns (x ranges over `0..width`).
    pub width: u32,
    /// Number of pixel rows (y ranges over `0..height`).
    pub height: u32,
}

impl Geometry {
    /// A geometry of `width` × `height` pixels.
    pub const fn new(width: u32, height: u32) -> Self {
        Geometry { width, height }
    }

    /// Whether pixel `(x, y)` lies on the sensor.
    #[inline]
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x < self.width && y < self.height
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

impl fmt::Display for Geometry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

/// One external trigger edge (laser pulse, synchronisation signal) recorded by the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub struct Trigger {
    /// Time stamp in µs, on the same clock as the events.
    pub t: i64,
    /// Trigger input channel.
    pub channel: u8,
    /// Edge: 1 rising, 0 falling (formats with pulse semantics report 1).
    pub value: u8,
}

/// One event, for convenient iteration; storage is [`EventBuffer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Event {
    /// Time stamp in µs.
    pub t: i64,
    /// Column.
    pub x: u16,
    /// Row (image coordinates, y down).
    pub y: u16,
    /// Polarity, 1 = ON, 0 = OFF.
    pub p: u8,
}

/// Events as a struct of arrays, plus the external triggers that arrived with them.
///
/// All four event arrays always have the same length. Readers fill buffers in file order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EventBuffer {
    /// Time stamps in µs.
    pub t: Vec<i64>,
    /// Columns.
    pub x: Vec<u16>,
    /// Rows.
    pub y: Vec<u16>,
    /// Polarities, 1 = ON, 0 = OFF.
    pub p: Vec<u8>,
    /// External trigger edges decoded from the same stretch of the file.
    pub triggers: Vec<Trigger>,
}

impl EventBuffer {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty buffer with room for `n` events.
    pub fn with_capacity(n: usize) -> Self {
        EventBuffer {
            t: Vec::with_capacity(n),
            x: Vec::with_capacity(n),
            y: Vec::with_capacity(n),
            p: Vec::with_capacity(n),
            triggers: Vec::new(),
        }
    }

    /// Number of events.
    #[inline]
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are no events (triggers are not counted).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Remove all events and triggers, keeping the allocations.
    pub fn clear(&mut self) {
        self.t.clear();
        self.x.clear();
        self.y.clear();
        self.p.clear();
        self.triggers.clear();
    }

    /// Reserve room for `n` more events.
    pub fn reserve(&mut self, n: usize) {
        self.t.reserve(n);
        self.x.reserve(n);
        self.y.reserve(n);
        self.p.reserve(n);
    }

    /// Keep the first `at` events and return the rest (the triggers stay here).
    pub fn split_off(&mut self, at: usize) -> EventBuffer {
        EventBuffer {
            t: self.t.split_off(at),
            x: self.x.split_off(at),
            y: self.y.split_off(at),
            p: self.p.split_off(at),
            ..EventBuffer::default()
        }
    }

    /// Append one event.
    #[inline]
    pub fn push(&mut self, t: i64, x: u16, y: u16, p: u8) {
        self.t.push(t);
        self.x.push(x);
        self.y.push(y);
        self.p.push(p);
    }

    /// Event `i`.
    #[inline]
    pub fn get(&self, i: usize) -> Event {
        Event {
            t: self.t[i],
            x: self.x[i],
            y: self.y[i],
            p: self.p[i],
        }
    }

    /// The events in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Event> + '_ {
        (0..self.len()).map(move |i| self.get(i))
    }

    /// Append all events and triggers of `other`.
    pub fn extend_from(&mut self, other: &EventBuffer) {
        self.t.extend_from_slice(&other.t);
        self.x.extend_from_slice(&other.x);
        self.y.extend_from_slice(&other.y);
        self.p.extend_from_slice(&other.p);
        self.triggers.extend_from_slice(&other.triggers);
    }

    /// Keep only the events for which `keep(event)` is true, in order; triggers are untouched.
    pub fn retain(&mut self, mut keep: impl FnMut(Event) -> bool) {
        let mut w = 0;
        for r in 0..self.len() {
            let e = self.get(r);
            if keep(e) {
                self.t[w] = e.t;
                self.x[w] = e.x;
                self.y[w] = e.y;
                self.p[w] = e.p;
                w += 1;
            }
        }
        self.t.truncate(w);
        self.x.truncate(w);
        self.y.truncate(w);
        self.p.truncate(w);
    }

    /// Number of ON events.
    pub fn count_on(&self) -> usize {
        self.p.iter().filter(|&&p| p != 0).count()
    }

    /// Smallest and largest time stamp, if any event exists.
    pub fn time_range(&self) -> Option<(i64, i64)> {
        let min = *self.t.iter().min()?;
        let max = *self.t.iter().max()?;
        Some((min, max))
    }

    /// Whether time stamps never decrease in storage order.
    pub fn is_time_sorted(&self) -> bool {
        self.t.windows(2).all(|w| w[0] <= w[1])
    }

    /// Sort events by time (stable, so equal time stamps keep file order).
    pub fn sort_by_time(&mut self) {
        if self.is_time_sorted() {
            return;
        }
        let mut order: Vec<usize> = (0..self.len()).collect();
        order.sort_by_key(|&i| self.t[i]);
        self.t = order.iter().map(|&i| self.t[i]).collect();
        self.x = order.iter().map(|&i| self.x[i]).collect();
        self.y = order.iter().map(|&i| self.y[i]).collect();
        self.p = order.iter().map(|&i| self.p[i]).collect();
        self.triggers.sort_by_key(|tr| tr.t);
    }
}

impl FromIterator<Event> for EventBuffer {
    fn from_iter<I: IntoIterator<Item = Event>>(iter: I) -> Self {
        let mut buf = EventBuffer::new();
        for e in iter {
            buf.push(e.t, e.x, e.y, e.p);
        }
        buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retain_keeps_order_and_columns_aligned() {
        let mut b: EventBuffer = (0..10)
            .map(|i| Event {
                t: i,
                x: i as u16,
                y: 2 * i as u16,
                p: (i % 2) as u8,
            })
            .collect();
        b.retain(|e| e.p == 1);
        assert_eq!(b.t, vec![1, 3, 5, 7, 9]);
        assert_eq!(b.y, vec![2, 6, 10, 14, 18]);
        assert_eq!(b.count_on(), 5);
    }

    #[test]
    fn sort_by_time_is_stable() {
        let mut b = EventBuffer::new();
        b.push(5, 1, 0, 0);
        b.push(3, 2, 0, 0);
        b.push(5, 3, 0, 1);
        b.sort_by_time();
        assert_eq!(b.t, vec![3, 5, 5]);
        assert_eq!(b.x, vec![2, 1, 3]);
    }

    #[test]
    fn polarity_selection() {
        assert!(PolaritySelection::Positive.accepts(1));
        assert!(!PolaritySelection::Positive.accepts(0));
        assert!(PolaritySelection::Negative.accepts(0));
        assert!(PolaritySelection::Both.accepts(0));
    }
}
