//! Vector fields from NetCDF classic files in the layout of ebiv's NetCDF export
//! ([`crate::export::write_field_netcdf`]): `u`, `v` over (time, y, x) or (y, x), coordinate
//! variables `x`, `y` (and `x_px`, `y_px` in calibrated files), optional `time`, `status`,
//! `peak`, `peak_ratio`, `event_count`, `slab_us`, `u_unc`, `v_unc`, the derived quantities
//! (`vorticity`, …, [`crate::derived`]: their calibration's factor undone, so that they are
//! written again unchanged); the calibration from the global attributes `mm_per_px`,
//! `origin_px` and `y_positive`.

use super::grid::set_uncertainty;
use super::FieldReadOptions;
use crate::derived::{DerivedField, DerivedQuantity};
use crate::error::Result;
use crate::field::{Calibration, FieldSeries, Quantity, Status, TimeBasis};
use crate::sim::flow::gridded::netcdf::Reader;
use std::path::Path;

/// Global attributes the writer sets itself, not copied into the series' attributes.
use crate::export::netcdf::OWN_GLOBALS as WRITER_GLOBALS;

fn global_number(r: &Reader, name: &str) -> Vec<f64> {
    let ds = r.reader.data_set();
    ds.get_global_attr_f64(name)
        .map(|v| v.to_vec())
        .or_else(|| {
            ds.get_global_attr_f32(name)
                .map(|v| v.iter().map(|&x| x as f64).collect())
        })
        .or_else(|| {
            ds.get_global_attr_i32(name)
                .map(|v| v.iter().map(|&x| x as f64).collect())
        })
        .unwrap_or_default()
}

fn units(r: &Reader, var: &str) -> String {
    r.reader
        .data_set()
        .get_var_attr_as_string(var, "units")
        .unwrap_or_default()
        .trim()
        .to_ascii_lowercase()
}

