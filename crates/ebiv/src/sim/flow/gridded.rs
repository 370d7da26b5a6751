//! A user-supplied velocity field on a grid (CFD/DNS data, measured fields, ebiv's own truth
//! or results), interpolated bilinearly in space and linearly in time, as FED-PV and the
//! synthetic-PIV generators of Cai et al. do (sensor-model.md §5, "CFD/DNS"). Particle paths
//! are integrated with the adaptive Dormand–Prince scheme (sensor-model.md §6, "gridded").
//!
//! Files: CSV with the columns `t_us,x,y,u,v` or, as ebiv writes fields and truth,
//! `t_us,x_px,y_px,u_px_ms,v_px_ms` (rows in any order) and NetCDF classic files with `u`, `v` over (time, y, x) or (y, x) and
//! coordinate variables `x`, `y` and optionally `time` (see [`GriddedFlow::from_netcdf`]).

pub(crate) mod netcdf;

use super::Flow;
use crate::error::{Error, Result};
use std::collections::HashSet;
use std::path::Path;

/// A velocity field sampled on a rectilinear grid at one or more times.
///
/// Between grid nodes the velocity is bilinear in (x, y) and linear in t; outside the grid it
/// is clamped to the values on the nearest edge (in space and in time), so a particle leaving
/// the grid keeps the edge velocity. Axes are strictly increasing; their spacing may vary.
/// A NaN node value (e.g. inside a body) makes the velocity NaN in the cells around it, and a
/// particle that reaches them stops there (see [`crate::sim::ode`]).
#[derive(Clone, PartialEq)]
pub struct GriddedFlow {
    times_us: Vec<f64>,
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// u, px/ms, indexed `[t][y][x]`.
    u: Vec<f64>,
    /// v, px/ms, indexed `[t][y][x]`.
    v: Vec<f64>,
}

impl std::fmt::Debug for GriddedFlow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let range = |c: &[f64]| (c[0], c[c.len() - 1], c.len());
        f.debug_struct("GriddedFlow")
            .field("times_us (first, last, n)", &range(&self.times_us))
            .field("x (first, last, n)", &range(&self.xs))
            .field("y (first, last, n)", &range(&self.ys))
            .finish()
    }
}

/// Where `value` falls on the axis `c`: the two bracketing nodes and the weight of the second.
/// Clamped to the end nodes outside the axis; a NaN value gives a NaN weight.
fn bracket(c: &[f64], value: f64) -> (usize, usize, f64) {
    let n = c.len();
    if value.is_nan() {
        return (0, 0, f64::NAN);
    }
    if n == 1 || value <= c[0] {
        return (0, 0, 0.0);
    }
    if value >= c[n - 1] {
        return (n - 1, n - 1, 0.0);
    }
    let i = (c.partition_point(|&ci| ci <= value) - 1).min(n - 2);
    (i, i + 1, (value - c[i]) / (c[i + 1] - c[i]))
}

/// The axis named `key` must be non-empty, finite and strictly monotonic. Returns whether it
/// decreases.
fn check_axis(key: &str, c: &[f64]) -> std::result::Result<bool, (String, String)> {
    let fail = |m: String| Err((key.to_string(), m));
    if c.is_empty() {
        return fail("has no values".into());
    }
    if let Some(bad) = c.iter().find(|v| !v.is_finite()) {
        return fail(format!("has a non-finite value {bad}"));
    }
    let increasing = c.windows(2).all(|w| w[1] > w[0]);
    let decreasing = c.windows(2).all(|w| w[1] < w[0]);
    if !increasing && !decreasing {
        let up = c[1] > c[0];
        let i = c
            .windows(2)
            .position(|w| if up { w[1] <= w[0] } else { w[1] >= w[0] })
            .unwrap_or(0);
        return fail(format!(
            "must be strictly increasing or decreasing: {} at index {i} is followed by {}",
            c[i],
            c.get(i + 1).copied().unwrap_or(f64::NAN)
        ));
    }
    Ok(decreasing && c.len() > 1)
}

