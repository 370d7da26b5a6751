//! The image of warped events (IWE) and its sharpness objectives.
//!
//! Events are warped to the reference time, `x' = x − u·t`, `y' = y − v·t` (Gallego, Rebecq
//! & Scaramuzza, "A unifying contrast maximization framework for event cameras", CVPR 2018),
//! splatted onto a padded canvas with a separable kernel read from a table, and the canvas is
//! scored with one of the objectives of Stoffregen & Kleeman, "Event cameras, contrast
//! maximization and reward functions: an analysis", CVPR 2019.
//!
//! Each evaluation touches only the pixels under the events' footprints: the scatter pass
//! records each footprint's first pixel, the scoring pass reads those pixels and zeroes them
//! again, so the canvas never needs clearing and the cost is proportional to the events.

use super::{Objective, Splat};
use crate::simd::{avx2_available, Quad};

/// Quantisation of the sub-pixel position in the kernel table (1/256 px).
const LEVELS: usize = 256;

/// Largest kernel footprint per axis, taps.
pub(crate) const MAX_TAPS: usize = 9;

/// Zero cells after the canvas, so that a footprint row may be written `lanes` wide.
const ROW_PAD: usize = 16;

/// Table row length for `taps` taps: a multiple of four lanes (one SSE register) above two
/// taps, zero-padded, so that every row operation of the scatter and read-back passes is a
/// whole number of vector operations. The padded lanes carry weight zero: they add zero to
/// cells next to the footprint and read nothing from them.
const fn lanes_of(taps: usize) -> usize {
    if taps <= 2 {
        taps
    } else {
        taps.div_ceil(4) * 4
    }
}

/// Splat weights per axis for every quantised sub-pixel position, normalised to sum 1.
#[derive(Debug, Clone)]
pub(crate) struct SplatTable {
    /// Taps per axis.
    pub taps: usize,
    /// Stored row length, `taps` zero-padded to whole vector registers ([`lanes_of`]).
    pub lanes: usize,
    /// Offset of the first tap from the base pixel `floor(x + shift)`.
    pub first: i64,
    /// Added before flooring: 0 for even footprints (bilinear), 0.5 for odd (centred).
    pub shift: f32,
    /// `(LEVELS + 1) × lanes` weights.
    pub weights: Vec<f32>,
    /// First and second derivatives of the weights with respect to the point's position
    /// (per cell and per cell²), same layout; zero for the bilinear tent, whose weights are
    /// piecewise linear.
    pub slope: Vec<f32>,
    pub curvature: Vec<f32>,
}

impl SplatTable {
    /// Σ w² of one point's splat, averaged over its sub-pixel position (the tabulated
    /// positions; the x and y weights are independent, so the mean of the product is the
    /// product of the means): what a lone event adds to Σ I², and half of what a pair of
    /// coinciding events adds to it beyond two lone ones (`(w + w)² = 2w² + 2w²`), so that
    /// a rise of Σ I² counts coinciding pairs.
    pub fn point_energy(&self) -> f64 {
        let rows = self.weights.chunks_exact(self.lanes);
        let count = rows.len().max(1) as f64;
        let per_axis = rows
            .map(|row| {
                row[..self.taps]
                    .iter()
                    .map(|&w| f64::from(w) * f64::from(w))
                    .sum::<f64>()
            })
            .sum::<f64>()
            / count;
        per_axis * per_axis
    }

    /// Panic unless the rows are stored `p` lanes wide, as the kernel about to read them
    /// assumes (a programming error, checked in release builds too: it costs one compare
    /// per evaluation).
    fn expect_lanes(&self, p: usize) {
        assert_eq!(
            self.lanes, p,
            "splat table padded to {} lanes, kernel built for {p}",
            self.lanes
        );
    }

    /// The table of `splat`.
    pub fn new(splat: Splat) -> Self {
        let (taps, shift, k) = match splat {
            Splat::Bilinear => (2, 0.0, None),
            Splat::Gaussian { sigma } => {
                let half = (2.5 * sigma).ceil().max(1.0) as usize;
                let taps = (2 * half + 1).min(MAX_TAPS);
                (taps, 0.5f32, Some(1.0 / (2.0 * sigma * sigma)))
            }
        };
        let first = -((taps as i64 - 1) / 2);
        let lanes = lanes_of(taps);
        let size = (LEVELS + 1) * lanes;
        let (mut weights, mut slope, mut curvature) =
            (vec![0f32; size], vec![0f32; size], vec![0f32; size]);
        for q in 0..=LEVELS {
            // Position of the point relative to the base pixel.
            let f = q as f64 / LEVELS as f64 - shift as f64;
            // Kernel g_j at tap j, distance d = j − f, and its derivatives in f.
            let (mut g, mut g1, mut g2) = ([0f64; MAX_TAPS], [0f64; MAX_TAPS], [0f64; MAX_TAPS]);
            for j in 0..taps {
                let d = (first + j as i64) as f64 - f;
                match k {
                    // The tent: bilinear weights of a point, (1 − f, f), correctly assigned
                    // (not mirrored, algorithms.md §4.5 item 1).
                    None => g[j] = (1.0 - d.abs()).max(0.0),
                    Some(k) => {
                        g[j] = (-d * d * k).exp();
                        g1[j] = 2.0 * k * d * g[j];
                        g2[j] = (4.0 * k * k * d * d - 2.0 * k) * g[j];
                    }
                }
            }
            // Normalised weights w = g / S and their derivatives (quotient rule).
            let (s0, s1, s2): (f64, f64, f64) = (
                g[..taps].iter().sum(),
                g1[..taps].iter().sum(),
                g2[..taps].iter().sum(),
            );
            for j in 0..taps {
                let at = q * lanes + j;
                weights[at] = (g[j] / s0) as f32;
                slope[at] = (g1[j] / s0 - g[j] * s1 / (s0 * s0)) as f32;
                curvature[at] = (g2[j] / s0 - 2.0 * g1[j] * s1 / (s0 * s0) - g[j] * s2 / (s0 * s0)
                    + 2.0 * g[j] * s1 * s1 / (s0 * s0 * s0)) as f32;
            }
        }
        SplatTable {
            taps,
            lanes,
            first,
            shift,
            weights,
            slope,
            curvature,
        }
    }

