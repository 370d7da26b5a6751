//! `ebiv assess`: errors of a vector field against the truth, or agreement of two fields.

use clap::Args;
use ebiv::assess::report::{self, ReportContext};
use ebiv::assess::{assess, compare, AssessOptions, CompareOptions, Truth};
use ebiv::io::field::{read_field, FieldReadOptions};
use std::path::{Path, PathBuf};

/// Measure the errors of a vector field against a known truth, or compare two fields.
///
/// With --truth (a simulation's truth field or scenario): bias and random error per
/// component, RMS and mean end-point error, outlier and valid shares, dynamic velocity range,
/// error maps, errors against the true speed and the events per window, coverage of the
/// per-vector uncertainty, and the fractional-displacement histogram with its peak-locking
/// index. With two fields A B: median |Δv|, the share of vectors differing by more than
/// --threshold, the mean difference and a scatter plot; B is matched to A's times and
/// interpolated to A's grid where the grids differ.
///
/// Fields: ebiv's NetCDF (.nc) or CSV output, or the text tables of other tools (OpenPIV,
/// PIVlab, any table with columns named x, y, u, v). Calibrated files are converted back to px
/// and px/ms with their own calibration or --mm-per-px. The metrics are explained in
/// docs/assess.md.
///
/// Examples:
///   ebiv simulate --example uniform --truth truth.nc -o rec.raw
///   ebiv process rec.raw -o field.nc
///   ebiv assess field.nc --truth truth.nc -o report/
///   ebiv assess field.nc --truth-example uniform
///   ebiv assess corrsum.nc motion.nc -o agreement/
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct AssessArgs {
    /// The vector field to assess (.nc, .csv or a text table).
    pub field: PathBuf,
    /// A second field to compare the first with, instead of a truth.
    #[arg(conflicts_with_all = ["truth", "truth_example"])]
    pub other: Option<PathBuf>,
    /// The truth: a truth field written by `ebiv simulate --truth` (.nc or .csv; bilinear in
    /// space, linear in time) or a scenario file (.toml), whose flow is evaluated exactly.
    #[arg(long, value_name = "FILE", conflicts_with = "truth_example")]
    pub truth: Option<PathBuf>,
    /// The truth is the flow of a ready scenario (as in `ebiv simulate --example NAME`).
    #[arg(long, value_name = "NAME")]
    pub truth_example: Option<String>,
    /// Score particle tracks instead (FIELD is then a track file of `ebiv track`, CSV)
    /// against the true paths written by `ebiv simulate --tracks`; --truth (a scenario
    /// file) or --truth-example gives the light sheet and walls that decide which particles
    /// are in view. Yield, spurious tracks, position, velocity and acceleration errors.
    #[arg(long, value_name = "FILE", conflicts_with = "other")]
    pub truth_tracks: Option<PathBuf>,
    /// Write the report here: JSON, a tidy CSV table, report.md and PNG figures.
    #[arg(short, long, value_name = "DIR")]
    pub output: Option<PathBuf>,
    /// Millimetres per pixel, for field files in physical units without a calibration of
    /// their own.
    #[arg(long, value_name = "MM")]
    pub mm_per_px: Option<f64>,
    /// Time between the two frames of a PIV pair (e.g. 2ms): turns displacements in px per
    /// frame (OpenPIV, PIVlab) into px/ms.
    #[arg(long, value_name = "DURATION", value_parser = ebiv::units::parse_us)]
    pub frame_interval: Option<i64>,
    /// Outlier: an end-point error above this many px of displacement over the vector's slab.
    #[arg(long, value_name = "PX", default_value_t = AssessOptions::default().outlier_px)]
    pub outlier_px: f64,
    /// Lowest outlier threshold, px/ms (long slabs, vectors without a slab).
    #[arg(long, value_name = "PX_MS", default_value_t = AssessOptions::default().outlier_floor)]
    pub outlier_floor: f64,
    /// A fixed outlier threshold in the field's unit instead of the two above.
    #[arg(long, value_name = "VALUE")]
    pub outlier_fixed: Option<f64>,
    /// Comparison of two fields: |Δv| beyond which two vectors disagree, in the fields' unit.
    #[arg(long, value_name = "VALUE", default_value_t = CompareOptions::default().threshold)]
    pub threshold: f64,
    /// Comparison of two fields: largest time difference of matched fields (default: half
    /// the spacing of the first field's times).
    #[arg(long, value_name = "DURATION", value_parser = ebiv::units::parse_us)]
    pub time_tolerance: Option<i64>,
}

