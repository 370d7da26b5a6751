//! The change detector of one pixel over one time step (sensor-model.md §2.1, §2.5): level
//! crossings of the low-passed log intensity, refractory period, jitter and latency.

use super::response::{clean_irradiance, Curve, Relaxation, Response};
use super::{PixelCounters, SimEvent};
use crate::sim::rng::{Rng, Stream};

/// Bit of [`Pixel::events`]: the pixel is blind (refractory) until `release`, then its
/// reference is reset.
const BLIND: u32 = 1 << 31;

/// Bit of [`Pixel::events`]: the pixel has a new input sample for the step being prepared.
const CHANGED: u32 = 1 << 30;

/// The bits of [`Pixel::events`] that count events.
const COUNT: u32 = CHANGED - 1;

/// State of one pixel: one cache line.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub(super) struct Pixel {
    /// Low-passed log intensity `L_lp` at time `t`.
    pub(super) l: f64,
    /// Reference level `L_ref` of the change detector.
    pub(super) l_ref: f64,
    /// Log response to `irr`, the input the low-pass relaxes to.
    pub(super) u: f64,
    /// Time of `l`, µs.
    pub(super) t: f64,
    /// Earliest time of the next comparator trip: previous trip + refractory period; the end
    /// of the blind time while blind.
    pub(super) release: f64,
    /// Frozen ON threshold θ_on(x).
    pub(super) theta_on: f64,
    /// Frozen OFF threshold θ_off(x).
    pub(super) theta_off: f64,
    /// Irradiance of the last sample.
    pub(super) irr: f32,
    /// Events emitted so far (30 bits, indexing the jitter stream) and the `BLIND` and
    /// `CHANGED` bits.
    events: u32,
}

impl Pixel {
    /// A pixel with thresholds `theta_on`, `theta_off`, adapted to log response `u` at `t`.
    pub(super) fn new(theta_on: f64, theta_off: f64) -> Self {
        Pixel {
            l: 0.0,
            l_ref: 0.0,
            u: 0.0,
            t: 0.0,
            release: f64::NEG_INFINITY,
            theta_on,
            theta_off,
            irr: 0.0,
            events: 0,
        }
    }

    /// Adapt to irradiance `irr` with log response `u` at time `t`: settled, not blind.
    pub(super) fn adapt(&mut self, irr: f32, u: f64, t: f64) {
        self.irr = irr;
        self.u = u;
        self.l = u;
        self.l_ref = u;
        self.t = t;
        self.release = f64::NEG_INFINITY;
        self.events &= COUNT;
    }

    /// The ON and OFF levels `(hi, lo)` of the change detector, each moved inside by
    /// [`TIE`]: `L` reaches a level where it is at or beyond it.
    #[inline(always)]
    fn levels(&self) -> (f64, f64) {
        (
            self.l_ref + self.theta_on - TIE,
            self.l_ref - self.theta_off + TIE,
        )
    }

    /// Mark the pixel as having a new sample; returns whether it was unmarked.
    #[inline]
    pub(super) fn mark_changed(&mut self) -> bool {
        let fresh = self.events & CHANGED == 0;
        self.events |= CHANGED;
        fresh
    }

    /// Clear the mark of [`Pixel::mark_changed`].
    #[inline]
    pub(super) fn clear_changed(&mut self) {
        self.events &= !CHANGED;
    }

    #[inline]
    fn blind(&self) -> bool {
        self.events & BLIND != 0
    }

    #[inline]
    fn set_blind(&mut self, blind: bool) {
        if blind {
            self.events |= BLIND;
        } else {
            self.events &= !BLIND;
        }
    }

    /// Count one event; returns the previous count.
    #[inline]
    fn count_event(&mut self) -> u32 {
        let n = self.events & COUNT;
        self.events = (self.events & !COUNT) | (n.wrapping_add(1) & COUNT);
        n
    }
}

/// A new sample cleaned ([`clean_irradiance`]) and its log response `u`, the low-pass
/// corner `omega` of the ramp to it (at the mean irradiance) and its [`Relaxation`] over the
/// step ([`StepContext::prepare`]).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Ramp {
    u: f64,
    omega: f64,
    relax: Relaxation,
    irr: f32,
}

