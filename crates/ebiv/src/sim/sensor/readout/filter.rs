//! The readout's refractory filter and token bucket over events in time order, run on
//! contiguous chunks of the events in parallel and checked afterwards (sensor-model.md §2.5,
//! §2.11).
//!
//! Both go in time order and carry state from one event to the next: the time of the last
//! event of each pixel that the refractory filter kept (the bucket may still drop it; it
//! blinds its pixel all the same), and the bucket's tokens. Each chunk but the first starts
//! from the state they almost always have at its start: no pixel blinded by an event of an
//! earlier chunk, and a full bucket. Whether that was so is checked in order once the chunk
//! before is final: only pixels with such an event within the refractory period before the
//! chunk matter, and the bucket, refilled up to the chunk's first kept event, must be full. A
//! chunk for which either fails is filtered again, on one thread, from its true state; a
//! refractory period longer than a chunk means one pass. The result is the same as one pass
//! over all events, whatever the chunks and the number of threads.

use std::collections::HashMap;

use rayon::iter::{IntoParallelRefIterator, ParallelIterator};

use super::{key_pixel, key_time};

/// Spacing tolerance of the refractory filter, µs: differences this close to the refractory
/// period are rounding, not violations.
const REFRACTORY_TOLERANCE_US: f64 = 1e-6;

/// Largest pixel table a chunk's refractory filter allocates densely; larger sensors use a
/// map.
const DENSE_TABLE_LIMIT: usize = 1 << 24;

/// How many events ahead [`ChunkState::run`] prefetches the refractory filter's table.
const PREFETCH_AHEAD: usize = 16;

/// Fewest events per chunk.
const MIN_CHUNK: usize = 1 << 16;

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

/// What [`drops`] found: the indices of the dropped events, ascending, and how many of them
/// each filter dropped.
#[derive(Debug, Default)]
pub(super) struct Drops {
    pub indices: Vec<usize>,
    pub refractory: u64,
    pub bandwidth: u64,
}

/// The events of `keys` (packed, valid and sorted) that the refractory filter or the token
/// bucket drops: an event closer than `refractory` (less [`REFRACTORY_TOLERANCE_US`]) to the
/// previous kept event of its pixel, then an event that finds the bucket empty. The bucket
/// starts full at the first event the refractory filter keeps.
pub(super) fn drops(keys: &[u128], filters: Filters) -> Drops {
    drops_in_chunks(keys, filters, MIN_CHUNK)
}

