//! `ebiv stats`: mean, RMS and Reynolds stresses of a series of vector fields at every node,
//! optionally phase-averaged ([`ebiv::statistics`]).

use clap::Args;
use ebiv::io::field::{read_field, FieldReadOptions};
use ebiv::statistics::{flow_statistics, StatsOptions};
use ebiv::Error;
use std::path::PathBuf;

/// Flow statistics of a field series: at every node the mean velocity, the RMS of its
/// fluctuations, the Reynolds stresses u'u', v'v', u'v' and the number of valid vectors.
///
/// Invalid vectors are left out (never counted as zero); replaced ones too, unless
/// --include-replaced. With --period the fields are sorted into --phases bins of the
/// period by their time (phase averaging).
#[derive(Debug, Args)]
pub struct StatsArgs {
    /// Field series: any file `ebiv assess` reads (.nc, .npz of ebiv; .csv; OpenPIV, PIVlab).
    pub field: PathBuf,
    /// Output: .nc (NetCDF) or .csv.
    #[arg(short, long, value_name = "FILE", default_value = "stats.nc")]
    pub output: PathBuf,
    /// Phase averaging: the period of the flow (e.g. 20ms).
    #[arg(long, value_name = "DUR")]
    pub period: Option<String>,
    /// With --period: phase bins per period [default: 8].
    #[arg(long, value_name = "N", requires = "period")]
    pub phases: Option<usize>,
    /// With --period: the time at which phase 0 begins, as the field file counts time
    /// (default: the first field's time).
    #[arg(
        long,
        value_name = "DUR",
        requires = "period",
        allow_hyphen_values = true
    )]
    pub phase_origin: Option<String>,
    /// Count replaced (interpolated) vectors as samples.
    #[arg(long)]
    pub include_replaced: bool,
    /// Millimetres per pixel, for files with physical units that carry no calibration.
    #[arg(long, value_name = "MM")]
    pub mm_per_px: Option<f64>,
}

pub fn run(args: &StatsArgs) -> Result<(), Error> {
    super::check_output_path(&args.output)?;
    let duration = |name: &str, text: &Option<String>| {
        text.as_deref()
            .map(|t| ebiv::units::parse_us(t).map_err(|m| Error::parameter(name, m)))
            .transpose()
    };
    let options = StatsOptions {
        period_us: duration("period", &args.period)?,
        phases: args.phases.unwrap_or(8),
        phase_origin_us: duration("phase-origin", &args.phase_origin)?,
        include_replaced: args.include_replaced,
    };
    let read_options = FieldReadOptions {
        mm_per_px: args.mm_per_px,
        ..FieldReadOptions::default()
    };
    read_options.validate()?;
    let mut series = read_field(&args.field, &read_options)?;
    if let (Some(mm_per_px), None) = (args.mm_per_px, series.calibration) {
        // A scale given for a file without one: the statistics in m/s, y down.
        series.calibration = Some(ebiv::field::Calibration {
            mm_per_px,
            origin_px: [0.0, 0.0],
            y_up: false,
        });
    }
    let stats = flow_statistics(&series, &options)?;
    ebiv::export::write_statistics(&stats, &series.attributes, &args.output)?;
    let bins = stats.count.len();
    let counted = stats.count.iter().filter(|&&c| c > 0).count();
    let mean_count = stats.count.iter().map(|&c| c as f64).sum::<f64>() / bins.max(1) as f64;
    if counted == 0 {
        eprintln!("warning: no valid vector in the series: every statistic is NaN");
    }
    let what = if stats.phases > 1 {
        "node-phase bins"
    } else {
        "nodes"
    };
    println!(
        "{} field(s), {}×{} nodes{}: {counted} of {bins} {what} with a valid vector, {mean_count:.1} valid samples per bin on average",
        stats.fields,
        stats.x.len(),
        stats.y.len(),
        if stats.phases > 1 {
            format!(" in {} phases", stats.phases)
        } else {
            String::new()
        }
    );
    println!("wrote {}", args.output.display());
    Ok(())
}