impl Ramp {
    /// The sample as `segment` takes it: `(irradiance, log response)`.
    #[inline]
    pub(super) fn sample(&self) -> (f32, f64) {
        (self.irr, self.u)
    }
}

/// Everything one step of one pixel needs besides the pixel.
pub(super) struct StepContext<'a> {
    pub(super) response: &'a Response,
    pub(super) jitter_seed: u64,
    pub(super) width: u32,
    pub(super) row0: u32,
    pub(super) first: u32,
    pub(super) counters: &'a mut PixelCounters,
    pub(super) out: &'a mut Vec<SimEvent>,
}

/// Linear ramps a pixel that may fire takes through a step of cubic input
/// ([`StepContext::hermite_step`]). Each ramp's own timing error is that of a linear interpolation
/// over a quarter of the step; measured on 50 ms of a 1280×720 uniform flow (0.00152 particles per
/// pixel, `gen4`) against 0.025 px per step, at 0.5 px per step four ramps put the events a mean
/// 7.9 µs from the reference's where two put them 18.9 µs.
const CUBIC_RAMPS: usize = 4;

/// Safety net: the most level crossings one pixel may process in one step.
const MAX_CROSSINGS_PER_STEP: u32 = 1 << 20;

/// A level counts as reached within this many ln units, so that rounding cannot decide a tie:
/// a return to the same irradiance gives exactly as many OFF as ON events (v2e rounds its log
/// values to 1e-8 for the same reason, sensor-model.md §2.2).
const TIE: f64 = 1e-9;

