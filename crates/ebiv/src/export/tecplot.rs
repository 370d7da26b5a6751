//! Vector fields as Tecplot ASCII data files (`.dat`), after the Tecplot 360 Data Format
//! Guide, chapter "ASCII Data": a file header (`TITLE`, `VARIABLES`, `DATASETAUXDATA`),
//! then one ordered zone per time step (`ZONE T=…, I=nx, J=ny, ZONETYPE=ORDERED,
//! DATAPACKING=POINT`), one line per grid point with I (x) varying fastest.
//!
//! Variables: `x`, `y` (with their unit in the name: `x [px]` or `x [mm]`), `u`, `v`
//! (`[px/ms]` or `[m/s]`), `u_unc`, `v_unc` (the standard uncertainty of `u`, `v`, one
//! standard deviation, in their unit; missing where unknown; never negated), `status` (0 =
//! valid, else the bits of [`Status`]), `peak`, `peak_ratio`, `event_count`, `slab_us` (the
//! time slab each vector was measured over, µs, 0 where there is none; described in
//! `DATASETAUXDATA slab_us`). All zones share `STRANDID=1`
//! and carry `SOLUTIONTIME` = the field time **in microseconds**, so Tecplot animates them as
//! one transient series.
//!
//! The ASCII grammar has no not-a-number token, and Tecplot's readers are not documented to
//! accept `NaN`; zero would pass for a measured vector. Non-finite values (invalid `u`, `v`,
//! unknown `u_unc`, `v_unc`, undefined `peak_ratio`) are therefore written as
//! [`TECPLOT_MISSING`], stated in a comment and in `DATASETAUXDATA missing_value`. Hide them
//! with value blanking on `status > 0` (or on `u < -1e29`); an unknown uncertainty of a valid
//! vector, on `u_unc < -1e29`.
//!
//! [`Status`]: crate::field::Status

use super::{check, metadata, write_atomic, Written};
use crate::error::{Error, Result};
use crate::field::FieldSeries;
use std::io::Write;
use std::path::Path;

/// The value written for NaN (and other non-finite values) in Tecplot files: far outside any
/// velocity, representable in single precision.
pub const TECPLOT_MISSING: f64 = -1.0e30;

/// Write `field` as a Tecplot ASCII data file, through a temporary file.
pub fn write_field_tecplot(field: &FieldSeries, path: &Path) -> Result<()> {
    check(field)?;
    if field.x.is_empty() || field.y.is_empty() {
        return Err(Error::parameter(
            "field",
            "Tecplot ordered zones need at least one grid column and row",
        ));
    }
    let w = Written::new(field);
    let (lu, vu) = (w.length_unit, w.velocity_unit);
    let meta = metadata(field);
    write_atomic(path, |out| {
        writeln!(
            out,
            "# ebiv vector field series, written by {}",
            super::SOFTWARE
        )?;
        writeln!(out, "# {}", one_line(&super::axis_convention(field)))?;
        writeln!(
            out,
            "# SOLUTIONTIME in microseconds; invalid values written as {TECPLOT_MISSING:e} \
             (blank on status > 0)"
        )?;
        writeln!(out, "TITLE = \"ebiv vector field\"")?;
        writeln!(
            out,
            "VARIABLES = \"x [{lu}]\" \"y [{lu}]\" \"u [{vu}]\" \"v [{vu}]\" \
             \"u_unc [{vu}]\" \"v_unc [{vu}]\" \"status\" \"peak\" \"peak_ratio\" \
             \"event_count\" \"slab_us\""
        )?;
        for (k, v) in &meta {
            writeln!(out, "DATASETAUXDATA {k}=\"{}\"", quote(v))?;
        }
        writeln!(out, "DATASETAUXDATA missing_value=\"{TECPLOT_MISSING:e}\"")?;
        for (ti, &t) in field.t_us.iter().enumerate() {
            writeln!(
                out,
                "ZONE T=\"t = {t} us\", I={}, J={}, K=1, ZONETYPE=ORDERED, DATAPACKING=POINT, \
                 DT=(DOUBLE DOUBLE SINGLE SINGLE SINGLE SINGLE SHORTINT SINGLE SINGLE DOUBLE \
                 DOUBLE), \
                 STRANDID=1, SOLUTIONTIME={t}",
                field.x.len(),
                field.y.len()
            )?;
            writeln!(out, "AUXDATA t_us=\"{t}\"")?;
            for (row, y) in w.y.iter().enumerate() {
                for (col, x) in w.x.iter().enumerate() {
                    let i = field.index(ti, row, col);
                    writeln!(
                        out,
                        "{} {} {} {} {} {} {} {} {} {} {}",
                        num(*x),
                        num(*y),
                        num(w.u[i] as f64),
                        num(w.v[i] as f64),
                        num(w.u_unc[i] as f64),
                        num(w.v_unc[i] as f64),
                        field.status[i].0,
                        num(field.peak[i] as f64),
                        num(field.peak_ratio[i] as f64),
                        field.event_count[i],
                        field.slab_us[i]
                    )?;
                }
            }
        }
        Ok(())
    })
}

