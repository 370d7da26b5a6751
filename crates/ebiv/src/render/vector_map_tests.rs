use super::*;
use crate::field::FieldSeries;
use crate::render::axes::probe::{colour_bar_column, plot_frame as frame};
use proptest::prelude::*;

/// A Lamb–Oseen vortex (circulation so the peak swirl is `peak` px/ms, core radius `rc` px)
/// on a grid of `step` px over a `w × h` sensor, centred at `(cx, cy)`.
pub(crate) fn lamb_oseen(w: f64, h: f64, step: f64, peak: f64, rc: f64) -> VectorField {
    let x = FieldSeries::axis(step, w - step, step);
    let y = FieldSeries::axis(step, h - step, step);
    let mut f = VectorField::new(x, y);
    let (cx, cy) = (w / 2.0, h / 2.0);
    // u_θ(r) = Γ/(2πr)(1 − e^{−r²/rc²}) peaks at r ≈ 1.1209 rc with 0.6382 Γ/(2π rc).
    let gamma_2pi = peak * rc / 0.638_2;
    for r in 0..f.height() {
        for c in 0..f.width() {
            let (dx, dy) = (f.x[c] - cx, f.y[r] - cy);
            let rr = dx.hypot(dy).max(1e-9);
            let ut = gamma_2pi / rr * (1.0 - (-(rr * rr) / (rc * rc)).exp());
            let i = f.index(r, c);
            f.u[i] = (-ut * dy / rr) as f32;
            f.v[i] = (ut * dx / rr) as f32;
            f.status[i] = Status::VALID;
        }
    }
    f
}

fn uniform(u: f32, v: f32) -> VectorField {
    let mut f = VectorField::new(vec![50.0], vec![50.0]);
    f.u[0] = u;
    f.v[0] = v;
    f.status[0] = Status::VALID;
    f
}

fn style() -> VectorMapStyle {
    VectorMapStyle {
        pixel_scale: Some(4.0),
        ..Default::default()
    }
}

#[test]
fn arrows_point_along_the_velocity() {
    for (u, v, dir) in [(1.0, 0.0, (1, 0)), (-1.0, 0.0, (-1, 0)), (0.0, 1.0, (0, 1))] {
        let f = uniform(u, v);
        let img = vector_map(&f, Geometry::new(100, 100), None, &style());
        let (left, top, ..) = frame(&img);
        // Node (50, 50) sits at output 4·50.5 px from the plot's inner corner.
        let (nx, ny) = ((left + 1) as i64 + 202, (top + 1) as i64 + 202);
        let white = |d: i64| {
            let p = img
                .get_pixel((nx + d * dir.0) as u32, (ny + d * dir.1) as u32)
                .0;
            p == VALID
        };
        // The arrow is white along the velocity direction and absent behind the node.
        assert!((4..28).all(white), "u={u} v={v}");
        assert!(!(-30..-6).any(white), "u={u} v={v}");
    }
}

#[test]
fn colour_bar_and_markers_are_drawn() {
    let mut f = lamb_oseen(100.0, 100.0, 10.0, 2.0, 20.0);
    f.invalidate(0, Status::MEDIAN_TEST);
    let i = f.index(2, 6);
    f.status[i] = Status::MEDIAN_TEST | Status::REPLACED;
    let img = vector_map(&f, Geometry::new(100, 100), None, &style());
    // The colour bar: inferno's bright end at the top, its dark end at the bottom.
    assert!(colour_bar_column(&img, inferno(1.0), inferno(0.0)).is_some());
    // The invalid node is a red cross, the replaced one has cyan.
    let count = |c: Colour| img.pixels().filter(|p| p.0 == c).count();
    assert!(count(super::super::arrow::INVALID) > 10);
    assert!(count(REPLACED) > 10);
}

#[test]
fn degenerate_fields_do_not_panic() {
    let g = Geometry::new(64, 48);
    let s = VectorMapStyle::default();
    vector_map(&VectorField::new(vec![], vec![]), g, None, &s);
    vector_map(&VectorField::new(vec![10.0, 20.0], vec![5.0]), g, None, &s);
    vector_map(&uniform(0.0, 0.0), g, None, &s);
    vector_map(&uniform(f32::INFINITY, 1.0), g, None, &s);
    vector_map(&uniform(f32::MAX, -f32::MAX), Geometry::new(0, 0), None, &s);
    let bg = RgbImage::new(3, 2);
    vector_map(&uniform(1.0, 1.0), g, Some(&bg), &s);
    let odd = VectorMapStyle {
        scale: Some(f64::NAN),
        magnitude_range: Some((1.0, 1.0)),
        pixel_scale: Some(1e9),
        stride: Some(0),
        ..s
    };
    vector_map(&uniform(1.0, 1.0), Geometry::new(2, 2), None, &odd);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn random_fields_do_not_panic(
        values in proptest::collection::vec(
            prop_oneof![any::<f32>(), -10.0f32..10.0, Just(f32::NAN)], 0..24),
        flags in proptest::collection::vec(any::<u8>(), 24),
        w in 1u32..200, h in 1u32..200, cols in 1usize..4,
    ) {
        let rows = values.len() / 2 / cols;
        let x = (0..cols).map(|c| c as f64 * 7.0).collect();
        let y = (0..rows).map(|r| r as f64 * 7.0).collect();
        let mut f = VectorField::new(x, y);
        for i in 0..f.len() {
            f.u[i] = values[2 * i];
            f.v[i] = values[2 * i + 1];
            f.status[i] = Status(flags[i]);
        }
        let style = VectorMapStyle { pixel_scale: Some(2.0), ..Default::default() };
        let img = vector_map(&f, Geometry::new(w, h), None, &style);
        prop_assert!(img.width() >= 2 * w);
    }
}

