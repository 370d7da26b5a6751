//! Read a recording, measure its velocity fields by sum of correlation with the default
//! settings, and write them as NetCDF.
//!
//! `cargo run --release --example corrsum_field -- RECORDING [OUT.nc]`

use ebiv::estimate::corrsum::SumOfCorrelation;
use ebiv::estimate::Estimator;
use ebiv::process::process_recording;
use ebiv::settings::ProcessSettings;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let input = args
        .next()
        .ok_or("usage: corrsum_field RECORDING [OUT.nc]")?;
    let output = args.next().unwrap_or_else(|| "flow.nc".into());
    let settings = ProcessSettings {
        input: Some(input.clone().into()),
        ..ProcessSettings::default()
    };
    let run = settings.resolve()?;
    let estimator = SumOfCorrelation::new(run.corrsum)?;
    let options = ebiv::io::ReadOptions::default();
    let mut plan = run.plan_fields(
        &run.event_source(&options),
        estimator.time_extent_us(),
        run.slab_us(),
    )?;
    let (series, summary) = process_recording(
        &mut plan.reader,
        plan.geometry,
        &estimator,
        &run.process,
        &plan.times,
        &mut |_| Ok(()),
    )?;
    ebiv::export::write_field(&series, output.as_ref())?;
    println!(
        "{} of {} vectors valid; wrote {output}",
        summary.valid, summary.vectors
    );
    Ok(())
}
