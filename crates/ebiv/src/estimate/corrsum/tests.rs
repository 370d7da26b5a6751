//! Kernel tests: direct and FFT planes against a dense evaluation of the definition.

use super::fit::{fit_gradient, refine_smoothed, refine_tilted, SmoothingKernel};
use super::fourier::Fourier;
use super::voxels::{
    slice_statistics, Overlap, PlaneShape, SliceStats, SubVolume, Voxeliser, Voxels,
};
use super::*;
use crate::peak::find_peak;
use crate::volume::TileRun;

/// SplitMix64: a small deterministic generator for test inputs.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// Random events in a `w × h` window over `[0, slab)`.
fn random_events(rng: &mut Rng, n: usize, w: u32, h: u32, slab: i64) -> WindowEvents {
    let mut e = WindowEvents::default();
    for _ in 0..n {
        e.x.push(rng.below(w as u64) as f32);
        e.y.push(rng.below(h as u64) as f32);
        e.t.push(rng.below(slab as u64) as f32);
    }
    e
}

/// The definition, evaluated on dense images: Σ_z w_z Σ_O (a − ā)(b − b̄) / (n(Δ) · N).
fn dense_plane(
    a: SubVolume<'_>,
    b: SubVolume<'_>,
    stats: &[SliceStats],
    s: PlaneShape,
) -> Vec<f64> {
    let (pw, ph) = (s.plane_width(), s.plane_height());
    let mut plane = vec![0.0; pw * ph];
    let image = |v: SubVolume<'_>, z: usize| {
        let mut img = vec![0.0; s.w * s.h];
        for i in v.range(z) {
            img[v.vox.y[i] as usize * s.w + v.vox.x[i] as usize] = v.vox.v[i];
        }
        img
    };
    for st in stats {
        let (ia, ib) = (image(a, st.z), image(b, st.z));
        for iy in 0..ph {
            for ix in 0..pw {
                let (dx, dy) = (ix as isize - s.rx as isize, iy as isize - s.ry as isize);
                let mut sum = 0.0;
                for y in 0..s.h as isize {
                    for x in 0..s.w as isize {
                        let (x2, y2) = (x + dx, y + dy);
                        if x2 < 0 || y2 < 0 || x2 >= s.w as isize || y2 >= s.h as isize {
                            continue;
                        }
                        let pa = ia[y as usize * s.w + x as usize] - st.mean_a;
                        let pb = ib[y2 as usize * s.w + x2 as usize] - st.mean_b;
                        sum += pa * pb;
                    }
                }
                plane[iy * pw + ix] += st.weight * sum;
            }
        }
    }
    Overlap::new(s).normalise(&mut plane, stats.len());
    plane
}

fn max_relative_difference(x: &[f64], y: &[f64]) -> f64 {
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    x.iter()
        .zip(y)
        .map(|(p, q)| (p - q).abs() / scale)
        .fold(0.0, f64::max)
}

/// [`direct::correlations_at`] of one lag.
fn correlation_at(
    a: SubVolume<'_>,
    b: SubVolume<'_>,
    stats: &[SliceStats],
    shape: PlaneShape,
    lag: [i64; 2],
) -> f64 {
    let mut out = [0.0];
    direct::correlations_at((a, b), stats, shape, &[lag], &mut Vec::new(), &mut out);
    out[0]
}

