//! The queue of slabs between the reading and the evaluating thread of a live run: bounded,
//! and, for a live input, dropping its oldest slab to make room for a new one, so that the
//! newest slab always waits and every dropped field is older than one delivered after it.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex};

/// A bounded queue shared by one producer and one consumer.
pub(super) struct SlabQueue<T> {
    state: Mutex<State<T>>,
    changed: Condvar,
    capacity: usize,
    /// Drop the oldest item when full (a live input), rather than wait for room.
    drop_oldest: bool,
}

struct State<T> {
    items: VecDeque<T>,
    /// Items dropped since the consumer last took one.
    dropped: u64,
    /// The producer is done.
    closed: bool,
    /// The consumer is gone (it failed): the producer should stop.
    abandoned: bool,
}

impl<T> SlabQueue<T> {
    pub(super) fn new(capacity: usize, drop_oldest: bool) -> Self {
        SlabQueue {
            state: Mutex::new(State {
                items: VecDeque::new(),
                dropped: 0,
                closed: false,
                abandoned: false,
            }),
            changed: Condvar::new(),
            capacity: capacity.max(1),
            drop_oldest,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State<T>> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Add `item`: when full, drop the oldest (`drop_oldest`) or wait for room. `false` once
    /// the consumer is gone.
    pub(super) fn push(&self, item: T) -> bool {
        let mut state = self.lock();
        while !self.drop_oldest && state.items.len() >= self.capacity && !state.abandoned {
            state = self.changed.wait(state).unwrap_or_else(|p| p.into_inner());
        }
        if state.abandoned {
            return false;
        }
        if state.items.len() >= self.capacity {
            state.items.pop_front();
            state.dropped += 1;
        }
        state.items.push_back(item);
        self.changed.notify_all();
        true
    }

    /// The oldest item and how many were dropped before it, waiting for one; `None` once
    /// the producer is done and the queue is empty.
    pub(super) fn pop(&self) -> Option<(T, u64)> {
        let mut state = self.lock();
        loop {
            if let Some(item) = state.items.pop_front() {
                let dropped = std::mem::take(&mut state.dropped);
                self.changed.notify_all();
                return Some((item, dropped));
            }
            if state.closed {
                return None;
            }
            state = self.changed.wait(state).unwrap_or_else(|p| p.into_inner());
        }
    }

    /// The producer is done.
    pub(super) fn close(&self) {
        self.lock().closed = true;
        self.changed.notify_all();
    }

    /// The consumer is gone: the producer's next push fails.
    pub(super) fn abandon(&self) {
        let mut state = self.lock();
        state.abandoned = true;
        state.items.clear();
        self.changed.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_live_queue_drops_its_oldest_and_counts_them() {
        let q = SlabQueue::new(2, true);
        for k in 0..5 {
            assert!(q.push(k));
        }
        q.close();
        assert_eq!(q.pop(), Some((3, 3)));
        assert_eq!(q.pop(), Some((4, 0)));
        assert_eq!(q.pop(), None);
    }

    #[test]
    fn a_waiting_queue_blocks_until_room_and_stops_when_abandoned() {
        let q = std::sync::Arc::new(SlabQueue::new(1, false));
        let producer = {
            let q = q.clone();
            std::thread::spawn(move || (0..3).map(|k| q.push(k)).collect::<Vec<_>>())
        };
        assert_eq!(q.pop(), Some((0, 0)));
        assert_eq!(q.pop(), Some((1, 0)));
        q.abandon();
        let pushed = producer.join().unwrap();
        assert_eq!(pushed[..2], [true, true]);
        let q2: SlabQueue<i32> = SlabQueue::new(1, false);
        q2.abandon();
        assert!(!q2.push(1));
    }
}
