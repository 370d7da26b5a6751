use super::*;
use crate::field::{Calibration, Status, VectorField};

/// A one-field series on a 7 × 5 grid of step 8 px (origin 4, 4) holding `f(x, y)`.
fn series_of(f: impl Fn(f64, f64) -> (f64, f64)) -> FieldSeries {
    let x: Vec<f64> = (0..7).map(|i| 4.0 + 8.0 * i as f64).collect();
    let y: Vec<f64> = (0..5).map(|i| 4.0 + 8.0 * i as f64).collect();
    let mut field = VectorField::new(x.clone(), y.clone());
    for (r, &yy) in y.iter().enumerate() {
        for (c, &xx) in x.iter().enumerate() {
            let i = field.index(r, c);
            let (u, v) = f(xx, yy);
            field.u[i] = u as f32;
            field.v[i] = v as f32;
            field.status[i] = Status::VALID;
        }
    }
    let mut s = FieldSeries::on_grid(x, y);
    s.push(1000, &field).unwrap();
    s
}

fn values(s: &FieldSeries, q: DerivedQuantity) -> Vec<f32> {
    derive_series(s, &[q]).unwrap().remove(0).values
}

fn all_near(values: &[f32], expected: f64, tol: f64) -> bool {
    values.iter().all(|&v| (v as f64 - expected).abs() <= tol)
}

#[test]
fn solid_body_rotation_has_twice_its_rate_as_vorticity_and_no_strain() {
    let omega = 0.05; // 1/ms
    let (x0, y0) = (27.0, 19.0);
    let s = series_of(|x, y| (-omega * (y - y0), omega * (x - x0)));
    assert!(all_near(
        &values(&s, DerivedQuantity::Vorticity),
        2.0 * omega,
        1e-6
    ));
    assert!(all_near(
        &values(&s, DerivedQuantity::SwirlingStrength),
        omega,
        1e-6
    ));
    for q in [
        DerivedQuantity::Divergence,
        DerivedQuantity::StrainXx,
        DerivedQuantity::StrainYy,
        DerivedQuantity::StrainXy,
    ] {
        assert!(all_near(&values(&s, q), 0.0, 1e-6), "{q:?}");
    }
    // The other sense of rotation: negative vorticity, the same swirling strength.
    let back = series_of(|x, y| (omega * (y - y0), -omega * (x - x0)));
    assert!(all_near(
        &values(&back, DerivedQuantity::Vorticity),
        -2.0 * omega,
        1e-6
    ));
    assert!(all_near(
        &values(&back, DerivedQuantity::SwirlingStrength),
        omega,
        1e-6
    ));
}

#[test]
fn pure_shear_has_half_its_rate_as_e_xy_and_minus_it_as_vorticity() {
    let gamma = 0.02;
    let s = series_of(|_, y| (gamma * y, 0.0));
    assert!(all_near(
        &values(&s, DerivedQuantity::StrainXy),
        gamma / 2.0,
        1e-7
    ));
    assert!(all_near(
        &values(&s, DerivedQuantity::Vorticity),
        -gamma,
        1e-7
    ));
    assert!(all_near(
        &values(&s, DerivedQuantity::Divergence),
        0.0,
        1e-7
    ));
    // A shear has real (zero) eigenvalues: no swirl.
    assert!(all_near(
        &values(&s, DerivedQuantity::SwirlingStrength),
        0.0,
        0.0
    ));
}

#[test]
fn linear_stretching_has_divergence_and_normal_strains() {
    let (a, b) = (0.03, -0.01);
    let s = series_of(|x, y| (a * x, b * y));
    assert!(all_near(
        &values(&s, DerivedQuantity::Divergence),
        a + b,
        1e-7
    ));
    assert!(all_near(&values(&s, DerivedQuantity::StrainXx), a, 1e-7));
    assert!(all_near(&values(&s, DerivedQuantity::StrainYy), b, 1e-7));
    assert!(all_near(&values(&s, DerivedQuantity::Vorticity), 0.0, 1e-7));
}

#[test]
fn central_differences_inside_one_sided_at_the_edges() {
    // u = x²: central differences give 2x exactly inside, one-sided ones 2x ± step at
    // the edges.
    let s = series_of(|x, _| (x * x / 100.0, 0.0));
    let e = values(&s, DerivedQuantity::StrainXx);
    let x = &s.x;
    for c in 0..7 {
        let expected = match c {
            0 => (x[1] + x[0]) / 100.0,
            6 => (x[6] + x[5]) / 100.0,
            _ => 2.0 * x[c] / 100.0,
        };
        assert!(
            (e[c] as f64 - expected).abs() < 1e-5,
            "column {c}: {}",
            e[c]
        );
    }
}

