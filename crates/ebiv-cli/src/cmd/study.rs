//! `ebiv study`: a Monte-Carlo parameter study ([`ebiv::study`]), with a progress bar on
//! standard error and a summary on standard output.

use clap::Args;
use ebiv::study::{self, StudySpec, EXAMPLES};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Simulate a setup many times over, sweeping scenario, sensor or processing parameters with
/// repeated seeds, process every recording and measure the errors against the truth. Writes
/// results.csv (one row per cell), summary.csv (means with 95 % confidence intervals), plots
/// and report.md into the output folder. Finished cells are kept there: a rerun (after
/// Ctrl-C, or with more values) computes only the cells it does not find. See docs/study.md.
#[derive(Debug, Args)]
pub struct StudyArgs {
    /// Study file (TOML). See `--print-example turntable` for a commented one.
    #[arg(required_unless_present_any = ["example", "print_example", "list_examples"])]
    pub study: Option<PathBuf>,
    /// Run a ready study instead: turntable, histograms, envelope, density (see
    /// --list-examples).
    #[arg(long, value_name = "NAME", conflicts_with = "study")]
    pub example: Option<String>,
    /// Print a ready study's TOML (to edit and pass back) and exit.
    #[arg(long, value_name = "NAME")]
    pub print_example: Option<String>,
    /// List the ready studies and exit.
    #[arg(long)]
    pub list_examples: bool,
    /// Output folder (created if needed). Default: study-NAME for an example, else the study
    /// file's name without its extension.
    #[arg(short, long, value_name = "DIR")]
    pub output: Option<PathBuf>,
}

pub fn run(args: &StudyArgs) -> Result<(), ebiv::Error> {
    if args.list_examples {
        for (name, about, _) in EXAMPLES {
            println!("{name:12} {about}");
        }
        return Ok(());
    }
    if let Some(name) = &args.print_example {
        print!("{}", study::example_text(name)?);
        return Ok(());
    }
    let (spec, default_out): (StudySpec, PathBuf) = match (&args.example, &args.study) {
        (Some(name), _) => (study::example(name)?, format!("study-{name}").into()),
        (None, Some(path)) => (
            study::open(path)?,
            path.with_extension("")
                .file_name()
                .map_or_else(|| "study".into(), PathBuf::from),
        ),
        (None, None) => unreachable!("clap requires a study or an example"),
    };
    let out = args.output.clone().unwrap_or(default_out);
    std::fs::create_dir_all(&out).map_err(|e| ebiv::Error::io(&out, e))?;
    let cells = study::cells::cells(&spec)?.len();
    eprintln!(
        "{}: {} cells ({} settings × {} method(s) × {} seed(s)) into {}",
        spec.title,
        cells,
        spec.combinations(),
        spec.methods.len(),
        spec.seeds.len(),
        out.display()
    );
    // Ctrl-C: the cells in progress finish and are stored; a rerun continues from there.
    let _catch = crate::interrupt::catch();
    let started = Instant::now();
    let bar = crate::progress::count_bar(0, "cells");
    bar.set_message("study");
    let outcome = study::run_study(
        &spec,
        &out,
        &|p| {
            bar.set_length(p.total as u64);
            bar.set_position(p.done as u64);
        },
        &|| stop_check(&out),
    );
    bar.finish_and_clear();
    if outcome.is_err() && crate::interrupt::check(&out).is_err() {
        eprintln!(
            "stopped; the finished cells are stored in {}: run the same command again to continue",
            out.display()
        );
    }
    let outcome = outcome?;
    eprintln!(
        "{} cells computed, {} found finished, in {:.0} s on {}",
        outcome.computed,
        outcome.reused,
        started.elapsed().as_secs_f64(),
        super::bench::worker_threads()
    );
    study::write_outputs(&spec, &outcome, &out)?;
    let failed = outcome.results.iter().filter(|r| r.error.is_some()).count();
    if failed > 0 {
        eprintln!("warning: {failed} cells could not run (see the note column of results.csv)");
    }
    println!(
        "wrote {0}/results.csv, {0}/summary.csv, {0}/report.md and {0}/plots/",
        out.display()
    );
    Ok(())
}

/// The interrupt check of the study's cells.
fn stop_check(out: &Path) -> Result<(), ebiv::Error> {
    crate::interrupt::check(out)
}
