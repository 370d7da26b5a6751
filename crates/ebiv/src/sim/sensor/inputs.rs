//! The new samples of one step of a band, queued for its pixel update.

/// `(local pixel, irradiance)` samples of one step, in the order given.
///
/// Its slots are kept from step to step, so that a caller queuing many samples at once
/// ([`InputQueue::queue`]) writes them straight into memory already allocated and
/// initialised, without a capacity check per sample or a fill of the slots first.
#[derive(Debug, Clone, Default)]
pub(super) struct InputQueue {
    slots: Vec<(u32, f32)>,
    len: usize,
}

impl InputQueue {
    /// The queued samples.
    #[inline]
    pub fn as_slice(&self) -> &[(u32, f32)] {
        &self.slots[..self.len]
    }

    /// The queued samples, to be changed in place.
    #[inline]
    pub fn as_mut_slice(&mut self) -> &mut [(u32, f32)] {
        &mut self.slots[..self.len]
    }

    /// Number of queued samples.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Forget the queued samples (their slots stay allocated).
    #[inline]
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Queue one sample.
    #[inline]
    pub fn push(&mut self, sample: (u32, f32)) {
        match self.slots.get_mut(self.len) {
            Some(slot) => *slot = sample,
            None => self.slots.push(sample),
        }
        self.len += 1;
    }

    /// Queue up to `max` samples at once: `fill` writes them into the first of the `max`
    /// slots it is given and returns how many it wrote (slots beyond that count may hold
    /// anything it wrote there; they are not queued).
    #[inline]
    pub fn queue(&mut self, max: usize, fill: impl FnOnce(&mut [(u32, f32)]) -> usize) {
        let end = self.len + max;
        if self.slots.len() < end {
            self.slots.resize(end, (0, 0.0));
        }
        let used = fill(&mut self.slots[self.len..end]).min(max);
        self.len += used;
    }
}

#[cfg(test)]
mod tests {
    use super::InputQueue;

    #[test]
    fn queued_samples_are_those_pushed_and_counted_in_order() {
        let mut q = InputQueue::default();
        q.push((7, 1.0));
        q.queue(3, |slots| {
            assert_eq!(slots.len(), 3);
            slots[0] = (8, 2.0);
            // Written but not counted: not queued.
            slots[1] = (9, 3.0);
            1
        });
        q.push((10, 4.0));
        assert_eq!(q.as_slice(), [(7, 1.0), (8, 2.0), (10, 4.0)]);
        q.as_mut_slice()[2].1 = 5.0;
        assert_eq!(q.len(), 3);
        q.clear();
        assert!(q.as_slice().is_empty());
        // Reused slots: what was left in them is not queued.
        q.queue(4, |_| 0);
        q.push((1, 0.5));
        assert_eq!(q.as_slice(), [(1, 0.5)]);
        // A count above `max` is taken as `max`.
        q.queue(2, |slots| {
            slots.copy_from_slice(&[(2, 0.25), (3, 0.125)]);
            usize::MAX
        });
        assert_eq!(q.as_slice(), [(1, 0.5), (2, 0.25), (3, 0.125)]);
    }
}
