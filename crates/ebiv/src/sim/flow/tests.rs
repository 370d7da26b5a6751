//! Tests of the analytic and integrated flows and of `FlowSpec`.

use super::*;
use crate::sim::ode;

const W: f64 = 320.0;
const H: f64 = 240.0;

fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

/// Starting points spread over the 320 × 240 image, including its corners and centre.
fn starts() -> Vec<(f64, f64)> {
    let mut p = Vec::new();
    for i in 0..=8 {
        for j in 0..=6 {
            p.push((
                i as f64 * W / 8.0 + 0.37 * j as f64,
                j as f64 * H / 6.0 + 0.11 * i as f64,
            ));
        }
    }
    p.push((160.0, 120.0));
    p
}

/// The closed-form flows at realistic speeds (1–20 px/ms in the image).
fn analytic_flows() -> Vec<(&'static str, Box<dyn Flow>)> {
    vec![
        (
            "uniform",
            Box::new(Uniform::from_speed_angle(12.0, 30f64.to_radians())),
        ),
        (
            "solid_body",
            Box::new(SolidBodyRotation {
                centre: (160.0, 120.0),
                omega_per_ms: 0.06,
            }),
        ),
        (
            "rankine",
            Box::new(RankineVortex {
                centre: (150.0, 110.0),
                omega_core_per_ms: 0.15,
                core_radius_px: 60.0,
            }),
        ),
        (
            "lamb_oseen",
            Box::new(LambOseenVortex {
                centre: (160.0, 120.0),
                circulation_px2_per_ms: 5000.0,
                core_radius_px: 40.0,
            }),
        ),
        (
            "couette_rotated",
            Box::new(Couette {
                gradient_per_ms: 0.08,
                x0: 100.0,
                y0: 120.0,
                angle_rad: 22.3f64.to_radians(),
            }),
        ),
        (
            "mixing_layer_rotated",
            Box::new(MixingLayer {
                u1: -3.0,
                u2: 12.0,
                x0: 150.0,
                y0: 110.0,
                thickness_px: 10.0,
                angle_rad: -30f64.to_radians(),
            }),
        ),
        (
            "poiseuille",
            Box::new(Poiseuille {
                u_max: 15.0,
                y_min: 20.0,
                y_max: 220.0,
            }),
        ),
        (
            "stagnation",
            Box::new(StagnationPoint {
                centre: (160.0, 240.0),
                k_per_ms: 0.05,
            }),
        ),
    ]
}

#[test]
fn exact_paths_agree_with_ode_integration_over_25_ms() {
    for (name, flow) in analytic_flows() {
        for p in starts() {
            let exact = flow.advect(p, 1_000.0, 26_000.0);
            let integrated = ode::integrate(|x, y, t| flow.velocity(x, y, t), p, 1_000.0, 26_000.0);
            let d = dist(exact, integrated);
            // The acceptance bound is 1e-3 px; the integrator does far better.
            assert!(
                d < 1e-6,
                "{name} from {p:?}: exact {exact:?}, ODE {integrated:?} ({d} px)"
            );
            let back = flow.advect(exact, 26_000.0, 1_000.0);
            assert!(dist(back, p) < 1e-9, "{name} from {p:?}: backward {back:?}");
            let halves = flow.advect(flow.advect(p, 1_000.0, 9_000.0), 9_000.0, 26_000.0);
            assert!(
                dist(halves, exact) < 1e-9,
                "{name} from {p:?}: in two steps {halves:?}"
            );
        }
    }
}

#[test]
fn max_speed_bounds_the_speed_in_the_image() {
    let mut flows = analytic_flows();
    flows.push((
        "sinusoidal",
        Box::new(Sinusoidal {
            amplitude_px: 6.0,
            wavelength_px: 128.0,
            speed: -5.0,
        }),
    ));
    flows.push((
        "cellular",
        Box::new(Cellular {
            amplitude: 10.0,
            period_px: 128.0,
        }),
    ));
    flows.push((
        "far_vortex",
        Box::new(LambOseenVortex {
            centre: (-300.0, 120.0),
            circulation_px2_per_ms: -5000.0,
            core_radius_px: 40.0,
        }),
    ));
    for (name, flow) in &flows {
        let bound = flow.max_speed(W, H, 0.0);
        let mut seen = 0.0f64;
        for i in 0..=320 {
            for j in 0..=240 {
                let (u, v) = flow.velocity(i as f64, j as f64, 0.0);
                seen = seen.max(u.hypot(v));
            }
        }
        assert!(
            seen <= bound * (1.0 + 1e-12),
            "{name}: speed {seen} > bound {bound}"
        );
        assert!(
            seen >= 0.9 * bound,
            "{name}: bound {bound} is loose (seen {seen})"
        );
    }
}

