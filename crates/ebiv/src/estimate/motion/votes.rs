//! A coarse velocity map from event pairs, the start of the Newton search.
//!
//! With a Gaussian splat, Σ I² of the IWE is a sum over event pairs of the overlap of their
//! two kernels, `exp(−|Δx − v Δt|² / 4σ²)`: a kernel density estimate, in velocity space,
//! of the pairs' velocities `Δx / Δt` (the pairwise form of contrast maximisation that
//! projection-concentration methods use, algorithms.md §15.1). Pairs far apart in time vote
//! sharply; pairs close in time vote for a broad blur of velocities and carry little
//! information. A histogram of the velocities of the pairs at least a quarter of the window's
//! time span apart ([`MIN_GAP`]), smoothed, is therefore a coarse picture of the
//! objective over a range much wider than the search range, for one pass over those pairs
//! instead of one IWE per candidate.

use super::iwe::Events;
use crate::peak::first_where;
use crate::simd::avx2_available;

/// Events voting in a window of up to [`DENSE`] events (≈ 5 800 pairs); beyond, the events
/// are thinned evenly in time.
const MAX_EVENTS: usize = 144;
/// Above this many events, the voting events grow as the square root of the window's
/// events ([`voters`]).
const DENSE: usize = 1_000;
/// Pairs closer in time than this fraction of the window's time span do not vote: their
/// velocity is too uncertain (a 1 px position error over 2.5 ms of a 10 ms slab is
/// 0.4 px/ms).
const MIN_GAP: f32 = 0.25;
/// Pairs closer than this in both x and y, px, do not vote: two events of one pixel. Where
/// each pixel fires several times while a particle passes, or several particles pass one
/// pixel in a slab (dense seeding, small particle images), such pairs outnumber the pairs
/// of one particle's trail and vote for zero velocity whatever the flow; the search
/// compares the objective at the centre of its range with the vote's starts instead.
const SAME_PIXEL: f32 = 1.0;
/// Starts returned at most.
pub(crate) const MAX_STARTS: usize = 3;
/// Local maxima below this fraction of the highest are not returned as starts.
const START_FRACTION: f64 = 0.5;

/// Working memory of the vote.
#[derive(Debug, Clone, Default)]
pub(crate) struct VoteScratch {
    /// Per event, its time's order key in the high half and its scrambled index in the low
    /// half ([`time_keys`], [`index_of`]).
    keys: Vec<u64>,
    sorted: [Vec<f32>; 3],
    cells: Vec<u32>,
    counts: Vec<u32>,
    rows: Vec<u32>,
    smooth: Vec<u32>,
    maxima: Vec<(u32, usize)>,
    /// Starts of the last vote, best first.
    pub starts: Vec<[f64; 2]>,
}

/// How many of a window's `total` events vote: all up to [`MAX_EVENTS`], then
/// [`MAX_EVENTS`] up to [`DENSE`] events, then `MAX_EVENTS · √(total / DENSE)`.
///
/// One particle's trail supplies about `(kept / particles)²` of the pairs, so the trail's
/// share of the votes falls with the number of particles in the window while the random
/// pairs spread evenly; dense windows (tens of particles, thousands of events) need more
/// voters for the trails to stand out. The vote's cost, ∝ `kept²`, then grows as the
/// window's events, as the objective's evaluations do.
fn voters(total: usize) -> usize {
    if total <= DENSE {
        return total.min(MAX_EVENTS);
    }
    let scaled = MAX_EVENTS as f64 * (total as f64 / DENSE as f64).sqrt();
    (scaled as usize).min(total)
}

/// `out += k · add`, element by element.
fn add_scaled(out: &mut [u32], add: &[u32], k: u32) {
    for (o, &a) in out.iter_mut().zip(add) {
        *o += k * a;
    }
}

