//! Motion compensation (contrast maximisation) against synthetic particle trails with known
//! velocity: sub-pixel accuracy, no zero-velocity locking (algorithms.md §4.5 item 8), status
//! flags for out-of-range, empty and flat windows, predictor-centred search.

use ebiv::estimate::motion::{ContrastMaximization, MotionParams, Objective, Splat};
use ebiv::estimate::{Estimator, Prediction, WindowEstimate};
use ebiv::field::Status;
use ebiv::grid::Window;
use ebiv::volume::Slab;
use ebiv::{Geometry, PolaritySelection};

const T0: i64 = 1_000_000;
const SIZE: u32 = 240;
const WINDOW: Window = Window {
    x0: 100,
    y0: 100,
    width: 40,
    height: 40,
};

/// splitmix64, for reproducible particle positions.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Events of particles (image diameter ≈ 2 px) moving with `vel` px/ms around [`T0`]: a
/// pixel fires when the particle's image edge reaches its centre, at three edge radii (the
/// intensity rising as the image enters), with integer pixel positions and µs times.
/// Particles are added until the window holds at least `target` events in the slab.
fn trails(vel: [f64; 2], seed: u64, target: usize) -> Slab {
    let mut rng = Rng(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x5DEE_CE66);
    let (half_t, r_max) = (5.0, 1.3);
    let margin = vel[0].abs().max(vel[1].abs()) * half_t + 3.0;
    let (mut t, mut x, mut y) = (Vec::new(), Vec::new(), Vec::new());
    let mut in_window = 0;
    while in_window < target {
        let px = WINDOW.x0 as f64 - margin + rng.next() * (40.0 + 2.0 * margin);
        let py = WINDOW.y0 as f64 - margin + rng.next() * (40.0 + 2.0 * margin);
        let reach = vel[0].abs().max(vel[1].abs()) * half_t + r_max + 1.0;
        let a = vel[0] * vel[0] + vel[1] * vel[1];
        for qy in (py - reach).floor() as i64..=(py + reach).ceil() as i64 {
            for qx in (px - reach).floor() as i64..=(px + reach).ceil() as i64 {
                if qx < 0 || qy < 0 || qx >= SIZE as i64 || qy >= SIZE as i64 {
                    continue;
                }
                let (dx, dy) = (px - qx as f64, py - qy as f64);
                let b = 2.0 * (vel[0] * dx + vel[1] * dy);
                for r in [1.3, 1.0, 0.7] {
                    let c = dx * dx + dy * dy - r * r;
                    let disc = b * b - 4.0 * a * c;
                    if a == 0.0 || disc <= 0.0 {
                        continue;
                    }
                    let enter = (-b - disc.sqrt()) / (2.0 * a);
                    if (-half_t..half_t).contains(&enter) {
                        t.push(T0 + (enter * 1000.0).round() as i64);
                        x.push(qx as u16);
                        y.push(qy as u16);
                        let inside = (WINDOW.x0..WINDOW.x0 + 40).contains(&qx)
                            && (WINDOW.y0..WINDOW.y0 + 40).contains(&qy);
                        in_window += inside as usize;
                    }
                }
            }
        }
    }
    let p = vec![1u8; t.len()];
    Slab::build(
        &t,
        &x,
        &y,
        &p,
        Geometry::new(SIZE, SIZE),
        T0 - 5_000,
        T0 + 5_000,
        PolaritySelection::Positive,
        16,
    )
}

fn run(est: &ContrastMaximization, slab: &Slab, predictor: Option<[f64; 2]>) -> WindowEstimate {
    let mut scratch = est.scratch([40, 40]);
    let predictor = predictor.map(|velocity| Prediction {
        velocity,
        deformation: None,
        search_radius: None,
    });
    est.estimate(slab, &WINDOW, T0, predictor.as_ref(), &mut scratch)
}

fn default_estimator() -> ContrastMaximization {
    ContrastMaximization::new(MotionParams::default()).unwrap()
}

#[test]
fn sub_pixel_velocities_are_recovered() {
    let est = default_estimator();
    let cases = [
        [0.22, 1.7],
        [-0.22, -0.6],
        [1.37, -2.11],
        [-2.6, 0.45],
        [0.07, 2.9],
        [2.1, 2.05],
        [-0.93, -0.18],
        [0.0, -1.3],
    ];
    let mut worst: f64 = 0.0;
    for (k, vel) in cases.iter().enumerate() {
        for seed in 0..3 {
            let slab = trails(*vel, 100 * k as u64 + seed, 250);
            let e = run(&est, &slab, None);
            assert!(e.status.is_valid(), "{vel:?} seed {seed}: {e:?}");
            let err = (e.u - vel[0]).abs().max((e.v - vel[1]).abs());
            worst = worst.max(err);
            assert!(err < 0.05, "{vel:?} seed {seed}: got ({}, {})", e.u, e.v);
            assert!(e.event_count >= 250 && e.peak > 0.0);
        }
    }
    eprintln!("worst component error {worst:.4} px/ms");
}