#[test]
fn default_arrows_are_thinned_and_stride_one_draws_all() {
    // 100 × 25 nodes 4 px apart, drawn 2× (8 px apart): every third node by default, so
    // arrows are ≥ 16 px apart and at most 40 span the grid.
    let x = FieldSeries::axis(2.0, 398.0, 4.0);
    let y = FieldSeries::axis(2.0, 98.0, 4.0);
    let mut f = VectorField::new(x, y);
    f.u.fill(1.0);
    f.v.fill(0.0);
    f.status.fill(Status::VALID);
    let g = Geometry::new(400, 100);
    assert_eq!(arrow_stride(&f.x, &f.y, g, &style()), 3);
    let two = VectorMapStyle {
        pixel_scale: Some(2.0),
        ..Default::default()
    };
    assert_eq!(arrow_stride(&f.x, &f.y, g, &two), 3);
    let all = VectorMapStyle {
        stride: Some(1),
        ..two.clone()
    };
    let thinned = vector_map(&f, g, None, &two);
    let every = vector_map(&f, g, None, &all);
    let (left, top, ..) = frame(&thinned);
    assert_eq!(frame(&every).0, left);
    // Row r of nodes lies at output y = top + 1 + 2·(4r + 2.5); its arrows point right.
    let white = |img: &RgbImage, r: u32, c: u32| {
        let (nx, ny) = (
            left + 1 + 2 * (4 * c + 2) + 1,
            top + 1 + 2 * (4 * r + 2) + 1,
        );
        arrow_at(img, (nx + 4) as f64, ny as f64)
    };
    for c in [0, 3, 30] {
        assert!(
            white(&thinned, 0, c) && white(&thinned, 3, c),
            "node ({c}) drawn"
        );
        assert!(white(&every, 1, c + 1), "stride 1 draws every node");
    }
    for r in [1, 2, 4, 5] {
        assert!(!white(&thinned, r, 3), "row {r} is left out by default");
    }
}

#[test]
fn auto_stride_bounds_density() {
    assert_eq!(auto_stride(30.0, 30), 1);
    assert_eq!(auto_stride(8.0, 10), 2, "≥ 16 px apart");
    assert_eq!(auto_stride(15.6, 64), 2, "≤ 40 across");
    assert_eq!(auto_stride(1.0, 1000), 25);
    assert_eq!(auto_stride(f64::NAN, 0), 1);
}

/// Whether a white arrow covers output pixel `(x, y)` or a neighbour. Thin arrows are
/// anti-aliased over their black halo, so their body is light grey rather than white: some
/// pixel of the 3 × 3 block is grey (channels within 10) and at least 140 bright, which
/// neither the inferno map, the halo nor the no-data grey is.
fn arrow_at(img: &RgbImage, x: f64, y: f64) -> bool {
    let (x, y) = (x as i64, y as i64);
    let inside =
        |a: i64, b: i64| a >= 0 && b >= 0 && a < img.width() as i64 && b < img.height() as i64;
    (x - 1..=x + 1)
        .flat_map(|a| (y - 1..=y + 1).map(move |b| (a, b)))
        .filter(|&(a, b)| inside(a, b))
        .any(|(a, b)| {
            let p = img.get_pixel(a as u32, b as u32).0;
            let (lo, hi) = (*p.iter().min().unwrap(), *p.iter().max().unwrap());
            lo >= 140 && hi - lo <= 10
        })
}

/// Output position of node (`r`, `c`) of `f` in a figure drawn with plot frame corner
/// `(left, top)` at `k` output px per image px.
fn node_position(f: &VectorField, left: u32, top: u32, k: f64, r: usize, c: usize) -> (f64, f64) {
    (
        (left + 1) as f64 + (f.x[c] + 0.5) * k,
        (top + 1) as f64 + (f.y[r] + 0.5) * k,
    )
}