#[test]
fn direct_fft_and_definition_agree_on_random_inputs() {
    let mut rng = Rng(7);
    let cases = [
        (40u32, 40u32, 20usize, 20usize, 20u32, 300usize, false),
        // The plane of the case before on a narrower window (other pair layout).
        (30, 40, 20, 20, 20, 300, true),
        (32, 24, 16, 12, 10, 200, true),
        (17, 23, 5, 9, 7, 400, false),
        (12, 12, 11, 11, 3, 120, true),
        (40, 40, 20, 20, 20, 4000, false),
    ];
    // Accumulators carried from case to case: rebuilt for each new shape.
    let mut carried: Option<direct::Accumulators> = None;
    for (case, &(w, h, rx, ry, slices, n, count)) in cases.iter().enumerate() {
        let shape = PlaneShape {
            w: w as usize,
            h: h as usize,
            rx,
            ry,
        };
        let mut voxeliser = Voxeliser::new(shape.w, shape.h);
        let (mut a, mut b) = (Voxels::default(), Voxels::default());
        voxeliser.run(
            &random_events(&mut rng, n, w, h, 1000),
            1000,
            slices,
            count,
            &mut a,
        );
        voxeliser.run(
            &random_events(&mut rng, n, w, h, 1000),
            1000,
            slices,
            count,
            &mut b,
        );
        let (a, b) = (a.all(), b.all());
        let mut stats = Vec::new();
        slice_statistics(a, b, shape, &mut stats);
        assert!(!stats.is_empty());
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        let overlap = Overlap::new(shape);
        let mut direct = vec![0.0; pw * ph];
        let mut acc = direct::Accumulators::new(shape);
        let best = direct::correlate(a, b, &stats, shape, &overlap, &mut direct, &mut acc);
        assert_eq!(best, crate::peak::argmax(&direct));
        // The row maxima tracked by the kernel are the plain maxima of the plane's rows.
        let plain: Vec<f64> = direct
            .chunks(pw)
            .map(|row| row.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v)))
            .collect();
        assert_eq!(acc.row_maxima(), &plain[..], "case {case}");
        // The accumulators are left cleared: a second run gives the same plane.
        let mut again = vec![0.0; pw * ph];
        direct::correlate(a, b, &stats, shape, &overlap, &mut again, &mut acc);
        assert_eq!(direct, again);
        let carried = carried.get_or_insert_with(|| direct::Accumulators::new(shape));
        let mut reused = vec![0.0; pw * ph];
        direct::correlate(a, b, &stats, shape, &overlap, &mut reused, carried);
        assert_eq!(direct, reused, "case {case}: accumulators of another shape");
        // The build chosen at run time (AVX2 where available) and the portable one give
        // the same bits.
        let mut portable = vec![0.0; pw * ph];
        let mut fresh = direct::Accumulators::new(shape);
        let inputs = direct::Inputs {
            a,
            b,
            stats: &stats,
            shape,
            overlap: &overlap,
        };
        let best_portable = direct::correlate_portable(inputs, &mut portable, &mut fresh);
        assert_eq!(best_portable, best, "case {case}");
        let bits = |plane: &[f64]| plane.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&direct), bits(&portable), "case {case}");
        // One lag at a time gives the plane's values, and a lag past the plane its own.
        for (iy, row) in direct.chunks(pw).enumerate() {
            for (ix, &cell) in row.iter().enumerate() {
                let lag = [ix as i64 - rx as i64, iy as i64 - ry as i64];
                let single = correlation_at(a, b, &stats, shape, lag);
                assert!(
                    (single - cell).abs() < 1e-9 * cell.abs().max(1.0),
                    "case {case}"
                );
            }
        }
        // Several lags at once give what each gives alone (the grid is left zeroed).
        let lags = [[0, 0], [1, -2], [-3, 1], [2, 2], [-(rx as i64), ry as i64]];
        let (mut together, mut image) = ([0.0; 5], Vec::new());
        direct::correlations_at((a, b), &stats, shape, &lags, &mut image, &mut together);
        assert!(image.iter().all(|&v| v == 0.0), "case {case}");
        for (lag, value) in lags.iter().zip(together) {
            assert_eq!(
                value,
                correlation_at(a, b, &stats, shape, *lag),
                "case {case}"
            );
        }
        if shape.w * shape.h < 500 {
            // The farthest corner of the widest plane (small windows: the dense plane is slow).
            let wide = PlaneShape {
                rx: shape.w - 1,
                ry: shape.h - 1,
                ..shape
            };
            let corner =
                dense_plane(a, b, &stats, wide)[(wide.plane_height() - 1) * wide.plane_width()];
            let far = [1 - shape.w as i64, shape.h as i64 - 1];
            let single = correlation_at(a, b, &stats, shape, far);
            assert!(
                (single - corner).abs() < 1e-9,
                "case {case}: {single} vs {corner}"
            );
        }
        // Lags without overlap, on one axis or on both.
        let (w, h) = (shape.w as i64, shape.h as i64);
        for lag in [[w, 0], [0, -h], [w + 1, h + 1], [-w - 3, h]] {
            assert_eq!(correlation_at(a, b, &stats, shape, lag), 0.0, "{lag:?}");
        }
        let mut fft = vec![0.0; pw * ph];
        Fourier::new(shape).correlate(a, b, &stats, &overlap, &mut fft);
        let dense = dense_plane(a, b, &stats, shape);
        let e1 = max_relative_difference(&dense, &direct);
        let e2 = max_relative_difference(&dense, &fft);
        assert!(
            e1 < 1e-9 && e2 < 1e-9,
            "case {case}: direct {e1:e}, fft {e2:e}"
        );
    }
}

