//! Vector fields as CSV (RFC 4180 layout, comma-separated, one header line, `\n` line ends).
//!
//! The header names every column with its unit as a suffix, so that the file says what it
//! holds to any CSV reader (pandas, `numpy.genfromtxt(..., names=True)`, spreadsheets)
//! without comment lines:
//!
//! * `t_us`: the field's time, µs of camera time (see [`TimeBasis`]); for image pairs, which
//!   carry no time stamps, the column is `field` instead: the index of the field (0, 1, …);
//! * `x_px,y_px`: window centre, px (image coordinates: x right, y down, pixel centres at
//!   integers);
//! * `u_px_ms,v_px_ms`: velocity, px/ms (v positive down); `u_px,v_px` for the displacements
//!   of image pairs without a time between the frames;
//! * `u_unc_px_ms,v_unc_px_ms`: standard uncertainty (one standard deviation) of `u` and `v`,
//!   in their unit (`u_unc_px,v_unc_px` for displacements), `NaN` where unknown and for
//!   invalid and replaced vectors ([`FieldSeries::u_unc`]);
//! * `status`: 0 = valid, else the bits of [`Status`](crate::field::Status);
//! * `peak,peak_ratio,event_count`: the quality of each vector;
//! * `slab_us`: the time slab the vector was measured over, µs, 0 where there is none
//!   ([`FieldSeries::slab_us`]).
//!
//! These columns always come first and always in image units; a ground truth
//! ([`FieldSeries::ground_truth`]) has neither the uncertainty columns nor any from `status`
//! on. With a calibration the physical columns `x_mm,y_mm,u_m_s,v_m_s,u_unc_m_s,v_unc_m_s`
//! follow (`u_mm,v_mm,u_unc_mm,v_unc_mm` for displacements; y and v positive up when the
//! calibration says `y_up`, the uncertainties scaled but never negated). One line per vector,
//! time-major, then rows, then columns. Quantities derived from the velocity gradient
//! ([`FieldSeries::derived`]) come last, each in image coordinates and units
//! (`vorticity_1_ms`; `vorticity_1` for displacements) and, where a calibration writes other
//! values, as it writes them (`vorticity_1_s`, `vorticity_y_up`; see
//! [`crate::derived::DerivedQuantity::physical_name`]). Invalid values are written as `NaN`;
//! floats in their shortest exact form.
//!
//! [`TimeBasis`]: crate::field::TimeBasis

use super::{check, write_atomic, Physical};
use crate::error::Result;
use crate::field::{FieldSeries, TimeBasis};
use std::io::Write;
use std::path::Path;

/// The header of a CSV of velocities measured in camera time, without calibration.
pub const CSV_HEADER: &str = "t_us,x_px,y_px,u_px_ms,v_px_ms,u_unc_px_ms,v_unc_px_ms,status,peak,\
                              peak_ratio,event_count,slab_us";

/// A unit as a column-name suffix: `px/ms` → `px_ms`, `m/s` → `m_s`.
fn suffix(unit: &str) -> String {
    unit.replace('/', "_")
}

/// The header line [`write_field_csv`] writes for `field` (without the line end).
pub fn csv_header(field: &FieldSeries) -> String {
    let (image_unit, physical_unit) = field.quantity.units();
    let time = if field.time_basis == TimeBasis::PairIndex {
        "field"
    } else {
        "t_us"
    };
    let image = suffix(image_unit);
    let mut header = format!("{time},x_px,y_px,u_{image},v_{image}");
    if !field.ground_truth {
        header.push_str(&format!(",u_unc_{image},v_unc_{image}"));
        header.push_str(",status,peak,peak_ratio,event_count,slab_us");
    }
    if field.calibration.is_some() {
        let physical = suffix(physical_unit);
        header.push_str(&format!(",x_mm,y_mm,u_{physical},v_{physical}"));
        if !field.ground_truth {
            header.push_str(&format!(",u_unc_{physical},v_unc_{physical}"));
        }
    }
    for d in &field.derived {
        header.push(',');
        header.push_str(&d.quantity.image_column(field.quantity));
        let physical = d
            .quantity
            .physical_name(field.quantity, field.calibration.as_ref());
        if let Some(name) = physical {
            header.push(',');
            header.push_str(&name);
        }
    }
    header
}

/// Write `field` as CSV (invalid vectors as `NaN`), through a temporary file.
pub fn write_field_csv(field: &FieldSeries, path: &Path) -> Result<()> {
    check(field)?;
    let physical = field.calibration.as_ref().map(|c| Physical::new(field, c));
    let header = csv_header(field);
    write_atomic(path, |w| {
        writeln!(w, "{header}")?;
        for ti in 0..field.t_us.len() {
            for row in 0..field.y.len() {
                for col in 0..field.x.len() {
                    write_csv_row(w, field, physical.as_ref(), ti, row, col)?;
                    writeln!(w)?;
                }
            }
        }
        Ok(())
    })
}