#[test]
fn solid_body_positive_omega_turns_clockwise_on_screen() {
    let flow = SolidBodyRotation {
        centre: (100.0, 100.0),
        omega_per_ms: 0.05,
    };
    // Right of the centre the particle moves down (+y); below it, to the left.
    let (u, v) = flow.velocity(150.0, 100.0, 0.0);
    assert!(u.abs() < 1e-12 && (v - 2.5).abs() < 1e-12, "({u}, {v})");
    let (u, v) = flow.velocity(100.0, 150.0, 0.0);
    assert!((u + 2.5).abs() < 1e-12 && v.abs() < 1e-12, "({u}, {v})");
    // A quarter turn takes the particle from the right of the centre to below it.
    let quarter_us = std::f64::consts::FRAC_PI_2 / 0.05 * 1e3;
    let p = flow.advect((150.0, 100.0), 0.0, quarter_us);
    assert!(dist(p, (100.0, 150.0)) < 1e-9, "{p:?}");
}

#[test]
fn vortices_with_positive_strength_turn_clockwise_on_screen() {
    let rankine = RankineVortex {
        centre: (0.0, 0.0),
        omega_core_per_ms: 0.1,
        core_radius_px: 20.0,
    };
    let lamb = LambOseenVortex {
        centre: (0.0, 0.0),
        circulation_px2_per_ms: 1000.0,
        core_radius_px: 20.0,
    };
    for flow in [&rankine as &dyn Flow, &lamb] {
        for r in [5.0, 20.0, 80.0] {
            let (u, v) = flow.velocity(r, 0.0, 0.0);
            assert!(u.abs() < 1e-12 && v > 0.0, "{flow:?} at r {r}: ({u}, {v})");
            let p = flow.advect((r, 0.0), 0.0, 100.0);
            assert!(p.1 > 0.0, "{flow:?} at r {r}: moved to {p:?}");
        }
    }
}

#[test]
fn rankine_velocity_at_known_radii() {
    let flow = RankineVortex {
        centre: (10.0, 20.0),
        omega_core_per_ms: 0.1,
        core_radius_px: 50.0,
    };
    let speed = |r: f64| {
        let (u, v) = flow.velocity(10.0, 20.0 + r, 0.0);
        assert_eq!(v, 0.0);
        -u
    };
    assert!((speed(25.0) - 2.5).abs() < 1e-12);
    assert!((speed(50.0) - 5.0).abs() < 1e-12);
    assert!((speed(100.0) - 2.5).abs() < 1e-12);
    assert_eq!(flow.velocity(10.0, 20.0, 0.0), (0.0, 0.0));
}

#[test]
fn lamb_oseen_speed_peaks_at_1_1209_core_radii() {
    // The constant is the root of e^q = 1 + 2q.
    let q = analytic::LAMB_OSEEN_PEAK_Q;
    assert!((q.exp() - 1.0 - 2.0 * q).abs() < 1e-13);
    let flow = LambOseenVortex {
        centre: (160.0, 120.0),
        circulation_px2_per_ms: 2500.0,
        core_radius_px: 64.0,
    };
    assert!((flow.peak_radius() / 64.0 - 1.1209).abs() < 5e-5);
    let peak = flow.tangential_velocity(flow.peak_radius());
    for f in [0.9, 0.99, 0.999, 1.001, 1.01, 1.1] {
        assert!(flow.tangential_velocity(f * flow.peak_radius()) < peak);
    }
    // u_θ(r_c) = Γ/(2π r_c) (1 − 1/e), from the velocity field.
    let (u, v) = flow.velocity(160.0 + 64.0, 120.0, 0.0);
    let want = 2500.0 / (2.0 * std::f64::consts::PI * 64.0) * (1.0 - (-1.0f64).exp());
    assert!(
        u.abs() < 1e-12 && (v - want).abs() < 1e-12,
        "({u}, {v}) vs {want}"
    );
    // Far away it is a point vortex.
    let far = flow.tangential_velocity(2000.0);
    assert!((far - 2500.0 / (2.0 * std::f64::consts::PI * 2000.0)).abs() < 1e-12);
}