    /// Kernel radius in pixels beyond the warped position (for padding).
    pub fn reach(&self) -> i64 {
        (self.taps as i64 - 1 + self.first).max(-self.first) + 1
    }
}

/// Placement of the canvas: warped coordinate `x'` maps to canvas column
/// `(x' − origin_x) / bin`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Canvas {
    pub origin_x: f32,
    pub origin_y: f32,
    pub inv_bin: f32,
    pub width: usize,
    pub height: usize,
}

impl Canvas {
    /// A canvas of `bin` px cells holding every event of a `width` × `height` px window
    /// warped by any velocity with components up to `max_u`, `max_v` (px/ms) over times up
    /// to `t_max` (ms) from the reference, plus the kernel's reach: no event is lost
    /// (algorithms.md §4.5 item 2).
    pub fn covering(window: [u32; 2], max_shift: [f64; 2], bin: f64, table: &SplatTable) -> Canvas {
        let margin = (table.reach() + 2) as f64 * bin;
        let axis = |size: u32, shift: f64| {
            let origin = -shift - margin;
            let cells = ((size as f64 - 1.0 + 2.0 * (shift + margin)) / bin).ceil() as usize + 2;
            (origin as f32, cells)
        };
        let (origin_x, width) = axis(window[0], max_shift[0]);
        let (origin_y, height) = axis(window[1], max_shift[1]);
        Canvas {
            origin_x,
            origin_y,
            inv_bin: (1.0 / bin) as f32,
            width,
            height,
        }
    }

    /// Number of canvas cells.
    pub fn cells(&self) -> usize {
        self.width * self.height
    }
}

/// Events of a window as the warp needs them: local pixel coordinates and times in ms
/// relative to the reference time.
#[derive(Debug, Clone, Default)]
pub(crate) struct Events {
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub t: Vec<f32>,
}

/// Working memory of one evaluation: the canvas (all zero between evaluations), the
/// footprint origins, and the events in canvas units for the canvas and table they were
/// prepared for (`x_c = (x − origin_x) / bin + shift`, `t_c = t / bin`), so a candidate
/// costs one multiply-add per coordinate and event.
#[derive(Debug, Clone, Default)]
pub(crate) struct Workspace {
    pub canvas: Vec<f32>,
    pub footprint: Vec<u32>,
    /// Objective evaluations so far (plain or with derivatives), for profiling.
    pub evaluations: u64,
    /// Canvases of ∂I/∂u and ∂I/∂v (derivative evaluations only; zero between them).
    ju: Vec<f32>,
    jv: Vec<f32>,
    /// Quantised sub-pixel positions `qx | qy << 16` of the last derivative scatter.
    quant: Vec<u32>,
    /// Whether [`derivatives`] records each event's share of the gradient in
    /// `event_gradients` (for the uncertainty, [`super::uncertainty`]).
    pub record_gradients: bool,
    /// Each event's share `−2 t Σ_p I ∂w/∂x` of the gradient of Σ I² (in event order), from
    /// the last [`derivatives`] with `record_gradients`; they add up to the gradient.
    pub event_gradients: Vec<[f64; 2]>,
    prepared: Option<(Canvas, f32)>,
    cx: Vec<f32>,
    cy: Vec<f32>,
    ct: Vec<f32>,
}

impl Workspace {
    /// Forget the prepared events: must be called whenever the events change.
    pub fn forget_events(&mut self) {
        self.prepared = None;
    }

    /// Prepare `events` for `canvas` and `table` unless already done.
    fn prepare(&mut self, events: &Events, canvas: &Canvas, table: &SplatTable) {
        let key = (*canvas, table.shift);
        if self.prepared == Some(key) && self.ct.len() == events.t.len() {
            return;
        }
        let (ox, oy, ib, shift) = (
            canvas.origin_x,
            canvas.origin_y,
            canvas.inv_bin,
            table.shift,
        );
        self.cx.clear();
        self.cy.clear();
        self.ct.clear();
        self.cx
            .extend(events.x.iter().map(|&x| (x - ox) * ib + shift));
        self.cy
            .extend(events.y.iter().map(|&y| (y - oy) * ib + shift));
        self.ct.extend(events.t.iter().map(|&t| t * ib));
        self.prepared = Some(key);
    }
}

/// Objective of the IWE of `events` warped by `(u, v)` px/ms on `canvas`.
pub(crate) fn evaluate(
    events: &Events,
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    objective: Objective,
    work: &mut Workspace,
) -> f64 {
    if work.canvas.len() < canvas.cells() + ROW_PAD {
        work.canvas.resize(canvas.cells() + ROW_PAD, 0.0);
    }
    work.prepare(events, canvas, table);
    work.evaluations += 1;
    match table.taps {
        2 => objective_of::<2, 2>(events, velocity, canvas, table, objective, work),
        3 => objective_of::<3, 4>(events, velocity, canvas, table, objective, work),
        5 => objective_of::<5, 8>(events, velocity, canvas, table, objective, work),
        7 => objective_of::<7, 8>(events, velocity, canvas, table, objective, work),
        _ => objective_of::<MAX_TAPS, 12>(events, velocity, canvas, table, objective, work),
    }
}

fn objective_of<const K: usize, const P: usize>(
    events: &Events,
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    objective: Objective,
    work: &mut Workspace,
) -> f64 {
    let squares = scatter::<K, P>(events, velocity, canvas, table, work);
    let cells = canvas.cells() as f64;
    let n = events.t.len() as f64;
    let w = canvas.width;
    match objective {
        Objective::Variance => {
            clear::<K>(w, work);
            // Every event stays on the padded canvas, so the mean is n / cells for every
            // candidate and the variance is comparable across candidates.
            squares / cells - (n / cells) * (n / cells)
        }
        Objective::SumOfSquares => {
            clear::<K>(w, work);
            squares
        }
        Objective::SumExp => cells + score::<K>(w, work, |i| i.exp() - 1.0),
        Objective::R1 => {
            squares / cells * (cells + score::<K>(w, work, |i| (-3.0 * i).exp() - 1.0))
        }
        Objective::Isoa => score::<K>(w, work, |i| if i > 1.0 { 1.0 } else { 0.0 }),
        Objective::MaxAccumulation => {
            let mut max = 0f32;
            score::<K>(w, work, |i| {
                max = max.max(i);
                0.0
            });
            max as f64
        }
    }
}