/// [`drops`] with chunks of at least `min_chunk` events.
fn drops_in_chunks(keys: &[u128], filters: Filters, min_chunk: usize) -> Drops {
    if keys.is_empty() || (filters.refractory <= 0.0 && filters.bucket.is_none()) {
        return Drops::default();
    }
    let (x_max, y_max) = keys
        .par_iter()
        .map(|&key| key_pixel(key))
        .reduce(|| (0, 0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
    let width = x_max as usize + 1;
    let table_size = width * (y_max as usize + 1);
    let limit = filters.limit();

    let chunks = rayon::current_num_threads()
        .min(keys.len() / min_chunk.max(1))
        .max(1);
    let size = keys.len().div_ceil(chunks);
    let mut ranges: Vec<(usize, usize)> = (0..chunks)
        .map(|c| (c * size, ((c + 1) * size).min(keys.len())))
        .filter(|(a, b)| a < b)
        .collect();
    // A refractory period longer than a chunk: one pass (the check would have to look back
    // over more than the chunk before).
    let long = filters.refractory > 0.0
        && ranges
            .windows(2)
            .any(|w| key_time(keys[w[1].0]) - key_time(keys[w[0].0]) < limit);
    if long {
        ranges = vec![(0, keys.len())];
    }
    let new_state = || ChunkState::new(width, table_size, filters);
    let mut outcomes: Vec<Outcome> = ranges
        .par_iter()
        .map(|&(a, b)| new_state().run(keys, a, b))
        .collect();

    // Check each chunk against the final state at its start; filter it again if needed.
    let mut bucket_before: Option<TokenBucket> = None;
    for c in 0..ranges.len() {
        let (a, b) = ranges[c];
        if c > 0 {
            let recent = recent_kept(keys, a, limit, &outcomes[..c]);
            let t_start = key_time(keys[a]);
            let blinded = filters.refractory > 0.0
                && keys[a..b]
                    .iter()
                    .take_while(|&&key| key_time(key) - t_start < limit)
                    .any(|&key| {
                        recent
                            .get(&key_pixel(key))
                            .is_some_and(|&last| key_time(key) - last < limit)
                    });
            let refilled = match (&bucket_before, outcomes[c].first_kept) {
                (Some(before), Some(t)) => before.full_at(t),
                _ => true,
            };
            if blinded || !refilled {
                let mut state = new_state();
                if let Some(filter) = &mut state.refractory {
                    for (pixel, last) in recent {
                        filter.set(pixel, last);
                    }
                }
                state.bucket = bucket_before;
                outcomes[c] = state.run(keys, a, b);
            }
        }
        if outcomes[c].bucket.is_some() {
            bucket_before = outcomes[c].bucket;
        }
    }

    let mut all = Drops::default();
    for outcome in outcomes {
        all.refractory += outcome.refractory.len() as u64;
        all.bandwidth += outcome.bandwidth.len() as u64;
        all.indices
            .extend(merge(&outcome.refractory, &outcome.bandwidth));
    }
    all
}

/// The filters' state carried from one window of a stream of sorted events to the next
/// ([`super::stream`]): each window is filtered as the next stretch of one pass.
pub(super) struct StreamFilter(ChunkState);

impl StreamFilter {
    /// No pixel of a `width` × `height` sensor blinded, and the bucket full at the first
    /// kept event.
    pub(super) fn new(width: usize, height: usize, filters: Filters) -> Self {
        StreamFilter(ChunkState::new(width, width * height, filters))
    }

    /// The drops among `keys` (packed, valid, sorted, and none before the keys of earlier
    /// calls), with indices into `keys`.
    pub(super) fn drops(&mut self, keys: &[u128]) -> Drops {
        if self.0.refractory.is_none() && self.0.bucket_params.is_none() {
            return Drops::default();
        }
        let outcome = self.0.run(keys, 0, keys.len());
        Drops {
            indices: merge(&outcome.refractory, &outcome.bandwidth),
            refractory: outcome.refractory.len() as u64,
            bandwidth: outcome.bandwidth.len() as u64,
        }
    }
}

/// The events the refractory filter kept within `limit` before `keys[start]`'s time (whether
/// or not the bucket then dropped them: they blind their pixel all the same), as the time of
/// each pixel's last one (from the final `outcomes` of the chunks before `start`).
fn recent_kept(
    keys: &[u128],
    start: usize,
    limit: f64,
    outcomes: &[Outcome],
) -> HashMap<(u16, u16), f64> {
    let t_start = key_time(keys[start]);
    let dropped = |i: usize| {
        outcomes
            .iter()
            .any(|o| o.refractory.binary_search(&i).is_ok())
    };
    let mut recent = HashMap::new();
    for i in (0..start).rev() {
        let t = key_time(keys[i]);
        if t_start - t >= limit {
            break;
        }
        if !dropped(i) {
            recent.entry(key_pixel(keys[i])).or_insert(t);
        }
    }
    recent
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

/// The filters' state while going through a chunk.
struct ChunkState {
    refractory: Option<RefractoryFilter>,
    bucket_params: Option<(f64, f64)>,
    bucket: Option<TokenBucket>,
}

/// What one chunk's filtering gave.
struct Outcome {
    /// Events the refractory filter dropped, ascending.
    refractory: Vec<usize>,
    /// Events the bucket dropped, ascending.
    bandwidth: Vec<usize>,
    /// Time of the first kept event.
    first_kept: Option<f64>,
    /// The bucket after the chunk's last kept event.
    bucket: Option<TokenBucket>,
}

impl ChunkState {
    /// No pixel blinded, and no bucket yet (it starts full at the first kept event).
    fn new(width: usize, table_size: usize, filters: Filters) -> Self {
        ChunkState {
            refractory: (filters.refractory > 0.0)
                .then(|| RefractoryFilter::new(width, table_size, filters.limit())),
            bucket_params: filters.bucket,
            bucket: None,
        }
    }

    /// Filter `keys[a..b]`, carrying the state on.
    fn run(&mut self, keys: &[u128], a: usize, b: usize) -> Outcome {
        let mut outcome = Outcome {
            refractory: Vec::new(),
            bandwidth: Vec::new(),
            first_kept: None,
            bucket: None,
        };
        for (i, &key) in keys.iter().enumerate().take(b).skip(a) {
            let t = key_time(key);
            if let Some(filter) = &mut self.refractory {
                if let Some(&ahead) = keys[..b].get(i + PREFETCH_AHEAD) {
                    filter.prefetch(key_pixel(ahead));
                }
                if !filter.pass(t, key_pixel(key)) {
                    outcome.refractory.push(i);
                    continue;
                }
            }
            outcome.first_kept.get_or_insert(t);
            if let Some((rate, burst)) = self.bucket_params {
                let bucket = self
                    .bucket
                    .get_or_insert_with(|| TokenBucket::new(rate, burst, t));
                if !bucket.pass(t) {
                    outcome.bandwidth.push(i);
                }
            }
        }
        outcome.bucket = self.bucket;
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

    /// Make `t` the time of pixel `(x, y)`'s last kept event.
    fn set(&mut self, pixel: (u16, u16), t: f64) {
        *self.slot(pixel) = t;
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

    /// Whether an event at `t` finds the bucket full: then the bucket is in the state
    /// [`TokenBucket::new`]`(rate, burst, t)` starts in, bit for bit.
    fn full_at(&self, t: f64) -> bool {
        self.refilled(t) == self.burst
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
    use super::{drops, drops_in_chunks, Filters, MIN_CHUNK};
    use crate::sim::rng::{Rng, Stream};
    use crate::sim::sensor::readout::pack;
    use crate::sim::sensor::SimEvent;

    /// Small random recordings cut into chunks of 16 events (ties, few pixels, refractory
    /// periods from none to longer than a chunk, buckets from none to one that runs dry at
    /// once): the drops of one pass for 2–4 threads.
    #[test]
    fn random_small_chunks_give_the_drops_of_one_pass() {
        let pools: Vec<_> = (1..=4)
            .map(|threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
            })
            .collect();
        let mut rng = Rng::new(5, Stream::Temporal, 0);
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
            let one = pools[0].install(|| drops_in_chunks(&keys, filters, 16));
            for pool in &pools[1..] {
                let got = pool.install(|| drops_in_chunks(&keys, filters, 16));
                assert_eq!(got.indices, one.indices, "trial {trial}: {filters:?}");
                assert_eq!(
                    (got.refractory, got.bandwidth),
                    (one.refractory, one.bandwidth),
                    "trial {trial}: {filters:?}"
                );
            }
        }
    }

    /// One pass over all events, as [`drops`] defines them.
    fn one_pass(keys: &[u128], filters: Filters) -> Vec<usize> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        pool.install(|| drops(keys, filters)).indices
    }

    /// `n` events `dt` µs apart cycling through `pixels` pixels of a row, every `collide`-th
    /// one on the pixel of the event before it and half a microsecond after it.
    fn keys(n: usize, dt: f64, pixels: usize, collide: usize) -> Vec<u128> {
        let mut keys: Vec<u128> = (0..n)
            .map(|i| {
                let (pixel, t) = if i % collide == collide - 1 {
                    ((i - 1) % pixels, (i - 1) as f64 * dt + 0.5)
                } else {
                    (i % pixels, i as f64 * dt)
                };
                pack(&SimEvent {
                    t_us: t,
                    x: pixel as u16,
                    y: 0,
                    p: (i % 2) as u8,
                })
            })
            .collect();
        keys.sort_unstable();
        keys
    }

    /// Chunks give the drops of one pass for any number of threads, both where a chunk's
    /// assumed start (no pixel blinded, a full bucket) holds and where it does not and the
    /// chunk is filtered again.
    #[test]
    fn chunks_give_the_drops_of_one_pass() {
        let n = 4 * MIN_CHUNK + 123;
        let refractory = Filters {
            refractory: 7.0,
            bucket: None,
        };
        let cases = [
            // Three pixels 1 µs apart: every chunk starts inside a refractory period.
            (keys(n, 1.0, 3, 1000), refractory),
            // A thousand pixels with an occasional collision: the assumed start holds.
            (keys(n, 1.0, 1000, 997), refractory),
            // A bucket refilled faster than it empties: always full at a chunk's start.
            (
                keys(n, 1.0, 1000, 997),
                Filters {
                    refractory: 7.0,
                    bucket: Some((1.5, 100.0)),
                },
            ),
            // Both, the bucket running dry: events the bucket drops still blind their pixel.
            (
                keys(n, 1.0, 3, 1000),
                Filters {
                    refractory: 4.0,
                    bucket: Some((0.2, 100.0)),
                },
            ),
            // A refractory period longer than a chunk: one pass.
            (
                keys(n, 1.0, 3, 1000),
                Filters {
                    refractory: 1e5,
                    bucket: None,
                },
            ),
            // A bucket that slowly runs dry and then drops every tenth event: never full.
            (
                keys(n, 1.0, 1000, 997),
                Filters {
                    refractory: 0.0,
                    bucket: Some((0.9, 100.0)),
                },
            ),
        ];
        for (keys, filters) in cases {
            let want = one_pass(&keys, filters);
            assert!(!want.is_empty(), "{filters:?} drops something");
            for threads in 2..=5 {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let got = pool.install(|| drops(&keys, filters));
                let first_difference = got.indices.iter().zip(&want).position(|(a, b)| a != b);
                assert!(
                    got.indices == want,
                    "{filters:?}, {threads} threads: {} drops, want {}; first difference at \
                     drop {first_difference:?}",
                    got.indices.len(),
                    want.len()
                );
                assert_eq!(
                    got.refractory + got.bandwidth,
                    want.len() as u64,
                    "{filters:?}"
                );
            }
        }
    }
}
