//! Coarse-to-fine search of the velocity that maximises the IWE objective.
//!
//! Candidates lie on an integer lattice of the finest step around the search centre (the
//! predictor or zero), so no grid depends on floating-point `arange` end points
//! (algorithms.md §4.5 item 5) and every candidate is evaluated at most once per level.
//!
//! 1. **Pyramid** (only for ranges wider than a few coarse steps): the whole range is scanned
//!    at `coarse_step · 2^L` on a canvas of `≈ 2^L` px cells with bilinear splatting, then
//!    refined level by level (5 × 5 neighbourhoods) down to twice the coarse step. A cell as
//!    large as the displacement step keeps the objective smooth at that step, so no peak
//!    falls between candidates, at a fraction of the cost of scanning the full range at
//!    `coarse_step`.
//! 2. **Coarse step**: the 5 × 5 neighbourhood at `coarse_step` with the configured splat. A
//!    best candidate on the edge of the range is flagged out of range
//!    (algorithms.md §4.5 item 3).
//! 3. **Refinement** (Willert & Klinner 2022: 0.25 → 0.05 px/ms): 5 × 5 neighbourhoods
//!    around the current best, re-centred while the best lies on their border, halving the
//!    step while it stays ≥ `final_step`.
//!    The same climb, from the coarse step down, also runs from the given start (a sum of
//!    correlation), and the higher of the two maxima wins.
//! 4. A 3-point fit per axis (or a 2-D Gaussian) through the best lattice point.
//!
//! [`SearchMethod::Newton`] replaces all four steps, when the objective allows, by Newton
//! ascents ([`super::newton`]) from several starts: a given start (a sum of correlation in
//! a first pass) or the predictor, the maxima of a pair-velocity vote ([`super::votes`]),
//! and zero velocity where its objective competes. The highest maximum wins.

use super::iwe::{evaluate, Canvas, Events, SplatTable, Workspace};
use super::newton::ascend;
use super::votes::{vote, VoteScratch, MAX_STARTS};
use super::{MotionParams, Objective, SearchMethod, Splat};
use crate::estimate::corrsum::MIN_PEAK_PAIRS;
use crate::field::Status;
use crate::peak::{self, SubPixelFit};

/// Largest half-width, in steps, of the grid scanned at the top of the pyramid.
const TOP_HALF: i64 = 2;
/// Re-centrings allowed per level before moving on.
const MAX_CLIMB: usize = 6;
/// The vote map spans the vote's range in this many cells per half-width (at least the
/// coarse step each).
const VOTE_CELLS: f64 = 16.0;
/// A candidate start is climbed where Σ I² there is at least this fraction of the best
/// maximum's height above the lowest value seen.
const COMPETES: f64 = 0.5;

/// Peak ratios below this flag the window [`Status::LOW_PEAK_RATIO`]: two velocities explain
/// its events about equally well, and the higher one is no better evidence than the other.
/// On the real wall flow (40 px, T = 10 ms, one pass), the six valid vectors with ratios
/// below 1.2 differ from sum of correlation by 0.23–1.15 px/ms, against a median of 0.065
/// px/ms for all.
const COMPARABLE: f64 = 1.2;
/// A maximum within a basin of zero velocity is flagged [`Status::LOW_PEAK_RATIO`] below
/// this ratio over the best maximum elsewhere (rather than [`COMPARABLE`]). Dense seeding
/// stacks repeated events of a pixel at zero velocity: on simulated uniform flows of
/// 10 px/ms (32 px windows, T = 10 ms, 0.05 particles/px, `ideal` sensor), the zero maxima
/// that beat the true one did so by ratios of 1.23–1.37, while correct maxima below 1.5 were
/// about 8 % of all (on flows of 2.5–10 px/ms); with this rule only for zero maxima, slow
/// flows, whose moving rivals are weak, keep their vectors.
const ZERO_COMPARABLE: f64 = 1.5;
/// Largest peak ratio reported: a peak [`MAX_RATIO`] times higher than anything else above
/// the background stands alone.
const MAX_RATIO: f64 = 1000.0;
/// The probes of the background lie this many basin half-widths from the best maximum.
const PROBE: f64 = 2.0;

