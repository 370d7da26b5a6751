//! Prophesee's ECF codec ("event compression format"), the HDF5 filter 0x8ECF that Metavision
//! applies to the chunks of `/CD/events` (formats.md §6.3). Written from the published layout
//! of the open-source `hdf5_ecf` codec; no code of it is used.
//!
//! One compressed buffer holds up to 65 535 events:
//! 1. a little-endian `u32`: `n << 2 | all_packed << 1 | x_and_p_packed`;
//! 2. the time stamps: a `u64` origin, then one byte per run of equal time stamps, its high
//!    nibble the time step from the previous run (0–14 µs) and its low nibble the run's
//!    length (15: the length follows as a `u16`). A high nibble of 15 starts a large step
//!    instead, 4 bits per byte, least significant first, ending at the next byte whose high
//!    nibble is not 15 (which then codes a run as usual). Time is µs; steps add modulo 2⁶⁴;
//! 3. the coordinates, either
//!    - *all packed*: `y << 12 | x << 1 | p` in 24 bits per event, 4 events in 3 `u32`, or
//!    - runs of equal y (`u16 = y << 5 | length`, 31: the length follows as a `u16`), then
//!      either *x and p packed* (`x << 1 | p` in 12 bits, 4 events in 3 `u16`) or *masked x*
//!      (`u16 = x << 5 | mask`, the mask's bit `4 − j` adding an event at `x + 1 + j`)
//!      followed by runs of equal polarity (`u8 = p << 7 | length`, 127: the length follows
//!      as a `u16`).
//!
//! Coordinates have 11 bits (up to 2047). The decoder checks every length against the
//! buffer and the event count, so a damaged buffer gives an error, never a read outside it
//! or an allocation beyond the 65 535 events a buffer may hold.

use std::fmt;

/// Most events in one ECF buffer (the codec's limit; Metavision writes 16 384 per chunk).
pub const MAX_EVENTS: usize = 65_535;
/// The HDF5 filter id of the codec.
pub const FILTER_ID: u16 = 0x8ECF;
/// Largest coordinate the codec stores (11 bits).
pub const MAX_COORDINATE: u16 = 2047;
/// Bytes of one decoded event as the HDF5 dataset stores it: `x u16, y u16, p i16, t i64`.
pub const RECORD_BYTES: usize = 16;

/// Why a buffer could not be decoded or events could not be encoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EcfError {
    /// Byte offset in the buffer where the problem was found.
    pub offset: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for EcfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} (byte {} of the ECF buffer)",
            self.message, self.offset
        )
    }
}

impl std::error::Error for EcfError {}

fn fail<T>(offset: usize, message: impl Into<String>) -> Result<T, EcfError> {
    Err(EcfError {
        offset,
        message: message.into(),
    })
}

/// Decoded events of one buffer, as columns.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EcfEvents {
    /// Column, 0 … 2047.
    pub x: Vec<u16>,
    /// Row, 0 … 2047.
    pub y: Vec<u16>,
    /// Polarity, 0 or 1.
    pub p: Vec<u8>,
    /// Time stamp, µs.
    pub t: Vec<i64>,
}

impl EcfEvents {
    /// Number of events.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are no events.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// How the coordinates of a buffer are stored ([`encode_with`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Packing {
    /// The smallest of the three layouts for the events at hand.
    Smallest,
    /// y, x and p packed in 24 bits per event.
    AllPacked,
    /// Runs of y, then x and p packed in 12 bits per event.
    XAndPPacked,
    /// Runs of y, masked x words, runs of p.
    Masked,
}