#[test]
fn zero_lag_is_the_mean_pearson_coefficient() {
    // Identical slices correlate perfectly at zero lag.
    let mut rng = Rng(3);
    let shape = PlaneShape {
        w: 20,
        h: 16,
        rx: 6,
        ry: 5,
    };
    let mut voxeliser = Voxeliser::new(20, 16);
    let mut a = Voxels::default();
    voxeliser.run(
        &random_events(&mut rng, 150, 20, 16, 500),
        500,
        5,
        false,
        &mut a,
    );
    let mut stats = Vec::new();
    slice_statistics(a.all(), a.all(), shape, &mut stats);
    let mut plane = vec![0.0; 13 * 11];
    let mut acc = direct::Accumulators::new(shape);
    let overlap = Overlap::new(shape);
    direct::correlate(
        a.all(),
        a.all(),
        &stats,
        shape,
        &overlap,
        &mut plane,
        &mut acc,
    );
    assert!(
        (plane[5 * 13 + 6] - 1.0).abs() < 1e-12,
        "{}",
        plane[5 * 13 + 6]
    );
    assert!(plane.iter().all(|&v| v <= 1.0 + 1e-12));
}

#[test]
fn voxeliser_bins_by_slice_and_deduplicates() {
    let events = WindowEvents {
        x: vec![1.0, 1.0, 1.0, 2.0, 3.0, 0.0],
        y: vec![0.0, 0.0, 0.0, 1.0, 1.0, 0.0],
        t: vec![0.0, 9.0, 10.0, 19.0, 99.0, 100.0],
    };
    let mut voxeliser = Voxeliser::new(4, 2);
    let mut out = Voxels::default();
    voxeliser.run(&events, 100, 10, false, &mut out);
    assert_eq!(out.all().events(), 5, "the event at t = slab is outside");
    assert_eq!(out.slice_events, vec![2, 2, 0, 0, 0, 0, 0, 0, 0, 1]);
    assert_eq!(out.start, vec![0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 4]);
    assert_eq!(out.v, vec![1.0; 4]);
    voxeliser.run(&events, 100, 10, true, &mut out);
    assert_eq!(out.v, vec![2.0, 1.0, 1.0, 1.0]);
    assert_eq!((out.x[1], out.y[1]), (1, 0));
}

#[test]
fn slices_are_exact_with_and_without_the_table() {
    // Short sub-volumes use the tabulated slices, long ones the arithmetic: both give ⌊tN/T⌋.
    // One voxeliser throughout: its table is reused or rebuilt as the sub-volume changes.
    let mut voxeliser = Voxeliser::new(1, 1);
    let mut out = Voxels::default();
    for (slab, slices) in [
        (1000i64, 7u32),
        (10_000, 20),
        (13_000, 26),
        (10_000, 20),
        (20_000, 40),
        (200_000, 30),
        (99_991, 13),
    ] {
        for t in [0, 1, slab / 3, slab / 2 + 1, slab - 2, slab - 1] {
            let events = WindowEvents {
                x: vec![0.0],
                y: vec![0.0],
                t: vec![t as f32],
            };
            voxeliser.run(&events, slab, slices, false, &mut out);
            let z = out.slice_events.iter().position(|&n| n == 1).unwrap();
            assert_eq!(
                z as i64,
                t * slices as i64 / slab,
                "T {slab}, N {slices}, t {t}"
            );
        }
    }
}

