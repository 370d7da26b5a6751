//! Scattered table rows (one vector per row, any order) placed on the regular grid they
//! span: the distinct x, y and times become the axes, nodes without a row stay invalid.

use crate::derived::DerivedField;
use crate::error::{Error, Result};
use crate::field::{FieldSeries, Status, TimeBasis};

/// The columns of a table, converted to image units, one entry per row.
#[derive(Debug, Default)]
pub(super) struct Rows {
    pub t: Vec<i64>,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub u: Vec<f32>,
    pub v: Vec<f32>,
    pub status: Vec<Status>,
    pub peak: Vec<f32>,
    pub peak_ratio: Vec<f32>,
    pub event_count: Vec<u32>,
    pub slab_us: Vec<u32>,
    pub u_unc: Vec<f32>,
    pub v_unc: Vec<f32>,
    /// Derived quantities, each with one value per row ([`crate::derived`]).
    pub derived: Vec<DerivedField>,
    /// 1-based line of each row, for errors.
    pub line: Vec<u64>,
}

/// Distinct values of `values`, ascending, merging values closer than 1e-6 of the range.
fn axis(values: &[f64]) -> Vec<f64> {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let span = sorted.last().unwrap_or(&0.0) - sorted.first().unwrap_or(&0.0);
    let tol = 1e-6 * span.abs().max(1.0);
    let mut out: Vec<f64> = Vec::new();
    for v in sorted {
        if out.last().is_none_or(|&l| v - l > tol) {
            out.push(v);
        }
    }
    out
}

fn find(axis: &[f64], v: f64) -> usize {
    let i = axis.partition_point(|&a| a < v);
    if i == axis.len() || (i > 0 && (v - axis[i - 1]).abs() < (axis[i] - v).abs()) {
        i - 1
    } else {
        i
    }
}

/// Place `rows` on their grid. `context` names the file in errors.
pub(super) fn assemble(rows: Rows, context: &str, basis: TimeBasis) -> Result<FieldSeries> {
    let n = rows.x.len();
    if n == 0 {
        return Err(Error::Empty {
            context: context.into(),
            message: "the table holds no vectors".into(),
        });
    }
    if let Some(i) = (0..n).find(|&i| !(rows.x[i].is_finite() && rows.y[i].is_finite())) {
        return Err(Error::Parse {
            context: context.into(),
            line: rows.line[i],
            message: "the position (x, y) is not a finite number".into(),
        });
    }
    let xs = axis(&rows.x);
    let ys = axis(&rows.y);
    let mut ts = rows.t.clone();
    ts.sort_unstable();
    ts.dedup();
    let nodes = xs.len() as u128 * ys.len() as u128 * ts.len() as u128;
    if nodes > 4 * n as u128 + 64 {
        return Err(Error::unsupported(
            context,
            format!(
                "the {n} vectors do not lie on a regular grid ({} distinct x, {} distinct y, \
                 {} times); only gridded fields are read",
                xs.len(),
                ys.len(),
                ts.len()
            ),
        ));
    }
    let mut s = FieldSeries::new(xs, ys, ts);
    s.time_basis = basis;
    let mut filled = vec![false; s.u.len()];
    let mut unc_u = vec![f32::NAN; s.u.len()];
    let mut unc_v = vec![f32::NAN; s.u.len()];
    let mut node = Vec::with_capacity(n);
    for r in 0..n {
        let ti = s.t_us.binary_search(&rows.t[r]).unwrap_or(0);
        let i = s.index(ti, find(&s.y, rows.y[r]), find(&s.x, rows.x[r]));
        node.push(i);
        if filled[i] {
            return Err(Error::Parse {
                context: context.into(),
                line: rows.line[r],
                message: format!(
                    "a second vector at x = {}, y = {}, t = {}",
                    rows.x[r], rows.y[r], rows.t[r]
                ),
            });
        }
        filled[i] = true;
        s.u[i] = rows.u[r];
        s.v[i] = rows.v[r];
        s.status[i] = rows.status[r];
        s.peak[i] = rows.peak[r];
        s.peak_ratio[i] = rows.peak_ratio[r];
        s.event_count[i] = rows.event_count[r];
        s.slab_us[i] = rows.slab_us[r];
        unc_u[i] = rows.u_unc[r];
        unc_v[i] = rows.v_unc[r];
    }
    set_uncertainty(&mut s, unc_u, unc_v);
    s.derived = rows
        .derived
        .iter()
        .map(|d| DerivedField {
            quantity: d.quantity,
            values: vec![f32::NAN; s.u.len()],
        })
        .collect();
    for (r, &i) in node.iter().enumerate() {
        for (to, from) in s.derived.iter_mut().zip(&rows.derived) {
            to.values[i] = from.values[r];
        }
    }
    Ok(s)
}

/// Attach per-vector standard uncertainties to `series`.
pub(super) fn set_uncertainty(series: &mut FieldSeries, u_unc: Vec<f32>, v_unc: Vec<f32>) {
    series.u_unc = u_unc;
    series.v_unc = v_unc;
}
