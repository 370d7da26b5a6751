//! Adaptive time slabs (`--slab auto`): each window is measured over the slab T that moves
//! its particles by about the same displacement, whatever their speed.
//!
//! With one slab for the whole field, slow regions move too little within it to be measured
//! precisely, fast regions move too far for the estimator's range, and short slabs leave
//! slow windows too few events (Willert & Klinner, Exp. Fluids 63:101, 2022, §5, name
//! adaptive slabs as the method still to be developed). PIV answers the same problem with a
//! time separation per window chosen from a first evaluation (Hain & Kähler, Exp. Fluids
//! 42:575, 2007); here the slab plays the role of the separation.
//!
//! [`AdaptiveSlab`] holds one estimator per slab of a geometric ladder from
//! [`AdaptiveSlabParams::min_us`] to [`AdaptiveSlabParams::max_us`] (steps of √2, so the
//! displacement over the chosen slab lies within a factor 2^¼ of the target):
//! - without one (a first pass), it is measured over the probe slab
//!   [`AdaptiveSlabParams::probe_us`], then over the slab its velocity chooses, until two
//!   measurements over different slabs, each without predictor, agree
//!   (`AdaptiveSlab::first_pass`); a probe that fails is first repeated over a slab four
//!   times longer (too few events, no peak) or shorter (beyond the estimator's range);
//! - with a predictor (a later pass), the window takes the slab whose predicted
//!   displacement |v|·T is nearest [`AdaptiveSlabParams::displacement_px`] (the next longer
//!   slabs, up to two steps, where that one has too few events). Where it still fails, or
//!   measures a velocity that asks for a slab more than one step away, the window finds its
//!   slab as a first pass does. Over slabs longer than the probe's the predictor's gradient
//!   does not deform the events (`AdaptiveSlab::guide`).
//!
//! The fields stay on one regular time grid (planned with the probe slab,
//! [`Estimator::planning_extent_us`]); every vector records the slab it was measured over
//! ([`WindowEstimate::slab_us`]). A slab never reaches past the events of the recording:
//! near its ends the longest slabs are shortened to what the data around the field time hold.

use super::{Estimator, Prediction, WindowEstimate};
use crate::error::{Error, Result};
use crate::field::Status;
use crate::grid::Window;
use crate::volume::Slab;

/// Ratio of successive slabs of the ladder.
const LADDER_RATIO: f64 = std::f64::consts::SQRT_2;
/// Ladder steps between a failed probe and its retry (4× longer or shorter).
const RETRY_STEPS: usize = 4;
/// Longer slabs tried at most when the chosen one has too few events.
const MORE_EVENTS_STEPS: usize = 2;
/// Measurements of a first-pass window after the probe, at most, looking for two that
/// agree.
const MAX_CONFIRMATIONS: usize = 3;
/// Ladder steps to the slab that confirms an estimate over the slab it chose (2: half as
/// long).
const CONFIRM_STEPS: usize = 2;

/// Two velocities measured over different slabs agree within this displacement over each
/// slab, px: several times the random error of either estimator (0.02–0.1 px over the
/// slab or delay), but a small part of the range over which a spurious peak falls.
const AGREEMENT_PX: f64 = 0.2;
/// … plus this share of the speed (a velocity gradient across the window weighs the
/// particles differently over slabs of different length).
const AGREEMENT_SHARE: f64 = 0.05;

/// Whether two estimates over different slabs give the same velocity: within
/// [`AGREEMENT_PX`] of displacement over each slab plus [`AGREEMENT_SHARE`] of the speed.
fn agree(a: &WindowEstimate, b: &WindowEstimate) -> bool {
    let px_per_ms = |e: &WindowEstimate| AGREEMENT_PX / (e.slab_us.max(1) as f64 / 1000.0);
    let tolerance = px_per_ms(a) + px_per_ms(b) + AGREEMENT_SHARE * speed(a).max(speed(b));
    (a.u - b.u).hypot(a.v - b.v) <= tolerance
}

/// The speed of an estimate, px/ms.
fn speed(e: &WindowEstimate) -> f64 {
    e.u.hypot(e.v)
}

/// The bounds and target of [`AdaptiveSlab`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveSlabParams {
    /// Shortest slab, µs: nothing finer than the sensor's latency can resolve.
    pub min_us: i64,
    /// Longest slab, µs.
    pub max_us: i64,
    /// Slab of a window without predictor (a first pass), µs, before its own velocity
    /// chooses one.
    pub probe_us: i64,
    /// Displacement over the slab, |v|·T, px, that the choice aims at (from below).
    pub displacement_px: f64,
}

