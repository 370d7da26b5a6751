//! Voxelisation of a sub-volume into per-slice occupancy lists, slice statistics and the
//! overlap normalisation shared by both correlation kernels.
//!
//! Events are binned into one occupancy bitmap per time slice (a bit per pixel, rows of
//! 64-bit words), so that a voxel holding several events costs nothing extra and reading the
//! bitmaps back yields each slice's voxels already sorted by row and column, which the direct
//! kernel uses to visit only the rows within its search radius.

use crate::volume::TileRun;
#[cfg(test)]
use crate::volume::WindowEvents;

/// Window size and search radius: the correlation plane holds the lags
/// `dx ∈ [−rx, rx]`, `dy ∈ [−ry, ry]`, row-major, `(2rx + 1) × (2ry + 1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct PlaneShape {
    pub w: usize,
    pub h: usize,
    pub rx: usize,
    pub ry: usize,
}

impl PlaneShape {
    pub fn plane_width(&self) -> usize {
        2 * self.rx + 1
    }

    pub fn plane_height(&self) -> usize {
        2 * self.ry + 1
    }
}

/// Non-empty voxels of consecutive time slices, grouped by slice (slice `z` holds
/// `start[z]..start[z + 1]`) and sorted by row, then column, within a slice.
#[derive(Debug, Clone, Default)]
pub(super) struct Voxels {
    pub x: Vec<u16>,
    pub y: Vec<u16>,
    pub v: Vec<f64>,
    pub start: Vec<usize>,
    /// Events binned into each slice.
    pub slice_events: Vec<usize>,
    /// Every value is 1 (binary occupancy), so that products with values and sums of values
    /// can be left out or counted, exactly.
    pub unit: bool,
}

impl Voxels {
    /// All slices, as one sub-volume.
    pub fn all(&self) -> SubVolume<'_> {
        SubVolume {
            vox: self,
            first: 0,
            slices: self.slice_events.len(),
        }
    }

    /// `slices` consecutive slices from `first` (which must exist).
    pub fn sub_volume(&self, first: usize, slices: usize) -> SubVolume<'_> {
        debug_assert!(first + slices <= self.slice_events.len());
        SubVolume {
            vox: self,
            first,
            slices,
        }
    }
}

/// A run of consecutive slices of [`Voxels`]: one sub-volume (S1 or S2) of the estimator.
/// When both sub-volumes share their pixels (no window offset) and the delay is a whole
/// number of slices, S1 and S2 are two overlapping runs of the same voxelisation.
#[derive(Debug, Clone, Copy)]
pub(super) struct SubVolume<'a> {
    pub vox: &'a Voxels,
    first: usize,
    slices: usize,
}

impl SubVolume<'_> {
    /// Number of slices.
    pub fn slices(&self) -> usize {
        self.slices
    }

    /// Indices into `vox.x`, `vox.y`, `vox.v` of slice `z` of this sub-volume.
    pub fn range(&self, z: usize) -> std::ops::Range<usize> {
        self.vox.start[self.first + z]..self.vox.start[self.first + z + 1]
    }

    pub fn len(&self, z: usize) -> usize {
        self.range(z).len()
    }

    /// Events that went into the voxels of this sub-volume.
    pub fn events(&self) -> usize {
        self.vox.slice_events[self.first..self.first + self.slices]
            .iter()
            .sum()
    }
}

/// Longest sub-volume whose slice of every µs is tabulated.
const TABLE_US: i64 = 1 << 16;

