//! Hand-computed cases of [`assess`] and [`compare`].

use super::*;
use crate::field::{FieldSeries, Quantity, Status, TimeBasis};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-6
}

/// Two nodes, two fields; errors (0.125, 0), (−0.125, 0.25), (0, −0.25) against a truth of
/// (1, 0); the fourth vector invalid. Slabs of 10 ms; 100, 200, 300 events.
fn known_series() -> FieldSeries {
    let mut s = FieldSeries::new(vec![0.0, 10.0], vec![0.0], vec![0, 1000]);
    let values = [(1.125, 0.0), (0.875, 0.25), (1.0, -0.25)];
    for (i, &(u, v)) in values.iter().enumerate() {
        s.u[i] = u;
        s.v[i] = v;
        s.status[i] = Status::VALID;
        s.slab_us[i] = 10_000;
        s.event_count[i] = 100 * (i as u32 + 1);
    }
    s
}

#[test]
fn assessment_of_a_known_series() {
    let options = AssessOptions {
        outlier_floor: 0.2,
        fraction_bins: 2,
        event_bins: 3,
        speed_bins: 2,
        ..AssessOptions::default()
    };
    let a = assess(&known_series(), &|_, _, _| (1.0, 0.0), &options);
    assert_eq!(
        (a.total, a.valid, a.compared, a.without_truth),
        (4, 3, 3, 0)
    );
    assert_eq!(a.unit, "px/ms");
    assert!(close(a.valid_share, 0.75));
    assert!(close(a.bias[0], 0.0) && close(a.bias[1], 0.0));
    assert!(close(a.random[0], (2.0 * 0.015625 / 3.0f64).sqrt()));
    assert!(close(a.random[1], (2.0 * 0.0625 / 3.0f64).sqrt()));
    let rms = (0.15625 / 3.0f64).sqrt();
    assert!(close(a.rms, rms));
    let epe2 = 0.078125f64.sqrt();
    assert!(close(a.aee, (0.125 + epe2 + 0.25) / 3.0));
    assert!(close(a.median, 0.25) && close(a.max, epe2));
    // Threshold max(0.5 px / 10 ms, 0.2) = 0.2 px/ms: two outliers.
    assert_eq!(a.outliers, 2);
    assert!(close(a.outlier_share, 2.0 / 3.0));
    assert!(close(a.rms_without_outliers, 0.125));
    assert!(close(a.outlier_threshold[0], 0.2) && close(a.outlier_threshold[1], 0.2));
    assert!(close(a.max_true_speed, 1.0) && close(a.dvr, 1.0 / rms));
    assert_eq!(a.error_map.count, vec![2, 1]);
    assert!(close(a.error_map.mean_error[0], 0.1875));
    assert!(close(a.error_map.mean_error[1], epe2));
    assert_eq!(a.by_events.len(), 3);
    assert_eq!(
        a.by_events.iter().map(|b| b.count).collect::<Vec<_>>(),
        vec![1, 1, 1]
    );
    assert!(close(a.by_events[2].aee, 0.25));
    // Every true speed is 1: one full bin and one empty.
    assert_eq!(a.by_speed[1].count, 3);
    // Displacements u·T, v·T: fractional parts 0.25, 0, −0.25, 0.5 → −0.5, 0, −0.5.
    assert_eq!(a.fractional.counts, vec![3, 3]);
    assert_eq!(a.fractional.samples, 6);
    assert_eq!(a.fractional.peak_locking_index, 0.0);
    // Without uncertainties every component is left out of the coverage.
    assert_eq!(a.coverage.samples + a.coverage.without_uncertainty, 6);
    assert_eq!(a.coverage.samples, 0);
}

