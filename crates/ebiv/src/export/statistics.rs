//! Flow statistics ([`crate::statistics`]) as NetCDF or CSV.
//!
//! NetCDF: dimensions `(y, x)`, or `(phase, y, x)` with phase averaging; variables `u_mean`,
//! `v_mean`, `u_rms`, `v_rms` (`double`, in the unit of the series), `uu`, `vv`, `uv` (in the
//! square of that unit), `count` (`int`, the valid samples), and `phase` (the centre of each
//! bin: µs from the phase origin by period, a fraction 0–1 of the trigger interval by
//! trigger). A calibrated series is written in m/s (and mm for `x_mm`, `y_mm`),
//! with y and v pointing up when the calibration says so, which flips the sign of `v_mean`
//! and `uv`. Nodes without two samples have NaN stresses; without one, NaN means.
//!
//! CSV: one line per node (`phase_us`, or `phase` by trigger, first with phase averaging), the same quantities, the
//! stresses' unit suffixed `_sq` (`uu_px_ms_sq`).
//!
//! Global attributes state the axis convention (which way y and v point), the calibration,
//! the period and phase origin, and whether replaced vectors were counted; then the source
//! series' attributes, prefixed `source_`.

use super::netcdf::{Attribute, Dataset, Values, Variable};
use super::{write_atomic, write_dataset_netcdf, SOFTWARE};
use crate::error::{Error, Result};
use crate::statistics::FlowStatistics;
use std::io::Write;
use std::path::Path;

/// The columns and variables of the statistics, with their meaning.
const QUANTITIES: [(&str, &str); 7] = [
    ("u_mean", "mean of u over the valid vectors"),
    ("v_mean", "mean of v over the valid vectors"),
    ("u_rms", "RMS of the fluctuation of u (square root of uu)"),
    ("v_rms", "RMS of the fluctuation of v (square root of vv)"),
    ("uu", "Reynolds normal stress u'u' (sample variance of u)"),
    ("vv", "Reynolds normal stress v'v' (sample variance of v)"),
    (
        "uv",
        "Reynolds shear stress u'v' (sample covariance of u and v)",
    ),
];

/// The values of each quantity of [`QUANTITIES`], physical when calibrated, and their
/// unit and squared unit.
fn quantities(st: &FlowStatistics) -> (Vec<Vec<f64>>, String, String) {
    let (image_unit, physical_unit) = st.quantity.units();
    let (scale, flip, unit) = match &st.calibration {
        Some(c) => (c.mm_per_px, if c.y_up { -1.0 } else { 1.0 }, physical_unit),
        None => (1.0, 1.0, image_unit),
    };
    let scaled = |v: &[f64], k: f64| v.iter().map(|x| x * k).collect::<Vec<f64>>();
    let values = vec![
        scaled(&st.u_mean, scale),
        scaled(&st.v_mean, scale * flip),
        scaled(&st.u_rms(), scale),
        scaled(&st.v_rms(), scale),
        scaled(&st.uu, scale * scale),
        scaled(&st.vv, scale * scale),
        scaled(&st.uv, scale * scale * flip),
    ];
    (values, unit.to_string(), format!("({unit})^2"))
}