impl StepContext<'_> {
    /// Advance one active pixel from its own time to `tb`; its input is constant up to `ta`
    /// and, with `new` ([`StepContext::prepare`] of a new sample), ramps to it over `[ta, tb]`.
    ///
    /// Returns `None` when the pixel leaves the active set (it cannot fire while its input is
    /// constant), else the time before which it need not be visited again unless its input
    /// changes: its blind time's end, the next crossing of its relaxation, or −∞.
    #[inline]
    pub(super) fn step(
        &mut self,
        px: &mut Pixel,
        local: u32,
        ta: f64,
        tb: f64,
        new: Option<&Ramp>,
    ) -> Option<f64> {
        if let Some(ramp) = new {
            let (irr, u) = ramp.sample();
            let u = if irr != px.irr { u } else { px.u };
            if px.t < ta {
                // A pixel frozen or asleep since `px.t`: its constant-input stretch first.
                self.segment(px, local, ta, None, None);
            }
            // The ramp's relaxation is that of the segment's curve if it starts at `ta` (same
            // corner, same length), which spares the segment an exponential and a division.
            let relax = (px.t == ta).then_some(ramp.relax);
            self.segment(px, local, tb, Some((irr, u)), relax);
        } else {
            self.segment(px, local, tb, None, None);
        }
        self.settled_or_due(px, new.is_some())
    }

    /// What [`StepContext::step`] returns for `px` at the end of its step (`new`: whether it
    /// had a new sample).
    #[inline]
    fn settled_or_due(&self, px: &Pixel, new: bool) -> Option<f64> {
        let r = self.response;
        if px.blind() {
            return Some(px.release);
        }
        if !r.low_pass() {
            return None;
        }
        let (hi, lo) = px.levels();
        let (l, u) = (px.l, px.u);
        if l < hi && l > lo && u < hi && u > lo {
            return None;
        }
        let omega = r.omega(px.irr as f64);
        if omega <= 0.0 {
            return None;
        }
        if new {
            return Some(f64::NEG_INFINITY);
        }
        // Constant input: `L` relaxes monotonically towards `u`, which lies beyond a level;
        // the crossing time follows from the exponential (IEBCS, §2.4). Rounding only makes
        // the pixel visited a step early or late; its event times come from `segment`.
        let level = if u >= hi { hi } else { lo };
        let wake = px.t - (-(level - l) / (u - l)).ln_1p() / omega;
        if wake.is_nan() {
            Some(f64::NEG_INFINITY)
        } else {
            // +∞: the input sits on the level and is only reached asymptotically.
            (wake < f64::INFINITY).then_some(wake)
        }
    }

    /// The log-response slopes `m_b` (per µs, rounded to `f32` as the pixels keep them; 0
    /// where not finite) of new samples with irradiance slopes `slopes`, and `1/ω` of their
    /// ramps, for [`StepContext::hermite_step`]: a loop of independent lanes, so that its
    /// divisions vectorise.
    #[inline(always)]
    pub(super) fn hermite_lanes(
        r: &Response,
        ramps: &[Ramp],
        slopes: &[f32],
        out: &mut Vec<HermiteEnds>,
    ) {
        out.clear();
        out.extend(ramps.iter().zip(slopes).map(|(ramp, &s)| {
            let mb = (s as f64 * r.log_slope(ramp.irr as f64)) as f32;
            HermiteEnds {
                mb: if mb.is_finite() { mb } else { 0.0 },
                inv_omega: 1.0 / ramp.omega,
            }
        }));
    }

    /// [`StepContext::step`] with a new sample, the pixel's log input over `[ta, tb]` the
    /// cubic Hermite interpolant between the samples with end slopes `ma` (of the pixel's
    /// last sample, taken as 0 if its input was held since before `ta`) and `ends.mb`, per
    /// µs; `inv_h` is `1/(tb − ta)`.
    ///
    /// A pixel whose `L` and the interpolant's Bézier control points (which bound the cubic,
    /// and with `L` bound `L` over the step) lie inside both levels cannot fire in the step;
    /// it takes the exact low-pass solution for the cubic input
    /// ([`Hermite::low_pass_end`]), with ω frozen at the step's mean irradiance as for a
    /// linear ramp. Any other pixel is advanced by [`CUBIC_RAMPS`] linear ramps through the
    /// interpolant's values at equal fractions of the step, with the crossing times of
    /// [`StepContext::step`] (each ramp with its own corner; [`StepContext::cubic_ramps`]).
    #[inline(always)]
    pub(super) fn hermite_step(
        &mut self,
        px: &mut Pixel,
        local: u32,
        (ta, tb, inv_h): (f64, f64, f64),
        ramp: &Ramp,
        ma: f32,
        ends: &HermiteEnds,
    ) -> Option<f64> {
        let r = self.response;
        let (irr_b, ub) = ramp.sample();
        let ub = if irr_b != px.irr { ub } else { px.u };
        let held = px.t < ta;
        if held && !(r.low_pass() && !px.blind() && Self::quiet_hold(r, px, ta)) {
            self.segment(px, local, ta, None, None);
        }
        let ma = if held { 0.0 } else { ma as f64 };
        let h = tb - ta;
        let ua = px.u;
        let (ma, mb) = limited_slopes(ma, ends.mb as f64, (ub - ua) * inv_h, r.log_range() * inv_h);
        let cubic = Hermite {
            ua,
            ub,
            ma,
            mb,
            h,
            inv_h,
        };
        if r.low_pass() && !px.blind() && px.t == ta && ramp.omega * h >= 0.5 {
            let (hi, lo) = px.levels();
            let inside = |v: f64| v < hi && v > lo;
            let third = h * (1.0 / 3.0);
            let (c1, c2) = (ua + third * ma, ub - third * mb);
            if inside(px.l) && inside(ua) && inside(c1) && inside(c2) && inside(ub) {
                let lb = cubic.low_pass_end(px.l, ends.inv_omega, ramp.relax);
                if inside(lb) {
                    px.l = lb;
                    px.u = ub;
                    px.irr = irr_b;
                    px.t = tb;
                    return None;
                }
            }
        }
        if px.t == ta && h > 1e-9 {
            self.cubic_ramps(px, local, (ta, tb), &cubic, irr_b);
        } else {
            self.segment(px, local, tb, Some((irr_b, ub)), None);
        }
        self.settled_or_due(px, true)
    }

    /// Advance `px`, at `ta`, to `tb` along [`CUBIC_RAMPS`] linear ramps through the values
    /// of `cubic` (its log input over the step, ending at the sample of irradiance `irr_b`)
    /// at equal fractions of the step, with the crossing times of `segment`. Each ramp has its
    /// own low-pass corner, at the mean of its ends' irradiances, taken from the irradiance's
    /// own Hermite interpolant (slopes `m/log′`), which needs no exponential; the ramps'
    /// relaxations are computed together ([`Relaxation::lanes`]; each ramp's length is
    /// the step's over [`CUBIC_RAMPS`] to within the rounding of its end times).
    #[inline(always)]
    fn cubic_ramps(
        &mut self,
        px: &mut Pixel,
        local: u32,
        (ta, tb): (f64, f64),
        cubic: &Hermite,
        irr_b: f32,
    ) {
        const N: usize = CUBIC_RAMPS;
        let r = self.response;
        let (ia, ib) = (px.irr as f64, irr_b as f64);
        let light = Hermite {
            ua: ia,
            ub: ib,
            ma: cubic.ma / r.log_slope(ia),
            mb: cubic.mb / r.log_slope(ib),
            h: cubic.h,
            inv_h: cubic.inv_h,
        };
        // (time, irradiance, log input) at the end of each ramp.
        let mut ends = [(tb, irr_b, cubic.ub); N];
        for (k, end) in ends.iter_mut().enumerate().take(N - 1) {
            let x = (k + 1) as f64 / N as f64;
            *end = (
                ta + x * cubic.h,
                clean_irradiance(light.at(x) as f32),
                cubic.at(x),
            );
        }
        let mut omega = [0.0; N];
        let mut start = px.irr;
        for (w, &(_, irr, _)) in omega.iter_mut().zip(&ends) {
            *w = r.omega(0.5 * (start as f64 + irr as f64));
            start = irr;
        }
        let relax = Relaxation::lanes(omega, cubic.h * (1.0 / N as f64));
        // With the low-pass on, every corner is positive (`OMEGA_FLOOR`).
        for (&(t, irr, u), relax) in ends.iter().zip(relax) {
            self.segment(px, local, t, Some((irr, u)), r.low_pass().then_some(relax));
        }
    }

    /// The transcendental parts of the update of `px` by the new sample `irr` over a step of
    /// `dt` µs (see [`Ramp`]). Each pixel's update is a chain of dependent operations;
    /// computing these parts for all new samples of a step in one loop of independent
    /// iterations lets the processor overlap them.
    #[inline(always)]
    pub(super) fn prepare(r: &Response, px: &Pixel, irr: f32, dt: f64) -> Ramp {
        let irr = clean_irradiance(irr);
        // `px.u` is `log(px.irr)`, so this is also right for an unchanged irradiance.
        let u = r.log(irr);
        let omega = r.omega(0.5 * (px.irr as f64 + irr as f64));
        Ramp {
            u,
            omega,
            relax: Relaxation::new(omega, dt),
            irr,
        }
    }

    /// [`StepContext::prepare`] of `N` new samples `irr` for pixels whose previous irradiances
    /// are `old`, bit for bit: the same operations lane by lane, without branches that differ
    /// between lanes, so that the compiler may pack lanes into vector instructions.
    #[inline(always)]
    pub(super) fn prepare_lanes<const N: usize>(
        r: &Response,
        old: [f32; N],
        irr: [f32; N],
        dt: f64,
    ) -> [Ramp; N] {
        let irr = irr.map(clean_irradiance);
        let u = r.log_lanes(irr);
        let mut omega = [0.0; N];
        for ((w, &a), &b) in omega.iter_mut().zip(&old).zip(&irr) {
            *w = r.omega(0.5 * (a as f64 + b as f64));
        }
        let relax = Relaxation::lanes(omega, dt);
        let mut ramps = [Ramp::default(); N];
        for (k, ramp) in ramps.iter_mut().enumerate() {
            *ramp = Ramp {
                u: u[k],
                omega: omega[k],
                relax: relax[k],
                irr: irr[k],
            };
        }
        ramps
    }

    /// The common case of [`StepContext::step`] with a new sample, done without a call: a
    /// pixel with the low-pass on, not blind, whose `L` neither reaches a level during the
    /// ramp over `[ta, tb]` nor can (input and output inside both levels, or no extremum
    /// inside the step). A pixel frozen or asleep since before `ta` is first brought to `ta`
    /// by [`StepContext::quiet_hold`] if that stretch reaches no level either. Same
    /// arithmetic as `segment` (the exact low-pass solution of [`Curve::low_pass`]), so the
    /// same result bit for bit. `ramp` is [`StepContext::prepare`] of the new sample for this
    /// pixel and step.
    ///
    /// Returns `None` if the pixel is not such a case (use `step`; the pixel is unchanged or,
    /// with the same result for `step`, brought to `ta`), else what `step` returns. Most
    /// updates of a recording are of this kind: the pixels a particle image brushes without
    /// changing them by a threshold.
    #[inline(always)]
    pub(super) fn quiet_ramp(
        r: &Response,
        px: &mut Pixel,
        ta: f64,
        tb: f64,
        ramp: &Ramp,
    ) -> Option<Option<f64>> {
        let omega = ramp.omega;
        if px.blind() || !r.low_pass() || !(omega > 0.0 && tb - ta > 1e-9) {
            return None;
        }
        if px.t != ta && !Self::quiet_hold(r, px, ta) {
            return None;
        }
        let ub = ramp.u;
        let curve = Curve::low_pass(ta, tb, px.l, px.u, ub, omega);
        let lb = curve.end_value_from(ramp.relax);
        let (hi, lo) = px.levels();
        let inside = |v: f64| v < hi && v > lo;
        let (ua_in, ub_in) = (inside(px.u), inside(ub));
        if !(inside(lb) && (ua_in && ub_in || !curve.may_turn())) {
            return None;
        }
        let irr_b = ramp.irr;
        px.l = lb;
        px.u = ub;
        px.irr = irr_b;
        px.t = tb;
        // As at the end of `step`: settled, or may fire with its input held.
        Some(if ub_in || r.omega(irr_b as f64) <= 0.0 {
            None
        } else {
            Some(f64::NEG_INFINITY)
        })
    }

    /// The constant-input stretch `[px.t, ta]` of a pixel (not blind, low-pass on) frozen or
    /// asleep since `px.t < ta`, as `segment` without a new sample computes it, applied if it
    /// reaches no level (then `segment` would emit nothing: the pixel ends the same, bit for
    /// bit). Returns whether it was applied; otherwise the pixel is unchanged.
    ///
    /// Pixels a particle image reaches after a quiet spell take this path instead of two
    /// calls of `segment`: the leading edge of every image.
    #[inline(always)]
    fn quiet_hold(r: &Response, px: &mut Pixel, ta: f64) -> bool {
        let before = px.t < ta;
        if !before {
            return false;
        }
        let omega = r.omega(0.5 * (px.irr as f64 + px.irr as f64));
        let curve = Curve::low_pass(px.t, ta, px.l, px.u, px.u, omega);
        let l = curve.end_value();
        let (hi, lo) = px.levels();
        let inside = |v: f64| v < hi && v > lo;
        if !(inside(l) && (inside(px.u) || !curve.may_turn())) {
            return false;
        }
        px.l = l;
        px.t = ta;
        true
    }

    /// Advance the pixel from `px.t` to `tb`, its input constant or, with `new = (irradiance,
    /// log response)`, ramping linearly in log to the new sample; emit the events of the
    /// stretch. `relax`, if given, is the [`Relaxation`] of this stretch's low-pass corner over
    /// `tb − px.t` ([`Curve::end_value_from`]).
    #[inline]
    fn segment(
        &mut self,
        px: &mut Pixel,
        local: u32,
        tb: f64,
        new: Option<(f32, f64)>,
        relax: Option<Relaxation>,
    ) {
        let r = self.response;
        let ta = px.t;
        let tb = tb.max(ta);
        let (irr_b, ub) = new.unwrap_or((px.irr, px.u));
        let curve = if r.low_pass() {
            let omega = r.omega(0.5 * (px.irr as f64 + irr_b as f64));
            Curve::low_pass(ta, tb, px.l, px.u, ub, omega)
        } else {
            Curve::direct(ta, tb, px.u, ub)
        };
        let lb = match relax {
            Some(relax) => curve.end_value_from(relax),
            None => curve.end_value(),
        };

        // Fast path: not blind, `L` inside both levels at the end and, if it may have an
        // extremum (which lies on the input line), the input inside them too.
        let (hi, lo) = px.levels();
        let inside = |v: f64| v < hi && v > lo;
        let quiet = !px.blind() && inside(lb) && (inside(px.u) && inside(ub) || !curve.may_turn());
        if !quiet {
            let start = (curve.ta, curve.start_value());
            match curve.extremum() {
                Some(s) => {
                    let turn = (s, curve.value(s));
                    self.crossings(px, local, &curve, start, turn);
                    self.crossings(px, local, &curve, turn, (curve.tb, lb));
                }
                None => self.crossings(px, local, &curve, start, (curve.tb, lb)),
            }
        }
        px.l = lb;
        px.u = ub;
        px.irr = irr_b;
        px.t = tb;
    }

    /// Process the level crossings of `L` on the monotone piece from `(p0, L(p0))` to
    /// `(p1, L(p1))`, starting with the pixel settled at `p0`: emit events, or count and absorb them while
    /// the pixel is blind (sensor-model.md §2.1, §2.5).
    fn crossings(
        &mut self,
        px: &mut Pixel,
        local: u32,
        curve: &Curve,
        (p0, l0): (f64, f64),
        (p1, l_end): (f64, f64),
    ) {
        let r = self.response;
        let (theta_on, theta_off) = (px.theta_on, px.theta_off);
        let (mut t, mut lt) = (p0, l0);
        let inv_omega = curve.inv_omega();
        for _ in 0..MAX_CROSSINGS_PER_STEP {
            if px.blind() {
                if px.release > p1 {
                    self.counters.suppressed_refractory += settle(px, l_end);
                    return;
                }
                // The blind time ends inside the piece: count what it hid, then reset the
                // reference to the photoreceptor value (IEBCS).
                let end = px.release.max(t);
                let l = curve.value_fast(end, inv_omega);
                self.counters.suppressed_refractory += settle(px, l);
                px.l_ref = l;
                px.set_blind(false);
                (t, lt) = (end, l);
                continue;
            }
            let (level, on) = if l_end >= px.l_ref + theta_on - TIE {
                (px.l_ref + theta_on, true)
            } else if l_end <= px.l_ref - theta_off + TIE {
                (px.l_ref - theta_off, false)
            } else {
                return;
            };
            let sign = if on { 1.0 } else { -1.0 };
            let t_cross = if sign * (lt - level) >= -TIE {
                t
            } else {
                // A level reached only within the tie tolerance (an input settling exactly
                // on it) is crossed where `L` comes within the tolerance.
                let target = if sign * (l_end - level) < 0.0 {
                    level - sign * TIE
                } else {
                    level
                };
                let root = curve.root(target, t, p1, lt, l_end, inv_omega);
                lt = target;
                root
            };
            px.l_ref = level;
            self.emit(px, local, t_cross, on);
            if r.refractory > 0.0 {
                px.set_blind(true);
            }
            t = t_cross;
        }
    }

    /// Emit one event whose threshold crossing is at `t_cross`.
    ///
    /// The comparator trips at `t_cross + j` with Gaussian jitter `j ≥ −latency` (events never
    /// precede their cause), but not before the pixel is released from its previous event; the
    /// event is stamped `latency` later; the pixel is blind until trip + refractory period.
    #[inline]
    fn emit(&mut self, px: &mut Pixel, local: u32, t_cross: f64, on: bool) {
        let r = self.response;
        let mut trip = t_cross;
        let k = px.count_event();
        if r.jitter > 0.0 {
            let index = ((k as u64) << 32) | self.first.wrapping_add(local) as u64;
            let z = Rng::first_normal(self.jitter_seed, Stream::Temporal, index);
            trip += (r.jitter * z).max(-r.latency);
        }
        if trip < px.release {
            trip = px.release;
        }
        px.release = trip + r.refractory;
        let x = local % self.width;
        let y = self.row0 + local / self.width;
        self.out.push(SimEvent {
            t_us: trip + r.latency,
            x: x as u16,
            y: y as u16,
            p: on as u8,
        });
        if on {
            self.counters.on += 1;
        } else {
            self.counters.off += 1;
        }
    }
}

