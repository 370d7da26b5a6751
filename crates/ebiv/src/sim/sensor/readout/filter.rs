//! The readout's refractory filter and token bucket over events in time order
//! (sensor-model.md §2.5, §2.11).
//!
//! Both go in time order and carry state from one event to the next: the time of the last
//! event of each pixel that the refractory filter kept (the bucket may still drop it; it
//! blinds its pixel all the same), and the bucket's tokens. [`StreamFilter`] keeps that state
//! from one window of a stream to the next, so that the windows are filtered as one pass.

use std::collections::HashMap;

use super::{key_pixel, key_time};

/// Spacing tolerance of the refractory filter, µs: differences this close to the refractory
/// period are rounding, not violations.
const REFRACTORY_TOLERANCE_US: f64 = 1e-6;

/// Largest pixel table the refractory filter allocates densely; larger sensors use a map.
const DENSE_TABLE_LIMIT: usize = 1 << 24;

/// How many events ahead [`FilterState::run`] prefetches the refractory filter's table.
const PREFETCH_AHEAD: usize = 16;

/// What the filters do: the refractory period in µs (0 = none) and the bucket's rate in
/// tokens per µs and depth (`None` = no bandwidth limit).
#[derive(Debug, Clone, Copy)]
pub(super) struct Filters {
    pub refractory: f64,
    pub bucket: Option<(f64, f64)>,
}

impl Filters {
    /// The smallest spacing, µs, that two kept events of a pixel may have: the refractory
    /// period less [`REFRACTORY_TOLERANCE_US`].
    fn limit(&self) -> f64 {
        self.refractory - REFRACTORY_TOLERANCE_US
    }
}

/// What the filters dropped: the indices of the dropped events, ascending, and how many of
/// them each filter dropped.
#[derive(Debug, Default)]
pub(super) struct Drops {
    pub indices: Vec<usize>,
    pub refractory: u64,
    pub bandwidth: u64,
}

/// The filters' state carried from one window of a stream of sorted events to the next
/// ([`super::stream`]): each window is filtered as the next stretch of one pass.
pub(super) struct StreamFilter(FilterState);

impl StreamFilter {
    /// No pixel of a `width` × `height` sensor blinded, and the bucket full at the first
    /// kept event.
    pub(super) fn new(width: usize, height: usize, filters: Filters) -> Self {
        StreamFilter(FilterState::new(width, width * height, filters))
    }

    /// The events of `keys` (packed, valid, sorted, and none before the keys of earlier
    /// calls) that the refractory filter or the token bucket drops, with indices into
    /// `keys`: an event closer than the refractory period (less
    /// [`REFRACTORY_TOLERANCE_US`]) to the previous kept event of its pixel, then an event
    /// that finds the bucket empty. The bucket starts full at the first event the refractory
    /// filter keeps.
    pub(super) fn drops(&mut self, keys: &[u128]) -> Drops {
        if self.0.refractory.is_none() && self.0.bucket_params.is_none() {
            return Drops::default();
        }
        let outcome = self.0.run(keys);
        Drops {
            indices: merge(&outcome.refractory, &outcome.bandwidth),
            refractory: outcome.refractory.len() as u64,
            bandwidth: outcome.bandwidth.len() as u64,
        }
    }
}