/// Mean estimate over seeds of a component of 0.22 px/ms (the reference returned 41 %).
fn small_component_gain(est: &ContrastMaximization) -> f64 {
    let mut sum = 0.0;
    for seed in 0..8 {
        let slab = trails([0.22, -1.45], 7_000 + seed, 250);
        sum += run(est, &slab, None).u / 0.22;
    }
    sum / 8.0
}

/// For true components drawn uniformly from ±0.6 px/ms: the fraction of estimated
/// components within 0.01 px/ms of zero (1.7 % expected by chance) and the RMS component
/// error, px/ms, of the valid estimates, and the share of windows flagged. (A velocity that
/// moves the trails less than about a pixel over the slab is flagged when its maximum does
/// not bring enough more events together than rest does.)
fn near_zero_statistics(est: &ContrastMaximization) -> (f64, f64, f64) {
    let mut rng = Rng(99);
    let (mut near, mut total, mut sq, mut flagged) = (0, 0, 0.0, 0);
    let windows = 32;
    for seed in 0..windows {
        let vel = [rng.next() * 1.2 - 0.6, rng.next() * 1.2 - 0.6];
        let e = run(est, &trails(vel, 500 + seed, 200), None);
        if !e.status.is_valid() {
            flagged += 1;
            continue;
        }
        for (c, truth) in [(e.u, vel[0]), (e.v, vel[1])] {
            total += 1;
            near += (c.abs() < 0.01) as usize;
            sq += (c - truth).powi(2);
        }
    }
    let total = total.max(1) as f64;
    (
        near as f64 / total,
        (sq / total).sqrt(),
        flagged as f64 / windows as f64,
    )
}

#[test]
fn no_zero_velocity_locking() {
    let est = default_estimator();
    let gain = small_component_gain(&est);
    let (near, rms, flagged) = near_zero_statistics(&est);
    // The same statistics catch the locking of bilinear splatting of integer pixels.
    let bilinear = ContrastMaximization::new(MotionParams {
        splat: Splat::Bilinear,
        ..MotionParams::default()
    })
    .unwrap();
    let gain_b = small_component_gain(&bilinear);
    let (near_b, rms_b, flagged_b) = near_zero_statistics(&bilinear);
    eprintln!(
        "gaussian: gain {gain:.3}, near zero {near:.3}, rms {rms:.4}, flagged {flagged:.3}; \
         bilinear: gain {gain_b:.3}, near zero {near_b:.3}, rms {rms_b:.4}, flagged {flagged_b:.3}"
    );
    assert!((gain - 1.0).abs() < 0.1, "0.22 px/ms returned at {gain:.3}");
    assert!(near < 0.05, "{:.1} % of components near zero", near * 100.0);
    assert!(rms < 0.03, "rms {rms}");
    assert!(
        flagged <= 0.1,
        "{:.1} % of the windows flagged",
        flagged * 100.0
    );
    assert!(
        near_b > 2.0 * near.max(0.02) || rms_b > 2.0 * rms,
        "bilinear"
    );
}

#[test]
fn edge_of_range_peaks_are_flagged() {
    let est = ContrastMaximization::new(MotionParams {
        search_range: Some(1.0),
        ..MotionParams::default()
    })
    .unwrap();
    let e = run(&est, &trails([2.4, 0.3], 3, 250), None);
    assert_eq!(e.status, Status::OUT_OF_RANGE, "{e:?}");
    assert!(e.u.is_nan() && e.v.is_nan());
    // Inside the range the same estimator is valid.
    let e = run(&est, &trails([0.6, 0.3], 3, 250), None);
    assert!(e.status.is_valid() && (e.u - 0.6).abs() < 0.05, "{e:?}");
}

#[test]
fn predictor_centres_the_search_for_large_velocities() {
    let vel = [7.3, -5.15];
    let slab = trails(vel, 11, 300);
    // A range of ±4 px/ms cannot reach it without a predictor.
    let narrow = ContrastMaximization::new(MotionParams {
        search_range: Some(4.0),
        ..MotionParams::default()
    })
    .unwrap();
    assert_eq!(run(&narrow, &slab, None).status, Status::OUT_OF_RANGE);
    // The default range, 4 W / T = 16 px/ms, does.
    let est = default_estimator();
    let e = run(&est, &slab, None);
    assert!(e.status.is_valid(), "{e:?}");
    assert!(
        (e.u - vel[0]).abs() < 0.05 && (e.v - vel[1]).abs() < 0.05,
        "{e:?}"
    );
    let e = run(&est, &slab, Some([6.8, -4.6]));
    assert!(e.status.is_valid(), "{e:?}");
    assert!(
        (e.u - vel[0]).abs() < 0.05 && (e.v - vel[1]).abs() < 0.05,
        "{e:?}"
    );
}