impl Default for AdaptiveSlabParams {
    fn default() -> Self {
        AdaptiveSlabParams {
            min_us: 1_000,
            max_us: 200_000,
            probe_us: 10_000,
            displacement_px: 20.0,
        }
    }
}

impl AdaptiveSlabParams {
    /// Reject bounds that cannot hold a ladder, naming the setting.
    pub fn validate(&self) -> Result<()> {
        if self.min_us <= 0 {
            return Err(Error::parameter(
                "slab-min",
                format!("must be positive, got {} µs", self.min_us),
            ));
        }
        if self.max_us < self.min_us {
            return Err(Error::parameter(
                "slab-max",
                format!(
                    "must be at least slab-min ({} µs), got {} µs",
                    self.min_us, self.max_us
                ),
            ));
        }
        if !(self.min_us..=self.max_us).contains(&self.probe_us) {
            return Err(Error::parameter(
                "slab-probe",
                format!(
                    "must lie between slab-min ({} µs) and slab-max ({} µs), got {} µs",
                    self.min_us, self.max_us, self.probe_us
                ),
            ));
        }
        if !(self.displacement_px.is_finite() && self.displacement_px > 0.0) {
            return Err(Error::parameter(
                "slab-displacement",
                format!(
                    "must be a positive number of px, got {}",
                    self.displacement_px
                ),
            ));
        }
        Ok(())
    }

    /// The slabs of the ladder, µs, ascending: `min · √2^k` below `max`, then `max` and the
    /// probe slab itself.
    pub fn ladder(&self) -> Vec<i64> {
        let mut slabs = Vec::new();
        let mut t = self.min_us as f64;
        while t < self.max_us as f64 * 0.999 {
            slabs.push(t.round() as i64);
            t *= LADDER_RATIO;
        }
        slabs.push(self.max_us);
        slabs.push(self.probe_us);
        slabs.sort_unstable();
        slabs.dedup();
        slabs
    }
}

/// One estimator per slab of a ladder, each window measured over the slab its velocity
/// chooses. See the module documentation.
#[derive(Debug, Clone)]
pub struct AdaptiveSlab<E> {
    params: AdaptiveSlabParams,
    /// Slabs, µs, ascending.
    slabs: Vec<i64>,
    /// The estimator of each slab.
    estimators: Vec<E>,
    /// Index of the probe slab.
    probe: usize,
}

impl<E: Estimator> AdaptiveSlab<E> {
    /// The ladder of `params`, with the estimator of each slab made by `make(slab_us)`.
    pub fn new(params: AdaptiveSlabParams, make: impl Fn(i64) -> Result<E>) -> Result<Self> {
        params.validate()?;
        let slabs = params.ladder();
        let estimators = slabs.iter().map(|&t| make(t)).collect::<Result<Vec<_>>>()?;
        let probe = slabs
            .iter()
            .position(|&t| t == params.probe_us)
            .expect("the ladder holds the probe slab");
        Ok(AdaptiveSlab {
            params,
            slabs,
            estimators,
            probe,
        })
    }

    /// The slabs of the ladder, µs, ascending.
    pub fn slabs(&self) -> &[i64] {
        &self.slabs
    }

    /// The bounds and target.
    pub fn params(&self) -> &AdaptiveSlabParams {
        &self.params
    }

    /// The slab (index) whose displacement at `speed` px/ms is nearest the target (on a
    /// log scale: within a factor 2^¼ on the ladder of √2), at most `longest`.
    pub fn slab_for_speed(&self, speed: f64, longest: usize) -> usize {
        let ideal_ms = self.params.displacement_px / speed;
        if !(ideal_ms.is_finite() && ideal_ms > 0.0) {
            return longest; // at rest, or too slow for any slab
        }
        let mismatch = |k: &usize| (self.slabs[*k] as f64 / 1000.0 / ideal_ms).ln().abs();
        (0..=longest)
            .min_by(|a, b| mismatch(a).total_cmp(&mismatch(b)))
            .unwrap_or(0)
    }

