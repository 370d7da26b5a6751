//! Both event estimators against simulator ground truth (fixed seeds, gen4 sensor model):
//! uniform flow, solid-body rotation, a Lamb–Oseen vortex, multi-pass against single pass.
//! Bounds are the issue's targets; each test prints its measured errors.

mod common;

use ebiv::assess::{field_errors, ErrorStats};
use ebiv::estimate::corrsum::{CorrSumParams, SumOfCorrelation};
use ebiv::estimate::motion::{ContrastMaximization, MotionParams};
use ebiv::estimate::Estimator;
use ebiv::field::{FieldSeries, Status};
use ebiv::grid::GridSpec;
use ebiv::process::{process_recording, MemorySource, ProcessParams};
use ebiv::sim::simulation::Simulation;
use ebiv::EventBuffer;

/// A 256 × 256 gen4 scene of `duration` with the given `[flow]` table.
fn scenario(flow: &str, duration: &str, seed: u64) -> (Simulation, EventBuffer) {
    common::simulate_scene(flow, duration, "", seed)
}

fn process<E: Estimator>(
    estimator: &E,
    sim: &Simulation,
    events: &EventBuffer,
    passes: &[(u32, u32)],
    times: &[i64],
) -> FieldSeries {
    process_with(estimator, sim, events, passes, times, true)
}

fn errors(series: &FieldSeries, sim: &Simulation) -> ErrorStats {
    field_errors(series, |x, y, t| sim.flow.velocity(x, y, t))
}

fn corrsum() -> SumOfCorrelation {
    SumOfCorrelation::new(CorrSumParams::default()).unwrap()
}

fn motion() -> ContrastMaximization {
    ContrastMaximization::new(MotionParams::default()).unwrap()
}

const FIELD_TIMES: [i64; 3] = [15_000, 20_000, 25_000];

#[test]
fn uniform_flow_of_2_px_per_ms_within_0_05_rms() {
    let (sim, events) = scenario("type = \"uniform\"\nu = 2.0\nv = 0.0", "40ms", 11);
    for (name, series) in [
        (
            "corrsum",
            process(&corrsum(), &sim, &events, &[(32, 16)], &FIELD_TIMES),
        ),
        (
            "motion",
            process(&motion(), &sim, &events, &[(32, 16)], &FIELD_TIMES),
        ),
    ] {
        let e = errors(&series, &sim);
        println!("uniform 2 px/ms, 32×32, T = 10 ms, {name}: {e}");
        assert!(e.rms <= 0.05, "{name}: {e}");
        assert!(
            e.bias[0].abs() <= 0.02 && e.bias[1].abs() <= 0.02,
            "{name}: {e}"
        );
        assert!(e.valid_share() >= 0.95, "{name}: {e}");
    }
}

/// Sum of correlation: the summed peak of pixel-quantised events is about a pixel wide and
/// locks onto whole-pixel displacements; smoothing it near the maximum before the fit
/// (default σ = 1 px) must lower the error of a flow displaced by half pixels over τ
/// (6.5 px, 2.5 px). Measured: RMS 0.027 px/ms without, 0.023 with (printed).
#[test]
fn peak_smoothing_reduces_peak_locking_of_half_pixel_displacements() {
    let flow = "type = \"uniform\"\nu = 2.1666667\nv = 0.8333333";
    let (sim, events) = scenario(flow, "40ms", 21);
    let passes = [(64, 32), (32, 16)];
    let locked = SumOfCorrelation::new(CorrSumParams {
        peak_smoothing_px: 0.0,
        ..CorrSumParams::default()
    })
    .unwrap();
    let raw = errors(
        &process(&locked, &sim, &events, &passes, &FIELD_TIMES),
        &sim,
    );
    let smoothed = errors(
        &process(&corrsum(), &sim, &events, &passes, &FIELD_TIMES),
        &sim,
    );
    println!("half-pixel displacements, corrsum 64→32 px, no smoothing: {raw}");
    println!("half-pixel displacements, corrsum 64→32 px, σ = 1 px: {smoothed}");
    assert!(smoothed.rms < 0.85 * raw.rms, "{smoothed}\nvs\n{raw}");
    assert!(smoothed.valid_share() >= 0.99, "{smoothed}");
}

