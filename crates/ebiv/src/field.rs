//! Vector fields on a regular grid: one field ([`VectorField`]) and a time series of them
//! ([`FieldSeries`]), with per-vector [`Status`] flags, per-vector standard uncertainties and
//! an optional [`Calibration`].
//!
//! Image coordinates (x right, y down, pixel centres at integers), velocities in px/ms,
//! invalid vectors NaN with a status saying why; never a zero vector for missing data.
//! The layout is (time, y, x), as in every file ebiv writes.

/// Why a vector is not a plain valid measurement: a bit set; `0` means valid.
///
/// A vector with any of the `INVALID` bits has NaN velocity; a replaced vector keeps the bit
/// of the test that rejected it and gains [`Status::REPLACED`], with the interpolated value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Status(pub u8);

impl Status {
    /// A valid measurement.
    pub const VALID: Status = Status(0);
    /// The window held no events (or too few to estimate anything).
    pub const NO_EVENTS: Status = Status(1);
    /// Fewer events than the configured minimum, or (sum of correlation) too few coincident
    /// voxel pairs behind the correlation peak to call it a measurement.
    pub const FEW_EVENTS: Status = Status(2);
    /// Correlation peak ratio (first/second peak) below the configured minimum, or a peak that
    /// does not stand clear of its objective: two comparable maxima (motion compensation), a
    /// peak of little contrast over its plane or missing from the plane of one half of the
    /// slices (sum of correlation).
    pub const LOW_PEAK_RATIO: Status = Status(4);
    /// Rejected by the normalized median test (Westerweel & Scarano 2005).
    pub const MEDIAN_TEST: Status = Status(8);
    /// The objective's peak lies on the edge of the search range (motion compensation) or of
    /// the correlation plane: the true value is probably outside.
    pub const OUT_OF_RANGE: Status = Status(16);
    /// No usable peak (flat objective, failed fit).
    pub const NO_PEAK: Status = Status(32);
    /// The vector was replaced by interpolation from its valid neighbours.
    pub const REPLACED: Status = Status(64);
    /// The window centre lies in the user's mask.
    pub const MASKED: Status = Status(128);