    /// The longest slab (index) that the events of `slab` cover around `t0_us`: a slab
    /// centred at `t0_us` reaching past the first or last event would hold events on one
    /// side only. At least the shortest slab.
    fn longest_covered(&self, slab: &Slab, t0_us: i64) -> usize {
        let Some((first, last)) = slab.event_span_us() else {
            return self.slabs.len() - 1;
        };
        let reach = (t0_us - first).min(last + 1 - t0_us);
        // Each estimator's own extent around t0 (sum of correlation reaches (T + τ)/2).
        let fits = |k: &usize| {
            let (before, after) = self.estimators[*k].time_extent_us();
            before.max(after) <= reach
        };
        (0..self.slabs.len()).rev().find(fits).unwrap_or(0)
    }

    /// A window without predictor: measured over the probe slab, then over the slab its
    /// velocity chooses, until two measurements over different slabs agree. Each
    /// measurement is made without predictor, so an agreement is independent evidence: a
    /// spurious peak (too little motion in a slab, or too much) falls at a velocity that
    /// another slab does not repeat. When the chosen slab is the one just measured, the
    /// confirmation comes from a slab half as long (twice as long at the shortest).
    /// Velocities that never agree within [`MAX_CONFIRMATIONS`] give the last estimate,
    /// flagged [`Status::LOW_PEAK_RATIO`]: the evidence does not single out one velocity.
    fn first_pass(
        &self,
        at: (&Slab, &Window, i64),
        longest: usize,
        scratch: &mut AdaptiveScratch<E::Scratch>,
    ) -> WindowEstimate {
        let mut k = self.probe.min(longest);
        let mut e = self.estimate_over(k, at, None, scratch);
        if !e.status.is_valid() {
            let retry = if e.status.contains(Status::OUT_OF_RANGE) {
                k.saturating_sub(RETRY_STEPS)
            } else {
                (k + RETRY_STEPS).min(longest)
            };
            if retry == k {
                return e;
            }
            k = retry;
            e = self.estimate_over(k, at, None, scratch);
            if !e.status.is_valid() {
                return e;
            }
        }
        self.settle(at, longest, (k, e), true, scratch)
    }

    /// From estimate `e` over slab `k`: measure again, without predictor, over the slab
    /// its velocity chooses until two measurements over different slabs agree (see
    /// [`AdaptiveSlab::first_pass`]). With `confirm_same` false (`e` measured over the slab
    /// a predictor chose), an estimate whose velocity chooses the same slab or a neighbour
    /// is accepted: the predictor already agrees with it, unless the slab it asks for is
    /// longer than the events allow.
    fn settle(
        &self,
        at: (&Slab, &Window, i64),
        longest: usize,
        (mut k, mut e): (usize, WindowEstimate),
        mut confirm_same: bool,
        scratch: &mut AdaptiveScratch<E::Scratch>,
    ) -> WindowEstimate {
        for _ in 0..MAX_CONFIRMATIONS {
            let chosen = self.slab_for_speed(speed(&e), longest);
            // A velocity that asks for a longer slab than the events around the field time
            // hold (near the ends of a recording) is confirmed even over the predictor's.
            let capped = self.slab_for_speed(speed(&e), self.slabs.len() - 1) > longest;
            if !confirm_same && !capped && chosen.abs_diff(k) <= 1 {
                return e;
            }
            let other = if chosen != k {
                chosen
            } else if k >= CONFIRM_STEPS {
                k - CONFIRM_STEPS
            } else if k + CONFIRM_STEPS <= longest {
                k + CONFIRM_STEPS
            } else {
                return e;
            };
            let mut other = other;
            let mut f = self.estimate_over(other, at, None, scratch);
            if f.status.intersects(TOO_LITTLE_DATA) {
                if other != chosen {
                    // A confirming slab without enough events cannot contradict the estimate.
                    return e;
                }
                // The velocity chose a slab too short to hold enough events: fast flow
                // fires many events, so test the slower hypothesis over a longer slab.
                let longer = (k + RETRY_STEPS).min(longest);
                if longer <= k {
                    return f;
                }
                other = longer;
                f = self.estimate_over(other, at, None, scratch);
            }
            if !f.status.is_valid() {
                return f;
            }
            if agree(&e, &f) {
                return if other == chosen { f } else { e };
            }
            (k, e) = (other, f);
            confirm_same = true;
        }
        WindowEstimate {
            u: f64::NAN,
            v: f64::NAN,
            u_unc: f32::NAN,
            v_unc: f32::NAN,
            status: Status::LOW_PEAK_RATIO,
            ..e
        }
    }