/// A number as Tecplot reads it: shortest exact decimal, exponent form for very large or
/// small magnitudes, [`TECPLOT_MISSING`] for non-finite values.
fn num(v: f64) -> String {
    if !v.is_finite() {
        format!("{TECPLOT_MISSING:e}")
    } else if v != 0.0 && !(1e-4..1e15).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// `s` on one line with `"` and `\` escaped for a Tecplot quoted string.
fn quote(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' | '\r' | '\t' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// `s` with line breaks replaced by spaces.
fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_plain_or_exponent_and_never_nan() {
        assert_eq!(num(1.5), "1.5");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(-2.5e-7), "-2.5e-7");
        assert_eq!(num(f64::NAN), "-1e30");
        assert_eq!(num(f64::INFINITY), "-1e30");
        assert_eq!("-1e30".parse::<f64>().unwrap(), TECPLOT_MISSING);
        assert_eq!(quote("a \"b\"\nc"), "a \\\"b\\\" c");
    }

    #[test]
    fn one_zone_per_time_with_solution_time() {
        let mut f = FieldSeries::new(vec![0.0, 8.0, 16.0], vec![4.0, 12.0], vec![100, 200]);
        f.u[0] = 1.25;
        f.status[0] = crate::field::Status::VALID;
        f.attributes.push(("note".into(), "say \"hi\"".into()));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.dat");
        write_field_tecplot(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(!text.to_ascii_lowercase().contains("nan"));
        let zones: Vec<&str> = text.lines().filter(|l| l.starts_with("ZONE")).collect();
        assert_eq!(zones.len(), 2);
        assert!(zones[1].contains("SOLUTIONTIME=200") && zones[1].contains("I=3, J=2"));
        assert!(text.contains("DATASETAUXDATA note=\"say \\\"hi\\\"\""));
        assert!(text.contains("\"x [px]\" \"y [px]\" \"u [px/ms]\""));
        assert!(text.contains("\n0 4 1.25 -1e30 -1e30 -1e30 0 -1e30 -1e30 0 0\n"));
    }

    #[test]
    fn uncertainties_follow_v_scaled_by_the_calibration_and_never_negated() {
        let mut f = FieldSeries::new(vec![0.0], vec![4.0], vec![0]);
        f.u[0] = 2.0;
        f.v[0] = 4.0;
        f.u_unc[0] = 0.25;
        f.v_unc[0] = 0.5;
        f.status[0] = crate::field::Status::VALID;
        f.calibration = Some(crate::field::Calibration {
            mm_per_px: 0.5,
            origin_px: [0.0, 0.0],
            y_up: true,
        });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.dat");
        write_field_tecplot(&f, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("\"u [m/s]\" \"v [m/s]\" \"u_unc [m/s]\" \"v_unc [m/s]\" \"status\""),
            "{text}"
        );
        // v flips with y up (4 px/ms → -2 m/s); its uncertainty is only scaled.
        assert!(text.contains("\n0 -2 1 -2 0.125 0.25 0 "), "{text}");
    }
}