/// The union of two ascending lists of distinct indices, ascending.
fn merge(a: &[usize], b: &[usize]) -> Vec<usize> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if a[i] < b[j] {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(b[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// The filters' state while going through the events.
struct FilterState {
    refractory: Option<RefractoryFilter>,
    bucket_params: Option<(f64, f64)>,
    bucket: Option<TokenBucket>,
}

/// The events one run of the filters dropped.
struct Outcome {
    /// Events the refractory filter dropped, ascending.
    refractory: Vec<usize>,
    /// Events the bucket dropped, ascending.
    bandwidth: Vec<usize>,
}

impl FilterState {
    /// No pixel blinded, and no bucket yet (it starts full at the first kept event).
    fn new(width: usize, table_size: usize, filters: Filters) -> Self {
        FilterState {
            refractory: (filters.refractory > 0.0)
                .then(|| RefractoryFilter::new(width, table_size, filters.limit())),
            bucket_params: filters.bucket,
            bucket: None,
        }
    }

    /// Filter `keys`, carrying the state on.
    fn run(&mut self, keys: &[u128]) -> Outcome {
        let mut outcome = Outcome {
            refractory: Vec::new(),
            bandwidth: Vec::new(),
        };
        for (i, &key) in keys.iter().enumerate() {
            let t = key_time(key);
            if let Some(filter) = &mut self.refractory {
                if let Some(&ahead) = keys.get(i + PREFETCH_AHEAD) {
                    filter.prefetch(key_pixel(ahead));
                }
                if !filter.pass(t, key_pixel(key)) {
                    outcome.refractory.push(i);
                    continue;
                }
            }
            if let Some((rate, burst)) = self.bucket_params {
                let bucket = self
                    .bucket
                    .get_or_insert_with(|| TokenBucket::new(rate, burst, t));
                if !bucket.pass(t) {
                    outcome.bandwidth.push(i);
                }
            }
        }
        outcome
    }
}

/// The refractory filter, fed the events in time order: an event within `limit` µs of the
/// previous kept event of its pixel does not pass.
struct RefractoryFilter {
    limit: f64,
    /// Time of the last kept event per pixel, in a dense table or, for a sensor too large
    /// for one, a map.
    last: PixelTable,
}

enum PixelTable {
    Dense { width: usize, last: Vec<f64> },
    Sparse(HashMap<(u16, u16), f64>),
}

impl RefractoryFilter {
    /// A filter for pixels `(x, y)` with `y·width + x < table_size`, none blinded yet.
    fn new(width: usize, table_size: usize, limit: f64) -> Self {
        let last = if table_size <= DENSE_TABLE_LIMIT {
            PixelTable::Dense {
                width,
                last: vec![f64::NEG_INFINITY; table_size],
            }
        } else {
            PixelTable::Sparse(HashMap::new())
        };
        RefractoryFilter { limit, last }
    }

    fn slot(&mut self, (x, y): (u16, u16)) -> &mut f64 {
        match &mut self.last {
            PixelTable::Dense { width, last } => &mut last[y as usize * *width + x as usize],
            PixelTable::Sparse(map) => map.entry((x, y)).or_insert(f64::NEG_INFINITY),
        }
    }

    /// Ask the processor to fetch the table entry of pixel `(x, y)` into the cache: the
    /// events' pixels are scattered over the sensor, so each entry is a cache miss that the
    /// processor would otherwise wait for.
    #[inline]
    fn prefetch(&self, (x, y): (u16, u16)) {
        if let PixelTable::Dense { width, last } = &self.last {
            if let Some(slot) = last.get(y as usize * *width + x as usize) {
                crate::simd::prefetch(slot);
            }
        }
    }

    /// Whether the event at `t` of pixel `(x, y)` passes; if it does, it is the pixel's last.
    #[inline]
    fn pass(&mut self, t: f64, pixel: (u16, u16)) -> bool {
        let limit = self.limit;
        let slot = self.slot(pixel);
        if t - *slot < limit {
            false
        } else {
            *slot = t;
            true
        }
    }
}

/// The token bucket, fed the kept events in time order: `rate` tokens per µs, depth `burst`,
/// full at the first event.
#[derive(Debug, Clone, Copy)]
struct TokenBucket {
    rate: f64,
    burst: f64,
    tokens: f64,
    last: f64,
}

impl TokenBucket {
    fn new(rate: f64, burst: f64, first: f64) -> Self {
        TokenBucket {
            rate,
            burst,
            tokens: burst,
            last: first,
        }
    }

    /// The tokens an event at `t` finds (before taking one).
    #[inline]
    fn refilled(&self, t: f64) -> f64 {
        (self.tokens + (t - self.last) * self.rate).min(self.burst)
    }

    /// Whether an event at `t` finds a token (and takes it).
    #[inline]
    fn pass(&mut self, t: f64) -> bool {
        self.tokens = self.refilled(t);
        self.last = t;
        if self.tokens >= 1.0 - 1e-9 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{Filters, StreamFilter};
    use crate::sim::rng::{Rng, Stream};
    use crate::sim::sensor::readout::pack;
    use crate::sim::sensor::SimEvent;

    /// Small random recordings (ties, few pixels, refractory periods from none to longer than
    /// a window, buckets from none to one that runs dry at once) cut into random windows of
    /// 1 to 40 events: each window, filtered with the state the windows before it left, drops
    /// what one pass over all events drops. (That one pass follows the readout's definition
    /// is tested against a step-by-step reference in `sim::sensor::tests::readout`.)
    #[test]
    fn windows_give_the_drops_of_one_pass() {
        let mut rng = Rng::new(5, Stream::Temporal, 0);
        let mut dropped_somewhere = 0;
        for trial in 0..600 {
            let n = 1 + (rng.next_u64() % 300) as usize;
            let pixels = 1 + rng.next_u64() % 10;
            let mut keys: Vec<u128> = (0..n)
                .map(|_| {
                    pack(&SimEvent {
                        t_us: (rng.next_u64() % 200) as f64 * 0.5,
                        x: (rng.next_u64() % pixels) as u16,
                        y: 0,
                        p: (rng.next_u64() % 2) as u8,
                    })
                })
                .collect();
            keys.sort_unstable();
            keys.dedup();
            let refractory = [0.0, 0.5, 1.0, 3.0, 20.0][trial % 5];
            let bucket = [
                None,
                Some((0.5, 1.0)),
                Some((2.0, 3.0)),
                Some((f64::INFINITY, 1.0)),
            ][(trial / 5) % 4];
            let filters = Filters { refractory, bucket };
            let one = StreamFilter::new(pixels as usize, 1, filters).drops(&keys);
            let mut windows = StreamFilter::new(pixels as usize, 1, filters);
            let (mut indices, mut by_refractory, mut by_bandwidth) = (Vec::new(), 0, 0);
            let mut start = 0;
            while start < keys.len() {
                let end = (start + 1 + (rng.next_u64() % 40) as usize).min(keys.len());
                let drops = windows.drops(&keys[start..end]);
                indices.extend(drops.indices.iter().map(|i| i + start));
                by_refractory += drops.refractory;
                by_bandwidth += drops.bandwidth;
                start = end;
            }
            assert_eq!(indices, one.indices, "trial {trial}: {filters:?}");
            assert_eq!(
                (by_refractory, by_bandwidth),
                (one.refractory, one.bandwidth),
                "trial {trial}: {filters:?}"
            );
            if by_refractory > 0 && by_bandwidth > 0 {
                dropped_somewhere += 1;
            }
        }
        assert!(
            dropped_somewhere > 50,
            "both filters drop in {dropped_somewhere} trials"
        );
    }
}