fn slab_of(t: &[i64], x: &[u16], y: &[u16]) -> Slab {
    let p = vec![1u8; t.len()];
    let geometry = Geometry::new(SIZE, SIZE);
    let both = PolaritySelection::Both;
    Slab::build(t, x, y, &p, geometry, T0 - 5_000, T0 + 5_000, both, 16)
}

#[test]
fn empty_sparse_and_flat_windows_are_invalid() {
    let est = default_estimator();
    let e = run(&est, &slab_of(&[], &[], &[]), None);
    assert_eq!(e.status, Status::NO_EVENTS);
    assert!(e.u.is_nan() && e.v.is_nan() && e.event_count == 0);
    let few = slab_of(&[T0; 3], &[110, 111, 112], &[110; 3]);
    assert_eq!(run(&est, &few, None).status, Status::FEW_EVENTS);
    // All events at the reference time: every velocity gives the same IWE.
    let xs: Vec<u16> = (0..40).map(|i| 100 + i).collect();
    let e = run(&est, &slab_of(&[T0; 40], &xs, &[120; 40]), None);
    assert_eq!(e.status, Status::NO_PEAK);
    assert!(e.u.is_nan());
}

#[test]
fn other_objectives_work() {
    let vel = [1.12, -0.74];
    let slab = trails(vel, 21, 250);
    for objective in [Objective::SumOfSquares, Objective::SumExp, Objective::R1] {
        let est = ContrastMaximization::new(MotionParams {
            objective,
            ..MotionParams::default()
        })
        .unwrap();
        let e = run(&est, &slab, None);
        let err = (e.u - vel[0]).abs().max((e.v - vel[1]).abs());
        assert!(e.status.is_valid() && err < 0.08, "{objective:?}: {e:?}");
    }
}

#[test]
fn parameters_deserialize_and_validate() {
    let p: MotionParams = toml::from_str(
        "slab_us = 8000\nobjective = \"sum-of-squares\"\nsplat = { gaussian = { sigma = 0.9 } }\n\
         search_range = 3.0\nt_ref = \"mean-event-time\"",
    )
    .unwrap();
    assert_eq!(p.slab_us, 8000);
    assert_eq!(p.splat, Splat::Gaussian { sigma: 0.9 });
    assert!(p.validate().is_ok());
    let b: MotionParams = toml::from_str("splat = \"bilinear\"").unwrap();
    assert_eq!(b.splat, Splat::Bilinear);
    assert!(toml::from_str::<MotionParams>("slab = 3").is_err());
    let bad = |p: MotionParams| p.validate().unwrap_err().to_string();
    let d = MotionParams::default;
    assert!(bad(MotionParams { slab_us: 0, ..d() }).contains("`slab`"));
    assert!(bad(MotionParams {
        coarse_step: f64::NAN,
        ..d()
    })
    .contains("coarse-step"));
    assert!(bad(MotionParams {
        final_step: 0.5,
        ..d()
    })
    .contains("final-step"));
    assert!(bad(MotionParams {
        search_range: Some(-1.0),
        ..d()
    })
    .contains("search-range"));
    let s = Splat::Gaussian { sigma: 9.0 };
    assert!(bad(MotionParams { splat: s, ..d() }).contains("sigma"));
    assert!(ContrastMaximization::new(MotionParams { slab_us: -5, ..d() }).is_err());
    assert_eq!(default_estimator().time_extent_us(), (5_000, 5_000));
}

/// Time per window at ≈ 250 events (not a pass/fail test; run with `--ignored`).
#[test]
#[ignore = "timing printout, not a pass/fail test (timed assertions are not allowed): run with --release -- --ignored --nocapture"]
fn time_per_window() {
    let est = default_estimator();
    let slabs: Vec<(Slab, [f64; 2])> = (0..20)
        .map(|k| {
            let vel = [0.3 * k as f64 - 2.95, 1.55 - 0.15 * k as f64];
            (trails(vel, k, 250), vel)
        })
        .collect();
    let mut scratch = est.scratch([40, 40]);
    for predictor in [false, true] {
        let start = std::time::Instant::now();
        let mut events = 0;
        let reps = 10;
        for _ in 0..reps {
            for (slab, vel) in &slabs {
                let p = predictor.then(|| Prediction {
                    velocity: [vel[0] + 0.3, vel[1] - 0.2],
                    deformation: None,
                    search_radius: None,
                });
                let e = est.estimate(slab, &WINDOW, T0, p.as_ref(), &mut scratch);
                events += e.event_count as usize;
            }
        }
        let n = (reps * slabs.len()) as f64;
        eprintln!(
            "predictor {predictor}: {:.1} µs per window, {:.0} events per window",
            start.elapsed().as_secs_f64() * 1e6 / n,
            events as f64 / n
        );
    }
}