    /// Names of the flags, in bit order, as written into file metadata.
    pub const NAMES: [(&'static str, Status); 8] = [
        ("no_events", Status::NO_EVENTS),
        ("few_events", Status::FEW_EVENTS),
        ("low_peak_ratio", Status::LOW_PEAK_RATIO),
        ("median_test", Status::MEDIAN_TEST),
        ("out_of_range", Status::OUT_OF_RANGE),
        ("no_peak", Status::NO_PEAK),
        ("replaced", Status::REPLACED),
        ("masked", Status::MASKED),
    ];

    /// True if no flag is set.
    pub fn is_valid(self) -> bool {
        self.0 == 0
    }

    /// True if every flag of `other` is set in `self`.
    pub fn contains(self, other: Status) -> bool {
        self.0 & other.0 == other.0
    }

    /// True if any flag of `other` is set in `self`.
    pub fn intersects(self, other: Status) -> bool {
        self.0 & other.0 != 0
    }

    /// True if the vector carries a value: valid, or replaced.
    pub fn has_value(self) -> bool {
        self.0 == 0 || self.contains(Status::REPLACED)
    }

    /// `self` with the flags of `other` added.
    pub fn with(self, other: Status) -> Status {
        Status(self.0 | other.0)
    }

    /// One line describing the flags, for file metadata: `1 no_events, 2 few_events, …`.
    pub fn legend() -> String {
        Status::NAMES
            .iter()
            .map(|(name, s)| format!("{} {name}", s.0))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl std::ops::BitOr for Status {
    type Output = Status;
    fn bitor(self, rhs: Status) -> Status {
        self.with(rhs)
    }
}

/// Physical scaling of a field: positions in mm and velocities in m/s.
///
/// With `mm_per_px` millimetres per pixel, 1 px/ms is `mm_per_px` mm/ms, i.e. `mm_per_px`
/// m/s. `origin_px` is the image point that becomes (0, 0) mm. With `y_up` the physical y
/// axis points up: positions and the v component both change sign, never only one of them.
/// An uncertainty is a spread, not a direction: it converts by the scale only and never
/// changes sign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Millimetres per pixel.
    pub mm_per_px: f64,
    /// Image position (x, y) in px of the physical origin.
    pub origin_px: [f64; 2],
    /// Physical y axis points up (image y points down).
    pub y_up: bool,
}

impl Calibration {
    /// Check that the scale is finite and positive.
    pub fn validate(&self) -> crate::Result<()> {
        if !(self.mm_per_px.is_finite() && self.mm_per_px > 0.0) {
            return Err(crate::Error::parameter(
                "mm-per-px",
                format!("must be a positive number, got {}", self.mm_per_px),
            ));
        }
        if !self.origin_px.iter().all(|c| c.is_finite()) {
            return Err(crate::Error::parameter("origin", "must be finite"));
        }
        Ok(())
    }

    /// Physical x position (mm) of image column `x` (px).
    pub fn x_mm(&self, x: f64) -> f64 {
        (x - self.origin_px[0]) * self.mm_per_px
    }

    /// Physical y position (mm) of image row `y` (px), flipped when `y_up`.
    pub fn y_mm(&self, y: f64) -> f64 {
        let d = (y - self.origin_px[1]) * self.mm_per_px;
        if self.y_up {
            -d
        } else {
            d
        }
    }

    /// Physical velocity (m/s) of an image velocity (px/ms), v flipped when `y_up`.
    pub fn velocity_m_per_s(&self, u: f32, v: f32) -> (f32, f32) {
        let s = self.mm_per_px as f32;
        let v = v * s;
        (u * s, if self.y_up { -v } else { v })
    }

    /// Physical standard uncertainty (m/s) of an image velocity's uncertainty (px/ms):
    /// scaled by `mm_per_px`, never flipped (`y_up` changes the sign of v, not its spread).
    /// The same scale converts an uncertainty of a displacement from px to mm.
    pub fn uncertainty_m_per_s(&self, u_unc: f32, v_unc: f32) -> (f32, f32) {
        let s = self.mm_per_px as f32;
        (u_unc * s, v_unc * s)
    }
}

/// One vector field on a regular grid, arrays indexed `[row][column]`.
#[derive(Debug, Clone, PartialEq)]
pub struct VectorField {
    /// Grid column positions (window centres), px.
    pub x: Vec<f64>,
    /// Grid row positions, px.
    pub y: Vec<f64>,
    /// x velocity, px/ms (NaN where invalid).
    pub u: Vec<f32>,
    /// y velocity (positive down), px/ms.
    pub v: Vec<f32>,
    /// Standard uncertainty (one standard deviation) of `u`, in the unit of `u`; NaN where
    /// unknown, and for invalid and replaced vectors.
    pub u_unc: Vec<f32>,
    /// Standard uncertainty (one standard deviation) of `v`, in the unit of `v`; NaN where
    /// unknown, and for invalid and replaced vectors.
    pub v_unc: Vec<f32>,
    /// Status flags (bits of [`Status`]).
    pub status: Vec<Status>,
    /// Peak value of the correlation plane or objective.
    pub peak: Vec<f32>,
    /// Ratio of the highest to the second-highest peak (NaN where not defined); for a vector
    /// re-evaluated on a lower peak by multiple-peak validation, that peak's height over the
    /// highest other peak (below 1 where a higher one lies elsewhere).
    pub peak_ratio: Vec<f32>,
    /// Events used by the estimator in the window.
    pub event_count: Vec<u32>,
    /// Length of the time slab the vector was measured over, µs; 0 where there is none (see
    /// [`FieldSeries::slab_us`]).
    pub slab_us: Vec<u32>,
}

impl VectorField {
    /// An all-NaN field flagged [`Status::NO_EVENTS`] on the given grid.
    pub fn new(x: Vec<f64>, y: Vec<f64>) -> Self {
        let n = x.len() * y.len();
        VectorField {
            x,
            y,
            u: vec![f32::NAN; n],
            v: vec![f32::NAN; n],
            u_unc: vec![f32::NAN; n],
            v_unc: vec![f32::NAN; n],
            status: vec![Status::NO_EVENTS; n],
            peak: vec![f32::NAN; n],
            peak_ratio: vec![f32::NAN; n],
            event_count: vec![0; n],
            slab_us: vec![0; n],
        }
    }

    /// Record `slab_us` as the time span every evaluated vector was measured over, for
    /// methods whose slab is one per field (PIV: the span of the field's frames); masked
    /// windows, which are not evaluated, keep 0.
    pub fn set_slab_us(&mut self, slab_us: u32) {
        for (s, status) in self.slab_us.iter_mut().zip(&self.status) {
            *s = if status.contains(Status::MASKED) {
                0
            } else {
                slab_us
            };
        }
    }

    /// Multiply every vector by `factor` (e.g. displacements in px by 1/Δt in ms to get
    /// px/ms) and its uncertainty by |`factor`|; NaN stays NaN.
    pub fn scale(&mut self, factor: f64) {
        for w in self.u.iter_mut().chain(self.v.iter_mut()) {
            *w = (*w as f64 * factor) as f32;
        }
        for w in self.u_unc.iter_mut().chain(self.v_unc.iter_mut()) {
            *w = (*w as f64 * factor.abs()) as f32;
        }
    }

    /// Number of columns.
    pub fn width(&self) -> usize {
        self.x.len()
    }

    /// Number of rows.
    pub fn height(&self) -> usize {
        self.y.len()
    }

    /// Flat index of `(row, column)`.
    #[inline]
    pub fn index(&self, row: usize, col: usize) -> usize {
        row * self.x.len() + col
    }

    /// Number of vectors.
    pub fn len(&self) -> usize {
        self.u.len()
    }

    /// True for a field without vectors.
    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }

    /// Mark vector `i` invalid for `reason`: NaN velocity and uncertainty, flag added.
    pub fn invalidate(&mut self, i: usize, reason: Status) {
        self.u[i] = f32::NAN;
        self.v[i] = f32::NAN;
        self.u_unc[i] = f32::NAN;
        self.v_unc[i] = f32::NAN;
        self.status[i] = self.status[i].with(reason);
    }

    /// Share of vectors that are valid measurements (status 0).
    pub fn valid_share(&self) -> f64 {
        if self.status.is_empty() {
            return 0.0;
        }
        let valid = self.status.iter().filter(|s| s.is_valid()).count();
        valid as f64 / self.status.len() as f64
    }

    /// Velocity at an arbitrary image point (px) by bilinear interpolation between the grid
    /// nodes that carry a value (valid or replaced), clamped to the grid's extent. Nodes
    /// without a value are left out and the weights renormalised; `None` if none of the four
    /// surrounding nodes has a value.
    pub fn sample(&self, px: f64, py: f64) -> Option<[f64; 2]> {
        if self.x.is_empty() || self.y.is_empty() {
            return None;
        }
        let (c0, c1, fx) = bracket(&self.x, px);
        let (r0, r1, fy) = bracket(&self.y, py);
        let mut sum = [0.0f64; 2];
        let mut weight = 0.0f64;
        for (r, wy) in [(r0, 1.0 - fy), (r1, fy)] {
            for (c, wx) in [(c0, 1.0 - fx), (c1, fx)] {
                let w = wx * wy;
                let i = self.index(r, c);
                if w > 0.0 && self.status[i].has_value() && self.u[i].is_finite() {
                    sum[0] += w * self.u[i] as f64;
                    sum[1] += w * self.v[i] as f64;
                    weight += w;
                }
            }
        }
        (weight > 1e-12).then(|| [sum[0] / weight, sum[1] / weight])
    }
}

/// Indices of the two axis nodes around `p` and the fractional position between them,
/// clamped at the ends of the (ascending) axis.
pub(crate) fn bracket(axis: &[f64], p: f64) -> (usize, usize, f64) {
    let last = axis.len() - 1;
    if last == 0 || p <= axis[0] {
        return (0, 0, 0.0);
    }
    if p >= axis[last] {
        return (last, last, 0.0);
    }
    let hi = axis.partition_point(|&a| a <= p).min(last);
    let lo = hi - 1;
    let span = axis[hi] - axis[lo];
    let f = if span > 0.0 {
        (p - axis[lo]) / span
    } else {
        0.0
    };
    (lo, hi, f)
}

/// What the `u`, `v` arrays of a [`FieldSeries`] hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Quantity {
    /// Velocity: px/ms in image coordinates, m/s when calibrated.
    #[default]
    Velocity,
    /// Displacement between two images: px, mm when calibrated (PIV of an image pair, where
    /// the time between the frames is not known).
    Displacement,
}