/// Read an ebiv NetCDF field file.
pub(super) fn read(path: &Path, options: &FieldReadOptions) -> Result<FieldSeries> {
    let mut r = Reader::open(path)?;
    let has = |r: &Reader, v: &str| r.reader.data_set().has_var(v);
    for var in ["x", "y", "u", "v"] {
        if !has(&r, var) {
            return Err(r.err(format!(
                "no variable `{var}`: a vector field needs `u`, `v` over (time, y, x) and the \
                 coordinates `x`, `y`"
            )));
        }
    }
    let mm = global_number(&r, "mm_per_px");
    let calibration = match mm.first() {
        Some(&s) if s.is_finite() && s > 0.0 => {
            let origin = global_number(&r, "origin_px");
            let y_up = r
                .reader
                .data_set()
                .get_global_attr_as_string("y_positive")
                .is_some_and(|s| s.trim() == "up");
            Some(Calibration {
                mm_per_px: s,
                origin_px: [
                    origin.first().copied().unwrap_or(0.0),
                    origin.get(1).copied().unwrap_or(0.0),
                ],
                y_up,
            })
        }
        _ => None,
    };
    let scale = calibration.map(|c| c.mm_per_px).or(options.mm_per_px);
    let axis = |r: &mut Reader, name: &str| -> Result<Vec<f64>> {
        let px = format!("{name}_px");
        if has(r, &px) {
            return r.read(&px);
        }
        let values = r.read(name)?;
        match units(r, name).as_str() {
            "" | "pixel" | "pixels" | "px" => Ok(values),
            "mm" => {
                let s = scale.ok_or_else(|| {
                    r.err(format!(
                        "`{name}` is in mm and the file carries no calibration; give the scale \
                         in mm per pixel (ebiv assess --mm-per-px)"
                    ))
                })?;
                let c = calibration.unwrap_or(Calibration {
                    mm_per_px: s,
                    origin_px: [0.0, 0.0],
                    y_up: false,
                });
                let (origin, flip) = if name == "x" {
                    (c.origin_px[0], 1.0)
                } else {
                    (c.origin_px[1], if c.y_up { -1.0 } else { 1.0 })
                };
                Ok(values.iter().map(|v| origin + flip * v / s).collect())
            }
            other => Err(r.err(format!("`{name}` has the unknown units `{other}`"))),
        }
    };
    let xs = axis(&mut r, "x")?;
    let ys = axis(&mut r, "y")?;
    let u_dims = r.dim_names("u")?;
    if r.dim_names("v")? != u_dims {
        return Err(r.err("`u` and `v` have different dimensions"));
    }
    let (times, basis) = if u_dims.len() == 3 && has(&r, "time") {
        let unit = units(&r, "time");
        let long = r
            .reader
            .data_set()
            .get_var_attr_as_string("time", "long_name")
            .unwrap_or_default();
        let basis = if unit == "1" || long.contains("index") {
            TimeBasis::PairIndex
        } else if long.contains("slab") {
            TimeBasis::SlabCentre
        } else if long.contains("frames") {
            TimeBasis::FrameCentre
        } else {
            TimeBasis::Instant
        };
        let factor = if basis == TimeBasis::PairIndex {
            1.0
        } else {
            r.time_scale()?
        };
        let t = r.read("time")?;
        if t.iter()
            .any(|v| !(v * factor).is_finite() || (v * factor).abs() > 9e18)
        {
            return Err(r.err("`time` holds values that are not times"));
        }
        let t: Vec<i64> = t.iter().map(|v| (v * factor).round() as i64).collect();
        (t, basis)
    } else if u_dims.len() == 2 {
        (vec![0], TimeBasis::Instant)
    } else {
        return Err(r.err(format!(
            "`u` has dimensions ({}); expected (time, y, x) or (y, x)",
            u_dims.join(", ")
        )));
    };
    let mut s = FieldSeries::new(xs, ys, times);
    s.time_basis = basis;
    let n = s.u.len();
    let read_len = |r: &mut Reader, name: &str| -> Result<Vec<f64>> {
        let values = r.read(name)?;
        if values.len() != n {
            return Err(r.err(format!(
                "`{name}` holds {} values, the grid {} × {} × {} needs {n}",
                values.len(),
                s.x.len(),
                s.y.len(),
                s.t_us.len()
            )));
        }
        Ok(values)
    };
    let u_units = units(&r, "u");
    let (quantity, physical) = match u_units.as_str() {
        "pixel/millisecond" | "px/ms" | "pixel/ms" => (Quantity::Velocity, false),
        "pixel" | "px" | "pixels" => (Quantity::Displacement, false),
        "m/s" => (Quantity::Velocity, true),
        "mm" => (Quantity::Displacement, true),
        other => {
            return Err(r.err(format!(
                "`u` has the units `{other}`; expected pixel/millisecond, pixel, m/s or mm"
            )))
        }
    };
    let (factor, v_sign) = if physical {
        let scale = scale.ok_or_else(|| {
            r.err(format!(
                "`u` is in {u_units} and the file carries no calibration; give the scale in mm \
                 per pixel (ebiv assess --mm-per-px)"
            ))
        })?;
        let flip = calibration.is_some_and(|c| c.y_up);
        (1.0 / scale, if flip { -1.0 } else { 1.0 })
    } else {
        (1.0, 1.0)
    };
    let to_f32 = |v: Vec<f64>, f: f64| -> Vec<f32> { v.iter().map(|x| (x * f) as f32).collect() };
    s.u = to_f32(read_len(&mut r, "u")?, factor);
    s.v = to_f32(read_len(&mut r, "v")?, factor * v_sign);
    s.quantity = quantity;
    if has(&r, "status") {
        let st = read_len(&mut r, "status")?;
        s.status = st
            .iter()
            .map(|&v| {
                Status(if (0.0..=255.0).contains(&v) {
                    v as u8
                } else {
                    0
                })
            })
            .collect();
        if let Some(i) = st.iter().position(|v| !(0.0..=255.0).contains(v)) {
            return Err(r.err(format!(
                "`status` holds {} (vector {i}), not 0 to 255",
                st[i]
            )));
        }
    } else {
        s.ground_truth = true;
        s.status = super::status_from_values(&s.u, &s.v);
    }
    let counts = super::counts_from_values;
    if has(&r, "peak") {
        s.peak = to_f32(read_len(&mut r, "peak")?, 1.0);
    }
    if has(&r, "peak_ratio") {
        s.peak_ratio = to_f32(read_len(&mut r, "peak_ratio")?, 1.0);
    }
    if has(&r, "event_count") {
        s.event_count = counts(read_len(&mut r, "event_count")?);
    }
    if has(&r, "slab_us") {
        s.slab_us = counts(read_len(&mut r, "slab_us")?);
    }
    for q in DerivedQuantity::ALL {
        if !has(&r, q.name()) {
            continue;
        }
        let mut unit = units(&r, q.name());
        if unit.is_empty() {
            // Without units: those the writer gives the series' velocities.
            unit = DerivedQuantity::unit(quantity, calibration.as_ref()).to_string();
        }
        let scale = match (quantity, unit.as_str()) {
            (Quantity::Velocity, "1/ms") | (Quantity::Displacement, "1") => 1.0,
            (Quantity::Velocity, "1/s") => 1000.0,
            _ => {
                return Err(r.err(format!(
                    "`{}` has the units `{unit}`; the {} of the file give {}",
                    q.name(),
                    quantity.noun(),
                    if quantity == Quantity::Velocity {
                        "1/ms or 1/s"
                    } else {
                        "1"
                    }
                )))
            }
        };
        // The writer negates the quantities odd in y with a y-up calibration.
        let factor = if calibration.is_some_and(|c| c.y_up) && q.odd_in_y() {
            -scale
        } else {
            scale
        };
        let values = read_len(&mut r, q.name())?
            .into_iter()
            .map(|w| DerivedQuantity::from_written(w, factor))
            .collect();
        s.derived.push(DerivedField {
            quantity: q,
            values,
        });
    }
    if has(&r, "u_unc") && has(&r, "v_unc") {
        let uu = to_f32(read_len(&mut r, "u_unc")?, factor);
        let vu = to_f32(read_len(&mut r, "v_unc")?, factor);
        set_uncertainty(&mut s, uu, vu);
    }
    if let (Quantity::Displacement, Some(dt)) = (s.quantity, options.frame_interval_us) {
        let k = 1000.0 / dt;
        s.u.iter_mut()
            .chain(s.v.iter_mut())
            .chain(s.u_unc.iter_mut())
            .chain(s.v_unc.iter_mut())
            .chain(s.derived.iter_mut().flat_map(|d| d.values.iter_mut()))
            .for_each(|w| *w = (*w as f64 * k) as f32);
        s.quantity = Quantity::Velocity;
    }
    s.calibration = calibration;
    s.time_origin_us = global_number(&r, "time_origin_us")
        .first()
        .filter(|v| v.is_finite() && v.abs() < 9e18)
        .map(|&v| v as i64);
    let ds = r.reader.data_set();
    for name in ds.get_global_attr_names() {
        if WRITER_GLOBALS.contains(&name.as_str()) {
            continue;
        }
        if let Some(value) = ds.get_global_attr_as_string(&name) {
            s.attributes.push((name, value));
        }
    }
    Ok(s)
}