/// Bins events into per-slice occupancy bitmaps and reads them back as [`Voxels`]. The
/// bitmaps are all zero between uses (reading clears them), so nothing is cleared per window.
#[derive(Debug, Clone)]
pub(super) struct Voxeliser {
    w: usize,
    h: usize,
    /// 64-bit words per bitmap row.
    words: usize,
    bits: Vec<u64>,
    /// Events per voxel, `[slice][row][column]`, only with count weighting.
    counts: Vec<u16>,
    /// Rows holding any event, a bit per row, `row_words` words per slice.
    rows: Vec<u64>,
    row_words: usize,
    slab_us: i64,
    /// `N_T / T`, per µs.
    slices_per_us: f64,
    /// The slice of every µs of the sub-volume, for sub-volumes up to [`TABLE_US`] long.
    slice_table: Vec<u16>,
    slices: usize,
    count: bool,
    slice_events: Vec<usize>,
    /// Sub-pixel mode ([`Voxeliser::add_splat`]): the splat weights of the voxels,
    /// `[slice][row][column]`, and the occupancy bitmaps and row masks of the pixels they
    /// reach (`bits` and `rows` then only deduplicate the voxels).
    weights: Vec<f64>,
    target_bits: Vec<u64>,
    target_rows: Vec<u64>,
    splat: bool,
}

/// The slicing of a sub-volume: `N` slices of a `T` µs long sub-volume.
#[derive(Debug, Clone, Copy)]
struct SliceTiming {
    slab_us: i64,
    slices: usize,
    slices_per_us: f64,
}

impl SliceTiming {
    fn of(v: &Voxeliser) -> Self {
        SliceTiming {
            slab_us: v.slab_us,
            slices: v.slices,
            slices_per_us: v.slices_per_us,
        }
    }

    /// `⌊t·N/T⌋` exactly (integer arithmetic: the f64 estimate is off by at most one).
    fn slice_by_arithmetic(self, time: i64) -> usize {
        let n = self.slices as i64;
        let scaled = time * n;
        let mut z = (time as f64 * self.slices_per_us) as i64;
        if (z + 1) * self.slab_us <= scaled {
            z += 1;
        } else if z * self.slab_us > scaled {
            z -= 1;
        }
        z.clamp(0, n - 1) as usize
    }
}

impl Voxeliser {
    pub fn new(w: usize, h: usize) -> Self {
        Voxeliser {
            w,
            h,
            words: w.div_ceil(64).max(1),
            bits: Vec::new(),
            counts: Vec::new(),
            rows: Vec::new(),
            row_words: h.div_ceil(64).max(1),
            slab_us: 1,
            slices_per_us: 1.0,
            slice_table: Vec::new(),
            slices: 1,
            count: false,
            slice_events: Vec::new(),
            weights: Vec::new(),
            target_bits: Vec::new(),
            target_rows: Vec::new(),
            splat: false,
        }
    }

    /// Start binning a sub-volume of `slab_us` µs cut into `slices` slices, with binary (or,
    /// with `count`, counted) voxels.
    pub fn begin(&mut self, slab_us: i64, slices: usize, count: bool) {
        let (slab_us, slices) = (slab_us.max(1), slices.max(1));
        // The same slice length (N/T) gives the same ⌊tN/T⌋: a table as long as `slab_us`
        // serves both the shared and the separate binning of a run.
        let same_length = slices as i64 * self.slab_us == self.slices as i64 * slab_us;
        let covered = same_length && slab_us as usize <= self.slice_table.len();
        if covered {
            self.slab_us = slab_us;
            self.slices = slices;
        } else if (slab_us, slices) != (self.slab_us, self.slices) || self.slice_table.is_empty() {
            self.slab_us = slab_us;
            self.slices = slices;
            self.slices_per_us = slices as f64 / slab_us as f64;
            self.slice_table.clear();
            if slab_us <= TABLE_US && slices <= usize::from(u16::MAX) {
                // ⌊tN/T⌋ = z for t from ⌈zT/N⌉ up to ⌈(z + 1)T/N⌉, filled slice by slice.
                let n = slices as i64;
                let first_us = |z: i64| ((z * slab_us + n - 1) / n) as usize;
                self.slice_table.resize(slab_us as usize, 0);
                for z in 1..n {
                    let end = first_us(z + 1).min(slab_us as usize);
                    self.slice_table[first_us(z)..end].fill(z as u16);
                }
                debug_assert!(self
                    .slice_table
                    .iter()
                    .enumerate()
                    .all(|(t, &z)| usize::from(z) == self.slice_by_arithmetic(t as i64)));
            }
        }
        self.count = count;
        let (bitmap, row_masks, voxels) = self.buffer_sizes();
        grow(&mut self.bits, bitmap);
        grow(&mut self.rows, row_masks);
        if count {
            grow(&mut self.counts, voxels);
        }
        self.slice_events.clear();
        self.slice_events.resize(self.slices, 0);
        self.splat = false;
    }