    /// What the predictor tells the estimator over slab `k`: everything over slabs up to
    /// the probe's, from which the predictor was measured; over longer slabs its velocity
    /// only, without the deformation, whose error (a gradient from a coarser grid, blurred
    /// across a shear layer) would move the events by that error × the window × a slab
    /// several times longer than the one it was measured over.
    fn guide(&self, k: usize, predictor: Option<&Prediction>) -> Option<Prediction> {
        let p = *predictor?;
        Some(if self.slabs[k] > self.params.probe_us {
            Prediction {
                deformation: None,
                ..p
            }
        } else {
            p
        })
    }

    /// Measure over slab `k`, with its own scratch.
    fn estimate_over(
        &self,
        k: usize,
        (slab, window, t0_us): (&Slab, &Window, i64),
        predictor: Option<&Prediction>,
        scratch: &mut AdaptiveScratch<E::Scratch>,
    ) -> WindowEstimate {
        let estimator = &self.estimators[k];
        let dims = scratch.window;
        let skip = scratch.skip_uncertainty;
        let own = scratch.per_slab[k].get_or_insert_with(|| {
            let mut own = estimator.scratch(dims);
            estimator.skip_uncertainty(&mut own, skip);
            own
        });
        estimator.estimate(slab, window, t0_us, predictor, own)
    }
}

/// The working memory of every slab's estimator, made when first needed.
pub struct AdaptiveScratch<S> {
    window: [u32; 2],
    per_slab: Vec<Option<S>>,
    /// No per-vector uncertainty ([`Estimator::skip_uncertainty`]).
    skip_uncertainty: bool,
}

/// Statuses that a longer slab, holding more events, may cure.
const TOO_LITTLE_DATA: Status =
    Status(Status::NO_EVENTS.0 | Status::FEW_EVENTS.0 | Status::NO_PEAK.0);

impl<E: Estimator> Estimator for AdaptiveSlab<E> {
    type Scratch = AdaptiveScratch<E::Scratch>;