/// A tile's events binned as a run ([`Voxeliser::add_narrow_run`], the path of the tiles
/// inside a window) give the voxels of binning them one by one with every test
/// ([`Voxeliser::add_pixel`]): both weightings, sub-volumes with and without the slice table.
#[test]
fn runs_bin_as_single_events() {
    let mut rng = Rng(23);
    let (w, h, origin) = (40usize, 33usize, [100i64, 50, 1_000]);
    for (slab, slices) in [(10_000i64, 20usize), (200_000, 30)] {
        for count in [false, true] {
            let n = 500;
            let at = |o: i64, extent: u64, rng: &mut Rng| (o as u64 + rng.below(extent)) as u16;
            let x: Vec<u16> = (0..n).map(|_| at(origin[0], w as u64, &mut rng)).collect();
            let y: Vec<u16> = (0..n).map(|_| at(origin[1], h as u64, &mut rng)).collect();
            let mut t: Vec<i64> = (0..n)
                .map(|_| origin[2] + rng.below(slab as u64) as i64)
                .collect();
            t.sort_unstable();
            let mut by_run = Voxeliser::new(w, h);
            by_run.begin(slab, slices, count);
            assert!(by_run.is_narrow());
            let run = TileRun {
                x: &x,
                y: &y,
                t: &t,
            };
            if count {
                by_run.add_narrow_run::<true>(run, origin);
            } else {
                by_run.add_narrow_run::<false>(run, origin);
            }
            let mut one_by_one = Voxeliser::new(w, h);
            one_by_one.begin(slab, slices, count);
            for i in 0..n {
                let (col, row) = (x[i] as i64 - origin[0], y[i] as i64 - origin[1]);
                one_by_one.add_pixel(col as usize, row as usize, t[i] - origin[2]);
            }
            let (mut a, mut b) = (Voxels::default(), Voxels::default());
            by_run.finish(&mut a);
            one_by_one.finish(&mut b);
            let case = format!("T {slab} µs, {slices} slices, count {count}");
            assert_eq!(a.slice_events.iter().sum::<usize>(), n, "{case}");
            assert_eq!(
                (&a.x, &a.y, &a.v, &a.start, &a.slice_events),
                (&b.x, &b.y, &b.v, &b.start, &b.slice_events),
                "{case}"
            );
        }
    }
}

#[test]
fn voxels_are_sorted_by_row_within_a_slice() {
    let mut rng = Rng(11);
    let mut voxeliser = Voxeliser::new(70, 9);
    let mut out = Voxels::default();
    voxeliser.run(
        &random_events(&mut rng, 400, 70, 9, 300),
        300,
        3,
        false,
        &mut out,
    );
    for z in 0..3 {
        let r = out.all().range(z);
        let keys: Vec<(u16, u16)> = r.map(|i| (out.y[i], out.x[i])).collect();
        assert!(keys.windows(2).all(|k| k[0] < k[1]), "slice {z}: {keys:?}");
    }
    // Reading the bitmaps back cleared them: an empty run gives no voxels.
    voxeliser.run(&WindowEvents::default(), 300, 3, false, &mut out);
    assert!(out.x.is_empty() && out.start == vec![0; 4]);
}

/// One voxelisation of `[S1 start, S2 end)` split into overlapping runs of slices gives the
/// same sub-volumes, statistics and plane as voxelising S1 and S2 separately.
#[test]
fn shared_voxelisation_equals_separate_sub_volumes() {
    let mut rng = Rng(5);
    let (slab, tau, slices, k) = (1000i64, 300i64, 10usize, 3usize);
    let shape = PlaneShape {
        w: 24,
        h: 20,
        rx: 8,
        ry: 6,
    };
    let all = random_events(&mut rng, 900, 24, 20, slab + tau);
    let part = |from: i64| {
        let mut e = WindowEvents::default();
        for i in 0..all.len() {
            let t = all.t[i] - from as f32;
            if (0.0..slab as f32).contains(&t) {
                e.x.push(all.x[i]);
                e.y.push(all.y[i]);
                e.t.push(t);
            }
        }
        e
    };
    let mut voxeliser = Voxeliser::new(24, 20);
    let (mut union, mut s1, mut s2) = Default::default();
    voxeliser.run(&all, slab + tau, (slices + k) as u32, false, &mut union);
    voxeliser.run(&part(0), slab, slices as u32, false, &mut s1);
    voxeliser.run(&part(tau), slab, slices as u32, false, &mut s2);
    let (a, b): (&Voxels, &Voxels) = (&s1, &s2);
    let (ua, ub) = (union.sub_volume(0, slices), union.sub_volume(k, slices));
    assert_eq!(
        (ua.events(), ub.events()),
        (a.all().events(), b.all().events())
    );
    let plane = |a: SubVolume<'_>, b: SubVolume<'_>| {
        let mut stats = Vec::new();
        slice_statistics(a, b, shape, &mut stats);
        let (pw, ph) = (shape.plane_width(), shape.plane_height());
        let mut plane = vec![0.0; pw * ph];
        direct::correlate(
            a,
            b,
            &stats,
            shape,
            &Overlap::new(shape),
            &mut plane,
            &mut direct::Accumulators::new(shape),
        );
        (stats, plane)
    };
    assert_eq!(plane(ua, ub), plane(a.all(), b.all()));
}