    /// Like [`Voxeliser::begin`], for voxels placed at the sub-pixel positions of their
    /// events ([`Voxeliser::add_splat`]).
    pub fn begin_splat(&mut self, slab_us: i64, slices: usize, count: bool) {
        self.begin(slab_us, slices, count);
        self.splat = true;
        let (bitmap, row_masks, voxels) = self.buffer_sizes();
        grow(&mut self.target_bits, bitmap);
        grow(&mut self.target_rows, row_masks);
        grow(&mut self.weights, voxels);
    }

    /// Lengths of the bitmaps, the row masks and the per-voxel arrays of the current
    /// sub-volume.
    fn buffer_sizes(&self) -> (usize, usize, usize) {
        let per_slice = |n: usize| self.slices * n;
        (
            per_slice(self.h * self.words),
            per_slice(self.row_words),
            per_slice(self.h * self.w),
        )
    }

    /// Bin one event at the sub-pixel local position `(x, y)`, time `t` µs after the
    /// sub-volume start, into a voxeliser started with [`Voxeliser::begin_splat`]. The voxel
    /// is the event's nearest pixel, as in [`Voxeliser::add`] (binary: the first event of a
    /// voxel stands for all of them), but its value is spread over the 3 × 3 pixels around
    /// it with the weights of [`shift_taps`] for the offset of `(x, y)` from the pixel
    /// centre: the occupancy image resampled at positions shifted by a fraction of a pixel,
    /// as PIV window deformation resamples its images (Scarano 2002, Meas. Sci. Technol.
    /// 13:R1), so that a predicted displacement is removed exactly instead of to the
    /// nearest pixel. Weights falling outside the window are dropped. With count weighting
    /// every event is spread from its own position, so a voxel's total weight is its event
    /// count.
    #[inline]
    pub fn add_splat(&mut self, x: f32, y: f32, t: f32) {
        let (xf, yf) = (x + 0.5, y + 0.5);
        if !(xf >= 0.0 && yf >= 0.0 && t >= 0.0) {
            return;
        }
        let (col, row, time) = (xf as usize, yf as usize, t as i64);
        if col >= self.w || row >= self.h || !(0..self.slab_us).contains(&time) {
            return;
        }
        let z = self.slice_of(time);
        self.slice_events[z] += 1;
        let line = (z * self.h + row) * self.words;
        let bit = 1u64 << (col % 64);
        if !self.count && self.bits[line + col / 64] & bit != 0 {
            return;
        }
        self.bits[line + col / 64] |= bit;
        self.rows[z * self.row_words + row / 64] |= 1u64 << (row % 64);
        let wx = shift_taps(f64::from(x) - col as f64);
        let wy = shift_taps(f64::from(y) - row as f64);
        let (col, row) = (col as isize - 1, row as isize - 1);
        for (dy, wy) in (0..).zip(wy) {
            for (dx, wx) in (0..).zip(wx) {
                self.put(z, col + dx, row + dy, wx * wy);
            }
        }
    }

    /// Bin one event at local position `(x, y)` (rounded to the nearest pixel: the identity
    /// for raw events, rounding for deformed ones) and time `t` µs after the sub-volume start.
    /// Events outside the window or the sub-volume (or NaN) are ignored.
    #[inline]
    pub fn add(&mut self, x: f32, y: f32, t: f32) {
        let (xf, yf) = (x + 0.5, y + 0.5);
        // For non-negative values truncation is the floor; NaN fails the comparisons and
        // huge values saturate beyond the window.
        if xf >= 0.0 && yf >= 0.0 && t >= 0.0 {
            self.add_pixel(xf as usize, yf as usize, t as i64);
        }
    }