#[test]
fn lamb_oseen_centre_is_regular() {
    let flow = LambOseenVortex {
        centre: (5.0, 5.0),
        circulation_px2_per_ms: 5000.0,
        core_radius_px: 40.0,
    };
    assert_eq!(flow.velocity(5.0, 5.0, 0.0), (0.0, 0.0));
    assert_eq!(flow.advect((5.0, 5.0), 0.0, 1e6), (5.0, 5.0));
    let omega0 = 5000.0 / (2.0 * std::f64::consts::PI * 1600.0);
    for r in [0.0, 1e-9, 1e-4, 1e-2] {
        let rel = (flow.angular_velocity(r) - omega0).abs() / omega0;
        assert!(rel < 1e-5, "r {r}: ω {}", flow.angular_velocity(r));
    }
}

#[test]
fn shear_and_channel_velocities_at_known_points() {
    let couette = Couette::horizontal(0.1, 50.0);
    assert_eq!(couette.velocity(7.0, 80.0, 0.0), (0.1 * 30.0, 0.0));
    let (u, v) = couette.velocity(7.0, 20.0, 0.0);
    assert!((u + 3.0).abs() < 1e-12 && v == 0.0);
    // Rotated by 45°: the velocity is along (cos α, −sin α), zero on the line through
    // (x0, y0), and proportional to s.
    let rotated = Couette {
        gradient_per_ms: 0.1,
        x0: 10.0,
        y0: 50.0,
        angle_rad: 45f64.to_radians(),
    };
    let (u, v) = rotated.velocity(20.0, 60.0, 0.0);
    let s = 10.0 * 2f64.sqrt();
    assert!((u - 0.1 * s / 2f64.sqrt()).abs() < 1e-12 && (v + u).abs() < 1e-12);
    let (u, v) = rotated.velocity(20.0, 40.0, 0.0);
    assert!(u.abs() < 1e-12 && v.abs() < 1e-12);

    let channel = Poiseuille {
        u_max: 8.0,
        y_min: 20.0,
        y_max: 60.0,
    };
    assert_eq!(channel.velocity(0.0, 40.0, 0.0), (8.0, 0.0));
    assert_eq!(channel.velocity(0.0, 30.0, 0.0), (6.0, 0.0));
    for y in [20.0, 60.0, 0.0, 100.0] {
        assert_eq!(channel.velocity(0.0, y, 0.0), (0.0, 0.0));
    }
    assert_eq!(channel.advect((1.0, 10.0), 0.0, 1e4), (1.0, 10.0));
    assert_eq!(channel.advect((1.0, 30.0), 0.0, 1e4), (61.0, 30.0));
}