/// Splat every warped event with a `K` × `K` footprint (rows written `P` ≥ `K` lanes wide,
/// the extra lanes with weight zero) and record each footprint's origin.
/// Returns Σ I², accumulated as the image grows: adding `w` to a cell holding `c` adds
/// `w (2c + w)`.
fn scatter<const K: usize, const P: usize>(
    events: &Events,
    [u, v]: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
) -> f64 {
    work.prepare(events, canvas, table);
    let (u, v) = (u as f32, v as f32);
    let stride = canvas.width;
    let first = table.first as isize;
    let levels = LEVELS as f32;
    table.expect_lanes(P);
    let grid = &mut work.canvas[..canvas.cells() + (P - K)];
    let n = work.ct.len();
    work.footprint.resize(n, 0);
    let mut squares = 0f64;
    let events = work.cx.iter().zip(&work.cy).zip(&work.ct);
    for (((&x, &y), &t), slot) in events.zip(work.footprint.iter_mut()) {
        // Canvas coordinates are positive by construction: truncation is the floor.
        let xc = x - u * t;
        let yc = y - v * t;
        let (bx, by) = (xc as u32 as usize, yc as u32 as usize);
        let qx = ((xc - bx as f32) * levels + 0.5) as u32 as usize;
        let qy = ((yc - by as f32) * levels + 0.5) as u32 as usize;
        let origin = (by as isize + first) as usize * stride + (bx as isize + first) as usize;
        *slot = origin as u32;
        let wx = lane_row::<P>(&table.weights, qx);
        let wy = lane_row::<P>(&table.weights, qy);
        // One partial sum per column: no serial chain of additions.
        let mut gain = [0f32; P];
        for (a, &wa) in wy[..K].iter().enumerate() {
            let row: &mut [f32; P] = (&mut grid[origin + a * stride..origin + a * stride + P])
                .try_into()
                .unwrap();
            splat_row(row, wa, &wx, &mut gain);
        }
        squares += gain.iter().sum::<f32>() as f64;
    }
    squares
}

/// Row `q` of a table stored `P` lanes wide, copied: the copy cannot alias the canvas, so
/// the row operations below compile to vector instructions.
#[inline(always)]
fn lane_row<const P: usize>(table: &[f32], q: usize) -> [f32; P] {
    table[q * P..q * P + P].try_into().unwrap()
}

/// `row += s · w`, accumulating the growth of Σ I² in `gain` (adding `x` to a cell holding
/// `c` adds `x (2c + x)`). A function of its own so that the compiler knows `row` aliases
/// nothing else.
#[inline(always)]
fn splat_row<const P: usize>(row: &mut [f32; P], s: f32, w: &[f32; P], gain: &mut [f32; P]) {
    for b in 0..P {
        let x = s * w[b];
        gain[b] += x * (2.0 * row[b] + x);
        row[b] += x;
    }
}

/// `row += s · w` (see [`splat_row`]).
#[inline(always)]
fn add_row<const P: usize>(row: &mut [f32; P], s: f32, w: &[f32; P]) {
    for b in 0..P {
        row[b] += s * w[b];
    }
}

/// Quads of lanes of a table row: rows with derivatives (Gaussian tables) are stored a
/// multiple of four lanes wide ([`lanes_of`]), at most [`MAX_QUADS`] quads.
const MAX_QUADS: usize = lanes_of(MAX_TAPS) / 4;

/// The quads of a row `P` lanes wide (a multiple of four).
#[inline(always)]
fn quads<const P: usize>(row: &[f32; P]) -> impl Iterator<Item = &[f32; 4]> {
    debug_assert!(P % 4 == 0 && P / 4 <= MAX_QUADS);
    row.chunks_exact(4)
        .map(|q| q.try_into().expect("chunks of four"))
}

/// `[Σ I², Σ J_u², Σ J_u J_v, Σ J_v²]` over one row segment of the three canvases, which are
/// zeroed on the way: four lanes at a time in [`Quad`]s (the compiler's own vectorisation
/// of lane arrays packed the four sums together instead, with a shuffle per cell).
#[inline(always)]
fn sum_and_clear(g: &mut [f32], gu: &mut [f32], gv: &mut [f32]) -> [f32; 4] {
    let n = g.len().min(gu.len()).min(gv.len());
    let whole = n - n % 4;
    let mut sums = [Quad::zero(); 4];
    for k in (0..whole).step_by(4) {
        let a: &mut [f32; 4] = (&mut g[k..k + 4]).try_into().unwrap();
        let b: &mut [f32; 4] = (&mut gu[k..k + 4]).try_into().unwrap();
        let c: &mut [f32; 4] = (&mut gv[k..k + 4]).try_into().unwrap();
        let (x, y, z) = (Quad::load(a), Quad::load(b), Quad::load(c));
        sums[0] = sums[0].add(x.mul(x));
        sums[1] = sums[1].add(y.mul(y));
        sums[2] = sums[2].add(y.mul(z));
        sums[3] = sums[3].add(z.mul(z));
        Quad::zero().store(a);
        Quad::zero().store(b);
        Quad::zero().store(c);
    }
    let [mut s, mut uu, mut uv, mut vv] = sums.map(Quad::to_array);
    for k in whole..n {
        s[0] += g[k] * g[k];
        uu[0] += gu[k] * gu[k];
        uv[0] += gu[k] * gv[k];
        vv[0] += gv[k] * gv[k];
        (g[k], gu[k], gv[k]) = (0.0, 0.0, 0.0);
    }
    let total = |x: [f32; 4]| (x[0] + x[2]) + (x[1] + x[3]);
    [total(s), total(uu), total(uv), total(vv)]
}

/// Σ I² of the IWE and its gradient and Hessian in the velocity `(u, v)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Derivatives {
    pub squares: f64,
    pub gradient: [f64; 2],
    pub hessian: [[f64; 2]; 2],
}