/// Reverse `axis` (0 = t, 1 = y, 2 = x) of data laid out `[t][y][x]` with sizes `dims`.
fn reverse_axis(data: &[f64], dims: [usize; 3], axis: usize) -> Vec<f64> {
    let [nt, ny, nx] = dims;
    let mut out = Vec::with_capacity(data.len());
    for it in 0..nt {
        for iy in 0..ny {
            for ix in 0..nx {
                let mut i = [it, iy, ix];
                i[axis] = dims[axis] - 1 - i[axis];
                out.push(data[(i[0] * ny + i[1]) * nx + i[2]]);
            }
        }
    }
    out
}

impl GriddedFlow {
    /// A field from its axes and values `u`, `v` (px/ms) indexed `[t][y][x]`, i.e. at
    /// `(it * ys.len() + iy) * xs.len() + ix`. Axes (µs, px) must be finite and strictly
    /// monotonic; decreasing axes (e.g. y stored bottom-up) are reversed together with the
    /// data. One time gives a steady field.
    pub fn new(
        times_us: Vec<f64>,
        xs: Vec<f64>,
        ys: Vec<f64>,
        u: Vec<f64>,
        v: Vec<f64>,
    ) -> Result<Self> {
        Self::build(times_us, xs, ys, u, v).map_err(|(key, message)| Error::parameter(key, message))
    }

    /// [`GriddedFlow::new`] with errors as (key, message).
    fn build(
        mut times_us: Vec<f64>,
        mut xs: Vec<f64>,
        mut ys: Vec<f64>,
        mut u: Vec<f64>,
        mut v: Vec<f64>,
    ) -> std::result::Result<Self, (String, String)> {
        let flips = [
            check_axis("time", &times_us)?,
            check_axis("y", &ys)?,
            check_axis("x", &xs)?,
        ];
        let dims = [times_us.len(), ys.len(), xs.len()];
        let n = dims[0]
            .checked_mul(dims[1])
            .and_then(|n| n.checked_mul(dims[2]));
        for (key, data) in [("u", &u), ("v", &v)] {
            if n != Some(data.len()) {
                return Err((
                    key.to_string(),
                    format!(
                        "has {} values; the grid has {} times × {} y × {} x",
                        data.len(),
                        dims[0],
                        dims[1],
                        dims[2]
                    ),
                ));
            }
        }
        for (axis, flip) in flips.into_iter().enumerate() {
            if flip {
                u = reverse_axis(&u, dims, axis);
                v = reverse_axis(&v, dims, axis);
                match axis {
                    0 => times_us.reverse(),
                    1 => ys.reverse(),
                    _ => xs.reverse(),
                }
            }
        }
        Ok(GriddedFlow {
            times_us,
            xs,
            ys,
            u,
            v,
        })
    }

