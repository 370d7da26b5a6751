//! Quantities derived from the velocity gradient of a vector field: vorticity, divergence,
//! the strain-rate components and the swirling strength, at every node of every field of a
//! series ([`derive_series`]).
//!
//! The four gradient components ∂u/∂x, ∂u/∂y, ∂v/∂x, ∂v/∂y come from finite differences over
//! the grid ([`gradient`]): second-order central differences inside the grid, first-order
//! one-sided differences at its edges and next to a node without a value, NaN where neither
//! neighbour along an axis has a value or the node itself has none. Invalid vectors never
//! enter as zeros. The central difference is the scheme of Raffel et al., "Particle Image
//! Velocimetry", 3rd ed. (2018), §10 (differential estimates of the vorticity): truncation
//! error O(Δ²) and, for independent vector errors ε, a random error of ε/(√2 Δ) ≈ 0.71 ε/Δ,
//! where a one-sided difference gives O(Δ) and √2 ε/Δ; the wider stencils of that section
//! (Richardson extrapolation, least squares) smooth over two grid spacings, where PIV vectors
//! of overlapping windows are already correlated.
//!
//! Values are computed in image coordinates (x right, y down, v positive down), in 1/ms
//! for velocities in px/ms (px per px per ms; the displacements of image pairs give a
//! dimensionless gradient per frame interval). [`DerivedQuantity::written`] converts them
//! as a calibration writes them: ×1000 to 1/s (the scale mm/px cancels between velocity and
//! position), and with y up the sign of the quantities odd in y (vorticity, e_xy) flips
//! with v and y.
//!
//! The vorticity ω_z = ∂v/∂x − ∂u/∂y holds in the coordinates written: in image coordinates
//! (y down) a positive ω_z turns clockwise as the image is seen; with a y-up calibration a
//! positive ω_z turns counter-clockwise. The swirling strength λ_ci is the imaginary part
//! of the complex eigenvalues of the 2-D velocity-gradient tensor, 0 where they are real
//! (Zhou, Adrian, Balachandar & Kendall, J. Fluid Mech. 387:353, 1999); it has no sign.

mod files;
mod gradient;

pub(crate) use files::written_value;
pub use gradient::{gradients, Gradient};

use crate::error::{Error, Result};
use crate::field::FieldSeries;
use rayon::prelude::*;

/// A quantity derived from the velocity gradient.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DerivedQuantity {
    /// ω_z = ∂v/∂x − ∂u/∂y.
    Vorticity,
    /// ∂u/∂x + ∂v/∂y (the in-plane divergence).
    Divergence,
    /// e_xx = ∂u/∂x.
    StrainXx,
    /// e_yy = ∂v/∂y.
    StrainYy,
    /// e_xy = ½ (∂u/∂y + ∂v/∂x).
    StrainXy,
    /// λ_ci: imaginary part of the complex eigenvalues of the gradient tensor, 0 if real.
    SwirlingStrength,
}

impl DerivedQuantity {
    /// Every quantity, in the order of the files.
    pub const ALL: [DerivedQuantity; 6] = [
        DerivedQuantity::Vorticity,
        DerivedQuantity::Divergence,
        DerivedQuantity::StrainXx,
        DerivedQuantity::StrainYy,
        DerivedQuantity::StrainXy,
        DerivedQuantity::SwirlingStrength,
    ];

    /// The name of the variable, column and setting value.
    pub fn name(self) -> &'static str {
        match self {
            DerivedQuantity::Vorticity => "vorticity",
            DerivedQuantity::Divergence => "divergence",
            DerivedQuantity::StrainXx => "e_xx",
            DerivedQuantity::StrainYy => "e_yy",
            DerivedQuantity::StrainXy => "e_xy",
            DerivedQuantity::SwirlingStrength => "swirling_strength",
        }
    }

    /// The quantity named `name` ([`DerivedQuantity::name`]).
    pub fn parse(name: &str) -> Option<DerivedQuantity> {
        DerivedQuantity::ALL
            .into_iter()
            .find(|q| q.name() == name.trim())
    }

    /// Whether its sign flips when y (and v) are flipped: vorticity and e_xy.
    pub fn odd_in_y(self) -> bool {
        matches!(self, DerivedQuantity::Vorticity | DerivedQuantity::StrainXy)
    }

    /// Whether it has a sign (a diverging colour map centred on 0 shows it).
    pub fn signed(self) -> bool {
        self != DerivedQuantity::SwirlingStrength
    }

    /// What it is, for file metadata; `y_up`: the coordinates written have y up.
    pub fn long_name(self, y_up: bool) -> String {
        let frame = if y_up {
            "y up, v positive up"
        } else {
            "image coordinates, y down, v positive down"
        };
        match self {
            DerivedQuantity::Vorticity => format!(
                "vorticity dv/dx - du/dy ({frame}: positive = {} as seen in the image)",
                if y_up {
                    "counter-clockwise"
                } else {
                    "clockwise"
                }
            ),
            DerivedQuantity::Divergence => "in-plane divergence du/dx + dv/dy".into(),
            DerivedQuantity::StrainXx => "normal strain rate e_xx = du/dx".into(),
            DerivedQuantity::StrainYy => "normal strain rate e_yy = dv/dy".into(),
            DerivedQuantity::StrainXy => format!("shear strain rate e_xy = (du/dy + dv/dx)/2 ({frame})"),
            DerivedQuantity::SwirlingStrength => {
                "swirling strength: imaginary part of the complex eigenvalues of the velocity gradient tensor, 0 where they are real (Zhou et al. 1999)".into()
            }
        }
    }

    /// Its value from the gradient at one node.
    pub fn of(self, g: &Gradient) -> f64 {
        match self {
            DerivedQuantity::Vorticity => g.dv_dx - g.du_dy,
            DerivedQuantity::Divergence => g.du_dx + g.dv_dy,
            DerivedQuantity::StrainXx => g.du_dx,
            DerivedQuantity::StrainYy => g.dv_dy,
            DerivedQuantity::StrainXy => 0.5 * (g.du_dy + g.dv_dx),
            DerivedQuantity::SwirlingStrength => g.swirling_strength(),
        }
    }
}

