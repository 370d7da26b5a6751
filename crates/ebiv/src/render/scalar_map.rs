//! Colour maps of a scalar at the nodes of a vector field (a derived quantity, the speed, a
//! statistic), filled between the nodes with a colour bar, optionally with the field's
//! arrows on top. Signed quantities get a diverging blue–white–red map centred on 0.

use super::colormap::{blue_red, inferno};
use super::vector_map::{auto_range_of, draw_map, Layer, ScalarLayer, VectorMapStyle};
use crate::event::Geometry;
use crate::field::VectorField;
use image::RgbImage;

/// The quantile of the values at the end of an automatic colour range: high, because a
/// vortex core or a shear layer covers a small part of a field, and below 1 so that a
/// single spurious value does not wash out the rest.
pub const RANGE_QUANTILE: f64 = 0.999;

/// How a scalar map is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarMapStyle {
    /// What the values are, with units, for the colour bar (`vorticity [1/ms]`).
    pub label: String,
    /// The values have a sign: a diverging map centred on 0, over ±`range`.
    pub signed: bool,
    /// Values at the ends of the colour map; `None`: the [`RANGE_QUANTILE`] of |value|
    /// rounded up to two significant digits (0 to it, or ± it when signed).
    pub range: Option<(f32, f32)>,
    /// Draw the field's arrows on top.
    pub vectors: bool,
    /// Title, arrow scale and stride, velocity units, size: as for vector maps.
    pub map: VectorMapStyle,
}

impl Default for ScalarMapStyle {
    fn default() -> Self {
        ScalarMapStyle {
            label: String::new(),
            signed: true,
            range: None,
            vectors: false,
            map: VectorMapStyle::default(),
        }
    }
}

/// The colour range of `values` for `style` (see [`ScalarMapStyle::range`]).
pub fn scalar_range(values: &[f32], style: &ScalarMapStyle) -> (f32, f32) {
    if let Some((a, b)) = style
        .range
        .filter(|(a, b)| a.is_finite() && b.is_finite() && b > a)
    {
        return (a, b);
    }
    let kept: Vec<f32> = if style.signed {
        values
            .iter()
            .map(|v| v.abs())
            .filter(|v| v.is_finite())
            .collect()
    } else {
        values.iter().copied().filter(|v| v.is_finite()).collect()
    };
    scalar_range_of_finite(kept, style.signed)
}

/// The automatic colour range (see [`ScalarMapStyle::range`]) of `kept`: the finite values,
/// or the finite |values| when `signed`; taken by value so that a series' values are held
/// once.
pub(crate) fn scalar_range_of_finite(kept: Vec<f32>, signed: bool) -> (f32, f32) {
    if signed {
        let (_, top) = auto_range_of(kept, RANGE_QUANTILE);
        (-top, top)
    } else {
        auto_range_of(kept, RANGE_QUANTILE)
    }
}

/// Draw `values` (one per node of `field`, NaN where there is none) on a sensor of
/// `geometry`, with `field`'s arrows when `style.vectors`. Never panics: values of another
/// length are drawn as no data.
pub fn scalar_map(
    field: &VectorField,
    values: &[f32],
    geometry: Geometry,
    style: &ScalarMapStyle,
) -> RgbImage {
    let values = if values.len() == field.len() {
        values.to_vec()
    } else {
        vec![f32::NAN; field.len()]
    };
    let range = scalar_range(&values, style);
    let layer = Layer::Scalar(ScalarLayer {
        values,
        range,
        colours: if style.signed { blue_red } else { inferno },
        label: style.label.clone(),
    });
    draw_map(field, geometry, layer, &style.map, style.vectors)
}

/// The sensor size a grid of window centres `x`, `y` (px) covers when its sensor is not
/// known: the last centre plus the first (windows start at the sensor's edge), at least the
/// last centre plus one.
pub fn grid_geometry(x: &[f64], y: &[f64]) -> Geometry {
    let side = |a: &[f64]| -> u32 {
        let (first, last) = match (a.first(), a.last()) {
            (Some(&f), Some(&l)) if f.is_finite() && l.is_finite() => (f.max(0.0), l.max(0.0)),
            _ => return 1,
        };
        (last + first.max(1.0)).ceil().clamp(1.0, 1e6) as u32
    };
    Geometry::new(side(x), side(y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Status;
    use crate::render::axes::probe;

    fn field() -> VectorField {
        let mut f = VectorField::new(vec![8.0, 24.0, 40.0], vec![8.0, 24.0]);
        for i in 0..f.len() {
            f.u[i] = 1.0;
            f.v[i] = 0.5;
            f.status[i] = Status::VALID;
        }
        f
    }

    #[test]
    fn signed_values_get_a_symmetric_range_and_a_diverging_map() {
        let values = [-2.0, -1.0, 0.0, 0.5, 1.0, f32::NAN];
        let r = scalar_range(&values, &ScalarMapStyle::default());
        assert_eq!(r, (-2.0, 2.0));
        let unsigned = ScalarMapStyle {
            signed: false,
            ..ScalarMapStyle::default()
        };
        assert_eq!(scalar_range(&[0.5, 1.5, f32::NAN], &unsigned), (0.0, 1.5));
        let f = field();
        let img = scalar_map(
            &f,
            &[-1.0, 0.0, 1.0, -1.0, 0.0, 1.0],
            grid_geometry(&f.x, &f.y),
            &ScalarMapStyle::default(),
        );
        let (x0, y0, x1, y1) = probe::plot_frame(&img);
        // Blue on the left of the plot, red on the right (a tenth of the width in).
        let inset = (x1 - x0) / 10;
        let left = img.get_pixel(x0 + inset, (y0 + y1) / 2).0;
        let right = img.get_pixel(x1 - inset, (y0 + y1) / 2).0;
        assert!(
            left[2] > left[0] && right[0] > right[2],
            "{left:?} {right:?}"
        );
    }

    #[test]
    fn arrows_are_drawn_only_when_asked_for() {
        let f = field();
        let g = grid_geometry(&f.x, &f.y);
        assert_eq!((g.width, g.height), (48, 32));
        let values = vec![0.0; f.len()];
        let plain = scalar_map(&f, &values, g, &ScalarMapStyle::default());
        let with = scalar_map(
            &f,
            &values,
            g,
            &ScalarMapStyle {
                vectors: true,
                ..ScalarMapStyle::default()
            },
        );
        assert_eq!(plain.dimensions(), with.dimensions());
        assert_ne!(plain, with);
        // Wrong lengths and empty grids do not panic.
        let _ = scalar_map(&f, &[1.0], g, &ScalarMapStyle::default());
        let empty = VectorField::new(vec![], vec![]);
        let _ = scalar_map(
            &empty,
            &[],
            grid_geometry(&[], &[]),
            &ScalarMapStyle::default(),
        );
    }
}
