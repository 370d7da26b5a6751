//! Appending decoded events to an [`EventBuffer`] without a capacity check per column and
//! event: a decoder reserves room for the most events its input can hold, writes every
//! candidate event into the next free slot, and keeps it by advancing the count, so the body
//! of a decoding loop needs no branch on whether an event is kept.

use crate::event::{EventBuffer, Trigger};
use std::mem::MaybeUninit;

/// The reserved, not yet initialised room at the end of the four columns of an
/// [`EventBuffer`], filled front to back; [`append`] makes the written events part of the
/// buffer.
pub(crate) struct EventSink<'a> {
    t: &'a mut [MaybeUninit<i64>],
    x: &'a mut [MaybeUninit<u16>],
    y: &'a mut [MaybeUninit<u16>],
    p: &'a mut [MaybeUninit<u8>],
    /// The buffer's triggers, appended to directly.
    pub triggers: &'a mut Vec<Trigger>,
    /// Events written and kept so far.
    len: usize,
}

impl EventSink<'_> {
    /// Write an event into the next slot and keep it when `keep` is true; a dropped event's
    /// slot is reused by the next one. Needs room for one more event (checked).
    #[inline(always)]
    pub fn push_if(&mut self, keep: bool, t: i64, x: u16, y: u16, p: u8) {
        let i = self.len;
        assert!(i < self.t.len(), "event sink overfilled");
        // SAFETY: the four columns have the same length (`append` cuts them so) and `i` is
        // below it.
        unsafe {
            self.t.get_unchecked_mut(i).write(t);
            self.x.get_unchecked_mut(i).write(x);
            self.y.get_unchecked_mut(i).write(y);
            self.p.get_unchecked_mut(i).write(p);
        }
        self.len = i + keep as usize;
    }

    /// Turn items of `items` into events while `event` gives one (`(keep, t, x, y, p)` as
    /// [`EventSink::push_if`] takes them); returns the item for which it gave none, `None`
    /// when the items ran out. The tight loop of a decoder: the columns and the count stay in
    /// registers. Needs room for every event written (checked).
    #[inline(always)]
    pub fn extend_while<I: Iterator>(
        &mut self,
        items: &mut I,
        mut event: impl FnMut(&I::Item) -> Option<(bool, i64, u16, u16, u8)>,
    ) -> Option<I::Item> {
        let n = self.t.len();
        let (t, x, y, p) = (
            &mut self.t[..n],
            &mut self.x[..n],
            &mut self.y[..n],
            &mut self.p[..n],
        );
        let mut len = self.len;
        let stop = loop {
            let Some(item) = items.next() else {
                break None;
            };
            let Some((keep, et, ex, ey, ep)) = event(&item) else {
                break Some(item);
            };
            if len >= n {
                self.len = len;
                panic!("event sink overfilled");
            }
            // SAFETY: the four columns were cut to the same length `n` and `len < n`.
            unsafe {
                t.get_unchecked_mut(len).write(et);
                x.get_unchecked_mut(len).write(ex);
                y.get_unchecked_mut(len).write(ey);
                p.get_unchecked_mut(len).write(ep);
            }
            len += keep as usize;
        };
        self.len = len;
        stop
    }

    /// Keep an event. Needs room for one more event (checked).
    #[inline(always)]
    pub fn push(&mut self, t: i64, x: u16, y: u16, p: u8) {
        self.push_if(true, t, x, y, p);
    }
}

/// Reserve room for `room` more events in `out`, let `fill` write events into it through an
/// [`EventSink`], and append the events it kept. Returns what `fill` returns.
pub(crate) fn append<R>(
    out: &mut EventBuffer,
    room: usize,
    fill: impl FnOnce(&mut EventSink<'_>) -> R,
) -> R {
    out.reserve(room);
    let start = out.t.len();
    let mut sink = EventSink {
        t: &mut out.t.spare_capacity_mut()[..room],
        x: &mut out.x.spare_capacity_mut()[..room],
        y: &mut out.y.spare_capacity_mut()[..room],
        p: &mut out.p.spare_capacity_mut()[..room],
        triggers: &mut out.triggers,
        len: 0,
    };
    let result = fill(&mut sink);
    let n = start + sink.len;
    // SAFETY: the sink wrote slots 0..len of every column's spare capacity (each push writes
    // all four columns at index `len` before `len` may advance past it), so the first `n`
    // elements of every column are initialised; `n` is within the reserved capacity.
    unsafe {
        out.t.set_len(n);
        out.x.set_len(n);
        out.y.set_len(n);
        out.p.set_len(n);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kept_events_follow_the_existing_ones() {
        let mut out = EventBuffer::new();
        out.push(1, 2, 3, 1);
        let written = append(&mut out, 3, |sink| {
            sink.push_if(false, 9, 9, 9, 0);
            sink.push(4, 5, 6, 0);
            sink.push_if(true, 7, 8, 9, 1);
            2
        });
        assert_eq!(written, 2);
        assert_eq!(out.t, vec![1, 4, 7]);
        assert_eq!(out.x, vec![2, 5, 8]);
        assert_eq!(out.y, vec![3, 6, 9]);
        assert_eq!(out.p, vec![1, 0, 1]);
    }

    #[test]
    #[should_panic]
    fn writing_past_the_room_panics_rather_than_corrupting() {
        let mut out = EventBuffer::new();
        append(&mut out, 1, |sink| {
            sink.push(1, 1, 1, 1);
            sink.push(2, 2, 2, 0);
        });
    }
}
