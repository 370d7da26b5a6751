//! Small dense matrices of the local fits (at most [`MAX_TERMS`] unknowns), in index
//! notation as the formulas are written.
#![allow(clippy::needless_range_loop)]

/// Largest number of unknowns per axis: a cubic and the polarity term.
pub const MAX_TERMS: usize = 5;

/// A square matrix of the fits; only its first n × n are used.
pub type Matrix = [[f64; MAX_TERMS]; MAX_TERMS];

/// The inverse of the symmetric positive definite `m` (its first n × n), by Cholesky;
/// `None` when it is singular.
pub fn cholesky_inverse(m: &Matrix, n: usize) -> Option<Matrix> {
    let mut l = [[0.0; MAX_TERMS]; MAX_TERMS];
    for i in 0..n {
        for j in 0..=i {
            let mut sum = m[i][j];
            for k in 0..j {
                sum -= l[i][k] * l[j][k];
            }
            if i == j {
                if sum <= m[i][i] * 1e-12 || sum <= 0.0 {
                    return None;
                }
                l[i][i] = sum.sqrt();
            } else {
                l[i][j] = sum / l[j][j];
            }
        }
    }
    // Inverse of L, then M⁻¹ = L⁻ᵀ L⁻¹.
    let mut li = [[0.0; MAX_TERMS]; MAX_TERMS];
    for i in 0..n {
        li[i][i] = 1.0 / l[i][i];
        for j in 0..i {
            let mut sum = 0.0;
            for k in j..i {
                sum -= l[i][k] * li[k][j];
            }
            li[i][j] = sum / l[i][i];
        }
    }
    let mut inv = [[0.0; MAX_TERMS]; MAX_TERMS];
    for i in 0..n {
        for j in 0..n {
            let mut sum = 0.0;
            for k in i.max(j)..n {
                sum += li[k][i] * li[k][j];
            }
            inv[i][j] = sum;
        }
    }
    Some(inv)
}

pub fn mat_vec(m: &Matrix, v: &[f64; MAX_TERMS], n: usize) -> [f64; MAX_TERMS] {
    let mut out = [0.0; MAX_TERMS];
    for i in 0..n {
        for j in 0..n {
            out[i] += m[i][j] * v[j];
        }
    }
    out
}

/// `inv · m2 · inv` (n × n): the covariance of weighted least squares in sandwich form.
pub fn sandwich(inv: &Matrix, m2: &Matrix, n: usize) -> Matrix {
    let mut tmp = [[0.0; MAX_TERMS]; MAX_TERMS];
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                tmp[i][j] += inv[i][k] * m2[k][j];
            }
        }
    }
    let mut out = [[0.0; MAX_TERMS]; MAX_TERMS];
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                out[i][j] += tmp[i][k] * inv[k][j];
            }
        }
    }
    out
}

/// The dot product of the first `n` values.
pub fn dot(a: &[f64; MAX_TERMS], b: &[f64; MAX_TERMS], n: usize) -> f64 {
    a.iter().zip(b).take(n).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_of_a_symmetric_matrix_and_singular_ones() {
        let mut m = [[0.0; MAX_TERMS]; MAX_TERMS];
        let a = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = a[i][j];
            }
        }
        let inv = cholesky_inverse(&m, 3).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let p: f64 = (0..3).map(|k| m[i][k] * inv[k][j]).sum();
                assert!((p - f64::from(u8::from(i == j))).abs() < 1e-12);
            }
        }
        // Identity M2 gives the inverse itself as the sandwich of M.
        let s = sandwich(&inv, &m, 3);
        for i in 0..3 {
            for j in 0..3 {
                assert!((s[i][j] - inv[i][j]).abs() < 1e-12);
            }
        }
        m[2] = m[1];
        m[0][2] = m[0][1];
        m[1][2] = m[1][1];
        m[2][2] = m[1][1];
        assert!(cholesky_inverse(&m, 3).is_none());
    }
}