/// `floor(a)` for `a` in `[−1, limit]` (`limit` < 2²¹), as `u32` with −1 wrapped to
/// `u32::MAX`; NaN and values outside are clamped first (`a − 0.5` is clamped to that range).
///
/// Rounding by adding 1.5 · 2²³ (the float's mantissa then holds the integer part) instead of
/// a saturating `as` cast, which the compiler cannot vectorise: the pair loop's cost is
/// dominated by the conversion otherwise. `round(a − 0.5)` is the floor except where `a` is
/// an exact odd integer, where rounding ties to even gives the cell below (pairs whose
/// displacement and time difference fall on the cell lattice exactly: rare, one cell off).
/// Unlike the earlier truncating cast, values in (−1, 0) fall outside the map instead of
/// into its first row or column.
#[inline(always)]
fn cell_index(a: f32, limit: f32) -> u32 {
    const MAGIC: f32 = 12_582_912.0;
    // Comparisons rather than `f32::max`/`min`, whose NaN rules cost a blend per lane: NaN
    // becomes −1 (outside), as does anything below.
    let a = a - 0.5;
    let a = if a > -1.0 { a } else { -1.0 };
    let a = if a < limit { a } else { limit };
    (a + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits())
}

/// Into `keys`, per time of `t`, a key whose order is the time's [`f32::total_cmp`] order:
/// `(ordered bits << 32) | scrambled index` ([`index_of`] recovers the index). Sorting the
/// keys as integers orders the events by time without the indirect loads of a comparison of
/// times through indices (159 M of the vote's 666 M instructions on two fields of a 1280×720
/// uniform flow of 0.00152 particles per pixel, `gen4`).
///
/// Equal times, frequent with µs time stamps, are ordered by the index multiplied by an odd
/// constant (a bijection of `u32`), not by the index itself: events are gathered tile by
/// tile, and the index order would keep each group of equal times tile by tile, so that the
/// evenly thinned voting events lean to some tiles (on the real wall flow 5 of 576 valid
/// vectors became out-of-range ones, as with the stable sort reverted in c76972e).
fn time_keys(t: &[f32], keys: &mut Vec<u64>) {
    debug_assert!(
        t.len() as u64 <= 1 << 32,
        "indices must fit the key's low half"
    );
    keys.clear();
    keys.extend(t.iter().enumerate().map(|(i, &t)| {
        let bits = t.to_bits();
        // Negative times (sign bit set) in reverse, below the positive ones, as total_cmp.
        let ordered = if bits >> 31 == 1 {
            !bits
        } else {
            bits | 1 << 31
        };
        let scrambled = (i as u32).wrapping_mul(TIE_SCRAMBLE);
        (u64::from(ordered) << 32) | u64::from(scrambled)
    }));
}

/// The odd multiplier that orders equal times in [`time_keys`] (2³²/φ, Knuth's
/// multiplicative hashing), and its inverse modulo 2³².
const TIE_SCRAMBLE: u32 = 0x9E37_79B9;
const TIE_UNSCRAMBLE: u32 = 0x144C_BC89;

/// The index of the event of a key made by [`time_keys`].
#[inline]
fn index_of(key: u64) -> usize {
    (key as u32).wrapping_mul(TIE_UNSCRAMBLE) as usize
}

/// `out[i] = c[i − 1] + 2 c[i] + c[i + 1]`, zero outside `c` (`out` as long as `c`): the
/// row pass of the vote's [1 2 1] smoothing, the interior as one loop over three shifted
/// slices, which the compiler vectorises.
fn smooth_row(c: &[u32], out: &mut [u32]) {
    let n = c.len();
    debug_assert_eq!(out.len(), n);
    match n {
        0 => {}
        1 => out[0] = 2 * c[0],
        _ => {
            out[0] = 2 * c[0] + c[1];
            let interior = out[1..n - 1]
                .iter_mut()
                .zip(c.iter().zip(&c[1..]).zip(&c[2..]));
            for (o, ((&left, &centre), &right)) in interior {
                *o = left + 2 * centre + right;
            }
            out[n - 1] = c[n - 2] + 2 * c[n - 1];
        }
    }
}

/// Index of the first value of `values` above `floor`, eight at a time
/// ([`first_where`]): the search of the vote map's maxima passes over most of the map whole.
fn first_above(values: &[u32], floor: u32) -> Option<usize> {
    first_where::<_, 8>(values, |v| v > floor)
}

/// Where the pair velocities fall in the vote map: cells of `1/inv` px/ms, the velocity
/// `(u, v)` in cell `(⌊u·inv + offset₀⌋, ⌊v·inv + offset₁⌋)` of a map `side` cells wide,
/// velocities outside the map in the cell `trash`.
#[derive(Debug, Clone, Copy)]
struct VoteMap {
    inv: f32,
    offset: [f32; 2],
    side: u32,
    trash: u32,
}

