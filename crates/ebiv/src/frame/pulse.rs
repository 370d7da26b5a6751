//! Pulsed EBIV timing: when the light pulses come, so that one frame per pulse can be built
//! (Willert, "Event-based imaging velocimetry using pulsed illumination", Exp. Fluids 64:98,
//! 2023; `docs/algorithms.md` §7).
//!
//! A pulsed light sheet makes the events of the seeding particles arrive in bursts, one per
//! pulse. The pulse period comes from the camera's trigger input when the laser trigger was
//! recorded, otherwise from the events themselves: the fundamental period of the event rate
//! (autocorrelation of the rate binned at 10 µs), refined by epoch folding, the classical
//! period search for pulsed signals in event (photon) lists (Leahy et al., ApJ 266:160,
//! 1983): the events folded at the right period pile up in one phase, at a wrong one they
//! smear out. A least-squares fit of the burst times over all pulses then gives the period
//! to a small fraction of a microsecond. Frames start in the middle of the longest quiet
//! stretch of the folded event rate, so that each frame holds one whole burst.

use crate::error::{Error, Result};
use crate::event::Trigger;
use realfft::RealFftPlanner;
use std::borrow::Cow;

/// Where the pulse timing came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PulseSource {
    /// Rising edges of the camera's external trigger input.
    Triggers,
    /// The periodic modulation of the event rate.
    EventHistogram,
}

impl PulseSource {
    /// Where the timing came from, in words.
    pub fn describe(self) -> &'static str {
        match self {
            PulseSource::Triggers => "trigger edges",
            PulseSource::EventHistogram => "the event rate",
        }
    }
}

/// The timing of a pulsed light source, as seen in a recording.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PulseTiming {
    /// Pulse frequency, Hz.
    pub frequency_hz: f64,
    /// Pulse period, µs (`1e6 / frequency_hz`).
    pub period_us: f64,
    /// Camera time, µs, of one frame start in the quiet gap before the events of a pulse,
    /// taken near the middle of the analysed data; frames start at `offset_us + k·period_us`.
    pub offset_us: f64,
    /// Where the timing came from.
    pub source: PulseSource,
    /// How pronounced the pulse modulation of the event rate is: (max − min) / mean of the
    /// folded histogram (0 when there were too few events to tell).
    pub contrast: f64,
    /// Number of pulse periods the estimate is based on.
    pub periods: usize,
}

impl PulseTiming {
    /// Time of the frame starts within a period: `offset_us` modulo the period, µs.
    pub fn phase_us(&self) -> f64 {
        self.offset_us.rem_euclid(self.period_us)
    }

    /// Exposure of one frame per pulse: the period rounded to whole µs.
    pub fn exposure_us(&self) -> i64 {
        (self.period_us.round() as i64).max(1)
    }
}

/// Fewest events the event-rate analysis works with.
pub const MIN_EVENTS: usize = 100;
/// Fewest pulse periods the data must span.
pub const MIN_PERIODS: f64 = 8.0;
/// Bin width of the event rate for the coarse period search, µs.
const RATE_BIN_US: f64 = 10.0;
/// Most bins of the event rate (the coarse search looks at the first ~21 s).
const MAX_RATE_BINS: usize = 1 << 21;
/// Shortest period found without a hint, µs (25 kHz, above the ~10–20 kHz that event
/// sensors follow, Willert 2023).
const MIN_PERIOD_US: f64 = 40.0;
/// Shortest period accepted from a hint or triggers, µs.
const MIN_HINT_PERIOD_US: f64 = 4.0;
/// Longest stretch of time stamps analysed, µs (a day; the detection needs seconds).
const MAX_SPAN_US: i64 = 86_400_000_000;
/// Fewest rising trigger edges used instead of the events.
const MIN_TRIGGER_EDGES: usize = 4;
/// Smallest modulation depth (1 − rate of the quietest quarter period / mean rate) taken as
/// pulsed light.
const MIN_MODULATION: f64 = 0.25;
/// Smallest significance (Poisson σ) of the quiet quarter's deficit taken as pulsed light.
const MIN_SIGNIFICANCE: f64 = 5.0;
/// A shorter candidate period wins over the best one when its folded peak rate reaches this
/// fraction of the best: folding at a multiple of the true period gives the same peak rate,
/// folding at a fraction of it at most half (it mixes empty periods in).
const SUBHARMONIC_RATIO: f64 = 0.75;
/// How many autocorrelation peaks (the shortest strong ones) are tried as candidate periods.
const CANDIDATES: usize = 3;

/// Find the pulse frequency and the frame phase of a pulsed recording.
///
/// `event_times` (µs, camera time, any order; typically the positive events of a second or
/// so) and `triggers` (the recording's trigger edges, may be empty). With at least four
/// rising edges on one trigger channel the period is the least-squares slope of the edge
/// times, and the events only place the frames; otherwise everything comes from the events.
/// `hint_hz`, the nominal pulse frequency, restricts the search to ±10 % around it (and must
/// agree with the triggers within 2 %).
///
/// Errors when the events show no pulse modulation (continuous light), when there are fewer
/// than [`MIN_EVENTS`] events or the data span fewer than [`MIN_PERIODS`] periods, or when
/// the hint is unusable.
pub fn detect_pulses(
    event_times: &[i64],
    triggers: &[Trigger],
    hint_hz: Option<f64>,
) -> Result<PulseTiming> {
    let hint_period = match hint_hz {
        None => None,
        Some(f) if f.is_finite() && f > 0.0 && 1e6 / f >= MIN_HINT_PERIOD_US => Some(1e6 / f),
        Some(f) => {
            return Err(Error::parameter(
                "pulse-hz",
                format!(
                    "{f} Hz is not a usable pulse frequency (need 0 < f ≤ {} Hz)",
                    1e6 / MIN_HINT_PERIOD_US
                ),
            ))
        }
    };
    let times: Cow<[i64]> = if event_times.windows(2).all(|w| w[0] <= w[1]) {
        Cow::Borrowed(event_times)
    } else {
        let mut sorted = event_times.to_vec();
        sorted.sort_unstable();
        Cow::Owned(sorted)
    };
    let edges = rising_edges(triggers);
    for (what, list) in [("event", &times[..]), ("trigger", &edges[..])] {
        if let (Some(&a), Some(&b)) = (list.first(), list.last()) {
            if b.checked_sub(a).is_none_or(|span| span > MAX_SPAN_US) {
                return Err(Error::parameter(
                    "pulse detection",
                    format!("the {what} times span {a} µs to {b} µs, too long to analyse"),
                ));
            }
        }
    }
    if edges.len() >= MIN_TRIGGER_EDGES {
        from_triggers(&edges, &times, hint_period)
    } else {
        from_events(&times, hint_period)
    }
}