impl Quantity {
    /// Unit of `u`, `v` in image coordinates and after calibration.
    pub fn units(self) -> (&'static str, &'static str) {
        match self {
            Quantity::Velocity => ("px/ms", "m/s"),
            Quantity::Displacement => ("px", "mm"),
        }
    }

    /// Plural noun for text: "velocities" or "displacements".
    pub fn noun(self) -> &'static str {
        match self {
            Quantity::Velocity => "velocities",
            Quantity::Displacement => "displacements",
        }
    }
}

/// What the times `t_us` of a [`FieldSeries`] stand for; the writers describe the time axis
/// from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeBasis {
    /// The centre of the time slab of events each field is measured from, µs of camera time
    /// (event estimators).
    #[default]
    SlabCentre,
    /// The centre of the time span of the frames each field is correlated from, µs of camera
    /// time (PIV of frames rebuilt from events).
    FrameCentre,
    /// The instant each field holds, µs of camera time (ground truth of a simulation).
    Instant,
    /// The index of the field, 0, 1, …: one per image pair, a single 0 for an ensemble of
    /// pairs. Image files carry no time stamps.
    PairIndex,
}

impl TimeBasis {
    /// Whether the times are µs of camera time (every basis but [`TimeBasis::PairIndex`]).
    pub fn is_camera_time(self) -> bool {
        self != TimeBasis::PairIndex
    }