/// Solid-body rotation: the velocity gradient makes a window estimate refer to wherever its
/// few particles are; deforming the events along the predictor's affine paths (later passes,
/// the last one repeated) must remove most of that error. With the default options and 32 px
/// windows the issue's DVR ≥ 350 is not reached (the options that reach it:
/// `turntable_dvr_above_350_with_subpixel_events_and_counts`): with the exact (true)
/// predictor the last pass gives RMS ≈ 0.03 px/ms
/// here, about what both estimators give for a uniform flow oblique to the pixel grid
/// (0.02–0.03 px/ms), so the bound is the DVR measured when it was set (115 corrsum with the
/// peak smoothing, 119 motion) less a margin. Measured: 106 corrsum, 123 motion (printed).
/// The truth is compared at each vector's window centre and field time (`assess`).
#[test]
fn turntable_event_deformation_removes_gradient_error() {
    let flow = "type = \"solid_body\"\ncentre = [127.5, 127.5]\nomega = 0.02";
    let (sim, events) = scenario(flow, "40ms", 12);
    let passes = [(64, 32), (32, 16)];
    for (name, deformed, plain, min_dvr) in [
        (
            "corrsum",
            process_with(&corrsum(), &sim, &events, &passes, &FIELD_TIMES, true),
            process_with(&corrsum(), &sim, &events, &passes, &FIELD_TIMES, false),
            105.0,
        ),
        (
            "motion",
            process_with(&motion(), &sim, &events, &passes, &FIELD_TIMES, true),
            process_with(&motion(), &sim, &events, &passes, &FIELD_TIMES, false),
            105.0,
        ),
    ] {
        let (d, p) = (errors(&deformed, &sim), errors(&plain, &sim));
        println!("turntable ω = 0.02 rad/ms, 64→32 px, {name}, deformed: {d}");
        println!("turntable ω = 0.02 rad/ms, 64→32 px, {name}, not deformed: {p}");
        assert!(d.rms < 0.6 * p.rms, "{name}: deformed {d}\nplain {p}");
        assert!(d.dvr() >= min_dvr, "{name}: DVR below {min_dvr}: {d}");
        assert!(d.valid_share() >= 0.95, "{name}: {d}");
    }
}

/// Sum of correlation with [`CorrSumParams::subpixel_shift`]: voxels of deformed events kept
/// at their sub-pixel positions (instead of rounded to pixels) and the predictor's
/// displacement removed exactly. On the turntable of the previous test the rounding of the
/// deformed positions is most of the error: measured RMS 0.0298 → 0.0179 px/ms (DVR 106 →
/// 177); removing only the sub-pixel part of the displacement from the plane, with rounded
/// positions, gives 0.030.
#[test]
fn turntable_subpixel_event_positions_raise_the_corrsum_dvr() {
    let flow = "type = \"solid_body\"\ncentre = [127.5, 127.5]\nomega = 0.02";
    let (sim, events) = scenario(flow, "40ms", 12);
    let passes = [(64, 32), (32, 16)];
    let run = |subpixel_shift| {
        let estimator = SumOfCorrelation::new(CorrSumParams {
            subpixel_shift,
            ..CorrSumParams::default()
        })
        .unwrap();
        errors(
            &process(&estimator, &sim, &events, &passes, &FIELD_TIMES),
            &sim,
        )
    };
    let (rounded, exact) = (run(false), run(true));
    println!("turntable, corrsum 64→32 px, rounded deformed events: {rounded}");
    println!("turntable, corrsum 64→32 px, sub-pixel deformed events: {exact}");
    assert!(exact.rms < 0.7 * rounded.rms, "{exact}\nvs\n{rounded}");
    assert!(exact.dvr() >= 175.0, "{exact}");
    assert!(exact.valid_share() >= 0.99, "{exact}");
}

fn process_with<E: Estimator>(
    estimator: &E,
    sim: &Simulation,
    events: &EventBuffer,
    passes: &[(u32, u32)],
    times: &[i64],
    deform: bool,
) -> FieldSeries {
    let params = ProcessParams {
        passes: passes
            .iter()
            .map(|&(w, s)| GridSpec::square(w, s))
            .collect(),
        deform,
        ..ProcessParams::default()
    };
    let mut source = MemorySource::new(events);
    process_recording(
        &mut source,
        sim.geometry,
        estimator,
        &params,
        times,
        &mut |_| Ok(()),
    )
    .unwrap()
    .0
}

/// `a` and `b` with only the vectors valid in both left valid (the others masked), so that
/// their errors are compared on the same windows.
fn on_common_windows(a: &FieldSeries, b: &FieldSeries) -> (FieldSeries, FieldSeries) {
    let (mut a, mut b) = (a.clone(), b.clone());
    for i in 0..a.status.len() {
        if !(a.status[i].is_valid() && b.status[i].is_valid()) {
            a.status[i] = Status::MASKED;
            b.status[i] = Status::MASKED;
        }
    }
    (a, b)
}

