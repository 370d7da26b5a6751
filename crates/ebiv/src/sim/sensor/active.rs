//! The active set of a band: a two-level bitmap over its pixels.
//!
//! Visiting the members in index order keeps the per-step pass over the pixel states
//! sequential in memory (the order in which pixels were activated is the renderer's, close to
//! random); the summary level skips 4096 idle pixels per word, so an idle sensor costs almost
//! nothing per step.

/// A set of pixel indices `0..n`.
#[derive(Debug, Clone, Default)]
pub(super) struct ActiveSet {
    /// Bit `i % 64` of word `i / 64`: pixel `i` is a member.
    words: Vec<u64>,
    /// Bit `w % 64` of word `w / 64`: `words[w]` is not zero.
    summary: Vec<u64>,
    len: usize,
}

impl ActiveSet {
    /// An empty set over `n` pixels.
    pub fn new(n: usize) -> Self {
        let words = n.div_ceil(64);
        ActiveSet {
            words: vec![0; words],
            summary: vec![0; words.div_ceil(64)],
            len: 0,
        }
    }

    /// Number of members.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Remove every member.
    pub fn clear(&mut self) {
        self.words.iter_mut().for_each(|w| *w = 0);
        self.summary.iter_mut().for_each(|w| *w = 0);
        self.len = 0;
    }

    /// Add pixel `i` (< n).
    #[inline]
    pub fn insert(&mut self, i: usize) {
        let (w, b) = (i / 64, i % 64);
        let word = &mut self.words[w];
        if *word & (1 << b) == 0 {
            *word |= 1 << b;
            self.summary[w / 64] |= 1 << (w % 64);
            self.len += 1;
        }
    }

    /// Remove pixel `i` (< n) if it is a member.
    #[inline]
    pub fn remove(&mut self, i: usize) {
        let (w, b) = (i / 64, i % 64);
        let word = &mut self.words[w];
        if *word & (1 << b) != 0 {
            *word &= !(1 << b);
            if *word == 0 {
                self.summary[w / 64] &= !(1 << (w % 64));
            }
            self.len -= 1;
        }
    }

    /// Visit every member in increasing order; `keep(i)` returns whether `i` stays.
    #[inline]
    pub fn retain(&mut self, mut keep: impl FnMut(usize) -> bool) {
        let mut len = 0;
        for s in 0..self.summary.len() {
            let mut summary = self.summary[s];
            let mut summary_kept = summary;
            while summary != 0 {
                let w = s * 64 + summary.trailing_zeros() as usize;
                summary &= summary - 1;
                let mut bits = self.words[w];
                let mut kept = bits;
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if !keep(w * 64 + b) {
                        kept &= !(1 << b);
                    }
                }
                self.words[w] = kept;
                len += kept.count_ones() as usize;
                if kept == 0 {
                    summary_kept &= !(1 << (w % 64));
                }
            }
            self.summary[s] = summary_kept;
        }
        self.len = len;
    }
}

#[cfg(test)]
mod tests {
    use super::ActiveSet;

    #[test]
    fn members_are_visited_in_order_and_removed_on_request() {
        let mut set = ActiveSet::new(10_000);
        for i in [9_999, 3, 64, 4_095, 4_096, 3, 70, 71, 5_000] {
            set.insert(i);
        }
        set.remove(5_000);
        set.remove(5_001);
        assert_eq!(set.len(), 7);
        let mut seen = Vec::new();
        set.retain(|i| {
            seen.push(i);
            i % 2 == 1
        });
        assert_eq!(seen, [3, 64, 70, 71, 4_095, 4_096, 9_999]);
        assert_eq!(set.len(), 4);
        let mut seen = Vec::new();
        set.retain(|i| {
            seen.push(i);
            true
        });
        assert_eq!(seen, [3, 71, 4_095, 9_999]);
        set.clear();
        set.retain(|_| panic!("empty"));
        assert_eq!(set.len(), 0);
    }
}