/// The maximum with the highest value.
fn best_of(maxima: &[([f64; 2], f64)]) -> Option<([f64; 2], f64)> {
    maxima.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1))
}

/// The lowest objective value evaluated during a search: the background the peak ratio is
/// measured from.
#[derive(Debug, Clone, Copy)]
struct Seen {
    lowest: f64,
}

impl Default for Seen {
    fn default() -> Self {
        Seen {
            lowest: f64::INFINITY,
        }
    }
}

impl Seen {
    fn add(&mut self, value: f64) {
        if value.is_finite() {
            self.lowest = self.lowest.min(value);
        }
    }
}

/// First-to-second peak ratio of the objective: `best` against `rival`, both above
/// `background`, as the correlation peak ratio compares two peaks above zero. Near 1, two
/// velocities explain the events about equally well (locking, shear, too few particles); NaN
/// when neither rises above the background.
fn peak_ratio(best: f64, rival: f64, background: f64) -> f64 {
    let (a, b) = (best - background, rival - background);
    // NaN heights count as none.
    if a.is_nan() || a <= 0.0 {
        return f64::NAN;
    }
    // A rival at the background itself: the ratio is large but finite.
    a / b.max(a / MAX_RATIO)
}

/// Outcome of a search.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Outcome {
    pub velocity: [f64; 2],
    pub status: Status,
    pub peak: f64,
    pub peak_ratio: f64,
}

/// Per-thread search memory.
#[derive(Debug, Clone, Default)]
pub(crate) struct SearchScratch {
    pub work: Workspace,
    /// Evaluated lattice points of the current level: `(kx, ky, value)`.
    cache: Vec<(i64, i64, f64)>,
    map: Vec<f64>,
    votes: VoteScratch,
    /// Gradients of the blocks of warped events ([`super::uncertainty`]).
    gradients: Vec<[f64; 2]>,
    /// Events of the blocks of warped events.
    block_events: Vec<f64>,
}

/// The search of one window.
pub(crate) struct Search<'a> {
    pub events: &'a Events,
    pub window: [u32; 2],
    /// Size of the box `[0, extent)` holding every event (at least the window), px.
    pub extent: [u32; 2],
    pub centre: [f64; 2],
    /// Whether `centre` is a previous pass's prediction (else zero).
    pub predicted: bool,
    /// A start of the search besides the vote's (the velocity of a sum of correlation).
    pub start: Option<[f64; 2]>,
    /// Half-width of the search range, px/ms.
    pub range: f64,
    pub params: &'a MotionParams,
    pub fine: &'a SplatTable,
    pub coarse: &'a SplatTable,
}

