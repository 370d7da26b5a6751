//! The events of one time slab, binned once into square tiles so that an interrogation
//! window gathers its events in time proportional to their number, not to the slab's.
//!
//! The reference code selects each window's events with a mask over the whole recording
//! (O(N) per window; algorithms.md §3); here a slab is sorted by tile once (counting sort,
//! O(N)) and kept in time order inside each tile, so a window visits only the tiles it
//! overlaps and finds its time range there by binary search.

use crate::deform::events::Deformation;
use crate::event::{Geometry, PolaritySelection};
use crate::grid::Window;

mod lone_pixels;

/// Events of a window in local coordinates, ready for an estimator.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WindowEvents {
    /// Column relative to the window's left edge, px (pixel centres at integers).
    pub x: Vec<f32>,
    /// Row relative to the window's top edge, px.
    pub y: Vec<f32>,
    /// Time relative to the reference time given to [`Slab::gather`], µs.
    pub t: Vec<f32>,
}

impl WindowEvents {
    /// Number of events.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True if there are no events.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Remove all events, keeping the allocations.
    pub fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
        self.t.clear();
    }
}

/// Indices of `t` that can hold times in `[start_us, end_us)`, and whether `t` is in time
/// order: found by binary search when it is (as readers deliver it, apart from rare EVT 3.0
/// time regressions), otherwise all of them.
fn candidate_range(t: &[i64], start_us: i64, end_us: i64) -> (std::ops::Range<usize>, bool) {
    if in_time_order(t) {
        let from = t.partition_point(|&v| v < start_us);
        (from..t.partition_point(|&v| v < end_us).max(from), true)
    } else {
        (0..t.len(), false)
    }
}

/// `v / d` for any `v < 2¹⁶` as a multiplication and a shift, which vectorises where the
/// division and a table lookup do not: with `m = ⌈2³²/d⌉ = 2³²/d + e`, `0 ≤ e < 1`,
/// `v·m/2³² = v/d + v·e/2³²` exceeds `v/d` by less than `2⁻¹⁶ ≤ 1/d` (for `d ≤ 2¹⁶`), too
/// little to reach the next integer; for `d > 2¹⁶` both sides are 0.
#[derive(Debug, Clone, Copy)]
struct Divider {
    m: u64,
}

impl Divider {
    fn new(d: u32) -> Self {
        Divider {
            m: (1u64 << 32).div_ceil(u64::from(d.max(1))),
        }
    }

    #[inline(always)]
    fn divide(self, v: u16) -> u32 {
        ((u64::from(v) * self.m) >> 32) as u32
    }
}

/// The filter of [`Slab::build`]: the tile of each event, or `skipped`.
struct TileClassifier {
    start_us: i64,
    end_us: i64,
    width: u32,
    height: u32,
    tile: Divider,
    tiles_x: u32,
    polarity: PolaritySelection,
    skipped: u32,
}

impl TileClassifier {
    /// The tile of every event of the columns (cut to the shortest), in the AVX2 build
    /// where the processor has it ([`crate::simd`]): its 64-bit time comparisons run four
    /// lanes wide (a slab build then takes 30 % fewer instructions, callgrind).
    fn classify(&self, t: &[i64], x: &[u16], y: &[u16], p: &[u8]) -> Vec<u32> {
        if crate::simd::avx2_available() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the processor has AVX2 (`avx2_available`).
            return unsafe { self.classify_avx2(t, x, y, p) };
        }
        self.classify_portable(t, x, y, p)
    }

    /// [`TileClassifier::classify_portable`] compiled for AVX2.
    ///
    /// # Safety
    /// Only where the processor has AVX2 ([`crate::simd::avx2_available`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn classify_avx2(&self, t: &[i64], x: &[u16], y: &[u16], p: &[u8]) -> Vec<u32> {
        self.classify_portable(t, x, y, p)
    }

    /// [`TileClassifier::classify`] in straight-line code that the compiler vectorises: no
    /// branch, no lookup.
    #[inline(always)]
    fn classify_portable(&self, t: &[i64], x: &[u16], y: &[u16], p: &[u8]) -> Vec<u32> {
        let n = t.len().min(x.len()).min(y.len()).min(p.len());
        let (t, x, y, p) = (&t[..n], &x[..n], &y[..n], &p[..n]);
        let (accept_off, accept_on) = (self.polarity.accepts(0), self.polarity.accepts(1));
        let mut tiles = vec![0u32; n];
        for i in 0..n {
            let (xi, yi) = (u32::from(x[i]), u32::from(y[i]));
            let accepted = if p[i] != 0 { accept_on } else { accept_off };
            let keep = (t[i] >= self.start_us)
                & (t[i] < self.end_us)
                & (xi < self.width)
                & (yi < self.height)
                & accepted;
            // (Wrapping: an event outside the sensor may give a meaningless index, masked.)
            let tile = (self.tile.divide(y[i]).wrapping_mul(self.tiles_x))
                .wrapping_add(self.tile.divide(x[i]));
            // A select by mask (`if` here compiled to a branch).
            let mask = u32::from(keep).wrapping_neg();
            tiles[i] = tile & mask | self.skipped & !mask;
        }
        tiles
    }
}

