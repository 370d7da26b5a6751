//! The predictor of a later pass: velocity and velocity gradient of the previous pass's field
//! at an arbitrary point.
//!
//! With smoothing, both come from one locally weighted linear regression (LOESS, Cleveland
//! 1979, J. Am. Stat. Assoc. 74:829): `u(x) ≈ u_c + ∇u·(x − c)` fitted by Gaussian-weighted
//! least squares to the nodes around `c` that carry a value. Unlike smoothing by normalised
//! convolution followed by bilinear interpolation and central differences, a local linear fit
//! reproduces a linear field exactly everywhere, including the last grid row and points
//! beyond the outermost nodes, where a clamped or one-sidedly averaged predictor is biased by
//! the gradient times the offset (the border artefacts of multi-pass PIV, algorithms.md §16.1;
//! on the role of predictor filtering: Schrijer & Scarano 2008, Exp. Fluids 45:927). In the
//! interior of a regular grid the fitted velocity equals the Gaussian-smoothed one.

use crate::estimate::{Deformation, Prediction};
use crate::field::VectorField;

/// The prediction of `field` at point `c` (image px) for a field at time `t0_us`.
///
/// `smoothing` is the standard deviation of the Gaussian weights in grid nodes: with
/// `smoothing > 0` velocity and gradient come from the local linear fit; with 0 (or where
/// the fit is degenerate, e.g. fewer than three non-collinear nodes) the velocity is the
/// bilinear interpolation of the field and the gradient a central difference over one grid
/// spacing. The gradient is only computed with `deform`.
pub(super) fn predict(
    field: &VectorField,
    c: [f64; 2],
    t0_us: i64,
    deform: bool,
    smoothing: f64,
) -> Option<Prediction> {
    let (velocity, gradient) = if smoothing > 0.0 {
        match local_linear(field, c, smoothing) {
            Some(fit) => (fit.0, Some(fit.1)),
            None => interpolated(field, c, deform)?,
        }
    } else {
        interpolated(field, c, deform)?
    };
    let deformation = gradient.filter(|_| deform).map(|gradient| Deformation {
        centre: c,
        velocity,
        gradient,
        t0_us,
    });
    Some(Prediction {
        velocity,
        deformation,
        search_radius: None,
    })
}

type Gradient = [[f64; 2]; 2];

/// Grid spacing of an axis (0 for a single node).
fn spacing(axis: &[f64]) -> f64 {
    axis.windows(2).map(|w| w[1] - w[0]).next().unwrap_or(0.0)
}

/// Bilinear velocity (clamped at the grid edge) and, with `deform`, the gradient by central
/// differences over one grid spacing.
fn interpolated(
    field: &VectorField,
    c: [f64; 2],
    deform: bool,
) -> Option<([f64; 2], Option<Gradient>)> {
    let velocity = field.sample(c[0], c[1])?;
    let (hx, hy) = (spacing(&field.x), spacing(&field.y));
    let gradient = (deform && hx > 0.0 && hy > 0.0).then(|| {
        let xp = field.sample(c[0] + hx, c[1])?;
        let xm = field.sample(c[0] - hx, c[1])?;
        let yp = field.sample(c[0], c[1] + hy)?;
        let ym = field.sample(c[0], c[1] - hy)?;
        // The predictor is clamped at the grid edge; difference over the true distance.
        let dx = (c[0] + hx).min(field.x[field.x.len() - 1]) - (c[0] - hx).max(field.x[0]);
        let dy = (c[1] + hy).min(field.y[field.y.len() - 1]) - (c[1] - hy).max(field.y[0]);
        (dx > 0.0 && dy > 0.0).then(|| {
            [
                [(xp[0] - xm[0]) / dx, (yp[0] - ym[0]) / dy],
                [(xp[1] - xm[1]) / dx, (yp[1] - ym[1]) / dy],
            ]
        })
    });
    Some((velocity, gradient.flatten()))
}

