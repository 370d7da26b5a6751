//! Vector fields on a regular grid, one per time step (`FieldSeries`).
//!
//! Image coordinates (x right, y down, pixel centres at integers), velocities in px/ms,
//! invalid vectors NaN. The layout is (time, y, x), as in every file ebiv writes.

/// A time series of 2-D vector fields on one regular grid.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldSeries {
    /// Grid column positions (window centres), px.
    pub x: Vec<f64>,
    /// Grid row positions, px.
    pub y: Vec<f64>,
    /// Time of each field, µs.
    pub t_us: Vec<i64>,
    /// x velocity, px/ms, indexed `[t][y][x]` (NaN where invalid).
    pub u: Vec<f32>,
    /// y velocity (positive down), px/ms, indexed `[t][y][x]`.
    pub v: Vec<f32>,
    /// Descriptive attributes written into every output (source, parameters, software).
    pub attributes: Vec<(String, String)>,
}

impl FieldSeries {
    /// An all-NaN series on the given grid and times.
    pub fn new(x: Vec<f64>, y: Vec<f64>, t_us: Vec<i64>) -> Self {
        let n = x.len() * y.len() * t_us.len();
        FieldSeries {
            x,
            y,
            t_us,
            u: vec![f32::NAN; n],
            v: vec![f32::NAN; n],
            attributes: Vec::new(),
        }
    }

    /// Flat index of `(t, row, column)`.
    #[inline]
    pub fn index(&self, t: usize, row: usize, col: usize) -> usize {
        (t * self.y.len() + row) * self.x.len() + col
    }

    /// Number of vectors in one field.
    pub fn field_len(&self) -> usize {
        self.x.len() * self.y.len()
    }

    /// Grid positions `start, start + step, …` up to `end` inclusive.
    pub fn axis(start: f64, end: f64, step: f64) -> Vec<f64> {
        let valid = step > 0.0 && end >= start && (end - start) / step < 1e7;
        if !valid {
            return vec![start];
        }
        let n = ((end - start) / step + 1e-9).floor() as usize + 1;
        (0..n).map(|i| start + i as f64 * step).collect()
    }
}
