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

/// Quantisation of the sub-pixel position in the kernel table (1/256 px).
const LEVELS: usize = 256;

/// Largest kernel footprint per axis, taps.
pub(crate) const MAX_TAPS: usize = 9;

/// Splat weights per axis for every quantised sub-pixel position, normalised to sum 1.
#[derive(Debug, Clone)]
pub(crate) struct SplatTable {
    /// Taps per axis.
    pub taps: usize,
    /// Offset of the first tap from the base pixel `floor(x + shift)`.
    pub first: i64,
    /// Added before flooring: 0 for even footprints (bilinear), 0.5 for odd (centred).
    pub shift: f32,
    /// `(LEVELS + 1) × taps` weights.
    pub weights: Vec<f32>,
}

impl SplatTable {
    /// The table of `splat`.
    pub fn new(splat: Splat) -> Self {
        let (taps, shift, kernel): (usize, f32, Box<dyn Fn(f64) -> f64>) = match splat {
            // The tent: bilinear weights of a point, (1 − f, f), correctly assigned
            // (not mirrored, algorithms.md §4.5 item 1).
            Splat::Bilinear => (2, 0.0, Box::new(|d: f64| (1.0 - d.abs()).max(0.0))),
            Splat::Gaussian { sigma } => {
                let half = (2.5 * sigma).ceil().max(1.0) as usize;
                let taps = (2 * half + 1).min(MAX_TAPS);
                let k = 1.0 / (2.0 * sigma * sigma);
                (taps, 0.5, Box::new(move |d: f64| (-d * d * k).exp()))
            }
        };
        let first = -((taps as i64 - 1) / 2);
        let mut weights = vec![0f32; (LEVELS + 1) * taps];
        for q in 0..=LEVELS {
            // Position of the point relative to the base pixel.
            let f = q as f64 / LEVELS as f64 - shift as f64;
            let row = &mut weights[q * taps..(q + 1) * taps];
            let w: Vec<f64> = (0..taps)
                .map(|j| kernel((first + j as i64) as f64 - f))
                .collect();
            let sum: f64 = w.iter().sum();
            for (r, w) in row.iter_mut().zip(&w) {
                *r = (w / sum) as f32;
            }
        }
        SplatTable {
            taps,
            first,
            shift,
            weights,
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
    if work.canvas.len() < canvas.cells() {
        work.canvas.resize(canvas.cells(), 0.0);
    }
    work.prepare(events, canvas, table);
    match table.taps {
        2 => objective_of::<2>(events, velocity, canvas, table, objective, work),
        3 => objective_of::<3>(events, velocity, canvas, table, objective, work),
        5 => objective_of::<5>(events, velocity, canvas, table, objective, work),
        7 => objective_of::<7>(events, velocity, canvas, table, objective, work),
        _ => objective_of::<MAX_TAPS>(events, velocity, canvas, table, objective, work),
    }
}

fn objective_of<const K: usize>(
    events: &Events,
    velocity: [f64; 2],
    canvas: &Canvas,
    table: &SplatTable,
    objective: Objective,
    work: &mut Workspace,
) -> f64 {
    let squares = scatter::<K>(events, velocity, canvas, table, work);
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

/// Splat every warped event with a `K` × `K` footprint and record each footprint's origin.
/// Returns Σ I², accumulated as the image grows: adding `w` to a cell holding `c` adds
/// `w (2c + w)`.
fn scatter<const K: usize>(
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
    let grid = &mut work.canvas[..canvas.cells()];
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
        let wx: &[f32; K] = table.weights[qx * K..qx * K + K].try_into().unwrap();
        let wy: &[f32; K] = table.weights[qy * K..qy * K + K].try_into().unwrap();
        let mut gain = 0f32;
        for (a, &wa) in wy.iter().enumerate() {
            let row: &mut [f32; K] = (&mut grid[origin + a * stride..origin + a * stride + K])
                .try_into()
                .unwrap();
            for (cell, &wb) in row.iter_mut().zip(wx) {
                let w = wa * wb;
                gain += w * (2.0 * *cell + w);
                *cell += w;
            }
        }
        squares += gain as f64;
    }
    squares
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
        scatter::<2>(&ev, [0.0, 0.0], &canvas, &table, &mut work);
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
            for row in table.weights.chunks(table.taps) {
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
                scatter::<2>(
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