    /// What the per-vector `slab_us` of a series with these times holds, as a phrase for file
    /// metadata (see [`FieldSeries::slab_us`]).
    pub fn describe_slab(self) -> &'static str {
        match self {
            TimeBasis::SlabCentre => {
                "length T of the time slab the vector was measured over, microseconds (sum of \
                 correlation: each of its two sub-volumes, which together span T + tau; motion \
                 compensation: the slab of warped events); 0 for masked windows"
            }
            TimeBasis::FrameCentre => {
                "time span of the frames the vector was correlated from, from the start of the \
                 first to the end of the last, microseconds; 0 for masked windows"
            }
            TimeBasis::Instant => "none: a sampled flow has no time slab (0)",
            TimeBasis::PairIndex => {
                "time between the two frames of a pair (--dt), microseconds; 0 when it is not \
                 given and for masked windows"
            }
        }
    }

    /// What a field's time is, as a phrase for file metadata.
    pub fn describe(self) -> &'static str {
        match self {
            TimeBasis::SlabCentre => "centre of the field's time slab, microseconds of camera time",
            TimeBasis::FrameCentre => {
                "centre of the time span of the field's frames, microseconds of camera time"
            }
            TimeBasis::Instant => "instant of the field, microseconds of camera time",
            TimeBasis::PairIndex => {
                "index of the field: 0, 1, ... one per image pair (0 for an ensemble of pairs); \
                 image files carry no time stamps"
            }
        }
    }
}