#[test]
fn coverage_of_known_uncertainties() {
    // Errors (0.125, 0), (−0.125, 0.25), (0, −0.25); σ = 0.2 for u, 0.2 and NaN for v.
    let mut s = known_series();
    s.u_unc[..3].fill(0.2);
    s.v_unc[..3].copy_from_slice(&[0.2, 0.2, f32::NAN]);
    let a = assess(&s, &|_, _, _| (1.0, 0.0), &AssessOptions::default());
    let c = &a.coverage;
    // e/σ: 0.625, 0, −0.625 (u); 0, 1.25 (v); one v left out.
    assert_eq!((c.samples, c.without_uncertainty), (5, 1));
    assert!(close(c.within_1_sigma, 0.8) && close(c.within_2_sigma, 1.0));
    let rms = ((2.0 * 0.390625 + 1.5625) / 5.0f64).sqrt();
    assert!(close(c.rms_normalised, rms), "{}", c.rms_normalised);
    // All σ equal: no rank correlation.
    assert!(c.spearman.is_nan());
}

#[test]
fn outlier_thresholds_follow_the_slab() {
    let o = AssessOptions::default();
    assert!(close(o.outlier_threshold(2000, false), 0.25));
    assert!(close(o.outlier_threshold(20_000, false), 0.1));
    assert!(close(o.outlier_threshold(0, false), 0.1));
    assert!(close(o.outlier_threshold(0, true), 0.5));
    let fixed = AssessOptions {
        outlier_fixed: Some(0.3),
        ..o.clone()
    };
    assert!(close(fixed.outlier_threshold(2000, false), 0.3));
    assert!(AssessOptions {
        fraction_bins: 0,
        ..o.clone()
    }
    .validate()
    .is_err());
    assert!(AssessOptions {
        outlier_px: f64::NAN,
        ..o
    }
    .validate()
    .is_err());
}

#[test]
fn unknown_truth_and_empty_series_give_counts_not_panics() {
    let s = known_series();
    let a = assess(
        &s,
        &|x, _, _| if x > 5.0 { (f64::NAN, 0.0) } else { (1.0, 0.0) },
        &AssessOptions::default(),
    );
    assert_eq!((a.compared, a.without_truth), (2, 1));
    let empty = FieldSeries::new(vec![], vec![], vec![]);
    let a = assess(&empty, &|_, _, _| (0.0, 0.0), &AssessOptions::default());
    assert_eq!(a.compared, 0);
    assert!(a.rms.is_nan() && a.dvr.is_nan() && a.valid_share.is_nan());
    let json = report::assessment_json(&a, &Default::default());
    assert!(json.contains("\"rms\": null"), "{json}");
}

#[test]
fn displacement_fields_are_their_own_displacements() {
    let mut s = known_series();
    s.quantity = Quantity::Displacement;
    s.slab_us = vec![0; 4];
    let a = assess(&s, &|_, _, _| (1.0, 0.0), &AssessOptions::default());
    assert_eq!(a.unit, "px");
    assert_eq!(a.fractional.samples, 6);
    assert_eq!(a.fractional.without_slab, 0);
    // 0.5 px threshold: no outliers.
    assert_eq!(a.outliers, 0);
    let mut s = known_series();
    s.slab_us = vec![0; 4];
    let a = assess(&s, &|_, _, _| (1.0, 0.0), &AssessOptions::default());
    assert_eq!((a.fractional.samples, a.fractional.without_slab), (0, 3));
}

fn one_field(x: Vec<f64>, u: &[f32]) -> FieldSeries {
    let mut s = FieldSeries::new(x, vec![0.0], vec![0]);
    for (i, &u) in u.iter().enumerate() {
        s.u[i] = u;
        s.v[i] = 0.0;
        s.status[i] = Status::VALID;
    }
    s
}

