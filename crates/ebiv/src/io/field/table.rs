//! Vector-field tables: ebiv's CSV and the text tables of other tools, columns found by name
//! (see [`super::columns`]).
//!
//! The header is the first of the first 50 lines that names x, y, u and v columns; a leading
//! `#` or `%` is ignored, so NumPy `savetxt` headers (OpenPIV) count, and lines before it are
//! skipped (PIVlab's title and frame lines, whose "conversion factor xy (px -> m)" gives the
//! scale of calibrated exports). Cells are separated by commas, semicolons, tabs or
//! whitespace, whichever the header uses. Later lines starting with `#` or `%` and blank lines
//! are skipped. Values `NaN`/`nan` are invalid vectors. The derived quantities of ebiv's
//! CSV are read from their columns in image units (`vorticity_1_ms`, `vorticity_1`).

use super::columns::{Column, Role};
use super::grid::{assemble, Rows};
use super::FieldReadOptions;
use crate::derived::{DerivedField, DerivedQuantity};
use crate::error::{Error, Result};
use crate::field::{FieldSeries, Quantity, Status, TimeBasis};

/// Lines searched for the header.
const HEADER_LINES: usize = 50;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Delimiter {
    Char(char),
    Whitespace,
}

impl Delimiter {
    fn of(line: &str) -> Delimiter {
        for c in [',', ';', '\t'] {
            if line.contains(c) {
                return Delimiter::Char(c);
            }
        }
        Delimiter::Whitespace
    }

    fn split<'a>(&self, line: &'a str) -> Vec<&'a str> {
        match self {
            Delimiter::Char(c) => line.split(*c).map(str::trim).collect(),
            Delimiter::Whitespace => line.split_whitespace().collect(),
        }
    }
}

fn strip_comment(line: &str) -> &str {
    line.trim_start().trim_start_matches(['#', '%']).trim()
}

/// mm per px from a PIVlab "conversion factor xy (px -> m): F" line.
fn pivlab_scale(line: &str) -> Option<f64> {
    let at = line.find("conversion factor xy (px -> m):")?;
    let rest = &line[at + "conversion factor xy (px -> m):".len()..];
    let number: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+'))
        .collect();
    let f: f64 = number.parse().ok()?;
    // A factor of 1 is PIVlab's "not calibrated".
    (f.is_finite() && f > 0.0 && f != 1.0).then_some(f * 1000.0)
}

/// Index of the column of `role`, preferring one in image units.
fn pick(columns: &[Column], role: Role) -> Option<usize> {
    let mut found = columns.iter().enumerate().filter(|(_, c)| c.role == role);
    let first = found.next()?;
    if first.1.in_image_units() {
        return Some(first.0);
    }
    Some(
        found
            .find(|(_, c)| c.in_image_units())
            .map_or(first.0, |(i, _)| i),
    )
}

/// What the u, v columns hold after conversion, and the factor to px/ms (or px).
struct VelocityUnit {
    quantity: Quantity,
    factor: f64,
}

fn need_scale(context: &str, column: &str, scale: Option<f64>) -> Result<f64> {
    scale.ok_or_else(|| {
        Error::unsupported(
            context,
            format!(
                "column `{column}` is in physical units and the file carries no calibration; \
                 give the scale in mm per pixel (ebiv assess --mm-per-px)"
            ),
        )
    })
}

fn length_factor(c: &Column, context: &str, scale: Option<f64>) -> Result<f64> {
    let mm = match c.unit.as_str() {
        "" | "px" | "pix" | "pixel" | "pixels" => return Ok(1.0),
        "mm" => 1.0,
        "m" => 1000.0,
        "cm" => 10.0,
        "um" | "µm" | "μm" => 1e-3,
        other => {
            return Err(Error::unsupported(
                context,
                format!(
                    "column `{}`: unknown length unit `{other}` (px, mm, m, cm, µm)",
                    c.name
                ),
            ))
        }
    };
    Ok(mm / need_scale(context, &c.name, scale)?)
}

fn velocity_unit(c: &Column, context: &str, scale: Option<f64>) -> Result<VelocityUnit> {
    use Quantity::{Displacement, Velocity};
    let (quantity, factor, physical_mm) = match c.unit.as_str() {
        "px/ms" | "pixel/millisecond" | "pixel/ms" => (Velocity, 1.0, None),
        "px/s" | "pixel/s" | "pixel/second" => (Velocity, 1e-3, None),
        "px/us" | "px/µs" => (Velocity, 1e3, None),
        "" | "px" | "pix" | "pixel" | "pixels" | "px/frame" | "pixel/frame" => {
            (Displacement, 1.0, None)
        }
        "m/s" => (Velocity, 1.0, Some(1.0)),
        "mm/s" => (Velocity, 1.0, Some(1e-3)),
        "mm/ms" => (Velocity, 1.0, Some(1.0)),
        "mm" => (Displacement, 1.0, Some(1.0)),
        "m" => (Displacement, 1.0, Some(1000.0)),
        other => {
            return Err(Error::unsupported(
                context,
                format!(
                    "column `{}`: unknown unit `{other}` (px/ms, px/s, px/frame, px, m/s, mm/s, \
                     mm)",
                    c.name
                ),
            ))
        }
    };
    // m/s = mm/ms; 1 px/ms = mm_per_px mm/ms.
    let factor = match physical_mm {
        Some(mm) => factor * mm / need_scale(context, &c.name, scale)?,
        None => factor,
    };
    Ok(VelocityUnit { quantity, factor })
}