impl VoteMap {
    /// The cell of the velocity of the pair of event `(ex, ey, et)` with each later event of
    /// `others` (x, y, t), into `cells` (one per other event).
    #[inline(always)]
    fn pair_cells(
        self,
        cells: &mut [u32],
        others: (&[f32], &[f32], &[f32]),
        event: (f32, f32, f32),
    ) {
        #[cfg(target_arch = "x86_64")]
        let done = if avx2_available() {
            // SAFETY: the processor has AVX2 (`avx2_available`).
            unsafe { self.pair_cells_avx2(cells, others, event) }
        } else {
            0
        };
        #[cfg(not(target_arch = "x86_64"))]
        let done = 0;
        let (x, y, t) = others;
        let rest = (&x[done..], &y[done..], &t[done..]);
        self.pair_cells_scalar(&mut cells[done..], rest, event);
    }

    /// [`VoteMap::pair_cells`], one pair at a time.
    #[inline(always)]
    fn pair_cells_scalar(
        self,
        cells: &mut [u32],
        (x, y, t): (&[f32], &[f32], &[f32]),
        (ex, ey, et): (f32, f32, f32),
    ) {
        let (limit, side) = (self.side as f32, self.side);
        for (((cell, &x), &y), &t) in cells.iter_mut().zip(x).zip(y).zip(t) {
            let k = self.inv / (t - et);
            let (dx, dy) = (x - ex, y - ey);
            let cx = cell_index(dx * k + self.offset[0], limit);
            let cy = cell_index(dy * k + self.offset[1], limit);
            let apart = (dx.abs() >= SAME_PIXEL) | (dy.abs() >= SAME_PIXEL);
            let inside = (cx < side) & (cy < side) & apart;
            *cell = if inside {
                cy.wrapping_mul(side).wrapping_add(cx)
            } else {
                self.trash
            };
        }
    }

    /// [`VoteMap::pair_cells_scalar`] eight pairs at a time in AVX registers, the same
    /// operations per lane, so the same cells (the compiler's own vectorisation of the
    /// scalar loop came out four or two lanes wide depending on the code around it). The
    /// cell index `cy · side + cx` is formed in `f32`, exact as both are small integers
    /// (maps under 2¹¹ cells wide; wider ones are left to the scalar loop). Returns how many
    /// pairs it did (a multiple of eight); the rest is left to the scalar loop.
    ///
    /// # Safety
    /// Only where the processor has AVX2 ([`avx2_available`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn pair_cells_avx2(
        self,
        cells: &mut [u32],
        (x, y, t): (&[f32], &[f32], &[f32]),
        (ex, ey, et): (f32, f32, f32),
    ) -> usize {
        use std::arch::x86_64::*;
        const MAGIC: f32 = 12_582_912.0;
        if self.side >= 1 << 11 {
            return 0;
        }
        let n = cells.len().min(x.len()).min(y.len()).min(t.len());
        let whole = n - n % 8;
        let (inv, limit) = (_mm256_set1_ps(self.inv), _mm256_set1_ps(self.side as f32));
        let (exv, eyv, etv) = (_mm256_set1_ps(ex), _mm256_set1_ps(ey), _mm256_set1_ps(et));
        let (ox, oy) = (
            _mm256_set1_ps(self.offset[0]),
            _mm256_set1_ps(self.offset[1]),
        );
        let (half, below) = (_mm256_set1_ps(0.5), _mm256_set1_ps(-1.0));
        let (zero, magic) = (_mm256_setzero_ps(), _mm256_set1_ps(MAGIC));
        let same_pixel = _mm256_set1_ps(SAME_PIXEL);
        let trash = _mm256_set1_epi32(self.trash as i32);
        // `cell_index` per lane, as a float: `max(a, b)` is `a > b ? a : b` and `min(a, b)`
        // is `a < b ? a : b`, the comparisons of the scalar code, and the integer it rounds
        // to is `(a + MAGIC) − MAGIC`, exactly. Within the map (`cell_index` below `side`,
        // unsigned) is `0 ≤ c < side` for the values it takes, −1 to `side`.
        let index = |a: __m256| {
            let a = _mm256_min_ps(_mm256_max_ps(_mm256_sub_ps(a, half), below), limit);
            let c = _mm256_sub_ps(_mm256_add_ps(a, magic), magic);
            let inside = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(c, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(c, limit),
            );
            (c, inside)
        };
        for i in (0..whole).step_by(8) {
            // SAFETY: `i + 8 ≤ whole ≤` the length of every slice.
            let (tv, xv, yv) = unsafe {
                (
                    _mm256_loadu_ps(t.as_ptr().add(i)),
                    _mm256_loadu_ps(x.as_ptr().add(i)),
                    _mm256_loadu_ps(y.as_ptr().add(i)),
                )
            };
            let k = _mm256_div_ps(inv, _mm256_sub_ps(tv, etv));
            let (dx, dy) = (_mm256_sub_ps(xv, exv), _mm256_sub_ps(yv, eyv));
            let (cx, in_x) = index(_mm256_add_ps(_mm256_mul_ps(dx, k), ox));
            let (cy, in_y) = index(_mm256_add_ps(_mm256_mul_ps(dy, k), oy));
            // |d| ≥ SAME_PIXEL, as `max(d, −d)` (the sign bit cleared would do too).
            let far = |d: __m256| {
                let abs = _mm256_max_ps(d, _mm256_sub_ps(zero, d));
                _mm256_cmp_ps::<_CMP_GE_OQ>(abs, same_pixel)
            };
            let apart = _mm256_or_ps(far(dx), far(dy));
            let inside = _mm256_castps_si256(_mm256_and_ps(_mm256_and_ps(in_x, in_y), apart));
            let cell = _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(cy, limit), cx));
            let chosen = _mm256_blendv_epi8(trash, cell, inside);
            // SAFETY: as the loads.
            unsafe { _mm256_storeu_si256(cells.as_mut_ptr().add(i) as *mut __m256i, chosen) };
        }
        whole
    }
}