/// A little-endian reader over the buffer that reports where it ran out.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], EcfError> {
        match self.bytes.get(self.at..self.at + n) {
            Some(s) => {
                self.at += n;
                Ok(s)
            }
            None => fail(self.at, format!("the buffer ends inside the {what}")),
        }
    }

    fn u8(&mut self, what: &str) -> Result<u8, EcfError> {
        Ok(self.take(1, what)?[0])
    }

    fn u16(&mut self, what: &str) -> Result<u16, EcfError> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self, what: &str) -> Result<u32, EcfError> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self, what: &str) -> Result<u64, EcfError> {
        let b = self.take(8, what)?;
        let mut w = [0u8; 8];
        w.copy_from_slice(b);
        Ok(u64::from_le_bytes(w))
    }
}

/// The number of events an ECF buffer declares (its first 4 bytes), if it has them.
pub fn declared_events(bytes: &[u8]) -> Option<usize> {
    let head: [u8; 4] = bytes.get(..4)?.try_into().ok()?;
    Some((u32::from_le_bytes(head) >> 2) as usize)
}

/// Where a decoded buffer goes: events written by index, `0..n` after [`Sink::start`].
trait Sink {
    /// Room for `n` events (and the codec's padding past them).
    fn start(&mut self, n: usize);
    fn t(&mut self, i: usize, t: i64);
    fn x(&mut self, i: usize, x: u16);
    fn y(&mut self, i: usize, y: u16);
    fn p(&mut self, i: usize, p: u8);
    /// Keep events `0..n` only.
    fn finish(&mut self, n: usize);
}

/// Extra room past the events: a masked x word or a packed group may write up to 5 (or 3)
/// values past the last event (the writer's padding, ignored).
const PAD: usize = 5;

impl Sink for EcfEvents {
    fn start(&mut self, n: usize) {
        self.x.clear();
        self.y.clear();
        self.p.clear();
        self.t.clear();
        self.x.resize(n + PAD, 0);
        self.y.resize(n + PAD, 0);
        self.p.resize(n + PAD, 0);
        self.t.resize(n + PAD, 0);
    }
    fn t(&mut self, i: usize, t: i64) {
        self.t[i] = t;
    }
    fn x(&mut self, i: usize, x: u16) {
        self.x[i] = x;
    }
    fn y(&mut self, i: usize, y: u16) {
        self.y[i] = y;
    }
    fn p(&mut self, i: usize, p: u8) {
        self.p[i] = p;
    }
    fn finish(&mut self, n: usize) {
        self.x.truncate(n);
        self.y.truncate(n);
        self.p.truncate(n);
        self.t.truncate(n);
    }
}

/// The 16-byte records of `/CD/events`, at least `min` of them (zero records past the
/// events).
struct Records {
    bytes: Vec<u8>,
    min: usize,
}

impl Records {
    #[inline(always)]
    fn put(&mut self, i: usize, at: usize, value: &[u8]) {
        let start = i * RECORD_BYTES + at;
        self.bytes[start..start + value.len()].copy_from_slice(value);
    }
}

impl Sink for Records {
    fn start(&mut self, n: usize) {
        self.bytes.clear();
        self.bytes.resize((n.max(self.min) + PAD) * RECORD_BYTES, 0);
    }
    fn t(&mut self, i: usize, t: i64) {
        self.put(i, 8, &t.to_le_bytes());
    }
    fn x(&mut self, i: usize, x: u16) {
        self.put(i, 0, &x.to_le_bytes());
    }
    fn y(&mut self, i: usize, y: u16) {
        self.put(i, 2, &y.to_le_bytes());
    }
    fn p(&mut self, i: usize, p: u8) {
        self.put(i, 4, &[p]);
    }
    fn finish(&mut self, n: usize) {
        self.bytes.truncate(n.max(self.min) * RECORD_BYTES);
        // Padding written past the events of a full-size chunk is not an event.
        self.bytes[n * RECORD_BYTES..].fill(0);
    }
}

/// Decode one ECF buffer into `out` (cleared first).
pub fn decode(bytes: &[u8], out: &mut EcfEvents) -> Result<(), EcfError> {
    let n = decode_into(bytes, out)?;
    out.finish(n);
    Ok(())
}

