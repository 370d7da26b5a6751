use super::*;
use crate::field::FieldSeries;
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

/// The plot frame (left, top, right, bottom): the first two rows with about the most ink, and the
/// first two columns inked over the whole height between them.
fn frame(img: &RgbImage) -> (u32, u32, u32, u32) {
    let ink = |x: u32, y: u32| img.get_pixel(x, y).0 == INK;
    let rows: Vec<usize> = (0..img.height())
        .map(|y| (0..img.width()).filter(|&x| ink(x, y)).count())
        .collect();
    let m = *rows.iter().max().unwrap();
    let mut full = (0..img.height()).filter(|&y| rows[y as usize] * 10 >= m * 9);
    let (top, bottom) = (full.next().unwrap(), full.next().unwrap());
    let mut sides = (0..img.width()).filter(|&x| (top..=bottom).all(|y| ink(x, y)));
    (sides.next().unwrap(), top, sides.next().unwrap(), bottom)
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
    let (_, top, right, bottom) = frame(&img);
    // The colour bar: inferno's bright end near the top, its dark end near the bottom.
    let near = |a: [u8; 3], b: [u8; 3]| (0..3).all(|k| a[k].abs_diff(b[k]) < 12);
    let bar_x = (right + 1..img.width()).find(|&x| near(img.get_pixel(x, top + 3).0, inferno(1.0)));
    let bar_x = bar_x.expect("colour bar");
    assert!(near(img.get_pixel(bar_x + 2, bottom - 3).0, inferno(0.0)));
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

/// Writes sample figures to `$EBIV_RENDER_SAMPLES` (when set) for looking at.
#[test]
fn sample_figures() {
    let Some(dir) = std::env::var_os("EBIV_RENDER_SAMPLES") else {
        return;
    };
    let dir = std::path::PathBuf::from(dir);
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
    let img = vector_map(&f, Geometry::new(1280, 720), None, &style);
    crate::render::save_png(&img, &dir.join("vector_map.png")).unwrap();
    let small = lamb_oseen(320.0, 240.0, 16.0, 1.5, 40.0);
    let img = vector_map(
        &small,
        Geometry::new(320, 240),
        None,
        &VectorMapStyle::default(),
    );
    crate::render::save_png(&img, &dir.join("vector_map_small.png")).unwrap();
    // A background: speckle standing in for a time-coded event image.
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
    let img = vector_map(
        &small,
        Geometry::new(320, 240),
        Some(&bg),
        &VectorMapStyle::default(),
    );
    crate::render::save_png(&img, &dir.join("vector_map_background.png")).unwrap();
}

/// Writes a histogram sample to `$EBIV_RENDER_SAMPLES` (when set): velocities with simulated
/// peak locking (displacements over τ = 2 ms pulled toward integers).
#[test]
fn sample_histogram() {
    let Some(dir) = std::env::var_os("EBIV_RENDER_SAMPLES") else {
        return;
    };
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
    let dir = std::path::PathBuf::from(dir);
    crate::render::save_png(&img, &dir.join("histograms.png")).unwrap();
}