/// The values of one vector of `field` as a CSV line, without its line end.
pub(crate) fn write_csv_row(
    w: &mut impl Write,
    field: &FieldSeries,
    physical: Option<&Physical>,
    ti: usize,
    row: usize,
    col: usize,
) -> std::io::Result<()> {
    let (t, x, y) = (field.t_us[ti], field.x[col], field.y[row]);
    let i = field.index(ti, row, col);
    write!(w, "{t},{x},{y},{},{}", field.u[i], field.v[i])?;
    if !field.ground_truth {
        write!(
            w,
            ",{},{},{},{},{},{},{}",
            field.u_unc[i],
            field.v_unc[i],
            field.status[i].0,
            field.peak[i],
            field.peak_ratio[i],
            field.event_count[i],
            field.slab_us[i]
        )?;
    }
    if let Some(p) = physical {
        write!(w, ",{},{},{},{}", p.x_mm[col], p.y_mm[row], p.u[i], p.v[i])?;
        if !field.ground_truth {
            write!(w, ",{},{}", p.u_unc[i], p.v_unc[i])?;
        }
    }
    let calibration = field.calibration.as_ref();
    for d in &field.derived {
        let value = d.values[i];
        write!(w, ",{value}")?;
        if d.quantity
            .physical_name(field.quantity, calibration)
            .is_some()
        {
            let k = d.quantity.written_factor(field.quantity, calibration);
            write!(w, ",{}", crate::derived::written_value(value, k))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Calibration, Quantity, Status};

    #[test]
    fn csv_has_the_documented_header() {
        let f = FieldSeries::new(vec![1.0], vec![2.0], vec![5]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.csv");
        write_field_csv(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "t_us,x_px,y_px,u_px_ms,v_px_ms,u_unc_px_ms,v_unc_px_ms,status,peak,peak_ratio,\
             event_count,slab_us\n\
             5,1,2,NaN,NaN,NaN,NaN,1,NaN,NaN,0,0\n"
        );
        assert_eq!(text.lines().next(), Some(CSV_HEADER));
        assert!(!dir.path().join("f.csv.partial").exists());
    }

    #[test]
    fn column_names_carry_the_units_of_what_is_written() {
        let mut f = FieldSeries::new(vec![1.0], vec![2.0], vec![0]);
        f.quantity = Quantity::Displacement;
        f.time_basis = TimeBasis::PairIndex;
        assert_eq!(
            csv_header(&f),
            "field,x_px,y_px,u_px,v_px,u_unc_px,v_unc_px,status,peak,peak_ratio,event_count,\
             slab_us"
        );
        f.calibration = Some(Calibration {
            mm_per_px: 0.5,
            origin_px: [0.0, 0.0],
            y_up: false,
        });
        assert!(csv_header(&f).ends_with(",x_mm,y_mm,u_mm,v_mm,u_unc_mm,v_unc_mm"));
        f.quantity = Quantity::Velocity;
        assert!(csv_header(&f).ends_with(",x_mm,y_mm,u_m_s,v_m_s,u_unc_m_s,v_unc_m_s"));
    }

    #[test]
    fn ground_truth_has_only_positions_and_velocities() {
        let mut f = FieldSeries::new(vec![1.0, 3.0], vec![2.0], vec![7]);
        f.ground_truth = true;
        f.time_basis = TimeBasis::Instant;
        f.u = vec![0.5, 1.5];
        f.v = vec![-1.0, 2.0];
        f.status = vec![Status::VALID; 2];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("truth.csv");
        write_field_csv(&f, &path).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "t_us,x_px,y_px,u_px_ms,v_px_ms\n7,1,2,0.5,-1\n7,3,2,1.5,2\n"
        );
        f.calibration = Some(Calibration {
            mm_per_px: 0.5,
            origin_px: [0.0, 0.0],
            y_up: false,
        });
        assert_eq!(
            csv_header(&f),
            "t_us,x_px,y_px,u_px_ms,v_px_ms,x_mm,y_mm,u_m_s,v_m_s"
        );
    }

    #[test]
    fn calibrated_csv_appends_physical_columns() {
        let mut f = FieldSeries::new(vec![10.0, 30.0], vec![100.0], vec![-7]);
        f.u[1] = 2.0;
        f.v[1] = 4.0;
        f.u_unc[1] = 0.25;
        f.v_unc[1] = 0.5;
        f.status[1] = Status::VALID;
        f.peak[1] = 0.25;
        f.peak_ratio[1] = 3.5;
        f.event_count[1] = 42;
        f.slab_us[1] = 7000;
        f.calibration = Some(Calibration {
            mm_per_px: 0.5,
            origin_px: [10.0, 90.0],
            y_up: true,
        });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.csv");
        write_field_csv(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "t_us,x_px,y_px,u_px_ms,v_px_ms,u_unc_px_ms,v_unc_px_ms,status,peak,peak_ratio,\
             event_count,slab_us,x_mm,y_mm,u_m_s,v_m_s,u_unc_m_s,v_unc_m_s"
        );
        assert_eq!(
            lines[1],
            "-7,10,100,NaN,NaN,NaN,NaN,1,NaN,NaN,0,0,0,-5,NaN,NaN,NaN,NaN"
        );
        // y up flips v (4 px/ms down is -2 m/s) but not its uncertainty.
        assert_eq!(
            lines[2],
            "-7,30,100,2,4,0.25,0.5,0,0.25,3.5,42,7000,10,-5,1,-2,0.125,0.25"
        );
    }
}