    /// Bin one event at pixel `(col, row)` of the window and time `time` µs after the
    /// sub-volume start; ignored outside the window or the sub-volume.
    #[inline(always)]
    pub fn add_pixel(&mut self, col: usize, row: usize, time: i64) {
        if col >= self.w || row >= self.h || !(0..self.slab_us).contains(&time) {
            return;
        }
        let z = self.slice_of(time);
        self.slice_events[z] += 1;
        self.rows[z * self.row_words + row / 64] |= 1u64 << (row % 64);
        let line = (z * self.h + row) * self.words;
        self.bits[line + col / 64] |= 1u64 << (col % 64);
        if self.count {
            let c = &mut self.counts[(z * self.h + row) * self.w + col];
            *c = c.saturating_add(1);
        }
    }

    /// True if rows and row masks are a single word each (window of at most 64 × 64 px),
    /// where [`Voxeliser::add_narrow_inside`] and [`Voxeliser::add_narrow_run`] may be used.
    pub fn is_narrow(&self) -> bool {
        self.words == 1 && self.row_words == 1
    }

    /// [`Voxeliser::add_pixel`] for a narrow window ([`Voxeliser::is_narrow`]) and an event
    /// known to lie in the window and the sub-volume (`col < w`, `row < h`, `0 ≤ time < T`),
    /// as [`crate::volume::Slab::visit_runs`] delivers them for the window and interval binned
    /// (one by one from the tiles that reach past the window):
    /// no test per event, and `COUNT` (the voxeliser's count weighting) fixed at compile
    /// time. The bitmap row and the row mask are single words, found without the word
    /// arithmetic. (The tests and the weighting's branch were about a quarter of the
    /// binning's instructions, callgrind.)
    #[inline(always)]
    pub fn add_narrow_inside<const COUNT: bool>(&mut self, col: usize, row: usize, time: i64) {
        debug_assert!(self.is_narrow() && COUNT == self.count);
        debug_assert!(col < self.w && row < self.h && (0..self.slab_us).contains(&time));
        let z = self.slice_of(time);
        self.slice_events[z] += 1;
        // `col < w ≤ 64` and `row < h ≤ 64`.
        self.rows[z] |= 1u64 << row;
        self.bits[z * self.h + row] |= 1u64 << col;
        if COUNT {
            let c = &mut self.counts[(z * self.h + row) * self.w + col];
            *c = c.saturating_add(1);
        }
    }

    /// [`Voxeliser::add_narrow_inside`] for every event of `run` (slab coordinates and
    /// times; `origin` the window's top-left pixel and the sub-volume's start), all known to
    /// lie in the window and the sub-volume, as [`crate::volume::Slab::visit_runs`] delivers
    /// a tile inside the window. The same voxels in the same order; the loop works on the
    /// arrays as local slices, so that their addresses stay in registers, and the slice of
    /// an event comes from the table alone where it covers the sub-volume.
    #[inline(always)]
    pub fn add_narrow_run<const COUNT: bool>(&mut self, run: TileRun<'_>, origin: [i64; 3]) {
        debug_assert!(self.is_narrow() && COUNT == self.count);
        let timing = SliceTiming::of(self);
        if self.slice_table.len() >= timing.slab_us as usize {
            let table = std::mem::take(&mut self.slice_table);
            self.bin_run::<COUNT>(run, origin, |time| usize::from(table[time as usize]));
            self.slice_table = table;
        } else {
            self.bin_run::<COUNT>(run, origin, |time| timing.slice_by_arithmetic(time));
        }
    }