/// The rising edges of the trigger channel that has most of them, sorted, without repeats.
fn rising_edges(triggers: &[Trigger]) -> Vec<i64> {
    let mut counts = [0usize; 256];
    for tr in triggers.iter().filter(|tr| tr.value == 1) {
        counts[tr.channel as usize] += 1;
    }
    let channel = (0..256)
        .max_by_key(|&c| (counts[c], std::cmp::Reverse(c)))
        .unwrap_or(0);
    let mut edges: Vec<i64> = triggers
        .iter()
        .filter(|tr| tr.value == 1 && tr.channel as usize == channel)
        .map(|tr| tr.t)
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Timing from trigger edges: median spacing, then a least-squares line through the edge
/// times against their pulse numbers (missing edges are skipped, not miscounted).
fn from_triggers(edges: &[i64], times: &[i64], hint_period: Option<f64>) -> Result<PulseTiming> {
    let mut gaps: Vec<i64> = edges.windows(2).map(|w| w[1] - w[0]).collect();
    gaps.sort_unstable();
    let median = gaps[gaps.len() / 2] as f64;
    if median < MIN_HINT_PERIOD_US {
        return Err(Error::unsupported(
            "trigger input",
            format!("rising edges only {median} µs apart; they cannot be light pulses"),
        ));
    }
    if let Some(p) = hint_period {
        if (median / p - 1.0).abs() > 0.02 {
            return Err(Error::parameter(
                "pulse-hz",
                format!(
                    "the trigger input has rising edges every {median} µs ({:.3} Hz), not at the \
                     {:.3} Hz given",
                    1e6 / median,
                    1e6 / p
                ),
            ));
        }
    }
    let e0 = edges[0];
    let points: Vec<(f64, f64, f64)> = edges
        .iter()
        .map(|&t| {
            let x = (t - e0) as f64;
            ((x / median).round(), x, 1.0)
        })
        .collect();
    let (period, intercept) = fit_line(&points).unwrap_or((median, 0.0));
    let epoch = e0 as f64 + intercept;
    let periods = ((edges[edges.len() - 1] - e0) as f64 / period).round() as usize;
    let mut timing = PulseTiming {
        frequency_hz: 1e6 / period,
        period_us: period,
        offset_us: epoch,
        source: PulseSource::Triggers,
        contrast: 0.0,
        periods,
    };
    if times.len() >= MIN_EVENTS {
        let shape = FoldedShape::new(times, period, epoch);
        timing.contrast = shape.contrast;
        if shape.is_pulsed() {
            timing.offset_us = epoch + shape.gap_centre;
        }
    }
    timing.offset_us = near_middle(timing.offset_us, period, times, edges);
    Ok(timing)
}

/// Timing from the events alone.
fn from_events(times: &[i64], hint_period: Option<f64>) -> Result<PulseTiming> {
    if times.len() < MIN_EVENTS {
        return Err(Error::unsupported(
            "pulse detection",
            format!(
                "{} events are too few to find light pulses; need at least {MIN_EVENTS}",
                times.len()
            ),
        ));
    }
    let span = (times[times.len() - 1] - times[0]) as f64;
    let shortest = hint_period.map_or(MIN_PERIOD_US, |p| 0.9 * p);
    if span < MIN_PERIODS * shortest {
        return Err(too_short(span, hint_period.unwrap_or(MIN_PERIOD_US)));
    }
    let bin = match hint_period {
        Some(p) => RATE_BIN_US.min(p / 8.0),
        None => RATE_BIN_US,
    };
    let candidates = coarse_candidates(times, bin, hint_period)?;
    // Score every candidate with the same phase resolution.
    let smallest = candidates.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
    let score_bin = RATE_BIN_US.min(smallest / 16.0);
    let mut refined: Vec<(f64, f64)> = Vec::new();
    for &(period, uncertainty) in &candidates {
        if span < MIN_PERIODS * period {
            continue;
        }
        let p = refine_by_folding(times, period, uncertainty);
        refined.push((p, peak_rate(times, p, score_bin)));
    }
    let best = refined.iter().map(|r| r.1).fold(0.0, f64::max);
    let chosen = if hint_period.is_some() {
        refined.iter().find(|r| r.1 == best)
    } else {
        refined
            .iter()
            .filter(|r| r.1 >= SUBHARMONIC_RATIO * best)
            .min_by(|a, b| a.0.total_cmp(&b.0))
    };
    let Some(&(mut period, _)) = chosen.filter(|_| best > 0.0) else {
        return Err(no_pulses("the event rate has no periodic component"));
    };
    let mut epoch = times[0] as f64;
    for _ in 0..2 {
        if let Some((p, e)) = fit_pulse_train(times, period) {
            let bins = fold_bins(period);
            let old = sum_of_squares(&fold_counts(times, period, epoch, bins));
            let new = sum_of_squares(&fold_counts(times, p, e, bins));
            if new >= 0.98 * old {
                period = p;
                epoch = e;
            }
        }
    }
    if span < MIN_PERIODS * period {
        return Err(too_short(span, period));
    }
    let shape = FoldedShape::new(times, period, epoch);
    if !shape.is_pulsed() {
        return Err(no_pulses(&format!(
            "folded at the best period ({period:.3} µs) the quietest quarter of the period \
             still has {:.0} % of the mean event rate ({:.1} σ below it; pulsed light gives \
             less than {:.0} % at more than {MIN_SIGNIFICANCE} σ)",
            100.0 * (1.0 - shape.modulation),
            shape.significance,
            100.0 * (1.0 - MIN_MODULATION)
        )));
    }
    Ok(PulseTiming {
        frequency_hz: 1e6 / period,
        period_us: period,
        offset_us: near_middle(epoch + shape.gap_centre, period, times, &[]),
        source: PulseSource::EventHistogram,
        contrast: shape.contrast,
        periods: (span / period).floor() as usize,
    })
}

fn too_short(span: f64, period: f64) -> Error {
    Error::unsupported(
        "pulse detection",
        format!(
            "the events span {span:.0} µs, fewer than {MIN_PERIODS} periods of {period:.1} µs; \
             use a longer stretch of the recording"
        ),
    )
}

fn no_pulses(why: &str) -> Error {
    Error::unsupported(
        "pulse detection",
        format!(
            "no light pulses found: {why}; is the light continuous? (if it is pulsed, give the \
             nominal pulse frequency or record the laser trigger)"
        ),
    )
}

/// `offset` moved by whole periods to the frame start nearest the middle of the data.
fn near_middle(offset: f64, period: f64, times: &[i64], edges: &[i64]) -> f64 {
    let (first, last) = match (times.first(), times.last()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => (edges[0], edges[edges.len() - 1]),
    };
    let middle = 0.5 * (first as f64 + last as f64);
    offset + ((middle - offset) / period).round() * period
}

/// Candidate periods (µs) with their uncertainty: the shortest strong local maxima of the
/// autocorrelation of the event rate, and (without a hint) their halves and thirds, so that
/// a subharmonic peak cannot hide the fundamental.
fn coarse_candidates(times: &[i64], bin: f64, hint_period: Option<f64>) -> Result<Vec<(f64, f64)>> {
    let t0 = times[0];
    let span = (times[times.len() - 1] - t0) as f64;
    let n = ((span / bin) as usize + 1).min(MAX_RATE_BINS);
    let mut rate = vec![0.0f64; n];
    for &t in times {
        let b = ((t - t0) as f64 / bin) as usize;
        if b >= n {
            break;
        }
        rate[b] += 1.0;
    }
    // A burst narrower than a bin spreads an autocorrelation peak over two lags when the
    // period is not a whole number of bins; a 3-lag sum keeps the peak's full height.
    let raw = autocorrelation(&rate)?;
    let acf: Vec<f64> = (0..raw.len())
        .map(|i| raw[i.saturating_sub(1)] + raw[i] + raw[(i + 1).min(raw.len() - 1)])
        .collect();
    let (lo, hi) = match hint_period {
        Some(p) => (
            ((0.9 * p / bin).floor() as usize).max(1),
            ((1.1 * p / bin).ceil() as usize).min(n - 1),
        ),
        None => (
            ((MIN_PERIOD_US / bin).ceil() as usize).max(2),
            ((n as f64 / MIN_PERIODS) as usize).min(n - 1),
        ),
    };
    let mut peaks: Vec<(f64, f64)> = Vec::new();
    for lag in lo.max(1)..hi.min(acf.len() - 1) {
        let (a, b, c) = (acf[lag - 1], acf[lag], acf[lag + 1]);
        if b > a && b >= c && b > 0.0 {
            // Parabolic interpolation of the peak's position.
            let denom = a - 2.0 * b + c;
            let shift = if denom < 0.0 {
                (0.5 * (a - c) / denom).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            peaks.push(((lag as f64 + shift) * bin, b));
        }
    }
    // The pulse period and all its multiples give peaks of about the same height: keep the
    // shortest lags among the strong peaks (as in autocorrelation pitch detection).
    let strongest = peaks.iter().map(|p| p.1).fold(0.0, f64::max);
    peaks.retain(|p| p.1 >= 0.5 * strongest);
    peaks.truncate(CANDIDATES);
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut push = |p: f64, u: f64| {
        if !out.iter().any(|&(q, _)| (q / p - 1.0).abs() < 0.005) {
            out.push((p, u));
        }
    };
    if let Some(p) = hint_period {
        push(p, 0.02 * p);
    }
    for &(p, _) in &peaks {
        push(p, bin);
        if hint_period.is_none() {
            for k in [2.0, 3.0] {
                if p / k >= MIN_PERIOD_US {
                    push(p / k, bin / k);
                }
            }
        }
    }
    if out.is_empty() {
        return Err(no_pulses("the event rate has no periodic component"));
    }
    Ok(out)
}

/// Autocorrelation of `x` with its mean removed, normalised to 1 at lag 0 (0 everywhere for
/// a constant signal), by FFT (Wiener–Khinchin).
fn autocorrelation(x: &[f64]) -> Result<Vec<f64>> {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let size = (2 * n).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(size);
    let inverse = planner.plan_fft_inverse(size);
    let mut data = forward.make_input_vec();
    for (d, &v) in data.iter_mut().zip(x) {
        *d = v - mean;
    }
    let mut spectrum = forward.make_output_vec();
    let fft_error = |e: realfft::FftError| Error::parameter("pulse detection", e.to_string());
    forward
        .process(&mut data, &mut spectrum)
        .map_err(fft_error)?;
    for c in spectrum.iter_mut() {
        *c = realfft::num_complex::Complex::new(c.norm_sqr(), 0.0);
    }
    inverse
        .process(&mut spectrum, &mut data)
        .map_err(fft_error)?;
    let zero = data[0];
    data.truncate(n);
    if zero > 0.0 {
        data.iter_mut().for_each(|v| *v /= zero);
    } else {
        data.iter_mut().for_each(|v| *v = 0.0);
    }
    Ok(data)
}

/// Number of phase bins used when folding at `period`: about 10 µs wide, 16 to 256 of them.
fn fold_bins(period: f64) -> usize {
    ((period / RATE_BIN_US).round() as usize).clamp(16, 256)
}

/// Event counts per phase bin when folded at `period` with phase 0 at `epoch` (µs).
fn fold_counts(times: &[i64], period: f64, epoch: f64, bins: usize) -> Vec<f64> {
    let mut h = vec![0.0; bins];
    fold_into(times, period, epoch, &mut h);
    h
}

fn fold_into(times: &[i64], period: f64, epoch: f64, h: &mut [f64]) {
    h.iter_mut().for_each(|v| *v = 0.0);
    let Some(&t0) = times.first() else {
        return;
    };
    let bins = h.len();
    let shift = epoch - t0 as f64;
    let scale = bins as f64 / period;
    for &t in times {
        let x = (t - t0) as f64 - shift;
        let phase = x - (x / period).floor() * period;
        let b = ((phase * scale) as usize).min(bins - 1);
        h[b] += 1.0;
    }
}

fn sum_of_squares(h: &[f64]) -> f64 {
    h.iter().map(|v| v * v).sum()
}

/// Refine a period by epoch folding: maximise the sum of squared folded counts (Leahy et al.
/// 1983) on successively longer stretches of the data, each four times longer with a four
/// times finer period step, so that the phase drift across the stretch stays below a
/// quarter bin at every stage.
fn refine_by_folding(times: &[i64], period: f64, uncertainty: f64) -> f64 {
    let t0 = times[0];
    let total = (times[times.len() - 1] - t0) as f64;
    let bins = fold_bins(period);
    let bin_width = period / bins as f64;
    let mut h = vec![0.0; bins];
    let mut p = period;
    let mut delta = uncertainty.max(1e-6);
    let mut periods = 16.0f64;
    loop {
        let stretch = (periods * p).min(total);
        let n = stretch / p;
        let end = times.partition_point(|&t| ((t - t0) as f64) <= stretch);
        let part = &times[..end];
        let step = (bin_width / (4.0 * n.max(1.0))).min(delta);
        let steps = ((delta / step).ceil() as i64).min(4000);
        let score = |q: f64, h: &mut [f64]| {
            fold_into(part, q, t0 as f64, h);
            sum_of_squares(h)
        };
        let (mut best_k, mut best) = (0, f64::MIN);
        for k in -steps..=steps {
            let s = score(p + k as f64 * step, &mut h);
            if s > best {
                best = s;
                best_k = k;
            }
        }
        p += best_k as f64 * step;
        if stretch >= total {
            return p;
        }
        delta = 2.0 * step;
        periods *= 4.0;
    }
}

/// The highest folded event rate (events/µs per period, 3-bin running mean) at `period` with
/// phase bins about `bin` µs wide: equal at the true period and its multiples, at most half
/// as high at its fractions.
fn peak_rate(times: &[i64], period: f64, bin: f64) -> f64 {
    let bins = ((period / bin).round() as usize).max(3);
    let h = fold_counts(times, period, times[0] as f64, bins);
    let periods = periods_touched(times, period);
    let width = period / bins as f64;
    (0..bins)
        .map(|i| h[(i + bins - 1) % bins] + h[i] + h[(i + 1) % bins])
        .fold(0.0, f64::max)
        / (3.0 * width * periods)
}

/// Number of periods (counted from time 0) that the data reach into.
fn periods_touched(times: &[i64], period: f64) -> f64 {
    match (times.first(), times.last()) {
        (Some(&a), Some(&b)) => {
            ((b as f64 / period).floor() - (a as f64 / period).floor() + 1.0).max(1.0)
        }
        _ => 1.0,
    }
}

/// Least-squares line `y = intercept + slope·x` through weighted points `(x, y, w)`.
fn fit_line(points: &[(f64, f64, f64)]) -> Option<(f64, f64)> {
    let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for &(x, y, w) in points {
        sw += w;
        sx += w * x;
        sy += w * y;
    }
    if sw <= 0.0 {
        return None;
    }
    let (mx, my) = (sx / sw, sy / sw);
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for &(x, y, w) in points {
        sxx += w * (x - mx) * (x - mx);
        sxy += w * (x - mx) * (y - my);
    }
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some((slope, my - slope * mx))
}

/// The pulse train's period and epoch (µs, time of the burst centre of pulse 0) from the
/// centroid time of every burst, by a line fitted through them weighted by their events.
/// The burst window is the part of the folded rate above half its height, plus a bin.
fn fit_pulse_train(times: &[i64], period: f64) -> Option<(f64, f64)> {
    let t0 = times[0];
    let bins = fold_bins(period);
    let width = period / bins as f64;
    let h = smooth(&fold_counts(times, period, t0 as f64, bins));
    let (peak, hi) = h
        .iter()
        .copied()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let lo = h.iter().copied().fold(f64::INFINITY, f64::min);
    let half = lo + 0.5 * (hi - lo);
    let (mut left, mut right) = (0usize, 0usize);
    while left < bins / 2 && h[(peak + bins - left - 1) % bins] > half {
        left += 1;
    }
    while right < bins / 2 && h[(peak + right + 1) % bins] > half {
        right += 1;
    }
    let (a, b) = (
        peak as f64 - left as f64 - 1.0,
        peak as f64 + right as f64 + 1.0,
    );
    let centre = 0.5 * (a + b + 1.0) * width;
    let half_width = 0.5 * (b + 1.0 - a) * width;
    if half_width > 0.45 * period {
        return None;
    }
    let count = ((times[times.len() - 1] - t0) as f64 / period) as usize + 3;
    if count > 1 << 24 {
        return None;
    }
    let mut sums = vec![(0.0f64, 0.0f64); count];
    for &t in times {
        let x = (t - t0) as f64 - centre;
        let k = (x / period).round();
        let d = x - k * period;
        let index = k as i64 + 1;
        if d.abs() <= half_width && index >= 0 && (index as usize) < count {
            let s = &mut sums[index as usize];
            s.0 += 1.0;
            s.1 += x;
        }
    }
    let points: Vec<(f64, f64, f64)> = sums
        .iter()
        .enumerate()
        .filter(|(_, s)| s.0 >= 2.0)
        .map(|(i, s)| (i as f64 - 1.0, s.1 / s.0, s.0))
        .collect();
    if points.len() < 3 {
        return None;
    }
    let (p, e) = fit_line(&points)?;
    (p > 0.0 && (p / period - 1.0).abs() < 0.01).then_some((p, t0 as f64 + e + centre))
}

/// Circular 3-bin running mean.
fn smooth(h: &[f64]) -> Vec<f64> {
    let n = h.len();
    (0..n)
        .map(|i| (h[(i + n - 1) % n] + h[i] + h[(i + 1) % n]) / 3.0)
        .collect()
}

/// The folded event rate at the final period: its contrast, modulation depth and the
/// centre of its quiet gap.
struct FoldedShape {
    /// (max − min) / mean of the folded rate.
    contrast: f64,
    /// 1 − (events in the quietest quarter period) / (a quarter of the events): about 0 for
    /// a steady rate, 1 when no event falls in the quietest quarter.
    modulation: f64,
    /// How many Poisson standard deviations the quietest quarter lies below a steady rate.
    significance: f64,
    /// Phase (µs after the epoch) of the middle of the longest quiet stretch before the
    /// burst.
    gap_centre: f64,
}

impl FoldedShape {
    /// Whether the folded rate shows a clear, significant quiet gap.
    fn is_pulsed(&self) -> bool {
        self.modulation >= MIN_MODULATION && self.significance >= MIN_SIGNIFICANCE
    }

    fn new(times: &[i64], period: f64, epoch: f64) -> Self {
        let bins = ((period / 5.0).round() as usize).clamp(16, 400);
        let width = period / bins as f64;
        let counts = fold_counts(times, period, epoch, bins);
        let total: f64 = counts.iter().sum();
        let mean = total / bins as f64;
        let (min, max) = counts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let contrast = if mean > 0.0 { (max - min) / mean } else { 0.0 };
        let quarter = bins / 4;
        let mut window: f64 = counts[..quarter].iter().sum();
        let mut quietest = window;
        for i in 0..bins {
            window += counts[(i + quarter) % bins] - counts[i];
            quietest = quietest.min(window);
        }
        let expected = total * quarter as f64 / bins as f64;
        let (modulation, significance) = if expected > 0.0 {
            (
                1.0 - quietest / expected,
                (expected - quietest) / expected.sqrt(),
            )
        } else {
            (0.0, 0.0)
        };
        let h = smooth(&counts);
        let gap_centre = quiet_gap_centre(&h) * width;
        FoldedShape {
            contrast,
            modulation,
            significance,
            gap_centre,
        }
    }
}

/// The middle (in bins, fractional) of the longest run of quiet bins of a circular
/// histogram, quiet meaning within 10 % of its range above its minimum. Runs are taken
/// scanning backward cyclically from the maximum, and of equally long runs the first met
/// (the one closest before the burst) wins, after the reference `DetermineOffsetTime`,
/// which takes the single lowest bin instead — a noisy choice anywhere in the gap.
fn quiet_gap_centre(h: &[f64]) -> f64 {
    let n = h.len();
    let (peak, hi) = h
        .iter()
        .copied()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, 0.0));
    let lo = h.iter().copied().fold(f64::INFINITY, f64::min);
    let quiet_level = lo + 0.1 * (hi - lo);
    let (mut best_len, mut best_first) = (0usize, peak);
    let mut run = 0usize;
    for j in 1..=n {
        let i = (peak + n - j) % n;
        if j < n && h[i] <= quiet_level {
            run += 1;
            if run > best_len {
                best_len = run;
                best_first = i;
            }
        } else {
            run = 0;
        }
    }
    if best_len == 0 {
        return peak as f64;
    }
    (best_first as f64 + 0.5 * best_len as f64).rem_euclid(n as f64)
}