/// The end slopes `ma`, `mb` of a step's cubic whose secant is `secant`, limited so that the
/// cubic stays within what a pixel's input can do: on a monotone step (both slopes of the
/// secant's sign) at most three times the secant, which keeps the cubic monotone, between its
/// ends (Fritsch & Carlson, SIAM J. Numer. Anal. 17, 1980; the dip of a steep leading edge
/// below the background otherwise), and any slope at most `max_slope`, the whole range of the
/// log response per step (an absurd slope would otherwise push the input beyond any level).
#[inline(always)]
fn limited_slopes(ma: f64, mb: f64, secant: f64, max_slope: f64) -> (f64, f64) {
    let max_slope = if max_slope.is_nan() {
        f64::INFINITY
    } else {
        max_slope
    };
    let (ma, mb) = (
        ma.clamp(-max_slope, max_slope),
        mb.clamp(-max_slope, max_slope),
    );
    if secant != 0.0 && ma * secant >= 0.0 && mb * secant >= 0.0 {
        let cap = 3.0 * secant.abs();
        (ma.clamp(-cap, cap), mb.clamp(-cap, cap))
    } else {
        (ma, mb)
    }
}

/// What [`StepContext::hermite_step`] needs of a new sample besides its [`Ramp`].
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct HermiteEnds {
    /// Slope of the log response at the sample, per µs.
    pub(super) mb: f32,
    /// `1/ω` of the ramp's corner.
    inv_omega: f64,
}

