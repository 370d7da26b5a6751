//! The velocity gradient at every node of one field by finite differences (see the parent
//! module for the scheme and its reference).

use crate::field::Status;

/// The velocity-gradient tensor at one node, image coordinates; NaN components where they
/// cannot be computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gradient {
    /// ∂u/∂x.
    pub du_dx: f64,
    /// ∂u/∂y.
    pub du_dy: f64,
    /// ∂v/∂x.
    pub dv_dx: f64,
    /// ∂v/∂y.
    pub dv_dy: f64,
}

impl Gradient {
    /// The imaginary part of the complex eigenvalues of the tensor, 0 when they are real
    /// (Zhou et al. 1999): with trace T and determinant D the eigenvalues are
    /// T/2 ± √(T²/4 − D), complex when D > T²/4, with imaginary part √(D − T²/4).
    pub fn swirling_strength(&self) -> f64 {
        let trace = self.du_dx + self.dv_dy;
        let det = self.du_dx * self.dv_dy - self.du_dy * self.dv_dx;
        let q = det - trace * trace / 4.0;
        if q.is_nan() {
            f64::NAN
        } else if q > 0.0 {
            q.sqrt()
        } else {
            0.0
        }
    }
}

/// The gradient of the field `u`, `v` (indexed `[row][column]`, with `status`) on the grid
/// `x`, `y` at every node. A node has a value when it is valid or replaced and finite.
pub fn gradients(x: &[f64], y: &[f64], u: &[f32], v: &[f32], status: &[Status]) -> Vec<Gradient> {
    let (nx, ny) = (x.len(), y.len());
    let has = |i: usize| status[i].has_value() && u[i].is_finite() && v[i].is_finite();
    let mut out = Vec::with_capacity(nx * ny);
    for r in 0..ny {
        for c in 0..nx {
            let i = r * nx + c;
            if !has(i) {
                out.push(Gradient {
                    du_dx: f64::NAN,
                    du_dy: f64::NAN,
                    dv_dx: f64::NAN,
                    dv_dy: f64::NAN,
                });
                continue;
            }
            let before_x = (c > 0 && has(i - 1)).then(|| i - 1);
            let after_x = (c + 1 < nx && has(i + 1)).then(|| i + 1);
            let before_y = (r > 0 && has(i - nx)).then(|| i - nx);
            let after_y = (r + 1 < ny && has(i + nx)).then(|| i + nx);
            let pos_x = |k: usize| x[k % nx];
            let pos_y = |k: usize| y[k / nx];
            let (du_dx, dv_dx) = difference(i, before_x, after_x, u, v, pos_x);
            let (du_dy, dv_dy) = difference(i, before_y, after_y, u, v, pos_y);
            out.push(Gradient {
                du_dx,
                du_dy,
                dv_dx,
                dv_dy,
            });
        }
    }
    out
}

/// ∂u/∂s and ∂v/∂s at node `i` along one axis, from its neighbours with a value `before`
/// and `after` at positions `pos`: central between both, one-sided with one, NaN without.
fn difference(
    i: usize,
    before: Option<usize>,
    after: Option<usize>,
    u: &[f32],
    v: &[f32],
    pos: impl Fn(usize) -> f64,
) -> (f64, f64) {
    let (a, b) = match (before, after) {
        (Some(a), Some(b)) => (a, b),
        (None, Some(b)) => (i, b),
        (Some(a), None) => (a, i),
        (None, None) => return (f64::NAN, f64::NAN),
    };
    let span = pos(b) - pos(a);
    if !(span.is_finite() && span != 0.0) {
        return (f64::NAN, f64::NAN);
    }
    (
        (u[b] as f64 - u[a] as f64) / span,
        (v[b] as f64 - v[a] as f64) / span,
    )
}