/// Histogram of the pair velocities of `events` in cells of `cell` px/ms over
/// `centre ± half` (each axis), smoothed with a binomial 3 × 3 kernel; its local maxima of
/// at least half the highest, best first and fitted to a fraction of a cell, become
/// `s.starts` (at most [`MAX_STARTS`]; none when no pair votes inside: all events at one
/// time, every pair inside one pixel, or every pair velocity outside).
pub(crate) fn vote(events: &Events, centre: [f64; 2], half: f64, cell: f64, s: &mut VoteScratch) {
    s.starts.clear();
    let (lo, hi) = events
        .t
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
    if (hi - lo).is_nan() || hi - lo <= 1e-6 {
        return;
    }
    // The events in time order, thinned evenly to at most MAX_EVENTS.
    let total = events.t.len();
    time_keys(&events.t, &mut s.keys);
    s.keys.sort_unstable();
    let kept = voters(total);
    for v in s.sorted.iter_mut() {
        v.clear();
    }
    for k in 0..kept {
        let i = index_of(s.keys[k * total / kept]);
        s.sorted[0].push(events.x[i]);
        s.sorted[1].push(events.y[i]);
        s.sorted[2].push(events.t[i]);
    }
    let gap = (hi - lo) * MIN_GAP;
    let n = (half / cell).ceil() as i64;
    let side = (2 * n + 1) as usize;
    let trash = (side * side) as u32;
    // A power of two long, so that the count loop masks its index instead of testing it;
    // every cell, `trash` included, lies below `side² + 1`, and only those are cleared.
    let used = side * side + 1;
    s.counts.resize(used.next_power_of_two(), 0);
    s.counts[..used].fill(0);
    let inv = (1.0 / cell) as f32;
    let offset = [
        n as f32 + 0.5 - centre[0] as f32 * inv,
        n as f32 + 0.5 - centre[1] as f32 * inv,
    ];
    let map = VoteMap {
        inv,
        offset,
        side: side as u32,
        trash,
    };
    let [sx, sy, st] = &s.sorted;
    s.cells.resize(kept, 0);
    let mut later = 0;
    for e in 0..kept {
        let (ex, ey, et) = (sx[e], sy[e], st[e]);
        while later < kept && st[later] < et + gap {
            later += 1;
        }
        // Cell of each pair's velocity, then the counts.
        let cells = &mut s.cells[later..];
        let others = (&sx[later..], &sy[later..], &st[later..]);
        map.pair_cells(cells, others, (ex, ey, et));
        let mask = s.counts.len() - 1;
        let counts = &mut s.counts[..=mask];
        // Four cells per turn of the loop (one pair's count is one instruction).
        let mut fours = cells.chunks_exact(4);
        for four in &mut fours {
            for &c in four {
                counts[c as usize & mask] += 1;
            }
        }
        for &c in fours.remainder() {
            counts[c as usize & mask] += 1;
        }
    }
    // Separable [1 2 1] smoothing (zero outside) into a map with a border of zeros, so that
    // neither pass nor the search of maxima needs bounds tests (vectorised row sums).
    let width = side + 2;
    s.rows.clear();
    s.rows.resize(width * side, 0);
    for j in 0..side {
        let c = &s.counts[j * side..(j + 1) * side];
        let r = &mut s.rows[j * width + 1..j * width + 1 + side];
        smooth_row(c, r);
    }
    s.smooth.clear();
    s.smooth.resize(width * width, 0);
    for j in 0..side {
        let here = &s.rows[j * width..(j + 1) * width];
        let out = &mut s.smooth[(j + 1) * width..(j + 2) * width];
        add_scaled(out, here, 2);
        if j > 0 {
            add_scaled(out, &s.rows[(j - 1) * width..j * width], 1);
        }
        if j + 1 < side {
            add_scaled(out, &s.rows[(j + 1) * width..(j + 2) * width], 1);
        }
    }
    // The highest local maxima (ties: the first in scan order), best first. A cell is
    // checked against its neighbours only if it would enter the list; the zero border never
    // disqualifies a cell above the map's minimum.
    let map = &s.smooth;
    let at = |i: usize, j: usize| (j + 1) * width + i + 1;
    let Some(min) = (0..side)
        .map(|j| s.smooth[at(0, j)..at(0, j) + side].iter().copied().min())
        .min()
        .flatten()
    else {
        return;
    };
    let maxima = &mut s.maxima;
    maxima.clear();
    let w = width;
    for j in 0..side {
        let row = &map[at(0, j)..at(0, j) + side];
        let mut i = 0;
        loop {
            let floor = if maxima.len() == MAX_STARTS {
                maxima[MAX_STARTS - 1].0 + min
            } else {
                min
            };
            // The next cell above the floor (the cells passed over would be skipped).
            let Some(k) = first_above(&row[i..], floor) else {
                break;
            };
            let col = i + k;
            i = col + 1;
            let p = at(col, j);
            let v = map[p];
            // Strictly higher neighbours, or equal ones earlier in scan order.
            let earlier = [p - w - 1, p - w, p - w + 1, p - 1];
            let later = [p + 1, p + w - 1, p + w, p + w + 1];
            if earlier.iter().any(|&q| map[q] >= v) || later.iter().any(|&q| map[q] > v) {
                continue;
            }
            let rank = maxima.partition_point(|m| m.0 >= v - min);
            maxima.insert(rank, (v - min, j * side + col));
            maxima.truncate(MAX_STARTS);
        }
    }
    let Some(best) = maxima.first().map(|m| m.0 as f64) else {
        return;
    };
    for &(v, index) in maxima.iter().take(MAX_STARTS) {
        if (v as f64) < START_FRACTION * best {
            break;
        }
        let (i, j) = (index % side, index / side);
        let value = |ii: usize, jj: usize| map[at(ii, jj)] as f64;
        let fit = |a: f64, b: f64, c: f64| {
            let d = 2.0 * a - 4.0 * b + 2.0 * c;
            if d < 0.0 {
                ((a - c) / d).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        };
        let dx = if i > 0 && i + 1 < side {
            fit(value(i - 1, j), value(i, j), value(i + 1, j))
        } else {
            0.0
        };
        let dy = if j > 0 && j + 1 < side {
            fit(value(i, j - 1), value(i, j), value(i, j + 1))
        } else {
            0.0
        };
        s.starts.push([
            centre[0] + (i as f64 + dx - n as f64) * cell,
            centre[1] + (j as f64 + dy - n as f64) * cell,
        ]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::xorshift;

    /// Sorted keys give the events in `total_cmp` order of their times, every index once,
    /// equal times by scrambled index: negative and positive times, both zeros, subnormals,
    /// the extremes, infinities and NaNs of both signs.
    #[test]
    fn time_keys_sort_as_total_cmp_then_scrambled_index() {
        let mut next = xorshift(3);
        for n in [0, 1, 2, 7, 100, 1000] {
            let t: Vec<f32> = (0..n)
                .map(|_| match next() % 14 {
                    0 => -0.0,
                    1 => 0.0,
                    2 => f32::INFINITY,
                    3 => f32::NEG_INFINITY,
                    4 => f32::NAN,
                    5 => -f32::NAN,
                    6 => f32::from_bits(0x7F80_0001),
                    7 => f32::from_bits(1),
                    8 => -f32::from_bits(1),
                    9 => f32::MAX,
                    10 => f32::MIN,
                    k => (next() % 41) as f32 * 0.25 - 5.0 + k as f32 * 1e-3,
                })
                .collect();
            let mut keys = Vec::new();
            time_keys(&t, &mut keys);
            keys.sort_unstable();
            let fast: Vec<usize> = keys.iter().map(|&k| index_of(k)).collect();
            let mut slow: Vec<usize> = (0..n).collect();
            let tie = |i: usize| (i as u32).wrapping_mul(TIE_SCRAMBLE);
            slow.sort_by(|&a, &b| t[a].total_cmp(&t[b]).then(tie(a).cmp(&tie(b))));
            assert_eq!(fast, slow, "n = {n}");
            // Equal times are not in index order: the scramble mixes them.
            if n == 1000 {
                let mut plain: Vec<usize> = (0..n).collect();
                plain.sort_by(|&a, &b| t[a].total_cmp(&t[b]).then(a.cmp(&b)));
                assert_ne!(fast, plain);
            }
        }
    }

    /// The row pass equals the [1 2 1] stencil with zeros outside, and the chunked search
    /// the plain one, for every length up to past two chunks.
    #[test]
    fn smoothing_and_search_equal_their_definitions() {
        let mut rng = xorshift(5);
        let mut next = move || (rng() % 7) as u32;
        for n in 0..40 {
            let c: Vec<u32> = (0..n).map(|_| next()).collect();
            let mut out = vec![u32::MAX; n];
            smooth_row(&c, &mut out);
            let at = |i: isize| {
                if (0..n as isize).contains(&i) {
                    c[i as usize]
                } else {
                    0
                }
            };
            let expected: Vec<u32> = (0..n as isize)
                .map(|i| at(i - 1) + 2 * at(i) + at(i + 1))
                .collect();
            assert_eq!(out, expected, "n = {n}");
            for floor in 0..8 {
                let plain = c.iter().position(|&v| v > floor);
                assert_eq!(first_above(&c, floor), plain, "n = {n}, floor {floor}");
            }
        }
    }

    /// The cells of the eight-lane AVX2 build (where the processor has it) are the scalar
    /// loop's, bit for bit: random pairs, pairs at the
    /// same time (infinite and NaN velocities), pairs far outside the map, and maps of
    /// several sizes and offsets.
    #[test]
    fn vectorised_pair_cells_equal_the_scalar_ones() {
        let mut rng = xorshift(0x1234_5678_9abc_def0);
        let mut uniform = move || (rng() >> 40) as f32 / (1u64 << 24) as f32;
        for (side, inv, offset) in [
            (33u32, 4.0f32, [16.5f32, 16.5]),
            (9, 1.0, [4.5, 3.0]),
            (65, 16.0, [-3.2, 70.1]),
        ] {
            let map = VoteMap {
                inv,
                offset,
                side,
                trash: side * side,
            };
            let n = 203;
            let x: Vec<f32> = (0..n).map(|_| uniform() * 60.0 - 10.0).collect();
            let y: Vec<f32> = (0..n).map(|_| uniform() * 60.0 - 10.0).collect();
            let mut t: Vec<f32> = (0..n).map(|_| uniform() * 10.0 - 5.0).collect();
            t[3] = 1.25;
            t[10] = f32::NAN;
            for event in [(20.0, 20.0, 1.25), (0.0, 59.0, -5.0), (13.7, -2.5, 4.9)] {
                let (mut fast, mut slow) = (vec![0u32; n], vec![0u32; n]);
                map.pair_cells(&mut fast, (&x, &y, &t), event);
                map.pair_cells_scalar(&mut slow, (&x, &y, &t), event);
                #[cfg(target_arch = "x86_64")]
                if avx2_available() {
                    // The AVX2 build does all but the last `n % 8` pairs.
                    let mut eight = vec![0u32; n];
                    // SAFETY: the processor has AVX2.
                    let done = unsafe { map.pair_cells_avx2(&mut eight, (&x, &y, &t), event) };
                    assert_eq!(done, n - n % 8);
                    assert_eq!(eight[..done], slow[..done]);
                }
                assert_eq!(fast, slow, "side {side}, event {event:?}");
                assert!(slow.iter().any(|&c| c < map.trash) && slow.contains(&map.trash));
            }
        }
    }
}