/// The cubic Hermite interpolant from `ua` (slope `ma`) to `ub` (slope `mb`) over `h` µs
/// (`inv_h = 1/h`).
pub(super) struct Hermite {
    pub(super) ua: f64,
    pub(super) ub: f64,
    pub(super) ma: f64,
    pub(super) mb: f64,
    pub(super) h: f64,
    pub(super) inv_h: f64,
}

impl Hermite {
    /// The interpolant's value at fraction `x` of the step (the Hermite basis polynomials).
    #[inline(always)]
    fn at(&self, x: f64) -> f64 {
        let (x2, x3) = (x * x, x * x * x);
        let (h00, h01) = (2.0 * x3 - 3.0 * x2 + 1.0, 3.0 * x2 - 2.0 * x3);
        let (h10, h11) = (x3 - 2.0 * x2 + x, x3 - x2);
        h00 * self.ua + h01 * self.ub + self.h * (h10 * self.ma + h11 * self.mb)
    }

    /// `L(h)` of the low-pass of corner ω (`inv_omega` = 1/ω, `relax` its [`Relaxation`] over
    /// `h`) from `la`, this cubic its input: with the polynomial particular solution
    /// `P = u − u′/ω + u″/ω² − u‴/ω³`, `L(τ) = P(τ) + (L_a − P(0))·e^(−ωτ)`. Used where
    /// `ω·h ≥ 0.5`, where the powers of `1/ω` lose about two digits (the terms are at most
    /// about 50 times the input's change).
    #[inline(always)]
    pub(super) fn low_pass_end(&self, la: f64, inv_omega: f64, relax: Relaxation) -> f64 {
        let Hermite {
            ua,
            ub,
            ma,
            mb,
            h,
            inv_h,
        } = *self;
        let secant = (ub - ua) * inv_h;
        // u = ua + ma·τ + c2·τ² + c3·τ³.
        let c2 = (3.0 * secant - 2.0 * ma - mb) * inv_h;
        let c3 = (ma + mb - 2.0 * secant) * (inv_h * inv_h);
        let w = inv_omega;
        let w2 = w * w;
        let jerk = 6.0 * c3 * w2 * w;
        let p0 = ua - ma * w + 2.0 * c2 * w2 - jerk;
        let ph = ub - mb * w + (2.0 * c2 + 6.0 * c3 * h) * w2 - jerk;
        ph + (la - p0) * (1.0 - relax.rise)
    }
}

/// Move the reference by whole thresholds until `l` lies between the levels (the crossings a
/// blind pixel does not report, ESIM's "consumed" change); returns how many.
fn settle(px: &mut Pixel, l: f64) -> u64 {
    let (theta_on, theta_off) = (px.theta_on, px.theta_off);
    let mut n = 0u64;
    if l >= px.l_ref + theta_on - TIE {
        let k = ((l - px.l_ref + TIE) / theta_on).floor().max(1.0);
        px.l_ref += k * theta_on;
        n += k as u64;
        while l >= px.l_ref + theta_on - TIE {
            px.l_ref += theta_on;
            n += 1;
        }
    } else if l <= px.l_ref - theta_off + TIE {
        let k = ((px.l_ref - l + TIE) / theta_off).floor().max(1.0);
        px.l_ref -= k * theta_off;
        n += k as u64;
        while l <= px.l_ref - theta_off + TIE {
            px.l_ref -= theta_off;
            n += 1;
        }
    }
    n
}
