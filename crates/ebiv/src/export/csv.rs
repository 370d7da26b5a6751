//! Vector fields as CSV (RFC 4180 layout, comma-separated, one header line, `\n` line ends).
//!
//! Columns, always first and always in image units so scripts keep working:
//! `t_us,x,y,u,v,status` (µs; window centre in px, x right, y down; px/ms; status 0 = valid,
//! else the bits of [`Status`](crate::field::Status)), then `peak,peak_ratio,event_count`.
//! With a calibration the physical columns `x_mm,y_mm,u_m_s,v_m_s` follow (y and v positive
//! up when the calibration says `y_up`). One line per vector, time-major, then rows, then
//! columns. Invalid values are written as `NaN`; floats in their shortest exact form.

use super::{check, write_atomic, Physical};
use crate::error::Result;
use crate::field::FieldSeries;
use std::io::Write;
use std::path::Path;

/// The header of a CSV without calibration.
pub const CSV_HEADER: &str = "t_us,x,y,u,v,status,peak,peak_ratio,event_count";

/// Write `field` as CSV (invalid vectors as `NaN`), through a temporary file.
pub fn write_field_csv(field: &FieldSeries, path: &Path) -> Result<()> {
    check(field)?;
    let physical = field.calibration.as_ref().map(|c| Physical::new(field, c));
    write_atomic(path, |w| {
        write!(w, "{CSV_HEADER}")?;
        if physical.is_some() {
            write!(w, ",x_mm,y_mm,u_m_s,v_m_s")?;
        }
        writeln!(w)?;
        for (ti, &t) in field.t_us.iter().enumerate() {
            for (row, &y) in field.y.iter().enumerate() {
                for (col, &x) in field.x.iter().enumerate() {
                    let i = field.index(ti, row, col);
                    write!(
                        w,
                        "{t},{x},{y},{},{},{},{},{},{}",
                        field.u[i],
                        field.v[i],
                        field.status[i].0,
                        field.peak[i],
                        field.peak_ratio[i],
                        field.event_count[i]
                    )?;
                    if let Some(p) = &physical {
                        write!(w, ",{},{},{},{}", p.x_mm[col], p.y_mm[row], p.u[i], p.v[i])?;
                    }
                    writeln!(w)?;
                }
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Calibration, Status};

    #[test]
    fn csv_has_the_documented_header() {
        let f = FieldSeries::new(vec![1.0], vec![2.0], vec![5]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.csv");
        write_field_csv(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "t_us,x,y,u,v,status,peak,peak_ratio,event_count\n5,1,2,NaN,NaN,1,NaN,NaN,0\n"
        );
        assert!(!dir.path().join("f.csv.partial").exists());
    }

    #[test]
    fn calibrated_csv_appends_physical_columns() {
        let mut f = FieldSeries::new(vec![10.0, 30.0], vec![100.0], vec![-7]);
        f.u[1] = 2.0;
        f.v[1] = 4.0;
        f.status[1] = Status::VALID;
        f.peak[1] = 0.25;
        f.peak_ratio[1] = 3.5;
        f.event_count[1] = 42;
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
            "t_us,x,y,u,v,status,peak,peak_ratio,event_count,x_mm,y_mm,u_m_s,v_m_s"
        );
        assert_eq!(lines[1], "-7,10,100,NaN,NaN,1,NaN,NaN,0,0,-5,NaN,NaN");
        assert_eq!(lines[2], "-7,30,100,2,4,0,0.25,3.5,42,10,-5,1,-2");
    }
}