pub fn run(args: &AssessArgs) -> Result<(), ebiv::Error> {
    let read_options = FieldReadOptions {
        mm_per_px: args.mm_per_px,
        frame_interval_us: args.frame_interval.map(|t| t as f64),
    };
    read_options.validate()?;
    if let Some(dir) = &args.output {
        if dir.exists() && !dir.is_dir() {
            return Err(ebiv::Error::Write {
                what: dir.display().to_string(),
                message: "exists and is not a folder; -o takes a folder for the report".into(),
            });
        }
    }
    if let Some(other) = &args.other {
        return run_compare(args, other, &read_options);
    }
    if let Some(truth_tracks) = &args.truth_tracks {
        return run_tracks(args, truth_tracks);
    }
    let options = AssessOptions {
        outlier_px: args.outlier_px,
        outlier_floor: args.outlier_floor,
        outlier_fixed: args.outlier_fixed,
        ..AssessOptions::default()
    };
    options.validate()?;
    let truth = load_truth(args)?;
    let field = read_field(&args.field, &read_options)?;
    let assessment = assess(&field, &|x, y, t| truth.velocity(x, y, t), &options);
    let context = ReportContext {
        field: args.field.display().to_string(),
        reference: truth.describe().to_string(),
    };
    println!("{}: {}", context.field, context.reference);
    print!("{}", report::assessment_summary(&assessment));
    if let Some(dir) = &args.output {
        let written = ebiv::render::write_assessment_report(dir, &assessment, &context)?;
        println!("wrote {} files to {}", written.len(), dir.display());
    }
    Ok(())
}

fn run_compare(
    args: &AssessArgs,
    other: &Path,
    read_options: &FieldReadOptions,
) -> Result<(), ebiv::Error> {
    let options = CompareOptions {
        threshold: args.threshold,
        time_tolerance_us: args.time_tolerance,
        ..CompareOptions::default()
    };
    let a = read_field(&args.field, read_options)?;
    let b = read_field(other, read_options)?;
    let agreement = compare(&a, &b, &options)?;
    let context = ReportContext {
        field: args.field.display().to_string(),
        reference: other.display().to_string(),
    };
    println!("a = {}, b = {}", context.field, context.reference);
    print!("{}", report::agreement_summary(&agreement));
    if let Some(dir) = &args.output {
        let written = ebiv::render::write_agreement_report(dir, &agreement, &context)?;
        println!("wrote {} files to {}", written.len(), dir.display());
    }
    Ok(())
}

/// Track mode: measured tracks against the simulator's particle paths.
fn run_tracks(args: &AssessArgs, truth_tracks: &Path) -> Result<(), ebiv::Error> {
    use ebiv::sim::scenario::Scenario;
    use ebiv::track::score::{score_tracks, ScoreOptions};
    let scenario = match (&args.truth_example, &args.truth) {
        (Some(name), _) => Some(Scenario::from_example(name)?),
        (None, Some(path)) => Some(Scenario::from_file(path)?),
        (None, None) => None,
    };
    let tracks = ebiv::export::read_tracks_csv(&args.field)?;
    let truth = ebiv::export::read_truth_tracks_csv(truth_tracks)?;
    let options = match &scenario {
        Some(s) => ScoreOptions::for_scenario(s),
        None => ScoreOptions::from_truth(&truth),
    };
    let score = score_tracks(&tracks, &truth, &options);
    println!(
        "{}: tracks against {}",
        args.field.display(),
        truth_tracks.display()
    );
    print!("{}", score.summary());
    if let Some(dir) = &args.output {
        std::fs::create_dir_all(dir).map_err(|e| ebiv::Error::io(dir, e))?;
        let path = dir.join("tracks.json");
        let json = serde_json::to_string_pretty(&score).map_err(|e| ebiv::Error::Write {
            what: path.display().to_string(),
            message: e.to_string(),
        })?;
        ebiv::export::write_text(&path, &(json + "\n"))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The truth named on the command line: a ready scenario, a scenario file, or a truth field.
fn load_truth(args: &AssessArgs) -> Result<Truth, ebiv::Error> {
    if let Some(name) = &args.truth_example {
        return Truth::from_example(name);
    }
    let Some(path) = &args.truth else {
        return Err(ebiv::Error::parameter(
            "truth",
            "give the truth (--truth FILE or --truth-example NAME), or a second field to \
             compare with",
        ));
    };
    Truth::from_path(path)
}