/// Decode one ECF buffer into the 16-byte records of `/CD/events` (`x u16, y u16, p i16,
/// t i64`, little-endian), padded with zero records to `records` when given (an HDF5
/// chunk's full size).
pub fn decode_records(bytes: &[u8], records: Option<usize>) -> Result<Vec<u8>, EcfError> {
    let mut out = Records {
        bytes: Vec::new(),
        min: records.unwrap_or(0),
    };
    let n = decode_into(bytes, &mut out)?;
    out.finish(n);
    Ok(out.bytes)
}

/// Decode one buffer into `out`; returns its number of events.
fn decode_into(bytes: &[u8], out: &mut impl Sink) -> Result<usize, EcfError> {
    let mut c = Cursor { bytes, at: 0 };
    let info = c.u32("event count")?;
    let n = (info >> 2) as usize;
    if n > MAX_EVENTS {
        return fail(
            0,
            format!("the buffer declares {n} events; ECF holds at most {MAX_EVENTS}"),
        );
    }
    out.start(n);
    let (all_packed, x_and_p_packed) = (info & 2 != 0, info & 1 != 0);
    decode_times(&mut c, n, out)?;
    if all_packed {
        decode_all_packed(&mut c, n, out)?;
    } else {
        decode_y_runs(&mut c, n, out)?;
        if x_and_p_packed {
            decode_x_and_p_packed(&mut c, n, out)?;
        } else {
            decode_masked_x(&mut c, n, out)?;
            decode_p_runs(&mut c, n, out)?;
        }
    }
    // A buffer holds exactly its encoded events (the codec's writer stores no more): bytes
    // left over mean a damaged event count or layout.
    if c.at != bytes.len() {
        return fail(
            c.at,
            format!(
                "{} bytes follow the buffer's {n} events",
                bytes.len() - c.at
            ),
        );
    }
    Ok(n)
}

/// A run's length: the low bits, or the `u16` after them when they are all ones.
fn run_length(
    c: &mut Cursor<'_>,
    low: usize,
    escape: usize,
    what: &str,
) -> Result<usize, EcfError> {
    if low == escape {
        Ok(c.u16(what)? as usize)
    } else {
        Ok(low)
    }
}

/// Check that a run of `len` more values fits in the `n` events.
fn check_run(done: usize, len: usize, n: usize, at: usize, what: &str) -> Result<(), EcfError> {
    if done + len > n {
        return fail(
            at,
            format!("a run of {len} {what} passes the buffer's {n} events (at event {done})"),
        );
    }
    Ok(())
}

fn decode_times(c: &mut Cursor<'_>, n: usize, out: &mut impl Sink) -> Result<(), EcfError> {
    let mut now = c.u64("time origin")?;
    let mut i = 0;
    while i < n {
        let at = c.at;
        let byte = c.u8("time stamps")?;
        let (step, low) = (byte >> 4, (byte & 0xF) as usize);
        if step == 0xF {
            // A large step, 4 bits per byte, until a byte whose high nibble is not 15.
            let mut delta = low as u64;
            let mut nibbles = 1;
            while c.bytes.get(c.at).is_some_and(|b| b >> 4 == 0xF) {
                if nibbles == 16 {
                    return fail(at, "a time step of more than 64 bits");
                }
                delta |= u64::from(c.u8("time step")? & 0xF) << (4 * nibbles);
                nibbles += 1;
            }
            now = now.wrapping_add(delta);
            continue;
        }
        now = now.wrapping_add(u64::from(step));
        let len = run_length(c, low, 0xF, "time-stamp run length")?;
        check_run(i, len, n, at, "time stamps")?;
        for k in i..i + len {
            out.t(k, now as i64);
        }
        i += len;
    }
    Ok(())
}

fn decode_y_runs(c: &mut Cursor<'_>, n: usize, out: &mut impl Sink) -> Result<(), EcfError> {
    let mut i = 0;
    while i < n {
        let at = c.at;
        let word = c.u16("y runs")?;
        let len = run_length(c, (word & 0x1F) as usize, 0x1F, "y run length")?;
        check_run(i, len, n, at, "rows")?;
        for k in i..i + len {
            out.y(k, word >> 5);
        }
        i += len;
    }
    Ok(())
}