/// Σ I² at `velocity` with its analytic gradient and Hessian (contrast maximisation with
/// derivatives: Gallego, Rebecq & Scaramuzza, CVPR 2018, §3). With the warped position
/// `x'_i = x_i − u t_i` and the splat weights `w(x')` of the table,
///
/// * `∂I(p)/∂u = −Σ_i t_i w'_x w_y` (canvas `J_u`, likewise `J_v`),
/// * `∂ΣI²/∂u = 2 Σ_p I ∂I/∂u`, read back per event from the finished image,
/// * `∂²ΣI²/∂u∂v = 2 Σ_p J_u J_v + 2 Σ_p I ∂²I/∂u∂v` with `∂²I/∂u∂v = Σ_i t_i² w'_x w'_y`.
///
/// Three passes: scatter I, J_u, J_v over the events; read I back under each event's
/// footprint; sum and zero the rows and columns the footprints reach. Only for kernels with derivatives (Gaussian tables).
pub(crate) fn derivatives(
    events: &Events,
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
) -> Derivatives {
    let cells = canvas.cells();
    for c in [&mut work.canvas, &mut work.ju, &mut work.jv] {
        if c.len() < cells + ROW_PAD {
            c.resize(cells + ROW_PAD, 0.0);
        }
    }
    work.prepare(events, canvas, table);
    work.evaluations += 1;
    if avx2_available() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the processor has AVX2 (`avx2_available`).
        return unsafe { derivatives_avx2(velocity, canvas, table, work) };
    }
    derivatives_portable(velocity, canvas, table, work)
}

/// [`derivatives_kernel`] without the AVX code: every processor.
#[inline(always)]
fn derivatives_portable(
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
) -> Derivatives {
    // SAFETY: without `WIDE` no AVX instruction runs.
    unsafe { derivatives_kernel::<false>(velocity, canvas, table, work) }
}

/// [`derivatives_kernel`] compiled for AVX2 ([`crate::simd`]): its lane loops, arrays of
/// 8 (4) `f32`, become one (half an) AVX register instead of two (one) SSE registers; the
/// same operations in the same order, so the same bits on every processor.
///
/// # Safety
/// Only where the processor has AVX2 ([`avx2_available`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn derivatives_avx2(
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
) -> Derivatives {
    derivatives_kernel::<true>(velocity, canvas, table, work)
}

/// [`derivatives`] for the table's number of taps; `WIDE` in the AVX2 build, whose per-event
/// scatter and read-back of eight-lane rows (5 and 7 taps, σ = 0.8 by default) are written out in
/// AVX registers ([`splat_footprint_avx2`], [`footprint_sums_avx2`]): on two fields of a 1280×720
/// uniform flow of 0.00152 particles per pixel (`gen4`) 998 M → 782 M instructions (callgrind), the
/// same bits.
///
/// # Safety
/// With `WIDE`, only where the processor has AVX2 ([`avx2_available`]).
#[inline(always)]
unsafe fn derivatives_kernel<const WIDE: bool>(
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
) -> Derivatives {
    match table.taps {
        3 => derivatives_of::<3, 4, WIDE>(velocity, canvas, table, work),
        5 => derivatives_of::<5, 8, WIDE>(velocity, canvas, table, work),
        7 => derivatives_of::<7, 8, WIDE>(velocity, canvas, table, work),
        _ => derivatives_of::<MAX_TAPS, 12, WIDE>(velocity, canvas, table, work),
    }
}

/// [`derivatives`] for `K` taps stored `P` lanes wide.
///
/// # Safety
/// With `WIDE`, only where the processor has AVX2 ([`avx2_available`]).
#[inline(always)]
unsafe fn derivatives_of<const K: usize, const P: usize, const WIDE: bool>(
    [u, v]: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    work: &mut Workspace,
) -> Derivatives {
    let (u, v) = (u as f32, v as f32);
    let stride = canvas.width;
    let first = table.first as isize;
    let levels = LEVELS as f32;
    table.expect_lanes(P);
    let cells = canvas.cells() + (P - K);
    let row = |tab: &[f32], q: usize| -> [f32; P] { lane_row::<P>(tab, q) };
    let n = work.ct.len();
    work.footprint.resize(n, 0);
    work.quant.resize(n, 0);
    // 1. Scatter I, J_u, J_v; `span` bounds the base pixels (x min, x max, y min, y max).
    let mut span = [u32::MAX, 0, u32::MAX, 0];
    {
        let (grid, ju, jv) = (
            &mut work.canvas[..cells],
            &mut work.ju[..cells],
            &mut work.jv[..cells],
        );
        let events = work.cx.iter().zip(&work.cy).zip(&work.ct);
        let slots = work.footprint.iter_mut().zip(work.quant.iter_mut());
        for (((&x, &y), &t), (slot, quant)) in events.zip(slots) {
            let (xc, yc) = (x - u * t, y - v * t);
            let (bx, by) = (xc as u32, yc as u32);
            span = [
                span[0].min(bx),
                span[1].max(bx),
                span[2].min(by),
                span[3].max(by),
            ];
            let (bx, by) = (bx as usize, by as usize);
            let qx = ((xc - bx as f32) * levels + 0.5) as u32 as usize;
            let qy = ((yc - by as f32) * levels + 0.5) as u32 as usize;
            // Wrapping, as release builds compute it, also where overflow is checked: a
            // footprint off the canvas then fails the kernels' bounds tests in every build.
            let origin = ((by as isize + first) as usize)
                .wrapping_mul(stride)
                .wrapping_add((bx as isize + first) as usize);
            *slot = origin as u32;
            *quant = (qx | qy << 16) as u32;
            let (wx, wy) = (row(&table.weights, qx), row(&table.weights, qy));
            let (sx, sy) = (row(&table.slope, qx), row(&table.slope, qy));
            let canvases = [&mut *grid, &mut *ju, &mut *jv];
            let kernels = [&wx, &sx, &wy, &sy];
            #[cfg(target_arch = "x86_64")]
            if WIDE && P == 8 {
                // SAFETY: with `WIDE` the processor has AVX2 (this function's contract).
                unsafe { splat_footprint_avx2::<K, P>(canvases, origin, stride, t, kernels) };
            } else {
                splat_footprint::<K, P>(canvases, origin, stride, t, kernels);
            }
            #[cfg(not(target_arch = "x86_64"))]
            splat_footprint::<K, P>(canvases, origin, stride, t, kernels);
        }
    }
    // 2. Read I back under each footprint: gradient and the I ∂²I term of the Hessian.
    let (mut g, mut h) = ([0f64; 2], [0f64; 3]);
    let record = work.record_gradients;
    work.event_gradients.clear();
    {
        let grid = &work.canvas[..cells];
        let event_gradients = &mut work.event_gradients;
        let events = work.ct.iter().zip(&work.footprint).zip(&work.quant);
        for ((&t, &origin), &quant) in events {
            let (qx, qy) = ((quant & 0xffff) as usize, (quant >> 16) as usize);
            let kernel = |q: usize| KernelRows {
                w: row(&table.weights, q),
                s: row(&table.slope, q),
                c: row(&table.curvature, q),
            };
            let (x, y) = (kernel(qx), kernel(qy));
            let origin = origin as usize;
            #[cfg(target_arch = "x86_64")]
            let [gu, gv, huu, huv, hvv] = if WIDE && P == 8 {
                // SAFETY: with `WIDE` the processor has AVX2 (this function's contract).
                unsafe { footprint_sums_avx2::<K, P>(grid, origin, stride, &x, &y) }
            } else {
                footprint_sums::<K, P>(grid, origin, stride, &x, &y)
            };
            #[cfg(not(target_arch = "x86_64"))]
            let [gu, gv, huu, huv, hvv] = footprint_sums::<K, P>(grid, origin, stride, &x, &y);
            let (t, t2) = (t as f64, (t * t) as f64);
            g[0] -= t * gu as f64;
            g[1] -= t * gv as f64;
            if record {
                event_gradients.push([-2.0 * t * gu as f64, -2.0 * t * gv as f64]);
            }
            h[0] += t2 * huu as f64;
            h[1] += t2 * huv as f64;
            h[2] += t2 * hvv as f64;
        }
    }
    // 3. Σ I², Σ J J^T over the rows and columns the footprints can reach (contiguous, so
    // vectorised), zeroing them.
    let (mut squares, mut j) = (0f64, [0f64; 3]);
    if n > 0 {
        let x0 = (span[0] as isize + first) as usize;
        let x1 = (span[1] as isize + first) as usize + K;
        let y0 = (span[2] as isize + first) as usize;
        let y1 = (span[3] as isize + first) as usize + K;
        for r in y0..y1 {
            let range = r * stride + x0..r * stride + x1;
            let sums = sum_and_clear(
                &mut work.canvas[range.clone()],
                &mut work.ju[range.clone()],
                &mut work.jv[range],
            );
            squares += sums[0] as f64;
            j[0] += sums[1] as f64;
            j[1] += sums[2] as f64;
            j[2] += sums[3] as f64;
        }
    }
    Derivatives {
        squares,
        gradient: [2.0 * g[0], 2.0 * g[1]],
        hessian: [
            [2.0 * (j[0] + h[0]), 2.0 * (j[1] + h[1])],
            [2.0 * (j[1] + h[1]), 2.0 * (j[2] + h[2])],
        ],
    }
}