/// One derived quantity over a series, in image coordinates and units (see the module
/// documentation), indexed `[t][y][x]`; NaN where it cannot be computed.
#[derive(Debug, Clone, PartialEq)]
pub struct DerivedField {
    /// What it holds.
    pub quantity: DerivedQuantity,
    /// The values.
    pub values: Vec<f32>,
}

/// The quantities a run derives (the setting `derive`): a list parsed by
/// [`parse_quantities`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DerivedList(pub Vec<DerivedQuantity>);

/// The quantities named in `text`, comma-separated (`vorticity,divergence`); `strain` stands
/// for e_xx, e_yy, e_xy and `all` for every quantity. Sorted, without repetitions.
pub fn parse_quantities(text: &str) -> std::result::Result<Vec<DerivedQuantity>, String> {
    let mut out = Vec::new();
    for name in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        match name {
            "all" => out.extend(DerivedQuantity::ALL),
            "strain" => out.extend([
                DerivedQuantity::StrainXx,
                DerivedQuantity::StrainYy,
                DerivedQuantity::StrainXy,
            ]),
            other => out.push(DerivedQuantity::parse(other).ok_or_else(|| {
                format!(
                    "`{other}` is not a derived quantity; give any of {}, strain or all",
                    DerivedQuantity::ALL.map(|q| q.name()).join(", ")
                )
            })?),
        }
    }
    if out.is_empty() {
        return Err("give at least one quantity (e.g. vorticity,divergence or all)".into());
    }
    out.sort();
    out.dedup();
    Ok(out)
}

/// The quantities of every field of `series` (see the module documentation), in image
/// coordinates and units.
pub fn derive_series(
    series: &FieldSeries,
    quantities: &[DerivedQuantity],
) -> Result<Vec<DerivedField>> {
    let n = series.field_len();
    let nt = series.t_us.len();
    if series.u.len() != n * nt || series.v.len() != n * nt || series.status.len() != n * nt {
        return Err(Error::parameter(
            "field",
            "the velocity arrays do not match the grid and times",
        ));
    }
    let mut out: Vec<DerivedField> = quantities
        .iter()
        .map(|&quantity| DerivedField {
            quantity,
            values: vec![f32::NAN; n * nt],
        })
        .collect();
    if n == 0 {
        return Ok(out);
    }
    let per_field: Vec<Vec<Gradient>> = (0..nt)
        .into_par_iter()
        .map(|t| {
            let r = t * n..(t + 1) * n;
            gradients(
                &series.x,
                &series.y,
                &series.u[r.clone()],
                &series.v[r.clone()],
                &series.status[r],
            )
        })
        .collect();
    for (t, grads) in per_field.iter().enumerate() {
        for d in out.iter_mut() {
            for (value, g) in d.values[t * n..(t + 1) * n].iter_mut().zip(grads) {
                *value = d.quantity.of(g) as f32;
            }
        }
    }
    Ok(out)
}

/// Compute `quantities` of `series` and keep them in it ([`FieldSeries::derived`]), for the
/// writers; an empty list removes them.
pub fn add_derived(series: &mut FieldSeries, quantities: &[DerivedQuantity]) -> Result<()> {
    series.derived = derive_series(series, quantities)?;
    Ok(())
}

/// Check that a field file named `path` can hold derived quantities: .nc, .csv or .npz.
pub fn check_output(path: &std::path::Path) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if matches!(ext.as_str(), "nc" | "csv" | "npz") {
        return Ok(());
    }
    Err(Error::parameter(
        "derive",
        format!(
            "{}: derived quantities are written to .nc, .csv or .npz files",
            path.display()
        ),
    ))
}

/// One sentence on the scheme, for file metadata.
pub const SCHEME: &str = "velocity gradient by second-order central differences between the \
    neighbouring nodes (Raffel et al. 2018, sec. 10); first-order one-sided differences at the \
    grid's edges and next to a node without a value; NaN where a node or both of its neighbours \
    along an axis have no value (invalid vectors never enter as zeros; replaced vectors are used)";

#[cfg(test)]
mod tests;