fn decode_p_runs(c: &mut Cursor<'_>, n: usize, out: &mut impl Sink) -> Result<(), EcfError> {
    let mut i = 0;
    while i < n {
        let at = c.at;
        let byte = c.u8("polarity runs")?;
        let len = run_length(c, (byte & 0x7F) as usize, 0x7F, "polarity run length")?;
        check_run(i, len, n, at, "polarities")?;
        for k in i..i + len {
            out.p(k, byte >> 7);
        }
        i += len;
    }
    Ok(())
}

fn decode_masked_x(c: &mut Cursor<'_>, n: usize, out: &mut impl Sink) -> Result<(), EcfError> {
    let mut i = 0;
    while i < n {
        let word = c.u16("masked x words")?;
        let base = word >> 5;
        // The last word may mark columns past the buffer's events (the writer's padding,
        // within the sink's room past them).
        let mut put = |i: &mut usize, x: u16| -> Result<(), EcfError> {
            if x > MAX_COORDINATE && *i < n {
                return fail(
                    c.at,
                    format!("masked column {x} of event {i} passes {MAX_COORDINATE}"),
                );
            }
            out.x(*i, x);
            *i += 1;
            Ok(())
        };
        put(&mut i, base)?;
        for j in 0..5u16 {
            if word & (1 << (4 - j)) != 0 {
                put(&mut i, base + j + 1)?;
            }
        }
    }
    Ok(())
}

fn decode_x_and_p_packed(
    c: &mut Cursor<'_>,
    n: usize,
    out: &mut impl Sink,
) -> Result<(), EcfError> {
    for g in 0..n.div_ceil(4) {
        let w = c.take(6, "packed x and polarities")?;
        let [a, b, d] = [0, 2, 4].map(|k| u16::from_le_bytes([w[k], w[k + 1]]));
        let values = [
            a >> 4,
            (a & 0xF) | ((b >> 8) << 4),
            (b & 0xFF) | ((d >> 12) << 8),
            d & 0xFFF,
        ];
        for (j, v) in values.into_iter().enumerate() {
            out.x(4 * g + j, v >> 1);
            out.p(4 * g + j, (v & 1) as u8);
        }
    }
    Ok(())
}

fn decode_all_packed(c: &mut Cursor<'_>, n: usize, out: &mut impl Sink) -> Result<(), EcfError> {
    for g in 0..n.div_ceil(4) {
        let w = c.take(12, "packed coordinates")?;
        let [a, b, d] = [0, 4, 8].map(|k| u32::from_le_bytes([w[k], w[k + 1], w[k + 2], w[k + 3]]));
        let values = [
            a >> 8,
            (a & 0xFF) | ((b >> 16) << 8),
            (b & 0xFFFF) | ((d >> 24) << 16),
            d & 0xFF_FFFF,
        ];
        for (j, v) in values.into_iter().enumerate() {
            let i = 4 * g + j;
            out.y(i, ((v >> 12) & 0x7FF) as u16);
            out.x(i, ((v >> 1) & 0x7FF) as u16);
            out.p(i, (v & 1) as u8);
        }
    }
    Ok(())
}

/// Encode events into one ECF buffer with the smallest coordinate layout.
pub fn encode(events: &EcfEvents) -> Result<Vec<u8>, EcfError> {
    encode_with(events, Packing::Smallest)
}

