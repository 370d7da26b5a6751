//! Settings of an assessment and of a comparison: one definition per setting, one default.

use serde::{Deserialize, Serialize};

/// How [`assess`](super::assess) measures a field series.
///
/// A valid vector is an *outlier* when its end-point error exceeds
/// `max(outlier_px / T, outlier_floor)` with T the vector's time slab in ms (`slab_us`), or
/// `outlier_fixed` when set. Half a pixel of displacement is the PIV convention for a
/// spurious vector (a correlation peak half a pixel or more away from the true one; Raffel et
/// al., *Particle Image Velocimetry*, 3rd ed., 2018, §6.1): over a slab of T ms it is an error
/// of 0.5/T px/ms. The floor keeps long slabs from calling the ordinary scatter of event
/// estimates an outlier: 0.1 px/ms is the median disagreement of the two event methods on the
/// EBIV paper's wall flow. A displacement field (PIV of an image pair) uses `outlier_px`
/// directly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct AssessOptions {
    /// End-point error, in px of displacement over the vector's slab, beyond which a vector is
    /// an outlier.
    pub outlier_px: f64,
    /// Lowest outlier threshold, px/ms, for long slabs and vectors without a slab.
    pub outlier_floor: f64,
    /// A fixed outlier threshold in the field's unit instead of the two above.
    pub outlier_fixed: Option<f64>,
    /// Bins of the errors against the true speed (equal widths from 0 to the largest speed).
    pub speed_bins: usize,
    /// Bins of the errors against the events per window (equal numbers of vectors).
    pub event_bins: usize,
    /// Bins of the fractional-displacement histogram on [−0.5, 0.5) px; the peak-locking
    /// index is taken from it.
    pub fraction_bins: usize,
}

impl Default for AssessOptions {
    fn default() -> Self {
        AssessOptions {
            outlier_px: 0.5,
            outlier_floor: 0.1,
            outlier_fixed: None,
            speed_bins: 10,
            event_bins: 10,
            fraction_bins: 10,
        }
    }
}

impl AssessOptions {
    /// Check the values: positive thresholds and at least one bin each.
    pub fn validate(&self) -> crate::Result<()> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(crate::Error::parameter(
                    name,
                    format!("must be a positive number, got {v}"),
                ))
            }
        };
        positive("outlier-px", self.outlier_px)?;
        positive("outlier-floor", self.outlier_floor)?;
        if let Some(v) = self.outlier_fixed {
            positive("outlier-fixed", v)?;
        }
        for (name, bins) in [
            ("speed-bins", self.speed_bins),
            ("event-bins", self.event_bins),
            ("fraction-bins", self.fraction_bins),
        ] {
            if !(1..=1000).contains(&bins) {
                return Err(crate::Error::parameter(
                    name,
                    format!("must be 1 to 1000, got {bins}"),
                ));
            }
        }
        Ok(())
    }

    /// The outlier threshold of a vector measured over `slab_us` (0: unknown), in the unit of
    /// the field: px for `displacement`, else px/ms.
    pub fn outlier_threshold(&self, slab_us: u32, displacement: bool) -> f64 {
        if let Some(fixed) = self.outlier_fixed {
            return fixed;
        }
        if displacement {
            return self.outlier_px;
        }
        if slab_us == 0 {
            return self.outlier_floor;
        }
        (self.outlier_px / (slab_us as f64 / 1000.0)).max(self.outlier_floor)
    }
}

/// How [`compare`](super::compare) matches and judges two field series.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct CompareOptions {
    /// End-point difference beyond which two vectors disagree, in the fields' unit (the
    /// wall-flow comparison counts differences above 1 px/ms).
    pub threshold: f64,
    /// Largest time difference, µs, between matched fields; `None`: half the smallest spacing
    /// of the first series' fields (any difference when it holds one field).
    pub time_tolerance_us: Option<i64>,
    /// Largest number of vector pairs kept as scatter data (evenly thinned beyond).
    pub max_scatter: usize,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            threshold: 1.0,
            time_tolerance_us: None,
            max_scatter: 20_000,
        }
    }
}