/// Event rate folded at `period_us` (phase = camera time modulo the period, as the reference
/// `MeanPulseHistogram`), in bins of `bin_us` (the last bin may be narrower), as events per
/// µs per period: the mean pulse shape. Empty when the period or bin is not positive and
/// finite or asks for more than ten million bins.
pub fn folded_histogram(event_times: &[i64], period_us: f64, bin_us: f64) -> Vec<f64> {
    if !(period_us.is_finite() && bin_us.is_finite() && period_us > 0.0 && bin_us > 0.0)
        || period_us / bin_us > 1e7
    {
        return Vec::new();
    }
    let bins = (period_us / bin_us).ceil().max(1.0) as usize;
    let mut h = vec![0.0; bins];
    for &t in event_times {
        let phase = (t as f64).rem_euclid(period_us);
        let b = ((phase / bin_us) as usize).min(bins - 1);
        h[b] += 1.0;
    }
    let (lo, hi) = match (event_times.iter().min(), event_times.iter().max()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => return h,
    };
    let periods =
        ((hi as f64 / period_us).floor() - (lo as f64 / period_us).floor() + 1.0).max(1.0);
    for (i, v) in h.iter_mut().enumerate() {
        let width = (period_us - i as f64 * bin_us).min(bin_us);
        *v /= periods * width;
    }
    h
}