/// Encode events into one ECF buffer with the coordinate layout `packing`. Every event
/// round-trips exactly, time stamps that go back included (a step back is stored as a large
/// step that wraps modulo 2⁶⁴). Fails for more than [`MAX_EVENTS`] events, columns of
/// different lengths, coordinates above [`MAX_COORDINATE`] or polarities other than 0 and 1.
pub fn encode_with(events: &EcfEvents, packing: Packing) -> Result<Vec<u8>, EcfError> {
    let n = events.t.len();
    if events.x.len() != n || events.y.len() != n || events.p.len() != n {
        return fail(0, "the x, y, p and t columns differ in length");
    }
    if n > MAX_EVENTS {
        return fail(
            0,
            format!("{n} events; an ECF buffer holds at most {MAX_EVENTS}"),
        );
    }
    if let Some(i) = (0..n).find(|&i| events.x[i] > MAX_COORDINATE || events.y[i] > MAX_COORDINATE)
    {
        return fail(
            0,
            format!(
                "event {i} at ({}, {}): ECF stores coordinates up to {MAX_COORDINATE}",
                events.x[i], events.y[i]
            ),
        );
    }
    if let Some(i) = events.p.iter().position(|&p| p > 1) {
        return fail(
            0,
            format!("event {i} has polarity {}; ECF stores 0 or 1", events.p[i]),
        );
    }
    let packing = match packing {
        Packing::Smallest => smallest_packing(events),
        chosen => chosen,
    };
    let mut out = Vec::with_capacity(12 + 4 * n);
    let flags = match packing {
        Packing::AllPacked => 2,
        Packing::XAndPPacked => 1,
        _ => 0,
    };
    out.extend_from_slice(&(((n as u32) << 2) | flags).to_le_bytes());
    encode_times(&events.t, &mut out);
    match packing {
        Packing::AllPacked => encode_all_packed(events, &mut out),
        Packing::XAndPPacked => {
            encode_runs(&events.y, &mut out, 0x1F, |y, len, out| {
                out.extend_from_slice(&((y << 5) | len as u16).to_le_bytes())
            });
            encode_x_and_p_packed(events, &mut out);
        }
        Packing::Masked | Packing::Smallest => {
            encode_runs(&events.y, &mut out, 0x1F, |y, len, out| {
                out.extend_from_slice(&((y << 5) | len as u16).to_le_bytes())
            });
            encode_masked_x(&events.x, &mut out);
            encode_runs(&events.p, &mut out, 0x7F, |p, len, out| {
                out.push((p << 7) | len as u8)
            });
        }
    }
    Ok(out)
}

/// The layout that stores these coordinates in the fewest bytes.
fn smallest_packing(events: &EcfEvents) -> Packing {
    let n = events.len();
    let groups = n.div_ceil(4);
    let runs = |escape: usize, word: usize, v: &mut dyn Iterator<Item = usize>| -> usize {
        run_lengths(v)
            .map(|len| if len >= escape { word + 2 } else { word })
            .sum()
    };
    let y_runs = runs(0x1F, 2, &mut events.y.iter().map(|&v| v as usize));
    let p_runs = runs(0x7F, 1, &mut events.p.iter().map(|&v| v as usize));
    let masked = 2 * masked_words(&events.x);
    let sizes = [
        (12 * groups, Packing::AllPacked),
        (y_runs + 6 * groups, Packing::XAndPPacked),
        (y_runs + masked + p_runs, Packing::Masked),
    ];
    sizes
        .iter()
        .min_by_key(|(size, _)| *size)
        .map_or(Packing::AllPacked, |&(_, p)| p)
}

/// The lengths of the runs of equal values.
fn run_lengths(values: &mut dyn Iterator<Item = usize>) -> impl Iterator<Item = usize> {
    let mut lengths = Vec::new();
    let mut current: Option<(usize, usize)> = None;
    for v in values {
        current = match current {
            Some((value, len)) if value == v => Some((value, len + 1)),
            Some((_, len)) => {
                lengths.push(len);
                Some((v, 1))
            }
            None => Some((v, 1)),
        };
    }
    lengths.extend(current.map(|(_, len)| len));
    lengths.into_iter()
}