/// The sample figures: a Lamb–Oseen vortex on a 1280 × 720 sensor (arrows thinned), a small
/// one (all arrows) alone and over a background. Checks the plot size, the colour bar, the
/// stride and that the drawn arrows point along the flow; writes the figures to
/// `$EBIV_RENDER_SAMPLES` when set, for looking at.
#[test]
fn sample_figures() {
    let dir = std::env::var_os("EBIV_RENDER_SAMPLES").map(std::path::PathBuf::from);
    let save = |img: &RgbImage, name: &str| {
        if let Some(dir) = &dir {
            crate::render::save_png(img, &dir.join(name)).unwrap();
        }
    };
    let mut f = lamb_oseen(1280.0, 720.0, 24.0, 2.0, 120.0);
    for i in [100, 341, 342, 900, 1201] {
        f.invalidate(i, Status::LOW_PEAK_RATIO);
    }
    for i in [500, 777] {
        f.status[i] = Status::MEDIAN_TEST | Status::REPLACED;
    }
    let style = VectorMapStyle {
        title: Some("Lamb-Oseen vortex, 24 px grid".into()),
        ..Default::default()
    };
    let g = Geometry::new(1280, 720);
    let img = vector_map(&f, g, None, &style);
    let (l, t, r, b) = frame(&img);
    assert_eq!((r - l - 1, b - t - 1), (1000, 563), "about 1000 px wide");
    assert!(colour_bar_column(&img, inferno(1.0), inferno(0.0)).is_some());
    // 53 × 29 nodes 18.75 output px apart: every second one, 27 across.
    assert_eq!(arrow_stride(&f.x, &f.y, g, &style), 2);
    let k = 1000.0 / 1280.0;
    for (row, col) in [(4, 10), (20, 40), (10, 26)] {
        let i = f.index(row, col);
        let (p, d) = (
            node_position(&f, l, t, k, row, col),
            (f.u[i] as f64, f.v[i] as f64),
        );
        let unit = (d.0 / d.0.hypot(d.1), d.1 / d.0.hypot(d.1));
        let along = |s: f64| arrow_at(&img, p.0 + s * unit.0, p.1 + s * unit.1);
        assert!(along(6.0), "arrow at node ({row}, {col}) along the flow");
        assert!(!along(-6.0), "nothing behind node ({row}, {col})");
    }
    save(&img, "vector_map.png");

    let small = lamb_oseen(320.0, 240.0, 16.0, 1.5, 40.0);
    let g = Geometry::new(320, 240);
    let img = vector_map(&small, g, None, &VectorMapStyle::default());
    let (l, t, r, b) = frame(&img);
    assert_eq!((r - l - 1, b - t - 1), (960, 720), "enlarged 3 times");
    assert_eq!(
        arrow_stride(&small.x, &small.y, g, &VectorMapStyle::default()),
        1
    );
    assert!(colour_bar_column(&img, inferno(1.0), inferno(0.0)).is_some());
    save(&img, "vector_map_small.png");
    // A background: speckle standing in for a time-coded event image; no colour bar.
    let bg = RgbImage::from_fn(320, 240, |x, y| {
        let h = (x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)) % 97;
        if h < 3 {
            [255, 255, 255].into()
        } else if h < 6 {
            [60, 90, 255].into()
        } else {
            [0, 0, 0].into()
        }
    });
    let img = vector_map(&small, g, Some(&bg), &VectorMapStyle::default());
    assert!(colour_bar_column(&img, inferno(1.0), inferno(0.0)).is_none());
    let (l, t, ..) = frame(&img);
    // Background pixels dimmed to 60 %: a blue speckle becomes [36, 54, 153].
    let dimmed = (0..320 * 240).filter(|i| {
        let (x, y) = (i % 320, i / 320);
        bg.get_pixel(x, y).0 == [60, 90, 255]
            && img.get_pixel(l + 1 + 3 * x + 1, t + 1 + 3 * y + 1).0 == [36, 54, 153]
    });
    assert!(dimmed.count() > 1000);
    save(&img, "vector_map_background.png");
}

/// The sample histogram: velocities with simulated peak locking (displacements over
/// τ = 2 ms pulled toward integers). Checks that the fractional-displacement panel shows the
/// locking (tall bars at 0 and 1) and that the caption is drawn; writes the figure to
/// `$EBIV_RENDER_SAMPLES` when set.
#[test]
fn sample_histogram() {
    let mut state = 12345u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let tau = 2.0;
    let mut locked = |mean: f64, sd: f64| {
        let g: f64 = (0..12).map(|_| uniform()).sum::<f64>() - 6.0;
        let d = (mean + sd * g) * tau;
        ((d - 0.1 * (std::f64::consts::TAU * d).sin()) / tau) as f32
    };
    let u: Vec<f32> = (0..20_000).map(|_| locked(1.5, 0.6)).collect();
    let v: Vec<f32> = (0..20_000).map(|_| locked(-0.3, 0.4)).collect();
    let style = crate::render::HistogramStyle {
        bins: 120,
        displacement_ms: Some(tau),
        title: Some("Velocity histograms, τ = 2 ms".into()),
        ..Default::default()
    };
    let img = crate::render::velocity_histograms(&u, &v, &style);
    let bars = super::super::histogram::tests::bar_heights(&img, 2 * img.width() / 3);
    assert_eq!(bars.len(), 10, "ten bars of fractional displacement");
    assert!(bars[0] > bars[4] + 20 && bars[9] > bars[5] + 20, "{bars:?}");
    assert!(super::super::histogram::tests::caption_ink(&img) > 500);
    if let Some(dir) = std::env::var_os("EBIV_RENDER_SAMPLES") {
        let dir = std::path::PathBuf::from(dir);
        crate::render::save_png(&img, &dir.join("histograms.png")).unwrap();
    }
}