#[test]
fn invalid_vectors_make_nan_or_one_sided_neighbours_never_zeros() {
    let omega = 0.05;
    let mut s = series_of(|x, y| (-omega * (y - 20.0), omega * (x - 28.0)));
    // Invalidate the node at row 2, column 3 as process does: NaN and a flag. A 0 in its
    // place would spoil the central differences of its neighbours.
    let i = s.index(0, 2, 3);
    s.u[i] = f32::NAN;
    s.v[i] = f32::NAN;
    s.status[i] = Status::MEDIAN_TEST;
    let w = values(&s, DerivedQuantity::Vorticity);
    assert!(w[i].is_nan(), "no value at an invalid node");
    // Its neighbours fall back to one-sided differences: still exact on a linear field.
    for k in [i - 1, i + 1, i - 7, i + 7] {
        assert!(
            (w[k] as f64 - 2.0 * omega).abs() < 1e-6,
            "node {k}: {}",
            w[k]
        );
    }
    // Also with a zero left in the arrays (a writer's fill value): the status decides.
    s.u[i] = 0.0;
    s.v[i] = 0.0;
    let w0 = values(&s, DerivedQuantity::Vorticity);
    assert!(w0[i].is_nan() && (w0[i - 1] as f64 - 2.0 * omega).abs() < 1e-6);
    // A node whose both neighbours along x are invalid has no ∂v/∂x: NaN.
    for k in [i - 2, i] {
        s.u[k] = f32::NAN;
        s.v[k] = f32::NAN;
        s.status[k] = Status::NO_EVENTS;
    }
    let w = values(&s, DerivedQuantity::Vorticity);
    assert!(w[i - 1].is_nan());
    assert!(values(&s, DerivedQuantity::StrainYy)[i - 1].is_finite());
}

#[test]
fn calibration_writes_per_second_and_flips_odd_quantities_with_y() {
    let omega = 0.05;
    let mut s = series_of(|x, y| (-omega * (y - 20.0), omega * (x - 28.0)));
    add_derived(&mut s, &DerivedQuantity::ALL).unwrap();
    let unit = |s: &FieldSeries| DerivedQuantity::unit(s.quantity, s.calibration.as_ref());
    assert_eq!(unit(&s), "1/ms");
    let vorticity = &s.derived[0];
    assert_eq!(DerivedQuantity::written(vorticity, &s), vorticity.values);
    s.calibration = Some(Calibration {
        mm_per_px: 0.02,
        origin_px: [0.0, 0.0],
        y_up: false,
    });
    assert_eq!(unit(&s), "1/s");
    // 0.1 per ms is 100 per s, whatever the scale in mm per px.
    let w = DerivedQuantity::written(vorticity, &s);
    assert!(all_near(&w, 2.0 * omega * 1000.0, 1e-3));
    s.calibration.as_mut().unwrap().y_up = true;
    let w = DerivedQuantity::written(vorticity, &s);
    assert!(all_near(&w, -2.0 * omega * 1000.0, 1e-3), "flipped with y");
    let swirl = &s.derived[5];
    assert!(all_near(
        &DerivedQuantity::written(swirl, &s),
        omega * 1000.0,
        1e-3
    ));
    assert!(
        s.push(2000, &s.field(0)).is_err(),
        "derived quantities cover the series"
    );
}

#[test]
fn quantity_lists_parse_and_name_the_choices() {
    assert_eq!(
        parse_quantities("divergence, vorticity,vorticity").unwrap(),
        vec![DerivedQuantity::Vorticity, DerivedQuantity::Divergence]
    );
    assert_eq!(parse_quantities("all").unwrap().len(), 6);
    assert_eq!(parse_quantities("strain").unwrap().len(), 3);
    let e = parse_quantities("curl").unwrap_err();
    assert!(e.contains("curl") && e.contains("swirling_strength"), "{e}");
    assert!(parse_quantities("").is_err());
}

#[test]
fn grids_of_one_node_and_empty_series_do_not_panic() {
    let mut f = VectorField::new(vec![0.0], vec![0.0]);
    f.u[0] = 1.0;
    f.v[0] = 1.0;
    f.status[0] = Status::VALID;
    let mut s = FieldSeries::on_grid(vec![0.0], vec![0.0]);
    s.push(0, &f).unwrap();
    assert!(values(&s, DerivedQuantity::Vorticity)[0].is_nan());
    let empty = FieldSeries::on_grid(vec![], vec![]);
    assert!(derive_series(&empty, &DerivedQuantity::ALL).is_ok());
}