#[test]
fn window_offsets_leave_at_most_half_a_pixel() {
    for &d in &[-7.6, -3.5, -0.4, 0.0, 0.5, 1.49, 2.5, 18.3, 17.7] {
        let s = window_offsets([d, -d]);
        for axis in 0..2 {
            let want = if axis == 0 { d } else { -d };
            let residual = want - (s[0][axis] + s[1][axis]) as f64;
            assert!(residual.abs() <= 0.5 + 1e-12, "{d}: {s:?}");
            assert!((s[0][axis] - s[1][axis]).abs() <= 1, "symmetric: {s:?}");
        }
    }
    assert_eq!(window_offsets([f64::NAN, 4.0]), [[0, 2], [0, 2]]);
}

/// The sub-pixel shift's split moves both windows by the same whole pixels and removes the
/// predicted displacement exactly: 2s + 2a = d with |a| ≤ ½ (ties of d/2 at k + ½ round away
/// from zero).
#[test]
fn symmetric_shift_removes_the_predicted_displacement() {
    for &d in &[
        -7.6, -3.0, -1.0, -0.4, 0.0, 0.5, 1.0, 1.49, 2.5, 3.0, 18.3, 17.7,
    ] {
        let (s, a) = symmetric_shift([d, -d]);
        for axis in 0..2 {
            let want = if axis == 0 { d } else { -d };
            assert_eq!(s[0][axis], s[1][axis], "{d}: {s:?}");
            assert!(a[axis].abs() <= 0.5, "{d}: {a:?}");
            let removed = 2.0 * (s[0][axis] as f64 + f64::from(a[axis]));
            assert!((removed - want).abs() < 1e-6, "{d}: {s:?} {a:?}");
        }
    }
    // Far beyond any sensor, clamped instead of overflowing.
    let (s, a) = symmetric_shift([1e300, -1e300]);
    assert_eq!(s, [[500_000, -500_000], [500_000, -500_000]]);
    assert_eq!(a, [0.0, 0.0]);
}

#[test]
fn parameters_validate_and_deserialise() {
    assert!(CorrSumParams::default().validate().is_ok());
    let bad = [
        CorrSumParams {
            tau_us: 0,
            ..Default::default()
        },
        CorrSumParams {
            slices: 0,
            ..Default::default()
        },
        CorrSumParams {
            slab_us: 10,
            slices: 20,
            tau_us: 5,
            ..Default::default()
        },
        CorrSumParams {
            tau_us: 20_000,
            ..Default::default()
        },
        CorrSumParams {
            tau_us: 400,
            ..Default::default()
        },
        CorrSumParams {
            slab_us: -5,
            ..Default::default()
        },
        CorrSumParams {
            search_radius_px: Some(0),
            ..Default::default()
        },
        CorrSumParams {
            peak_smoothing_px: -1.0,
            ..Default::default()
        },
        CorrSumParams {
            peak_smoothing_px: f64::NAN,
            ..Default::default()
        },
    ];
    for p in bad {
        assert!(p.validate().is_err(), "{p:?}");
        assert!(SumOfCorrelation::new(p).is_err());
    }
    let p: CorrSumParams =
        toml::from_str("tau_us = 2000\nkernel = \"direct\"\nweighting = \"count\"").unwrap();
    assert_eq!(p.tau_us, 2000);
    assert_eq!(p.kernel, CorrKernel::Direct);
    assert_eq!(p.weighting, Weighting::Count);
    assert_eq!(p.slab_us, 10_000);
    assert!(toml::from_str::<CorrSumParams>("taus = 1").is_err());
    let e = SumOfCorrelation::new(CorrSumParams {
        slab_us: 10_001,
        ..Default::default()
    })
    .unwrap();
    assert_eq!(e.time_extent_us(), (6501, 6501));
}