impl Search<'_> {
    /// Run the search. `None` if the canvas would be unreasonably large (absurd predictor).
    pub fn run(&self, s: &mut SearchScratch) -> Option<Outcome> {
        let p = self.params;
        s.work.forget_events();
        let t_max = self.events.t.iter().fold(0f32, |m, t| m.max(t.abs())) as f64;
        // Refinement halvings: the last step is the smallest coarse_step / 2^m ≥ final_step.
        let mut refinements = 0u32;
        while p.coarse_step / f64::from(1u32 << (refinements + 1)) >= p.final_step * (1.0 - 1e-9) {
            refinements += 1;
        }
        let unit = p.coarse_step / f64::from(1u32 << refinements);
        let n_coarse = ((self.range / p.coarse_step) - 1e-9).ceil().max(1.0) as i64;
        let limit = n_coarse << refinements;
        // Pyramid height: cells no larger than an eighth of the window.
        let bin = |level: u32| (f64::from(1u32 << level) * p.coarse_step * t_max * 0.8).max(1.0);
        let max_bin = (self.window[0].min(self.window[1]) as f64 / 8.0).max(1.0);
        let mut top = 0u32;
        while (n_coarse + (1 << top) - 1) >> top > TOP_HALF && bin(top + 1) <= max_bin {
            top += 1;
        }
        let max_speed = [
            self.centre[0].abs() + limit as f64 * unit,
            self.centre[1].abs() + limit as f64 * unit,
        ];
        let shift = [max_speed[0] * t_max, max_speed[1] * t_max];
        let fine_canvas = Canvas::covering(self.extent, shift, 1.0, self.fine);
        if fine_canvas.width.max(fine_canvas.height) > 16_384 {
            return None;
        }
        if self.newton_applies() {
            if let Some(out) = self.newton(limit as f64 * unit, t_max, s) {
                return Some(out);
            }
        }
        // Level `l` of the pyramid: lattice step 2^(refinements + l) units.
        let level_step = |l: u32| 1i64 << (refinements + l);
        // The configured splat below the coarse step; bilinear cells matched to the step above
        // and at it (the refinement re-centres on the configured splat's maximum).
        let canvas_of = |l: u32| {
            if l == 0 && top == 0 {
                (fine_canvas, self.fine)
            } else {
                (
                    Canvas::covering(self.extent, shift, bin(l), self.coarse),
                    self.coarse,
                )
            }
        };

        // 1. Full scan at the top level.
        let (canvas, table) = canvas_of(top);
        let step = level_step(top);
        let half = limit / step;
        let side = (2 * half + 1) as usize;
        s.cache.clear();
        s.map.clear();
        let mut best = (0i64, 0i64, f64::NEG_INFINITY);
        for j in -half..=half {
            for i in -half..=half {
                let k = (i * step, j * step);
                let value = self.value(k, unit, &canvas, table, &mut s.work);
                s.map.push(value);
                s.cache.push((k.0, k.1, value));
                if value > best.2 {
                    best = (k.0, k.1, value);
                }
            }
        }
        let (lo, hi) = s
            .map
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        if !(hi.is_finite() && lo.is_finite()) || hi - lo <= 1e-12 * hi.abs().max(1e-300) {
            return Some(Outcome {
                velocity: [f64::NAN; 2],
                status: Status::NO_PEAK,
                peak: hi,
                peak_ratio: f64::NAN,
            });
        }
        s.map.iter_mut().for_each(|v| *v -= lo);
        let peak_ratio = peak::find_peak(&s.map, side, side, SubPixelFit::Parabolic3, 1)
            .map_or(f64::NAN, |pk| pk.ratio());

        // 2. Down the pyramid to the coarse step, then refine.
        for l in (0..top).rev() {
            let (canvas, table) = canvas_of(l);
            s.cache.clear();
            best = self.climb(best, level_step(l), 2, limit, unit, &canvas, table, s);
        }
        let mut status = Status::VALID;
        if best.0.abs() >= limit || best.1.abs() >= limit {
            status = Status::OUT_OF_RANGE;
        }
        if top > 0 {
            s.cache.clear();
            best.2 = self.cached((best.0, best.1), unit, &fine_canvas, self.fine, s);
        }
        for m in 1..=refinements {
            let step = 1 << (refinements - m);
            best = self.climb(best, step, 1, limit, unit, &fine_canvas, self.fine, s);
        }
        // The given start (a sum of correlation): the scan's coarse cells blur a narrow
        // maximum away where a broad false one (zero velocity in dense seeding) stands beside
        // it, so the same climb, from the coarse step down, also runs from the start's lattice
        // point, and the higher of the two maxima wins.
        if let Some(start) = self.start {
            let snap = |a: f64, c: f64| {
                let k = ((a - c) / unit).round();
                if k.is_finite() {
                    (k as i64).clamp(-limit, limit)
                } else {
                    0
                }
            };
            let k = (
                snap(start[0], self.centre[0]),
                snap(start[1], self.centre[1]),
            );
            let value = self.cached(k, unit, &fine_canvas, self.fine, s);
            let coarse = 1 << refinements;
            let mut other = self.climb(
                (k.0, k.1, value),
                coarse,
                2,
                limit,
                unit,
                &fine_canvas,
                self.fine,
                s,
            );
            let on_edge = other.0.abs() >= limit || other.1.abs() >= limit;
            for m in 1..=refinements {
                let step = 1 << (refinements - m);
                other = self.climb(other, step, 1, limit, unit, &fine_canvas, self.fine, s);
            }
            if other.2 > best.2 {
                best = other;
                status = if on_edge {
                    Status::OUT_OF_RANGE
                } else {
                    Status::VALID
                };
            }
        }

        // 3. Sub-grid fit through the best lattice point.
        let mut at = |dx: i64, dy: i64| {
            let k = (best.0 + dx, best.1 + dy);
            self.cached(k, unit, &fine_canvas, self.fine, s)
        };
        let fit = p.fit;
        let mut offset = None;
        if fit == SubPixelFit::Gaussian2d {
            let mut n = [[0.0; 3]; 3];
            for (r, row) in n.iter_mut().enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = at(c as i64 - 1, r as i64 - 1);
                }
            }
            offset = peak::gaussian_2d(n);
        }
        let offset = offset.unwrap_or_else(|| {
            let fit = fit.per_axis();
            let b = best.2;
            let dx = peak::three_point(at(-1, 0), b, at(1, 0), fit).unwrap_or(0.0);
            let dy = peak::three_point(at(0, -1), b, at(0, 1), fit).unwrap_or(0.0);
            (dx, dy)
        });
        Some(Outcome {
            velocity: [
                self.centre[0] + (best.0 as f64 + offset.0) * unit,
                self.centre[1] + (best.1 as f64 + offset.1) * unit,
            ],
            status,
            peak: best.2,
            peak_ratio,
        })
    }

    /// Standard uncertainty, px/ms per component, of `velocity`, the maximum the search
    /// found ([`super::uncertainty::velocity_sigma`]); NaN where the search is not the
    /// Newton search of Σ I² (the grid search's other objectives have no derivatives).
    pub fn uncertainty(&self, velocity: [f64; 2], s: &mut SearchScratch) -> [f64; 2] {
        if !self.newton_applies() || velocity.iter().any(|v| !v.is_finite()) {
            return [f64::NAN; 2];
        }
        let t_max = self.events.t.iter().fold(0f32, |m, t| m.max(t.abs())) as f64;
        let shift = velocity.map(|v| (v.abs() + 1.0) * t_max);
        let canvas = Canvas::covering(self.extent, shift, 1.0, self.fine);
        if canvas.width.max(canvas.height) > 16_384 {
            return [f64::NAN; 2];
        }
        super::uncertainty::velocity_sigma(
            self.events,
            velocity,
            &canvas,
            self.fine,
            &mut s.work,
            (&mut s.gradients, &mut s.block_events),
        )
    }

    /// Whether [`SearchMethod::Newton`] is configured and the objective has the derivatives
    /// it needs (Σ I² or the variance of a Gaussian-splatted IWE).
    fn newton_applies(&self) -> bool {
        let p = self.params;
        p.search == SearchMethod::Newton
            && matches!(p.splat, Splat::Gaussian { .. })
            && matches!(p.objective, Objective::Variance | Objective::SumOfSquares)
    }

    /// Newton ascents of Σ I² from the candidates for the global maximum inside
    /// `centre ± extent`, wider than the search box `centre ± half`: first the most trusted
    /// start (the given one, else the predictor, else the vote's best peak), then the vote's
    /// other peaks (up to `W / t_max` from the centre) and zero velocity, each climbed only
    /// where its value competes with the best maximum so far. The highest maximum wins; one
    /// outside the box is out of range, one at zero velocity needs [`ZERO_COMPARABLE`]. `None` if the canvas would be unreasonably large: the grid search
    /// decides.
    ///
    /// The objective's own evidence gives the peak ratio ([`peak_ratio`]): the winner against
    /// the best value seen outside its basin (other maxima, candidates, two probes of the
    /// background), both above the lowest value evaluated.
    fn newton(&self, half: f64, t_max: f64, s: &mut SearchScratch) -> Option<Outcome> {
        let p = self.params;
        // Beyond the box by its half-width, at least 2 px/ms: a maximum outside is found
        // there and flagged, not clamped to the border, where a lower maximum inside the
        // box would win.
        let extent = half + half.max(2.0);
        let shift = [
            (self.centre[0].abs() + extent) * t_max,
            (self.centre[1].abs() + extent) * t_max,
        ];
        let canvas = Canvas::covering(self.extent, shift, 1.0, self.fine);
        if canvas.width.max(canvas.height) > 16_384 {
            return None;
        }
        let invalid = |status, ratio| Outcome {
            velocity: [f64::NAN; 2],
            status,
            peak: f64::NAN,
            peak_ratio: ratio,
        };
        // The vote's pairs lie at least a quarter of the events' time span apart, so it sees
        // velocities up to about the window's size per half slab, `W / t_max` (twice the
        // velocity at which a particle crosses the window within the slab): a map wider than
        // that would only coarsen its cells.
        let crossing = f64::from(self.window[0].max(self.window[1])) / t_max.max(1e-3);
        let vote_extent = extent.min(crossing);
        let cell = p.coarse_step.max(vote_extent / VOTE_CELLS);
        // The vote may have no start: every pair inside one pixel (slow flow) or outside the
        // range. The centre is then the only start.
        vote(self.events, self.centre, vote_extent, cell, &mut s.votes);
        // Starts lie on vote cells, which may reach past the range by part of a cell: clamp
        // them to the range the canvas covers.
        let (c, e) = (self.centre, extent);
        let clamp = |v: [f64; 2]| {
            [
                v[0].clamp(c[0] - e, c[0] + e),
                v[1].clamp(c[1] - e, c[1] + e),
            ]
        };
        let basin = self.basin(t_max);
        let mut seen = Seen::default();
        // Maxima found, (velocity, Σ I²): one per start at most.
        let mut found = [([0.0; 2], f64::NEG_INFINITY); MAX_STARTS + 2];
        let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) <= basin;
        // The most trusted start: the given one (a sum of correlation), else the predictor,
        // else the vote's best, else the centre. Climbed first.
        let votes = &s.votes.starts[..s.votes.starts.len().min(MAX_STARTS)];
        let (first, others) = match self.start.or(self.predicted.then_some(self.centre)) {
            Some(start) => (start, votes),
            None => match votes.split_first() {
                Some((&best, rest)) => (best, rest),
                None => (self.centre, votes),
            },
        };
        let mut candidates = [[0.0; 2]; MAX_STARTS + 1];
        let mut n = 0;
        for &v in others {
            candidates[n] = clamp(v);
            n += 1;
        }
        if !self.predicted {
            candidates[n] = self.centre;
            n += 1;
        }
        let top = self.ascend(clamp(first), extent, &canvas, s);
        seen.add(top.1);
        found[0] = top;
        let mut count = 1;
        // Two plain evaluations twice the basin's half-width from that maximum, on either
        // side, sample the background the peak stands on.
        let mut samples = [([0.0; 2], f64::NEG_INFINITY); MAX_STARTS + 3];
        for (sample, side) in samples.iter_mut().zip([PROBE, -PROBE]) {
            let d = side * basin * std::f64::consts::FRAC_1_SQRT_2;
            let at = clamp([top.0[0] + d, top.0[1] + d]);
            *sample = (at, self.squares(at, &canvas, s));
            seen.add(sample.1);
        }
        // The other candidates (the vote's other peaks, zero velocity): one plain evaluation
        // each, and an ascent where the value competes with the best maximum so far (a
        // narrow true maximum, or a slow flow whose pairs lie inside one pixel and do not
        // vote); those in the basin of a maximum found are skipped.
        let mut sampled = 2;
        for &start in &candidates[..n] {
            if found[..count].iter().any(|m| near(m.0, start)) {
                continue;
            }
            let value = self.squares(start, &canvas, s);
            seen.add(value);
            samples[sampled] = (start, value);
            sampled += 1;
            let best = best_of(&found[..count]).map_or(f64::NEG_INFINITY, |m| m.1);
            if value - seen.lowest >= COMPETES * (best - seen.lowest) {
                let top = self.ascend(start, extent, &canvas, s);
                seen.add(top.1);
                found[count] = top;
                count += 1;
            }
        }
        let Some((velocity, squares)) = best_of(&found[..count]) else {
            return Some(invalid(Status::NO_PEAK, f64::NAN));
        };
        // The rival: the highest value seen outside the winner's basin (another maximum, a
        // candidate, a probe).
        let rival = found[..count]
            .iter()
            .chain(&samples)
            .filter(|(v, _)| !near(*v, velocity))
            .fold(f64::NEG_INFINITY, |r, m| r.max(m.1));
        let ratio = peak_ratio(squares, rival, seen.lowest);
        let height = squares - seen.lowest;
        if height.is_nan() || height <= 0.0 {
            return Some(invalid(Status::NO_PEAK, ratio));
        }
        // The events the maximum brings together: pairs of events that coincide there
        // beyond the background ([`SplatTable::point_energy`]), as many as sum of
        // correlation asks of its peak.
        let pairs = |rise: f64| rise / (2.0 * self.fine.point_energy());
        if pairs(height) < MIN_PEAK_PAIRS {
            return Some(invalid(Status::FEW_EVENTS, ratio));
        }
        // A maximum that claims motion, half a pixel or more over the events' time span, must
        // also bring that many more pairs together than rest does: where the particles move
        // a fraction of a pixel, the contrast is about as high anywhere within a pixel per
        // slab of zero, and chance alignments of neighbouring pixels' events place the
        // maximum there.
        let moves = velocity[0].hypot(velocity[1]) * 2.0 * t_max >= 0.5;
        let tested_at_rest = self.predicted && !near(velocity, [0.0; 2]);
        // Zero velocity is one of the candidates without a prediction, and was evaluated
        // unless it lay in the basin of a maximum found.
        let at_rest = if moves || tested_at_rest {
            match samples[..sampled].iter().find(|(v, _)| *v == [0.0; 2]) {
                Some(&(_, value)) => value,
                None => self.squares([0.0; 2], &canvas, s),
            }
        } else {
            f64::NAN
        };
        if moves && pairs(squares - at_rest) < MIN_PEAK_PAIRS {
            return Some(invalid(Status::LOW_PEAK_RATIO, ratio));
        }
        if ratio < COMPARABLE {
            return Some(invalid(Status::LOW_PEAK_RATIO, ratio));
        }
        // A maximum at zero velocity must stand higher above a moving one: pixels that fire
        // several times, whether as one particle passes or as several particles pass within
        // the slab, raise the contrast at zero velocity whatever the flow.
        if near(velocity, [0.0; 2]) {
            let moving = found[..count]
                .iter()
                .filter(|(v, _)| !near(*v, velocity) && !near(*v, [0.0; 2]))
                .fold(f64::NEG_INFINITY, |r, m| r.max(m.1));
            if peak_ratio(squares, moving, seen.lowest) < ZERO_COMPARABLE {
                return Some(invalid(Status::LOW_PEAK_RATIO, ratio));
            }
        }
        // Around a prediction the search sees only its neighbourhood. Where the events are
        // far sharper at rest than anywhere near the prediction, the prediction is wrong
        // for this window (a coarser pass's window that reached into faster flow), and the
        // maximum near it is a local one: one plain evaluation at zero velocity (which the
        // canvas covers) tells, with the margin a zero maximum needs over a moving one.
        if tested_at_rest {
            let lowest = seen.lowest.min(at_rest);
            if peak_ratio(at_rest, squares, lowest) >= ZERO_COMPARABLE {
                return Some(invalid(
                    Status::LOW_PEAK_RATIO,
                    peak_ratio(squares, at_rest, lowest),
                ));
            }
        }
        // Within half a refinement step of the border counts as on it, as for the grid's
        // last lattice point.
        let edge = half - 0.5 * p.final_step;
        let outside_range = (velocity[0] - self.centre[0]).abs() >= edge
            || (velocity[1] - self.centre[1]).abs() >= edge;
        if outside_range {
            return Some(invalid(Status::OUT_OF_RANGE, ratio));
        }
        let peak = match p.objective {
            Objective::Variance => {
                let (cells, n) = (canvas.cells() as f64, self.events.t.len() as f64);
                squares / cells - (n / cells) * (n / cells)
            }
            _ => squares,
        };
        Some(Outcome {
            velocity,
            status: Status::VALID,
            peak,
            peak_ratio: ratio,
        })
    }

    /// Half-width of a maximum of Σ I² in velocity, px/ms: two maxima closer than this are
    /// one. A particle image of about a pixel, splatted with σ, stays within about
    /// `2σ + 1` px of itself while the velocity is off by less than that over the events'
    /// largest time offset `t_max`, so the peak is about particle size / T wide; never below
    /// two refinement steps.
    fn basin(&self, t_max: f64) -> f64 {
        let sigma = match self.params.splat {
            Splat::Gaussian { sigma } => sigma,
            Splat::Bilinear => 0.5,
        };
        ((2.0 * sigma + 1.0) / t_max.max(1e-3)).max(2.0 * self.params.final_step)
    }

    /// Newton ascent of Σ I² from `start` within `centre ± extent`: the maximum and its value.
    fn ascend(
        &self,
        start: [f64; 2],
        extent: f64,
        canvas: &Canvas,
        s: &mut SearchScratch,
    ) -> ([f64; 2], f64) {
        let top = ascend(
            self.events,
            start,
            self.centre,
            extent,
            canvas,
            self.fine,
            &mut s.work,
        );
        (top.velocity, top.squares)
    }

    /// Σ I² at `velocity` on `canvas` (one plain evaluation).
    fn squares(&self, velocity: [f64; 2], canvas: &Canvas, s: &mut SearchScratch) -> f64 {
        evaluate(
            self.events,
            velocity,
            canvas,
            self.fine,
            Objective::SumOfSquares,
            &mut s.work,
        )
    }

    /// Objective at lattice point `k`.
    fn value(
        &self,
        k: (i64, i64),
        unit: f64,
        canvas: &Canvas,
        table: &SplatTable,
        work: &mut Workspace,
    ) -> f64 {
        let velocity = [
            self.centre[0] + k.0 as f64 * unit,
            self.centre[1] + k.1 as f64 * unit,
        ];
        evaluate(
            self.events,
            velocity,
            canvas,
            table,
            self.params.objective,
            work,
        )
    }

    /// Objective at `k`, from the level's cache if evaluated before.
    fn cached(
        &self,
        k: (i64, i64),
        unit: f64,
        canvas: &Canvas,
        table: &SplatTable,
        s: &mut SearchScratch,
    ) -> f64 {
        if let Some(&(_, _, v)) = s.cache.iter().find(|c| (c.0, c.1) == k) {
            return v;
        }
        let v = self.value(k, unit, canvas, table, &mut s.work);
        s.cache.push((k.0, k.1, v));
        v
    }

    /// Hill-climb on (2 `reach` + 1)² neighbourhoods of spacing `step` inside `±limit`,
    /// re-centring while the best point lies on the neighbourhood's border.
    #[allow(clippy::too_many_arguments)]
    fn climb(
        &self,
        start: (i64, i64, f64),
        step: i64,
        reach: i64,
        limit: i64,
        unit: f64,
        canvas: &Canvas,
        table: &SplatTable,
        s: &mut SearchScratch,
    ) -> (i64, i64, f64) {
        let mut centre = start;
        for _ in 0..MAX_CLIMB {
            let mut best = (centre.0, centre.1, f64::NEG_INFINITY);
            for j in -reach..=reach {
                for i in -reach..=reach {
                    let k = (centre.0 + i * step, centre.1 + j * step);
                    if k.0.abs() > limit || k.1.abs() > limit {
                        continue;
                    }
                    let v = self.cached(k, unit, canvas, table, s);
                    if v > best.2 {
                        best = (k.0, k.1, v);
                    }
                }
            }
            let on_border = (best.0 - centre.0).abs() == reach * step
                || (best.1 - centre.1).abs() == reach * step;
            centre = best;
            if !on_border {
                break;
            }
        }
        centre
    }
}