/// A time series of 2-D vector fields on one regular grid.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldSeries {
    /// Grid column positions (window centres), px.
    pub x: Vec<f64>,
    /// Grid row positions, px.
    pub y: Vec<f64>,
    /// Time of each field, µs of camera time, or an index (see `time_basis`).
    pub t_us: Vec<i64>,
    /// x velocity, px/ms, indexed `[t][y][x]` (NaN where invalid).
    pub u: Vec<f32>,
    /// y velocity (positive down), px/ms, indexed `[t][y][x]`.
    pub v: Vec<f32>,
    /// Standard uncertainty (one standard deviation) of `u`, in the unit of `u`; NaN where
    /// unknown, and for invalid and replaced vectors; indexed `[t][y][x]`.
    pub u_unc: Vec<f32>,
    /// Standard uncertainty (one standard deviation) of `v`, in the unit of `v`; NaN where
    /// unknown, and for invalid and replaced vectors; indexed `[t][y][x]`.
    pub v_unc: Vec<f32>,
    /// Status flags, indexed `[t][y][x]`.
    pub status: Vec<Status>,
    /// Peak value of the correlation plane or objective, indexed `[t][y][x]`.
    pub peak: Vec<f32>,
    /// First-to-second peak ratio (NaN where not defined; see [`VectorField::peak_ratio`]),
    /// indexed `[t][y][x]`.
    pub peak_ratio: Vec<f32>,
    /// Events used per window, indexed `[t][y][x]`.
    pub event_count: Vec<u32>,
    /// Length T of the time slab each vector was measured over, µs, indexed `[t][y][x]`: the
    /// estimator's slab (sum of correlation: the length of each of its two sub-volumes, which
    /// together span T + τ; motion compensation: the slab whose events are warped), the time
    /// span of the frames (PIV of frames rebuilt from events, pulsed EBIV), or the time
    /// between the frames of an image pair when it is given. 0 where there is no slab: masked
    /// windows, image pairs without a time between the frames, and a ground truth. A
    /// replaced vector keeps the slab its window was evaluated over.
    ///
    /// `u32` microseconds rather than the `i64` of time stamps: a duration is never negative,
    /// and 32 bits (up to 71 minutes; PIV refuses frames or a `dt` spanning more) keep every
    /// output format's integer type: NetCDF `int` (up to 35 minutes), NumPy `<u4`, VTK
    /// `unsigned_int`.
    pub slab_us: Vec<u32>,
    /// Physical scaling applied by the writers, if any.
    pub calibration: Option<Calibration>,
    /// What `u` and `v` hold: velocities (event estimators) or displacements (PIV of an
    /// image pair).
    pub quantity: Quantity,
    /// What the times `t_us` stand for.
    pub time_basis: TimeBasis,
    /// The camera time, µs, that the run's requested field times (`ebiv process --time`)
    /// count from: the first event of the recording, or 0 when they were given in camera time.
    /// Written next to the time axis so that the two can be related; `None` when unknown.
    pub time_origin_us: Option<i64>,
    /// The series is a ground truth (a simulation's flow sampled on a grid): `u_unc`,
    /// `v_unc` (NaN), `status`, `peak`, `peak_ratio`, `event_count` and `slab_us` carry no
    /// information and the writers leave them out.
    pub ground_truth: bool,
    /// Descriptive attributes written into every output: the source and the processing
    /// settings. The writers add the software, units, axis convention, time basis and
    /// status legend themselves.
    pub attributes: Vec<(String, String)>,
    /// Quantities derived from the velocity gradient ([`crate::derived`]), written next to
    /// `u` and `v`; empty unless asked for.
    pub derived: Vec<crate::derived::DerivedField>,
}

impl FieldSeries {
    /// An all-NaN series (status [`Status::NO_EVENTS`]) on the given grid and times.
    pub fn new(x: Vec<f64>, y: Vec<f64>, t_us: Vec<i64>) -> Self {
        let n = x.len() * y.len() * t_us.len();
        FieldSeries {
            x,
            y,
            t_us,
            u: vec![f32::NAN; n],
            v: vec![f32::NAN; n],
            u_unc: vec![f32::NAN; n],
            v_unc: vec![f32::NAN; n],
            status: vec![Status::NO_EVENTS; n],
            peak: vec![f32::NAN; n],
            peak_ratio: vec![f32::NAN; n],
            event_count: vec![0; n],
            slab_us: vec![0; n],
            calibration: None,
            quantity: Quantity::Velocity,
            time_basis: TimeBasis::SlabCentre,
            time_origin_us: None,
            ground_truth: false,
            attributes: Vec::new(),
            derived: Vec::new(),
        }
    }