    /// The loop of [`Voxeliser::add_narrow_run`], `slice_of(time)` the slice of a time.
    #[inline(always)]
    fn bin_run<const COUNT: bool>(
        &mut self,
        run: TileRun<'_>,
        [x0, y0, t0]: [i64; 3],
        slice_of: impl Fn(i64) -> usize,
    ) {
        let (w, h, slab_us) = (self.w, self.h, self.slab_us);
        let slice_events = &mut self.slice_events[..];
        let (rows, bits, counts) = (&mut self.rows[..], &mut self.bits[..], &mut self.counts[..]);
        for ((&x, &y), &t) in run.x.iter().zip(run.y).zip(run.t) {
            let (col, row, time) = ((x as i64 - x0) as usize, (y as i64 - y0) as usize, t - t0);
            debug_assert!(col < w && row < h && (0..slab_us).contains(&time));
            let z = slice_of(time);
            slice_events[z] += 1;
            // `col < w ≤ 64` and `row < h ≤ 64`.
            rows[z] |= 1u64 << row;
            bits[z * h + row] |= 1u64 << col;
            if COUNT {
                let c = &mut counts[(z * h + row) * w + col];
                *c = c.saturating_add(1);
            }
        }
    }

    /// The slice of `time` µs (in `[0, T)`): `⌊t·N/T⌋`.
    #[inline(always)]
    fn slice_of(&self, time: i64) -> usize {
        match self.slice_table.get(time as usize) {
            Some(&z) => usize::from(z),
            None => self.slice_by_arithmetic(time),
        }
    }

    /// `⌊t·N/T⌋` exactly ([`SliceTiming::slice_by_arithmetic`]).
    fn slice_by_arithmetic(&self, time: i64) -> usize {
        SliceTiming::of(self).slice_by_arithmetic(time)
    }

    /// Add `weight` to pixel `(c, r)` of slice `z` (splat mode), unless it lies outside the
    /// window or the weight is zero.
    #[inline(always)]
    fn put(&mut self, z: usize, c: isize, r: isize, weight: f64) {
        if c < 0 || r < 0 || c as usize >= self.w || r as usize >= self.h || weight <= 0.0 {
            return;
        }
        let (c, r) = (c as usize, r as usize);
        self.weights[(z * self.h + r) * self.w + c] += weight;
        self.target_bits[(z * self.h + r) * self.words + c / 64] |= 1u64 << (c % 64);
        self.target_rows[z * self.row_words + r / 64] |= 1u64 << (r % 64);
    }

    /// Read the bitmaps back into `out` (clearing them), visiting only rows that hold events.
    pub fn finish(&mut self, out: &mut Voxels) {
        if self.splat {
            // Clear the deduplication bitmaps, then read the splatted pixels back.
            for z in 0..self.slices {
                for rw in 0..self.row_words {
                    let mut mask = std::mem::take(&mut self.rows[z * self.row_words + rw]);
                    while mask != 0 {
                        let row = rw * 64 + mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let line = (z * self.h + row) * self.words;
                        self.bits[line..line + self.words].fill(0);
                    }
                }
            }
            std::mem::swap(&mut self.bits, &mut self.target_bits);
            std::mem::swap(&mut self.rows, &mut self.target_rows);
            self.read_back(out, true);
            std::mem::swap(&mut self.bits, &mut self.target_bits);
            std::mem::swap(&mut self.rows, &mut self.target_rows);
            self.splat = false;
        } else {
            self.read_back(out, false);
        }
    }

    /// Read the occupancy bitmaps (and counts or, `splatted`, weights) into `out`, clearing
    /// them: first the positions, then the values.
    fn read_back(&mut self, out: &mut Voxels, splatted: bool) {
        self.read_positions(out, splatted);
        out.v.clear();
        out.unit = !splatted && !self.count;
        if splatted {
            self.read_values(out, |v, at| std::mem::take(&mut v.weights[at]));
        } else if self.count {
            self.read_values(out, |v, at| f64::from(std::mem::take(&mut v.counts[at])));
        } else {
            // Binary occupancy: every voxel is 1.
            out.v.resize(out.x.len(), 1.0);
        }
    }