/// A point's kernel rows along one axis: weights `w`, slopes `w'` and curvatures `w''` at
/// its quantised sub-pixel position, `P` lanes wide.
struct KernelRows<const P: usize> {
    w: [f32; P],
    s: [f32; P],
    c: [f32; P],
}

/// One event's rows of I, J_u and J_v (pass 1 of [`derivatives`]): `I += w_y[a] w_x`,
/// `J_u += (−t w_y[a]) w'_x`, `J_v += (−t w'_y[a]) w_x` on the `K` rows from `origin` of
/// `canvases` `[I, J_u, J_v]`; `kernels` are `[w_x, w'_x, w_y, w'_y]`.
#[inline(always)]
fn splat_footprint<const K: usize, const P: usize>(
    [grid, ju, jv]: [&mut [f32]; 3],
    origin: usize,
    stride: usize,
    t: f32,
    [wx, sx, wy, sy]: [&[f32; P]; 4],
) {
    for a in 0..K {
        let at = origin + a * stride;
        let (wa, sa) = (wy[a], -t * sy[a]);
        let ta = -t * wy[a];
        // One array at a time: the compiler cannot tell the three canvases apart.
        add_row((&mut grid[at..at + P]).try_into().unwrap(), wa, wx);
        add_row((&mut ju[at..at + P]).try_into().unwrap(), ta, sx);
        add_row((&mut jv[at..at + P]).try_into().unwrap(), sa, wx);
    }
}

/// [`splat_footprint`] for rows of eight lanes in AVX registers: the same operations per
/// lane in the same order as [`add_row`], so the same bits. One bounds test covers the
/// footprint on the three canvases.
///
/// # Safety
/// Only where the processor has AVX2 ([`crate::simd::avx2_available`]), and for `P` = 8.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn splat_footprint_avx2<const K: usize, const P: usize>(
    [grid, ju, jv]: [&mut [f32]; 3],
    origin: usize,
    stride: usize,
    t: f32,
    [wx, sx, wy, sy]: [&[f32; P]; 4],
) {
    use std::arch::x86_64::*;
    assert!(P == 8 && K <= 8, "eight-lane rows");
    // Checked: a footprint left of or above the canvas wraps `origin` around (release builds
    // do not trap the overflow), and a wrapped `end` could pass the test.
    let end = origin.checked_add((K - 1) * stride + P);
    let len = grid.len().min(ju.len()).min(jv.len());
    assert!(
        end.is_some_and(|end| end <= len),
        "footprint inside the canvases"
    );
    let (wxv, sxv) = (_mm256_loadu_ps(wx.as_ptr()), _mm256_loadu_ps(sx.as_ptr()));
    let (g, u, v) = (grid.as_mut_ptr(), ju.as_mut_ptr(), jv.as_mut_ptr());
    for a in 0..K {
        // In bounds: origin + a·stride + 8 ≤ end ≤ every canvas's length (asserted above).
        let at = origin + a * stride;
        let (wa, sa) = (wy[a], -t * sy[a]);
        let ta = -t * wy[a];
        for (cells, scale, row) in [(g, wa, wxv), (u, ta, sxv), (v, sa, wxv)] {
            let p = cells.add(at);
            let add = _mm256_mul_ps(_mm256_set1_ps(scale), row);
            _mm256_storeu_ps(p, _mm256_add_ps(_mm256_loadu_ps(p), add));
        }
    }
}

