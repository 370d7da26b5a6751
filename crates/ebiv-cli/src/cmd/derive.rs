//! `ebiv derive`: vorticity, divergence, strain rates and swirling strength of a field series
//! ([`ebiv::derived`]), written with the field, and maps of them.

use clap::Args;
use ebiv::derived::{add_derived, parse_quantities};
use ebiv::io::field::{read_field, FieldReadOptions};
use ebiv::render::{field_map, save_png, FieldMapStyle, MapQuantity};
use ebiv::Error;
use std::path::PathBuf;

/// Quantities derived from the velocity gradient of a field series: vorticity, divergence,
/// the strain-rate components e_xx, e_yy, e_xy and the swirling strength, at every node of
/// every field, written with the field (.nc, .csv or .npz).
///
/// Second-order central differences inside the grid, one-sided ones at its edges and next to
/// an invalid vector; invalid vectors never enter as zeros (docs/derived.md). Units: 1/ms for
/// fields in px/ms, 1/s with a calibration. The vorticity dv/dx - du/dy is computed in the
/// coordinates of the file: with image axes (y down) a positive value turns clockwise as the
/// image is seen.
#[derive(Debug, Args)]
pub struct DeriveArgs {
    /// Field series: any file `ebiv assess` reads (.nc, .csv of ebiv; OpenPIV, PIVlab tables).
    pub field: PathBuf,
    /// Output: .nc (NetCDF), .csv or .npz: the field with the derived quantities.
    #[arg(short, long, value_name = "FILE", default_value = "derived.nc")]
    pub output: PathBuf,
    /// The quantities, comma-separated: vorticity, divergence, e_xx, e_yy, e_xy,
    /// swirling_strength, strain (the three e) or all.
    #[arg(long, value_name = "QTY[,QTY..]", default_value = "all")]
    pub quantities: String,
    /// Millimetres per pixel, for files with physical units that carry no calibration; the
    /// quantities are then in 1/s.
    #[arg(long, value_name = "MM")]
    pub mm_per_px: Option<f64>,
    /// Folder for figures: a colour map of --quantity per field, with a colour bar.
    #[arg(long, value_name = "DIR")]
    pub png: Option<PathBuf>,
    /// With --png: what the maps show: one of the derived quantities, or speed
    /// [default: the first quantity].
    #[arg(long, value_name = "QTY", requires = "png")]
    pub quantity: Option<String>,
    /// With --png: draw the vectors on top of the colour map.
    #[arg(long, requires = "png")]
    pub vectors: bool,
    /// With --vectors: draw every Nth arrow in x and y (default: a readable density).
    #[arg(long, value_name = "N", requires = "vectors")]
    pub arrow_stride: Option<usize>,
}

pub fn run(args: &DeriveArgs) -> Result<(), Error> {
    super::check_output_path(&args.output)?;
    ebiv::export::field_extension(&args.output)?;
    ebiv::derived::check_output(&args.output)?;
    let quantities =
        parse_quantities(&args.quantities).map_err(|m| Error::parameter("quantities", m))?;
    let map = match &args.quantity {
        Some(name) => MapQuantity::parse(name).map_err(|m| Error::parameter("quantity", m))?,
        None => MapQuantity::Derived(quantities[0]),
    };
    if let MapQuantity::Derived(q) = map {
        if !quantities.contains(&q) {
            return Err(Error::parameter(
                "quantity",
                format!("{} is not among --quantities", q.name()),
            ));
        }
    }
    if args.arrow_stride == Some(0) {
        return Err(Error::parameter("arrow-stride", "must be at least 1"));
    }
    let read_options = FieldReadOptions {
        mm_per_px: args.mm_per_px,
        ..FieldReadOptions::default()
    };
    let mut series = read_field(&args.field, &read_options)?;
    series.scale_if_uncalibrated(args.mm_per_px);
    add_derived(&mut series, &quantities)?;
    ebiv::export::write_field(&series, &args.output)?;
    let unit = ebiv::derived::DerivedQuantity::unit(series.quantity, series.calibration.as_ref());
    let names: Vec<&str> = quantities.iter().map(|q| q.name()).collect();
    let nodes = series.derived[0].values.len();
    let finite = series.derived[0]
        .values
        .iter()
        .filter(|v| v.is_finite())
        .count();
    println!(
        "{} field(s), {}×{} nodes: {} in {unit}; {finite} of {nodes} {} values finite",
        series.t_us.len(),
        series.x.len(),
        series.y.len(),
        names.join(", "),
        names[0],
    );
    println!("wrote {}", args.output.display());
    if let Some(dir) = &args.png {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let style = FieldMapStyle {
            vectors: args.vectors,
            stride: args.arrow_stride,
            range: Some(ebiv::render::series_range(&series, map)?),
            title: args
                .field
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned(),
        };
        for t in 0..series.t_us.len() {
            let img = field_map(&series, t, map, &style)?;
            save_png(&img, &dir.join(format!("{}_{t:04}.png", map.name())))?;
        }
        println!(
            "figures in {}: {} map(s) of {}",
            dir.display(),
            series.t_us.len(),
            map.name()
        );
    }
    Ok(())
}