#[test]
fn comparison_on_one_grid() {
    let a = one_field(vec![0.0, 10.0], &[1.0, 2.0]);
    let b = one_field(vec![0.0, 10.0], &[1.5, 2.0]);
    let options = CompareOptions {
        threshold: 0.4,
        ..CompareOptions::default()
    };
    let g = compare(&a, &b, &options).unwrap();
    assert_eq!((g.compared, g.a_valid, g.without_b), (2, 2, 0));
    assert!(!g.interpolated);
    assert!(close(g.median_difference, 0.25));
    assert!(close(g.beyond_share, 0.5));
    assert!(close(g.mean_component_difference[0], -0.25));
    assert!(close(g.mean_component_difference[1], 0.0));
    assert!(close(g.sd_component_difference[0], 0.25));
    assert!(close(g.rms_difference, 0.125f64.sqrt()));
    assert_eq!(g.scatter, vec![[1.0, 0.0, 1.5, 0.0], [2.0, 0.0, 2.0, 0.0]]);
    let csv = report::agreement_csv(&g);
    assert!(
        csv.contains("agreement,median_difference,,,,2,0.25,px/ms"),
        "{csv}"
    );
}

#[test]
fn comparison_interpolates_b_and_skips_nodes_outside_it() {
    let a = one_field(vec![0.0, 10.0, 30.0], &[1.0, 2.0, 9.0]);
    let mut b = one_field(vec![0.0, 20.0], &[1.0, 3.0]);
    let g = compare(&a, &b, &CompareOptions::default()).unwrap();
    assert!(g.interpolated);
    assert_eq!((g.compared, g.without_b), (2, 1));
    assert!(close(g.median_difference, 0.0));
    // A replaced vector of b is not used.
    b.status[1] = Status::MEDIAN_TEST | Status::REPLACED;
    let g = compare(&a, &b, &CompareOptions::default()).unwrap();
    assert_eq!(g.compared, 2);
    assert!(close(g.median_difference, 0.5), "{}", g.median_difference);
}

#[test]
fn comparison_matches_times_and_refuses_unlike_quantities() {
    let mut a = FieldSeries::new(vec![0.0], vec![0.0], vec![0, 1000, 2000]);
    let mut b = FieldSeries::new(vec![0.0], vec![0.0], vec![10, 1990]);
    for s in [&mut a, &mut b] {
        s.u.iter_mut().for_each(|u| *u = 1.0);
        s.v.iter_mut().for_each(|v| *v = 0.0);
        s.status.iter_mut().for_each(|st| *st = Status::VALID);
    }
    let g = compare(&a, &b, &CompareOptions::default()).unwrap();
    assert_eq!(
        g.pairs,
        vec![MatchedPair { a: 0, b: 0 }, MatchedPair { a: 2, b: 1 }]
    );
    assert_eq!(g.unmatched_fields, 1);
    // Image pairs: matched by index.
    let mut c = b.clone();
    c.t_us = vec![0, 1];
    c.time_basis = TimeBasis::PairIndex;
    let g = compare(&c, &b, &CompareOptions::default()).unwrap();
    assert_eq!(g.pairs.len(), 2);
    c.quantity = Quantity::Displacement;
    let e = compare(&c, &b, &CompareOptions::default()).unwrap_err();
    assert!(e.to_string().contains("displacements"), "{e}");
}

#[test]
fn reports_name_every_figure_and_number() {
    let a = assess(
        &known_series(),
        &|_, _, _| (1.0, 0.0),
        &AssessOptions::default(),
    );
    let context = report::ReportContext {
        field: "f.nc".into(),
        reference: "truth.nc".into(),
    };
    let md = report::assessment_markdown(&a, &context);
    for name in [
        report::figures::ERROR_MAP,
        report::figures::ERROR_VS_SPEED,
        report::figures::ERROR_VS_EVENTS,
        report::figures::FRACTIONAL,
    ] {
        assert!(md.contains(name), "{name}");
    }
    assert!(md.contains("Christensen"));
    let csv = report::assessment_csv(&a);
    assert!(csv.starts_with(report::CSV_HEADER));
    assert!(csv.contains("summary,valid,,,,,3,1"), "{csv}");
    assert!(csv.contains("error_map,aee,,0,0,2,0.1875,px/ms"), "{csv}");
    let json: serde_json::Value =
        serde_json::from_str(&report::assessment_json(&a, &context)).unwrap();
    assert_eq!(json["assessment"]["compared"], 3);
    let summary = report::assessment_summary(&a);
    assert!(summary.contains("3 valid of 4"), "{summary}");
}