/// The image `grid` read back under one event's `K` × `K` footprint at `origin`, weighted by
/// its kernel rows `x` (columns) and `y` (rows): `[Σ I w'_x w_y, Σ I w_x w'_y,
/// Σ I w''_x w_y, Σ I w'_x w'_y, Σ I w_x w''_y]`. Column sums of I weighted by the row
/// kernels w_y, w'_y, w''_y, then dot products with the column kernels (independent lanes,
/// no serial chain), in [`Quad`]s: as lane arrays the compiler packed the three sums
/// together, with a shuffle per value (325 instead of 177 instructions per event,
/// callgrind).
#[inline(always)]
fn footprint_sums<const K: usize, const P: usize>(
    grid: &[f32],
    origin: usize,
    stride: usize,
    x: &KernelRows<P>,
    y: &KernelRows<P>,
) -> [f32; 5] {
    let (mut r0, mut r1, mut r2) = (
        [Quad::zero(); MAX_QUADS],
        [Quad::zero(); MAX_QUADS],
        [Quad::zero(); MAX_QUADS],
    );
    for a in 0..K {
        let at = origin + a * stride;
        let cells: &[f32; P] = (&grid[at..at + P]).try_into().unwrap();
        let (w, s, c) = (
            Quad::splat(y.w[a]),
            Quad::splat(y.s[a]),
            Quad::splat(y.c[a]),
        );
        for (q, cells) in quads(cells).enumerate() {
            let v = Quad::load(cells);
            r0[q] = r0[q].add(w.mul(v));
            r1[q] = r1[q].add(s.mul(v));
            r2[q] = r2[q].add(c.mul(v));
        }
    }
    let quad_dot = |r: &[Quad; MAX_QUADS], w: &[f32; P]| {
        let mut acc = Quad::zero();
        for (q, w) in quads(w).enumerate() {
            acc = acc.add(r[q].mul(Quad::load(w)));
        }
        let acc = acc.to_array();
        (acc[0] + acc[2]) + (acc[1] + acc[3])
    };
    [
        quad_dot(&r0, &x.s),
        quad_dot(&r1, &x.w),
        quad_dot(&r0, &x.c),
        quad_dot(&r1, &x.s),
        quad_dot(&r2, &x.w),
    ]
}

/// [`footprint_sums`] for rows of eight lanes in AVX registers: the same operations per
/// lane in the same order (a row's two [`Quad`]s are the halves of one register, and a dot
/// product adds the low half to zero before the high half, as the [`Quad`] version does),
/// so the same bits (≈ 230 → 155 instructions per event with the bounds tests, callgrind).
/// One bounds test covers the footprint.
///
/// # Safety
/// Only where the processor has AVX2 ([`crate::simd::avx2_available`]), and for `P` = 8.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn footprint_sums_avx2<const K: usize, const P: usize>(
    grid: &[f32],
    origin: usize,
    stride: usize,
    x: &KernelRows<P>,
    y: &KernelRows<P>,
) -> [f32; 5] {
    use std::arch::x86_64::*;
    assert!(P == 8 && K <= 8, "eight-lane rows");
    let end = origin.checked_add((K - 1) * stride + P);
    assert!(
        end.is_some_and(|end| end <= grid.len()),
        "footprint inside the canvas"
    );
    let base = grid.as_ptr().add(origin);
    let (mut r0, mut r1, mut r2) = (
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
    );
    for a in 0..K {
        // In bounds: origin + a·stride + 8 ≤ end ≤ grid.len() (asserted above).
        let v = _mm256_loadu_ps(base.add(a * stride));
        let (w, s, c) = (
            _mm256_set1_ps(y.w[a]),
            _mm256_set1_ps(y.s[a]),
            _mm256_set1_ps(y.c[a]),
        );
        r0 = _mm256_add_ps(r0, _mm256_mul_ps(w, v));
        r1 = _mm256_add_ps(r1, _mm256_mul_ps(s, v));
        r2 = _mm256_add_ps(r2, _mm256_mul_ps(c, v));
    }
    let dot = |r: __m256, w: &[f32; P]| {
        let p = _mm256_mul_ps(r, _mm256_loadu_ps(w.as_ptr()));
        let low = _mm_add_ps(_mm_setzero_ps(), _mm256_castps256_ps128(p));
        let acc = _mm_add_ps(low, _mm256_extractf128_ps::<1>(p));
        // (acc0 + acc2) + (acc1 + acc3).
        let pairs = _mm_add_ps(acc, _mm_movehl_ps(acc, acc));
        _mm_cvtss_f32(pairs) + _mm_cvtss_f32(_mm_shuffle_ps::<1>(pairs, pairs))
    };
    [
        dot(r0, &x.s),
        dot(r1, &x.w),
        dot(r0, &x.c),
        dot(r1, &x.s),
        dot(r2, &x.w),
    ]
}

/// Zero the touched cells.
fn clear<const K: usize>(stride: usize, work: &mut Workspace) {
    for &origin in &work.footprint {
        let origin = origin as usize;
        for a in 0..K {
            let row: &mut [f32; K] = (&mut work.canvas
                [origin + a * stride..origin + a * stride + K])
                .try_into()
                .unwrap();
            *row = [0.0; K];
        }
    }
}

