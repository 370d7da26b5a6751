//! Writers for vector fields: NetCDF (MATLAB `ncread`, xarray, ParaView) and CSV.

mod csv;
mod netcdf;

pub use self::csv::write_field_csv;
pub use self::netcdf::write_field_netcdf;

/// Ground-truth particle tracks as CSV: header `id,t_us,x,y,z,u,v` (px, µs, px/ms).
pub fn write_tracks_csv(
    tracks: &[crate::sim::simulation::TrackPoint],
    path: &std::path::Path,
) -> crate::Result<()> {
    use std::io::Write;
    let temp = netcdf::partial_path(path);
    let io = |e: std::io::Error| crate::Error::io(path, e);
    let mut w = std::io::BufWriter::new(std::fs::File::create(&temp).map_err(io)?);
    writeln!(w, "id,t_us,x,y,z,u,v").map_err(io)?;
    for p in tracks {
        writeln!(
            w,
            "{},{},{},{},{},{},{}",
            p.id, p.t_us, p.x, p.y, p.z, p.u, p.v
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)?;
    drop(w);
    std::fs::rename(&temp, path).map_err(io)
}
