//! Maps of a quantity of a field series, one per field: a derived quantity
//! ([`crate::derived`]) or the speed, in the units the field file holds them, over the
//! grid's extent, optionally with the vectors on top ([`super::scalar_map`]).

use super::scalar_map::{grid_geometry, scalar_map, ScalarMapStyle};
use super::vector_map::VectorMapStyle;
use crate::derived::{written_value, DerivedField, DerivedQuantity};
use crate::error::{Error, Result};
use crate::field::FieldSeries;
use image::RgbImage;

/// What a map of a series shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapQuantity {
    /// A derived quantity, which the series must hold ([`FieldSeries::derived`]).
    Derived(DerivedQuantity),
    /// The magnitude of the velocity (or displacement).
    Speed,
}

impl MapQuantity {
    /// `speed` or a derived quantity's name.
    pub fn parse(name: &str) -> std::result::Result<MapQuantity, String> {
        match name.trim() {
            "speed" => Ok(MapQuantity::Speed),
            other => DerivedQuantity::parse(other)
                .map(MapQuantity::Derived)
                .ok_or_else(|| {
                    format!(
                        "`{other}` cannot be drawn; give speed or one of {}",
                        DerivedQuantity::ALL.map(|q| q.name()).join(", ")
                    )
                }),
        }
    }

    /// Its name, for file names and labels.
    pub fn name(self) -> &'static str {
        match self {
            MapQuantity::Speed => "speed",
            MapQuantity::Derived(q) => q.name(),
        }
    }
}

/// How the maps of a series are drawn.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FieldMapStyle {
    /// Draw the vectors on top.
    pub vectors: bool,
    /// Draw every Nth arrow; `None`: a readable density.
    pub stride: Option<usize>,
    /// Values at the ends of the colour map; `None`: from each field's values.
    pub range: Option<(f32, f32)>,
    /// Text before the field's time in the title (a file name).
    pub title: String,
}

/// The unit of `quantity` of `series` as its writers write it, and whether it has a sign;
/// an error when the series does not hold the quantity.
fn unit_of(series: &FieldSeries, quantity: MapQuantity) -> Result<(&'static str, bool)> {
    let calibration = series.calibration.as_ref();
    Ok(match quantity {
        MapQuantity::Derived(q) => {
            derived_of(series, q)?;
            (
                DerivedQuantity::unit(series.quantity, calibration),
                q.signed(),
            )
        }
        MapQuantity::Speed => {
            let (image, physical) = series.quantity.units();
            (
                if calibration.is_some() {
                    physical
                } else {
                    image
                },
                false,
            )
        }
    })
}

/// The derived quantity `q` of `series`; an error when the series does not hold it.
fn derived_of(series: &FieldSeries, q: DerivedQuantity) -> Result<&DerivedField> {
    series
        .derived
        .iter()
        .find(|d| d.quantity == q)
        .ok_or_else(|| {
            Error::parameter(
                "quantity",
                format!(
                    "{} is not among the derived quantities of the series",
                    q.name()
                ),
            )
        })
}

/// The values of `quantity` at the nodes of field `t` of `series` as its writers write them
/// (1/s and m/s with a calibration, odd quantities flipped with y up), pushed onto `out`.
fn push_field_values(
    series: &FieldSeries,
    t: usize,
    quantity: MapQuantity,
    out: &mut Vec<f32>,
) -> Result<()> {
    let n = series.field_len();
    let nodes = t * n..(t + 1) * n;
    let calibration = series.calibration.as_ref();
    match quantity {
        MapQuantity::Derived(q) => {
            let d = derived_of(series, q)?;
            let k = q.written_factor(series.quantity, calibration);
            let values = d.values.get(nodes).ok_or_else(|| {
                Error::parameter(
                    "field",
                    format!("{} holds fewer values than the series' nodes", q.name()),
                )
            })?;
            out.extend(values.iter().map(|&v| written_value(v, k)));
        }
        MapQuantity::Speed => {
            let scale = calibration.map_or(1.0, |c| c.mm_per_px);
            out.extend(nodes.map(|i| {
                let m = (series.u[i] as f64).hypot(series.v[i] as f64) * scale;
                if series.status[i].has_value() {
                    m as f32
                } else {
                    f32::NAN
                }
            }));
        }
    }
    Ok(())
}

/// One colour range for the maps of `quantity` over every field of `series` (see
/// [`super::scalar_range`]), so that the maps of a series compare. One pass over the
/// series, holding one value per node with a value (|value| for a signed quantity).
pub fn series_range(series: &FieldSeries, quantity: MapQuantity) -> Result<(f32, f32)> {
    let (_, signed) = unit_of(series, quantity)?;
    let mut kept = Vec::new();
    let mut field = Vec::with_capacity(series.field_len());
    for t in 0..series.t_us.len() {
        field.clear();
        push_field_values(series, t, quantity, &mut field)?;
        if signed {
            kept.extend(field.iter().map(|v| v.abs()).filter(|v| v.is_finite()));
        } else {
            kept.extend(field.iter().copied().filter(|v| v.is_finite()));
        }
    }
    Ok(super::scalar_map::scalar_range_of_finite(kept, signed))
}