/// Whether `t` is in time order, in the AVX2 build where the processor has it (SSE2 has no
/// 64-bit comparison; AVX2 compares four times per instruction).
fn in_time_order(t: &[i64]) -> bool {
    /// A branch-free fold, so the check costs about one compare per event.
    #[inline(always)]
    fn fold(t: &[i64]) -> bool {
        t.windows(2).fold(true, |ok, w| ok & (w[0] <= w[1]))
    }
    /// [`fold`] compiled for AVX2.
    ///
    /// # Safety
    /// Only where the processor has AVX2 ([`crate::simd::avx2_available`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn fold_avx2(t: &[i64]) -> bool {
        fold(t)
    }
    if crate::simd::avx2_available() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the processor has AVX2 (`avx2_available`).
        return unsafe { fold_avx2(t) };
    }
    fold(t)
}

/// The events of one tile with time in an interval, in slab coordinates (sensor pixels) and
/// times (µs), as [`Slab::visit_runs`] delivers them: three columns of equal length.
#[derive(Debug, Clone, Copy)]
pub struct TileRun<'a> {
    pub x: &'a [u16],
    pub y: &'a [u16],
    pub t: &'a [i64],
}

/// What [`Slab::visit_runs`] delivers the events to.
pub trait TileVisitor {
    /// The events of a tile inside the window: all of them are visited.
    fn run(&mut self, events: TileRun<'_>);
    /// One event inside the window, from a tile that reaches past it: local column and row,
    /// time relative to the reference time.
    fn event(&mut self, x: i64, y: i64, t: i64);
}

/// Events of the time interval `[start_us, end_us)` over the whole sensor, grouped by tile.
#[derive(Debug, Clone)]
pub struct Slab {
    start_us: i64,
    end_us: i64,
    tile: u32,
    tiles_x: u32,
    tiles_y: u32,
    /// Offsets of each tile's events; tile `k` holds `tile_start[k]..tile_start[k + 1]`.
    tile_start: Vec<usize>,
    x: Vec<u16>,
    y: Vec<u16>,
    t: Vec<i64>,
    /// Events removed by [`Slab::drop_lone_pixels`].
    lone_pixel_events: usize,
}

impl Slab {
    /// Bin the events of `[start_us, end_us)` with the selected polarity into tiles of
    /// `tile` × `tile` px. Events outside the geometry are ignored. The arrays are the
    /// struct-of-arrays columns of an [`crate::EventBuffer`] (in file order; time order is
    /// restored within each tile if needed).
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        t: &[i64],
        x: &[u16],
        y: &[u16],
        p: &[u8],
        geometry: Geometry,
        start_us: i64,
        end_us: i64,
        polarity: PolaritySelection,
        tile: u32,
    ) -> Slab {
        let tile = tile.max(1);
        let tiles_x = geometry.width.div_ceil(tile).max(1);
        let tiles_y = geometry.height.div_ceil(tile).max(1);
        // (In usize: a 65 536 × 65 536 header with 1 px tiles overflows u32.)
        let n_tiles = tiles_x as usize * tiles_y as usize;
        let n = t.len().min(x.len()).min(y.len()).min(p.len());
        let (candidates, sorted) = candidate_range(&t[..n], start_us, end_us);
        // Tile of every candidate; events outside the interval, the sensor or the polarity
        // selection go to an extra last bucket, `skipped`. The filter runs once, and neither
        // it nor the passes below branch on an event: with both polarities recorded, half of
        // the events are left out in an unpredictable pattern, and a branch per event cost
        // about one misprediction per two events (callgrind's branch simulation).
        let skipped = n_tiles as u32;
        let r = candidates.clone();
        let tiles = TileClassifier {
            start_us,
            end_us,
            // (Coordinates are u16: no more columns or rows than that, whatever a header
            // declares.)
            width: geometry.width.min(1 << 16),
            height: geometry.height.min(1 << 16),
            tile: Divider::new(tile),
            tiles_x,
            polarity,
            skipped,
        }
        .classify(&t[r.clone()], &x[r.clone()], &y[r.clone()], &p[r]);
        // Bucket sizes, then their offsets: bucket `k` starts at `counts[k]`.
        let mut counts = vec![0usize; n_tiles + 2];
        for &k in &tiles {
            counts[k as usize + 1] += 1;
        }
        for k in 0..=n_tiles {
            counts[k + 1] += counts[k];
        }
        let total = counts[n_tiles];
        // Every skipped event is written to the one slot past the kept ones (its bucket's
        // fill never advances), then cut off: no branch, and no room held for them.
        let mut fill = counts.clone();
        let (mut sx, mut sy, mut st) = (
            vec![0u16; total + 1],
            vec![0u16; total + 1],
            vec![0i64; total + 1],
        );
        let r = candidates.clone();
        let events = tiles
            .iter()
            .zip(&x[r.clone()])
            .zip(&y[r.clone()])
            .zip(&t[r]);
        for (((&k, &xi), &yi), &ti) in events {
            // `k ≤ skipped` and `at ≤ total`: the clamps, which change nothing, spare the
            // bounds tests.
            let k = (k as usize).min(n_tiles);
            let at = fill[k].min(total);
            fill[k] += usize::from(k != n_tiles);
            sx[at] = xi;
            sy[at] = yi;
            st[at] = ti;
        }
        sx.truncate(total);
        sy.truncate(total);
        st.truncate(total);
        counts.truncate(n_tiles + 1);
        let mut slab = Slab {
            start_us,
            end_us,
            tile,
            tiles_x,
            tiles_y,
            tile_start: counts,
            x: sx,
            y: sy,
            t: st,
            lone_pixel_events: 0,
        };
        // Tiles of events in time order are in time order.
        if !sorted {
            slab.restore_time_order();
        }
        // The binary searches of `visit_runs` (and `visit`), and the binning that trusts what
        // they deliver, need every tile in time order.
        debug_assert!(slab.tile_start.windows(2).all(|k| {
            let times = &slab.t[k[0]..k[1]];
            times.windows(2).all(|p| p[0] <= p[1])
        }));
        slab
    }