/// Multi-pass (64 → 32 px, deformed events) against one 32 px pass in a Lamb–Oseen vortex
/// (up to 4 px/ms, 12 px within τ near the core, beyond the single pass's search radius):
/// the multi-pass run is more accurate on the windows both measure. (Sum of correlation's
/// single pass flags the windows whose peak lies beyond its radius rather than passing a
/// wrong one, so over all their valid vectors it can look the better of the two.)
#[test]
fn multi_pass_beats_single_pass_in_a_lamb_oseen_vortex() {
    let flow = r#"type = "lamb_oseen"
centre = [127.5, 127.5]
circulation = 1000.0
core_radius = 25.0"#;
    let (sim, events) = scenario(flow, "40ms", 13);
    let (c, m) = (corrsum(), motion());
    type Run<'a> = &'a dyn Fn(&[(u32, u32)]) -> FieldSeries;
    let runs: [(&str, Run); 2] = [
        ("corrsum", &|passes| {
            process(&c, &sim, &events, passes, &FIELD_TIMES)
        }),
        ("motion", &|passes| {
            process(&m, &sim, &events, passes, &FIELD_TIMES)
        }),
    ];
    for (name, run) in runs {
        let (single, multi) = (run(&[(32, 16)]), run(&[(64, 32), (32, 16)]));
        let (all_single, all_multi) = (errors(&single, &sim), errors(&multi, &sim));
        let (single, multi) = on_common_windows(&single, &multi);
        let (single, multi) = (errors(&single, &sim), errors(&multi, &sim));
        println!(
            "Lamb–Oseen, {name} single 32 px: {all_single}\n  on the windows both measure: {single}"
        );
        println!(
            "Lamb–Oseen, {name} 64→32 px: {all_multi}\n  on the windows both measure: {multi}"
        );
        assert!(
            multi.rms < single.rms,
            "{name}: single {single}\nmulti {multi}"
        );
    }
}

/// The issue's dynamic velocity range, DVR ≥ 350 on the turntable (the paper reports 175),
/// with the command line's default passes (64 → 40 px, step 32 → 20): sum of correlation
/// with sub-pixel event positions and count weighting (`--subpixel-shift --weighting count`)
/// at τ = 8 ms. Deformation removes the rotation's gradient and curvature, so τ is no longer
/// bound by decorrelation and the same displacement error is a 2.7× smaller velocity error.
/// Measured (seeds 12 / 13 / 14): DVR 589 / 640 / 419 at τ = 8 ms; at the paper's τ = 3 ms
/// 435 / 413 / 256 with these options and 162 / 166 / 133 without them (printed; bound: the
/// options cut the RMS by 30 %). With 32 px windows in the last pass (step 16), printed:
/// 328 / 380 / 279 at τ = 8 ms: random error falls with the number of events per window.
/// Motion compensation with its defaults, same passes: DVR 211 / 193 / 181 (printed).
/// The first pass's search radius (21 px of a 64 px window) covers 2.6 px/ms at τ = 8 ms;
/// faster windows are found from their neighbours' prediction in the second pass.
#[test]
fn turntable_dvr_above_350_with_subpixel_events_and_counts() {
    let flow = "type = \"solid_body\"\ncentre = [127.5, 127.5]\nomega = 0.02";
    let estimator = |tau_us, accurate: bool| {
        SumOfCorrelation::new(CorrSumParams {
            tau_us,
            subpixel_shift: accurate,
            weighting: if accurate {
                ebiv::estimate::corrsum::Weighting::Count
            } else {
                ebiv::estimate::corrsum::Weighting::Binary
            },
            ..CorrSumParams::default()
        })
        .unwrap()
    };
    let passes = [(64, 32), (40, 20)];
    for seed in [12, 13, 14] {
        let (sim, events) = scenario(flow, "40ms", seed);
        let run = |tau_us, accurate| {
            let e = estimator(tau_us, accurate);
            errors(&process(&e, &sim, &events, &passes, &FIELD_TIMES), &sim)
        };
        let paper = run(3_000, false);
        let short = run(3_000, true);
        let long = run(8_000, true);
        println!("turntable seed {seed}, corrsum 64→40 px, τ = 3 ms: {paper}");
        println!("turntable seed {seed}, same, sub-pixel, counts: {short}");
        println!("turntable seed {seed}, same, τ = 8 ms: {long}");
        // Printed, not bounded: the row for 32 px windows in the last pass (docs/process.md).
        let e = estimator(8_000, true);
        let fine = errors(
            &process(&e, &sim, &events, &[(64, 32), (32, 16)], &FIELD_TIMES),
            &sim,
        );
        println!("turntable seed {seed}, same, 64→32 px: {fine}");
        let moving = errors(
            &process(&motion(), &sim, &events, &passes, &FIELD_TIMES),
            &sim,
        );
        println!("turntable seed {seed}, motion 64→40 px: {moving}");
        assert!(moving.valid_share() >= 0.95, "seed {seed}: {moving}");
        assert!(moving.dvr() >= 150.0, "seed {seed}: {moving}");
        assert!(long.dvr() >= 350.0, "seed {seed}: {long}");
        assert!(long.valid_share() >= 0.99, "seed {seed}: {long}");
        assert!(
            short.rms < 0.7 * paper.rms,
            "seed {seed}: {short}\nvs\n{paper}"
        );
    }
}