/// The map of `quantity` of field `t` of `series`, the values as its writers write them
/// (see [`series_range`]); axes in image pixels, y down, over the grid's extent. An error
/// when the series does not hold the quantity.
pub fn field_map(
    series: &FieldSeries,
    t: usize,
    quantity: MapQuantity,
    style: &FieldMapStyle,
) -> Result<RgbImage> {
    if t >= series.t_us.len() {
        return Err(Error::parameter(
            "field",
            format!("no field {t} in the series"),
        ));
    }
    let (unit, signed) = unit_of(series, quantity)?;
    let mut values = Vec::with_capacity(series.field_len());
    push_field_values(series, t, quantity, &mut values)?;
    let field = series.field(t);
    let time = if series.time_basis.is_camera_time() {
        format!("t = {:.2} ms", series.t_us[t] as f64 / 1000.0)
    } else {
        format!("field {}", series.t_us[t])
    };
    let title = format!("{} {time}", style.title).trim().to_string();
    let map_style = ScalarMapStyle {
        label: format!("{} [{unit}]", quantity.name()),
        signed,
        range: style.range,
        vectors: style.vectors,
        map: VectorMapStyle {
            title: Some(title),
            units: series.quantity.units().0.into(),
            stride: style.stride,
            ..VectorMapStyle::default()
        },
    };
    Ok(scalar_map(
        &field,
        &values,
        grid_geometry(&series.x, &series.y),
        &map_style,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Status, VectorField};

    #[test]
    fn maps_need_the_quantity_in_the_series() {
        let mut f = VectorField::new(vec![8.0, 24.0, 40.0], vec![8.0, 24.0]);
        for i in 0..f.len() {
            f.u[i] = i as f32;
            f.v[i] = 1.0;
            f.status[i] = Status::VALID;
        }
        let mut s = FieldSeries::on_grid(f.x.clone(), f.y.clone());
        s.push(5000, &f).unwrap();
        let vorticity = MapQuantity::parse("vorticity").unwrap();
        let style = FieldMapStyle::default();
        assert!(field_map(&s, 0, vorticity, &style).is_err());
        assert!(field_map(&s, 0, MapQuantity::Speed, &style).is_ok());
        crate::derived::add_derived(&mut s, &[DerivedQuantity::Vorticity]).unwrap();
        assert!(field_map(&s, 0, vorticity, &style).is_ok());
        assert!(field_map(&s, 1, vorticity, &style).is_err());
        // u = node index on 3 × 2 nodes 16 px apart: du/dy = 3/16 per ms, v uniform, so the
        // vorticity is -0.1875 everywhere: the range ±0.19 (two significant digits, up).
        let r = series_range(&s, vorticity).unwrap();
        assert_eq!(r, (-0.19, 0.19));
        let speed = series_range(&s, MapQuantity::Speed).unwrap();
        assert!(speed.0 == 0.0 && speed.1 >= (5f32 * 5.0 + 1.0).sqrt());
        assert!(MapQuantity::parse("curl")
            .unwrap_err()
            .contains("vorticity"));
    }

    /// The shared range and each map equal those drawn from the whole series' values at
    /// once (every field's values as written, the series' slice of field t).
    #[test]
    fn shared_range_and_maps_equal_those_of_the_whole_series_values() {
        let (x, y) = (vec![8.0, 24.0, 40.0, 56.0], vec![8.0, 24.0, 40.0]);
        let mut s = FieldSeries::on_grid(x.clone(), y.clone());
        for t in 0..3 {
            let mut f = VectorField::new(x.clone(), y.clone());
            for i in 0..f.len() {
                let k = (i * 7 + t * 5) % 11;
                f.u[i] = k as f32 * 0.3 - 1.0;
                f.v[i] = (i as f32 * 0.1).sin() * (t as f32 + 1.0);
                f.status[i] = Status::VALID;
            }
            f.u[t + 2] = f32::NAN;
            f.v[t + 2] = f32::NAN;
            f.status[t + 2] = Status::NO_EVENTS;
            s.push(1000 * t as i64, &f).unwrap();
        }
        s.calibration = Some(crate::field::Calibration {
            mm_per_px: 0.05,
            origin_px: [0.0, 0.0],
            y_up: true,
        });
        crate::derived::add_derived(&mut s, &DerivedQuantity::ALL).unwrap();
        let n = s.field_len();
        for quantity in [
            MapQuantity::Speed,
            MapQuantity::Derived(DerivedQuantity::Vorticity),
            MapQuantity::Derived(DerivedQuantity::SwirlingStrength),
        ] {
            let (all, signed): (Vec<f32>, bool) = match quantity {
                MapQuantity::Derived(q) => {
                    let d = s.derived.iter().find(|d| d.quantity == q).unwrap();
                    (DerivedQuantity::written(d, &s), q.signed())
                }
                MapQuantity::Speed => (
                    (0..s.u.len())
                        .map(|i| {
                            let m = (s.u[i] as f64).hypot(s.v[i] as f64) * 0.05;
                            if s.status[i].has_value() {
                                m as f32
                            } else {
                                f32::NAN
                            }
                        })
                        .collect(),
                    false,
                ),
            };
            let whole = ScalarMapStyle {
                signed,
                ..ScalarMapStyle::default()
            };
            let range = series_range(&s, quantity).unwrap();
            assert_eq!(range, crate::render::scalar_range(&all, &whole));
            for range in [None, Some(range)] {
                let style = FieldMapStyle {
                    range,
                    ..FieldMapStyle::default()
                };
                for t in 0..3 {
                    let map = field_map(&s, t, quantity, &style).unwrap();
                    let unit = unit_of(&s, quantity).unwrap().0;
                    let expected = scalar_map(
                        &s.field(t),
                        &all[t * n..(t + 1) * n],
                        grid_geometry(&s.x, &s.y),
                        &ScalarMapStyle {
                            label: format!("{} [{unit}]", quantity.name()),
                            signed,
                            range,
                            vectors: false,
                            map: VectorMapStyle {
                                title: Some(format!("t = {:.2} ms", t as f64)),
                                units: s.quantity.units().0.into(),
                                ..VectorMapStyle::default()
                            },
                        },
                    );
                    assert!(map == expected, "{} field {t}", quantity.name());
                }
            }
        }
    }
}