/// The tanh profile (Michalke 1964): its values, its shear, its vorticity and momentum
/// thicknesses (2δ and δ/2), and streamwise paths, horizontal and rotated.
#[test]
fn mixing_layer_follows_the_tanh_profile() {
    let (u1, u2, delta) = (0.05, 5.0, 8.0);
    let layer = MixingLayer::horizontal(u1, u2, 64.0, delta);
    // u1 at the top of the image (small y), u2 at the bottom, the mean on the centre line.
    let centre = layer.velocity(3.0, 64.0, 0.0);
    assert!((centre.0 - 0.5 * (u1 + u2)).abs() < 1e-12);
    // v is +0, not −0, so that files print 0.
    assert!(
        centre.1 == 0.0 && centre.1.is_sign_positive(),
        "v = {}",
        centre.1
    );
    let (top, bottom) = (
        layer.velocity(0.0, -200.0, 0.0),
        layer.velocity(0.0, 400.0, 0.0),
    );
    assert!((top.0 - u1).abs() < 1e-12 && top.1 == 0.0, "{top:?}");
    assert!(
        (bottom.0 - u2).abs() < 1e-12 && bottom.1 == 0.0,
        "{bottom:?}"
    );
    let one_delta = u1 + (u2 - u1) * 0.5 * (1.0 + 1f64.tanh());
    assert!((layer.velocity(0.0, 72.0, 0.0).0 - one_delta).abs() < 1e-12);
    // Antisymmetric about the centre line: U(s) + U(−s) = u1 + u2.
    for s in [0.5, 3.0, 11.0, 40.0] {
        let sum = layer.profile(s) + layer.profile(-s);
        assert!((sum - (u1 + u2)).abs() < 1e-12, "s {s}: {sum}");
    }
    // The shear: analytic against central differences, largest on the centre line.
    let e = 1e-4;
    for s in [-20.0, -8.0, -1.0, 0.0, 2.5, 8.0, 30.0] {
        let numeric = (layer.profile(s + e) - layer.profile(s - e)) / (2.0 * e);
        assert!((layer.shear_rate(s) - numeric).abs() < 1e-8, "s {s}");
    }
    let peak = layer.shear_rate(0.0);
    assert!((peak - (u2 - u1) / (2.0 * delta)).abs() < 1e-15);
    assert!(
        ((u2 - u1) / peak - 2.0 * delta).abs() < 1e-12,
        "vorticity thickness 2δ"
    );
    // Momentum thickness ∫ (U − u1)(u2 − U) / (u2 − u1)² ds = δ/2 (midpoint rule, ±20δ).
    let ds = 1e-3;
    let theta: f64 = (0..320_000)
        .map(|i| {
            let u = layer.profile(-160.0 + (i as f64 + 0.5) * ds);
            (u - u1) * (u2 - u) / ((u2 - u1) * (u2 - u1)) * ds
        })
        .sum();
    assert!(
        (theta - 0.5 * delta).abs() < 1e-6,
        "momentum thickness {theta}"
    );
    // Paths run along x at the speed of their row.
    let p = layer.advect((10.0, 72.0), 0.0, 20_000.0);
    assert_eq!(p.1, 72.0);
    assert!((p.0 - 10.0 - 20.0 * one_delta).abs() < 1e-12);
    // Rotated by 90°, the flow runs up the screen (−y) and u1 lies to its left (−x).
    let up = MixingLayer {
        angle_rad: 90f64.to_radians(),
        x0: 100.0,
        ..layer
    };
    let (u, v) = up.velocity(100.0, 7.0, 0.0);
    assert!(
        u.abs() < 1e-12 && (v + 0.5 * (u1 + u2)).abs() < 1e-12,
        "({u}, {v})"
    );
    let (u, v) = up.velocity(-300.0, 7.0, 0.0);
    assert!(u.abs() < 1e-12 && (v + u1).abs() < 1e-12, "({u}, {v})");
}

#[test]
fn uniform_and_stagnation_velocities_at_known_points() {
    let down = Uniform::from_speed_angle(3.0, 90f64.to_radians());
    let (u, v) = down.velocity(0.0, 0.0, 0.0);
    assert!(u.abs() < 1e-15 && v == 3.0);
    let p = Uniform { u: 2.0, v: -1.0 }.advect((1.0, 1.0), 500.0, 2_500.0);
    assert_eq!(p, (5.0, -1.0));

    let stagnation = StagnationPoint {
        centre: (100.0, 200.0),
        k_per_ms: 0.1,
    };
    assert_eq!(stagnation.velocity(110.0, 180.0, 0.0), (1.0, 2.0));
    let p = stagnation.advect((110.0, 180.0), 0.0, 10_000.0);
    let e = 1f64.exp();
    assert!(dist(p, (100.0 + 10.0 * e, 200.0 - 20.0 / e)) < 1e-12);
}