    /// Load a field from `path`: NetCDF classic (recognised by its signature) or CSV.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let mut magic = [0u8; 4];
        {
            use std::io::Read;
            let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
            let mut got = 0;
            while got < magic.len() {
                match file.read(&mut magic[got..]) {
                    Ok(0) => break,
                    Ok(k) => got += k,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(Error::io(path, e)),
                }
            }
        }
        if magic.starts_with(b"CDF") {
            Self::from_netcdf(path)
        } else if magic == *b"\x89HDF" {
            Err(Error::unsupported(
                path.display().to_string(),
                "NetCDF-4/HDF5 files are not read; convert to NetCDF classic first \
                 (`nccopy -k classic in.nc out.nc`, \
                 or xarray `to_netcdf(format=\"NETCDF3_64BIT\")`)",
            ))
        } else {
            Self::from_csv(path)
        }
    }

    /// Load a field from a CSV file with the header `t_us,x,y,u,v` (see
    /// [`GriddedFlow::from_csv_str`]).
    pub fn from_csv(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::from_csv_str(&text, &path.display().to_string())
    }

    /// Parse CSV text: a header naming the columns `t_us`, `x`, `y`, `u`, `v` (or, with
    /// their units as ebiv's field and truth files name them, `x_px`, `y_px`, `u_px_ms`,
    /// `v_px_ms`; any order; other columns are ignored), then one row per grid point and time, in any order. Blank
    /// lines and lines starting with `#` are skipped. Every combination of the distinct
    /// `t_us`, `x` and `y` values must appear exactly once; `u`, `v` may be `NaN`. `context`
    /// (the file name) prefixes every error.
    pub fn from_csv_str(text: &str, context: &str) -> Result<Self> {
        const COLUMNS: [&str; 5] = ["t_us", "x", "y", "u", "v"];
        let parse_err = |line: usize, message: String| Error::Parse {
            context: context.to_string(),
            line: line as u64,
            message,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((header_line, header)) = lines.next() else {
            return Err(Error::unsupported(
                context,
                "empty file: expected a header `t_us,x,y,u,v`",
            ));
        };
        let names: Vec<&str> = header
            .split(',')
            .map(|s| s.trim().trim_matches('"'))
            .collect();
        // The same columns with their units, as ebiv's CSV writer names them.
        const WITH_UNITS: [&str; 5] = ["t_us", "x_px", "y_px", "u_px_ms", "v_px_ms"];
        let mut column = [0usize; 5];
        for ((slot, want), alias) in column.iter_mut().zip(COLUMNS).zip(WITH_UNITS) {
            *slot = names
                .iter()
                .position(|n| *n == want || *n == alias)
                .ok_or_else(|| {
                    parse_err(
                        header_line,
                        format!("the header has no column `{want}` (expected `t_us,x,y,u,v`)"),
                    )
                })?;
        }

        let mut rows: Vec<[f64; 5]> = Vec::new();
        let mut row_lines: Vec<usize> = Vec::new();
        for (line, text) in lines {
            let fields: Vec<&str> = text.split(',').collect();
            let mut row = [0.0; 5];
            for (k, (&c, name)) in column.iter().zip(COLUMNS).enumerate() {
                let field = fields.get(c).map(|s| s.trim()).ok_or_else(|| {
                    parse_err(
                        line,
                        format!("{} fields; column `{name}` is missing", fields.len()),
                    )
                })?;
                let value: f64 = field
                    .parse()
                    .map_err(|_| parse_err(line, format!("`{name}`: `{field}` is not a number")))?;
                if k < 3 && !value.is_finite() {
                    return Err(parse_err(
                        line,
                        format!("`{name}` must be finite, not {field}"),
                    ));
                }
                // `+ 0.0` turns −0 into +0 so both name the same grid line.
                row[k] = if k < 3 { value + 0.0 } else { value };
            }
            rows.push(row);
            row_lines.push(line);
        }
        if rows.is_empty() {
            return Err(Error::unsupported(context, "no data rows after the header"));
        }

        let axis = |k: usize| {
            let mut c: Vec<f64> = rows.iter().map(|r| r[k]).collect();
            c.sort_by(f64::total_cmp);
            c.dedup();
            c
        };
        let (times, xs, ys) = (axis(0), axis(1), axis(2));
        let (nt, ny, nx) = (times.len(), ys.len(), xs.len());
        let find = |c: &[f64], v: f64| c.binary_search_by(|p| p.total_cmp(&v)).unwrap_or(0);
        let node = |r: &[f64; 5]| (find(&times, r[0]), find(&ys, r[2]), find(&xs, r[1]));
        let n = nt.checked_mul(ny).and_then(|n| n.checked_mul(nx));
        if n.is_none_or(|n| n > rows.len()) {
            // Name the first missing grid point; one exists among the first rows + 1.
            let present: HashSet<(usize, usize, usize)> = rows.iter().map(node).collect();
            let missing = (0..nt)
                .flat_map(|it| (0..ny).flat_map(move |iy| (0..nx).map(move |ix| (it, iy, ix))))
                .find(|k| !present.contains(k))
                .unwrap_or((0, 0, 0));
            return Err(Error::unsupported(
                context,
                format!(
                    "the grid is incomplete: no row for t_us = {}, x = {}, y = {} \
                     ({nt} times × {ny} y × {nx} x values need {} rows, the file has {})",
                    times[missing.0],
                    xs[missing.2],
                    ys[missing.1],
                    n.map_or("too many".to_string(), |n| n.to_string()),
                    rows.len()
                ),
            ));
        }
        let n = n.unwrap_or(0);
        let mut u = vec![f64::NAN; n];
        let mut v = vec![f64::NAN; n];
        let mut first_line = vec![0usize; n];
        for (r, &line) in rows.iter().zip(&row_lines) {
            let (it, iy, ix) = node(r);
            let i = (it * ny + iy) * nx + ix;
            if first_line[i] != 0 {
                return Err(parse_err(
                    line,
                    format!(
                        "duplicate grid point t_us = {}, x = {}, y = {} (first on line {})",
                        r[0], r[1], r[2], first_line[i]
                    ),
                ));
            }
            first_line[i] = line;
            u[i] = r[3];
            v[i] = r[4];
        }
        Self::build(times, xs, ys, u, v)
            .map_err(|(key, m)| Error::unsupported(context, format!("`{key}` {m}")))
    }

    /// Times of the samples, µs.
    pub fn times_us(&self) -> &[f64] {
        &self.times_us
    }

    /// Grid columns, px.
    pub fn x(&self) -> &[f64] {
        &self.xs
    }

    /// Grid rows, px.
    pub fn y(&self) -> &[f64] {
        &self.ys
    }

    fn index(&self, it: usize, iy: usize, ix: usize) -> usize {
        (it * self.ys.len() + iy) * self.xs.len() + ix
    }
}

