//! Voxelisation of a sub-volume into per-slice occupancy lists, slice statistics and the
//! overlap normalisation shared by both correlation kernels.

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

/// Non-empty voxels of one sub-volume, grouped by slice: slice `z` holds
/// `start[z]..start[z + 1]`.
#[derive(Debug, Clone, Default)]
pub(super) struct Voxels {
    pub x: Vec<u16>,
    pub y: Vec<u16>,
    pub v: Vec<f64>,
    pub start: Vec<usize>,
    /// Events that went into the voxels.
    pub events: usize,
}

impl Voxels {
    pub fn range(&self, z: usize) -> std::ops::Range<usize> {
        self.start[z]..self.start[z + 1]
    }

    pub fn len(&self, z: usize) -> usize {
        self.start[z + 1] - self.start[z]
    }
}

/// Reusable buffers for [`Voxeliser::run`]: a generation stamp per pixel marks voxels
/// already seen in the current slice, so nothing is cleared between slices or windows.
#[derive(Debug, Clone)]
pub(super) struct Voxeliser {
    w: usize,
    h: usize,
    stamp: Vec<u32>,
    slot: Vec<u32>,
    generation: u32,
    slice: Vec<u32>,
    order: Vec<u32>,
    counts: Vec<usize>,
}

impl Voxeliser {
    pub fn new(w: usize, h: usize) -> Self {
        Voxeliser {
            w,
            h,
            stamp: vec![0; w * h],
            slot: vec![0; w * h],
            generation: 0,
            slice: Vec::new(),
            order: Vec::new(),
            counts: Vec::new(),
        }
    }

    /// Bin `events` (local coordinates, time relative to the sub-volume start, in
    /// `[0, slab_us)`) into `slices` slices of binary (or, with `count`, counted) voxels.
    pub fn run(
        &mut self,
        events: &WindowEvents,
        slab_us: i64,
        slices: u32,
        count: bool,
        out: &mut Voxels,
    ) {
        let n_slices = slices as usize;
        out.x.clear();
        out.y.clear();
        out.v.clear();
        out.start.clear();
        out.events = 0;
        self.slice.clear();
        self.slice.reserve(events.len());
        self.counts.clear();
        self.counts.resize(n_slices + 1, 0);
        let (w, h) = (self.w, self.h);
        let slab = slab_us as f64;
        let last = n_slices - 1;
        let (xs, ys, ts) = (&events.x, &events.y, &events.t);
        let n = ts.len().min(xs.len()).min(ys.len());
        for i in 0..n {
            // Nearest pixel: identity for raw events, rounding for deformed ones. For
            // `xf ≥ 0` truncation is the floor; NaN fails the comparison.
            let (xf, yf) = (xs[i] + 0.5, ys[i] + 0.5);
            let t = ts[i] as f64;
            let inside = xf >= 0.0 && yf >= 0.0 && (xf as usize) < w && (yf as usize) < h;
            if !inside || !(0.0..slab).contains(&t) {
                self.slice.push(u32::MAX);
                continue;
            }
            // ⌊t·N / T⌋ in f64 is exact: the dividend is an integer below 2⁵³ and
            // T·N < 2⁵³, so a non-integral quotient never rounds up to the next integer.
            let z = (((t as i64 * slices as i64) as f64 / slab) as usize).min(last);
            self.slice.push(z as u32);
            self.counts[z + 1] += 1;
        }
        for z in 0..n_slices {
            self.counts[z + 1] += self.counts[z];
        }
        out.events = self.counts[n_slices];
        self.order.clear();
        self.order.resize(out.events, 0);
        // Counting sort by slice: `counts[z]` advances as slice z fills; the sorted entries
        // are the pixel coordinates packed as `y << 16 | x`.
        for (i, &z) in self.slice.iter().enumerate() {
            if z != u32::MAX {
                let at = &mut self.counts[z as usize];
                let (x, y) = ((xs[i] + 0.5) as u32, (ys[i] + 0.5) as u32);
                self.order[*at] = (y << 16) | x;
                *at += 1;
            }
        }
        out.x.reserve(out.events);
        out.y.reserve(out.events);
        out.v.reserve(out.events);
        out.start.reserve(n_slices + 1);
        let mut first = 0usize;
        out.start.push(0);
        for z in 0..n_slices {
            let end = self.counts[z];
            self.next_generation();
            let generation = self.generation;
            for &xy in &self.order[first..end] {
                let (x, y) = ((xy & 0xffff) as usize, (xy >> 16) as usize);
                let pixel = y * w + x;
                if self.stamp[pixel] != generation {
                    self.stamp[pixel] = generation;
                    self.slot[pixel] = out.v.len() as u32;
                    out.x.push(x as u16);
                    out.y.push(y as u16);
                    out.v.push(1.0);
                } else if count {
                    out.v[self.slot[pixel] as usize] += 1.0;
                }
            }
            first = end;
            out.start.push(out.v.len());
        }
    }

    fn next_generation(&mut self) {
        if self.generation == u32::MAX {
            self.stamp.fill(0);
            self.generation = 0;
        }
        self.generation += 1;
    }
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
    a: &Voxels,
    b: &Voxels,
    shape: PlaneShape,
    out: &mut Vec<SliceStats>,
) {
    out.clear();
    let pixels = (shape.w * shape.h) as f64;
    let moments = |v: &Voxels, z: usize| {
        let (s, s2) = v.v[v.range(z)]
            .iter()
            .fold((0.0, 0.0), |(s, s2), &x| (s + x, s2 + x * x));
        let mean = s / pixels;
        (mean, s2 / pixels - mean * mean)
    };
    for z in 0..a.start.len().saturating_sub(1) {
        if a.len(z) == 0 || b.len(z) == 0 {
            continue;
        }
        let (mean_a, var_a) = moments(a, z);
        let (mean_b, var_b) = moments(b, z);
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

/// Turn the summed covariance numerators into correlation coefficients: divide each lag by
/// its overlap area `(W − |dx|)(H − |dy|)` (unbiased linear correlation, no bias toward zero
/// displacement) and by the number of contributing slices.
pub(super) fn normalise(plane: &mut [f64], shape: PlaneShape, slices: usize) {
    let (pw, ph) = (shape.plane_width(), shape.plane_height());
    let n = slices.max(1) as f64;
    for iy in 0..ph {
        let oy = (shape.h - iy.abs_diff(shape.ry)) as f64;
        for ix in 0..pw {
            let ox = (shape.w - ix.abs_diff(shape.rx)) as f64;
            plane[iy * pw + ix] /= ox * oy * n;
        }
    }
}
