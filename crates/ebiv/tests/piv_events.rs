//! PIV of frames rebuilt from simulated event recordings (fixed seeds, gen4 sensor): the
//! same flow measured by `piv`, `corrsum` and `motion` agrees within the estimators' errors
//! against the truth, and pulsed EBIV recovers the truth from one frame per light pulse.

mod common;

use ebiv::assess::{field_errors, ErrorStats};
use ebiv::estimate::corrsum::{CorrSumParams, SumOfCorrelation};
use ebiv::estimate::motion::{ContrastMaximization, MotionParams};
use ebiv::estimate::Estimator;
use ebiv::field::FieldSeries;
use ebiv::frame::events::{FrameKind, FrameSpec};
use ebiv::frame::pulse::detect_pulses;
use ebiv::grid::GridSpec;
use ebiv::piv::{piv_events, EventPivParams, FrameClock, PivParams};
use ebiv::process::{process_recording, MemorySource, ProcessParams};
use ebiv::sim::simulation::Simulation;
use ebiv::{EventBuffer, PolaritySelection};

/// A 256 × 256 gen4 scene with the given `[flow]` and extra TOML (e.g. illumination).
fn scenario(flow: &str, extra: &str, seed: u64) -> (Simulation, EventBuffer) {
    common::simulate_scene(flow, "40ms", extra, seed)
}

const FIELD_TIMES: [i64; 3] = [15_000, 20_000, 25_000];

fn passes() -> Vec<GridSpec> {
    vec![GridSpec::square(64, 32), GridSpec::square(32, 16)]
}

fn event_piv(sim: &Simulation, events: &EventBuffer, params: &EventPivParams) -> FieldSeries {
    let mut source = MemorySource::new(events);
    piv_events(&mut source, sim.geometry, params, &FIELD_TIMES, &mut |_| {
        Ok(())
    })
    .unwrap()
    .0
}

fn estimate<E: Estimator>(e: &E, sim: &Simulation, events: &EventBuffer) -> FieldSeries {
    let params = ProcessParams {
        passes: passes(),
        ..ProcessParams::default()
    };
    let mut source = MemorySource::new(events);
    process_recording(
        &mut source,
        sim.geometry,
        e,
        &params,
        &FIELD_TIMES,
        &mut |_| Ok(()),
    )
    .unwrap()
    .0
}

fn errors(series: &FieldSeries, sim: &Simulation) -> ErrorStats {
    field_errors(series, |x, y, t| sim.flow.velocity(x, y, t))
}

/// Share of the vectors valid in both series whose difference is within `bound` px/ms.
fn share_within(a: &FieldSeries, b: &FieldSeries, bound: f64) -> (f64, usize) {
    let (mut within, mut n) = (0usize, 0usize);
    for i in 0..a.u.len() {
        if a.status[i].is_valid() && b.status[i].is_valid() {
            let d = ((a.u[i] - b.u[i]) as f64).hypot((a.v[i] - b.v[i]) as f64);
            within += (d <= bound) as usize;
            n += 1;
        }
    }
    (within as f64 / n.max(1) as f64, n)
}

fn regular_frames() -> EventPivParams {
    EventPivParams {
        frames: FrameSpec {
            kind: FrameKind::Count,
            exposure_us: 1000,
            polarity: PolaritySelection::Positive,
            splat_sigma: 0.0,
        },
        clock: FrameClock::Regular { step_us: 2000 },
        pairs: 3,
        piv: PivParams {
            passes: passes(),
            ..PivParams::default()
        },
    }
}