fn time_factor(c: &Column, context: &str) -> Result<f64> {
    match c.unit.as_str() {
        "" | "us" | "µs" | "μs" => Ok(1.0),
        "ms" => Ok(1e3),
        "s" => Ok(1e6),
        other => Err(Error::unsupported(
            context,
            format!(
                "column `{}`: unknown time unit `{other}` (us, ms, s)",
                c.name
            ),
        )),
    }
}

/// Read a table (see the module documentation).
pub(super) fn read_str(
    text: &str,
    context: &str,
    options: &FieldReadOptions,
) -> Result<FieldSeries> {
    let mut header = None;
    let mut file_scale = None;
    for (k, line) in text.lines().enumerate().take(HEADER_LINES) {
        let stripped = strip_comment(line);
        let delimiter = Delimiter::of(stripped);
        let columns: Vec<Column> = delimiter
            .split(stripped)
            .into_iter()
            .map(Column::parse)
            .collect();
        let has = |r: Role| columns.iter().any(|c| c.role == r);
        if has(Role::X) && has(Role::Y) && has(Role::U) && has(Role::V) {
            header = Some((k, delimiter, columns));
            break;
        }
        file_scale = file_scale.or_else(|| pivlab_scale(line));
    }
    let Some((header_line, delimiter, columns)) = header else {
        let first = text
            .lines()
            .next()
            .unwrap_or("")
            .chars()
            .take(80)
            .collect::<String>();
        return Err(Error::unsupported(
            context,
            format!(
                "no header line naming the columns x, y, u and v in the first {HEADER_LINES} \
                 lines (the first line is `{first}`); ebiv reads tables with named columns, \
                 e.g. `x,y,u,v` or `x [px],y [px],u [px/frame],v [px/frame]`"
            ),
        ));
    };
    let scale = options.mm_per_px.or(file_scale);
    let col = |r: Role| pick(&columns, r);
    let (ix, iy, iu, iv) = (
        col(Role::X).unwrap_or(0),
        col(Role::Y).unwrap_or(0),
        col(Role::U).unwrap_or(0),
        col(Role::V).unwrap_or(0),
    );
    let fx = length_factor(&columns[ix], context, scale)?;
    let fy = length_factor(&columns[iy], context, scale)?;
    let mut unit_u = velocity_unit(&columns[iu], context, scale)?;
    let unit_v = velocity_unit(&columns[iv], context, scale)?;
    if unit_u.quantity != unit_v.quantity
        || (unit_u.factor - unit_v.factor).abs() > 1e-12 * unit_u.factor.abs()
    {
        return Err(Error::unsupported(
            context,
            format!(
                "columns `{}` and `{}` have different units",
                columns[iu].name, columns[iv].name
            ),
        ));
    }
    let derived = derived_columns(&columns, unit_u.quantity);
    let mut derived_factor = 1.0;
    if let (Quantity::Displacement, Some(dt)) = (unit_u.quantity, options.frame_interval_us) {
        derived_factor = 1000.0 / dt;
        unit_u = VelocityUnit {
            quantity: Quantity::Velocity,
            factor: unit_u.factor / (dt / 1000.0),
        };
    }
    let (time, basis) = match (col(Role::Time), col(Role::FieldIndex)) {
        (Some(i), _) => (
            Some((i, time_factor(&columns[i], context)?)),
            TimeBasis::SlabCentre,
        ),
        (None, Some(i)) => (Some((i, 1.0)), TimeBasis::PairIndex),
        (None, None) => (None, TimeBasis::PairIndex),
    };
    let optional = |r: Role| col(r);
    let (i_status, i_flags, i_mask, i_valid) = (
        optional(Role::Status),
        optional(Role::Flags),
        optional(Role::Mask),
        optional(Role::Valid),
    );
    let (i_peak, i_ratio, i_events, i_slab) = (
        optional(Role::Peak),
        optional(Role::PeakRatio),
        optional(Role::EventCount),
        optional(Role::SlabUs),
    );
    let (i_uu, i_vu) = (optional(Role::UUnc), optional(Role::VUnc));
    let ground_truth = i_status.is_none()
        && i_flags.is_none()
        && i_mask.is_none()
        && i_valid.is_none()
        && i_peak.is_none()
        && i_events.is_none()
        && context_is_truth(&columns);
    let mut rows = Rows {
        derived: derived
            .iter()
            .map(|&(quantity, _)| DerivedField {
                quantity,
                values: Vec::new(),
            })
            .collect(),
        ..Rows::default()
    };
    let needed = columns.len();
    for (k, line) in text.lines().enumerate().skip(header_line + 1) {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') || trimmed.starts_with('%') {
            continue;
        }
        let line_no = k as u64 + 1;
        let cells = delimiter.split(trimmed);
        if cells.len() < needed {
            return Err(Error::Parse {
                context: context.into(),
                line: line_no,
                message: format!("{} values, the header names {needed} columns", cells.len()),
            });
        }
        let num = |i: usize| -> Result<f64> {
            let cell = cells[i].trim_matches('"');
            cell.parse::<f64>().map_err(|_| Error::Parse {
                context: context.into(),
                line: line_no,
                message: format!("`{cell}` in column `{}` is not a number", columns[i].name),
            })
        };
        let opt = |i: Option<usize>| -> Result<Option<f64>> { i.map(num).transpose() };
        let (u, v) = (
            (num(iu)? * unit_u.factor) as f32,
            (num(iv)? * unit_u.factor) as f32,
        );
        let finite = u.is_finite() && v.is_finite();
        let mut status = match opt(i_status)? {
            Some(s) if (0.0..=255.0).contains(&s) && s.fract() == 0.0 => Status(s as u8),
            Some(s) => {
                return Err(Error::Parse {
                    context: context.into(),
                    line: line_no,
                    message: format!("status `{s}` is not a whole number from 0 to 255"),
                })
            }
            None if finite => Status::VALID,
            None => Status::NO_EVENTS,
        };
        if opt(i_flags)?.is_some_and(|f| f != 0.0) {
            status = status.with(Status::MEDIAN_TEST);
            if finite {
                status = status.with(Status::REPLACED);
            }
        }
        if opt(i_mask)?.is_some_and(|m| m != 0.0) {
            status = status.with(Status::MASKED);
        }
        if opt(i_valid)?.is_some_and(|m| m == 0.0) {
            status = status.with(Status::MEDIAN_TEST);
        }
        let (u, v) = if status.has_value() {
            (u, v)
        } else {
            (f32::NAN, f32::NAN)
        };
        let t = match time {
            Some((i, factor)) => {
                let t = num(i)? * factor;
                if !(t.is_finite() && t.abs() < 9e18) {
                    return Err(Error::Parse {
                        context: context.into(),
                        line: line_no,
                        message: format!("time `{}` is out of range", cells[i]),
                    });
                }
                t.round() as i64
            }
            None => 0,
        };
        let count = |i: Option<usize>| -> Result<u32> {
            Ok(opt(i)?
                .filter(|c| c.is_finite() && *c >= 0.0)
                .map_or(0, |c| c.min(u32::MAX as f64) as u32))
        };
        rows.t.push(t);
        rows.x.push(num(ix)? * fx);
        rows.y.push(num(iy)? * fy);
        rows.u.push(u);
        rows.v.push(v);
        rows.status.push(status);
        rows.peak.push(opt(i_peak)?.map_or(f32::NAN, |p| p as f32));
        rows.peak_ratio
            .push(opt(i_ratio)?.map_or(f32::NAN, |p| p as f32));
        rows.event_count.push(count(i_events)?);
        rows.slab_us.push(count(i_slab)?);
        rows.u_unc
            .push(opt(i_uu)?.map_or(f32::NAN, |s| (s * unit_u.factor) as f32));
        rows.v_unc
            .push(opt(i_vu)?.map_or(f32::NAN, |s| (s * unit_u.factor) as f32));
        for (to, &(_, i)) in rows.derived.iter_mut().zip(&derived) {
            to.values.push((num(i)? * derived_factor) as f32);
        }
        rows.line.push(line_no);
    }
    let mut series = assemble(rows, context, basis)?;
    series.quantity = unit_u.quantity;
    series.ground_truth = ground_truth;
    if ground_truth {
        series.time_basis = TimeBasis::Instant;
    }
    series
        .attributes
        .push(("source".into(), context.to_string()));
    Ok(series)
}

/// The columns of the derived quantities in the image units of a table of `quantity`
/// (`vorticity_1_ms` for velocities, `vorticity_1` for displacements), with their index.
/// The copies in a calibration's units and frame (`vorticity_1_s`, `vorticity_y_up`) repeat
/// them and are not read.
fn derived_columns(columns: &[Column], quantity: Quantity) -> Vec<(DerivedQuantity, usize)> {
    let unit = DerivedQuantity::unit(quantity, None);
    DerivedQuantity::ALL
        .into_iter()
        .filter_map(|q| {
            columns
                .iter()
                .position(|c| c.role == Role::Derived(q) && c.unit == unit)
                .map(|i| (q, i))
        })
        .collect()
}

/// A table with exactly ebiv's truth columns (`t_us,x_px,y_px,u_px_ms,v_px_ms`) is a ground
/// truth as `ebiv simulate --truth` writes it.
fn context_is_truth(columns: &[Column]) -> bool {
    let names: Vec<&str> = columns.iter().map(|c| c.name.as_str()).collect();
    names == ["t_us", "x_px", "y_px", "u_px_ms", "v_px_ms"]
}