    /// Sort each tile by time where the input was not in time order (rare: EVT 3.0 time
    /// regressions are passed through by the readers).
    fn restore_time_order(&mut self) {
        for k in 0..self.tile_start.len() - 1 {
            let r = self.tile_start[k]..self.tile_start[k + 1];
            if self.t[r.clone()].windows(2).all(|w| w[0] <= w[1]) {
                continue;
            }
            let mut order: Vec<usize> = r.clone().collect();
            order.sort_by_key(|&i| self.t[i]);
            let (x, y, t): (Vec<u16>, Vec<u16>, Vec<i64>) = (
                order.iter().map(|&i| self.x[i]).collect(),
                order.iter().map(|&i| self.y[i]).collect(),
                order.iter().map(|&i| self.t[i]).collect(),
            );
            self.x[r.clone()].copy_from_slice(&x);
            self.y[r.clone()].copy_from_slice(&y);
            self.t[r].copy_from_slice(&t);
        }
    }

    /// Start of the slab's time interval, µs.
    pub fn start_us(&self) -> i64 {
        self.start_us
    }

    /// End (exclusive) of the slab's time interval, µs.
    pub fn end_us(&self) -> i64 {
        self.end_us
    }

    /// Times of the earliest and the latest event in the slab, µs; `None` if it is empty.
    /// (Each tile is in time order, so this looks at the ends of the tiles only.)
    pub fn event_span_us(&self) -> Option<(i64, i64)> {
        let tiles = self.tile_start.windows(2).filter(|k| k[1] > k[0]);
        tiles.fold(None, |span, k| {
            let (first, last) = (self.t[k[0]], self.t[k[1] - 1]);
            Some(span.map_or((first, last), |(a, b): (i64, i64)| {
                (a.min(first), b.max(last))
            }))
        })
    }