    /// An empty series on a grid, to which fields are appended with [`FieldSeries::push`].
    pub fn on_grid(x: Vec<f64>, y: Vec<f64>) -> Self {
        FieldSeries::new(x, y, Vec::new())
    }

    /// Give a series without a calibration of its own the scale `mm_per_px` (origin at
    /// (0, 0) px, y down), so that it is written in mm and m/s (as `ebiv stats` and `ebiv
    /// derive --mm-per-px` do); a series with a calibration keeps it.
    pub fn scale_if_uncalibrated(&mut self, mm_per_px: Option<f64>) {
        if let (Some(mm_per_px), None) = (mm_per_px, self.calibration) {
            self.calibration = Some(Calibration {
                mm_per_px,
                origin_px: [0.0, 0.0],
                y_up: false,
            });
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

    /// Append a field at time `t_us`; it must lie on this series' grid, and the series must
    /// hold no derived quantities (they would not cover the new field).
    pub fn push(&mut self, t_us: i64, field: &VectorField) -> crate::Result<()> {
        if !self.derived.is_empty() {
            return Err(crate::Error::parameter(
                "field",
                "the series holds derived quantities; add fields before deriving them",
            ));
        }
        if field.x != self.x || field.y != self.y {
            return Err(crate::Error::parameter(
                "field",
                format!(
                    "field at {t_us} µs is on a {}×{} grid, the series on {}×{}",
                    field.width(),
                    field.height(),
                    self.x.len(),
                    self.y.len()
                ),
            ));
        }
        self.t_us.push(t_us);
        self.u.extend_from_slice(&field.u);
        self.v.extend_from_slice(&field.v);
        self.u_unc.extend_from_slice(&field.u_unc);
        self.v_unc.extend_from_slice(&field.v_unc);
        self.status.extend_from_slice(&field.status);
        self.peak.extend_from_slice(&field.peak);
        self.peak_ratio.extend_from_slice(&field.peak_ratio);
        self.event_count.extend_from_slice(&field.event_count);
        self.slab_us.extend_from_slice(&field.slab_us);
        Ok(())
    }

    /// A copy of the field at time index `t`.
    pub fn field(&self, t: usize) -> VectorField {
        let n = self.field_len();
        let r = t * n..(t + 1) * n;
        VectorField {
            x: self.x.clone(),
            y: self.y.clone(),
            u: self.u[r.clone()].to_vec(),
            v: self.v[r.clone()].to_vec(),
            u_unc: self.u_unc[r.clone()].to_vec(),
            v_unc: self.v_unc[r.clone()].to_vec(),
            status: self.status[r.clone()].to_vec(),
            peak: self.peak[r.clone()].to_vec(),
            peak_ratio: self.peak_ratio[r.clone()].to_vec(),
            event_count: self.event_count[r.clone()].to_vec(),
            slab_us: self.slab_us[r].to_vec(),
        }
    }

    /// Value of a named attribute, if set.
    pub fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_interpolates_and_skips_missing_nodes() {
        let mut f = VectorField::new(vec![0.0, 10.0], vec![0.0, 10.0]);
        for (i, u) in [1.0f32, 3.0, 1.0, 3.0].into_iter().enumerate() {
            f.u[i] = u;
            f.v[i] = -u;
            f.status[i] = Status::VALID;
        }
        let s = f.sample(5.0, 5.0).unwrap();
        assert!((s[0] - 2.0).abs() < 1e-12 && (s[1] + 2.0).abs() < 1e-12);
        // Outside the grid: clamped to the edge.
        assert_eq!(f.sample(-5.0, 0.0).unwrap()[0], 1.0);
        f.invalidate(1, Status::MEDIAN_TEST);
        f.invalidate(3, Status::MEDIAN_TEST);
        assert_eq!(f.sample(9.0, 5.0).unwrap()[0], 1.0);
        f.invalidate(0, Status::MEDIAN_TEST);
        f.invalidate(2, Status::MEDIAN_TEST);
        assert!(f.sample(5.0, 5.0).is_none());
    }

    #[test]
    fn calibration_flips_position_and_velocity_together() {
        let c = Calibration {
            mm_per_px: 0.05,
            origin_px: [10.0, 100.0],
            y_up: true,
        };
        assert!((c.x_mm(30.0) - 1.0).abs() < 1e-12);
        assert!((c.y_mm(80.0) - 1.0).abs() < 1e-12);
        let (u, v) = c.velocity_m_per_s(2.0, 4.0);
        assert!((u - 0.1).abs() < 1e-6 && (v + 0.2).abs() < 1e-6);
        // An uncertainty is scaled, never flipped.
        let (u_unc, v_unc) = c.uncertainty_m_per_s(0.2, 0.4);
        assert!((u_unc - 0.01).abs() < 1e-7 && (v_unc - 0.02).abs() < 1e-7);
        let down = Calibration { y_up: false, ..c };
        assert_eq!(down.uncertainty_m_per_s(0.2, 0.4), (u_unc, v_unc));
        assert!(c.uncertainty_m_per_s(f32::NAN, 0.4).0.is_nan());
        assert!(Calibration {
            mm_per_px: 0.0,
            ..c
        }
        .validate()
        .is_err());
    }

    #[test]
    fn one_slab_per_field_leaves_masked_windows_without_one() {
        let mut f = VectorField::new(vec![0.0, 1.0, 2.0], vec![0.0]);
        f.status[1] = Status::MASKED;
        f.status[2] = Status::MEDIAN_TEST | Status::REPLACED;
        f.set_slab_us(7000);
        assert_eq!(f.slab_us, vec![7000, 0, 7000]);
        let mut s = FieldSeries::on_grid(f.x.clone(), f.y.clone());
        s.push(3, &f).unwrap();
        s.push(4, &VectorField::new(f.x.clone(), f.y.clone()))
            .unwrap();
        assert_eq!(s.slab_us, vec![7000, 0, 7000, 0, 0, 0]);
        assert_eq!(s.field(0).slab_us, f.slab_us);
    }

    #[test]
    fn uncertainties_are_carried_scaled_by_the_magnitude_and_cleared_when_invalid() {
        let mut f = VectorField::new(vec![0.0, 1.0, 2.0], vec![0.0]);
        assert!(f.u_unc.iter().chain(&f.v_unc).all(|x| x.is_nan()));
        f.u = vec![1.0, 2.0, 3.0];
        f.v = vec![-1.0, -2.0, -3.0];
        f.u_unc = vec![0.1, 0.2, f32::NAN];
        f.v_unc = vec![0.3, 0.4, f32::NAN];
        f.status = vec![Status::VALID; 3];
        // A negative factor flips the vectors but not the spread of their errors.
        f.scale(-2.0);
        assert_eq!(f.u[..2], [-2.0, -4.0]);
        assert_eq!(f.u_unc[..2], [0.2, 0.4]);
        assert_eq!(f.v_unc[..2], [0.6, 0.8]);
        assert!(f.u_unc[2].is_nan());
        f.invalidate(1, Status::MEDIAN_TEST);
        assert!(f.u_unc[1].is_nan() && f.v_unc[1].is_nan());
        let mut s = FieldSeries::on_grid(f.x.clone(), f.y.clone());
        s.push(0, &VectorField::new(f.x.clone(), f.y.clone()))
            .unwrap();
        s.push(1, &f).unwrap();
        assert_eq!(s.u_unc.len(), 6);
        assert_eq!(s.u_unc[3], 0.2);
        assert_eq!(s.v_unc[3], 0.6);
        let back = s.field(1);
        assert_eq!((back.u_unc[0], back.v_unc[0]), (0.2, 0.6));
        assert!(back.u_unc[1].is_nan() && back.v_unc[2].is_nan());
    }

    #[test]
    fn push_rejects_other_grids() {
        let mut s = FieldSeries::on_grid(vec![0.0, 1.0], vec![0.0]);
        s.push(5, &VectorField::new(vec![0.0, 1.0], vec![0.0]))
            .unwrap();
        assert!(s.push(6, &VectorField::new(vec![0.0], vec![0.0])).is_err());
        assert_eq!(s.t_us, vec![5]);
        assert_eq!(s.field(0).status, vec![Status::NO_EVENTS; 2]);
    }
}