#[test]
fn tilted_peaks_with_a_negative_neighbour_are_fitted_in_two_dimensions() {
    // A narrow Gaussian elongated along (1, 1) at (5.3, 4.6); one corner pushed negative,
    // as beside real event-correlation peaks.
    let (w, h) = (11usize, 9usize);
    let mut plane: Vec<f64> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 - 5.3, (i / w) as f64 - 4.6);
            let (a, b) = ((x + y) / 2f64.sqrt(), (x - y) / 2f64.sqrt());
            (-a * a / 4.0 - b * b / 0.6).exp()
        })
        .collect();
    plane[3 * w + 6] = -0.01;
    let peak = find_peak(&plane, w, h, SubPixelFit::Gaussian2d, 2).unwrap();
    let [x, y] = refine_tilted(&plane, w, &peak, SubPixelFit::Gaussian2d);
    assert!((x - 5.3).abs() < 0.03 && (y - 4.6).abs() < 0.03, "{x} {y}");
    let axis_wise = ((peak.x - 5.3).powi(2) + (peak.y - 4.6).powi(2)).sqrt();
    assert!(
        axis_wise > 0.1,
        "the axis-wise fall-back is biased here: {peak:?}"
    );
}

/// Smoothing a Gaussian peak with a Gaussian keeps its centre: the smoothed fit finds
/// tilted and round peaks anywhere between pixels.
#[test]
fn smoothed_fit_keeps_the_centre_of_a_gaussian_peak() {
    let (w, h) = (15usize, 15usize);
    for (cx, cy, tilt) in [(6.3, 7.4, 0.0), (7.5, 6.05, 0.6), (8.85, 7.7, -0.4)] {
        let plane: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 - cx, (i / w) as f64 - cy);
                (-(x * x + y * y + 2.0 * tilt * x * y) / (2.0 * 0.8 * 0.8)).exp()
            })
            .collect();
        let peak = find_peak(&plane, w, h, SubPixelFit::Gaussian2d, 2).unwrap();
        for sigma in [0.7, 1.0, 1.5] {
            let [x, y] = refine_smoothed(&plane, [w, h], &peak, sigma, SubPixelFit::Gaussian2d);
            assert!(
                (x - cx).abs() < 0.01 && (y - cy).abs() < 0.01,
                "σ {sigma}: ({x}, {y}) vs ({cx}, {cy})"
            );
        }
    }
}

/// The fit's gradient predicts how the fitted position moves when plane values change:
/// for small changes of single cells and of a random pattern of cells, smoothed (σ 1 px) and
/// not, with the 2-D Gaussian and the three-point fits, within 2 % of the change measured
/// by fitting again (the peak's three-point fit included, which the refinement without
/// smoothing takes as it is).
#[test]
fn fit_gradient_predicts_the_shift_of_the_fit() {
    let (w, h) = (13usize, 13usize);
    let plane: Vec<f64> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 - 6.3, (i / w) as f64 - 5.8);
            0.05 + (-(x * x + y * y + 0.8 * x * y) / (2.0 * 1.1 * 1.1)).exp()
        })
        .collect();
    let mut next = crate::test_rng::xorshift(5);
    let mut uniform = || (next() >> 11) as f64 / (1u64 << 53) as f64;
    for fit in [SubPixelFit::Gaussian2d, SubPixelFit::Gaussian3] {
        let peak = find_peak(&plane, w, h, fit, 2).unwrap();
        for sigma in [0.0, 1.0] {
            let kernel = SmoothingKernel::new(sigma);
            let mut gradient = [Vec::new(), Vec::new()];
            fit_gradient(&plane, [w, h], &peak, &kernel, fit, &mut gradient);
            // The estimator's whole fit: the peak's three-point fit, then the refinement.
            let at = |p: &[f64]| {
                let peak = find_peak(p, w, h, fit, 2).unwrap();
                refine_smoothed(p, [w, h], &peak, sigma, fit)
            };
            let base = at(&plane);
            let mut changes: Vec<Vec<f64>> = [(6, 6), (5, 7), (7, 4)]
                .iter()
                .map(|&(r, c)| {
                    let mut d = vec![0.0; w * h];
                    d[r * w + c] = 1e-3;
                    d
                })
                .collect();
            changes.push((0..w * h).map(|_| 1e-3 * (uniform() - 0.5)).collect());
            for d in changes {
                let moved: Vec<f64> = plane.iter().zip(&d).map(|(p, d)| p + d).collect();
                let measured = at(&moved);
                for axis in 0..2 {
                    let predicted: f64 = gradient[axis].iter().zip(&d).map(|(g, d)| g * d).sum();
                    let shift = measured[axis] - base[axis];
                    assert!(
                        (predicted - shift).abs() <= 0.02 * shift.abs() + 1e-9,
                        "{fit:?} σ {sigma} axis {axis}: predicted {predicted}, measured {shift}"
                    );
                }
            }
        }
    }
}
