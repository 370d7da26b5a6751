//! `ebiv stats`: mean, RMS and Reynolds stresses of a series of vector fields at every node,
//! optionally phase-averaged ([`ebiv::statistics`]).

use clap::Args;
use ebiv::io::field::{read_field, FieldReadOptions};
use ebiv::statistics::{flow_statistics, triggers_for, StatsOptions, TriggerPolarity};
use ebiv::Error;
use std::path::PathBuf;

/// Flow statistics of a field series: at every node the mean velocity, the RMS of its
/// fluctuations, the Reynolds stresses u'u', v'v', u'v' and the number of valid vectors.
///
/// Invalid vectors are left out (never counted as zero); replaced ones too, unless
/// --include-replaced. With --period the fields are sorted into --phases bins of the
/// period by their time (phase averaging); with --triggers REC into --phases bins of the
/// interval between the recording's trigger edges around each field.
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
    /// Phase averaging by trigger: the recording the fields were measured from; a field's
    /// phase is its fraction of the interval between the trigger edges around it. Fields
    /// before the first or after the last edge are left out and counted.
    #[arg(long, value_name = "REC", conflicts_with = "period")]
    pub triggers: Option<PathBuf>,
    /// With --triggers: the edges that start a cycle: rising, falling or any.
    #[arg(
        long,
        value_name = "EDGE",
        requires = "triggers",
        default_value = "rising"
    )]
    pub trigger_polarity: String,
    /// With --triggers: the trigger channel (default: the only one the recording uses).
    #[arg(long, value_name = "N", requires = "triggers")]
    pub trigger_channel: Option<u8>,
    /// With --period or --triggers: phase bins per period or trigger interval [default: 8].
    #[arg(long, value_name = "N")]
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
    #[command(flatten)]
    pub input: crate::input::InputArgs,
}

pub fn run(args: &StatsArgs) -> Result<(), Error> {
    super::check_output_path(&args.output)?;
    let duration = |name: &str, text: &Option<String>| {
        text.as_deref()
            .map(|t| ebiv::units::parse_us(t).map_err(|m| Error::parameter(name, m)))
            .transpose()
    };
    if args.phases.is_some() && args.period.is_none() && args.triggers.is_none() {
        return Err(Error::parameter(
            "phases",
            "phase bins need --period or --triggers",
        ));
    }
    let polarity = TriggerPolarity::parse(&args.trigger_polarity).ok_or_else(|| {
        Error::parameter(
            "trigger-polarity",
            format!("`{}` is not rising, falling or any", args.trigger_polarity),
        )
    })?;
    let mut options = StatsOptions {
        period_us: duration("period", &args.period)?,
        triggers_us: None,
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
    // A scale given for a file without one: the statistics in m/s, y down.
    series.scale_if_uncalibrated(args.mm_per_px);
    if let Some(recording) = &args.triggers {
        let times = triggers_for(
            &series,
            recording,
            &args.input.read_options()?,
            polarity,
            args.trigger_channel,
        )?;
        println!(
            "{} {} trigger edge(s) in {} ({} edge(s) in all)",
            times.times_us.len(),
            polarity.name(),
            recording.display(),
            times.all_edges
        );
        options.triggers_us = Some(times.times_us);
    }
    let stats = flow_statistics(&series, &options)?;
    if let Some(tr) = &stats.trigger {
        println!(
            "{} trigger interval(s), {:.1} us on average; {} field(s) outside the triggers left out",
            tr.triggers - 1,
            tr.mean_interval_us,
            tr.fields_outside
        );
    }
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