/// Append the runs of equal `values` (`write(value, length)`; a length of `escape` or more
/// is written as `escape` and followed by the length as a `u16`).
fn encode_runs<T: Copy + PartialEq>(
    values: &[T],
    out: &mut Vec<u8>,
    escape: usize,
    write: impl Fn(T, usize, &mut Vec<u8>),
) {
    let mut i = 0;
    while i < values.len() {
        let v = values[i];
        let len = values[i..].iter().take_while(|&&w| w == v).count();
        if len >= escape {
            write(v, escape, out);
            out.extend_from_slice(&(len as u16).to_le_bytes());
        } else {
            write(v, len, out);
        }
        i += len;
    }
}

fn encode_times(t: &[i64], out: &mut Vec<u8>) {
    let origin = t.first().copied().unwrap_or(0) as u64;
    out.extend_from_slice(&origin.to_le_bytes());
    let mut now = origin;
    let mut i = 0;
    while i < t.len() {
        let next = t[i] as u64;
        let mut step = next.wrapping_sub(now);
        if step >= 0xF {
            // A large step (or a step back, which wraps): 4 bits per byte, then a run
            // with no step.
            while step > 0 {
                out.push(0xF0 | (step & 0xF) as u8);
                step >>= 4;
            }
        }
        now = next;
        let len = t[i..].iter().take_while(|&&v| v as u64 == next).count();
        if len >= 0xF {
            out.push(((step as u8) << 4) | 0xF);
            out.extend_from_slice(&(len as u16).to_le_bytes());
        } else {
            out.push(((step as u8) << 4) | len as u8);
        }
        i += len;
    }
}

/// The number of masked-x words the columns `x` need.
fn masked_words(x: &[u16]) -> usize {
    let mut words = 0;
    let mut i = 0;
    while i < x.len() {
        i += masked_word(x, i).1;
        words += 1;
    }
    words
}

/// The masked-x word that starts at event `i` and how many events it covers: the column of
/// event `i` and a bit for each following event at `x + 1 + j`, `j` rising from 0 to 4.
fn masked_word(x: &[u16], i: usize) -> (u16, usize) {
    let base = x[i];
    let mut word = base << 5;
    let mut used = 1;
    for j in 0..5u16 {
        if x.get(i + used) == Some(&(base + j + 1)) {
            word |= 1 << (4 - j);
            used += 1;
        }
    }
    (word, used)
}

fn encode_masked_x(x: &[u16], out: &mut Vec<u8>) {
    let mut i = 0;
    while i < x.len() {
        let (word, used) = masked_word(x, i);
        out.extend_from_slice(&word.to_le_bytes());
        i += used;
    }
}

fn encode_x_and_p_packed(events: &EcfEvents, out: &mut Vec<u8>) {
    for (xs, ps) in events.x.chunks(4).zip(events.p.chunks(4)) {
        let mut v = [0u16; 4];
        for (k, (x, p)) in xs.iter().zip(ps).enumerate() {
            v[k] = (x << 1) | u16::from(*p);
        }
        let words = [
            (v[0] << 4) | (v[1] & 0xF),
            ((v[1] >> 4) << 8) | (v[2] & 0xFF),
            ((v[2] >> 8) << 12) | (v[3] & 0xFFF),
        ];
        for w in words {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }
}

fn encode_all_packed(events: &EcfEvents, out: &mut Vec<u8>) {
    for k in (0..events.len()).step_by(4) {
        let mut v = [0u32; 4];
        for (j, slot) in v.iter_mut().enumerate() {
            if let (Some(&x), Some(&y), Some(&p)) = (
                events.x.get(k + j),
                events.y.get(k + j),
                events.p.get(k + j),
            ) {
                *slot = (u32::from(y) << 12) | (u32::from(x) << 1) | u32::from(p);
            }
        }
        let words = [
            (v[0] << 8) | (v[1] & 0xFF),
            ((v[1] >> 8) << 16) | (v[2] & 0xFFFF),
            ((v[2] >> 16) << 24) | (v[3] & 0xFF_FFFF),
        ];
        for w in words {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests;