    /// Read the occupancy bitmaps into the positions and slice starts of `out`, clearing
    /// them. Positions are written by index into buffers long enough for every event to
    /// have a voxel of its own (up to 9 pixels per event `splatted`), then cut to length:
    /// no capacity check and length update per voxel, as pushes would cost.
    fn read_positions(&mut self, out: &mut Voxels, splatted: bool) {
        let (h, words, row_words) = (self.h, self.words, self.row_words);
        let events: usize = self.slice_events.iter().sum();
        let bound = if splatted { 9 * events } else { events };
        // Room for the narrow path's second write past the last voxel.
        grow(&mut out.x, bound + 1);
        grow(&mut out.y, bound + 1);
        out.start.clear();
        out.start.push(0);
        out.slice_events.clone_from(&self.slice_events);
        let (xs, ys) = (&mut out.x[..], &mut out.y[..]);
        let mut n = 0;
        if self.is_narrow() {
            // One word per bitmap row and per row mask: no loops over words.
            for (z, mask) in self.rows[..self.slices].iter_mut().enumerate() {
                let mut mask = std::mem::take(mask);
                while mask != 0 {
                    let row = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let mut word = std::mem::take(&mut self.bits[z * h + row]);
                    // Two voxels per step, whether or not the row holds a second (its
                    // column is then past the window and `n` does not count it): most rows
                    // of a slice hold one or two, so the loop rarely turns and its exit
                    // branch, taken after a varying number of voxels, is rarely
                    // mispredicted.
                    while word != 0 {
                        let rest = word & (word - 1);
                        xs[n] = word.trailing_zeros() as u16;
                        xs[n + 1] = rest.trailing_zeros() as u16;
                        ys[n] = row as u16;
                        ys[n + 1] = row as u16;
                        n += 1 + usize::from(rest != 0);
                        word = rest & rest.wrapping_sub(1);
                    }
                }
                out.start.push(n);
            }
            out.x.truncate(n);
            out.y.truncate(n);
            return;
        }
        for z in 0..self.slices {
            for rw in 0..row_words {
                let mut mask = std::mem::take(&mut self.rows[z * row_words + rw]);
                while mask != 0 {
                    let row = rw * 64 + mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let line = (z * h + row) * words;
                    for (k, word) in self.bits[line..line + words].iter_mut().enumerate() {
                        let mut word = std::mem::take(word);
                        while word != 0 {
                            let col = k * 64 + word.trailing_zeros() as usize;
                            word &= word - 1;
                            xs[n] = col as u16;
                            ys[n] = row as u16;
                            n += 1;
                        }
                    }
                }
            }
            out.start.push(n);
        }
        out.x.truncate(n);
        out.y.truncate(n);
    }

    /// Append to `out.v` the value of every voxel of `out` (as read by
    /// [`Voxeliser::read_positions`]), taken by `take` from the voxeliser's buffers at the
    /// voxel's index `[slice][row][column]`.
    fn read_values(&mut self, out: &mut Voxels, mut take: impl FnMut(&mut Self, usize) -> f64) {
        let (w, h) = (self.w, self.h);
        for z in 0..self.slices {
            let range = out.start[z]..out.start[z + 1];
            let positions = out.x[range.clone()].iter().zip(&out.y[range]);
            out.v.extend(
                positions.map(|(&x, &y)| take(self, (z * h + usize::from(y)) * w + usize::from(x))),
            );
        }
    }

    /// Bin `events` (local coordinates, time relative to the sub-volume start) into `out`.
    #[cfg(test)]
    pub fn run(
        &mut self,
        events: &WindowEvents,
        slab_us: i64,
        slices: u32,
        count: bool,
        out: &mut Voxels,
    ) {
        self.begin(slab_us, slices as usize, count);
        for ((&x, &y), &t) in events.x.iter().zip(&events.y).zip(&events.t) {
            self.add(x, y, t);
        }
        self.finish(out);
    }
}

/// Lengthen `buffer` with zeros to at least `len` (never shortened: the buffers are reused by
/// windows of every size and stay zero where unused).
fn grow<T: Default + Clone>(buffer: &mut Vec<T>, len: usize) {
    if buffer.len() < len {
        buffer.resize(len, T::default());
    }
}