impl Flow for GriddedFlow {
    fn velocity(&self, x: f64, y: f64, t_us: f64) -> (f64, f64) {
        let (t0, t1, wt) = bracket(&self.times_us, t_us);
        let (y0, y1, wy) = bracket(&self.ys, y);
        let (x0, x1, wx) = bracket(&self.xs, x);
        let (mut u, mut v) = (0.0, 0.0);
        // Zero weights are skipped so that a NaN node only affects the cells around it.
        for (it, a) in [(t0, 1.0 - wt), (t1, wt)] {
            for (iy, b) in [(y0, 1.0 - wy), (y1, wy)] {
                for (ix, c) in [(x0, 1.0 - wx), (x1, wx)] {
                    let w = a * b * c;
                    if w != 0.0 {
                        let i = self.index(it, iy, ix);
                        u += w * self.u[i];
                        v += w * self.v[i];
                    }
                }
            }
        }
        (u, v)
    }

    /// The largest node speed of the cells that cover the rectangle, in the two samples that
    /// bracket `t_us` (all samples if `t_us` is NaN). Interpolated velocities are convex
    /// combinations of node velocities, so this bounds the speed. NaN nodes are ignored.
    fn max_speed(&self, w: f64, h: f64, t_us: f64) -> f64 {
        let (t0, t1) = match bracket(&self.times_us, t_us) {
            (_, _, wt) if wt.is_nan() => (0, self.times_us.len() - 1),
            (a, b, _) => (a, b),
        };
        let span = |c: &[f64], hi: f64| {
            let lo = bracket(c, 0.0_f64.min(hi)).0;
            let hi = bracket(c, 0.0_f64.max(hi)).1;
            (lo, hi)
        };
        let (y0, y1) = span(&self.ys, if h.is_nan() { 0.0 } else { h });
        let (x0, x1) = span(&self.xs, if w.is_nan() { 0.0 } else { w });
        let mut best = 0.0_f64;
        for it in t0..=t1 {
            for iy in y0..=y1 {
                for ix in x0..=x1 {
                    let i = self.index(it, iy, ix);
                    let s = self.u[i].hypot(self.v[i]);
                    if s.is_finite() {
                        best = best.max(s);
                    }
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests;