    /// Events of lone persistent pixels removed from the slab ([`Slab::drop_lone_pixels`]).
    pub fn lone_pixel_events(&self) -> usize {
        self.lone_pixel_events
    }

    /// Number of events in the slab.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True if the slab holds no events.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Append to `out` the events inside `window` with time in `[t_from, t_to)` (clipped to
    /// the slab), in local coordinates relative to the window's top-left pixel and to
    /// `t_ref_us`. Parts of the window beyond the sensor simply hold no events.
    pub fn gather(
        &self,
        window: &Window,
        t_from: i64,
        t_to: i64,
        t_ref_us: i64,
        out: &mut WindowEvents,
    ) {
        self.visit(window, t_from, t_to, t_ref_us, |x, y, t| {
            out.x.push(x as f32);
            out.y.push(y as f32);
            out.t.push(t as f32);
        });
    }

    /// Call `f(x, y, t)` for every event [`Slab::gather`] would append, without copying:
    /// local column and row, time relative to `t_ref_us`.
    pub fn visit(
        &self,
        window: &Window,
        t_from: i64,
        t_to: i64,
        t_ref_us: i64,
        f: impl FnMut(i64, i64, i64),
    ) {
        /// Every event through `f`, in local coordinates.
        struct EachEvent<F> {
            f: F,
            origin: [i64; 3],
        }
        impl<F: FnMut(i64, i64, i64)> TileVisitor for EachEvent<F> {
            #[inline(always)]
            fn run(&mut self, run: TileRun<'_>) {
                let [x0, y0, t0] = self.origin;
                for ((&x, &y), &t) in run.x.iter().zip(run.y).zip(run.t) {
                    (self.f)(x as i64 - x0, y as i64 - y0, t - t0);
                }
            }
            #[inline(always)]
            fn event(&mut self, x: i64, y: i64, t: i64) {
                (self.f)(x, y, t)
            }
        }
        let origin = [window.x0, window.y0, t_ref_us];
        self.visit_runs(
            window,
            (t_from, t_to),
            t_ref_us,
            &mut EachEvent { f, origin },
        );
    }