/// Gaussian-weighted linear least squares of `u` and `v` over the nodes within `2.5 σ` (at
/// least 1.5 nodes) of `c`, coordinates in grid nodes: `(value at c, gradient per px)`.
fn local_linear(field: &VectorField, c: [f64; 2], sigma: f64) -> Option<([f64; 2], Gradient)> {
    let (hx, hy) = (spacing(&field.x), spacing(&field.y));
    if !(hx > 0.0 && hy > 0.0 && sigma.is_finite()) {
        return None;
    }
    let reach = (2.5 * sigma).max(1.5);
    let range = |axis: &[f64], p: f64, h: f64| {
        let lo = axis.partition_point(|&a| a < p - reach * h);
        let hi = axis.partition_point(|&a| a <= p + reach * h);
        lo..hi
    };
    let k = 1.0 / (2.0 * sigma * sigma);
    // Normal equations of [1, ξ, η] with ξ, η the offsets in nodes.
    let mut m = [[0.0f64; 3]; 3];
    let mut ru = [0.0f64; 3];
    let mut rv = [0.0f64; 3];
    for row in range(&field.y, c[1], hy) {
        let eta = (field.y[row] - c[1]) / hy;
        for col in range(&field.x, c[0], hx) {
            let i = field.index(row, col);
            let (u, v) = (field.u[i], field.v[i]);
            if !(field.status[i].has_value() && u.is_finite() && v.is_finite()) {
                continue;
            }
            let xi = (field.x[col] - c[0]) / hx;
            let w = (-(xi * xi + eta * eta) * k).exp();
            let basis = [1.0, xi, eta];
            for a in 0..3 {
                for b in 0..3 {
                    m[a][b] += w * basis[a] * basis[b];
                }
                ru[a] += w * basis[a] * u as f64;
                rv[a] += w * basis[a] * v as f64;
            }
        }
    }
    let inverse = invert3(m)?;
    let solve = |r: [f64; 3]| {
        let mut s = [0.0; 3];
        for (a, out) in s.iter_mut().enumerate() {
            *out = (0..3).map(|b| inverse[a][b] * r[b]).sum();
        }
        s
    };
    let (su, sv) = (solve(ru), solve(rv));
    Some((
        [su[0], sv[0]],
        [[su[1] / hx, su[2] / hy], [sv[1] / hx, sv[2] / hy]],
    ))
}

/// Inverse of a symmetric 3 × 3 matrix, `None` if (nearly) singular: the nodes do not span
/// a plane.
fn invert3(m: [[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let cof =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let c = [
        [cof(1, 2, 1, 2), -cof(1, 2, 0, 2), cof(1, 2, 0, 1)],
        [-cof(0, 2, 1, 2), cof(0, 2, 0, 2), -cof(0, 2, 0, 1)],
        [cof(0, 1, 1, 2), -cof(0, 1, 0, 2), cof(0, 1, 0, 1)],
    ];
    let det = m[0][0] * c[0][0] + m[0][1] * c[0][1] + m[0][2] * c[0][2];
    let scale = m[0][0] * m[1][1] * m[2][2];
    if !(det.is_finite() && scale > 0.0 && det > 1e-9 * scale) {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for (r, row) in inv.iter_mut().enumerate() {
        for (col, x) in row.iter_mut().enumerate() {
            *x = c[col][r] / det;
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Status;

    /// A linear field `u = 1 + 0.02 x − 0.03 y`, `v = −2 + 0.01 x + 0.04 y` on a 7 × 5 grid.
    fn linear_field() -> VectorField {
        let x: Vec<f64> = (0..7).map(|i| 31.5 + 32.0 * i as f64).collect();
        let y: Vec<f64> = (0..5).map(|i| 31.5 + 32.0 * i as f64).collect();
        let mut f = VectorField::new(x.clone(), y.clone());
        for (r, &yy) in y.iter().enumerate() {
            for (c, &xx) in x.iter().enumerate() {
                let i = f.index(r, c);
                f.u[i] = (1.0 + 0.02 * xx - 0.03 * yy) as f32;
                f.v[i] = (-2.0 + 0.01 * xx + 0.04 * yy) as f32;
                f.status[i] = Status::VALID;
            }
        }
        f
    }

    #[test]
    fn local_linear_fit_is_exact_for_linear_fields_up_to_and_beyond_the_border() {
        let mut f = linear_field();
        // A gap does not matter either.
        let gap = f.index(2, 3);
        f.invalidate(gap, Status::MEDIAN_TEST);
        for c in [[15.5, 15.5], [100.0, 77.7], [239.5, 160.0], [240.0, 3.0]] {
            let p = predict(&f, c, 0, true, 1.0).unwrap();
            let u = 1.0 + 0.02 * c[0] - 0.03 * c[1];
            let v = -2.0 + 0.01 * c[0] + 0.04 * c[1];
            assert!((p.velocity[0] - u).abs() < 1e-5, "{c:?} {p:?}");
            assert!((p.velocity[1] - v).abs() < 1e-5, "{c:?} {p:?}");
            let g = p.deformation.unwrap().gradient;
            let expected = [[0.02, -0.03], [0.01, 0.04]];
            for a in 0..2 {
                for b in 0..2 {
                    assert!((g[a][b] - expected[a][b]).abs() < 1e-6, "{c:?} {g:?}");
                }
            }
        }
        // The bilinear, clamped predictor is biased outside the outermost nodes.
        let p = predict(&f, [15.5, 15.5], 0, true, 0.0).unwrap();
        assert!((p.velocity[0] - (1.0 + 0.02 * 15.5 - 0.03 * 15.5)).abs() > 0.1);
    }

    #[test]
    fn a_single_row_falls_back_to_interpolation() {
        let mut f = VectorField::new(vec![0.0, 10.0, 20.0], vec![5.0]);
        for i in 0..3 {
            f.u[i] = i as f32;
            f.v[i] = 0.0;
            f.status[i] = Status::VALID;
        }
        let p = predict(&f, [5.0, 5.0], 0, false, 1.0).unwrap();
        assert!((p.velocity[0] - 0.5).abs() < 1e-9);
        assert!(p.deformation.is_none());
    }
}