/// One frame start per pulse: every `offset_us + k·period_us` (rounded to µs) from
/// `t_start` on whose whole frame, one period long ([`PulseTiming::exposure_us`]), ends by
/// `t_end`. Empty for an unusable timing.
pub fn pulse_frame_starts(timing: &PulseTiming, t_start: i64, t_end: i64) -> Vec<i64> {
    let p = timing.period_us;
    let mut out = Vec::new();
    if !(p.is_finite() && p >= 1.0 && timing.offset_us.is_finite()) {
        return out;
    }
    let exposure = timing.exposure_us();
    let mut k = ((t_start as f64 - timing.offset_us) / p).ceil();
    loop {
        let s = (timing.offset_us + k * p).round();
        if s.is_nan() || s.abs() >= 9.0e18 {
            break;
        }
        let s = s as i64;
        if s.saturating_add(exposure) > t_end {
            break;
        }
        if s >= t_start {
            out.push(s);
        }
        k += 1.0;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::sim::rng::{Rng, Stream};

    /// A pulsed recording's event times: per pulse an ON burst `on_us` after the pulse edge
    /// and an OFF burst `off_us` after it (Gaussian jitter `jitter_us`), plus uniform
    /// background events making up `background` of the total.
    struct Train {
        period: f64,
        first_edge: f64,
        pulses: usize,
        per_pulse: usize,
        on_us: f64,
        off_us: f64,
        jitter_us: f64,
        background: f64,
    }

    impl Train {
        fn new(period: f64, pulses: usize) -> Self {
            Train {
                period,
                first_edge: 1_234_567.8,
                pulses,
                per_pulse: 20,
                on_us: 15.0,
                off_us: 0.1 * period + 15.0,
                jitter_us: 4.0,
                background: 0.3,
            }
        }

        fn times(&self, seed: u64) -> Vec<i64> {
            let mut rng = Rng::new(seed, Stream::Temporal, 0);
            let mut out = Vec::new();
            for k in 0..self.pulses {
                let edge = self.first_edge + k as f64 * self.period;
                for i in 0..self.per_pulse {
                    let delay = if i % 2 == 0 { self.on_us } else { self.off_us };
                    out.push((edge + delay + self.jitter_us * rng.normal()).round() as i64);
                }
            }
            let signal = out.len() as f64;
            let noise = (signal * self.background / (1.0 - self.background)) as usize;
            let span = self.pulses as f64 * self.period;
            for _ in 0..noise {
                out.push((self.first_edge + span * rng.uniform()) as i64);
            }
            out.sort_unstable();
            out
        }

        /// Whether time `t` lies at least `margin` µs outside every burst (4σ wide).
        fn in_gap(&self, t: i64, margin: f64) -> bool {
            let phase = (t as f64 - self.first_edge).rem_euclid(self.period);
            let burst = (self.on_us - 4.0 * self.jitter_us - margin)
                ..(self.off_us + 4.0 * self.jitter_us + margin);
            !burst.contains(&phase) && !burst.contains(&(phase - self.period))
        }
    }

    fn relative_error(timing: &PulseTiming, period: f64) -> f64 {
        (timing.period_us / period - 1.0).abs()
    }

    #[test]
    fn finds_period_and_gap_of_noisy_pulse_trains() {
        for (period, pulses) in [(5000.0, 60), (1000.0, 100), (487.3, 300), (100.0, 400)] {
            let train = Train::new(period, pulses);
            let times = train.times(7);
            let timing = detect_pulses(&times, &[], None).unwrap();
            assert_eq!(timing.source, PulseSource::EventHistogram);
            let err = relative_error(&timing, period);
            assert!(
                err < 1e-4,
                "P {period}: found {} µs ({err:e})",
                timing.period_us
            );
            assert!(
                timing.contrast > 3.0,
                "P {period}: contrast {}",
                timing.contrast
            );
            let t_end = times[times.len() - 1];
            let starts = pulse_frame_starts(&timing, times[0], t_end);
            assert!(starts.len() + 2 >= pulses, "{} starts", starts.len());
            for &s in &starts {
                assert!(
                    train.in_gap(s, 0.02 * period),
                    "P {period}: start {s} in a burst"
                );
            }
        }
    }

    #[test]
    fn prefers_the_fundamental_over_sub_harmonics_and_flicker() {
        // Every other pulse much weaker (a sub-harmonic structure), ON and OFF bursts far
        // apart within a pulse (a harmonic), background flickering at 100 Hz.
        let period = 250.0;
        let train = Train {
            off_us: 110.0,
            ..Train::new(period, 400)
        };
        let mut rng = Rng::new(3, Stream::Temporal, 0);
        let mut times: Vec<i64> = train
            .times(11)
            .into_iter()
            .filter(|&t| {
                let k = ((t as f64 - train.first_edge) / period).floor() as i64;
                k % 2 == 0 || rng.uniform() < 0.7
            })
            .collect();
        let span = 400.0 * period;
        for _ in 0..20_000 {
            let t = train.first_edge + span * rng.uniform();
            let flicker = 0.5 * (1.0 + (std::f64::consts::TAU * 100.0 * t * 1e-6).sin());
            if rng.uniform() < flicker {
                times.push(t as i64);
            }
        }
        times.sort_unstable();
        let timing = detect_pulses(&times, &[], None).unwrap();
        assert!(
            relative_error(&timing, period) < 1e-4,
            "found {} µs",
            timing.period_us
        );
    }

    #[test]
    fn trigger_edges_give_the_period_and_events_the_gap() {
        let period = 333.4;
        let train = Train::new(period, 200);
        let times = train.times(5);
        let mut rng = Rng::new(9, Stream::Temporal, 0);
        let triggers: Vec<Trigger> = (0..200)
            .filter(|k| k % 37 != 5) // a few edges missing
            .flat_map(|k| {
                let t = train.first_edge + k as f64 * period + 0.3 * rng.normal();
                [
                    Trigger {
                        t: t.round() as i64,
                        channel: 1,
                        value: 1,
                    },
                    Trigger {
                        t: (t + 20.0).round() as i64,
                        channel: 1,
                        value: 0,
                    },
                ]
            })
            .chain([Trigger {
                t: 5,
                channel: 0,
                value: 1,
            }])
            .collect();
        let timing = detect_pulses(&times, &triggers, None).unwrap();
        assert_eq!(timing.source, PulseSource::Triggers);
        assert!(
            relative_error(&timing, period) < 1e-5,
            "{}",
            timing.period_us
        );
        assert!(train.in_gap(timing.offset_us.round() as i64, 20.0));
        // Without events the frames start at the trigger edges.
        let timing = detect_pulses(&[], &triggers, Some(3000.0)).unwrap();
        let phase = (timing.offset_us - train.first_edge).rem_euclid(period);
        assert!(phase.min(period - phase) < 1.0, "phase {phase}");
        assert_eq!(timing.contrast, 0.0);
        // A hint that contradicts the triggers is an error.
        let e = detect_pulses(&times, &triggers, Some(2000.0)).unwrap_err();
        assert!(e.to_string().contains("2000.000 Hz"), "{e}");
    }

    #[test]
    fn a_hint_narrows_the_search() {
        let period = 1e6 / 2004.0;
        let times = Train::new(period, 200).times(21);
        let timing = detect_pulses(&times, &[], Some(2000.0)).unwrap();
        assert!(
            relative_error(&timing, period) < 1e-4,
            "{}",
            timing.frequency_hz
        );
        for bad in [0.0, -5.0, f64::NAN, 1e9] {
            let e = detect_pulses(&times, &[], Some(bad)).unwrap_err();
            assert!(e.to_string().contains("pulse-hz"), "{e}");
        }
    }

    #[test]
    fn continuous_light_and_too_little_data_are_errors() {
        let mut rng = Rng::new(1, Stream::Temporal, 0);
        let mut steady: Vec<i64> = (0..30_000).map(|_| (1e6 * rng.uniform()) as i64).collect();
        steady.sort_unstable();
        let e = detect_pulses(&steady, &[], None).unwrap_err().to_string();
        assert!(e.contains("no light pulses"), "{e}");
        let e = detect_pulses(&steady, &[], Some(1000.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no light pulses"), "{e}");

        let times = Train::new(500.0, 100).times(2);
        let e = detect_pulses(&times[..50], &[], None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("too few"), "{e}");
        let short = Train::new(500.0, 5).times(2);
        let e = detect_pulses(&short, &[], Some(2000.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("periods"), "{e}");
        assert!(detect_pulses(&[], &[], None).is_err());
        let mut extreme = times.clone();
        extreme.push(i64::MAX);
        extreme.insert(0, i64::MIN);
        let e = detect_pulses(&extreme, &[], None).unwrap_err().to_string();
        assert!(e.contains("too long"), "{e}");
        // Unsorted input is fine.
        let mut shuffled = times.clone();
        shuffled.reverse();
        assert!(detect_pulses(&shuffled, &[], None).is_ok());
    }

    #[test]
    fn odd_inputs_give_errors_or_timings_never_panics() {
        let tr = |t: i64, value: u8| Trigger {
            t,
            channel: 0,
            value,
        };
        let train = Train::new(500.0, 50).times(4);
        let cases: Vec<(Vec<i64>, Vec<Trigger>, Option<f64>)> = vec![
            (vec![7; 1000], vec![], None),
            (vec![0, 1_000_000], vec![], Some(1.0)),
            ((0..1000).map(|i| i * 40).collect(), vec![], None),
            (
                (0..1000).map(|i| i * 41 % 977).collect(),
                vec![],
                Some(250_000.0),
            ),
            (train.clone(), vec![tr(5, 1); 10], None),
            (train.clone(), (0..10).map(|i| tr(i * 3, 1)).collect(), None),
            (
                train.clone(),
                (0..10).map(|i| tr(i * 1000, 0)).collect(),
                None,
            ),
            (vec![], (0..10).map(|i| tr(i * 1000, 1)).collect(), None),
            (vec![-5_000_000_000, 5_000_000_000], vec![], None),
        ];
        for (times, triggers, hint) in cases {
            let _ = detect_pulses(&times, &triggers, hint);
        }
    }

    #[test]
    fn folded_histogram_is_events_per_microsecond_per_period() {
        // One event per period at phase 15 µs, 100 periods of 100 µs.
        let times: Vec<i64> = (0..100).map(|k| 1000 + k * 100 + 15).collect();
        let h = folded_histogram(&times, 100.0, 10.0);
        assert_eq!(h.len(), 10);
        assert!((h[1] - 1.0 / 10.0).abs() < 1e-12);
        assert_eq!(h.iter().filter(|&&v| v > 0.0).count(), 1);
        // A narrower last bin is normalised by its own width.
        let h = folded_histogram(&[95, 195, 295], 100.0, 30.0);
        assert_eq!(h.len(), 4);
        assert!((h[3] - 3.0 / (3.0 * 10.0)).abs() < 1e-12);
        assert!(folded_histogram(&times, 0.0, 1.0).is_empty());
        assert!(folded_histogram(&times, 100.0, f64::NAN).is_empty());
        assert!(folded_histogram(&times, 1e9, 1e-3).is_empty());
        assert_eq!(folded_histogram(&[], 100.0, 10.0), vec![0.0; 10]);
    }

    #[test]
    fn one_whole_frame_per_pulse() {
        let timing = PulseTiming {
            frequency_hz: 1e6 / 499.6,
            period_us: 499.6,
            offset_us: 10_250.3,
            source: PulseSource::Triggers,
            contrast: 5.0,
            periods: 100,
        };
        assert_eq!(timing.exposure_us(), 500);
        assert!((timing.phase_us() - 10_250.3f64.rem_euclid(499.6)).abs() < 1e-9);
        let starts = pulse_frame_starts(&timing, 0, 20_000);
        assert_eq!(
            starts.first(),
            Some(&((10_250.3f64 - 20.0 * 499.6).round() as i64))
        );
        assert!(starts.iter().all(|&s| s >= 0 && s + 500 <= 20_000));
        assert_eq!(starts.len(), 39);
        for w in starts.windows(2) {
            assert!((w[1] - w[0] - 499).abs() <= 1, "{w:?}");
        }
        assert!(pulse_frame_starts(&timing, 100, 300).is_empty());
        let broken = PulseTiming {
            period_us: f64::NAN,
            ..timing
        };
        assert!(pulse_frame_starts(&broken, 0, 20_000).is_empty());
    }

    /// A short pulsed recording through the real simulator (uniform flow, 2 kHz, duty 0.1,
    /// Gen4 sensor model): the pulse rate is recovered to 0.1 % and every frame starts in the
    /// dark between pulses; the same scene in continuous light is rejected.
    #[test]
    fn simulated_pulsed_recording() {
        use crate::sim::flow::analytic::Uniform;
        use crate::sim::particles::SeedingParams;
        use crate::sim::scene::{IlluminationParams, LightMode};
        use crate::sim::sensor::SensorParams;
        use crate::sim::simulation::{Interpolation, Simulation};

        let simulation = |mode: LightMode, flicker_hz: f64| Simulation {
            geometry: crate::Geometry::new(64, 48),
            flow: Box::new(Uniform { u: 2.0, v: 0.5 }),
            seeding: SeedingParams {
                density: 0.01,
                ..SeedingParams::default()
            },
            illumination: IlluminationParams {
                mode,
                frequency_hz: 2000.0,
                duty: 0.1,
                phase_us: 130.0,
                edge_us: 2.0,
                flicker_hz,
                flicker_amplitude: 0.2,
                ..IlluminationParams::default()
            },
            sensor: SensorParams::default(),
            start_us: 0,
            duration_us: 60_000,
            step_px: 0.1,
            max_step_us: 20.0,
            interpolation: Interpolation::Linear,
            seed: 17,
        };
        for flicker_hz in [0.0, 100.0] {
            let sim = simulation(LightMode::Pulsed, flicker_hz);
            let out = sim.run(None, &|_| {}).unwrap();
            let times: Vec<i64> = (0..out.events.len())
                .filter(|&i| out.events.p[i] == 1)
                .map(|i| out.events.t[i])
                .collect();
            let timing = detect_pulses(&times, &[], None).unwrap();
            let error = (timing.frequency_hz / 2000.0 - 1.0).abs();
            eprintln!(
                "simulated, flicker {flicker_hz} Hz: {} ON events, {:.4} Hz (error {:.2e}), \
                 phase {:.1} µs, contrast {:.1}",
                times.len(),
                timing.frequency_hz,
                error,
                timing.phase_us(),
                timing.contrast
            );
            assert!(error < 1e-3, "{} Hz", timing.frequency_hz);
            let starts = pulse_frame_starts(&timing, 0, 60_000);
            assert!(starts.len() >= 110, "{} frames", starts.len());
            let per_frame = times.len() as f64 / starts.len() as f64;
            for &s in &starts {
                // Dark for 100 µs on either side: the middle of the 450 µs gap.
                for dt in [-100.0, 0.0, 100.0] {
                    let t = s as f64 + dt;
                    assert_eq!(sim.illumination.sheet(t), 0.0, "light on at {t}");
                }
                if flicker_hz == 0.0 {
                    let near = times.iter().filter(|&&t| (t - s).abs() <= 10).count();
                    assert!(
                        (near as f64) < 0.02 * per_frame + 1.0,
                        "{near} events within 10 µs of the frame start {s}"
                    );
                }
            }
            // Frames of one period each tile the time, and each holds one pulse's events.
            let spec = crate::frame::FrameSpec {
                exposure_us: timing.exposure_us(),
                polarity: crate::PolaritySelection::Positive,
                ..Default::default()
            };
            for &s in &starts[..5] {
                let (_, n) =
                    crate::frame::events::build_frame_counted(&out.events, sim.geometry, s, &spec);
                assert!(n as f64 > 0.5 * per_frame, "{n} events in the frame at {s}");
            }
        }
        let steady = simulation(LightMode::Continuous, 0.0)
            .run(None, &|_| {})
            .unwrap();
        let e = detect_pulses(&steady.events.t, &[], None).unwrap_err();
        eprintln!("continuous simulation: {e}");
        assert!(e.to_string().contains("no light pulses"), "{e}");
    }
}
