//! Vector fields as CSV: header `t_us,x,y,u,v`, one vector per line, px and px/ms.

use crate::error::{Error, Result};
use crate::field::FieldSeries;
use std::io::Write;
use std::path::Path;

/// Write `field` as CSV (invalid vectors as `NaN`), through a temporary file.
pub fn write_field_csv(field: &FieldSeries, path: &Path) -> Result<()> {
    let temp = super::netcdf::partial_path(path);
    let io = |e: std::io::Error| Error::io(path, e);
    let file = std::fs::File::create(&temp).map_err(io)?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "t_us,x,y,u,v").map_err(io)?;
    for (ti, &t) in field.t_us.iter().enumerate() {
        for (row, &y) in field.y.iter().enumerate() {
            for (col, &x) in field.x.iter().enumerate() {
                let i = field.index(ti, row, col);
                writeln!(w, "{t},{x},{y},{},{}", field.u[i], field.v[i]).map_err(io)?;
            }
        }
    }
    w.flush().map_err(io)?;
    drop(w);
    std::fs::rename(&temp, path).map_err(io)
}
