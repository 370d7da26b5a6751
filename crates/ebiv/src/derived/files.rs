//! How the derived quantities of a series are stored in its field files: one convention for
//! every writer and reader (docs/derived.md, "Output").
//!
//! A [`DerivedField`] holds its values in image coordinates (x right, y down, v positive
//! down) and image units: 1/ms for velocities in px/ms, `1` (per frame interval) for the
//! displacements of image pairs. A calibration writes them in its own frame: ×1000 to 1/s
//! for velocities (the scale mm/px cancels between velocity and position), and the
//! quantities odd in y (vorticity, e_xy) negated when it has y up, as v and y are.
//!
//! * NetCDF holds one variable per quantity, in the frame of the file's `u` and `v`: as the
//!   calibration writes it, or in image coordinates without one ([`DerivedQuantity::written`]).
//! * NPZ and CSV always hold the image values (NPZ `vorticity`; CSV `vorticity_1_ms`, or
//!   `vorticity_1` for displacements). Where the calibration writes other values, a second
//!   copy follows ([`DerivedQuantity::physical_name`]): `vorticity_1_s` for calibrated
//!   velocities, `vorticity_y_up` for calibrated displacements with y up. Calibrated
//!   displacements with y down have none: it would repeat the image values.
//!
//! So the NetCDF variable equals the second copy of NPZ and CSV where there is one, and their
//! image values otherwise. The readers take the image values (NPZ, CSV) or undo the
//! calibration's factor exactly ([`DerivedQuantity::from_written`], NetCDF), so that a file
//! written again holds the same values.

use super::{DerivedField, DerivedQuantity};
use crate::field::{Calibration, FieldSeries, Quantity};

impl DerivedQuantity {
    /// The unit of the quantity of a series holding `quantity`, as written with
    /// `calibration`: 1/ms (1/s calibrated) for velocities, `1` (per frame interval) for the
    /// displacements of image pairs.
    pub fn unit(quantity: Quantity, calibration: Option<&Calibration>) -> &'static str {
        match (quantity, calibration) {
            (Quantity::Displacement, _) => "1",
            (Quantity::Velocity, None) => "1/ms",
            (Quantity::Velocity, Some(_)) => "1/s",
        }
    }

    /// The factor from the computed value (image coordinates) to the written one: 1000
    /// from 1/ms to 1/s for calibrated velocities, negated for a quantity odd in y when the
    /// calibration has y up.
    pub fn written_factor(self, quantity: Quantity, calibration: Option<&Calibration>) -> f64 {
        let Some(c) = calibration else {
            return 1.0;
        };
        let scale = if quantity == Quantity::Velocity {
            1000.0
        } else {
            1.0
        };
        if c.y_up && self.odd_in_y() {
            -scale
        } else {
            scale
        }
    }

    /// The values of `field` of `series` as written (see [`DerivedQuantity::written_factor`]).
    pub fn written(field: &DerivedField, series: &FieldSeries) -> Vec<f32> {
        let k = field
            .quantity
            .written_factor(series.quantity, series.calibration.as_ref());
        field.values.iter().map(|&v| written_value(v, k)).collect()
    }

    /// The CSV column of the image values (`vorticity_1_ms`; `vorticity_1` for
    /// displacements).
    pub fn image_column(self, quantity: Quantity) -> String {
        let unit = DerivedQuantity::unit(quantity, None).replace('/', "_");
        format!("{}_{unit}", self.name())
    }

    /// The NPZ array and CSV column of the values as `calibration` writes them, where they
    /// differ from the image values: `vorticity_1_s` for calibrated velocities,
    /// `vorticity_y_up` for calibrated displacements with y up (only the quantities that
    /// change sign with y: the others would repeat the image values); `None` otherwise.
    pub fn physical_name(
        self,
        quantity: Quantity,
        calibration: Option<&Calibration>,
    ) -> Option<String> {
        match (calibration, quantity) {
            (Some(_), Quantity::Velocity) => Some(format!("{}_1_s", self.name())),
            (Some(c), Quantity::Displacement) if c.y_up && self.odd_in_y() => {
                Some(format!("{}_y_up", self.name()))
            }
            _ => None,
        }
    }

    /// The image value whose written value (with `factor`, see
    /// [`DerivedQuantity::written_factor`]) is `written`: the nearest `f32` to
    /// `written / factor`, or its neighbour where that one is written as `written` and the
    /// nearest is not, so that values read from a file are written again unchanged.
    pub fn from_written(written: f64, factor: f64) -> f32 {
        let guess = (written / factor) as f32 + 0.0;
        if !guess.is_finite() || factor.abs() == 1.0 {
            return guess;
        }
        let target = written as f32;
        // The neighbours of `guess` in magnitude, one bit pattern either side.
        let bits = guess.to_bits();
        let neighbours = [bits.wrapping_add(1), bits.wrapping_sub(1)].map(f32::from_bits);
        std::iter::once(guess)
            .chain(neighbours)
            .find(|&c| written_value(c, factor) == target)
            .unwrap_or(guess)
    }
}

/// One image value `v` as written with `factor`; `+ 0.0` turns the -0 of a flipped zero
/// into 0.
pub(crate) fn written_value(v: f32, factor: f64) -> f32 {
    (v as f64 * factor + 0.0) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_values_are_read_back_to_values_written_again_unchanged() {
        // Values spread over many binades, where ×1000 rounds either way.
        let mut v = 1.234_567e-4_f32;
        for _ in 0..20_000 {
            for k in [1000.0, -1000.0, 1.0, -1.0] {
                let w = written_value(v, k);
                let back = DerivedQuantity::from_written(w as f64, k);
                assert_eq!(written_value(back, k).to_bits(), w.to_bits(), "{v} × {k}");
            }
            v = v * 1.000_73 + 1e-9;
        }
        assert!(DerivedQuantity::from_written(f64::NAN, 1000.0).is_nan());
    }

    #[test]
    fn names_are_unique_for_every_kind_of_series() {
        let calibration = |y_up| Calibration {
            mm_per_px: 0.1,
            origin_px: [0.0, 0.0],
            y_up,
        };
        for quantity in [Quantity::Velocity, Quantity::Displacement] {
            for c in [None, Some(calibration(false)), Some(calibration(true))] {
                for q in DerivedQuantity::ALL {
                    let image = q.image_column(quantity);
                    if let Some(physical) = q.physical_name(quantity, c.as_ref()) {
                        assert_ne!(image, physical);
                        assert_ne!(q.name(), physical);
                    }
                }
            }
        }
    }
}