    fn name(&self) -> &'static str {
        self.estimators[0].name()
    }

    fn scratch(&self, window: [u32; 2]) -> Self::Scratch {
        AdaptiveScratch {
            window,
            per_slab: (0..self.slabs.len()).map(|_| None).collect(),
            skip_uncertainty: false,
        }
    }

    fn skip_uncertainty(&self, scratch: &mut Self::Scratch, skip: bool) {
        scratch.skip_uncertainty = skip;
        for (estimator, own) in self.estimators.iter().zip(&mut scratch.per_slab) {
            if let Some(own) = own {
                estimator.skip_uncertainty(own, skip);
            }
        }
    }

    /// The longest slab's extent: every slab of a field must be in memory.
    fn time_extent_us(&self) -> (i64, i64) {
        self.estimators
            .iter()
            .map(|e| e.time_extent_us())
            .fold((0, 0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
    }

    /// The probe slab's extent: fields are planned as for a fixed slab of that length.
    fn planning_extent_us(&self) -> (i64, i64) {
        self.estimators[self.probe].time_extent_us()
    }

    fn estimate(
        &self,
        slab: &Slab,
        window: &Window,
        t0_us: i64,
        predictor: Option<&Prediction>,
        scratch: &mut Self::Scratch,
    ) -> WindowEstimate {
        let at = (slab, window, t0_us);
        let longest = self.longest_covered(slab, t0_us);
        let predicted_speed = predictor.map(|p| p.velocity[0].hypot(p.velocity[1]));
        if let Some(speed) = predicted_speed.filter(|s| s.is_finite()) {
            let chosen = self.slab_for_speed(speed, longest);
            let mut k = chosen;
            let mut e = self.estimate_over(k, at, self.guide(k, predictor).as_ref(), scratch);
            for longer in (chosen + 1..=longest).take(MORE_EVENTS_STEPS) {
                if !e.status.intersects(TOO_LITTLE_DATA) {
                    break;
                }
                k = longer;
                e = self.estimate_over(k, at, self.guide(k, predictor).as_ref(), scratch);
            }
            // A restricted search (multiple-peak validation) is judged by the caller.
            if predictor.is_some_and(|p| p.search_radius.is_some()) {
                return e;
            }
            // No valid estimate over the slabs the predictor chose: the predictor may be
            // wrong (a coarser pass's window that reached into faster flow, whose particles
            // fire most of its events); the window finds its slab as a first pass does.
            if !e.status.is_valid() {
                return self.first_pass(at, longest, scratch);
            }
            return self.settle(at, longest, (k, e), false, scratch);
        }
        self.first_pass(at, longest, scratch)
    }

    fn parameters(&self) -> Vec<(String, String)> {
        let ms = |us: i64| crate::units::format_us(us);
        let mut p = self.estimators[self.probe].parameters();
        p.retain(|(name, _)| name != "slab");
        for (_, value) in p.iter_mut().filter(|(name, _)| name == "tau") {
            *value = format!("in proportion to the slab; {value} at the first pass's slab");
        }
        p.push((
            "slab".into(),
            format!(
                "auto: {} … {} (ladder of {} slabs, ratio √2), |v|·T ≤ {} px, first pass {}",
                ms(self.params.min_us),
                ms(self.params.max_us),
                self.slabs.len(),
                self.params.displacement_px,
                ms(self.params.probe_us)
            ),
        ));
        p
    }

    fn finds_secondary_peaks(&self) -> bool {
        self.estimators[0].finds_secondary_peaks()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::motion::{ContrastMaximization, MotionParams};
    use crate::event::{Geometry, PolaritySelection};

    fn motion_ladder(params: AdaptiveSlabParams) -> AdaptiveSlab<ContrastMaximization> {
        AdaptiveSlab::new(params, |slab_us| {
            ContrastMaximization::new(MotionParams {
                slab_us,
                ..MotionParams::default()
            })
        })
        .unwrap()
    }

    #[test]
    fn the_ladder_spans_the_bounds_in_steps_of_at_most_root_two() {
        let ladder = AdaptiveSlabParams::default().ladder();
        assert_eq!((ladder[0], *ladder.last().unwrap()), (1_000, 200_000));
        assert!(ladder.contains(&10_000), "the probe slab: {ladder:?}");
        for pair in ladder.windows(2) {
            let ratio = pair[1] as f64 / pair[0] as f64;
            assert!(ratio > 1.0 && ratio <= LADDER_RATIO * 1.001, "{ladder:?}");
        }
    }

    #[test]
    fn the_slab_moves_particles_by_about_the_target() {
        let adaptive = motion_ladder(AdaptiveSlabParams::default());
        let last = adaptive.slabs().len() - 1;
        let slab_ms =
            |speed: f64| adaptive.slabs()[adaptive.slab_for_speed(speed, last)] as f64 / 1000.0;
        for speed in [0.2, 1.0, 2.5, 5.0, 10.0] {
            let displacement = speed * slab_ms(speed);
            assert!(
                (16.8..=23.8).contains(&displacement),
                "{speed} px/ms: {displacement} px"
            );
        }
        // At rest or very slow: the longest slab; very fast: the shortest.
        assert_eq!(slab_ms(0.0), 200.0);
        assert_eq!(slab_ms(0.01), 200.0);
        assert_eq!(slab_ms(1000.0), 1.0);
        assert_eq!(
            adaptive.slab_for_speed(0.0, 3),
            3,
            "capped by the slabs that fit"
        );
    }

    #[test]
    fn bad_bounds_name_their_setting() {
        let bad = |p: AdaptiveSlabParams| p.validate().unwrap_err().to_string();
        let d = AdaptiveSlabParams::default();
        assert!(bad(AdaptiveSlabParams { min_us: 0, ..d }).contains("slab-min"));
        assert!(bad(AdaptiveSlabParams { max_us: 500, ..d }).contains("slab-max"));
        assert!(bad(AdaptiveSlabParams {
            probe_us: 500_000,
            ..d
        })
        .contains("slab-probe"));
        let nan = AdaptiveSlabParams {
            displacement_px: f64::NAN,
            ..d
        };
        assert!(bad(nan).contains("slab-displacement"));
    }

    /// Near the ends of a recording the longest slab is the one its events cover.
    #[test]
    fn slabs_stay_within_the_events_around_the_field_time() {
        let adaptive = motion_ladder(AdaptiveSlabParams::default());
        let t: Vec<i64> = (0..=100).map(|k| k * 1000).collect(); // 0 … 100 ms
        let n = t.len();
        let slab = Slab::build(
            &t,
            &vec![5; n],
            &vec![5; n],
            &vec![1; n],
            Geometry::new(16, 16),
            -200_000,
            300_000,
            PolaritySelection::Both,
            8,
        );
        assert_eq!(slab.event_span_us(), Some((0, 100_000)));
        let longest = |t0: i64| adaptive.slabs()[adaptive.longest_covered(&slab, t0)];
        assert_eq!(longest(50_000), 90_510); // ≤ 2 × 50 ms
        assert_eq!(longest(10_000), 16_000); // ≤ 2 × 10 ms
        assert_eq!(longest(-5_000), 1_000, "at least the shortest");
    }
}
