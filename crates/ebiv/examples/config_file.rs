//! Measure velocity fields with the settings of an `ebiv init` configuration file, the same
//! settings `ebiv process --config FILE` reads, here by motion compensation.
//!
//! `cargo run --release --example config_file -- CONFIG.toml RECORDING`

use ebiv::estimate::motion::ContrastMaximization;
use ebiv::estimate::Estimator;
use ebiv::process::process_recording;
use ebiv::settings::ProcessSettings;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [config, input] = args.as_slice() else {
        return Err("usage: config_file CONFIG.toml RECORDING".into());
    };
    let mut settings = ProcessSettings::default();
    for warning in settings.apply_file(config.as_ref())? {
        eprintln!("warning: {warning}");
    }
    settings.set("input", &toml::Value::String(input.clone()))?;
    let run = settings.resolve()?;
    let estimator = ContrastMaximization::new(run.motion.clone())?;
    let options = ebiv::io::ReadOptions::default();
    let mut plan = run.plan_fields(
        &run.event_source(&options),
        estimator.time_extent_us(),
        run.slab_us(),
    )?;
    let (series, _) = process_recording(
        &mut plan.reader,
        plan.geometry,
        &estimator,
        &run.process,
        &plan.times,
        &mut |_| Ok(()),
    )?;
    ebiv::export::write_field(&series, &run.output)?;
    println!(
        "{} field(s) written to {}",
        series.t_us.len(),
        run.output.display()
    );
    Ok(())
}