/// Weights of the pixels `−1, 0, +1` for a point at offset `a` (|a| ≤ ½) from the centre
/// pixel, per axis ([`Voxeliser::add_splat`]): non-negative, summing to 1, with mean `a` and
/// no third central moment, i.e. `w±1 = (s ± a)/2`, `w0 = 1 − s`, `s = (1 + 2a²)/3`
/// (at `a = 0` the sampled cubic B-spline, 1/6, 2/3, 1/6; at `a = ±½` the bilinear weights).
///
/// The skewness matters: the cross-correlation of two images resampled by kernels `k1`
/// and `k2` is the original one convolved with `k2 ⋆ k1`, whose third cumulant is the
/// difference of theirs; with the symmetric split the two shifts are opposite and the
/// skews add. Bilinear weights (skewness `a(1 − a)(1 − 2a)` for a fraction `a` from the
/// lower pixel) then tilt the summed peak, and the peak fit converges to a displacement off
/// by a fraction of the shift: measured +0.009 px/ms bias (0.4 %) on a uniform flow of
/// (2.17, 0.83) px/ms, 64 → 32 px, against −0.002 with these weights.
pub(super) fn shift_taps(a: f64) -> [f64; 3] {
    let s = (1.0 + 2.0 * a * a) / 3.0;
    [(s - a) / 2.0, 1.0 - s, (s + a) / 2.0]
}

/// Statistics of one slice pair with data in both sub-volumes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SliceStats {
    pub z: usize,
    pub mean_a: f64,
    pub mean_b: f64,
    /// `1 / (σ_a σ_b)`, population standard deviations over the window.
    pub weight: f64,
}

/// Slices where both occupancy images vary (neither empty nor full): they contribute to the
/// sum; the others contribute nothing and are not counted.
pub(super) fn slice_statistics(
    a: SubVolume<'_>,
    b: SubVolume<'_>,
    shape: PlaneShape,
    out: &mut Vec<SliceStats>,
) {
    out.clear();
    let pixels = (shape.w * shape.h) as f64;
    for z in 0..a.slices().min(b.slices()) {
        if a.len(z) == 0 || b.len(z) == 0 {
            continue;
        }
        let (mean_a, var_a) = moments(a, z, pixels);
        let (mean_b, var_b) = moments(b, z, pixels);
        let floor = 1e-12 * (1.0 + mean_a * mean_a + mean_b * mean_b);
        if var_a > floor && var_b > floor {
            out.push(SliceStats {
                z,
                mean_a,
                mean_b,
                weight: 1.0 / (var_a * var_b).sqrt(),
            });
        }
    }
}

/// Mean and population variance over the `pixels` pixels of the window of slice `z` of `v`
/// (its voxels, zero elsewhere). Inlined: called twice per slice, the call costs as much as
/// the moments of binary voxels.
#[inline(always)]
fn moments(v: SubVolume<'_>, z: usize, pixels: f64) -> (f64, f64) {
    let (s, s2) = if v.vox.unit {
        // Sums of ones: the count, exactly.
        let n = v.len(z) as f64;
        (n, n)
    } else {
        v.vox.v[v.range(z)]
            .iter()
            .fold((0.0, 0.0), |(s, s2), &x| (s + x, s2 + x * x))
    };
    let mean = s / pixels;
    (mean, s2 / pixels - mean * mean)
}

/// The overlap area `n(Δ) = (W − |dx|)(H − |dy|)` of every lag of a plane, and its
/// reciprocal: dividing by it gives the unbiased linear correlation (no bias toward zero
/// displacement).
#[derive(Debug, Clone)]
pub(super) struct Overlap {
    pub area: Vec<f64>,
    pub inverse: Vec<f64>,
}

impl Overlap {
    pub fn new(shape: PlaneShape) -> Self {
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        let area: Vec<f64> = (0..pw * ph)
            .map(|i| {
                let oy = shape.h - (i / pw).abs_diff(shape.ry);
                let ox = shape.w - (i % pw).abs_diff(shape.rx);
                (ox * oy) as f64
            })
            .collect();
        let inverse = area.iter().map(|a| 1.0 / a).collect();
        Overlap { area, inverse }
    }

