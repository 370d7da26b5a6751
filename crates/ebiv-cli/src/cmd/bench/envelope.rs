//! `ebiv bench envelope`: the operating-envelope study of the two event estimators
//! ([`ebiv::assess::envelope`]), with progress on standard error and the report on standard
//! output.

use ebiv::assess::envelope::{
    run_study_with_vectors, EnvelopeSpec, PassSchedule, Step, ValidVector,
};
use std::path::PathBuf;
use std::time::Instant;

/// The cells of the study; each list restricts it (defaults: the full study, 63 recordings).
#[derive(Debug, clap::Args)]
pub struct EnvelopeBenchArgs {
    /// Estimators, comma-separated: corrsum, motion.
    #[arg(long, value_delimiter = ',', default_values_t = EnvelopeSpec::default().methods)]
    pub methods: Vec<String>,
    /// Flow speeds, px/ms, comma-separated (uniform flow, 30° from +x).
    #[arg(long, value_delimiter = ',', default_values_t = EnvelopeSpec::default().speeds)]
    pub speeds: Vec<f64>,
    /// Seeding densities, particles per pixel, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = EnvelopeSpec::default().densities)]
    pub densities: Vec<f64>,
    /// Final window sizes, px, comma-separated (50 % overlap).
    #[arg(long, value_delimiter = ',', default_values_t = EnvelopeSpec::default().windows)]
    pub windows: Vec<u32>,
    /// Time slabs T, as `ebiv process --slab` takes them, comma-separated (e.g. 10ms,auto).
    #[arg(long, value_delimiter = ',', default_values_t = EnvelopeSpec::default().slabs)]
    pub slabs: Vec<String>,
    /// Pass schedules, comma-separated: single (one pass of W px) and default (2W then W px,
    /// the last pass repeated).
    #[arg(long, value_delimiter = ',', value_parser = parse_passes,
          default_values_t = EnvelopeSpec::default().passes)]
    pub passes: Vec<PassSchedule>,
    /// Simulation seeds, comma-separated: one recording per speed, density and seed.
    #[arg(long, value_delimiter = ',', default_values_t = EnvelopeSpec::default().seeds)]
    pub seeds: Vec<u64>,
    /// Side of the square frame, px.
    #[arg(long, default_value_t = EnvelopeSpec::default().size)]
    pub size: u32,
    /// Also write every cell's figures to FILE as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Also write every valid vector to FILE as CSV: its cell, seed, position, velocity,
    /// peak, peak ratio, events, slab, the displacement it claims (|v|·τ for corrsum, |v|·T
    /// for motion, px), its error and whether it is a gross error.
    #[arg(long, value_name = "FILE")]
    pub vectors: Option<PathBuf>,
}

fn parse_passes(text: &str) -> Result<PassSchedule, String> {
    PassSchedule::parse(text).ok_or_else(|| format!("`{text}`: use single or default"))
}

pub fn run(args: &EnvelopeBenchArgs) -> Result<(), ebiv::Error> {
    let spec = EnvelopeSpec {
        methods: args.methods.clone(),
        speeds: args.speeds.clone(),
        densities: args.densities.clone(),
        windows: args.windows.clone(),
        slabs: args.slabs.clone(),
        passes: args.passes.clone(),
        seeds: args.seeds.clone(),
        size: args.size,
    };
    spec.validate()?;
    for path in [&args.csv, &args.vectors].into_iter().flatten() {
        crate::cmd::check_output_path(path)?;
    }
    // Ctrl-C stops the study after the run in progress; nothing is printed or written.
    let _catch = crate::interrupt::catch();
    let stop_path = args.csv.clone().unwrap_or_else(|| "envelope study".into());
    let started = Instant::now();
    let bar = crate::progress::count_bar(0, "runs");
    bar.set_message("envelope");
    let mut vectors = args
        .vectors
        .as_ref()
        .map(|_| String::from(ValidVector::CSV_HEADER));
    let mut on_vector = |v: &ValidVector| {
        if let Some(text) = vectors.as_mut() {
            text.push_str(&v.csv_row());
        }
    };
    let results = run_study_with_vectors(
        &spec,
        &mut |step| {
            match step {
            Step::Simulated {
                index,
                total,
                speed,
                density,
                seed,
                events,
            } => bar.suspend(|| {
                eprintln!(
                    "recording {index}/{total}: {speed} px/ms, {density} particles/px, seed {seed}: {events} events ({:.0} s)",
                    started.elapsed().as_secs_f64()
                )
            }),
            Step::Processed { done, total } => {
                bar.set_length(total as u64);
                bar.set_position(done as u64);
            }
        }
            crate::interrupt::check(&stop_path)
        },
        &mut on_vector,
    )?;
    bar.finish_and_clear();
    let runs = results
        .cells
        .iter()
        .filter_map(|c| c.outcome.as_ref().ok())
        .map(|c| c.recordings)
        .sum::<usize>();
    eprintln!(
        "{runs} processing runs on {} recordings in {:.0} s on {}",
        spec.speeds.len() * spec.densities.len() * spec.seeds.len(),
        started.elapsed().as_secs_f64(),
        super::worker_threads()
    );
    print!("{}", results.markdown());
    if let Some(path) = &args.csv {
        ebiv::export::write_text(path, &results.csv())?;
        eprintln!("wrote {}", path.display());
    }
    if let (Some(path), Some(text)) = (&args.vectors, &vectors) {
        ebiv::export::write_text(path, text)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