/// Sum `g` over the touched cells and zero them. Footprints overlap; a cell is counted once
/// because it is zero when met again and `g(0) = 0`.
fn score<const K: usize>(
    stride: usize,
    work: &mut Workspace,
    mut g: impl FnMut(f32) -> f32,
) -> f64 {
    let mut sum = 0f64;
    for &origin in &work.footprint {
        let origin = origin as usize;
        let mut acc = 0f32;
        for a in 0..K {
            let row: &mut [f32; K] = (&mut work.canvas
                [origin + a * stride..origin + a * stride + K])
                .try_into()
                .unwrap();
            for cell in row.iter_mut() {
                acc += g(*cell);
                *cell = 0.0;
            }
        }
        sum += acc as f64;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_event(x: f32, y: f32) -> Events {
        Events {
            x: vec![x],
            y: vec![y],
            t: vec![0.0],
        }
    }

    #[test]
    fn bilinear_weights_are_not_mirrored() {
        let table = SplatTable::new(Splat::Bilinear);
        let canvas = Canvas::covering([8, 8], [0.0, 0.0], 1.0, &table);
        let mut work = Workspace::default();
        let ev = one_event(3.25, 5.75);
        work.canvas.resize(canvas.cells(), 0.0);
        scatter::<2, 2>(&ev, [0.0, 0.0], &canvas, &table, &mut work);
        let at = |x: f32, y: f32| {
            let c = (
                (x - canvas.origin_x) as usize,
                (y - canvas.origin_y) as usize,
            );
            work.canvas[c.1 * canvas.width + c.0]
        };
        assert!((at(3.0, 5.0) - 0.75 * 0.25).abs() < 1e-3);
        assert!((at(4.0, 5.0) - 0.25 * 0.25).abs() < 1e-3);
        assert!((at(3.0, 6.0) - 0.75 * 0.75).abs() < 1e-3);
        assert!((at(4.0, 6.0) - 0.25 * 0.75).abs() < 1e-3);
    }

    #[test]
    fn tables_are_normalised_and_scoring_clears_the_canvas() {
        for splat in [Splat::Bilinear, Splat::Gaussian { sigma: 0.8 }] {
            let table = SplatTable::new(splat);
            for row in table.weights.chunks(table.lanes) {
                assert!((row.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            }
            // Events pushed to the extreme warps stay on the canvas: the total is kept.
            let canvas = Canvas::covering([10, 6], [2.0 * 5.0, 1.0 * 5.0], 1.0, &table);
            let ev = Events {
                x: vec![0.0, 9.0, 0.0, 9.0],
                y: vec![0.0, 5.0, 5.0, 0.0],
                t: vec![-5.0, 5.0, 5.0, -5.0],
            };
            let mut work = Workspace::default();
            for vel in [[2.0, 1.0], [-2.0, -1.0], [2.0, -1.0], [-2.0, 1.0]] {
                let total = evaluate(&ev, vel, &canvas, &table, Objective::Isoa, &mut work);
                assert_eq!(total, 0.0);
                work.canvas.iter().for_each(|&c| assert_eq!(c, 0.0));
                scatter::<2, 2>(
                    &ev,
                    vel,
                    &canvas,
                    &SplatTable::new(Splat::Bilinear),
                    &mut work,
                );
                let sum: f32 = work.canvas.iter().sum();
                assert!((sum - 4.0).abs() < 1e-4, "{vel:?}: {sum}");
                work.canvas.iter_mut().for_each(|c| *c = 0.0);
            }
        }
    }

    /// Where the processor has AVX2, `derivatives` runs the AVX2 build of the kernel: it must
    /// give the same bits as the portable build, for every kernel width.
    #[test]
    fn derivatives_are_the_same_bits_with_and_without_avx2() {
        let n = 300;
        let events = Events {
            x: (0..n).map(|i| (i * 7 % 40) as f32 + 0.37).collect(),
            y: (0..n).map(|i| (i * 13 % 40) as f32 + 0.71).collect(),
            t: (0..n).map(|i| (i as f32 / n as f32 - 0.5) * 10.0).collect(),
        };
        for sigma in [0.4, 0.8, 1.2, 1.5] {
            let table = SplatTable::new(Splat::Gaussian { sigma });
            let canvas = Canvas::covering([40, 40], [20.0, 20.0], 1.0, &table);
            let (mut dispatched, mut portable) = (Workspace::default(), Workspace::default());
            for velocity in [[0.3, -1.7], [1.9, 0.05], [-2.0, 2.0]] {
                let fast = derivatives(&events, velocity, &canvas, &table, &mut dispatched);
                // `derivatives`' preparation, then the portable kernel.
                let cells = canvas.cells() + ROW_PAD;
                for c in [&mut portable.canvas, &mut portable.ju, &mut portable.jv] {
                    c.resize(cells.max(c.len()), 0.0);
                }
                portable.prepare(&events, &canvas, &table);
                let slow = derivatives_portable(velocity, &canvas, &table, &mut portable);
                assert_eq!(fast, slow, "σ = {sigma}, velocity {velocity:?}");
                assert!(fast.squares > 0.0);
            }
        }
        println!("AVX2 available: {}", avx2_available());
    }

    /// The analytic gradient against central differences of Σ I², the analytic Hessian
    /// against central differences of the analytic gradient. They describe the
    /// smooth part of Σ I² only: the kernel, cut off at ±K/2 px and renormalised, changes
    /// its taps where a point crosses a pixel boundary, so Σ I² and its gradient jump by
    /// small amounts that central differences see and the analytic derivatives do not
    /// (measured: gradients within 4 %, Hessian diagonals 5–15 % smaller than the
    /// differences near the maximum and up to 40 % away from it; with the kernel cut off at
    /// 3.5 σ instead of 2.5 σ all agree within 1 %). Newton's steps from such a Hessian
    /// overshoot by the same fraction: the ascent converges with a step ratio of about 0.1
    /// rather than quadratically.
    #[test]
    fn derivatives_match_central_differences_of_the_objective() {
        use crate::estimate::motion::test_events::trails;
        let events = trails([1.2, -0.4], 7);
        for sigma in [0.8, 1.2] {
            let table = SplatTable::new(Splat::Gaussian { sigma });
            let canvas = Canvas::covering([40, 40], [20.0, 20.0], 1.0, &table);
            let mut work = Workspace::default();
            let mut at = |v: [f64; 2]| derivatives(&events, v, &canvas, &table, &mut work);
            // Near the maximum (1.23, −0.38) and away from it, where the gradient is large.
            for (k, v) in [[1.23, -0.38], [1.0, -0.1], [1.6, -0.7]]
                .into_iter()
                .enumerate()
            {
                let near_maximum = k == 0;
                let d = at(v);
                let h = 0.01;
                for axis in 0..2 {
                    let mut step = |s: f64| {
                        let mut w = v;
                        w[axis] += s * h;
                        at(w)
                    };
                    let (plus, minus) = (step(1.0), step(-1.0));
                    let slope = (plus.squares - minus.squares) / (2.0 * h);
                    let curvature = (plus.gradient[axis] - minus.gradient[axis]) / (2.0 * h);
                    let (g, c) = (d.gradient[axis], d.hessian[axis][axis]);
                    let context = format!("σ {sigma}, v {v:?}, axis {axis}");
                    assert!(
                        (g - slope).abs() < 0.05 * slope.abs() + 0.005 * curvature.abs(),
                        "{context}: gradient {g} vs {slope}"
                    );
                    if near_maximum {
                        assert!(c < 0.0, "{context}: Hessian {c}");
                        assert!(
                            (c - curvature).abs() < 0.2 * curvature.abs(),
                            "{context}: Hessian {c} vs {curvature}"
                        );
                        // The mixed term: the other component's change along this axis.
                        let other = 1 - axis;
                        let mixed = (plus.gradient[other] - minus.gradient[other]) / (2.0 * h);
                        let m = d.hessian[other][axis];
                        assert!(
                            (m - mixed).abs() < 0.02 * curvature.abs(),
                            "{context}: mixed Hessian {m} vs {mixed}"
                        );
                    }
                }
            }
        }
    }

    /// A velocity that puts footprints past the canvas's last cell, or above and left of its
    /// first (where the footprint's first cell wraps around `usize`), which the search's
    /// clamping to the range the canvas covers prevents, must stop the program, not write
    /// outside the canvases, in the AVX2 and the portable kernel alike.
    #[test]
    fn footprints_off_the_canvas_panic() {
        let events = Events {
            x: vec![3.0],
            y: vec![3.0],
            t: vec![1.0],
        };
        let table = SplatTable::new(Splat::Gaussian { sigma: 0.8 });
        let canvas = Canvas::covering([8, 8], [1.0, 1.0], 1.0, &table);
        for velocity in [[-1e4, 0.0], [0.0, -1e4], [1e4, 1e4]] {
            // The panic's message, if it panicked.
            let run = |portable: bool| {
                std::panic::catch_unwind(|| {
                    let mut work = Workspace::default();
                    if portable {
                        let cells = canvas.cells() + ROW_PAD;
                        for c in [&mut work.canvas, &mut work.ju, &mut work.jv] {
                            c.resize(cells, 0.0);
                        }
                        work.prepare(&events, &canvas, &table);
                        derivatives_portable(velocity, &canvas, &table, &mut work)
                    } else {
                        derivatives(&events, velocity, &canvas, &table, &mut work)
                    }
                })
                .err()
                .map(|payload| {
                    let text = payload.downcast_ref::<&str>().map(|s| s.to_string());
                    text.or_else(|| payload.downcast_ref::<String>().cloned())
                        .unwrap_or_default()
                })
            };
            let dispatched = run(false);
            assert!(
                dispatched.is_some(),
                "dispatched kernel, velocity {velocity:?}"
            );
            if avx2_available() {
                // Stopped by the AVX2 scatter's own bounds test (the first to meet the
                // footprint), in debug and release builds alike.
                let message = dispatched.unwrap();
                assert!(
                    message.contains("footprint inside the canvases"),
                    "{message}"
                );
            }
            assert!(
                run(true).is_some(),
                "portable kernel, velocity {velocity:?}"
            );
        }
    }

    #[test]
    fn point_energy_is_what_a_pair_of_coinciding_events_adds_beyond_two_lone_ones() {
        // Bilinear: (1 − f)² + f² averages 2/3 over f per axis.
        let bilinear = SplatTable::new(Splat::Bilinear).point_energy();
        assert!((bilinear - 4.0 / 9.0).abs() < 0.01, "{bilinear}");
        // A normalised Gaussian of σ: ∫ g² = 1 / (4π σ²) in two dimensions.
        let sigma = 0.8;
        let gaussian = SplatTable::new(Splat::Gaussian { sigma }).point_energy();
        let expected = 1.0 / (4.0 * std::f64::consts::PI * sigma * sigma);
        assert!(
            (gaussian / expected - 1.0).abs() < 0.03,
            "{gaussian} vs {expected}"
        );
        // Two events at one position raise Σ I² by twice the energy over two far apart.
        let table = SplatTable::new(Splat::Gaussian { sigma });
        let canvas = Canvas::covering([32, 32], [0.0, 0.0], 1.0, &table);
        // A workspace per event set: it keeps what it derived from the events it saw.
        let squares = |x: [f32; 2]| {
            let events = Events {
                x: x.to_vec(),
                y: vec![10.3; 2],
                t: vec![0.0; 2],
            };
            let mut work = Workspace::default();
            evaluate(
                &events,
                [0.0; 2],
                &canvas,
                &table,
                Objective::SumOfSquares,
                &mut work,
            )
        };
        let (together, apart) = (squares([10.3, 10.3]), squares([4.3, 20.3]));
        let rise = (together - apart) / (2.0 * table.point_energy());
        assert!((rise - 1.0).abs() < 0.03, "{rise} pairs");
    }

    #[test]
    fn gaussian_self_energy_hardly_depends_on_the_sub_pixel_position() {
        // The pixel-grid ripple behind zero-velocity locking (algorithms.md §4.5 item 8):
        // bilinear splatting halves a point's energy between pixel centre and pixel corner.
        let energy = |splat: Splat, x: f32| {
            let table = SplatTable::new(splat);
            let canvas = Canvas::covering([8, 8], [0.0, 0.0], 1.0, &table);
            let ev = one_event(x, x);
            let mut work = Workspace::default();
            evaluate(
                &ev,
                [0.0, 0.0],
                &canvas,
                &table,
                Objective::SumOfSquares,
                &mut work,
            )
        };
        let ratio = |s| energy(s, 4.0) / energy(s, 4.5);
        assert!((ratio(Splat::Bilinear) - 4.0).abs() < 1e-3);
        assert!((ratio(Splat::Gaussian { sigma: 0.8 }) - 1.0).abs() < 0.01);
    }
}

#[cfg(test)]
mod timing {
    use super::*;
    #[test]
    #[ignore = "timing printout, not a pass/fail test (timed assertions are not allowed): run with --release -- --ignored --nocapture"]
    fn time_evaluate() {
        let n = 300;
        let ev = Events {
            x: (0..n).map(|i| (i * 7 % 40) as f32).collect(),
            y: (0..n).map(|i| (i * 13 % 40) as f32).collect(),
            t: (0..n).map(|i| (i as f32 / n as f32 - 0.5) * 10.0).collect(),
        };
        for splat in [Splat::Bilinear, Splat::Gaussian { sigma: 0.8 }] {
            let table = SplatTable::new(splat);
            let canvas = Canvas::covering([40, 40], [20.0, 20.0], 1.0, &table);
            let mut work = Workspace::default();
            let start = std::time::Instant::now();
            let mut s = 0.0;
            for k in 0..2000 {
                s += evaluate(
                    &ev,
                    [k as f64 * 0.001, 0.5],
                    &canvas,
                    &table,
                    Objective::Variance,
                    &mut work,
                );
            }
            eprintln!(
                "{splat:?}: {:.2} µs per evaluation ({s})",
                start.elapsed().as_secs_f64() * 1e6 / 2000.0
            );
        }
    }
}