    /// Turn the summed covariance numerators into correlation coefficients: divide each lag
    /// by its overlap area and by the number of contributing slices.
    pub fn normalise(&self, plane: &mut [f64], slices: usize) {
        let per_slice = 1.0 / slices.max(1) as f64;
        for (p, inverse) in plane.iter_mut().zip(&self.inverse) {
            *p *= inverse * per_slice;
        }
    }
}

#[cfg(test)]
mod slice_table_tests {
    use super::{shift_taps, Voxeliser, Voxels};
    use crate::volume::WindowEvents;

    #[test]
    fn shift_taps_keep_mean_and_have_no_skew() {
        for k in 0..=20 {
            let a = -0.5 + k as f64 / 20.0;
            let w = shift_taps(a);
            let moment = |p: i32| {
                (-1..=1)
                    .zip(w)
                    .map(|(x, w)| (x as f64 - a).powi(p) * w)
                    .sum::<f64>()
            };
            assert!(w.iter().all(|&w| w >= 0.0), "{a}: {w:?}");
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{a}: {w:?}");
            assert!(moment(1).abs() < 1e-12, "{a}: mean off by {}", moment(1));
            assert!(moment(3).abs() < 1e-12, "{a}: skewness {}", moment(3));
        }
        assert_eq!(shift_taps(0.5), [0.0, 0.5, 0.5]);
    }

    #[test]
    fn splatted_voxels_sit_at_their_sub_pixel_position() {
        // Three events of one pixel and slice (binary: one voxel), shifted by (0.3, −0.2) px:
        // the weights sum to 1 and their centroid is the shifted position.
        let events = WindowEvents {
            x: vec![4.3; 3],
            y: vec![2.8; 3],
            t: vec![1.0, 2.0, 3.0],
        };
        let mut v = Voxeliser::new(8, 6);
        let mut out = Voxels::default();
        for round in 0..2 {
            v.begin_splat(100, 2, false);
            for ((&x, &y), &t) in events.x.iter().zip(&events.y).zip(&events.t) {
                v.add_splat(x, y, t);
            }
            v.finish(&mut out);
            assert_eq!(out.slice_events, [3, 0], "round {round}");
            assert_eq!(out.x.len(), 9, "round {round}");
            let total: f64 = out.v.iter().sum();
            let cx: f64 = out
                .x
                .iter()
                .zip(&out.v)
                .map(|(&x, v)| f64::from(x) * v)
                .sum();
            let cy: f64 = out
                .y
                .iter()
                .zip(&out.v)
                .map(|(&y, v)| f64::from(y) * v)
                .sum();
            assert!((total - 1.0).abs() < 1e-9, "{total}");
            assert!(
                (cx - 4.3).abs() < 1e-6 && (cy - 2.8).abs() < 1e-6,
                "({cx}, {cy})"
            );
        }
        // The plain voxeliser afterwards sees cleared bitmaps.
        v.begin(100, 2, false);
        v.add(1.0, 1.0, 60.0);
        v.finish(&mut out);
        assert_eq!(
            (out.x.as_slice(), out.y.as_slice(), out.v.as_slice()),
            (&[1u16][..], &[1u16][..], &[1.0][..])
        );
    }

    #[test]
    fn tabulated_slices_equal_the_arithmetic() {
        let mut v = Voxeliser::new(8, 8);
        for (slab_us, slices) in [(10_000, 20), (13_000, 26), (997, 13), (7, 7), (1000, 1)] {
            v.begin(slab_us, slices, false);
            assert_eq!(v.slice_table.len(), slab_us as usize);
            for t in 0..slab_us {
                assert_eq!(
                    v.slice_of(t),
                    v.slice_by_arithmetic(t),
                    "{slab_us} {slices} {t}"
                );
            }
        }
    }
}