#[cfg(test)]
mod timing {
    use super::*;
    use crate::estimate::motion::test_events::trails;
    use crate::estimate::motion::MotionParams;

    #[test]
    #[ignore = "timing printout, not a pass/fail test (timed assertions are not allowed): run with --release -- --ignored --nocapture"]
    fn time_search_methods() {
        let cases: Vec<([f64; 2], Events)> = (0..40)
            .map(|k| {
                let vel = [0.17 * k as f64 - 3.3, 2.1 - 0.11 * k as f64];
                (vel, trails(vel, k + 1))
            })
            .collect();
        {
            let mut vs = VoteScratch::default();
            let start = std::time::Instant::now();
            let mut sum = 0.0;
            for _ in 0..20 {
                for (_, events) in &cases {
                    vote(events, [0.0, 0.0], 8.0, 0.5, &mut vs);
                    sum += vs.starts.len() as f64;
                }
            }
            eprintln!(
                "vote: {:.1} µs per window ({sum})",
                start.elapsed().as_secs_f64() * 1e6 / (20 * cases.len()) as f64
            );
        }
        for search in [SearchMethod::Grid, SearchMethod::Newton] {
            let params = MotionParams {
                search,
                ..MotionParams::default()
            };
            let (fine, coarse) = (
                SplatTable::new(params.splat),
                SplatTable::new(Splat::Bilinear),
            );
            let mut s = SearchScratch::default();
            let (mut sq, mut bad) = (0.0, 0);
            let start = std::time::Instant::now();
            let reps = 20;
            for _ in 0..reps {
                for (vel, events) in &cases {
                    let search = Search {
                        events,
                        window: [40, 40],
                        extent: [40, 40],
                        centre: [0.0, 0.0],
                        predicted: false,
                        start: None,
                        range: 4.0,
                        params: &params,
                        fine: &fine,
                        coarse: &coarse,
                    };
                    let out = search.run(&mut s).unwrap();
                    let e = (out.velocity[0] - vel[0]).hypot(out.velocity[1] - vel[1]);
                    if e.is_finite() && e < 0.2 {
                        sq += e * e;
                    } else {
                        bad += 1;
                        if bad <= 12 {
                            eprintln!("{vel:?} -> {:?} {:?}", out.velocity, out.status);
                        }
                    }
                }
            }
            let windows = (reps * cases.len()) as f64;
            let per_window = start.elapsed().as_secs_f64() * 1e6 / windows;
            let evaluations = s.work.evaluations as f64 / windows;
            eprintln!(
                "{search:?}: {per_window:.1} µs per window, {evaluations:.1} evaluations per \
                 window ({:.2} µs each), rms error {:.4} px/ms, {bad} failures",
                per_window / evaluations,
                (sq / (windows - bad as f64)).sqrt()
            );
        }
    }
}