/// Arc length of `y = a sin(2πx/b) + c` between `x0` and `x1` (Gauss–Legendre, 5 points per
/// panel, panels of at most 1 px).
fn arc_length(flow: &Sinusoidal, x0: f64, x1: f64) -> f64 {
    const NODES: [(f64, f64); 5] = [
        (0.0, 0.568_888_888_888_888_9),
        (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
        (0.906_179_845_938_664, 0.236_926_885_056_189_1),
    ];
    let panels = ((x1 - x0).abs().ceil() as usize).max(1);
    let h = (x1 - x0) / panels as f64;
    (0..panels)
        .map(|i| {
            let mid = x0 + (i as f64 + 0.5) * h;
            NODES
                .iter()
                .map(|&(z, w)| w * flow.slope(mid + 0.5 * h * z).hypot(1.0))
                .sum::<f64>()
                * 0.5
                * h
        })
        .sum::<f64>()
        .abs()
}

#[test]
fn sinusoidal_path_keeps_its_streamline_and_speed() {
    for (amplitude, wavelength, speed) in [(6.0, 128.0, 5.0), (5.0, 32.0, 20.0), (6.0, 64.0, -8.0)]
    {
        let flow = Sinusoidal {
            amplitude_px: amplitude,
            wavelength_px: wavelength,
            speed,
        };
        for p in [(0.0, 100.0), (17.3, 42.0), (300.0, 7.5)] {
            let (u, v) = flow.velocity(p.0, p.1, 0.0);
            assert!((u.hypot(v) - speed.abs()).abs() < 1e-12);
            let t_ms = 25.0;
            let q = flow.advect(p, 0.0, t_ms * 1e3);
            let drift = flow.streamline_offset(q.0, q.1) - flow.streamline_offset(p.0, p.1);
            assert!(
                drift.abs() < 1e-6,
                "{flow:?} from {p:?}: offset drift {drift}"
            );
            let travelled = arc_length(&flow, p.0, q.0);
            let err = travelled - speed.abs() * t_ms;
            assert!(
                err.abs() < 1e-6,
                "{flow:?} from {p:?}: arc length error {err}"
            );
            assert!((q.0 - p.0) * speed > 0.0);
        }
    }
}

#[test]
fn cellular_path_conserves_the_stream_function() {
    let flow = Cellular {
        amplitude: 10.0,
        period_px: 128.0,
    };
    for p in [
        (10.0, 20.0),
        (40.0, 40.0),
        (100.0, 170.0),
        (250.0, 3.0),
        (33.0, 60.0),
    ] {
        let q = flow.advect(p, 0.0, 25_000.0);
        let (u, v) = flow.velocity(q.0, q.1, 0.0);
        // ψ changes by |∇ψ| = speed per pixel across streamlines.
        let drift = (flow.stream_function(q.0, q.1) - flow.stream_function(p.0, p.1)) / u.hypot(v);
        assert!(
            drift.abs() < 1e-6,
            "from {p:?} to {q:?}: {drift} px across streamlines"
        );
        assert!(dist(p, q) > 1.0, "from {p:?}: did not move");
    }
    // Consistency of ψ with the velocity: u = ∂ψ/∂y, v = −∂ψ/∂x.
    let (x, y, e) = (37.0, 81.0, 1e-5);
    let (u, v) = flow.velocity(x, y, 0.0);
    let dpsi_dy = (flow.stream_function(x, y + e) - flow.stream_function(x, y - e)) / (2.0 * e);
    let dpsi_dx = (flow.stream_function(x + e, y) - flow.stream_function(x - e, y)) / (2.0 * e);
    assert!((u - dpsi_dy).abs() < 1e-6 && (v + dpsi_dx).abs() < 1e-6);
}

#[test]
fn superposition_adds_velocities_and_integrates_paths() {
    let vortex = RankineVortex {
        centre: (160.0, 120.0),
        omega_core_per_ms: 0.1,
        core_radius_px: 50.0,
    };
    let stream = Uniform { u: 3.0, v: -1.0 };
    let sum = Superposition(vec![Box::new(vortex), Box::new(stream)]);
    let (a, b, c) = (
        sum.velocity(200.0, 90.0, 0.0),
        vortex.velocity(200.0, 90.0, 0.0),
        stream.velocity(200.0, 90.0, 0.0),
    );
    assert!(dist(a, (b.0 + c.0, b.1 + c.1)) < 1e-12);
    assert!((sum.max_speed(W, H, 0.0) - (5.0 + 10f64.sqrt())).abs() < 1e-12);
    // A superposition of one uniform stream reproduces the exact path.
    let single = Superposition(vec![Box::new(stream)]);
    let p = single.advect((10.0, 10.0), 0.0, 30_000.0);
    assert!(dist(p, (100.0, -20.0)) < 1e-9, "{p:?}");
    // Two opposite rotations cancel.
    let still = Superposition(vec![
        Box::new(SolidBodyRotation {
            centre: (0.0, 0.0),
            omega_per_ms: 0.2,
        }),
        Box::new(SolidBodyRotation {
            centre: (0.0, 0.0),
            omega_per_ms: -0.2,
        }),
    ]);
    assert_eq!(still.advect((3.0, 4.0), 0.0, 1e5), (3.0, 4.0));
}
