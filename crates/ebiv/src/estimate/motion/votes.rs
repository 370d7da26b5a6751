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

/// Events voting at most (≈ 5 800 pairs); beyond, the events are thinned evenly in time.
const MAX_EVENTS: usize = 144;
/// Pairs closer in time than this fraction of the window's time span do not vote: their
/// velocity is too uncertain (a 1 px position error over 2.5 ms of a 10 ms slab is
/// 0.4 px/ms).
const MIN_GAP: f32 = 0.25;
/// Starts returned at most.
pub(crate) const MAX_STARTS: usize = 3;
/// Local maxima below this fraction of the highest are not returned as starts.
const START_FRACTION: f64 = 0.5;

/// Working memory of the vote.
#[derive(Debug, Clone, Default)]
pub(crate) struct VoteScratch {
    order: Vec<u32>,
    sorted: [Vec<f32>; 3],
    cells: Vec<u32>,
    counts: Vec<u32>,
    rows: Vec<u32>,
    smooth: Vec<u32>,
    maxima: Vec<(u32, usize)>,
    /// Starts of the last vote, best first.
    pub starts: Vec<[f64; 2]>,
}

/// Outcome of a vote: the starts are in [`VoteScratch::starts`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Vote {
    /// First-to-second local maximum ratio of the smoothed map, both above its minimum
    /// (NaN without a second maximum).
    pub ratio: f64,
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

/// Histogram of the pair velocities of `events` in cells of `cell` px/ms over
/// `centre ± half` (each axis), smoothed with a binomial 3 × 3 kernel; its local maxima of
/// at least half the highest, best first and fitted to a fraction of a cell, become
/// `s.starts` (at most [`MAX_STARTS`]). `None` when no pair votes inside (all events at
/// one time, or every pair velocity outside).
pub(crate) fn vote(
    events: &Events,
    centre: [f64; 2],
    half: f64,
    cell: f64,
    s: &mut VoteScratch,
) -> Option<Vote> {
    s.starts.clear();
    let (lo, hi) = events
        .t
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
    if (hi - lo).is_nan() || hi - lo <= 1e-6 {
        return None;
    }
    // The events in time order, thinned evenly to at most MAX_EVENTS.
    let total = events.t.len();
    s.order.clear();
    s.order.extend(0..total as u32);
    s.order
        .sort_unstable_by(|&a, &b| events.t[a as usize].total_cmp(&events.t[b as usize]));
    let kept = total.min(MAX_EVENTS);
    for v in s.sorted.iter_mut() {
        v.clear();
    }
    for k in 0..kept {
        let i = s.order[k * total / kept] as usize;
        s.sorted[0].push(events.x[i]);
        s.sorted[1].push(events.y[i]);
        s.sorted[2].push(events.t[i]);
    }
    let gap = (hi - lo) * MIN_GAP;
    let n = (half / cell).ceil() as i64;
    let side = (2 * n + 1) as usize;
    let trash = (side * side) as u32;
    s.counts.clear();
    s.counts.resize(side * side + 1, 0);
    let inv = (1.0 / cell) as f32;
    let offset = [
        n as f32 + 0.5 - centre[0] as f32 * inv,
        n as f32 + 0.5 - centre[1] as f32 * inv,
    ];
    let limit = side as f32;
    let [sx, sy, st] = &s.sorted;
    s.cells.resize(kept, 0);
    let mut later = 0;
    for e in 0..kept {
        let (ex, ey, et) = (sx[e], sy[e], st[e]);
        while later < kept && st[later] < et + gap {
            later += 1;
        }
        // Cell of each pair's velocity (straight-line code the compiler vectorises), then
        // the counts.
        let cells = &mut s.cells[later..];
        let pairs = cells
            .iter_mut()
            .zip(&sx[later..])
            .zip(&sy[later..])
            .zip(&st[later..]);
        for (((cellref, &x), &y), &t) in pairs {
            let k = inv / (t - et);
            let cx = cell_index((x - ex) * k + offset[0], limit);
            let cy = cell_index((y - ey) * k + offset[1], limit);
            let inside = (cx < side as u32) & (cy < side as u32);
            *cellref = if inside {
                cy.wrapping_mul(side as u32).wrapping_add(cx)
            } else {
                trash
            };
        }
        let counts = &mut s.counts[..];
        for &c in cells.iter() {
            counts[c as usize] += 1;
        }
    }
    // Separable [1 2 1] smoothing (zero outside) into a map with a border of zeros, so that
    // neither pass nor the search of maxima needs bounds tests (vectorised row sums).
    let width = side + 2;
    s.rows.clear();
    s.rows.resize(width * side, 0);
    for j in 0..side {
        let c = &s.counts[j * side..(j + 1) * side];
        let r = &mut s.rows[j * width..(j + 1) * width];
        r[1..side + 1].copy_from_slice(c);
        let mut left = 0;
        for i in 0..side {
            let centre = r[i + 1];
            let right = if i + 1 < side { c[i + 1] } else { 0 };
            r[i + 1] = left + 2 * centre + right;
            left = centre;
        }
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
    let min = (0..side)
        .map(|j| s.smooth[at(0, j)..at(0, j) + side].iter().copied().min())
        .min()
        .flatten()?;
    let maxima = &mut s.maxima;
    maxima.clear();
    let w = width;
    for j in 0..side {
        for i in 0..side {
            let p = at(i, j);
            let v = map[p];
            let floor = if maxima.len() == MAX_STARTS {
                maxima[MAX_STARTS - 1].0 + min
            } else {
                min
            };
            if v <= floor {
                continue;
            }
            // Strictly higher neighbours, or equal ones earlier in scan order.
            let earlier = [p - w - 1, p - w, p - w + 1, p - 1];
            let later = [p + 1, p + w - 1, p + w, p + w + 1];
            if earlier.iter().any(|&q| map[q] >= v) || later.iter().any(|&q| map[q] > v) {
                continue;
            }
            let rank = maxima.partition_point(|m| m.0 >= v - min);
            maxima.insert(rank, (v - min, j * side + i));
            maxima.truncate(MAX_STARTS);
        }
    }
    if maxima.is_empty() {
        return None;
    }
    let best = maxima[0].0 as f64;
    let ratio = maxima.get(1).map_or(f64::NAN, |m| best / m.0.max(1) as f64);
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
    Some(Vote { ratio })
}