/// A solid-body rotation (max 1.8 px/ms) measured three ways. Each estimator's RMS error
/// against the truth (of the error vector) is its stated uncertainty, σ = RMS/√2 per
/// component. For Gaussian errors 95 % of the differences between two estimators would lie
/// within 2.45·√(σ₁² + σ₂²) and 99 % within 3.03·√(σ₁² + σ₂²); the errors have heavier tails
/// (measured: 93–94 % within the first bound), so at least 95 % must lie within the second.
#[test]
fn piv_of_event_frames_agrees_with_corrsum_and_motion() {
    let flow = "type = \"solid_body\"\ncentre = [127.5, 127.5]\nomega = 0.01";
    let (sim, events) = scenario(flow, "", 31);
    let piv = event_piv(&sim, &events, &regular_frames());
    let corrsum = estimate(
        &SumOfCorrelation::new(CorrSumParams::default()).unwrap(),
        &sim,
        &events,
    );
    let motion = estimate(
        &ContrastMaximization::new(MotionParams::default()).unwrap(),
        &sim,
        &events,
    );
    let (ep, ec, em) = (
        errors(&piv, &sim),
        errors(&corrsum, &sim),
        errors(&motion, &sim),
    );
    println!("turntable ω = 0.01 rad/ms, 64→32 px: piv of 4 count frames (1 ms every 2 ms): {ep}");
    println!("corrsum: {ec}\nmotion: {em}");
    // Each vector records the time it was measured over: the span of the four frames,
    // 3 × 2 ms + 1 ms, or the estimators' slab T (10 ms by default; no mask here).
    assert!(piv.slab_us.iter().all(|&s| s == 7000));
    assert!(corrsum.slab_us.iter().all(|&s| s == 10_000));
    assert!(motion.slab_us.iter().all(|&s| s == 10_000));
    assert!(ep.rms <= 0.1, "piv {ep}");
    assert!(ep.valid_share() >= 0.95, "piv {ep}");
    for (name, other, e) in [("corrsum", &corrsum, &ec), ("motion", &motion, &em)] {
        let sigma = ((ep.rms * ep.rms + e.rms * e.rms) / 2.0).sqrt();
        let (share95, _) = share_within(&piv, other, 2.45 * sigma);
        let (share, n) = share_within(&piv, other, 3.03 * sigma);
        println!(
            "piv vs {name}: {:.1} % of {n} vectors within {:.3} px/ms, {:.1} % within {:.3} px/ms",
            100.0 * share95,
            2.45 * sigma,
            100.0 * share,
            3.03 * sigma
        );
        assert!(share >= 0.95, "piv vs {name}: {share}");
        assert!(n > 100);
    }
}

/// Pulsed light sheet (500 Hz, 5 % duty: 100 µs flashes, 3 px between pulses) on a uniform
/// flow: the pulse timing is found from the events alone, one frame per pulse, and PIV
/// recovers the velocity.
#[test]
fn pulsed_ebiv_recovers_the_truth() {
    let flow = "type = \"uniform\"\nu = 1.5\nv = -0.4";
    let illumination = r#"[illumination]
mode = "pulsed"
frequency_hz = 500.0
duty = 0.05
phase_us = 130.0
"#;
    let (sim, events) = scenario(flow, illumination, 32);
    let on: Vec<i64> = (0..events.len())
        .filter(|&i| events.p[i] != 0)
        .map(|i| events.t[i])
        .collect();
    let timing = detect_pulses(&on, &[], None).unwrap();
    println!(
        "pulses: {:.3} Hz, phase {:.1} µs, contrast {:.2}",
        timing.frequency_hz,
        timing.phase_us(),
        timing.contrast
    );
    assert!((timing.frequency_hz - 500.0).abs() < 0.5, "{timing:?}");
    let params = EventPivParams {
        clock: FrameClock::Pulsed(timing),
        pairs: 4,
        frames: FrameSpec {
            kind: FrameKind::Count,
            ..regular_frames().frames
        },
        ..regular_frames()
    };
    let series = event_piv(&sim, &events, &params);
    let e = errors(&series, &sim);
    println!("pulsed EBIV, uniform (1.5, −0.4) px/ms, 64→32 px, 5 pulses per field: {e}");
    assert!(e.rms <= 0.05, "{e}");
    assert!(e.bias[0].abs() <= 0.02 && e.bias[1].abs() <= 0.02, "{e}");
    assert!(e.valid_share() >= 0.95, "{e}");
    // The five frames of a field, one pulse period each, span five periods (frame starts
    // and the exposure rounded to whole µs).
    let span = 5.0 * timing.period_us;
    assert!(series
        .slab_us
        .iter()
        .all(|&s| (s as f64 - span).abs() <= 2.0));
}