    /// The events [`Slab::visit`] visits, a tile at a time: [`TileVisitor::run`] with the
    /// events of a tile inside the window (as the tiles of windows on a grid of half-window
    /// steps are), in slab coordinates and times, which need no test per event;
    /// [`TileVisitor::event`] (local column and row, time relative to `t_ref_us`) for each
    /// event inside the window of a tile that reaches past it. A visitor of runs loops over
    /// plain slices, its own state in registers rather than reloaded per event as through a
    /// closure.
    pub fn visit_runs(
        &self,
        window: &Window,
        (t_from, t_to): (i64, i64),
        t_ref_us: i64,
        visitor: &mut impl TileVisitor,
    ) {
        let x_end = window.x0 + window.width as i64;
        let y_end = window.y0 + window.height as i64;
        let Some((tx0, tx1)) = self.tile_span(window.x0, x_end, self.tiles_x) else {
            return;
        };
        let Some((ty0, ty1)) = self.tile_span(window.y0, y_end, self.tiles_y) else {
            return;
        };
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let k = (ty * self.tiles_x + tx) as usize;
                let (a, b) = (self.tile_start[k], self.tile_start[k + 1]);
                let times = &self.t[a..b];
                let lo = a + times.partition_point(|&t| t < t_from);
                // (An empty interval, `t_to < t_from`, gives no events.)
                let hi = (a + times.partition_point(|&t| t < t_to)).max(lo);
                let events = TileRun {
                    x: &self.x[lo..hi],
                    y: &self.y[lo..hi],
                    t: &self.t[lo..hi],
                };
                let tile = self.tile as i64;
                let (left, top) = (tx as i64 * tile, ty as i64 * tile);
                let covered = left >= window.x0
                    && left + tile <= x_end
                    && top >= window.y0
                    && top + tile <= y_end;
                if covered {
                    visitor.run(events);
                    continue;
                }
                for ((&x, &y), &t) in events.x.iter().zip(events.y).zip(events.t) {
                    let (x, y) = (x as i64, y as i64);
                    if x >= window.x0 && x < x_end && y >= window.y0 && y < y_end {
                        visitor.event(x - window.x0, y - window.y0, t - t_ref_us);
                    }
                }
            }
        }
    }

    /// Like [`Slab::gather`], then move every event against the non-uniform part of the
    /// predicted motion (`deformation`), so that the events of a sheared or rotating flow
    /// look as if all moved with the velocity at the window centre; see [`Deformation`].
    pub fn gather_deformed(
        &self,
        window: &Window,
        t_from: i64,
        t_to: i64,
        t_ref_us: i64,
        deformation: &Deformation,
        out: &mut WindowEvents,
    ) {
        let first = out.len();
        self.gather(window, t_from, t_to, t_ref_us, out);
        let offset_ms = (t_ref_us - deformation.t0_us) as f64 / 1000.0;
        // Window-local position of the deformation centre.
        let cx = deformation.centre[0] - window.x0 as f64;
        let cy = deformation.centre[1] - window.y0 as f64;
        // The events' largest |dt| and offset from the centre bound the paths' truncation.
        // Event times lie within the slab as well as in [t_from, t_to).
        let (from, to) = (t_from.max(self.start_us), t_to.min(self.end_us));
        let max_dt_ms = [from, to]
            .map(|t| (t.saturating_sub(deformation.t0_us) as f64 / 1000.0).abs())
            .into_iter()
            .fold(0.0, f64::max);
        let reach = [cx, cy, window.width as f64 - cx, window.height as f64 - cy]
            .into_iter()
            .fold(0.0f64, |r, e| r.max(e.abs()));
        let paths = deformation.paths(max_dt_ms, reach);
        for i in first..out.len() {
            let d = [out.x[i] as f64 - cx, out.y[i] as f64 - cy];
            let dt_ms = out.t[i] as f64 / 1000.0 + offset_ms;
            let moved = paths.undeform(d, dt_ms);
            out.x[i] = (moved[0] + cx) as f32;
            out.y[i] = (moved[1] + cy) as f32;
        }
    }

    /// Number of events inside `window` with time in `[t_from, t_to)`.
    pub fn count(&self, window: &Window, t_from: i64, t_to: i64) -> usize {
        let mut n = 0;
        self.visit(window, t_from, t_to, 0, |_, _, _| n += 1);
        n
    }

    /// First and last tile index overlapping the pixel range `[from, to)`, if any.
    fn tile_span(&self, from: i64, to: i64, tiles: u32) -> Option<(u32, u32)> {
        let limit = tiles as i64 * self.tile as i64;
        let (from, to) = (from.max(0), to.min(limit));
        (from < to).then(|| {
            (
                (from / self.tile as i64) as u32,
                ((to - 1) / self.tile as i64) as u32,
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute_force(
        ev: &[(i64, u16, u16, u8)],
        w: &Window,
        t_from: i64,
        t_to: i64,
        slab: (i64, i64),
        polarity: PolaritySelection,
    ) -> Vec<(i64, i64, i64)> {
        let mut v: Vec<_> = ev
            .iter()
            .filter(|e| e.0 >= slab.0 && e.0 < slab.1 && e.0 >= t_from && e.0 < t_to)
            .filter(|e| match polarity {
                PolaritySelection::Positive => e.3 != 0,
                PolaritySelection::Negative => e.3 == 0,
                PolaritySelection::Both => true,
            })
            .filter(|e| {
                let (x, y) = (e.1 as i64, e.2 as i64);
                x >= w.x0 && x < w.x0 + w.width as i64 && y >= w.y0 && y < w.y0 + w.height as i64
            })
            .map(|e| (e.0, e.1 as i64 - w.x0, e.2 as i64 - w.y0))
            .collect();
        v.sort();
        v
    }

    /// The `size` × `size` window at the sensor's top-left corner.
    fn square_window(size: u32) -> Window {
        Window {
            x0: 0,
            y0: 0,
            width: size,
            height: size,
        }
    }

    #[test]
    fn deformation_removes_a_velocity_gradient() {
        // Two events of a shear flow u = 0.1·(y − 10): one at y = 20 (u = 1) seen 2 ms after
        // t0 (moved 2 px), one at y = 0 (u = −1) seen 2 ms after t0 (moved −2 px).
        let t = [2000i64, 2000];
        let x = [12u16, 8];
        let y = [20u16, 0];
        let p = [1u8, 1];
        let slab = Slab::build(
            &t,
            &x,
            &y,
            &p,
            Geometry::new(32, 32),
            0,
            5000,
            PolaritySelection::Both,
            8,
        );
        let window = square_window(32);
        let d = Deformation {
            centre: [10.0, 10.0],
            velocity: [0.0, 0.0],
            gradient: [[0.0, 0.1], [0.0, 0.0]],
            t0_us: 0,
        };
        let mut out = WindowEvents::default();
        slab.gather_deformed(&window, 0, 5000, 0, &d, &mut out);
        let mut xs = out.x.clone();
        xs.sort_by(f32::total_cmp);
        // Both now appear to have moved with the centre's velocity 0: back at x = 10.
        assert!(
            (xs[0] - 10.0).abs() < 1e-5 && (xs[1] - 10.0).abs() < 1e-5,
            "{xs:?}"
        );
    }

    /// Odd intervals give empty or whole slabs, never a panic: a reversed interval, and a
    /// deformed gather over all of time.
    #[test]
    fn reversed_and_unbounded_intervals() {
        let (t, x, y, p) = ([10i64, 20, 30], [1u16, 2, 3], [1u16, 2, 3], [1u8, 1, 1]);
        let geometry = Geometry::new(8, 8);
        let reversed = Slab::build(&t, &x, &y, &p, geometry, 25, 15, PolaritySelection::Both, 4);
        assert!(reversed.is_empty());
        let slab = Slab::build(&t, &x, &y, &p, geometry, 0, 100, PolaritySelection::Both, 4);
        let window = square_window(8);
        let d = Deformation {
            centre: [4.0, 4.0],
            velocity: [1.0, 0.0],
            gradient: [[0.0, -0.02], [0.02, 0.0]],
            t0_us: 20,
        };
        let mut out = WindowEvents::default();
        slab.gather_deformed(&window, i64::MIN, i64::MAX, 20, &d, &mut out);
        assert_eq!(out.len(), 3);
        assert!(out.x.iter().chain(&out.y).all(|v| v.is_finite()));
        // A reversed interval around the events of a tile holds none (and does not panic).
        let mut reversed_window = WindowEvents::default();
        slab.gather(&window, 25, 15, 0, &mut reversed_window);
        assert_eq!(reversed_window.len(), 0);
        assert_eq!(slab.count(&window, 25, 15), 0);
    }

    #[test]
    fn the_divider_divides_every_coordinate_exactly() {
        let divisors = (1..=300).chain([511, 512, 1000, 4095, 4096, 65_535, 65_536, 65_537]);
        for d in divisors.chain([u32::MAX]) {
            let divider = Divider::new(d);
            for v in 0..=u16::MAX {
                assert_eq!(divider.divide(v), u32::from(v) / d, "{v} / {d}");
            }
        }
    }

    #[test]
    fn both_builds_of_the_filter_give_the_tiles_of_the_definition() {
        // Times around the interval, coordinates up to u16::MAX (outside the sensor, where
        // the tile arithmetic wraps), all polarity values, all selections.
        let n = 1000;
        let mut state = 7u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 33) as u32
        };
        let t: Vec<i64> = (0..n).map(|_| i64::from(next() % 1200) - 100).collect();
        let x: Vec<u16> = (0..n)
            .map(|i| {
                if i % 7 == 0 {
                    u16::MAX - next() as u16 % 8
                } else {
                    (next() % 1300) as u16
                }
            })
            .collect();
        let y: Vec<u16> = (0..n)
            .map(|i| {
                if i % 11 == 0 {
                    u16::MAX
                } else {
                    (next() % 730) as u16
                }
            })
            .collect();
        let p: Vec<u8> = (0..n).map(|_| (next() % 3) as u8).collect();
        for polarity in [
            PolaritySelection::Positive,
            PolaritySelection::Negative,
            PolaritySelection::Both,
        ] {
            for tile in [1, 7, 20, 64, 1000] {
                let (width, height) = (1280u32, 720u32);
                let tiles_x = width.div_ceil(tile);
                let skipped = tiles_x * height.div_ceil(tile);
                let classifier = TileClassifier {
                    start_us: 0,
                    end_us: 1000,
                    width,
                    height,
                    tile: Divider::new(tile),
                    tiles_x,
                    polarity,
                    skipped,
                };
                let expected: Vec<u32> = (0..n)
                    .map(|i| {
                        let (xi, yi) = (u32::from(x[i]), u32::from(y[i]));
                        let inside = (0..1000).contains(&t[i]) && xi < width && yi < height;
                        if inside && polarity.accepts(p[i]) {
                            yi / tile * tiles_x + xi / tile
                        } else {
                            skipped
                        }
                    })
                    .collect();
                assert_eq!(classifier.classify_portable(&t, &x, &y, &p), expected);
                assert_eq!(classifier.classify(&t, &x, &y, &p), expected);
            }
        }
    }

    proptest! {
        #[test]
        fn gather_matches_brute_force(
            ev in prop::collection::vec((0i64..1000, 0u16..70, 0u16..50, 0u8..2), 0..400),
            x0 in -20i64..80, y0 in -20i64..60, w in 1u32..40, h in 1u32..40,
            t_from in -10i64..1000, dt in 0i64..1000, tile in 1u32..20, selection in 0usize..3,
        ) {
            let polarity = [
                PolaritySelection::Positive,
                PolaritySelection::Negative,
                PolaritySelection::Both,
            ][selection];
            // In file order (any) and in time order, where the slab's time range is found
            // by binary search.
            let mut sorted = ev.clone();
            sorted.sort_by_key(|e| e.0);
            for ev in [ev, sorted] {
                let t: Vec<i64> = ev.iter().map(|e| e.0).collect();
                let x: Vec<u16> = ev.iter().map(|e| e.1).collect();
                let y: Vec<u16> = ev.iter().map(|e| e.2).collect();
                let p: Vec<u8> = ev.iter().map(|e| e.3).collect();
                let slab = Slab::build(&t, &x, &y, &p, Geometry::new(64, 48), 100, 900,
                    polarity, tile);
                let window = Window { x0, y0, width: w, height: h };
                let mut out = WindowEvents::default();
                slab.gather(&window, t_from, t_from + dt, 50, &mut out);
                let mut got: Vec<(i64, i64, i64)> = (0..out.len())
                    .map(|i| (out.t[i] as i64 + 50, out.x[i] as i64, out.y[i] as i64))
                    .collect();
                got.sort();
                // Events outside the 64×48 geometry are ignored by the slab.
                let inside: Vec<_> = ev.iter().copied().filter(|e| e.1 < 64 && e.2 < 48).collect();
                let expected = brute_force(&inside, &window, t_from, t_from + dt, (100, 900), polarity);
                prop_assert_eq!(&got, &expected);
                prop_assert_eq!(slab.count(&window, t_from, t_from + dt), got.len());
            }
        }
    }
}