/// The NetCDF dataset of `st`, with `attributes` (the source's) added.
pub fn statistics_dataset(st: &FlowStatistics, attributes: &[(String, String)]) -> Dataset {
    let phased = st.phased();
    let grid: Vec<String> = if phased {
        vec!["phase".into(), "y".into(), "x".into()]
    } else {
        vec!["y".into(), "x".into()]
    };
    let text = |s: &str| Attribute::Text(s.to_string());
    let mut variables = Vec::new();
    if phased {
        variables.push(Variable {
            name: "phase".into(),
            dims: vec!["phase".into()],
            values: Values::F64(st.phase_centres_us.clone()),
            attributes: if st.trigger.is_some() {
                vec![
                    (
                        "long_name".into(),
                        text("centre of the phase bin, fraction of the interval between consecutive triggers"),
                    ),
                    ("units".into(), text("1")),
                ]
            } else {
                vec![
                    (
                        "long_name".into(),
                        text("centre of the phase bin, from the phase origin"),
                    ),
                    ("units".into(), text("us")),
                ]
            },
        });
    }
    for (name, values, long) in [
        ("y", &st.y, "row centre (image y, down)"),
        ("x", &st.x, "column centre (image x, right)"),
    ] {
        variables.push(Variable {
            name: name.into(),
            dims: vec![name.into()],
            values: Values::F64(values.clone()),
            attributes: vec![
                ("long_name".into(), text(long)),
                ("units".into(), text("px")),
            ],
        });
    }
    if let Some(c) = &st.calibration {
        let ys = st.y.iter().map(|&y| c.y_mm(y)).collect();
        let xs = st.x.iter().map(|&x| c.x_mm(x)).collect();
        for (name, dim, values) in [("y_mm", "y", ys), ("x_mm", "x", xs)] {
            variables.push(Variable {
                name: name.into(),
                dims: vec![dim.into()],
                values: Values::F64(values),
                attributes: vec![("units".into(), text("mm"))],
            });
        }
    }
    let (values, unit, squared) = quantities(st);
    let v_direction = match &st.calibration {
        Some(c) if c.y_up => " (v positive up)",
        _ => " (v positive down)",
    };
    for ((name, long), values) in QUANTITIES.iter().zip(values) {
        let unit = if name.len() == 2 { &squared } else { &unit };
        // The quantities whose sign depends on the direction of v.
        let long = if matches!(*name, "v_mean" | "uv") {
            format!("{long}{v_direction}")
        } else {
            long.to_string()
        };
        variables.push(Variable {
            name: (*name).into(),
            dims: grid.clone(),
            values: Values::F64(values),
            attributes: vec![
                ("long_name".into(), Attribute::Text(long)),
                ("units".into(), text(unit)),
            ],
        });
    }
    variables.push(Variable {
        name: "count".into(),
        dims: grid,
        values: Values::I32(st.count.iter().map(|&c| c as i32).collect()),
        attributes: vec![
            (
                "long_name".into(),
                text("valid vectors averaged at the node"),
            ),
            ("units".into(), text("1")),
        ],
    });
    let mut dims = Vec::new();
    if phased {
        dims.push(("phase".to_string(), st.phases));
    }
    dims.push(("y".to_string(), st.y.len()));
    dims.push(("x".to_string(), st.x.len()));
    let mut globals = vec![
        ("Conventions".to_string(), text("CF-1.8")),
        ("title".to_string(), text("ebiv flow statistics")),
        ("software".to_string(), text(SOFTWARE)),
        ("fields".to_string(), Attribute::F64(vec![st.fields as f64])),
        (
            "statistics".to_string(),
            text(if st.include_replaced {
                "over the valid and replaced vectors; stresses are sample covariances (N - 1)"
            } else {
                "over the valid vectors only; stresses are sample covariances (N - 1)"
            }),
        ),
        (
            "axis_convention".to_string(),
            text(&super::axis_convention_of(
                st.quantity,
                st.calibration.as_ref(),
            )),
        ),
    ];
    if let Some(period) = st.period_us {
        globals.push(("period_us".to_string(), Attribute::F64(vec![period as f64])));
        globals.push((
            "phase_origin_us".to_string(),
            Attribute::F64(vec![st.phase_origin_us as f64]),
        ));
    }
    if let Some(tr) = &st.trigger {
        globals.push((
            "phase_by".to_string(),
            text("trigger: phase = (t - last trigger at or before t) / (next trigger - that trigger)"),
        ));
        globals.push((
            "triggers".to_string(),
            Attribute::F64(vec![tr.triggers as f64]),
        ));
        globals.push((
            "trigger_span_us".to_string(),
            Attribute::F64(vec![tr.span_us.0 as f64, tr.span_us.1 as f64]),
        ));
        globals.push((
            "trigger_interval_mean_us".to_string(),
            Attribute::F64(vec![tr.mean_interval_us]),
        ));
        globals.push((
            "fields_outside_triggers".to_string(),
            Attribute::F64(vec![tr.fields_outside as f64]),
        ));
    }
    if let Some(c) = &st.calibration {
        globals.push(("mm_per_px".to_string(), Attribute::F64(vec![c.mm_per_px])));
        globals.push((
            "origin_px".to_string(),
            Attribute::F64(c.origin_px.to_vec()),
        ));
    }
    for (key, value) in attributes {
        let name = format!("source_{}", super::sanitize_name(key));
        if !globals.iter().any(|(k, _)| *k == name) {
            globals.push((name, text(value)));
        }
    }
    Dataset {
        dims,
        variables,
        attributes: globals,
    }
}

/// Write `st` to `path`: `.nc` (NetCDF-3) or `.csv`.
pub fn write_statistics(
    st: &FlowStatistics,
    attributes: &[(String, String)],
    path: &Path,
) -> Result<()> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("nc") => write_dataset_netcdf(&statistics_dataset(st, attributes), path),
        Some("csv") => write_statistics_csv(st, path),
        _ => Err(Error::parameter(
            "output",
            format!("{}: statistics are written as .nc or .csv", path.display()),
        )),
    }
}

fn write_statistics_csv(st: &FlowStatistics, path: &Path) -> Result<()> {
    let (values, unit, _) = quantities(st);
    let suffix = unit.replace('/', "_");
    let phased = st.phased();
    let nodes = st.x.len() * st.y.len();
    write_atomic(path, |w| {
        if phased {
            let name = if st.trigger.is_some() {
                "phase"
            } else {
                "phase_us"
            };
            write!(w, "{name},")?;
        }
        write!(w, "x_px,y_px")?;
        for (name, _) in QUANTITIES {
            let unit = if name.len() == 2 {
                format!("{suffix}_sq")
            } else {
                suffix.clone()
            };
            write!(w, ",{name}_{unit}")?;
        }
        writeln!(w, ",count")?;
        for phase in 0..st.phases {
            for (row, &y) in st.y.iter().enumerate() {
                for (col, &x) in st.x.iter().enumerate() {
                    let i = phase * nodes + row * st.x.len() + col;
                    if phased {
                        write!(w, "{},", st.phase_centres_us[phase])?;
                    }
                    write!(w, "{x},{y}")?;
                    for v in &values {
                        write!(w, ",{}", v[i])?;
                    }
                    writeln!(w, ",{}", st.count[i])?;
                }
            }
        }
        Ok(())
    })
}
